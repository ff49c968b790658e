"""Soft Actor-Critic experts for the MuJoCo tasks, and the demonstrations the imitation scripts learn from.

Paper: "Soft Actor-Critic Algorithms and Applications", Haarnoja et al. 2018, https://arxiv.org/abs/1812.05905

SAC learns a stochastic tanh-Gaussian policy and twin Q-functions off-policy, maximising return plus
entropy; the entropy temperature alpha is tuned so that the policy's entropy tracks -|A|. This script
trains it on the environment's own reward (`python expert.py --env-id Hopper-v4`), then records
demonstrations with the deterministic policy into `experts/<env-id>.npz` and copies the actor beside
them (`experts/<env-id>-actor.pt`). `python expert.py --env-id Hopper-v4 --record-from <actor.pt>`
records from any saved actor of this project without training.

The SAC here is the block every algorithm script of the project copies (see the `# --- shared:`
markers; tests/test_shared_blocks.py keeps the copies identical).

Implementation choices and deviations
1. Actor and critic are updated once per env step (the original SAC and SB3 cadence), not CleanRL's
   "policy every 2 steps, twice". One learning rate (3e-4) for actor, critics and alpha, as in the
   RILe paper's table; `--q-lr` changes the critics'.
2. The twin critics are one module whose weights carry a leading dimension of 2 (batched matmuls):
   one kernel per layer for both critics. The actor loss reads the critics through detached weights,
   so no gradient is computed for them there.
3. The replay buffer is one preallocated float tensor, one row per transition
   [obs | action | next_obs | reward | terminated]: adding is one copy, sampling is one gather.
   Only `terminated` is stored for bootstrapping; time-limit truncations keep bootstrapping.
4. log pi of the squashed Gaussian uses the exact identity log(1 - tanh(u)^2) = 2(log 2 - u - softplus(-2u))
   instead of CleanRL's log(1 - tanh(u)^2 + 1e-6): finite and exact at the action bounds.
5. Speed flags: `--compile` (torch.compile of the update; a modest gain on CPU, large on GPU),
   `--cudagraphs` (GPU only: the whole update, optimiser steps included, and the acting forward pass
   are captured once in CUDA graphs and replayed), `--threads` (torch intra-op threads; default 2, the
   cores of the reference machine: 2 threads gave ~1.6x the updates/s of 1 there; see README).
   On this CPU torch.compile gave no reliable gain (0.75x-1.2x of eager), so it is off by default (README).
6. Resume (`--resume runs/<run>`) restores networks, optimisers, temperature, replay buffer, step
   counter, RNG states and the evaluation history. The training episode in progress when the
   checkpoint was written is cut: the resumed run starts a new episode from a reset seeded by
   (seed, step). A resumed run is therefore deterministic but not bit-identical to an uninterrupted one.
7. Demonstrations are the first `--num-demos` episodes of the deterministic policy on resets seeded
   `--demo-seed + i`; none is filtered out, and the metadata says so.

Logged metrics: charts/episodic_return, charts/episodic_length, charts/SPS, eval/return,
eval/return_std, losses/qf_loss, losses/qf_values, losses/actor_loss, losses/alpha, losses/alpha_loss,
losses/entropy.
"""

import json
import os
import platform
import random
import signal
import subprocess
import sys
import time
from dataclasses import asdict, dataclass, fields
from typing import Optional

import gymnasium as gym
import numpy as np
import torch
import torch.nn as nn
import torch.nn.functional as F
import tyro


@dataclass
class Args:
    exp_name: str = "expert"
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
    """save the final actor to `runs/<run>/actor.pt`"""
    run_name: Optional[str] = None
    """run directory under runs/ (default: {env_id}__{exp_name}__{seed}__{unix_time})"""
    resume: Optional[str] = None
    """continue the run saved in this run directory (or checkpoint file); its config is reused,
    except total_timesteps, cuda, compile, cudagraphs and threads when given on the command line"""
    checkpoint_freq: int = 50_000
    """write a resumable checkpoint every this many env steps (and on Ctrl-C / SIGTERM); 0 disables"""
    threads: int = 2
    """torch intra-op threads on the CPU"""
    compile: bool = False
    """torch.compile the SAC update (no reliable gain measured on the 2-core CPU; compiling takes a minute)"""
    cudagraphs: bool = False
    """capture the update and the acting step in CUDA graphs (needs --cuda)"""

    # Algorithm specific arguments
    env_id: str = "Hopper-v4"
    """the id of the gymnasium environment"""
    total_timesteps: int = 1_000_000
    """total env steps of training"""
    buffer_size: int = 1_000_000
    """the replay memory buffer size"""
    gamma: float = 0.99
    """the discount factor gamma"""
    tau: float = 0.005
    """target smoothing coefficient"""
    batch_size: int = 256
    """the batch size of a SAC update"""
    learning_starts: int = 5_000
    """env steps of uniform random actions before learning starts"""
    policy_lr: float = 3e-4
    """the learning rate of the actor (and of alpha)"""
    q_lr: float = 3e-4
    """the learning rate of the critics"""
    alpha: float = 0.2
    """entropy temperature (the initial value when autotuned)"""
    autotune: bool = True
    """tune alpha automatically towards the target entropy -|A|"""
    hidden_dim: int = 256
    """width of the two hidden layers of actor and critics"""
    eval_freq: int = 10_000
    """evaluate the deterministic policy every this many env steps"""
    eval_episodes: int = 10
    """episodes per evaluation"""

    # Demonstration arguments
    record_demos: bool = True
    """after training, record demonstrations and copy the actor to `experts/`"""
    record_from: Optional[str] = None
    """skip training: record demonstrations from this saved actor checkpoint"""
    num_demos: int = 25
    """episodes to record"""
    demo_seed: int = 10_000
    """demonstration episode i starts from env.reset(seed=demo_seed + i)"""
    demo_path: Optional[str] = None
    """where to write the demonstrations (default: experts/<env_id>.npz)"""
    full_episodes_only: bool = False
    """keep only episodes that reach the time limit (try seeds demo_seed, demo_seed + 1, ... until
    num_demos are kept); the metadata records every episode tried"""
    max_demo_tries: int = 200
    """with --full-episodes-only, give up after this many episodes"""


