"""Behavioural cloning of the SAC actor on the expert's (state, action) pairs.

Reference: Pomerleau, "Efficient Training of Artificial Neural Networks for Autonomous Navigation", 1991,
https://doi.org/10.1162/neco.1991.3.1.88; the squashed-Gaussian likelihood form follows the SAC-actor BC of
https://github.com/Kaixhin/imitation-learning.

Supervised learning of pi(a|s) on demonstrations, with no environment interaction while learning:
the budget is a number of gradient steps, not env steps. The actor is the project's SAC actor (the
shared `actor` block), so its saved actor.pt is a valid warm start for every other script and can
record demonstrations with `expert.py --record-from`.

Implementation choices and deviations
1. `--loss mse` (default): ||tanh(mean) - a_E||^2 in env units, on the action that is evaluated. `--loss nll`:
   -log pi(a_E|s) of the squashed Gaussian (a_E clamped inside the box; trains log std too: a SAC warm start).
2. Held-out split: the last `--holdout-fraction` (10%) of the selected episodes, whole episodes (a random split
   would leak near-duplicate neighbours); with a single episode, its last 10% of transitions.
3. Early stopping by selection: at every evaluation the held-out loss and the held-out squared error of tanh(mean)
   are logged, and the actor with the lowest such error is saved as actor_best.pt; actor.pt is the final one.
4. The deterministic policy is evaluated in the env every `--eval-freq` gradient steps; results.json's "step"
   counts gradient steps, and each evaluation holds its "holdout_loss" and "holdout_mse".
5. Checkpoints every `--checkpoint-freq` gradient steps, on Ctrl-C / SIGTERM and at the end (`--resume runs/<run>`);
   no env is stepped while learning, so a resumed run goes on exactly as one that never stopped.

Logged metrics: losses/{train,holdout,holdout_mse}, eval/{return,normalized_return}, charts/SPS (gradient steps per
second). Details: docs/baselines.md
"""

import glob
import json
import os
import platform
import random
import shutil
import signal
import subprocess
import sys
import time
from dataclasses import asdict, dataclass, fields, replace
from importlib import metadata
from typing import Annotated, Literal, Optional

import gymnasium as gym
import numpy as np
import torch
import torch.nn as nn
import torch.nn.functional as F
import tyro


@dataclass
class Args:
    """Behavioural cloning: the SAC actor learns the expert's actions from its states by supervised learning, with no
    environment interaction, for a budget of gradient steps (--total-timesteps). Start it
    with `python bc.py --env-id Hopper-v4`."""
    exp_name: str = "bc"
    """the name of this experiment"""
    seed: int = 1
    """seed of the experiment (python, numpy, torch, env resets, action space)"""
    torch_deterministic: bool = True
    """sets `torch.backends.cudnn.deterministic`"""
    cuda: bool = False
    """train on the GPU if one is available"""
    track: bool = False
    """mirror the TensorBoard logs to Weights & Biases"""
    wandb_project_name: str = "rile"
    """the W&B project name"""
    wandb_entity: Optional[str] = None
    """the W&B entity (team)"""
    capture_video: bool = False
    """record a video of one deterministic episode at the end (needs `pip install moviepy`)"""
    save_model: bool = True
    """save the final actor (actor.pt) and the best held-out one (actor_best.pt)"""
    run_name: Annotated[Optional[str], tyro.conf.arg(
        help_behavior_hint="(default: {env_id}__{exp_name}__{seed}__{unix_time})")] = None
    """the run directory under runs/"""
    resume: Optional[str] = None
    """continue this run (directory or checkpoint) on its config; --total-timesteps, --cuda, --threads may change"""
    checkpoint_freq: int = 50_000
    """write a resumable checkpoint every this many gradient steps (and on Ctrl-C / SIGTERM); 0 disables"""
    threads: int = 2
    """torch intra-op threads on the CPU"""

    # Algorithm specific arguments
    env_id: str = "Hopper-v4"
    """the id of the gymnasium environment"""
    total_timesteps: int = 100_000
    """gradient steps of training (named like the other scripts' budget so sweep.py can pass it)"""
    batch_size: int = 256
    """expert pairs per gradient step"""
    learning_rate: float = 3e-4
    """Adam learning rate"""
    hidden_dim: int = 256
    """width of the actor's two hidden layers"""
    loss: Literal["nll", "mse"] = "mse"
    """mse: ||tanh(mean) - a_E||^2; nll: -log pi(a_E|s) of the squashed Gaussian (trains log std as well)"""
    holdout_fraction: float = 0.1
    """share of the expert episodes held out for the held-out loss"""
    eval_freq: int = 5_000
    """evaluate in the env every this many gradient steps"""
    eval_episodes: int = 10
    """episodes per evaluation"""

    # Imitation arguments
    expert_path: Annotated[Optional[str], tyro.conf.arg(help_behavior_hint="(default: experts/<env-id>.npz)")] = None
    """the demonstrations file"""
    num_expert_trajs: int = 25
    """use the first this many demonstration episodes"""


