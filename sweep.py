"""Multi-seed sweeps of the project's scripts that survive sessions; results tables and learning curves.

    python sweep.py --scripts rile.py gail.py --env-ids Hopper-v4 --seeds 1 2 3 --total-timesteps 200000
    python sweep.py --status            # which jobs are done, running, interrupted or waiting
    python sweep.py --report            # the defaults in the README, every tag in docs/results.md, the paper's
                                        # experiments in docs/experiments.md (tables and figures)
    python sweep.py ... --launcher slurm --partition gpu --time 720 --cpus 4 --gpus 1

Each job (script x env x seed) runs as its own process, `python <script> --env-id E --seed S
--total-timesteps T --run-name bench__<E>__<algo>__<S> <extra args>`, writing to runs/<run-name>/.
A job whose results file exists for the same --total-timesteps is skipped; a job with a checkpoint but no
such result is resumed (`--resume runs/<run-name>`), so a longer sweep extends shorter runs and a sweep
spread over several sessions simply continues: run the same command again. Arguments that sweep.py does
not know pass through to the scripts; give such a variant its own `--tag` so that its results do not
collide with the default's.

Results: each finished run's results.json (the format every script writes) is copied to
benchmarks/results/<env-id>/<algo>__<seed>.json, with the command that produced it. Details: docs/sweeps.md
"""

import argparse
import contextlib
import json
import math
import os
import re
import subprocess
import sys
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from typing import List, NamedTuple, Optional

import numpy as np

ROOT = os.path.dirname(os.path.abspath(__file__))
RESULTS_DIR = os.path.join(ROOT, "benchmarks", "results")
RUNS_DIR = "runs"  # relative to the working directory, as the scripts write it
README_START, README_END = "<!-- benchmark:start -->", "<!-- benchmark:end -->"
DOCS_PAGE = "docs/results.md"  # beside the README: the generated page of every tag

# Which results tags ran today's defaults, and the name their row has in the README. A results file is
# benchmarks/results/<env-id>/<script stem>-<tag>__<seed>.json (`sweep.py --scripts S --tag T`); the README's results
# section shows only the tags listed here, under these names, grouped by script in this order; docs/results.md shows
# every tag. A tag is listed when its files' "config" equals the script's current Args defaults in everything but the
# run's length and evaluation (--total-timesteps, --learning-starts, --eval-freq, --eval-episodes, --threads,
# --checkpoint-freq) and the number of demonstrations, which the row's name then states. When a default changes, run
# the new defaults under a new tag and point the entry at it: the old tag's rows stay in docs/results.md.
DEFAULT_ROWS = {
    ("rile.py", "paperD"): "rile.py defaults",
    ("rile.py", "paperD-control"): "rile.py control: r_S = v(D), no trainer",  # --student-reward discriminator
    ("gail.py", "paperD-autotune"): "gail.py defaults",
    ("airl.py", ""): "airl.py defaults",
    ("gaifo.py", ""): "gaifo.py defaults",  # ran before the --disc-* flags existed, with the paper's D they default to
    ("iqlearn.py", "chi2-policy"): "iqlearn.py defaults",  # Hopper-v4's preset; tag `iqlearn`: chi^2 replay
    ("bc.py", "10demos"): "bc.py defaults with 10 demonstrations",  # tag `bc` (25) ran --loss nll
    ("bco.py", ""): "bco.py defaults",
    # Pendulum-v1: every script from 10 demonstrations, 15k steps, learning from step 2,000 (ENV_NOTES)
    ("rile.py", "10demos-paperD"): "rile.py defaults with 10 demonstrations",
    ("gail.py", "10demos-paperD-autotune"): "gail.py defaults with 10 demonstrations",
    ("airl.py", "10demos"): "airl.py defaults with 10 demonstrations",
    ("gaifo.py", "10demos"): "gaifo.py defaults with 10 demonstrations",
    ("iqlearn.py", "10demos-chi2replay"): "iqlearn.py defaults with 10 demonstrations",  # the preset for unlisted envs
    # Not listed, so in docs/results.md only: drail_disc.py (every run at --disc-hidden-dim 256; the default is 1024)
    # and bco.py on Pendulum-v1 (--pre-demo-steps 5000 --iterations 100, to fit 15k steps).
}
DEFAULT_NAMES = {(os.path.splitext(script)[0] + (f"-{tag}" if tag else "")): name
                 for (script, tag), name in DEFAULT_ROWS.items()}  # results-file algo -> row name
SCRIPT_ORDER = list(dict.fromkeys(script for script, _ in DEFAULT_ROWS))  # README rows: by script, then as listed
# The line under the README tables that hold rile.py's or gail.py's 200k runs (SELECTED): which seeds chose their
# defaults, so that a reader can tell tuned from held-out.
SELECTION_NOTE = "Seeds 1 and 2 of rile.py and gail.py were used to choose the defaults; seeds 3 and 4 were not."
SELECTED = ("rile-paperD", "gail-paperD-autotune")
# The line on what RILe's trainer adds: rile.py's defaults minus the control that rewards the student with v(D).
TRAINER_GAP = ("rile-paperD", "rile-paperD-control")
ENV_NOTES = {  # a line under an env's README table, where its runs differ from the others' protocol
    "Pendulum-v1": "Pendulum-v1 checks the defaults on a task without terminations, actions in [-2, 2]: 10 "
                   "demonstrations of this project's SAC expert, 15k env steps, learning from step 2,000 (iqlearn.py's "
                   "preset for envs its paper does not list was chosen on these three seeds).",
}

# The RILe paper's MuJoCo table (v2 envs, 25 demonstrations, mean +- s.e.), by env and script.
PAPER = {
    "Humanoid": {"rile": 5928, "gail": 5709, "airl": 5623, "iqlearn": 327, "drail_disc": 5755},
    "Walker2d": {"rile": 4435, "gail": 4906, "airl": 4823, "iqlearn": 270, "drail_disc": 4016},
    "Hopper": {"rile": 3417, "gail": 3361, "airl": 3014, "iqlearn": 310, "drail_disc": 1230},
    "HalfCheetah": {"rile": 5205, "gail": 4173, "airl": 3991, "iqlearn": 755, "drail_disc": 4133},
}


@dataclass
class Job:
    script: str
    env_id: str
    seed: int
    total_timesteps: int
    extra: List[str]
    tag: str = ""

    @property
    def algo(self) -> str:
        stem = os.path.splitext(os.path.basename(self.script))[0]
        return f"{stem}-{self.tag}" if self.tag else stem

    @property
    def run_name(self) -> str:
        return f"bench__{self.env_id}__{self.algo}__{self.seed}"

    @property
    def run_dir(self) -> str:
        return os.path.join(RUNS_DIR, self.run_name)

    def result_path(self, results_dir: str = RESULTS_DIR) -> str:
        return os.path.join(results_dir, self.env_id, f"{self.algo}__{self.seed}.json")

    def command(self, resume: Optional[bool] = None) -> List[str]:
        """The script's command line; with --resume where a checkpoint exists (resume=None) or where told."""
        cmd = [sys.executable, os.path.join(ROOT, self.script), "--env-id", self.env_id, "--seed", str(self.seed),
               "--total-timesteps", str(self.total_timesteps), "--run-name", self.run_name, *self.extra]
        if os.path.basename(self.script) == "expert.py":
            cmd.append("--no-record-demos")  # a benchmark run must not overwrite the shipped experts/
        if resume or resume is None and os.path.exists(os.path.join(self.run_dir, "checkpoint.pt")):
            cmd += ["--resume", self.run_dir]
        return cmd


def job_state(job: Job, results_dir: str = RESULTS_DIR) -> str:
    """done (a result of this length exists), running, interrupted (a checkpoint exists) or waiting.
    A result of another --total-timesteps does not count: the job runs (or extends its checkpoint)."""
    try:
        with open(job.result_path(results_dir)) as f:
            if json.load(f)["config"]["total_timesteps"] == job.total_timesteps:
                return "done"
    except (OSError, ValueError, KeyError):
        pass
    lock = os.path.join(job.run_dir, "sweep.lock")
    if os.path.exists(lock):
        try:
            os.kill(int(open(lock).read().split()[0]), 0)
            return "running"
        except (OSError, ValueError):
            pass  # its process is gone: the job was interrupted
    if os.path.exists(os.path.join(job.run_dir, "checkpoint.pt")):
        return "interrupted"
    return "waiting"


