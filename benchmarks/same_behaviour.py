"""Does a change leave every script's behaviour as it was? Short fixed-seed CPU runs, compared number for number.

    python benchmarks/same_behaviour.py --out before.json            # before the change
    python benchmarks/same_behaviour.py --out after.json --compare before.json

Each variant below runs 3,000 env steps of InvertedPendulum-v4 (learning from step 1,000; bc.py and bco.py
their own short schedules) with seed 1 on one thread, and records the final evaluation return and the last
logged value of every TensorBoard scalar but the timings. A refactor that keeps the arithmetic and the order
of random draws reproduces them exactly; `--compare` prints every number that moved.
"""

import argparse
import json
import os
import subprocess
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SHORT = ["--env-id", "InvertedPendulum-v4", "--seed", "1", "--threads", "1", "--eval-episodes", "3"]
OFF_POLICY = SHORT + ["--total-timesteps", "3000", "--learning-starts", "1000", "--eval-freq", "3000"]
VARIANTS = {
    "expert": ["expert.py", *OFF_POLICY, "--no-record-demos"],
    "gail": ["gail.py", *OFF_POLICY],
    "gail-absorbing": ["gail.py", *OFF_POLICY, "--termination-remedy", "absorbing"],
    "rile": ["rile.py", *OFF_POLICY, "--trainer-freeze-min-updates", "1000", "--dynamics-freq", "1000"],
    "rile-survival": ["rile.py", *OFF_POLICY, "--termination-remedy", "survival", "--student-expert-fraction", "0.25",
                      "--trainer-expert-fraction", "0.25"],
    "rile-control": ["rile.py", *OFF_POLICY, "--student-reward", "discriminator", "--dynamics-freq", "1000"],
    "airl": ["airl.py", *OFF_POLICY],
    "gaifo": ["gaifo.py", *OFF_POLICY],
    "iqlearn": ["iqlearn.py", *OFF_POLICY],
    "drail-gail": ["drail_disc.py", *OFF_POLICY, "--student-reward", "gail", "--disc-hidden-dim", "64"],
    "drail-rile": ["drail_disc.py", *OFF_POLICY, "--student-reward", "rile", "--disc-hidden-dim", "64"],
    "bc": ["bc.py", *SHORT, "--total-timesteps", "2000", "--eval-freq", "1000"],
    "bco": ["bco.py", *SHORT, "--pre-demo-steps", "1000", "--iterations", "2", "--inverse-steps", "500",
            "--inverse-steps-per-iteration", "200", "--bc-steps", "500", "--bc-steps-per-iteration", "200"],
}
TIMINGS = ("charts/SPS",)


def last_scalars(run_dir: str) -> dict:
    from tensorboard.backend.event_processing.event_accumulator import EventAccumulator

    events = EventAccumulator(run_dir, size_guidance={"scalars": 0})
    events.Reload()
    return {tag: events.Scalars(tag)[-1].value for tag in events.Tags()["scalars"] if tag not in TIMINGS}


def run_variant(name: str, argv: list, workdir: str) -> dict:
    run_name = f"same__{name}"
    proc = subprocess.run([sys.executable, "-W", "ignore", os.path.join(ROOT, argv[0]), *argv[1:], "--run-name",
                           run_name, "--expert-path" if argv[0] != "expert.py" else "--demo-path",
                           os.path.join(ROOT, "experts", "InvertedPendulum-v4.npz")],
                          cwd=workdir, capture_output=True, text=True)
    if proc.returncode != 0:
        return {"error": (proc.stderr or proc.stdout).strip().splitlines()[-1]}
    run_dir = os.path.join(workdir, "runs", run_name)
    with open(os.path.join(run_dir, "results.json")) as f:
        results = json.load(f)
    return {"final_return": results["final_return"], "scalars": last_scalars(run_dir)}


def compare(before: dict, after: dict) -> int:
    moved = 0
    for name in sorted(set(before) | set(after)):
        b, a = before.get(name, {}), after.get(name, {})
        flat_b = {"final_return": b.get("final_return"), **b.get("scalars", {}), "error": b.get("error")}
        flat_a = {"final_return": a.get("final_return"), **a.get("scalars", {}), "error": a.get("error")}
        for key in sorted(set(flat_b) | set(flat_a)):
            if flat_b.get(key) != flat_a.get(key):
                moved += 1
                print(f"{name:16s} {key:40s} {flat_b.get(key)!s:>24s} -> {flat_a.get(key)!s}")
    print(f"{moved} numbers moved across {len(set(before) | set(after))} variants")
    return moved


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", required=True, help="write the numbers here (json)")
    parser.add_argument("--compare", help="numbers of an earlier run to compare with")
    parser.add_argument("--variants", nargs="+", default=list(VARIANTS), choices=list(VARIANTS))
    args = parser.parse_args()
    numbers = {}
    with tempfile.TemporaryDirectory() as workdir:  # the demo-path of expert.py is never written: --no-record-demos
        for name in args.variants:
            numbers[name] = run_variant(name, VARIANTS[name], workdir)
            print(f"{name:16s} final return {numbers[name].get('final_return')} {numbers[name].get('error', '')}",
                  flush=True)
    with open(args.out, "w") as f:
        json.dump(numbers, f, indent=1, sort_keys=True)
    if args.compare:
        with open(args.compare) as f:
            sys.exit(1 if compare(json.load(f), numbers) else 0)