# ALGO LOGIC: the BC loss and the held-out split
def bc_loss(actor: "Actor", obs, actions, kind: str):
    """Mean -log pi(a_E|s) (actions clamped inside the box) or mean squared error of tanh(mean)."""
    if kind == "nll":
        return -actor.log_prob(obs, actions).mean()
    if kind == "mse":
        return (actor.deterministic(obs) - actions).pow(2).sum(-1).mean()
    raise ValueError(f"unknown loss '{kind}'; choose nll or mse")


def holdout_split(demos: dict, fraction: float):
    """Row indices (train, held out): the last whole episodes, or the last transitions of a single one."""
    starts, lengths = demos["episode_starts"], demos["episode_lengths"]
    n = int(lengths.sum())
    if len(lengths) >= 2:
        k = max(1, int(round(fraction * len(lengths))))
        cut = int(starts[len(lengths) - k])
    else:
        cut = n - max(1, int(round(fraction * n)))
    return np.arange(cut), np.arange(cut, n)


# --- shared: env ---
def make_env(env_id: str, seed: int, render_mode: Optional[str] = None) -> gym.Env:
    """One seeded gymnasium env (no vector env: episodes are reset explicitly), or a one-line error."""
    try:
        env = gym.make(env_id, render_mode=render_mode)
    except gym.error.Error as e:
        raise SystemExit(f"error: cannot make environment '{env_id}' ({e}); check --env-id") from None
    if not isinstance(env.action_space, gym.spaces.Box) or not isinstance(env.observation_space, gym.spaces.Box):
        raise SystemExit(f"error: '{env_id}' needs Box observation and action spaces")
    env.action_space.seed(seed)
    return gym.wrappers.RecordEpisodeStatistics(env)


def seed_everything(seed: int, torch_deterministic: bool = True) -> None:
    random.seed(seed), np.random.seed(seed), torch.manual_seed(seed)
    torch.backends.cudnn.deterministic = torch_deterministic
# --- end shared: env ---


# --- shared: actor ---
LOG_STD_MIN, LOG_STD_MAX = -5, 2