# --- shared: env ---
def make_env(env_id: str, seed: int, render_mode: Optional[str] = None) -> gym.Env:
    """One gymnasium env (no vector env: episodes are reset explicitly), seeded, with a clear error."""
    try:
        env = gym.make(env_id, render_mode=render_mode)
    except gym.error.Error as e:
        raise SystemExit(f"error: cannot make environment '{env_id}' ({e}); check --env-id") from None
    if not isinstance(env.action_space, gym.spaces.Box) or not isinstance(env.observation_space, gym.spaces.Box):
        raise SystemExit(f"error: '{env_id}' needs Box observation and action spaces")
    env = gym.wrappers.RecordEpisodeStatistics(env)
    env.action_space.seed(seed)
    env.observation_space.seed(seed)
    return env


def seed_everything(seed: int, torch_deterministic: bool = True) -> None:
    random.seed(seed)
    np.random.seed(seed)
    torch.manual_seed(seed)
    torch.backends.cudnn.deterministic = torch_deterministic
# --- end shared: env ---


# --- shared: actor ---
LOG_STD_MAX = 2
LOG_STD_MIN = -5


class Actor(nn.Module):
    """tanh-squashed Gaussian policy; actions are scaled from [-1, 1] into the env's action box."""

    def __init__(self, obs_dim: int, act_dim: int, action_low, action_high, hidden_dim: int = 256):
        super().__init__()
        self.net = nn.Sequential(
            nn.Linear(obs_dim, hidden_dim), nn.ReLU(), nn.Linear(hidden_dim, hidden_dim), nn.ReLU()
        )
        self.fc_mean = nn.Linear(hidden_dim, act_dim)
        self.fc_logstd = nn.Linear(hidden_dim, act_dim)
        low = torch.as_tensor(action_low, dtype=torch.float32)
        high = torch.as_tensor(action_high, dtype=torch.float32)
        self.register_buffer("action_scale", (high - low) / 2.0)
        self.register_buffer("action_bias", (high + low) / 2.0)

    def forward(self, obs):
        h = self.net(obs)
        log_std = torch.tanh(self.fc_logstd(h))
        log_std = LOG_STD_MIN + 0.5 * (LOG_STD_MAX - LOG_STD_MIN) * (log_std + 1)
        return self.fc_mean(h), log_std

    def _log_prob(self, u, noise, log_std):
        """log pi(a|s) for a = tanh(u) * scale + bias, u = mean + std * noise.
        log(1 - tanh(u)^2) is written as 2 (log 2 - u - softplus(-2u)): exact, and finite at the bounds."""
        gauss = -0.5 * noise.pow(2) - log_std - 0.5 * np.log(2 * np.pi)
        squash = 2.0 * (np.log(2.0) - u - F.softplus(-2.0 * u)) + torch.log(self.action_scale)
        return (gauss - squash).sum(-1)

    def sample(self, obs):
        """A reparameterised action in env units and its log-probability."""
        mean, log_std = self(obs)
        noise = torch.randn_like(mean)
        u = mean + log_std.exp() * noise
        action = torch.tanh(u) * self.action_scale + self.action_bias
        return action, self._log_prob(u, noise, log_std)

    def log_prob(self, obs, action, eps: float = 1e-6):
        """log pi(action|obs) of given env-unit actions (e.g. expert actions), clamped inside the box."""
        mean, log_std = self(obs)
        y = ((action - self.action_bias) / self.action_scale).clamp(-1 + eps, 1 - eps)
        u = torch.atanh(y)
        return self._log_prob(u, (u - mean) / log_std.exp(), log_std)

    def deterministic(self, obs):
        return torch.tanh(self(obs)[0]) * self.action_scale + self.action_bias


def make_act_fn(actor: Actor, obs_dim: int, device, cudagraphs: bool):
    """Returns act(obs: np.ndarray, deterministic: bool) -> np.ndarray, for one env step."""
    def act(obs, deterministic=False):
        with torch.no_grad():
            o = torch.as_tensor(obs, dtype=torch.float32, device=device).unsqueeze(0)
            a = actor.deterministic(o) if deterministic else actor.sample(o)[0]
        return a[0].cpu().numpy()

    if not cudagraphs:
        return act
    static_obs = torch.zeros(1, obs_dim, device=device)
    graphs, outputs = {}, {}
    for det in (False, True):
        act(np.zeros(obs_dim), det)  # warm-up
        graphs[det] = torch.cuda.CUDAGraph()
        with torch.no_grad(), torch.cuda.graph(graphs[det]):
            outputs[det] = actor.deterministic(static_obs) if det else actor.sample(static_obs)[0]

    def act_graphed(obs, deterministic=False):
        static_obs.copy_(torch.as_tensor(obs, dtype=torch.float32).unsqueeze(0))
        graphs[deterministic].replay()
        return outputs[deterministic][0].cpu().numpy()

    return act_graphed
