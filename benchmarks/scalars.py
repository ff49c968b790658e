"""A run's logged scalars beside its evaluations: one row per evaluation, each tag averaged over the steps since the last.

For reading what a learner's losses, values and rewards did when its evaluations rose or fell (IQ-Learn losing a
near-expert policy, issue 16) without opening TensorBoard:

    python benchmarks/scalars.py runs/bench__Hopper-v4__iqlearn-chi2-policy__2 \
        --tags losses/q_expert losses/q_policy reward/implicit_expert reward/implicit_current_policy
"""

import argparse
import glob
import os

import numpy as np
from tensorboard.backend.event_processing.event_accumulator import EventAccumulator


def load(run_dir: str) -> dict:
    """Every scalar of every event file in run_dir (a resumed run writes several), as {tag: (steps, values)}."""
    files = sorted(glob.glob(os.path.join(run_dir, "events.out.tfevents.*")))
    if not files:
        raise SystemExit(f"{run_dir}: no events.out.tfevents.* files; pass a run directory under runs/")
    series = {}
    for path in files:
        events = EventAccumulator(path, size_guidance={"scalars": 0})
        events.Reload()
        for tag in events.Tags()["scalars"]:
            steps, values = series.setdefault(tag, ([], []))
            for event in events.Scalars(tag):
                steps.append(event.step)
                values.append(event.value)
    return {tag: (np.array(steps), np.array(values)) for tag, (steps, values) in series.items()}


def table(series: dict, tags: list, eval_tag: str = "eval/return") -> list:
    """Rows of (eval step, eval value, mean of each tag over the steps after the previous evaluation up to this one)."""
    missing = [tag for tag in [eval_tag] + tags if tag not in series]
    if missing:
        raise SystemExit(f"tags not logged in this run: {', '.join(missing)}; logged: {', '.join(sorted(series))}")
    eval_steps, eval_values = series[eval_tag]
    order = np.argsort(eval_steps, kind="stable")
    rows, previous = [], -1
    for step, value in zip(eval_steps[order], eval_values[order]):
        means = []
        for tag in tags:
            steps, values = series[tag]
            window = values[(steps > previous) & (steps <= step)]
            means.append(float(window.mean()) if len(window) else float("nan"))
        rows.append((int(step), float(value), means))
        previous = step
    return rows


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("run_dir", help="a run directory holding events.out.tfevents.* files")
    parser.add_argument("--tags", nargs="+", required=True, help="scalar tags to average between evaluations")
    parser.add_argument("--eval-tag", default="eval/return", help="the tag whose steps make the rows")
    cli = parser.parse_args()
    rows = table(load(cli.run_dir), cli.tags, cli.eval_tag)
    print("\t".join(["step", cli.eval_tag] + cli.tags))
    for step, value, means in rows:
        print("\t".join([str(step), f"{value:.1f}"] + [f"{m:.3g}" for m in means]))


if __name__ == "__main__":
    main()