class Actor(nn.Module):
    """tanh-squashed Gaussian policy, actions scaled from [-1, 1] into the env's action box. Its log pi writes
    log(1 - tanh(u)^2) as 2 (log 2 - u - softplus(-2u)): exact, and finite at the bounds."""

    def __init__(self, obs_dim: int, act_dim: int, action_low, action_high, hidden_dim: int = 256):
        super().__init__()
        self.net = nn.Sequential(nn.Linear(obs_dim, hidden_dim), nn.ReLU(), nn.Linear(hidden_dim, hidden_dim),
                                 nn.ReLU())
        self.fc_mean, self.fc_logstd = nn.Linear(hidden_dim, act_dim), nn.Linear(hidden_dim, act_dim)
        low, high = torch.as_tensor(action_low, dtype=torch.float32), torch.as_tensor(action_high, dtype=torch.float32)
        self.register_buffer("action_scale", (high - low) / 2.0)
        self.register_buffer("action_bias", (high + low) / 2.0)

    def forward(self, obs):
        h = self.net(obs)
        log_std = LOG_STD_MIN + 0.5 * (LOG_STD_MAX - LOG_STD_MIN) * (torch.tanh(self.fc_logstd(h)) + 1)
        return self.fc_mean(h), log_std

    def _log_prob(self, u, noise, log_std):  # log pi(a|s) for a = tanh(u) * scale + bias, u = mean + std * noise
        gauss = -0.5 * noise.pow(2) - log_std - 0.5 * np.log(2 * np.pi)
        squash = 2.0 * (np.log(2.0) - u - F.softplus(-2.0 * u)) + torch.log(self.action_scale)
        return (gauss - squash).sum(-1)

    def sample(self, obs):
        """A reparameterised action in env units and its log-probability."""
        mean, log_std = self(obs)
        noise = torch.randn_like(mean)
        u = mean + log_std.exp() * noise
        return torch.tanh(u) * self.action_scale + self.action_bias, self._log_prob(u, noise, log_std)

    def log_prob(self, obs, action, eps: float = 1e-6):
        """log pi(action|obs) of given env-unit actions (e.g. expert actions), clamped inside the box."""
        mean, log_std = self(obs)
        u = torch.atanh(((action - self.action_bias) / self.action_scale).clamp(-1 + eps, 1 - eps))
        return self._log_prob(u, (u - mean) / log_std.exp(), log_std)

    def deterministic(self, obs):
        return torch.tanh(self(obs)[0]) * self.action_scale + self.action_bias

    @torch.no_grad()
    def act(self, obs: np.ndarray, deterministic: bool = False) -> np.ndarray:
        """The action for one env step: sampled, or the mean action (evaluation)."""
        obs = torch.as_tensor(obs, dtype=torch.float32, device=self.action_scale.device).unsqueeze(0)
        return (self.deterministic(obs) if deterministic else self.sample(obs)[0])[0].cpu().numpy()


def actor_file(actor: Actor, env_id: str, **extra) -> dict:
    """What actor.pt holds: the actor and what rebuilds it (`expert.py --record-from` reads any script's)."""
    return {"actor": actor.state_dict(), "env_id": env_id, "obs_dim": actor.net[0].in_features,
            "act_dim": actor.fc_mean.out_features, "hidden_dim": actor.fc_mean.in_features, **extra}
# --- end shared: actor ---


# --- shared: demonstrations ---
DEMO_KEYS = ("observations", "next_observations", "rewards", "terminations", "truncations", "episode_starts",
             "episode_lengths", "episode_returns")  # and "actions", except in state-only files


def load_demonstrations(path: str, env: gym.Env, num_trajs: Optional[int] = None, state_only: bool = False) -> dict:
    """experts/<env-id>.npz (format in README), checked against `env`, cut to its first `num_trajs` episodes.
    With `state_only` the actions are dropped (a file without them loads). Each problem is one SystemExit line."""
    env_id, obs_dim, act_dim = env.spec.id, env.observation_space.shape[0], env.action_space.shape[0]

    def fail(problem: str, fix: str = f"record them with `python expert.py --env-id {env_id}` (hours on a CPU)"):
        raise SystemExit(f"error: demonstrations '{path}' {problem}; {fix}")

    if not os.path.isfile(path):
        fail(f"do not exist (experts/ has {sorted(n[:-4] for n in glob.glob('*.npz', root_dir='experts'))})")
    try:
        with np.load(path, allow_pickle=False) as f:
            data = {k: f[k] for k in f.files}
        meta = json.loads(str(data.pop("metadata"))) if "metadata" in data else None
    except Exception as e:
        fail(f"are unreadable or corrupt ({type(e).__name__}: {e})")
    if meta is None:
        fail("are not in this project's format (no metadata)", f"convert them with `python demos.py convert {path} "
             f"--env-id {env_id}`")
    if missing := [k for k in DEMO_KEYS if k not in data]:
        fail(f"lack {missing}")
    if state_only:
        data.pop("actions", None)  # never seen by a state-only method
    elif "actions" not in data:
        fail("hold states only, and this method needs actions", "record them with actions, or use a method that "
             "imitates from states (--state-only, or the README's state-only scripts)")
    if meta.get("env_id") != env_id:
        fail(f"were recorded on {meta.get('env_id')}, not {env_id}", f"pass the file for {env_id} with --expert-path")
    act_shape = data["actions"].shape[1:] if "actions" in data else (act_dim,)
    if data["observations"].shape[1:] != (obs_dim,) or act_shape != (act_dim,):
        fail(f"have obs/act dims {data['observations'].shape[1:]}/{act_shape}, {env_id} has ({obs_dim},)/({act_dim},)",
             f"pass the file for {env_id} with --expert-path")
    if num_trajs is not None:
        if not 1 <= num_trajs <= len(data["episode_lengths"]):
            fail(f"hold {len(data['episode_lengths'])} episodes, fewer than --num-expert-trajs {num_trajs}",
                 "pass a smaller --num-expert-trajs")
        end = int(data["episode_starts"][num_trajs - 1] + data["episode_lengths"][num_trajs - 1])
        data |= {k: data[k][: num_trajs if k.startswith("episode_") else end]
                 for k in (*DEMO_KEYS, "actions") if k in data}
    if "random_return" not in meta:  # older files: measured now (`demos.py info --add-random-return` stores it)
        meta["random_return"] = random_return(env_id)
        print(f"{path}: no random-policy return in its metadata; uniform actions return {meta['random_return']:.1f}")
    return data | {"metadata": meta}