# --- end shared: actor ---


# --- shared: sac ---
class TwinQ(nn.Module):
    """Two Q-networks as one module: every weight has a leading dimension of 2, so each layer of
    both critics is a single batched matmul. forward returns Q-values of shape (2, batch)."""

    def __init__(self, obs_dim: int, act_dim: int, hidden_dim: int = 256, num_q: int = 2):
        super().__init__()
        sizes = [obs_dim + act_dim, hidden_dim, hidden_dim, 1]
        self.weights = nn.ParameterList()
        self.biases = nn.ParameterList()
        for fan_in, fan_out in zip(sizes[:-1], sizes[1:]):
            bound = 1.0 / np.sqrt(fan_in)  # nn.Linear's default initialisation
            self.weights.append(nn.Parameter(torch.empty(num_q, fan_in, fan_out).uniform_(-bound, bound)))
            self.biases.append(nn.Parameter(torch.empty(num_q, 1, fan_out).uniform_(-bound, bound)))

    def forward(self, obs, action, detach_params: bool = False):
        x = torch.cat([obs, action], -1).unsqueeze(0).expand(len(self.weights[0]), -1, -1)
        last = len(self.weights) - 1
        for i, (w, b) in enumerate(zip(self.weights, self.biases)):
            if detach_params:  # gradients flow to the input (the action) only
                w, b = w.detach(), b.detach()
            x = torch.baddbmm(b, x, w)
            if i < last:
                x = F.relu(x)
        return x.squeeze(-1)


class SAC(nn.Module):
    """Actor, twin critics, target critics and the temperature, with one `update` per env step.
    absorbing=True (DAC's absorbing states, `--termination-remedy absorbing` of the imitation scripts):
    observations carry a last indicator column, 1 at the absorbing state that follows a termination.
    The actor never sees that column; at the absorbing state the only action is zero, so it has no
    entropy term and no actor or temperature loss."""

    def __init__(self, obs_dim, act_dim, action_low, action_high, args, device, capturable: bool = False,
                 absorbing: bool = False):
        super().__init__()
        self.absorbing = absorbing
        self.actor = Actor(obs_dim - absorbing, act_dim, action_low, action_high, args.hidden_dim)
        self.qf = TwinQ(obs_dim, act_dim, args.hidden_dim)
        self.qf_target = TwinQ(obs_dim, act_dim, args.hidden_dim)
        self.qf_target.load_state_dict(self.qf.state_dict())
        self.qf_target.requires_grad_(False)
        self.log_alpha = nn.Parameter(torch.tensor(float(np.log(args.alpha))), requires_grad=args.autotune)
        self.target_entropy = -float(act_dim)
        self.gamma, self.tau = args.gamma, args.tau
        self.to(device)
        adam = dict(capturable=capturable, fused=True)  # capturable: the optimiser steps can sit in a CUDA graph
        self.q_optimizer = torch.optim.Adam(self.qf.parameters(), lr=args.q_lr, **adam)
        self.actor_optimizer = torch.optim.Adam(self.actor.parameters(), lr=args.policy_lr, **adam)
        self.alpha_optimizer = torch.optim.Adam([self.log_alpha], lr=args.policy_lr, **adam) if args.autotune else None

    def policy(self, obs):
        """a ~ pi(.|s) and log pi(a|s); with absorbing states, a = 0 and log pi = 0 where s is absorbing."""
        if not self.absorbing:
            return self.actor.sample(obs)
        actions, log_pi = self.actor.sample(obs[:, :-1])
        live = 1.0 - obs[:, -1]
        return actions * live.unsqueeze(-1), log_pi * live

    @torch.no_grad()
    def td_target(self, next_obs, rewards, terminations):
        """r + gamma (1 - terminated) (min_i Q'_i(s', a') - alpha log pi(a'|s')), with a' ~ pi(.|s').
        Only a true termination stops bootstrapping; a time-limit truncation is stored as not terminated."""
        next_actions, next_log_pi = self.policy(next_obs)
        next_q = self.qf_target(next_obs, next_actions).min(0).values - self.log_alpha.exp() * next_log_pi
        return rewards + (1.0 - terminations) * self.gamma * next_q

    def critic_loss(self, obs, actions, next_obs, rewards, terminations):
        target = self.td_target(next_obs, rewards, terminations)
        q = self.qf(obs, actions)
        return (q - target).pow(2).mean(1).sum(), q.mean()

    def actor_loss(self, obs):
        actions, log_pi = self.policy(obs)
        q = self.qf(obs, actions, detach_params=True).min(0).values
        mean = torch.mean
        if self.absorbing:  # nothing to learn at the absorbing state: average over the other states
            live = 1.0 - obs[:, -1]
            mean = lambda x: (x * live).sum() / live.sum().clamp_min(1.0)
        actor_loss = mean(self.log_alpha.detach().exp() * log_pi - q)
        alpha_loss = -mean(self.log_alpha.exp() * (log_pi.detach() + self.target_entropy))
        return actor_loss, alpha_loss, -mean(log_pi.detach())

    def update(self, obs, actions, next_obs, rewards, terminations):
        """One SAC step: critics, then actor and temperature on the updated critics, then targets.
        Returns a tensor of metrics (no .item() here: reading it synchronises)."""
        qf_loss, q_mean = self.critic_loss(obs, actions, next_obs, rewards, terminations)
        self.q_optimizer.zero_grad(set_to_none=False)
        qf_loss.backward()
        self.q_optimizer.step()

        actor_loss, alpha_loss, entropy = self.actor_loss(obs)
        self.actor_optimizer.zero_grad(set_to_none=False)
        if self.alpha_optimizer is not None:
            self.alpha_optimizer.zero_grad(set_to_none=False)
            (actor_loss + alpha_loss).backward()  # disjoint parameters: one backward for both
            self.alpha_optimizer.step()
        else:
            actor_loss.backward()
        self.actor_optimizer.step()

        with torch.no_grad():
            torch._foreach_lerp_(list(self.qf_target.parameters()), list(self.qf.parameters()), self.tau)
        return torch.stack([qf_loss, q_mean, actor_loss, alpha_loss, self.log_alpha.exp(), entropy]).detach()


