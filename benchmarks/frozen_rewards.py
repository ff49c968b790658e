"""The frozen rewards of the covariate-shift experiment (docs/experiments.md): each method's seed-1 default run on an
env at 200k steps (rile.py, the control, gail.py, airl.py), run or resumed from its checkpoint, then its reward.pt
copied to benchmarks/rewards/<env-id>/<algo>__1.pt, where `python sweep.py ... --reward-from` reads it, with a line in
benchmarks/rewards/README.md saying which run, commit and machine made it, and its results file copied to
benchmarks/results/<env-id>/<algo>-source__1.json (the experiment page's source row).

    python benchmarks/frozen_rewards.py                    # the four Hopper-v4 sources, two at a time
    python benchmarks/frozen_rewards.py --methods airl     # one of them

Each source has the flags and seed of the default run the README's tables hold for seed 1, and its README line gives
both finals; runs that were resumed or evaluated otherwise need not repeat their numbers.
"""

import argparse
import json
import os
import shutil
import subprocess
import sys
from concurrent.futures import ThreadPoolExecutor

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)
import sweep  # noqa: E402  (the methods, their scripts and flags)


def make(method: str, env_id: str, threads: int, steps: int, out: str, results_dir: str) -> str:
    """Run (or resume) one source, copy its reward.pt into `out` and its results file into `results_dir`, and return
    its README line."""
    script, flags = sweep.METHODS[method].script, sweep.METHODS[method].flags
    run_dir = os.path.join("runs", f"source__{env_id}__{method}__1")
    cmd = [sys.executable, os.path.join(ROOT, script), "--env-id", env_id, "--seed", "1", "--total-timesteps", str(steps),
           "--threads", str(threads), "--checkpoint-freq", "10000", "--run-name", os.path.basename(run_dir), *flags.split()]
    if os.path.exists(os.path.join(run_dir, "checkpoint.pt")):
        cmd += ["--resume", run_dir]
    os.makedirs("runs", exist_ok=True)
    with open(run_dir + ".log", "a") as log:
        if subprocess.run(cmd, stdout=log, stderr=subprocess.STDOUT).returncode != 0:
            raise SystemExit(f"error: {' '.join(cmd)} failed; see {run_dir}.log, and run this again to resume it")
    with open(os.path.join(run_dir, "results.json")) as f:
        results = json.load(f)
    target = os.path.join(out, env_id, f"{method}__1.pt")
    os.makedirs(os.path.dirname(target), exist_ok=True)
    shutil.copyfile(os.path.join(run_dir, "reward.pt"), target)
    command = " ".join(["python", script] + cmd[2:])
    sweep.collect(sweep.Job(script, env_id, 1, steps, [], f"{sweep.METHODS[method].tag}-source".lstrip("-")), results,
                  [sys.executable, script] + cmd[2:], results_dir)  # <results_dir>/<env-id>/<algo>-source__1.json
    committed = os.path.join(results_dir, env_id, f"{method}__1.json")
    before = json.load(open(committed)) if os.path.exists(committed) else None
    before = before["final_return"] if before and before["config"]["total_timesteps"] == steps else None
    machine = results["machine"]
    return (f"- `{os.path.relpath(target, out)}`: `{command}` at commit "
            f"{machine['git']}, {machine['cpu']} ({machine['cpu_capability']}), torch {machine['torch']}, "
            f"{machine['threads']} thread(s); final return {results['final_return']:.1f}"
            + (f" (the committed default run's: {before:.1f})" if before is not None else ""))


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--env-id", default="Hopper-v4")
    parser.add_argument("--methods", nargs="+", default=list(sweep.METHODS), choices=list(sweep.METHODS))
    parser.add_argument("--workers", type=int, default=2, help="sources at once")
    parser.add_argument("--threads", type=int, default=1, help="torch threads of each source")
    parser.add_argument("--total-timesteps", type=int, default=200_000)
    parser.add_argument("--out", default=os.path.join(ROOT, "benchmarks", "rewards"))
    parser.add_argument("--results-dir", default=sweep.RESULTS_DIR)
    args = parser.parse_args()
    with ThreadPoolExecutor(args.workers) as pool:
        lines = list(pool.map(lambda m: make(m, args.env_id, args.threads, args.total_timesteps, args.out,
                                             args.results_dir), args.methods))
    readme = os.path.join(args.out, "README.md")
    old = open(readme).read().splitlines() if os.path.exists(readme) else []
    paths = {line.split("`")[1] for line in lines}
    kept = [line for line in old if line.startswith("- `") and line.split("`")[1] not in paths]
    with open(readme, "w") as f:
        f.write("# Frozen rewards of the covariate-shift experiment\n\nMade by `python benchmarks/frozen_rewards.py`; "
                "read by `--reward-from` (docs/experiments.md). Each file, the run that saved it:\n\n"
                + "\n".join(sorted(kept + lines)) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
