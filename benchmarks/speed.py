"""Env steps per second after learning starts: expert.py's SAC, rile.py and the baselines on SAC, against
Stable-Baselines3's SAC.

Both run on Hopper-v4 with the same hyperparameters (batch 256, 256-256 ReLU, buffer 1e6, lr 3e-4,
gamma 0.99, tau 0.005, autotuned entropy, one gradient step per env step, `--learning-starts` random
steps first), one after the other in this one invocation, each in its own process with the same torch
thread count, alternating `--repeats` times (the shared host's speed drifts; medians are reported).
Only the steps after learning starts are timed (evaluation excluded). Writes
benchmarks/results/speed.json and prints a Markdown table.

    pip install stable-baselines3   # only for this benchmark
    python benchmarks/speed.py                       # expert.py (eager) vs SB3
    python benchmarks/speed.py --variants eager compile rile rile-frozen --steps 5000
    python benchmarks/speed.py --variants gail airl gaifo iqlearn drail-gail drail-rile

Each script runs with its own defaults (the paper's settings), so the baselines' figures include their
discriminator updates; drail-* use DRAIL's width 1024 unless `--drail-width` says otherwise.
"""

import argparse
import json
import os
import platform
import statistics
import subprocess
import sys
import tempfile
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

SB3_SCRIPT = """
import json, sys, time, torch, gymnasium as gym
from stable_baselines3 import SAC
from stable_baselines3.common.callbacks import BaseCallback
env_id, learning_starts, steps, threads, out = sys.argv[1], int(sys.argv[2]), int(sys.argv[3]), int(sys.argv[4]), sys.argv[5]
torch.set_num_threads(threads)
class Timer(BaseCallback):
    def _on_step(self):
        if self.num_timesteps == learning_starts:
            self.t0 = time.perf_counter()
        return True
timer = Timer()
model = SAC("MlpPolicy", gym.make(env_id), learning_rate=3e-4, buffer_size=1_000_000, learning_starts=learning_starts,
            batch_size=256, tau=0.005, gamma=0.99, train_freq=1, gradient_steps=1, ent_coef="auto",
            policy_kwargs=dict(net_arch=[256, 256]), seed=1, device="cpu")
model.learn(learning_starts + steps, callback=timer)
json.dump({"sps": steps / (time.perf_counter() - timer.t0)}, open(out, "w"))
"""


def run_script(variant: str, args, workdir: str) -> float:
    """expert.py (eager / compile), or an imitation script on the project's demonstrations. rile-frozen:
    rile.py with its trainer frozen from the first updates on, the regime of a run once the trainer
    has converged (student and discriminator updates only)."""
    demos = ["--expert-path", os.path.join(ROOT, "experts", f"{args.env_id}.npz")]
    rile = demos + ["--dynamics-freq", "0"]
    drail = demos + ["--disc-hidden-dim", str(args.drail_width)]
    script, flags = {"eager": ("expert.py", ["--no-record-demos"]),
                     "compile": ("expert.py", ["--no-record-demos", "--compile"]),
                     "rile": ("rile.py", rile),
                     "rile-frozen": ("rile.py", rile + ["--trainer-freeze-min-updates", "0",
                                                        "--trainer-freeze-threshold", "1e9"]),
                     "gail": ("gail.py", demos), "airl": ("airl.py", demos), "gaifo": ("gaifo.py", demos),
                     "iqlearn": ("iqlearn.py", demos), "drail-gail": ("drail_disc.py", drail + ["--student-reward", "gail"]),
                     "drail-rile": ("drail_disc.py", drail + ["--student-reward", "rile"])}[variant]
    cmd = [sys.executable, "-W", "ignore", os.path.join(ROOT, script), "--env-id", args.env_id,
           "--total-timesteps", str(args.learning_starts + args.steps), "--learning-starts", str(args.learning_starts),
           "--eval-freq", str(10**9), "--eval-episodes", "1", "--checkpoint-freq", "0", "--no-save-model",
           "--threads", str(args.threads), "--run-name", f"speed_{variant}", *flags]
    subprocess.run(cmd, cwd=workdir, check=True, capture_output=True)
    with open(os.path.join(workdir, "runs", f"speed_{variant}", "results.json")) as f:
        return json.load(f)["sps"]