# --- end shared: demonstrations ---


# --- shared: evaluation ---
def evaluate(act, env_id: str, num_episodes: int, seed: int, capture_video_dir: Optional[str] = None) -> list:
    """Returns of the deterministic policy on its own env, episode i from reset(seed=seed + i): the same starts."""
    env = make_env(env_id, seed, render_mode="rgb_array" if capture_video_dir else None)
    if capture_video_dir:
        env = gym.wrappers.RecordVideo(env, capture_video_dir, episode_trigger=lambda ep: ep == 0, disable_logger=True)
    returns = []
    for i in range(num_episodes):
        obs, _ = env.reset(seed=seed + i)
        done, ep_return = False, 0.0
        while not done:
            obs, reward, terminated, truncated, _ = env.step(act(obs, deterministic=True))
            ep_return, done = ep_return + float(reward), terminated or truncated
        returns.append(ep_return)
    env.close()
    return returns


def random_return(env_id: str, num_episodes: int = 10, seed: int = 100_000) -> float:
    """The mean return of uniform random actions under `evaluate`'s protocol: where a normalized score reads 0."""
    space = make_env(env_id, seed).action_space
    return float(np.mean(evaluate(lambda obs, deterministic: space.sample(), env_id, num_episodes, seed)))


def normalized_score(ret: float, random: Optional[float], expert: Optional[float]) -> Optional[float]:
    """(R - R_random) / (R_expert - R_random), D4RL's: 0 random, 1 the demonstrations; None if unknown or not above."""
    return (ret - random) / (expert - random) if random is not None and expert is not None and expert > random else None
# --- end shared: evaluation ---