def last_eval(job: Job) -> str:
    evals = (read_run_results(job) or {}).get("evals")
    return f"step {evals[-1]['step']}: {evals[-1]['mean']:.1f}" if evals else "-"


def read_run_results(job: Job) -> Optional[dict]:
    try:
        with open(os.path.join(job.run_dir, "results.json")) as f:
            return json.load(f)
    except (OSError, ValueError):
        return None


def run_job(job: Job, results_dir: str = RESULTS_DIR) -> str:
    """Run (or resume) one job to the end and copy its results file. Returns a one-line outcome.
    A module-level function, so that submitit can ship it to a cluster node."""
    if job_state(job, results_dir) == "done":
        return f"{job.run_name}: already done"
    results = read_run_results(job)
    if results and results.get("finished") and results["config"].get("total_timesteps") == job.total_timesteps:
        # finished, but its result was never copied: the command it last ran with, resumed or not
        return collect(job, results, job.command(resume=bool(results["config"].get("resume"))), results_dir)
    os.makedirs(job.run_dir, exist_ok=True)
    lock = os.path.join(job.run_dir, "sweep.lock")
    with open(lock, "w") as f:
        f.write(f"{os.getpid()} {os.uname().nodename}\n")
    cmd = job.command()
    try:
        with open(job.run_dir + ".log", "a") as log:
            log.write(f"\n$ {' '.join(cmd)}\n")
            log.flush()
            rc = subprocess.run(cmd, stdout=log, stderr=subprocess.STDOUT).returncode
    finally:
        with contextlib.suppress(FileNotFoundError):  # removed by hand while the job ran
            os.remove(lock)
    if rc != 0:
        return f"{job.run_name}: exit code {rc} (log: {job.run_dir}.log); run the sweep again to resume it"
    results = read_run_results(job)
    if not results or not results.get("finished"):
        return f"{job.run_name}: stopped before the end; run the sweep again to resume it"
    return collect(job, results, cmd, results_dir)


def collect(job: Job, results: dict, cmd: List[str], results_dir: str) -> str:
    results["command"] = " ".join(["python", job.script] + cmd[2:])
    os.makedirs(os.path.dirname(job.result_path(results_dir)), exist_ok=True)
    with open(job.result_path(results_dir) + ".tmp", "w") as f:
        json.dump(results, f, indent=1)
    os.replace(job.result_path(results_dir) + ".tmp", job.result_path(results_dir))
    return f"{job.run_name}: done, final return {results['final_return']:.1f}"


def print_status(jobs: List[Job], results_dir: str = RESULTS_DIR) -> None:
    states = [job_state(j, results_dir) for j in jobs]
    print(f"{len(jobs)} jobs: " + ", ".join(f"{states.count(s)} {s}"
                                            for s in ("done", "running", "interrupted", "waiting")))
    for job, state in zip(jobs, states):
        print(f"  {state:<11} {job.run_name:<50} {last_eval(job)}")


def run_sweep(jobs: List[Job], args) -> List[str]:
    todo = [j for j in jobs if job_state(j, args.results_dir) != "done"]
    print(f"{len(jobs) - len(todo)} of {len(jobs)} jobs already done; running {len(todo)}", flush=True)
    if args.launcher == "local":
        with ThreadPoolExecutor(args.workers) as pool:
            outcomes = []
            for outcome in pool.map(lambda j: run_job(j, args.results_dir), todo):
                print(outcome, flush=True)
                outcomes.append(outcome)
        return outcomes
    import cloudpickle
    import submitit  # only for --launcher slurm / submitit-local

    if __name__ != "__main__":  # ship this module's code with the jobs, the node need not import it
        cloudpickle.register_pickle_by_value(sys.modules[__name__])
    folder = os.path.join(RUNS_DIR, "submitit")
    if args.launcher == "slurm":
        executor = submitit.AutoExecutor(folder=folder, cluster="slurm")
        executor.update_parameters(timeout_min=args.time, slurm_partition=args.partition, cpus_per_task=args.cpus,
                                   gpus_per_node=args.gpus, name="rile-benchmark")
    else:  # submitit's local executor: the same code path as Slurm, on this machine (used by the tests)
        executor = submitit.LocalExecutor(folder=folder)
        executor.update_parameters(timeout_min=args.time)
    submitted = [executor.submit(run_job, job, args.results_dir) for job in todo]
    print(f"submitted {len(submitted)} jobs ({', '.join(s.job_id for s in submitted)}); logs in {folder}", flush=True)
    if not args.wait:
        return []
    outcomes = [s.result() for s in submitted]
    for outcome in outcomes:
        print(outcome)
    return outcomes


# ---------------------------------------------------------------- report


def mean_se(values) -> tuple:
    x = np.asarray(values, dtype=np.float64)
    return float(x.mean()), float(x.std(ddof=1) / math.sqrt(len(x))) if len(x) > 1 else float("nan")


def iqm(values) -> float:
    """Interquartile mean: the mean of the middle 50% (scipy.stats.trim_mean(x, 0.25))."""
    x = np.sort(np.asarray(values, dtype=np.float64))
    cut = int(0.25 * len(x))
    return float(x[cut : len(x) - cut].mean())


def bootstrap_ci(values, stat=iqm, num_samples: int = 2000, confidence: float = 0.95, seed: int = 0):
    """Percentile bootstrap over seeds (fixed RNG seed: the report is reproducible); None for one seed, whose
    resamples are all the same value: no spread to show."""
    x = np.asarray(values, dtype=np.float64)
    if len(x) < 2:
        return None
    rng = np.random.default_rng(seed)
    stats = [stat(x[rng.integers(0, len(x), len(x))]) for _ in range(num_samples)]
    return float(np.quantile(stats, (1 - confidence) / 2)), float(np.quantile(stats, (1 + confidence) / 2))


def difference_ci(a, b, num_samples: int = 2000, confidence: float = 0.95, seed: int = 0):
    """Percentile bootstrap of mean(a) - mean(b), each group's seeds resampled on their own (fixed RNG seed); None
    where either group has one seed."""
    a, b = np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64)
    if min(len(a), len(b)) < 2:
        return None
    rng = np.random.default_rng(seed)
    diffs = [a[rng.integers(0, len(a), len(a))].mean() - b[rng.integers(0, len(b), len(b))].mean()
             for _ in range(num_samples)]
    return float(np.quantile(diffs, (1 - confidence) / 2)), float(np.quantile(diffs, (1 + confidence) / 2))


REQUIRED = ("algo", "env_id", "seed", "evals", "final_return", "expert_return", "wall_time_s", "config")


def load_results(results_dir: str = RESULTS_DIR):
    """All results files, grouped {env_id: {algo: [results]}}, and the files that could not be used."""
    grouped, bad = {}, []
    for env_id in sorted(os.listdir(results_dir)) if os.path.isdir(results_dir) else []:
        env_dir = os.path.join(results_dir, env_id)
        if not os.path.isdir(env_dir):
            continue
        for name in sorted(os.listdir(env_dir)):
            if not name.endswith(".json"):
                continue
            path = os.path.join(env_dir, name)
            try:
                with open(path) as f:
                    r = json.load(f)
                missing = [k for k in REQUIRED if k not in r]
                if missing:
                    raise ValueError(f"missing {missing}")
                if not r["evals"]:
                    raise ValueError("no evaluations")
            except (OSError, ValueError) as e:
                bad.append(f"{os.path.relpath(path, results_dir)}: {e}")
                continue
            algo = name.rsplit("__", 1)[0]
            budget = r["config"].get("total_timesteps") or r["evals"][-1]["step"]
            grouped.setdefault(env_id, {}).setdefault(algo, {}).setdefault(budget, []).append(r)
    # runs of different lengths are never pooled: an algorithm with several gets a row per length
    return {env_id: {(algo if len(by_budget) == 1 else f"{algo} ({budget // 1000}k)"): runs
                     for algo, by_budget in algos.items() for budget, runs in sorted(by_budget.items())}
            for env_id, algos in grouped.items()}, bad