METRIC_NAMES = ["qf_loss", "qf_values", "actor_loss", "alpha_loss", "alpha", "entropy"]


class ReplayBuffer:
    """Preallocated transitions, one row each: [obs | action | next_obs | reward | terminated | extra].
    `extra_dim` columns hold whatever else a script stores per transition (none for plain SAC)."""

    def __init__(self, obs_dim: int, act_dim: int, capacity: int, device, extra_dim: int = 0):
        self.obs_dim, self.act_dim, self.capacity = obs_dim, act_dim, capacity
        self.storage = torch.zeros(capacity, 2 * obs_dim + act_dim + 2 + extra_dim, dtype=torch.float32, device=device)
        self.pos, self.size = 0, 0

    def add(self, obs, action, next_obs, reward, terminated, extra=()):
        row = np.concatenate([obs, action, next_obs, [reward, float(terminated)], extra]).astype(np.float32)
        self.storage[self.pos].copy_(torch.from_numpy(row), non_blocking=False)
        self.pos = (self.pos + 1) % self.capacity
        self.size = min(self.size + 1, self.capacity)

    def sample(self, batch_size: int, recent: Optional[int] = None):
        """Uniform rows; with `recent`, only from the last `recent` added (a FIFO buffer of that size)."""
        window = self.size if recent is None else min(recent, self.size)
        idx = torch.randint(0, window, (batch_size,), device=self.storage.device)
        if window < self.size:
            idx = (self.pos - 1 - idx) % self.capacity
        return self.storage[idx]

    def split(self, rows):
        """rows (B, width) -> obs, actions, next_obs, rewards, terminations."""
        o, a = self.obs_dim, self.act_dim
        return rows[:, :o], rows[:, o : o + a], rows[:, o + a : 2 * o + a], rows[:, 2 * o + a], rows[:, 2 * o + a + 1]

    def extra(self, rows):
        return rows[:, 2 * self.obs_dim + self.act_dim + 2 :]

    def state_dict(self):
        return {"storage": self.storage[: self.size].cpu().clone(), "pos": self.pos, "size": self.size}

    def load_state_dict(self, state):
        self.size, self.pos = state["size"], state["pos"]
        self.storage[: self.size].copy_(state["storage"])
# --- end shared: sac ---


def make_update_fn(agent: SAC, rb: ReplayBuffer, args):
    """Returns step() -> metrics tensor: sample a batch and run one SAC update, plain, compiled or
    replayed from a CUDA graph."""
    update = torch.compile(agent.update) if args.compile else agent.update
    if not args.cudagraphs:
        return lambda: update(*rb.split(rb.sample(args.batch_size)))
    static_rows = rb.sample(args.batch_size)
    stream = torch.cuda.Stream()
    stream.wait_stream(torch.cuda.current_stream())
    with torch.cuda.stream(stream):  # warm-up on a side stream (these are real updates)
        for _ in range(3):
            update(*rb.split(static_rows))
    torch.cuda.current_stream().wait_stream(stream)
    graph = torch.cuda.CUDAGraph()
    with torch.cuda.graph(graph):
        static_metrics = update(*rb.split(static_rows))

    def step():
        torch.index_select(rb.storage, 0, torch.randint(0, rb.size, (args.batch_size,), device=rb.storage.device), out=static_rows)
        graph.replay()
        return static_metrics.clone()

    return step


# --- shared: evaluation ---
def evaluate(act, env_id: str, num_episodes: int, seed: int, capture_video_dir: Optional[str] = None):
    """Deterministic policy on its own env; episode i starts from reset(seed=seed + i), so every
    evaluation of a run sees the same start states. Returns the list of episode returns."""
    env = make_env(env_id, seed, render_mode="rgb_array" if capture_video_dir else None)
    if capture_video_dir:
        env = gym.wrappers.RecordVideo(env, capture_video_dir, episode_trigger=lambda ep: ep == 0, disable_logger=True)
    returns = []
    for i in range(num_episodes):
        obs, _ = env.reset(seed=seed + i)
        done, ep_return = False, 0.0
        while not done:
            obs, reward, terminated, truncated, _ = env.step(act(obs, deterministic=True))
            ep_return += float(reward)
            done = terminated or truncated
        returns.append(ep_return)
    env.close()
    return returns
# --- end shared: evaluation ---


# --- shared: results ---
def cpu_name() -> str:
    try:
        with open("/proc/cpuinfo") as f:
            return next(line.split(":", 1)[1].strip() for line in f if line.startswith("model name"))
    except (OSError, StopIteration):
        return platform.processor() or platform.machine()