# --- shared: run ---
class Run:
    """The run's directory (config.json, TensorBoard, results.json with `extra`), evaluations, its `Checkpoints`."""

    def __init__(self, args, checkpoint: Optional[dict], stateful: dict, demos: Optional[dict], device,
                 checkpoint_freq: int = 0, learning_starts: int = 0):
        self.args, self.extra, self.evals, self.start_step, self.sps = args, {}, [], 0, None
        returns = demos["episode_returns"] if demos else np.array([np.nan])  # the normalized score's 1 (random's: 0)
        self.expert_return = float(returns.mean()) if np.isfinite(returns.mean()) else None
        self.random_return = demos["metadata"]["random_return"] if demos else None
        self.name = checkpoint["run_name"] if checkpoint else args.run_name or \
            f"{args.env_id}__{args.exp_name}__{args.seed}__{int(time.time())}"
        self.dir = os.path.join("runs", self.name)
        os.makedirs(self.dir, exist_ok=True)
        save_file(os.path.join(self.dir, "config.json"), asdict(args))
        self.writer, self.machine = tensorboard(args, self.name, self.dir), machine(device)
        self.start_time = time.time()  # time.time() - start_time: the run's wall time (a resumed run's included)
        self.checkpoints = Checkpoints(self, stateful, checkpoint_freq, checkpoint, device)
        self.shown, self.tty, self.marks, self.learning_starts = 0.0, sys.stdout.isatty(), [], learning_starts
        expert = f"{len(returns)} demonstration episodes, return {returns.mean():.1f} | " if demos else ""
        print(f"{'resumed ' * bool(checkpoint)}{self.dir} at step {self.start_step} of {args.total_timesteps} | "
              f"{args.env_id} | {expert}{device}, threads {torch.get_num_threads()}", flush=True)

    def log(self, metrics: dict, step: int) -> None:
        for name, value in metrics.items():
            if value is not None:  # not measured
                self.writer.add_scalar(name, float(value), step)

    def end_step(self, step: int, act) -> None:
        """After env step `step` (counted from 1): an evaluation every --eval-freq steps, a checkpoint when due."""
        now, evaluation = time.perf_counter(), step % self.args.eval_freq == 0 or step == self.args.total_timesteps
        if step > self.learning_starts and (not self.marks or now - self.marks[-1][1] >= 10):
            self.marks = self.marks[-60:] + [(step, now)]  # every 10 s of learning: SPS over this process's last 10 min
        if evaluation or (self.tty and now - self.shown > 10):  # on a terminal, progress every 10 s
            first_step, first = self.marks[0] if self.marks else (step, now)
            self.sps = (step - first_step) / (now - first) if now - first >= 60 else None  # None: not measured yet
            self.evaluate(step, act) if evaluation else self.show(step)
        self.checkpoints.end_step(step)

    def evaluate(self, step: int, act) -> None:
        """--eval-episodes of the deterministic policy: logged, written to results.json, shown."""
        returns = evaluate(act, self.args.env_id, self.args.eval_episodes, seed=self.args.seed + 100_000)
        mean, std = float(np.mean(returns)), float(np.std(returns))
        normalized = normalized_score(mean, self.random_return, self.expert_return)
        self.evals.append({"step": step, "mean": mean, "std": std, "normalized": normalized})
        self.log({"eval/return": mean, "eval/normalized_return": normalized, "charts/SPS": self.sps}, step)
        self.write_results(finished=False)
        self.show(step)

    def show(self, step: int) -> None:
        """One line: steps, minutes so far, SPS and minutes left, the latest evaluation (on a terminal, in place)."""
        total, last = self.args.total_timesteps, self.evals[-1] if self.evals else None
        rate = f"{self.sps:.0f} SPS, {(total - step) / self.sps / 60:.0f} min left" if self.sps else "SPS: measuring"
        line = f"step {step}/{total} | {(time.time() - self.start_time) / 60:.0f} min | {rate}"
        if last:
            score = f" = {last['normalized']:.2f} normalized" if last["normalized"] is not None else ""
            line += f" | eval at {last['step']}: return {last['mean']:.1f} +- {last['std']:.1f}{score}"
        stays = not self.tty or (last is not None and last["step"] == step)
        print(f"\r{line}\033[K" if self.tty else line, end="\n" if stays else "", flush=True)
        self.shown = time.perf_counter()

    def write_results(self, finished: bool) -> None:
        """results.json: the run's config, its evaluation curve and where it ran (format in docs/sweeps.md)."""
        final = self.evals[-1] if self.evals else {}
        save_file(os.path.join(self.dir, "results.json"), {
            "algo": self.args.exp_name, "env_id": self.args.env_id, "seed": self.args.seed, "finished": finished,
            "evals": self.evals, "final_return": final.get("mean"), "final_normalized_return": final.get("normalized"),
            "random_return": self.random_return, "expert_return": self.expert_return, "sps": self.sps,
            "wall_time_s": time.time() - self.start_time, "machine": self.machine, "config": asdict(self.args),
        } | self.extra)

    def finish(self, act, models: dict) -> None:
        """The last checkpoint and results.json, the models (unless --no-save-model), a video (--capture-video)."""
        if self.checkpoints.freq:
            self.checkpoints.save(self.args.total_timesteps)
        self.write_results(finished=True)
        for filename, content in models.items() if self.args.save_model else ():
            save_file(os.path.join(self.dir, filename), content)
        if self.args.capture_video:
            evaluate(act, self.args.env_id, 1, self.args.seed + 100_000, os.path.join(self.dir, "videos"))
        self.writer.close()
        print(f"done: {self.args.total_timesteps} steps in {(time.time() - self.start_time) / 60:.1f} min: {self.dir}")