def normalized_score(ret: float, random_return: Optional[float], expert_return: Optional[float]) -> Optional[float]:
    """(R - R_random) / (R_expert - R_random): 0 for uniform random actions, 1 for the demonstrations (D4RL's and
    rliable's convention, the scripts' too); None where either is unknown or the expert is no better than random."""
    if random_return is None or expert_return is None or not expert_return > random_return:
        return None
    return (ret - random_return) / (expert_return - random_return)


def random_return_of(r: dict) -> Optional[float]:
    """A results file's random-policy return: its own, else (older files) the one in the metadata of the
    demonstrations it names (experts/<env-id>.npz by default), so that older files are re-normalised."""
    if r.get("random_return") is not None:
        return r["random_return"]
    path = (r.get("config") or {}).get("expert_path") or os.path.join("experts", f"{r['env_id']}.npz")
    path = path if os.path.isabs(path) else os.path.join(ROOT, path)
    if path not in _RANDOM_RETURNS:
        try:
            with np.load(path, allow_pickle=False) as f:
                _RANDOM_RETURNS[path] = json.loads(str(f["metadata"])).get("random_return")
        except (OSError, KeyError, ValueError):
            _RANDOM_RETURNS[path] = None
    return _RANDOM_RETURNS[path]


_RANDOM_RETURNS = {}  # demonstration file -> its random_return


def last_quarter(r: dict, normalize: bool, worst: bool = False, after: float = 0.75) -> float:
    """The mean (or, `worst`, the lowest) of one run's evaluations in the last quarter of its steps (after 150k of
    200k: its last five at the default 10k): steadier than the final evaluation where evaluations swing (Hopper-v4).
    `after=0.5`: over its second half instead (its last ten), which one fall of the hopper moves half as much."""
    end = r["evals"][-1]["step"]
    means = [e["mean"] for e in r["evals"] if e["step"] > after * end]
    if normalize:
        means = [normalized_score(m, random_return_of(r), r.get("expert_return")) for m in means]
    return float(np.min(means) if worst else np.mean(means))


def summarize(runs: list) -> dict:
    finals = [r["final_return"] for r in runs]
    normalized = [normalized_score(r["final_return"], random_return_of(r), r.get("expert_return")) for r in runs]
    normalized = [n for n in normalized if n is not None]
    score = normalized if len(normalized) == len(runs) else finals
    return {"n": len(runs), "return": mean_se(finals), "normalized": mean_se(normalized) if normalized else None,
            "iqm": iqm(score), "iqm_ci": bootstrap_ci(score),
            "iqm_of": "normalized" if score is normalized else "return",
            "last_quarter": mean_se([last_quarter(r, score is normalized) for r in runs]),
            "worst": min(last_quarter(r, score is normalized, worst=True) for r in runs),
            "steps": max(r["evals"][-1]["step"] for r in runs),
            "wall_h": float(np.mean([r["wall_time_s"] for r in runs])) / 3600,
            "seeds": sorted(r["seed"] for r in runs)}


def fmt(pair, digits=1) -> str:
    m, se = pair
    return f"{m:.{digits}f}" if math.isnan(se) else f"{m:.{digits}f} ± {se:.{digits}f}"


def default_name(algo: str) -> Optional[str]:
    """The README's name of a row of today's defaults ("rile.py defaults (500k)" for "rile-paperD (500k)"), or None."""
    base, _, length = algo.partition(" (")
    return DEFAULT_NAMES[base] + (f" ({length}" if length else "") if base in DEFAULT_NAMES else None


def default_rows(algos: dict) -> dict:
    """The rows of today's defaults, keyed by results-file algo: by script (SCRIPT_ORDER), then as DEFAULT_ROWS lists
    them, then by length (as load_results orders them)."""
    keys = {algo: (SCRIPT_ORDER.index(script), i)
            for i, ((script, _), algo) in enumerate(zip(DEFAULT_ROWS, DEFAULT_NAMES))}
    rows = [algo for algo in algos if default_name(algo)]
    return {algo: algos[algo] for algo in sorted(rows, key=lambda a: keys[a.partition(" (")[0]])}


def env_table(env_id: str, algos: dict, names: Optional[dict] = None) -> str:
    """One row per algo (named names[algo] where given); the paper's column is that of the algo's script."""
    paper = PAPER.get(env_id.split("-")[0], {})
    lines = ["| algorithm | seeds | final return | normalized | IQM [95% CI] | last quarter | worst | steps "
             "| wall time (h) | paper (v2) |", "|---|---|---|---|---|---|---|---|---|---|"]
    for algo, runs in algos.items():  # in the order given
        s = summarize(runs)
        norm = fmt(s["normalized"], 3) if s["normalized"] else "-"
        digits = 3 if s["iqm_of"] == "normalized" else 1
        name = (names or {}).get(algo, algo)
        ci = f" [{s['iqm_ci'][0]:.{digits}f}, {s['iqm_ci'][1]:.{digits}f}]" if s["iqm_ci"] else ""
        lines.append(f"| {name} | {s['n']} | {fmt(s['return'])} | {norm} | {s['iqm']:.{digits}f}{ci} "
                     f"| {fmt(s['last_quarter'], digits)} | "
                     f"{s['worst']:.{digits}f} | {s['steps']} | {s['wall_h']:.2f} | "
                     f"{'-' if 'control' in algo else paper.get(algo.split(' ')[0].split('-')[0], '-')} |")
    return "\n".join(lines)


VERSION_KEYS = ("torch", "numpy", "gymnasium", "mujoco", "cpu", "cpu_capability")


def version_note(algos: dict) -> str:
    """A line saying which versions and CPUs the rows of one table came from, when they are not all the same
    (older results files record only torch's version)."""
    seen = {}
    for algo, runs in algos.items():
        for r in runs:
            machine = r.get("machine") or {}
            key = ", ".join(f"{k} {machine[k]}" for k in VERSION_KEYS if machine.get(k)) or "no versions recorded"
            seen.setdefault(key, set()).add(algo)
    if len(seen) < 2:
        return ""
    return "Versions differ between these rows: " + "; ".join(f"{key} ({', '.join(sorted(a))})"
                                                                for key, a in seen.items())


def plot_env(env_id: str, algos: dict, path: str, names: Optional[dict] = None) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(8, 4))
    for i, (algo, runs) in enumerate(algos.items()):  # in the order given
        steps = sorted(set.intersection(*[{e["step"] for e in r["evals"]} for r in runs]))  # steps every seed has
        curves = np.array([[{e["step"]: e["mean"] for e in r["evals"]}[s] for s in steps] for r in runs])
        mean, color = curves.mean(0), plt.cm.tab10(i % 10)  # past ten curves the colours repeat, dashed
        ax.plot(steps, mean, color=color, ls="-" if i < 10 else "--",
                label=f"{(names or {}).get(algo, algo)} ({len(runs)} seed{'s' if len(runs) > 1 else ''})")
        if len(runs) > 1:
            se = curves.std(0, ddof=1) / math.sqrt(len(runs))
            ax.fill_between(steps, mean - se, mean + se, color=color, alpha=0.25)
    expert = [r["expert_return"] for runs in algos.values() for r in runs if r.get("expert_return")]
    if expert:
        ax.axhline(np.mean(expert), color="k", ls="--", lw=1, label="expert")
    random_returns = [x for runs in algos.values() for r in runs if (x := random_return_of(r)) is not None]
    if random_returns:
        ax.axhline(np.mean(random_returns), color="k", ls=":", lw=1, label="random actions")
    ax.set(title=env_id, xlabel="env steps", ylabel="evaluation return (mean ± s.e. over seeds)")
    ax.xaxis.set_major_formatter(lambda x, _: f"{x / 1000:g}k")  # 200k, not 200000 running into its neighbour
    ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1))  # beside the axes, off the curves
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