def machine_info(device) -> dict:
    git = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True,
                         cwd=os.path.dirname(os.path.abspath(__file__)))
    info = {"host": platform.node(), "cpu": cpu_name(),
            "cpu_count": os.cpu_count(), "torch": torch.__version__, "threads": torch.get_num_threads(),
            "device": str(device), "python": platform.python_version(), "gymnasium": gym.__version__,
            "git_commit": git.stdout.strip() if git.returncode == 0 else None}
    if torch.device(device).type == "cuda":
        info["gpu"] = torch.cuda.get_device_name(device)
    return info


def write_results(path: str, args, evals: list, expert_return: Optional[float], wall_time: float,
                  sps: float, machine: dict, finished: bool) -> None:
    """results.json: the run's config, its evaluation curve and where it ran (format in README)."""
    final = evals[-1] if evals else None
    results = {
        "algo": args.exp_name, "env_id": args.env_id, "seed": args.seed, "finished": finished,
        "evals": evals,  # [{"step", "mean", "std", "normalized"}]
        "final_return": final["mean"] if final else None,
        "final_normalized_return": final["normalized"] if final else None,
        "expert_return": expert_return, "wall_time_s": wall_time, "sps": sps,
        "machine": machine, "config": asdict(args),
    }
    with open(path + ".tmp", "w") as f:
        json.dump(results, f, indent=1)
    os.replace(path + ".tmp", path)
def format_time(seconds: float) -> str:
    seconds = int(seconds)
    return f"{seconds // 3600}h{seconds % 3600 // 60:02d}m" if seconds >= 3600 else f"{seconds // 60}m{seconds % 60:02d}s"
# --- end shared: results ---


# --- shared: checkpoint ---
class StopRequest:
    """Turns Ctrl-C / SIGTERM into a flag that the loop checks, so the run can save and exit cleanly."""

    def __init__(self):
        self.signum = 0
        signal.signal(signal.SIGINT, self._handler)
        signal.signal(signal.SIGTERM, self._handler)

    def _handler(self, signum, frame):
        if self.signum:  # a second Ctrl-C stops at once
            raise KeyboardInterrupt
        self.signum = signum
        print(f"\nsignal {signum}: saving a checkpoint at the end of this step, then exiting", flush=True)


def save_checkpoint(path: str, state: dict) -> None:
    torch.save(state, path + ".tmp")
    os.replace(path + ".tmp", path)  # atomic: an interrupted save never leaves a broken checkpoint


def load_checkpoint(path: str) -> dict:
    if os.path.isdir(path):
        path = os.path.join(path, "checkpoint.pt")
    if not os.path.isfile(path):
        raise SystemExit(f"error: no checkpoint at '{path}'; pass --resume runs/<run> of a run that saved one")
    try:
        return torch.load(path, map_location="cpu", weights_only=False)
    except Exception as e:
        raise SystemExit(f"error: cannot read checkpoint '{path}' ({type(e).__name__}: {e})") from None


def rng_state() -> dict:
    return {"python": random.getstate(), "numpy": np.random.get_state(), "torch": torch.get_rng_state(),
            "cuda": torch.cuda.get_rng_state_all() if torch.cuda.is_available() else None}


def set_rng_state(state: dict) -> None:
    random.setstate(state["python"])
    np.random.set_state(state["numpy"])
    torch.set_rng_state(state["torch"])
    if state["cuda"] is not None and torch.cuda.is_available():
        torch.cuda.set_rng_state_all(state["cuda"])


def resume_args(cli_args, saved_config: dict):
    """The saved run's config, with the fields a user may change on resume taken from the command line
    when they differ from their defaults."""
    args = type(cli_args)(**{f.name: saved_config[f.name] for f in fields(cli_args) if f.name in saved_config})
    defaults = type(cli_args)()
    for name in ("total_timesteps", "cuda", "compile", "cudagraphs", "threads"):
        if hasattr(cli_args, name) and getattr(cli_args, name) != getattr(defaults, name):
            setattr(args, name, getattr(cli_args, name))
    args.resume = cli_args.resume
    return args
# --- end shared: checkpoint ---


# --- shared: actor io ---
def save_actor(path: str, actor: Actor, env_id: str, obs_dim: int, act_dim: int, hidden_dim: int, **extra) -> None:
    """The actor alone, with what is needed to rebuild it: any script's actor.pt can record demos."""
    torch.save({"actor": actor.state_dict(), "env_id": env_id, "obs_dim": obs_dim, "act_dim": act_dim,
                "hidden_dim": hidden_dim, **extra}, path)


def load_actor(path: str, env: gym.Env, device="cpu"):
    """Rebuild a saved actor for `env`, with clear errors for a missing file or another env's actor."""
    if not os.path.isfile(path):
        raise SystemExit(f"error: no actor checkpoint at '{path}'")
    try:
        ckpt = torch.load(path, map_location="cpu", weights_only=True)
    except Exception as e:
        raise SystemExit(f"error: cannot read actor checkpoint '{path}' ({type(e).__name__}: {e})") from None
    obs_dim, act_dim = env.observation_space.shape[0], env.action_space.shape[0]
    if (ckpt.get("obs_dim"), ckpt.get("act_dim")) != (obs_dim, act_dim):
        raise SystemExit(f"error: actor '{path}' was saved for {ckpt.get('env_id')} (obs {ckpt.get('obs_dim')}, "
                         f"act {ckpt.get('act_dim')}), not for {env.spec.id} (obs {obs_dim}, act {act_dim})")
    actor = Actor(obs_dim, act_dim, env.action_space.low, env.action_space.high, ckpt["hidden_dim"])
    actor.load_state_dict(ckpt["actor"])
    return actor.to(device).eval(), ckpt
