"""What a learned reward paid over a run (rile.py's; gail.py's, gaifo.py's, airl.py's since issue 29), from its results
file: one row per measure (every --dynamics-freq steps), beside the evaluation at that step.

Columns: the student's evaluation (normalized as the file stored it: random 0, expert 1 since issue 31, x expert
before); r_S on the demonstrations' pairs, on the student's pairs of the
interval, their spread, and at the absorbing state; D on both; the Pearson correlation of r_S and 2D - 1 on the
student's pairs (since 2026-12-02; "-" in older files); the freeze test's statistic (critic loss
relative to its targets' variance); FS-RFDC and CPR; whether the trainer was frozen.

    python benchmarks/reward_measures.py benchmarks/results/HalfCheetah-v4/rile-gp0-autotune__1.json [more files]
"""

import argparse
import json

COLUMNS = [("r_s_demos", "r_S demo"), ("r_s_student", "r_S stud"), ("r_s_spread", "spread"), ("r_s_absorbing", "r_S abs"),
           ("d_demos", "D demo"), ("d_student", "D stud"), ("r_s_follows_d", "r_S~D"), ("critic_loss_relative", "crit rel"),
           ("critic_loss_to_reward", "crit/r_T"), ("critic_excess_to_reward", "crit>noise"),
           ("fs_rfdc", "FS-RFDC"), ("cpr", "CPR")]


def table(results: dict) -> str:
    """The measures of one results file as a tab-separated table with a header line."""
    normalized = {e["step"]: e["normalized"] for e in results["evals"]}
    rows = ["step\teval (norm.)\t" + "\t".join(label for _, label in COLUMNS) + "\ttrainer"]
    for m in results.get("reward_measures") or []:
        cells = [f"{m[key]:.3f}" if m.get(key) is not None else "-" for key, _ in COLUMNS]
        frozen = m.get("trainer_frozen_at")
        trainer = "-" if "trainer_frozen_at" not in m else "learning" if frozen is None else f"frozen at {frozen}"
        score = normalized.get(m["step"])
        rows.append(f"{m['step']}\t{'-' if score is None else f'{score:.2f}'}\t" + "\t".join(cells) + f"\t{trainer}")
    return "\n".join(rows)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("files", nargs="+", help="results files of rile.py, gail.py, gaifo.py or airl.py runs")
    for path in parser.parse_args(argv).files:
        with open(path) as f:
            results = json.load(f)
        if not results.get("reward_measures"):
            raise SystemExit(f"error: {path} has no reward_measures; rile.py runs write them since issue 28, "
                             "gail.py, gaifo.py and airl.py runs since issue 29")
        frozen = f": trainer frozen at {results['trainer_frozen_at']}" if "trainer_frozen_at" in results else ""
        print(f"{path}{frozen}\n{table(results)}\n")


if __name__ == "__main__":
    main()