COLUMNS = ("Final return: the last deterministic evaluation of each seed, mean ± standard error over seeds; "
           "normalized: (return - random) / (expert - random), 0 for uniform random actions and 1 for the "
           "demonstrations' mean return (D4RL's convention); IQM: interquartile mean over seeds with a "
           "95% percentile-bootstrap interval (none for one seed); last quarter: the mean of each seed's evaluations "
           "after 3/4 of its steps (its last five of a 200k run; normalized where the IQM is), then mean ± standard "
           "error over seeds; "
           "worst: the lowest of those evaluations over all seeds; steps: env steps, "
           "except bc.py's (gradient steps, no env interaction). Paper: the RILe paper's "
           "MuJoCo table (v2 envs, its own training length).\n")


def trainer_gap(rows: dict) -> str:
    """The line on what RILe's trainer adds where a table holds rile.py's defaults and the control: the difference of
    their last-quarter means (normalized), with a bootstrap interval, and of their finals."""
    if not all(algo in rows for algo in TRAINER_GAP):
        return ""
    runs = [rows[algo] for algo in TRAINER_GAP]
    final = [[normalized_score(r["final_return"], random_return_of(r), r.get("expert_return")) for r in g]
             for g in runs]
    if None in final[0] + final[1]:
        return ""
    quarter = [[last_quarter(r, normalize=True) for r in g] for g in runs]
    ci = difference_ci(*quarter)
    interval = "95% bootstrap interval [{:+.3f}, {:+.3f}]".format(*ci) if ci else "one seed: no interval"
    return (f"What the trainer adds, rile.py defaults minus the control ({len(runs[0])} and {len(runs[1])} seeds): "
            f"last quarter {np.mean(quarter[0]) - np.mean(quarter[1]):+.3f} ({interval}), "
            f"final {np.mean(final[0]) - np.mean(final[1]):+.3f}, normalized.")


# ---------------------------------------------------------------- the paper's experiments (docs/experiments.md)

EXPERIMENTS_PAGE = "docs/experiments.md"
EXPERIMENT_RUN = "--total-timesteps 200000 --threads 1 --checkpoint-freq 10000"  # every experiment's runs: 200k steps
class Method(NamedTuple):
    name: str  # its column
    script: str
    tag: str  # of its default runs
    flags: str  # beyond the script's defaults
    paper: Optional[str]  # its key in the paper's tables (None: not in the paper)


# The methods each experiment compares, by the results-file algo of their default runs.
METHODS = {
    "rile-paperD": Method("rile.py", "rile.py", "paperD", "", "rile"),
    "rile-paperD-control": Method("the control", "rile.py", "paperD-control", "--student-reward discriminator", None),
    "gail-paperD-autotune": Method("gail.py", "gail.py", "paperD-autotune", "", "gail"),
    "airl": Method("airl.py", "airl.py", "", "", "airl"),
}
# Noisy demonstrations: condition -> (the tag it adds to each method's, its flags, its seeds); clean: the default runs.
NOISE = {"clean": ("", "", (1, 2, 3, 4)), "actions 0.5": ("act0.5", "--expert-action-noise 0.5", (1, 2)),
         "actions 1.25": ("act1.25", "--expert-action-noise 1.25", (1, 2)),
         "states 0.5": ("state0.5", "--expert-state-noise 0.5", (1, 2)),
         "actions 1.25 unclipped": ("act1.25-noclip", "--expert-action-noise 1.25 --no-expert-noise-clip", (1,)),
         "clean, D without gradient penalty": ("gp0", "--disc-gp 0", (1,)),
         "actions 1.25, D without gradient penalty": ("gp0-act1.25", "--disc-gp 0 --expert-action-noise 1.25", (1,)),
         "states 0.5, D without gradient penalty": ("gp0-state0.5", "--disc-gp 0 --expert-state-noise 0.5", (1,))}
ONLY = {"actions 1.25 unclipped": ("rile-paperD", "gail-paperD-autotune"),  # conditions that not every method runs
        "clean, D without gradient penalty": ("gail-paperD-autotune",),
        "actions 1.25, D without gradient penalty": ("gail-paperD-autotune",),
        "states 0.5, D without gradient penalty": ("rile-paperD", "rile-paperD-control", "gail-paperD-autotune")}
NOISE_ENVS = {  # env -> (methods, conditions)
    "Hopper-v4": (["rile-paperD", "rile-paperD-control", "gail-paperD-autotune", "airl"], list(NOISE)),
    "HalfCheetah-v4": (["rile-paperD", "rile-paperD-control", "gail-paperD-autotune"], ["clean", "actions 1.25",
                                                                                      "states 0.5"]),
}
# The paper's table "Robustness to different noise levels in the expert demonstrations" (Humanoid-v2, returns), at
# the same noise relative to the action box: its action noise 0.2
# and 0.5 on [-0.4, 0.4] are 0.5 and 1.25 on our [-1, 1]; state noise is absolute (its 0.5).
PAPER_NOISE = {"clean": {"rile": 5928, "gail": 5709, "airl": 5623},
               "actions 0.5": {"rile": 5280, "gail": 5275, "airl": 4869},
               "actions 1.25": {"rile": 5154, "gail": 902, "airl": 4589},
               "states 0.5": {"rile": 5205, "gail": 917, "airl": 4780}}
# Covariate shift on Hopper-v4: a fresh learner against the frozen reward of each method's seed-1 default run, which
# benchmarks/frozen_rewards.py makes (benchmarks/rewards/, and the source run's results file under the tag "source"),
# with noise on the actions it executes.
SHIFT_REWARD = "--reward-from benchmarks/rewards/{env_id}/{algo}__1.pt"
SHIFT = {"source run": ("source", "", (1,)), "no noise": ("shift0", "--student-action-noise 0", (1, 2)),
         "noise 0.5": ("shift0.5", "--student-action-noise 0.5", (1,)),
         "noise 1.25": ("shift1.25", "--student-action-noise 1.25", (1, 2))}
PAPER_SHIFT = {"no noise": {"rile": 5928, "airl": 5623}, "noise 0.5": {"rile": 5201, "airl": 5005},
               "noise 1.25": {"rile": 5196, "airl": 4967}}  # "Robustness to covariate shifts", Humanoid-v2


def condition_algo(method: str, tag: str) -> str:
    """The results-file algo of a method under an experiment's condition: its defaults' algo with the tag added."""
    return f"{method}-{tag}" if tag else method


def sweep_command(method: str, env_id: str, tag: str, flags: str, seeds: str = "1 2") -> str:
    m = METHODS[method]
    tag = "-".join(t for t in (m.tag, tag) if t)
    return " ".join(x for x in (f"python sweep.py --scripts {m.script} --env-ids {env_id} --seeds {seeds}",
                                EXPERIMENT_RUN, f"--tag {tag}" if tag else "", m.flags, flags) if x)


def runs_of(algos: dict, algo: str) -> list:
    """The 200k runs of an algo, by seed (an algo run at several lengths has a row per length)."""
    runs = algos.get(algo) or algos.get(f"{algo} (200k)") or []
    return sorted((r for r in runs if r["evals"][-1]["step"] == 200_000), key=lambda r: r["seed"])


def last_quarter_d(r: dict) -> str:
    """D on the demonstrations / on the student, mean over the last quarter's reward measures ('-' if not measured)."""
    end = r["evals"][-1]["step"]
    rows = [m for m in r.get("reward_measures") or [] if m["step"] > 0.75 * end and m.get("d_demos") is not None]
    mean = lambda key: np.mean([m[key] for m in rows])
    return f"{mean('d_demos'):.2f} / {mean('d_student'):.2f}" if rows else "-"