# --- end shared: actor io ---


# --- shared: demonstrations ---
DEMO_KEYS = ("observations", "actions", "next_observations", "rewards", "terminations", "truncations",
             "episode_starts", "episode_lengths", "episode_returns", "metadata")


def load_demonstrations(path: str, env: gym.Env, num_trajs: Optional[int] = None) -> dict:
    """Load experts/<env-id>.npz (format in README), check it belongs to `env`, keep the first
    `num_trajs` episodes. Every problem is one clear SystemExit line."""
    env_id = env.spec.id
    if not os.path.isfile(path):
        raise SystemExit(f"error: no demonstrations at '{path}'; record them with "
                         f"`python expert.py --env-id {env_id}` or pass --expert-path")
    try:
        with np.load(path, allow_pickle=False) as f:
            data = {k: f[k] for k in f.files}
        meta = json.loads(str(data["metadata"]))
    except Exception as e:
        raise SystemExit(f"error: demonstrations '{path}' are unreadable or corrupt ({type(e).__name__}: {e}); "
                         f"record them again with `python expert.py --env-id {env_id}`") from None
    missing = [k for k in DEMO_KEYS if k not in data]
    if missing:
        raise SystemExit(f"error: demonstrations '{path}' lack {missing}; record them again with expert.py")
    if meta.get("env_id") != env_id:
        raise SystemExit(f"error: demonstrations '{path}' were recorded on {meta.get('env_id')}, not {env_id}; "
                         f"pass the file for {env_id} with --expert-path")
    obs_dim, act_dim = env.observation_space.shape[0], env.action_space.shape[0]
    if data["observations"].shape[1:] != (obs_dim,) or data["actions"].shape[1:] != (act_dim,):
        raise SystemExit(f"error: demonstrations '{path}' have obs/act dims {data['observations'].shape[1:]}/"
                         f"{data['actions'].shape[1:]}, {env_id} has ({obs_dim},)/({act_dim},)")
    num_episodes = len(data["episode_lengths"])
    if num_trajs is not None:
        if not 1 <= num_trajs <= num_episodes:
            raise SystemExit(f"error: --num-expert-trajs {num_trajs}, but '{path}' holds {num_episodes} episodes")
        end = int(data["episode_starts"][num_trajs - 1] + data["episode_lengths"][num_trajs - 1])
        for k in ("observations", "actions", "next_observations", "rewards", "terminations", "truncations"):
            data[k] = data[k][:end]
        for k in ("episode_starts", "episode_lengths", "episode_returns"):
            data[k] = data[k][:num_trajs]
    data["metadata"] = meta
    return data
# --- end shared: demonstrations ---


def record_demonstrations(act, env_id: str, num_episodes: int, seed: int, full_episodes_only: bool = False,
                          max_tries: int = 200) -> tuple[dict, list]:
    """Run the deterministic policy on resets seeded seed + i, i = 0, 1, ..., until `num_episodes` are kept.

    With `full_episodes_only`, an episode that terminates (falls) before the time limit is discarded;
    Returns the demonstrations and every episode run as (reset seed, length, return, kept)."""
    env = make_env(env_id, seed)
    keys = ("observations", "actions", "next_observations", "rewards", "terminations", "truncations")
    buf = {k: [] for k in keys}
    starts, lengths, returns, tried = [], [], [], []
    i = 0
    while len(lengths) < num_episodes:
        if i >= max_tries:
            raise SystemExit(f"error: only {len(lengths)} of {i} episodes reached the time limit; "
                             f"train the expert longer or raise --max-demo-tries")
        obs, _ = env.reset(seed=seed + i)
        episode = {k: [] for k in keys}
        done, ep_return = False, 0.0
        while not done:
            action = act(obs, deterministic=True)
            next_obs, reward, terminated, truncated, _ = env.step(action)
            for k, v in zip(keys, (obs, action, next_obs, reward, terminated, truncated)):
                episode[k].append(v)
            ep_return += float(reward)
            obs, done = next_obs, terminated or truncated
        keep = not (full_episodes_only and terminated)
        tried.append((seed + i, len(episode["rewards"]), ep_return, keep))
        i += 1
        if keep:
            starts.append(len(buf["rewards"]))
            for k in keys:
                buf[k].extend(episode[k])
            lengths.append(len(episode["rewards"]))
            returns.append(ep_return)
    env.close()
    demos = {k: np.asarray(v, dtype=np.float32) for k, v in buf.items() if k not in ("terminations", "truncations")}
    demos["terminations"] = np.asarray(buf["terminations"], dtype=bool)
    demos["truncations"] = np.asarray(buf["truncations"], dtype=bool)
    demos["episode_starts"] = np.asarray(starts, dtype=np.int64)
    demos["episode_lengths"] = np.asarray(lengths, dtype=np.int64)
    demos["episode_returns"] = np.asarray(returns, dtype=np.float64)
    return demos, tried


def save_demonstrations(path: str, demos: dict, metadata: dict) -> None:
    os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
    np.savez_compressed(path, **demos, metadata=np.array(json.dumps(metadata)))