class Checkpoints:
    """A run's checkpoint.pt, one dict: each `stateful` object's state_dict() (a plain dict as it is), the RNG states
    and the run's progress. Written every `freq` env steps (0: never) and on Ctrl-C / SIGTERM; read back on --resume."""

    def __init__(self, run: Run, stateful: dict, freq: int, checkpoint: Optional[dict], device):
        self.run, self.stateful, self.freq, self.stop_signal = run, stateful, freq, 0
        if checkpoint:
            for name, obj in stateful.items():  # load_state_dict, or for a plain dict an update (tensors to `device`)
                if isinstance(obj, dict):
                    obj.update({k: v.to(device) if torch.is_tensor(v) else v for k, v in checkpoint[name].items()})
                else:
                    obj.load_state_dict(checkpoint[name])
            run.evals, run.start_step = checkpoint["evals"], checkpoint["step"]
            run.start_time -= checkpoint["wall_time"]
            rng = checkpoint["rng"]
            random.setstate(rng["python"]), np.random.set_state(rng["numpy"]), torch.set_rng_state(rng["torch"])
            if rng["cuda"] is not None and torch.cuda.is_available():
                torch.cuda.set_rng_state_all(rng["cuda"])
        signal.signal(signal.SIGINT, self.on_signal), signal.signal(signal.SIGTERM, self.on_signal)

    def on_signal(self, signum, frame):
        if self.stop_signal:  # a second Ctrl-C stops at once
            raise KeyboardInterrupt
        self.stop_signal = signum
        print(f"\nsignal {signum}: saving a checkpoint at the end of this step, then exiting", flush=True)

    def due(self, step: int) -> bool:
        """Whether env step `step` ends with a checkpoint: every `freq` steps before the last, or after a signal."""
        return bool(self.stop_signal or (self.freq and step % self.freq == 0 and step < self.run.args.total_timesteps))

    def end_step(self, step: int) -> None:
        if self.due(step):
            self.save(step)
        if self.stop_signal:
            print(f"checkpoint saved at step {step}; continue with: python {sys.argv[0]} --resume {self.run.dir}")
            self.run.writer.close()
            sys.exit(128 + self.stop_signal)

    def save(self, step: int) -> None:
        run, state = self.run, {name: dict(obj) if isinstance(obj, dict) else obj.state_dict()
                                for name, obj in self.stateful.items()}
        rng = {"python": random.getstate(), "numpy": np.random.get_state(), "torch": torch.get_rng_state(),
               "cuda": torch.cuda.get_rng_state_all() if torch.cuda.is_available() else None}
        save_file(os.path.join(run.dir, "checkpoint.pt"), state | dict(step=step, evals=run.evals, rng=rng,
                  wall_time=time.time() - run.start_time, config=asdict(run.args), run_name=run.name))


def tensorboard(args, name: str, run_dir: str):
    """The run's TensorBoard writer (mirrored to Weights & Biases with --track), the config as its first text."""
    if args.track:
        import wandb
        wandb.init(project=args.wandb_project_name, entity=args.wandb_entity, sync_tensorboard=True,
                   config=vars(args), name=name, id=name, resume="allow", save_code=True)
    from torch.utils.tensorboard import SummaryWriter
    writer = SummaryWriter(run_dir)
    writer.add_text("hyperparameters", "|param|value|\n|-|-|" + "".join(f"\n|{k}|{v}|" for k, v in vars(args).items()))
    return writer


def save_file(path: str, obj) -> None:
    """torch.save for .pt files, JSON otherwise, through a temporary file: a run killed while saving keeps the old."""
    if path.endswith(".pt"):
        torch.save(obj, path + ".tmp")
    else:
        with open(path + ".tmp", "w") as f:
            json.dump(obj, f, indent=1)
    os.replace(path + ".tmp", path)


def machine(device) -> dict:
    """What decides a run's numbers besides its config: versions, CPU, threads, device, the code's commit ("-dirty")."""
    cpuinfo = open("/proc/cpuinfo").read().splitlines() if os.path.exists("/proc/cpuinfo") else []
    models = (line.split(":", 1)[1].strip() for line in cpuinfo if line.startswith("model name"))
    cpu = next(models, platform.processor())
    git = subprocess.run(["git", "describe", "--always", "--dirty", "--abbrev=12"], capture_output=True, text=True,
                         cwd=os.path.dirname(os.path.abspath(__file__))).stdout.strip() if shutil.which("git") else ""
    return {"host": platform.node(), "cpu": cpu, "cpu_capability": torch.backends.cpu.get_cpu_capability(),
            "threads": torch.get_num_threads(), "device": str(device), "python": platform.python_version(),
            **{name: metadata.version(name) for name in ("torch", "numpy", "gymnasium", "mujoco")}, "git": git or None}