def reward_paid(r: dict) -> str:
    """What a run's reward paid per step at its last reward measure, on its student's pairs of the last interval / on
    the demonstrations' pairs, then its correlation with the env's reward on the student's pairs, mean over the last
    quarter's measures ('-' if not measured)."""
    measures = [m for m in r.get("reward_measures") or [] if m.get("r_s_demos") is not None]
    if not measures:
        return "-"
    end, last = r["evals"][-1]["step"], measures[-1]
    corr = [m["cpr"] for m in measures if m["step"] > 0.75 * end and m.get("cpr") is not None]
    return f"{last['r_s_student']:.2f} / {last['r_s_demos']:.2f}" + (f", env {np.mean(corr):+.2f}" if corr else "")


def condition_runs(algos: dict, methods: list, conditions: dict) -> dict:
    """{(method, condition): its 200k runs of the condition's seeds}."""
    return {(m, c): [r for r in runs_of(algos, condition_algo(m, tag)) if r["seed"] in seeds]
            for m in methods for c, (tag, _, seeds) in conditions.items()}


def condition_table(title: str, methods: list, conditions: list, scores: dict, baseline: str, paper: dict) -> list:
    """Per condition and method: each seed's last-quarter score, their mean in bold, its fraction of the baseline
    condition's mean, and the paper's fraction at that condition ('not yet run' without results)."""
    lines = [f"| {title} | " + " | ".join(METHODS[m].name for m in methods) + " |", "|---" * (len(methods) + 1) + "|"]
    for c in conditions:
        cells = []
        for m in methods:
            x, base, key = scores[m, c], scores[m, baseline], METHODS[m].paper
            in_paper = key in paper.get(c, {}) and c != baseline
            of_paper = f" (paper {paper[c][key] / paper[baseline][key]:.2f})" if in_paper else ""
            if m not in ONLY.get(c, methods):
                cells.append("-")  # not part of this condition
            elif not x:
                cells.append("not yet run" + of_paper)
            else:
                cell = f"{', '.join(f'{v:.2f}' for v in x)}: **{np.mean(x):.2f}**"
                if conditions.index(c) > conditions.index(baseline) and base:
                    cell += f" = {np.mean(x) / np.mean(base):.2f} of {baseline}{of_paper}"
                cells.append(cell)
        lines.append(f"| {c} | " + " | ".join(cells) + " |")
    return lines


GAP_COLUMNS = "rile.py minus the control: last quarter [95% interval] | the same over the second half"


def trainer_rows(conditions: list, runs: dict) -> list:
    """rile.py minus the control per condition: difference of the last-quarter means and its 95% bootstrap interval
    (none where either has one seed), then the same over the second half (a single fall of one seed moves a
    five-evaluation mean by up to 0.2; where the two disagree, it is when the falls came, not how many)."""
    rows = []
    for c in conditions:
        a, b = (runs[m, c] for m in TRAINER_GAP)
        if a and b:
            cells = []
            for after in (0.75, 0.5):
                x, y = ([last_quarter(r, normalize=True, after=after) for r in rs] for rs in (a, b))
                gap, ci = f"{np.mean(x) - np.mean(y):+.3f}", difference_ci(x, y)
                cells.append(f"{gap} [{ci[0]:+.3f}, {ci[1]:+.3f}]" if ci else f"{gap} (one seed: no interval)")
            rows.append((c, f"{len(a)} and {len(b)} | " + " | ".join(cells)))
    return rows


def figure(png: str, page_dir: str, title: str, methods: list, conditions: list, scores: dict, baseline: str) -> str:
    """The bars (written when a condition beside the baseline has results, else removed) and their markdown link."""
    if not any(scores[m, c] for m in methods for c in conditions if c != baseline):
        if os.path.exists(png):
            os.remove(png)
        return ""
    plot_conditions(title, methods, conditions, scores, png)
    return f"![{title}]({os.path.relpath(png, page_dir)})\n\n"


D_ON_ACTIONS = ("actions D trained on", "the expert's clean actions", "the student's mean action",
                "uniform random actions")


def d_on_actions_table(results_dir: str, env_id: str, methods: list, conditions: list) -> str:
    """What D reads at the end of each noisy run that benchmarks/d_on_actions.py measured (its --out files under
    <env-id>/d-on-actions/): D on the demonstrations' states with each kind of action, on the student's states with
    its own and random actions, and the logit's gradient on action against state columns ('' if none measured)."""
    rows = []
    for c in conditions:
        for m in methods:
            algo = condition_algo(m, NOISE[c][0])
            for seed in NOISE[c][2]:
                path = os.path.join(results_dir, env_id, "d-on-actions", f"{algo}__{seed}.json")
                if not os.path.isfile(path):
                    continue
                with open(path) as f:
                    p = json.load(f)
                demos = " / ".join(f"{p['d'][f'demonstrations: {k}']:.2f}" for k in D_ON_ACTIONS)
                student = " / ".join(f"{p['d'][f'student: {k}']:.2f}" for k in ("its stored actions",
                                                                                "uniform random actions"))
                clean = p["d"]["clean: the expert's clean actions"]
                rows.append(f"| {c} | {METHODS[m].name}, seed {seed} | {p['step'] // 1000}k | {demos} | "
                            f"{clean:.2f} | {student} | {p['grad_action'] / p['grad_state']:.2f} |")
    if not rows:
        return ""
    return ("What D reads at the end of a run (`python benchmarks/d_on_actions.py runs/<run> --out ...`, the command "
            "in each file under `" + f"benchmarks/results/{env_id}/d-on-actions/" + "`): D on the demonstrations' "
            "states with the actions it trained on, with the expert's clean actions, with the student's mean action "
            "and with uniform random actions; on the expert's clean states and actions (under state noise, the states "
            "the student should reach; otherwise the same as clean actions); on the student's newest states with its "
            "own and with random actions; and the mean |gradient| of D's logit on an action column over that on a "
            "state column (0: D ignores actions).\n\n| demonstrations | run | step | D on the demonstrations' states: "
            "their actions / clean / the student's / random | D on the clean demonstrations | D on the student's "
            "states: its actions / random | gradient, action / state |\n|---|---|---|---|---|---|---|\n"
            + "\n".join(rows) + "\n\n")


def noise_section(grouped: dict, results_dir: str, page_dir: str) -> str:
    parts = []
    for env_id, (methods, conditions) in NOISE_ENVS.items():
        algos = grouped.get(env_id, {})
        runs = condition_runs(algos, methods, {c: NOISE[c] for c in conditions})
        scores = {key: [last_quarter(r, normalize=True) for r in rs] for key, rs in runs.items()}
        lines = condition_table("demonstrations", methods, conditions, scores, "clean", PAPER_NOISE)
        gap = [f"| demonstrations | seeds | {GAP_COLUMNS} | "
               + " | ".join(f"{METHODS[m].name}: D on demos / student" for m in methods) + " |",
               "|---" * (len(methods) + 4) + "|"]
        for c, cell in trainer_rows(conditions, runs):
            d = [", ".join(last_quarter_d(r) for r in runs[m, c]) for m in methods]
            gap.append(f"| {c} | {cell} | " + " | ".join(x or "-" for x in d) + " |")
        commands = []
        for c in conditions[1:]:
            tag, flags, seeds = NOISE[c]
            for m in ONLY.get(c, methods):
                command = sweep_command(m, env_id, tag, flags, " ".join(map(str, seeds)))
                commands.append(f"{command}  # {c}, {METHODS[m].name}")
        png = os.path.join(results_dir, f"noise-{env_id}.png")
        parts.append(f"### {env_id}\n\n" + "\n".join(lines) + "\n\n" + "\n".join(gap) + "\n\n"
                     + d_on_actions_table(results_dir, env_id, methods, conditions)
                     + figure(png, page_dir, f"{env_id}: noisy demonstrations", methods, conditions, scores, "clean")
                     + "The commands (the clean row is the default runs of the README's tables):\n\n```bash\n"
                     + "\n".join(commands) + "\n```\n")
    return "\n".join(parts)


def rollout_actor(path: str) -> str:
    """Who an actor of benchmarks/frozen_reward_rollouts.py is: the demonstrator, the source run's student, or a
    fresh student of a covariate-shift condition and seed."""
    if path.startswith("experts/"):
        return "the demonstrator"
    if "source__" in path:
        return "the source run's student"
    found = re.search(r"-(shift[\d.]+)__(\d+)", path)
    condition = {tag: c for c, (tag, _, _) in SHIFT.items()}.get(found and found[1])
    return f"fresh student, {condition}, seed {found[2]}" if condition else path