def record_and_save(act, actor: Actor, args, training_steps: int, source: str, obs_dim: int, act_dim: int):
    import mujoco

    demo_path = args.demo_path or os.path.join("experts", f"{args.env_id}.npz")
    demos, tried = record_demonstrations(act, args.env_id, args.num_demos, args.demo_seed, args.full_episodes_only,
                                         args.max_demo_tries)
    returns = demos["episode_returns"]
    all_returns = np.array([t[2] for t in tried])
    if args.full_episodes_only:
        selection = (f"the first {args.num_demos} episodes of the deterministic policy (tanh of the mean) that "
                     f"reached the time limit, trying resets seeded {args.demo_seed}, {args.demo_seed} + 1, ...: "
                     f"{len(tried) - args.num_demos} of {len(tried)} tried fell first and were discarded")
    else:
        selection = (f"the first {args.num_demos} episodes of the deterministic policy (tanh of the mean), "
                     f"episode i reset with seed {args.demo_seed} + i; no episode filtered out")
    metadata = {
        "env_id": args.env_id, "gymnasium_version": gym.__version__, "mujoco_version": mujoco.__version__,
        "torch_version": torch.__version__, "expert_training_steps": training_steps, "expert_source": source,
        "training_seed": args.seed, "demo_seed": args.demo_seed, "num_episodes": args.num_demos,
        "selection": selection,
        "episodes_tried": [{"reset_seed": a, "length": b, "return": c, "kept": d} for a, b, c, d in tried],
        "tried_return_mean": float(all_returns.mean()), "tried_return_std": float(all_returns.std()),
        "return_mean": float(returns.mean()), "return_std": float(returns.std()),
        "return_min": float(returns.min()), "return_max": float(returns.max()),
        "actions": "env units (the env's action box), as sent to env.step",
        "created": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
    }
    save_demonstrations(demo_path, demos, metadata)
    actor_path = os.path.splitext(demo_path)[0] + "-actor.pt"
    if os.path.abspath(actor_path) != os.path.abspath(source):
        save_actor(actor_path, actor, args.env_id, obs_dim, act_dim, args.hidden_dim, training_steps=training_steps)
    check = load_demonstrations(demo_path, make_env(args.env_id, args.seed))  # round trip
    print(f"recorded {len(check['episode_lengths'])} episodes ({len(tried)} tried), {len(check['rewards'])} "
          f"transitions, return {returns.mean():.1f} +- {returns.std():.1f} (min {returns.min():.1f}) -> "
          f"{demo_path}, {actor_path}")