NAMES = {"eager": "expert.py (eager)", "compile": "expert.py (compile)", "rile": "rile.py",
         "rile-frozen": "rile.py, trainer frozen", "gail": "gail.py", "airl": "airl.py", "gaifo": "gaifo.py",
         "iqlearn": "iqlearn.py", "drail-gail": "drail_disc.py (GAIL)", "drail-rile": "drail_disc.py (RILe)"}


def run_sb3(args, workdir: str) -> float:
    out = os.path.join(workdir, "sb3.json")
    subprocess.run([sys.executable, "-W", "ignore", "-c", SB3_SCRIPT, args.env_id, str(args.learning_starts),
                    str(args.steps), str(args.threads), out], check=True, capture_output=True)
    with open(out) as f:
        return json.load(f)["sps"]


def cpu_name() -> str:
    try:
        with open("/proc/cpuinfo") as f:
            return next(line.split(":", 1)[1].strip() for line in f if line.startswith("model name"))
    except (OSError, StopIteration):
        return platform.processor() or platform.machine()


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--env-id", default="Hopper-v4")
    parser.add_argument("--learning-starts", type=int, default=5000)
    parser.add_argument("--steps", type=int, default=3000, help="timed env steps after learning starts")
    parser.add_argument("--threads", type=int, default=2, help="torch intra-op threads for both")
    parser.add_argument("--repeats", type=int, default=3, help="alternating runs of each; medians are reported")
    parser.add_argument("--variants", nargs="+", default=["eager"], choices=list(NAMES))
    parser.add_argument("--drail-width", type=int, default=1024, help="drail_disc.py's --disc-hidden-dim")
    parser.add_argument("--out", default=os.path.join(ROOT, "benchmarks", "results", "speed.json"))
    args = parser.parse_args()

    import torch

    # the machine's speed drifts (shared host): alternate the implementations and report medians
    runs = {"sb3": []} | {NAMES[v]: [] for v in args.variants}
    variant_of = {name: v for v, name in NAMES.items()}
    with tempfile.TemporaryDirectory() as workdir:
        for repeat in range(args.repeats):
            for name in runs:
                sps = run_sb3(args, workdir) if name == "sb3" else run_script(variant_of[name], args, workdir)
                runs[name].append(sps)
                print(f"repeat {repeat + 1}: {name}: {sps:.1f} steps/s", flush=True)
    results = {name: statistics.median(values) for name, values in runs.items()}
    git = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=ROOT, capture_output=True, text=True)
    record = {
        "what": "env steps per second after learning starts, evaluation excluded",
        "env_id": args.env_id, "learning_starts": args.learning_starts, "timed_steps": args.steps,
        "repeats": args.repeats, "drail_width": args.drail_width, "sps_runs": runs, "sps": results,
        "ratio_to_sb3": {k: v / results["sb3"] for k, v in results.items() if k != "sb3"},
        "machine": {"cpu": cpu_name(), "cpu_count": os.cpu_count(),
                    "torch": torch.__version__, "threads": args.threads, "python": platform.python_version()},
        "git_commit": git.stdout.strip() or None, "date": time.strftime("%Y-%m-%d %H:%M"),
        "command": " ".join([os.path.relpath(sys.argv[0], ROOT)] + sys.argv[1:]),
    }
    os.makedirs(os.path.dirname(args.out), exist_ok=True)
    with open(args.out, "w") as f:
        json.dump(record, f, indent=1)
    print("\n| implementation | steps/s | vs SB3 |\n|---|---|---|")
    for name, sps in results.items():
        print(f"| {name} | {sps:.1f} | {sps / results['sb3']:.2f}x |")
    print(f"\n{args.env_id}, {args.steps} timed steps after {args.learning_starts}; torch {torch.__version__}, "
          f"{args.threads} threads, {os.cpu_count()} CPUs; written to {os.path.relpath(args.out, ROOT)}")


if __name__ == "__main__":
    main()