def frozen_rollouts_table(results_dir: str, env_id: str, methods: list) -> str:
    """Each frozen reward on rollouts of the actors benchmarks/frozen_reward_rollouts.py scored (its --out files under
    <env-id>/frozen-rollouts/<method>.json): env return, falls, and the frozen reward per step and discounted from
    reset, with the mean action / sampled actions ('' if none measured)."""
    rows, commands = [], []
    for m in methods:
        path = os.path.join(results_dir, env_id, "frozen-rollouts", f"{m}.json")
        if not os.path.isfile(path):
            continue
        with open(path) as f:
            p = json.load(f)
        commands.append(p["command"])
        by_actor = {}
        for row in p["rows"]:
            by_actor.setdefault(row["actor"], {})[row["action"]] = row
        for actor, modes in by_actor.items():
            both = lambda key, fmt: " / ".join(format(np.mean(modes[a][key]), fmt) for a in ("mean", "sampled"))
            rows.append(f"| {METHODS[m].name} | {rollout_actor(actor)} | {both('return', '.0f')} | "
                        f"{sum(modes['mean']['terminated'])} / {sum(modes['sampled']['terminated'])} of "
                        f"{p['episodes']} | {both('frozen_per_step', '.3f')} | {both('frozen_discounted', '.1f')} |")
    if not rows:
        return ""
    return (ROLLOUTS_HEAD + "| reward | actor | env return | falls | frozen reward per step | discounted frozen return "
            "|\n|---|---|---|---|---|---|\n" + "\n".join(rows) + "\n\n```bash\n" + "\n".join(commands) + "\n```\n\n")


def shift_section(grouped: dict, results_dir: str, page_dir: str, env_id: str = "Hopper-v4") -> str:
    methods, conditions = list(METHODS), list(SHIFT)
    runs = condition_runs(grouped.get(env_id, {}), methods, SHIFT)
    scores = {key: [last_quarter(r, normalize=True) for r in rs] for key, rs in runs.items()}
    lines = condition_table("student's actions", methods, conditions, scores, "no noise", PAPER_SHIFT)
    gap = [f"| student's actions | seeds | {GAP_COLUMNS} |", "|---|---|---|---|"]
    gap += [f"| {c} | {cell} |" for c, cell in trainer_rows(conditions[1:], runs)]
    paid = ["| student's actions | " + " | ".join(METHODS[m].name for m in methods) + " |",
            "|---" * (len(methods) + 1) + "|"]
    paid += [f"| {c} | " + " | ".join("; ".join(map(reward_paid, runs[m, c])) or "-" for m in methods) + " |"
             for c in conditions]
    commands = []
    for c in conditions[1:]:
        tag, flags, seeds = SHIFT[c]
        for m in methods:
            reward = SHIFT_REWARD.format(env_id=env_id, algo=m)
            command = sweep_command(m, env_id, tag, f"{reward} {flags}", " ".join(map(str, seeds)))
            commands.append(f"{command}  # {c}, {METHODS[m].name}")
    png = os.path.join(results_dir, f"shift-{env_id}.png")
    return (f"### {env_id}\n\n" + "\n".join(lines) + "\n\n" + "\n".join(gap) + "\n\n" + PAID_HEAD
            + "\n".join(paid) + "\n\n" + frozen_rollouts_table(results_dir, env_id, methods)
            + figure(png, page_dir, f"{env_id}: a frozen reward, noisy student actions", methods, conditions[1:],
                     scores, "no noise")
            + "The commands, after `python benchmarks/frozen_rewards.py` (the source row):\n\n```bash\n"
            + "\n".join(commands) + "\n```\n")


# The trainer's design, on Hopper-v4 seed 1: variant -> (tag added to rile.py's, flags, row it is compared with); the
# first row is the default. A tag in SCREENED was run before the experiment, with today's defaults and that flag, into
# SCREENS beside the results folder (rile.py's choice 8): its file is read from there and its command says so.
TRAINER_REWARDS = {"exp-difference (default)": ("", "", "")} | {
    name: (f"tr-{name}", f"--trainer-reward {name}", "") for name in ("difference", "multiplication", "naive",
                                                                      "exp-naive", "sigmoid")}
PAPER_TRAINER_REWARDS = {"exp-difference (default)": "highest final score",
                         "exp-naive": "fastest to converge, plateaus lower"}
STUDENT_ZERO = "none in the student's batches, 0.1 of the trainer's (defaults)"
TRAINER_ZERO = "0 of the trainer's batches"
EXPERT_DATA = {STUDENT_ZERO: ("", "", "")} | {
    f"{f} of the student's batches": (f"sef{f}", f"--student-expert-fraction {f}", STUDENT_ZERO)
    for f in (0.25, 0.5, 1.0)} | {TRAINER_ZERO: ("tef0", "--trainer-expert-fraction 0", "")} | {
    f"{f} of the trainer's batches": (f"tef{f}", f"--trainer-expert-fraction {f}", TRAINER_ZERO) for f in (0.5, 1.0)}
SCREENED, SCREENS = ("tef0",), "screens"


def first_at(r: dict, level: float = 0.8) -> Optional[int]:
    """The first evaluation step whose normalized score is at or above `level` (the paper's convergence measure)."""
    return next((e["step"] for e in r["evals"]
                 if (normalized_score(e["mean"], random_return_of(r), r.get("expert_return")) or 0) >= level), None)


def variants_section(grouped: dict, results_dir: str, page_dir: str, variants: dict, name: str,
                     paper: Optional[dict] = None, env_id: str = "Hopper-v4") -> str:
    """One row per variant of rile.py's defaults, seed 1: its final score, that score as a fraction of the row it is
    compared with (or, where a variant names none, of the best final score), its last quarter, its first evaluation
    at 0.8 or above and that step as a fraction of the compared row's; 'not yet run' and the command where no results
    file exists; the learning curves of the variants that ran."""
    screens = os.path.join(os.path.dirname(os.path.abspath(results_dir)), SCREENS)
    runs, commands = {}, {}
    for variant, (tag, flags, _) in variants.items():
        algos = load_results(screens)[0].get(env_id, {}) if tag in SCREENED else grouped.get(env_id, {})
        runs[variant] = [r for r in runs_of(algos, condition_algo("rile-paperD", tag)) if r["seed"] == 1][:1]
        commands[variant] = sweep_command("rile-paperD", env_id, tag, flags, "1") + (
            f" --results-dir {os.path.relpath(os.path.join(os.path.dirname(RESULTS_DIR), SCREENS), ROOT)}"
            if tag in SCREENED else "")
    final = {v: normalized_score(rs[0]["final_return"], random_return_of(rs[0]), rs[0].get("expert_return"))
             for v, rs in runs.items() if rs}
    first = {v: first_at(rs[0]) for v, rs in runs.items() if rs}
    best = max(final.values(), default=None)
    ratio = lambda x, y: f"{x / y:.2f}" if x is not None and y else "-"
    lines = [f"| variant | final, normalized | final, of {'the compared row' if paper is None else 'the best'} | "
             "last quarter | first evaluation at 0.8 or above | "
             + ("that step, of the compared row's | " if paper is None else "the paper | ") + "command |",
             "|---|---|---|---|---|---|---|"]
    for variant, (_, _, against) in variants.items():
        paper_cell = (paper or {}).get(variant, "")
        if variant not in final:
            lines.append(f"| {variant} | not yet run | | | | {paper_cell} | `{commands[variant]}` |")
            continue
        step = first[variant]
        if paper is not None:  # the ablation: a fraction of the best final score, the paper's words beside
            of, last = ratio(final[variant], best), paper_cell or "-"
        else:  # expert data: fractions of the compared row's final score and of its convergence step
            of = ratio(final[variant], final.get(against)) if against else "-"
            last = ratio(step, first.get(against)) if against else "-"
        quarter = last_quarter(runs[variant][0], normalize=True)
        lines.append(f"| {variant} | {final[variant]:.2f} | {of} | {quarter:.2f} | "
                     f"{f'{step // 1000}k' if step else 'never'} | {last} | `{commands[variant]}` |")
    ran = {v: rs for v, rs in runs.items() if rs}
    png = os.path.join(results_dir, f"{name}-{env_id}.png")
    if len(ran) > 1:
        plot_env(f"{env_id}, seed 1", ran, png)
        lines.append(f"\n![{env_id}: {name}]({os.path.relpath(png, page_dir)})")
    elif os.path.exists(png):
        os.remove(png)
    return "\n".join(lines) + "\n"