if __name__ == "__main__":
    args = tyro.cli(Args)
    checkpoint = None
    if args.resume:
        checkpoint = load_checkpoint(args.resume)
        args = resume_args(args, checkpoint["config"])
    if args.cudagraphs and not args.cuda:
        raise SystemExit("error: --cudagraphs needs --cuda")
    torch.set_num_threads(args.threads)
    device = torch.device("cuda" if torch.cuda.is_available() and args.cuda else "cpu")
    if args.cuda and device.type != "cuda":
        print("warning: --cuda given but no GPU is available; running on the CPU", file=sys.stderr)
        args.cudagraphs = False
    seed_everything(args.seed, args.torch_deterministic)
    env = make_env(args.env_id, args.seed)
    obs_dim, act_dim = env.observation_space.shape[0], env.action_space.shape[0]

    if args.record_from:  # demonstrations only, from a saved actor
        actor, ckpt = load_actor(args.record_from, env, device)
        act = make_act_fn(actor, obs_dim, device, cudagraphs=False)
        record_and_save(act, actor, args, ckpt.get("training_steps", -1), args.record_from, obs_dim, act_dim)
        sys.exit(0)

    run_name = checkpoint["run_name"] if checkpoint else (
        args.run_name or f"{args.env_id}__{args.exp_name}__{args.seed}__{int(time.time())}")
    run_dir = os.path.join("runs", run_name)
    os.makedirs(run_dir, exist_ok=True)
    with open(os.path.join(run_dir, "config.json"), "w") as f:
        json.dump(asdict(args), f, indent=1)
    if args.track:
        import wandb

        wandb.init(project=args.wandb_project_name, entity=args.wandb_entity, sync_tensorboard=True,
                   config=vars(args), name=run_name, id=run_name, resume="allow", save_code=True)
    from torch.utils.tensorboard import SummaryWriter

    writer = SummaryWriter(run_dir)
    writer.add_text("hyperparameters", "|param|value|\n|-|-|\n" + "\n".join(f"|{k}|{v}|" for k, v in vars(args).items()))

    # ALGO LOGIC: initialise the agent and its replay buffer
    agent = SAC(obs_dim, act_dim, env.action_space.low, env.action_space.high, args, device, capturable=args.cudagraphs)
    rb = ReplayBuffer(obs_dim, act_dim, args.buffer_size, device)
    evals, start_step, wall_offset, refill_until = [], 0, 0.0, 0
    if checkpoint:
        agent.load_state_dict(checkpoint["agent"])
        for name in ("q_optimizer", "actor_optimizer", "alpha_optimizer"):
            if getattr(agent, name) is not None:
                getattr(agent, name).load_state_dict(checkpoint[name])
        evals, start_step, wall_offset = checkpoint["evals"], checkpoint["global_step"], checkpoint["wall_time"]
        if "replay_buffer" in checkpoint:
            rb.load_state_dict(checkpoint["replay_buffer"])
        else:  # a checkpoint saved without its buffer (to move it between machines): refill before updating
            refill_until = start_step + args.learning_starts
            print(f"warning: the checkpoint holds no replay buffer; the current policy refills it for "
                  f"{args.learning_starts} steps before updates resume")
        set_rng_state(checkpoint["rng"])
        print(f"resumed {run_dir} at step {start_step} ({rb.size} transitions in the replay buffer)")
    act = make_act_fn(agent.actor, obs_dim, device, args.cudagraphs)
    update_step = None  # built when learning starts (CUDA graphs capture real batches)
    machine = machine_info(device)

    def checkpoint_state(step):
        state = {"agent": agent.state_dict(), "replay_buffer": rb.state_dict(), "global_step": step,
                 "evals": evals, "wall_time": wall_offset + time.time() - start_time, "rng": rng_state(),
                 "config": asdict(args), "run_name": run_name}
        for name in ("q_optimizer", "actor_optimizer", "alpha_optimizer"):
            if getattr(agent, name) is not None:
                state[name] = getattr(agent, name).state_dict()
        return state

    # TRY NOT TO MODIFY: start the game
    stop = StopRequest()
    start_time = time.time()
    learn_time, learn_steps, sps, last_print = 0.0, 0, 0.0, 0.0  # SPS counts steps after learning starts, evaluation excluded
    obs, _ = env.reset(seed=args.seed + start_step)
    global_step = start_step
    for global_step in range(start_step, args.total_timesteps):
        step_start = time.perf_counter()
        if global_step < args.learning_starts:
            action = env.action_space.sample()
        else:
            action = act(obs)
        next_obs, reward, terminated, truncated, info = env.step(action)
        rb.add(obs, action, next_obs, reward, terminated)  # next_obs is the true one, also at truncation
        obs = next_obs
        if terminated or truncated:
            writer.add_scalar("charts/episodic_return", info["episode"]["r"], global_step)
            writer.add_scalar("charts/episodic_length", info["episode"]["l"], global_step)
            obs, _ = env.reset()

        # ALGO LOGIC: training
        if global_step >= max(args.learning_starts, refill_until):
            if update_step is None:
                update_step = make_update_fn(agent, rb, args)
            metrics = update_step()
            learn_time, learn_steps = learn_time + time.perf_counter() - step_start, learn_steps + 1
            sps = learn_steps / learn_time
            if global_step % 1000 == 0:
                for name, value in zip(METRIC_NAMES, metrics.tolist()):
                    writer.add_scalar(f"losses/{name}", value, global_step)
                writer.add_scalar("charts/SPS", sps, global_step)

        step = global_step + 1
        if step % args.eval_freq == 0 or step == args.total_timesteps:
            returns = evaluate(act, args.env_id, args.eval_episodes, seed=args.seed + 100_000)
            evals.append({"step": step, "mean": float(np.mean(returns)), "std": float(np.std(returns)), "normalized": None})
            writer.add_scalar("eval/return", evals[-1]["mean"], step)
            writer.add_scalar("eval/return_std", evals[-1]["std"], step)
            write_results(os.path.join(run_dir, "results.json"), args, evals, None,
                          wall_offset + time.time() - start_time, sps, machine, finished=False)
            if evals[-1]["mean"] >= max(e["mean"] for e in evals):  # keep the best actor: experts are picked by it
                save_actor(os.path.join(run_dir, "actor_best.pt"), agent.actor, args.env_id, obs_dim, act_dim,
                           args.hidden_dim, training_steps=step, eval_return=evals[-1]["mean"])
        if time.time() - last_print > 30 or step == args.total_timesteps:
            last_print = time.time()
            eta = (args.total_timesteps - step) / sps if sps > 0 else float("nan")
            last = f"{evals[-1]['mean']:.1f} (step {evals[-1]['step']})" if evals else "-"
            print(f"step {step}/{args.total_timesteps} | {sps:.0f} SPS | eval return {last} | "
                  f"left {format_time(eta) if sps > 0 else '?'}", flush=True)
        if stop.signum or (args.checkpoint_freq and step % args.checkpoint_freq == 0 and step < args.total_timesteps):
            save_checkpoint(os.path.join(run_dir, "checkpoint.pt"), checkpoint_state(step))
            save_actor(os.path.join(run_dir, "actor.pt"), agent.actor, args.env_id, obs_dim, act_dim,
                       args.hidden_dim, training_steps=step)
            if stop.signum:
                print(f"checkpoint saved at step {step}; continue with: python {sys.argv[0]} --resume {run_dir}")
                writer.close()
                sys.exit(128 + stop.signum)

    wall_time = wall_offset + time.time() - start_time
    save_checkpoint(os.path.join(run_dir, "checkpoint.pt"), checkpoint_state(args.total_timesteps))  # to extend the run
    write_results(os.path.join(run_dir, "results.json"), args, evals, None, wall_time, sps, machine, finished=True)
    if args.save_model:
        save_actor(os.path.join(run_dir, "actor.pt"), agent.actor, args.env_id, obs_dim, act_dim, args.hidden_dim,
                   training_steps=args.total_timesteps)
        print(f"saved {run_dir}/actor.pt")
    if args.capture_video:
        evaluate(act, args.env_id, 1, seed=args.seed + 100_000, capture_video_dir=os.path.join(run_dir, "videos"))
    if args.record_demos:
        record_and_save(act, agent.actor, args, args.total_timesteps, os.path.join(run_dir, "actor.pt"), obs_dim, act_dim)
    env.close()
    writer.close()
    print(f"done: {args.total_timesteps} steps in {format_time(wall_time)}, final eval return "
          f"{evals[-1]['mean']:.1f} +- {evals[-1]['std']:.1f}" if evals else "done")