def resume(args, keep=("total_timesteps", "cuda", "threads")):
    """--resume: the saved checkpoint, and its run's config with the fields in `keep` from the command line if given."""
    path = os.path.join(args.resume, "checkpoint.pt") if os.path.isdir(args.resume) else args.resume
    if not os.path.isfile(path):
        raise SystemExit(f"error: no checkpoint at '{path}'; pass --resume runs/<run> of a run that saved one")
    try:
        checkpoint = torch.load(path, map_location="cpu", weights_only=False)
    except Exception as e:
        raise SystemExit(f"error: cannot read checkpoint '{path}' ({type(e).__name__}: {e})") from None
    given, default = asdict(args), asdict(type(args)())
    saved = type(args)(**{f.name: checkpoint["config"][f.name] for f in fields(args) if f.name in checkpoint["config"]})
    return replace(saved, resume=args.resume, **{k: given[k] for k in keep if given[k] != default[k]}), checkpoint
# --- end shared: run ---


if __name__ == "__main__":
    args = tyro.cli(Args)
    args, checkpoint = resume(args) if args.resume else (args, None)
    torch.set_num_threads(args.threads)
    device = torch.device("cuda" if torch.cuda.is_available() and args.cuda else "cpu")
    seed_everything(args.seed, args.torch_deterministic)
    env = make_env(args.env_id, args.seed)
    obs_dim, act_dim = env.observation_space.shape[0], env.action_space.shape[0]
    demos = load_demonstrations(args.expert_path or f"experts/{args.env_id}.npz", env, args.num_expert_trajs)
    train_idx, holdout_idx = holdout_split(demos, args.holdout_fraction)
    obs = torch.as_tensor(demos["observations"], device=device)
    actions = torch.as_tensor(demos["actions"], device=device)
    train_idx, holdout_idx = torch.as_tensor(train_idx, device=device), torch.as_tensor(holdout_idx, device=device)
    print(f"BC ({args.loss}) on {len(train_idx)} expert pairs, {len(holdout_idx)} held out")

    # ALGO LOGIC: the agent (the actor) and its optimiser
    agent = Actor(obs_dim, act_dim, env.action_space.low, env.action_space.high, args.hidden_dim).to(device)
    optimizer = torch.optim.Adam(agent.parameters(), lr=args.learning_rate)
    best = {"holdout_mse": float("inf")}
    stateful = {"agent": agent, "optimizer": optimizer, "best": best}
    run = Run(args, checkpoint, stateful, demos, device, checkpoint_freq=args.checkpoint_freq)

    # TRY NOT TO MODIFY: start training
    for step in range(run.start_step + 1, args.total_timesteps + 1):
        idx = train_idx[torch.randint(0, len(train_idx), (args.batch_size,), device=device)]
        loss = bc_loss(agent, obs[idx], actions[idx], args.loss)
        optimizer.zero_grad(set_to_none=False)
        loss.backward()
        optimizer.step()

        run.end_step(step, agent.act)
        if step % args.eval_freq == 0 or step == args.total_timesteps:  # just evaluated: add the held-out loss
            with torch.no_grad():
                holdout = bc_loss(agent, obs[holdout_idx], actions[holdout_idx], args.loss).item()
                holdout_mse = bc_loss(agent, obs[holdout_idx], actions[holdout_idx], "mse").item()
            run.evals[-1].update(holdout_loss=holdout, holdout_mse=holdout_mse)
            run.log({"losses/train": loss, "losses/holdout": holdout, "losses/holdout_mse": holdout_mse}, step)
            if args.save_model and holdout_mse < best["holdout_mse"]:  # early stopping by selection
                best["holdout_mse"] = holdout_mse
                torch.save(actor_file(agent, args.env_id, training_steps=step, holdout_loss=holdout,
                                      holdout_mse=holdout_mse), os.path.join(run.dir, "actor_best.pt"))

    run.finish(agent.act, {"actor.pt": actor_file(agent, args.env_id, training_steps=args.total_timesteps)})
    if args.save_model:
        print(f"actor_best.pt: the actor with the lowest held-out action error, {best['holdout_mse']:.2e}")
    env.close()