EXPERIMENTS_HEAD = """# The RILe paper's experiments

Generated by `python sweep.py --report` from the results files in `benchmarks/results/`; do not edit by hand. Each
experiment runs rile.py beside the control that rewards the same student with v(D) = 2D - 1 directly, with no trainer
(`--student-reward discriminator`), and beside gail.py and airl.py where the paper has them, for 200k env steps.
Scores are normalized (uniform random actions 0, the demonstrations' mean return 1). "Last quarter" is the mean of a
run's evaluations after 150k steps (its last five). Each results file holds the exact command that made it; the
commands below are the sweeps that make or continue them (`python sweep.py --status ...` shows what is done).
"""

NOISE_HEAD = """## Noisy demonstrations

The paper adds zero-mean Gaussian noise to the expert's actions or states (Humanoid-v2, one seed) and reports RILe
keeping 0.87-0.89 of its clean return, GAIL 0.16 at the heavy level and AIRL 0.82-0.87. Here the noise is drawn once
per run from `--seed` (one fixed noisy demonstrator, not fresh noise per batch), on the actions with
`--expert-action-noise` (clipped to the action box) or on the observations and next observations with
`--expert-state-noise`, and every consumer of the demonstrations sees the noisy pairs. The paper's action noise 0.2
and 0.5 on Humanoid's [-0.4, 0.4] box are 0.5 and 1.25 on the [-1, 1] boxes here; state noise has no box and keeps
the paper's 0.5. The clean row is the default runs (four seeds; airl.py two). Each cell: the last-quarter score of
each seed, their mean in bold, that mean as a fraction of the method's clean mean, and the paper's Humanoid fraction
at the same level (of returns; Humanoid's random-action return is small beside its expert's). The second table:
what the trainer adds under each condition, over the last quarter and over the second half (evaluations after 100k:
with two seeds, one fall of a hopper to 0.1-0.3 moves a last quarter by up to 0.2, so where the two columns disagree
the difference is in when the falls came), and whether D saturates (D near 1 on the demonstrations and near 0 on the
student leaves little to learn from), as the mean over the last quarter of the reward measures taken every 10k steps.
The paper does not say whether its noisy actions stayed in the box; unclipped ones outside it would let D tell the
demonstrations from any policy at once, so the row "actions 1.25 unclipped" runs rile.py and gail.py (seed 1) with
`--no-expert-noise-clip`. gail.py's D has the paper's gradient penalty (weight 1, one-centred); the rows "D
without gradient penalty" (`--disc-gp 0`, seed 1, their fractions of the clean runs with the penalty), on clean, on
action-noisy and on state-noisy demonstrations, test whether the penalty is what keeps gail.py's D from the
confidence that would collapse its student, and whether dropping it costs under noise more than on clean
demonstrations; on state-noisy demonstrations, where gail.py without it collapsed, rile.py and the control run
without it too, to see whether the trainer holds where v(D) does not. Other levels, or iqlearn.py and bc.py (which
take no noise flags), are not run: the same sweep with another `--expert-action-noise`/`--expert-state-noise` and
`--tag` adds them. What the discriminator did with the
noisy demonstrations, over training: [noisy-demonstrations.md](noisy-demonstrations.md).
"""

SHIFT_HEAD = """## Covariate shift: a frozen reward, a fresh student with noisy actions

The paper trains in the clean env, freezes the learned reward, then trains a fresh student against it with Gaussian
noise on the actions it executes (Humanoid-v2: RILe keeps 0.88 of its no-noise score at both levels, AIRL 0.89 and
0.88). rile.py, gail.py and airl.py do it with `--reward-from runs/<run>/reward.pt --student-action-noise <std>`:
the reward a finished run of the same script saved, its networks frozen, nothing but the fresh learner learning; the
env executes, and the buffer stores, the noisy action (clipped to the box); evaluations run without noise. The frozen
rewards come from each method's seed-1 default run on Hopper-v4, run again by `python benchmarks/frozen_rewards.py`
(first: the commands below read its files), which writes them to `benchmarks/rewards/` with the run and commit
behind each, and the source runs' results files under the tag `source`: rile.py's trainer, the control's D (r_S =
v(D)), gail.py's D (its softplus reward), and airl.py's g, h and level with `--reward softplus`, the reward its own
agent learned from (`--reward g`: g alone, AIRL's transfer, not run). The noise 0.5 and 1.25 are the paper's 0.2 and
0.5 on Humanoid's [-0.4, 0.4] box. Each cell as above, as a fraction of the method's no-noise score; the source row
is the run each reward came from.
"""

PAID_HEAD = """What each reward paid per step at the end of the run (its last measure, at 200k): on the student's
pairs of the last 10k steps / on the demonstrations' pairs, then its correlation with the env's reward on the student's
pairs (mean over the last quarter), one entry per seed. The source row is the reward while it was learned, the others
the same reward frozen. A fresh student that earns per step what the source's student earned has got from the frozen
reward what its source got; if it scores lower all the same, the reward pays its gait as well as the expert-like one,
and it is the reward, not the student, that did not transfer.

"""

ROLLOUTS_HEAD = """Each frozen reward on whole episodes of the demonstrator, of the source run's student and of fresh
students (`benchmarks/frozen_reward_rollouts.py`, the command below the table; the same reset seeds for every actor),
each cell with the mean action / with sampled actions, which the students trained on: the env return, the falls, the
frozen reward per step, and the frozen return discounted from the reset state with the student's gamma (where the run
used absorbing states, a fall then pays the absorbing state's reward forever). A reward that transfers pays these
actors in the env's order. A fresh student paid more than the source run's student while the env pays it less has
found a gait the reward overpays; one paid less has not climbed the reward as far as the source's student did.

"""

TRAINER_HEAD = """## The six trainer rewards

The paper's ablation of the trainer's reward (its figure "Trainer-Discriminator Relation"); `--trainer-reward`,
Hopper-v4 seed 1. The first evaluation at or above 0.8 is the paper's convergence measure. The paper: "exponential naive
converges faster but plateaus at a lower final reward, whereas exponential difference yields the highest
performance". What the formulas predict before any run (naive and exp-naive give the student nothing D says; sigmoid a
small reward rising with D; the others about v(D)):
[rile.md](rile.md#the-six-trainer-rewards-what-the-formulas-predict).
"""

EXPERT_DATA_HEAD = """## Expert data in the buffers

The paper replaces a share of the student's or the trainer's batches with expert pairs (its figure "Explicit Usage of
Expert Data"): `--student-expert-fraction`, `--trainer-expert-fraction`; Hopper-v4 seed 1. The paper: more expert data
speeds convergence but lowers the final score, and with only expert data the student drops markedly; 0 % scored
highest. Today's default already puts 0.1 expert pairs in the trainer's batches (rile.py's header, choice 8); the row
with none there is the screening run behind that choice (benchmarks/screens/, today's defaults, an earlier commit of
rile.py than this experiment's runs: its results file names it). Each student row is compared with the defaults, each
trainer row with that run: its final score and its first evaluation at 0.8 or above as fractions of theirs (the
paper's measures, normalized by the 0 % run).
"""


