"""AIRL on SAC: a discriminator with the structure of a reward plus a shaping potential.

Paper: Fu, Luo & Levine, "Learning Robust Rewards with Adversarial Inverse Reinforcement Learning",
https://arxiv.org/abs/1710.11248 (on TRPO; here on the shared SAC block).

The discriminator is D(s, a, s') = exp f / (exp f + pi(a|s)) with f(s, a, s') = g(s, a) + gamma h(s') - h(s):
g is the reward to recover, h a shaping potential. Its logit is f - log pi(a|s) under the current policy.
Trained like GAIL's (expert = 1), it makes g a reward that transfers. `diff gail.py airl.py` shows what
AIRL changes about GAIL.

Implementation choices and deviations
1. The SAC reward is f(s, a, s') (`--reward f`, default) or the unshaped g (`--reward g`), recomputed
   with the current networks for every sampled batch. AIRL's policy objective is f - log pi: SAC's own
   entropy term supplies the -alpha log pi part (exact at alpha = 1; with the paper's alpha = 0.2 it is
   the standard approximation), so log pi is never subtracted from the reward as well.
2. h(s') is masked by (1 - terminated): a true termination has no future potential; a time-limit
   truncation keeps it (its next state is real). gamma in f is SAC's gamma.
3. log pi(a|s) in the logit comes from the current actor, detached; expert actions are clamped inside
   the action box first (Actor.log_prob), so the log-probability never diverges.
4. g and h are 64-64 tanh MLPs (the paper's discriminator size), one Adam (lr 3e-5), 32 + 32 samples
   per update on the most recent 16,384 transitions, and the one-centred gradient penalty (weight 1)
   of gail.py on f over random interpolates of expert and learner (s, a, s'). `--state-only` makes g a
   function of s alone (the paper's transfer variant).
5. The learned reward g is saved to runs/<run>/reward.pt for reuse.
6. `--termination-remedy absorbing` (DAC, as in gail.py; the default here, because f is signed and with
   terminations terminal the Hopper-v4 learner fell on purpose): terminations lead to an absorbing
   state that loops to itself, for learner and expert alike; nothing is terminal any more, so h(s') is
   never masked and h(s_abs) is learned; log pi at the absorbing state is 0 (its only action is zero).

Logged metrics: charts/episodic_return, charts/SPS, eval/return, eval/normalized_return,
losses/{qf_loss,qf_values,actor_loss,alpha_loss,alpha,entropy}, losses/disc_loss, losses/disc_gp,
disc/expert_prob, disc/policy_prob, reward/learned_mean, reward/learned_std.
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
from typing import Literal, Optional

import gymnasium as gym
import numpy as np
import torch
import torch.nn as nn
import torch.nn.functional as F
import tyro


@dataclass
class Args:
    exp_name: str = "airl"
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
    """save the actor (actor.pt) and the learned reward g (reward.pt) in the run directory"""
    run_name: Optional[str] = None
    """run directory under runs/ (default: {env_id}__{exp_name}__{seed}__{unix_time})"""
    resume: Optional[str] = None
    """continue the run saved in this run directory (or checkpoint file); its config is reused,
    except total_timesteps, cuda and threads when given on the command line"""
    checkpoint_freq: int = 50_000
    """write a resumable checkpoint every this many env steps (and on Ctrl-C / SIGTERM); 0 disables"""
    threads: int = 2
    """torch intra-op threads on the CPU"""

    # Algorithm specific arguments
    env_id: str = "Hopper-v4"
    """the id of the gymnasium environment"""
    total_timesteps: int = 1_000_000
    """total env steps of training"""
    buffer_size: int = 1_000_000
    """the replay buffer size"""
    gamma: float = 0.99
    """the discount factor"""
    tau: float = 0.01
    """target smoothing coefficient (the paper's GAIL setting)"""
    batch_size: int = 256
    """the SAC batch size"""
    learning_starts: int = 5_000
    """env steps of uniform random actions before any update"""
    policy_lr: float = 3e-4
    """the learning rate of the actor"""
    q_lr: float = 3e-4
    """the learning rate of the critics"""
    alpha: float = 0.2
    """the entropy temperature"""
    autotune: bool = False
    """tune the temperature towards -|A| (the paper fixes it at 0.2)"""
    hidden_dim: int = 256
    """width of the actor's and critics' two hidden layers"""
    reward: Literal["f", "g"] = "f"
    """the SAC reward: f = g(s, a) + gamma h(s') - h(s) (shaped), or the learned reward g alone"""
    state_only: bool = False
    """g depends on the state only (the paper's variant for transfer)"""
    termination_remedy: Literal["none", "absorbing"] = "absorbing"
    """absorbing: DAC's absorbing states for agent and expert data (default); none: a termination ends
    bootstrapping, and a negative f then pays the learner to fall (on Hopper-v4 it did, see README)"""
    eval_freq: int = 10_000
    """evaluate the deterministic policy every this many env steps"""
    eval_episodes: int = 10
    """episodes per evaluation"""

    # Discriminator arguments
    disc_hidden_dim: int = 64
    """width of the two hidden layers of g and of h"""
    disc_lr: float = 3e-5
    """the learning rate of g and h"""
    disc_batch_size: int = 32
    """expert pairs and learner pairs per discriminator update (each)"""
    disc_buffer_size: int = 16_384
    """the discriminator learns from this many most recent learner transitions"""
    disc_gp: float = 1.0
    """weight of the one-centred gradient penalty on f"""

    # Imitation arguments
    expert_path: Optional[str] = None
    """demonstrations (default: experts/<env_id>.npz)"""
    num_expert_trajs: int = 25
    """use the first this many demonstration episodes"""
    expert_action_noise: float = 0.0
    """std of Gaussian noise added to the expert's actions (noise-robustness experiment)"""
    expert_state_noise: float = 0.0
    """std of Gaussian noise added to the expert's states (noise-robustness experiment)"""


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


# --- shared: expert data ---
def expert_tensors(demos: dict, args, action_low, action_high, device) -> dict:
    """The expert transitions as tensors, with the noise of the noise-robustness experiment added once."""
    rng = np.random.default_rng(args.seed + 1)
    obs, next_obs, actions = demos["observations"], demos["next_observations"], demos["actions"]
    if args.expert_state_noise > 0:
        obs = obs + rng.normal(0, args.expert_state_noise, obs.shape).astype(np.float32)
        next_obs = next_obs + rng.normal(0, args.expert_state_noise, next_obs.shape).astype(np.float32)
    if getattr(args, "expert_action_noise", 0.0) > 0:  # state-only methods have no such flag
        actions = np.clip(actions + rng.normal(0, args.expert_action_noise, actions.shape), action_low, action_high)
    as_tensor = lambda x: torch.as_tensor(np.asarray(x, dtype=np.float32), device=device)
    return {"obs": as_tensor(obs), "actions": as_tensor(actions), "next_obs": as_tensor(next_obs),
            "terminations": as_tensor(demos["terminations"])}
# --- end shared: expert data ---


# --- shared: absorbing ---
def absorbing_state(obs_dim: int) -> np.ndarray:
    """DAC's absorbing state for observations of `obs_dim`: zeros, then the indicator column set to 1."""
    s = np.zeros(obs_dim + 1, dtype=np.float32)
    s[-1] = 1.0
    return s


def store(rb: "ReplayBuffer", obs, action, next_obs, reward, terminated, absorbing: bool, extra=(), absorbing_extra=()):
    """Store one env transition. With absorbing states (DAC, Kostrikov et al. 2019) observations get an
    indicator column (0); a termination leads to the absorbing state instead and is no longer terminal,
    and the transition (absorbing state, zero action, absorbing state) is added after it, so ending an
    episode is worth the learned reward of the absorbing state forever, not an implicit 0.
    `absorbing_extra` fills the extra columns of that added row."""
    if not absorbing:
        rb.add(obs, action, next_obs, reward, terminated, extra)
        return
    s_abs = absorbing_state(len(obs))
    rb.add(np.append(obs, 0.0), action, s_abs if terminated else np.append(next_obs, 0.0), reward, False, extra)
    if terminated:
        rb.add(s_abs, np.zeros_like(action), s_abs, 0.0, False, absorbing_extra)


def absorbing_expert(expert: dict) -> dict:
    """store()'s treatment applied to the demonstrations (a dict of tensors): the indicator column,
    terminal transitions lead to the absorbing state, one absorbing self-loop per termination."""
    obs, actions, next_obs, term = expert["obs"], expert["actions"], expert["next_obs"], expert["terminations"] > 0
    s_abs = torch.as_tensor(absorbing_state(obs.shape[1]), device=obs.device)
    loops = s_abs.expand(int(term.sum()), -1)
    next_obs = torch.where(term.unsqueeze(-1), s_abs, F.pad(next_obs, (0, 1)))
    return {**expert, "obs": torch.cat([F.pad(obs, (0, 1)), loops]), "next_obs": torch.cat([next_obs, loops]),
            "actions": torch.cat([actions, actions.new_zeros(len(loops), actions.shape[1])]),
            "terminations": obs.new_zeros(len(obs) + len(loops))}
# --- end shared: absorbing ---




# ALGO LOGIC: AIRL's discriminator
def mlp(in_dim: int, hidden_dim: int) -> nn.Module:
    return nn.Sequential(nn.Linear(in_dim, hidden_dim), nn.Tanh(), nn.Linear(hidden_dim, hidden_dim), nn.Tanh(),
                         nn.Linear(hidden_dim, 1))


class AIRLDiscriminator(nn.Module):
    """f(s, a, s') = g(s, a) + gamma (1 - terminated) h(s') - h(s); logit = f - log pi(a|s)."""

    def __init__(self, obs_dim: int, act_dim: int, hidden_dim: int, gamma: float, state_only: bool, lr: float,
                 gp_weight: float):
        super().__init__()
        self.obs_dim, self.state_only, self.gamma, self.gp_weight = obs_dim, state_only, gamma, gp_weight
        self.g = mlp(obs_dim if state_only else obs_dim + act_dim, hidden_dim)
        self.h = mlp(obs_dim, hidden_dim)
        self.optimizer = torch.optim.Adam(self.parameters(), lr=lr)

    def reward_g(self, obs, actions):
        return self.g(obs if self.state_only else torch.cat([obs, actions], -1)).squeeze(-1)

    def forward(self, obs, actions, next_obs, terminations):
        """f(s, a, s'): the shaping term h(s') is masked by true terminations only."""
        h, h_next = self.h(obs).squeeze(-1), self.h(next_obs).squeeze(-1)
        return self.reward_g(obs, actions) + self.gamma * (1 - terminations) * h_next - h

    def loss(self, expert: tuple, policy: tuple, expert_log_pi, policy_log_pi):
        """BCE on logits f - log pi (expert = 1) + gp_weight E[(||grad f(x_hat)|| - 1)^2], x_hat between
        expert and learner (s, a, s')."""
        expert_logits = self(*expert) - expert_log_pi
        policy_logits = self(*policy) - policy_log_pi
        bce = (F.binary_cross_entropy_with_logits(expert_logits, torch.ones_like(expert_logits))
               + F.binary_cross_entropy_with_logits(policy_logits, torch.zeros_like(policy_logits)))
        eps = torch.rand(len(expert[0]), 1, device=expert[0].device)
        mixed = [(eps * e + (1 - eps) * p).requires_grad_(True) for e, p in zip(expert[:3], policy[:3])]
        terminations = eps.squeeze(-1) * expert[3] + (1 - eps.squeeze(-1)) * policy[3]
        grads = torch.autograd.grad(self(*mixed, terminations).sum(), mixed, create_graph=True, allow_unused=True)
        grads = [torch.zeros_like(x) if g is None else g for g, x in zip(grads, mixed)]  # state-only g: no action input
        gp = (torch.cat(grads, -1).norm(2, dim=1) - 1).pow(2).mean()
        return bce + self.gp_weight * gp, bce, gp, torch.sigmoid(expert_logits).mean(), torch.sigmoid(policy_logits).mean()

    def update(self, expert, policy, expert_log_pi, policy_log_pi):
        loss, bce, gp, expert_prob, policy_prob = self.loss(expert, policy, expert_log_pi, policy_log_pi)
        self.optimizer.zero_grad(set_to_none=False)
        loss.backward()
        self.optimizer.step()
        return torch.stack([bce, gp, expert_prob, policy_prob]).detach()


DISC_METRIC_NAMES = ["losses/disc_loss", "losses/disc_gp", "disc/expert_prob", "disc/policy_prob"]


def policy_log_prob(agent: "SAC", obs, actions):
    """log pi(a|s) under the current actor; 0 at absorbing states, where the only action is zero."""
    if not agent.absorbing:
        return agent.actor.log_prob(obs, actions)
    return agent.actor.log_prob(obs[:, :-1], actions) * (1 - obs[:, -1])


def airl_update(agent: "SAC", disc: AIRLDiscriminator, rb: "ReplayBuffer", expert: dict, args) -> dict:
    """One SAC update on f (or g) from the current discriminator, then one discriminator update."""
    obs, actions, next_obs, _env_reward, terminations = rb.split(rb.sample(args.batch_size))
    with torch.no_grad():
        rewards = disc(obs, actions, next_obs, terminations) if args.reward == "f" else disc.reward_g(obs, actions)
    out = {"sac": agent.update(obs, actions, next_obs, rewards, terminations),
           "reward": torch.stack([rewards.mean(), rewards.std()])}
    idx = torch.randint(0, len(expert["obs"]), (args.disc_batch_size,), device=expert["obs"].device)
    expert_batch = tuple(expert[k][idx] for k in ("obs", "actions", "next_obs", "terminations"))
    policy_batch = rb.split(rb.sample(args.disc_batch_size, recent=args.disc_buffer_size))
    policy_batch = (policy_batch[0], policy_batch[1], policy_batch[2], policy_batch[4])
    with torch.no_grad():  # log pi of the current policy, detached (expert actions clamped inside the box)
        expert_log_pi = policy_log_prob(agent, expert_batch[0], expert_batch[1])
        policy_log_pi = policy_log_prob(agent, policy_batch[0], policy_batch[1])
    out["disc"] = disc.update(expert_batch, policy_batch, expert_log_pi, policy_log_pi)
    return out


if __name__ == "__main__":
    args = tyro.cli(Args)
    checkpoint = None
    if args.resume:
        checkpoint = load_checkpoint(args.resume)
        args = resume_args(args, checkpoint["config"])
    torch.set_num_threads(args.threads)
    device = torch.device("cuda" if torch.cuda.is_available() and args.cuda else "cpu")
    seed_everything(args.seed, args.torch_deterministic)
    env = make_env(args.env_id, args.seed)
    obs_dim, act_dim = env.observation_space.shape[0], env.action_space.shape[0]
    low, high = env.action_space.low, env.action_space.high
    demos = load_demonstrations(args.expert_path or os.path.join("experts", f"{args.env_id}.npz"), env, args.num_expert_trajs)
    expert = expert_tensors(demos, args, low, high, device)
    absorbing = args.termination_remedy == "absorbing"
    if absorbing:
        expert = absorbing_expert(expert)
    expert_return = float(demos["episode_returns"].mean())

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
    print(f"AIRL reward: {args.reward}" + (" (state-only g)" if args.state_only else ""))

    # ALGO LOGIC: the learner, the discriminator and the replay buffer
    aug_dim = obs_dim + absorbing  # with absorbing states, every stored observation has the indicator column
    agent = SAC(aug_dim, act_dim, low, high, args, device, absorbing=absorbing)
    disc = AIRLDiscriminator(aug_dim, act_dim, args.disc_hidden_dim, args.gamma, args.state_only, args.disc_lr,
                             args.disc_gp).to(device)
    rb = ReplayBuffer(aug_dim, act_dim, args.buffer_size, device)
    evals, start_step, wall_offset = [], 0, 0.0
    if checkpoint:
        agent.load_state_dict(checkpoint["agent"])
        for opt in ("q_optimizer", "actor_optimizer", "alpha_optimizer"):
            if getattr(agent, opt) is not None:
                getattr(agent, opt).load_state_dict(checkpoint[opt])
        disc.load_state_dict(checkpoint["disc"])
        disc.optimizer.load_state_dict(checkpoint["disc_optimizer"])
        rb.load_state_dict(checkpoint["replay_buffer"])
        evals, start_step, wall_offset = checkpoint["evals"], checkpoint["global_step"], checkpoint["wall_time"]
        set_rng_state(checkpoint["rng"])
        print(f"resumed {run_dir} at step {start_step} ({rb.size} transitions in the replay buffer)")
    act = make_act_fn(agent.actor, obs_dim, device, cudagraphs=False)
    machine = machine_info(device)

    def checkpoint_state(step):
        ckpt = {"agent": agent.state_dict(), "disc": disc.state_dict(), "disc_optimizer": disc.optimizer.state_dict(),
                "replay_buffer": rb.state_dict(), "global_step": step, "evals": evals,
                "wall_time": wall_offset + time.time() - start_time, "rng": rng_state(), "config": asdict(args),
                "run_name": run_name}
        for opt in ("q_optimizer", "actor_optimizer", "alpha_optimizer"):
            if getattr(agent, opt) is not None:
                ckpt[opt] = getattr(agent, opt).state_dict()
        return ckpt

    # TRY NOT TO MODIFY: start the game
    stop = StopRequest()
    start_time = time.time()
    learn_time, learn_steps, sps, last_print = 0.0, 0, 0.0, 0.0  # SPS counts steps after learning starts, evaluation excluded
    obs, _ = env.reset(seed=args.seed + start_step)
    for global_step in range(start_step, args.total_timesteps):
        step_start = time.perf_counter()
        if global_step < args.learning_starts:
            action = env.action_space.sample()
        else:
            action = act(obs)
        next_obs, reward, terminated, truncated, info = env.step(action)
        store(rb, obs, action, next_obs, reward, terminated, absorbing)  # the env reward is stored, never learned from
        obs = next_obs
        if terminated or truncated:
            writer.add_scalar("charts/episodic_return", info["episode"]["r"], global_step)
            writer.add_scalar("charts/episodic_length", info["episode"]["l"], global_step)
            obs, _ = env.reset()

        # ALGO LOGIC: training
        if global_step >= args.learning_starts:
            metrics = airl_update(agent, disc, rb, expert, args)
            learn_time, learn_steps = learn_time + time.perf_counter() - step_start, learn_steps + 1
            sps = learn_steps / learn_time
            if global_step % 1000 == 0:
                for key, value in zip(METRIC_NAMES, metrics["sac"].tolist()):
                    writer.add_scalar(f"losses/{key}", value, global_step)
                for key, value in zip(DISC_METRIC_NAMES, metrics["disc"].tolist()):
                    writer.add_scalar(key, value, global_step)
                mean, std = metrics["reward"].tolist()
                writer.add_scalar("reward/learned_mean", mean, global_step)
                writer.add_scalar("reward/learned_std", std, global_step)
                writer.add_scalar("charts/SPS", sps, global_step)

        step = global_step + 1
        if step % args.eval_freq == 0 or step == args.total_timesteps:
            returns = evaluate(act, args.env_id, args.eval_episodes, seed=args.seed + 100_000)
            mean = float(np.mean(returns))
            evals.append({"step": step, "mean": mean, "std": float(np.std(returns)), "normalized": mean / expert_return})
            writer.add_scalar("eval/return", mean, step)
            writer.add_scalar("eval/normalized_return", mean / expert_return, step)
            write_results(os.path.join(run_dir, "results.json"), args, evals, expert_return,
                          wall_offset + time.time() - start_time, sps, machine, finished=False)
        if time.time() - last_print > 30 or step == args.total_timesteps:
            last_print = time.time()
            last = (f"{evals[-1]['mean']:.1f} = {evals[-1]['normalized']:.2f} x expert {expert_return:.1f} "
                    f"(step {evals[-1]['step']})") if evals else "-"
            print(f"step {step}/{args.total_timesteps} | {sps:.0f} SPS | eval return {last} | left "
                  f"{format_time((args.total_timesteps - step) / sps) if sps > 0 else '?'}", flush=True)
        if stop.signum or (args.checkpoint_freq and step % args.checkpoint_freq == 0 and step < args.total_timesteps):
            save_checkpoint(os.path.join(run_dir, "checkpoint.pt"), checkpoint_state(step))
            if stop.signum:
                print(f"checkpoint saved at step {step}; continue with: python {sys.argv[0]} --resume {run_dir}")
                writer.close()
                sys.exit(128 + stop.signum)

    wall_time = wall_offset + time.time() - start_time
    save_checkpoint(os.path.join(run_dir, "checkpoint.pt"), checkpoint_state(args.total_timesteps))
    write_results(os.path.join(run_dir, "results.json"), args, evals, expert_return, wall_time, sps, machine, finished=True)
    if args.save_model:
        save_actor(os.path.join(run_dir, "actor.pt"), agent.actor, args.env_id, obs_dim, act_dim, args.hidden_dim,
                   training_steps=args.total_timesteps)
        torch.save({"g": disc.g.state_dict(), "h": disc.h.state_dict(), "env_id": args.env_id, "obs_dim": obs_dim,
                    "act_dim": act_dim, "hidden_dim": args.disc_hidden_dim, "state_only": args.state_only,
                    "termination_remedy": args.termination_remedy},
                   os.path.join(run_dir, "reward.pt"))
        print(f"saved {run_dir}/actor.pt and the learned reward g (with h) {run_dir}/reward.pt")
    if args.capture_video:
        evaluate(act, args.env_id, 1, seed=args.seed + 100_000, capture_video_dir=os.path.join(run_dir, "videos"))
    env.close()
    writer.close()
    if evals:
        print(f"done: {args.total_timesteps} steps in {format_time(wall_time)}, final eval return {evals[-1]['mean']:.1f} "
              f"+- {evals[-1]['std']:.1f} ({evals[-1]['normalized']:.2f} x expert {expert_return:.1f})")