def experiments_text(grouped: dict, results_dir: str, page_dir: str) -> str:
    sections = [EXPERIMENTS_HEAD, NOISE_HEAD, noise_section(grouped, results_dir, page_dir), SHIFT_HEAD,
                shift_section(grouped, results_dir, page_dir), TRAINER_HEAD,
                variants_section(grouped, results_dir, page_dir, TRAINER_REWARDS, "trainer-rewards",
                                 PAPER_TRAINER_REWARDS), EXPERT_DATA_HEAD,
                variants_section(grouped, results_dir, page_dir, EXPERT_DATA, "expert-data")]
    return "\n".join(sections)


def plot_conditions(title: str, methods: list, conditions: list, scores: dict, path: str) -> None:
    """Bars: each method's mean last-quarter score per condition, its seeds as dots."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(8, 3.5))
    width = 0.8 / len(conditions)
    for j, c in enumerate(conditions):
        offset = (j - (len(conditions) - 1) / 2) * width
        xs = [(i + offset, scores[m, c]) for i, m in enumerate(methods) if scores[m, c]]
        if not xs:
            continue  # not run yet: no bars, no legend entry
        ax.bar([x for x, _ in xs], [np.mean(y) for _, y in xs], width, color=plt.cm.tab10(j), label=c)
        for x, y in xs:
            ax.plot([x] * len(y), y, "k.", ms=4)
    ax.set_xticks(range(len(methods)), [METHODS[m].name for m in methods])
    ax.axhline(1.0, color="k", ls="--", lw=1)
    ax.set(title=f"{title}, 200k steps", ylabel="last quarter, normalized")
    ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1))
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def all_tags_text(grouped: dict, bad: list, results_dir: str, page_dir: str) -> str:
    """Every tag of every env, today's defaults named as well; image links relative to page_dir."""
    parts = []
    for env_id, algos in grouped.items():
        names = {algo: f"{algo} ({default_name(algo)})" for algo in algos if default_name(algo)}
        png = os.path.relpath(os.path.join(results_dir, f"{env_id}-all.png"), page_dir)
        note = version_note(algos)
        parts.append(f"### {env_id}\n\n{env_table(env_id, algos, names)}\n\n" + (f"{note}\n\n" if note else "")
                     + f"![{env_id} learning curves, every tag]({png})\n")
    text = ("\n".join(parts) or "No results yet.\n") + "\n" + COLUMNS
    if bad:
        text += "\nResults files skipped:\n" + "".join(f"- {b}\n" for b in bad)
    return text


def defaults_text(grouped: dict, results_dir: str, page_dir: str) -> str:
    """The README's section: today's defaults only (DEFAULT_ROWS), by their row names; links relative to page_dir."""
    parts = []
    for env_id, algos in grouped.items():
        rows = default_rows(algos)
        if not rows:
            continue
        names = {algo: default_name(algo) for algo in rows}
        png = os.path.relpath(os.path.join(results_dir, f"{env_id}.png"), page_dir)
        lines = [ENV_NOTES.get(env_id, ""), trainer_gap(rows),
                 SELECTION_NOTE if any(algo in rows for algo in SELECTED) else "",
                 f"Learning curves: [{env_id}.png]({png})."]
        parts.append(f"### {env_id}\n\n{env_table(env_id, rows, names)}\n\n" + "".join(f"{x}\n" for x in lines if x))
    return (("\n".join(parts) or "No results with today's defaults yet.\n") + "\n" + COLUMNS
            + "\nEvery other configuration that was run, and the versions and CPUs behind each row: "
            f"[{DOCS_PAGE}]({DOCS_PAGE}).\n")


DOCS_HEAD = ("# Results of every configuration run\n\n"
             "Generated by `python sweep.py --report` from `benchmarks/results/`; do not edit by hand. Rows are named "
             "by their results files, `<script>-<tag>`: each file holds the command that made it and every flag "
             "(`config`). Rows of today's defaults carry their README name in parentheses; the README shows only "
             "those. Other tags ran earlier defaults or variants; how the defaults came to be: "
             "[history.md](history.md).\n\n")


def report(results_dir: str = RESULTS_DIR, readme: Optional[str] = os.path.join(ROOT, "README.md")) -> str:
    """Tables and learning curves of every results file. results_dir/REPORT.md and, beside the README,
    docs/results.md show every tag (curves in <env-id>-all.png); the README's section between its markers shows
    today's defaults only (DEFAULT_ROWS, curves in <env-id>.png). Returns REPORT.md's text."""
    grouped, bad = load_results(results_dir)
    for env_id, algos in grouped.items():
        plot_env(env_id, algos, os.path.join(results_dir, f"{env_id}-all.png"))
        rows, png = default_rows(algos), os.path.join(results_dir, f"{env_id}.png")
        if rows:
            plot_env(env_id, rows, png, {algo: default_name(algo) for algo in rows})
        elif os.path.exists(png):
            os.remove(png)  # a curve of defaults that are no longer listed
    for b in bad:
        print(f"warning: skipped {b}", file=sys.stderr)
    text = all_tags_text(grouped, bad, results_dir, results_dir)
    with open(os.path.join(results_dir, "REPORT.md"), "w") as f:
        f.write(text)
    if readme and os.path.exists(readme):
        readme_dir = os.path.dirname(os.path.abspath(readme))
        docs_page = os.path.join(readme_dir, DOCS_PAGE)
        os.makedirs(os.path.dirname(docs_page), exist_ok=True)
        with open(docs_page, "w") as f:
            f.write(DOCS_HEAD + all_tags_text(grouped, bad, results_dir, os.path.dirname(docs_page)))
        experiments_page = os.path.join(readme_dir, EXPERIMENTS_PAGE)
        with open(experiments_page, "w") as f:
            f.write(experiments_text(grouped, results_dir, os.path.dirname(experiments_page)))
        content = open(readme).read()
        if README_START in content and README_END in content:
            head, rest = content.split(README_START, 1)
            section = defaults_text(grouped, results_dir, readme_dir)
            content = head + README_START + "\n" + section + rest[rest.index(README_END):]
            with open(readme, "w") as f:
                f.write(content)
    return text


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--scripts", nargs="+", default=["expert.py"], help="the scripts to run")
    parser.add_argument("--env-ids", nargs="+", default=["Hopper-v4"])
    parser.add_argument("--seeds", nargs="+", type=int, default=[1, 2, 3])
    parser.add_argument("--total-timesteps", type=int, default=200_000)
    parser.add_argument("--tag", default="", help="names a variant (its extra args) so its results stay apart")
    parser.add_argument("--workers", type=int, default=1, help="jobs at once on this machine")
    parser.add_argument("--launcher", choices=["local", "slurm", "submitit-local"], default="local")
    parser.add_argument("--partition", default=None, help="Slurm partition")
    parser.add_argument("--time", type=int, default=24 * 60, help="Slurm time limit per job, minutes")
    parser.add_argument("--cpus", type=int, default=2, help="Slurm CPUs per job")
    parser.add_argument("--gpus", type=int, default=0, help="Slurm GPUs per job (pass --cuda through as well)")
    parser.add_argument("--wait", action=argparse.BooleanOptionalAction, default=True,
                        help="with a submitit launcher, wait for the jobs and collect their results")
    parser.add_argument("--status", action="store_true", help="show the sweep's jobs and exit")
    parser.add_argument("--report", action="store_true",
                        help="write tables and curves: today's defaults in the README, every tag in docs/results.md, "
                        "the paper's experiments in docs/experiments.md")
    parser.add_argument("--results-dir", default=RESULTS_DIR)
    args, extra = parser.parse_known_args(argv)
    if args.report:
        print(report(args.results_dir))
        return
    for script in args.scripts:
        if not os.path.exists(os.path.join(ROOT, script)):
            parser.error(f"no script '{script}' in {ROOT}")
    jobs = [Job(s, e, seed, args.total_timesteps, extra, args.tag)
            for s in args.scripts for e in args.env_ids for seed in args.seeds]
    if args.status:
        print_status(jobs, args.results_dir)
        return
    start = time.time()
    run_sweep(jobs, args)
    print_status(jobs, args.results_dir)
    print(f"sweep took {(time.time() - start) / 60:.1f} min; `python sweep.py --report` for tables and curves")


if __name__ == "__main__":
    main()
