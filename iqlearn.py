"""IQ-Learn (online, chi^2): inverse soft-Q learning on the SAC machinery.

Paper: Garg, Chakraborty, Cundy, Song & Ermon, "IQ-Learn: Inverse soft-Q Learning for Imitation",
https://arxiv.org/abs/2106.12142 (written from the paper and a description of the authors' code, whose licence is
academic-use only; none of it was copied).

A single soft Q-function is learned directly from expert and policy data, with no discriminator and no
reward network: the implicit reward is r(s, a) = Q(s, a) - gamma (1 - d) V(s'), with
V(s) = Q(s, a~) - alpha log pi(a~|s). The critic minimises -mean_expert(r) + a value term + 1/(4 chi2_alpha)
mean(r^2), the chi^2 regulariser; the actor is SAC's, trained on policy and expert states. On tasks that
terminate its evaluations swing, with no loss diverging: the objective's own behaviour, not a bug.

Implementation choices and deviations
1. Every update: 256 replay + 256 expert transitions, the chi^2 term over both (the online form). Value term
   (`--value-loss`): `value` = mean_both(V(s) - gamma (1 - d) V_targ(s')), or `v0` = (1 - gamma) mean_expert(V(s)).
2. `--preset auto` (default): the value term and alpha of the paper's scripts for the MuJoCo envs it lists
   (`PRESETS`), actor lr 3e-5; elsewhere v0, alpha 1e-2, actor lr 3e-4, chi^2 at the stored actions. `--preset none`:
   IQ-Learn's generic configs (value, alpha 1e-2, actor lr 3e-4, chi^2 at the policy's actions). Flags override both.
3. `--chi2-actions policy` (the listed envs' default): on policy states the chi^2 term takes r at the current
   policy's action, as the authors' code does; `replay` takes the stored action (the older policies' rewards).
4. `v0` averages V over all expert states, as the authors' code does, not over initial states only (the paper's).
5. Done semantics (`--timeout-done`): off (default), only true terminations stop bootstrapping, for expert and online
   data alike; on, truncations count as done in both, as the authors' code does on MuJoCo.
6. One Q network (the shared critic block with one head: twin-min critics diverge here), a target copy updated
   with tau 0.005 every step, fixed alpha, critic lr 3e-4.
7. As in the authors' setup, no random warm-up: the stochastic policy acts from the first step and updates start
   once 1,280 transitions are stored. No observation normalisation.

Logged metrics: charts/{episodic_return,episodic_length,SPS}, eval/{return,normalized_return}, losses/{softq,value,
chi2,critic,actor,q_expert,q_policy}, reward/implicit_{expert,policy} and, with `--chi2-actions policy`,
reward/implicit_current_policy: the implicit reward shows divergence first. Details: docs/baselines.md
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
from typing import Annotated, Literal, NamedTuple, Optional

import gymnasium as gym
import numpy as np
import torch
import torch.nn as nn
import torch.nn.functional as F
import tyro

# the IQ-Learn paper's MuJoCo scripts: (value variant, alpha)
PRESETS = {"Hopper": ("v0", 1e-2), "Walker2d": ("v0", 1e-2), "HalfCheetah": ("value", 1e-2), "Ant": ("value", 1e-3),
           "Humanoid": ("v0", 1.0)}


@dataclass
class Args:
    """IQ-Learn, inverse soft-Q learning (online, chi^2): one soft Q-function learned from expert and agent data, with
    no discriminator and no reward network, and a SAC actor that follows it. Start it
    with `python iqlearn.py --env-id Hopper-v4 --total-timesteps 200000`. "The paper" below is IQ-Learn's,
    arXiv 2106.12142. Flags given on the command line win over --preset."""
    exp_name: str = "iqlearn"
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
    """save the actor (actor.pt) and the Q-function (q.pt) in the run directory"""
    run_name: Annotated[Optional[str], tyro.conf.arg(
        help_behavior_hint="(default: {env_id}__{exp_name}__{seed}__{unix_time})")] = None
    """the run directory under runs/"""
    resume: Optional[str] = None
    """continue this run (directory or checkpoint) on its config; --total-timesteps, --cuda, --threads may change"""
    checkpoint_freq: int = 50_000
    """write a resumable checkpoint every this many env steps (and on Ctrl-C / SIGTERM); 0 disables"""
    threads: int = 2
    """torch intra-op threads on the CPU"""

    # Algorithm specific arguments
    env_id: str = "Hopper-v4"
    """the id of the gymnasium environment"""
    total_timesteps: int = 500_000
    """total env steps of training"""
    buffer_size: int = 500_000
    """the replay buffer size"""
    gamma: float = 0.99
    """the discount factor"""
    tau: float = 0.005
    """the target smoothing coefficient"""
    batch_size: int = 256
    """policy transitions per update (the same number of expert transitions joins them)"""
    learning_starts: int = 1_280
    """updates start once this many transitions are stored (the policy acts from the first step)"""
    preset: Literal["auto", "none"] = "auto"
    """auto: the paper's settings on the MuJoCo envs it lists, this script's elsewhere; none: IQ-Learn's generic ones"""
    value_loss: Annotated[Optional[Literal["value", "v0"]], tyro.conf.arg(
        help_behavior_hint="(default: by --preset)")] = None
    """the value term: value, on policy and expert states; v0, (1 - gamma) V on expert states"""
    alpha: Annotated[Optional[float], tyro.conf.arg(help_behavior_hint="(default: by --preset)")] = None
    """the fixed entropy temperature: the paper's on the envs it lists (0.01; Ant 0.001, Humanoid 1), else 0.01"""
    policy_lr: Annotated[Optional[float], tyro.conf.arg(help_behavior_hint="(default: by --preset)")] = None
    """the learning rate of the actor: 3e-5 on the MuJoCo envs the paper lists, else 3e-4"""
    q_lr: float = 3e-4
    """the learning rate of the critic"""
    chi2_alpha: float = 0.5
    """the chi^2 regulariser is 1 / (4 chi2_alpha) mean(r^2)"""
    chi2_actions: Annotated[Optional[Literal["policy", "replay"]], tyro.conf.arg(
        help_behavior_hint="(default: by --preset)")] = None
    """the chi^2 term's action on policy states: policy, a ~ pi(s) (the authors' code); replay, the stored one"""
    timeout_done: bool = False
    """count time-limit truncations as done (IQ-Learn's code) for expert and online data alike"""
    hidden_dim: int = 256
    """width of the actor's and critic's two hidden layers"""
    eval_freq: int = 10_000
    """evaluate the deterministic policy every this many env steps"""
    eval_episodes: int = 10
    """episodes per evaluation"""

    # Imitation arguments
    expert_path: Annotated[Optional[str], tyro.conf.arg(help_behavior_hint="(default: experts/<env-id>.npz)")] = None
    """the demonstrations file"""
    num_expert_trajs: int = 25
    """use the first this many demonstration episodes (the paper's: 1)"""


# ALGO LOGIC: IQ-Learn's critic and actor losses and its update
class IQLearn(nn.Module):
    """Actor, one Q-network and its target, a fixed temperature, and the IQ-Learn update."""

    def __init__(self, obs_dim, act_dim, action_low, action_high, args, device):
        super().__init__()
        self.actor = Actor(obs_dim, act_dim, action_low, action_high, args.hidden_dim)
        self.q = TwinQ(obs_dim, act_dim, args.hidden_dim, num_q=1)
        self.q_target = TwinQ(obs_dim, act_dim, args.hidden_dim, num_q=1)
        self.q_target.load_state_dict(self.q.state_dict())
        self.q_target.requires_grad_(False)
        self.alpha, self.gamma, self.tau = args.alpha, args.gamma, args.tau
        self.value_loss, self.chi2_actions = args.value_loss, args.chi2_actions
        self.chi2_coef = 1.0 / (4 * args.chi2_alpha)
        self.to(device)
        self.q_optimizer = torch.optim.Adam(self.q.parameters(), lr=args.q_lr)
        self.actor_optimizer = torch.optim.Adam(self.actor.parameters(), lr=args.policy_lr)

    def value(self, q_net, obs, detach_params=False):
        """V(s) = Q(s, a~) - alpha log pi(a~|s), a~ ~ pi(.|s), the policy held fixed."""
        with torch.no_grad():
            actions, log_pi = self.actor.sample(obs)
        return q_net(obs, actions, detach_params=detach_params)[0] - self.alpha * log_pi

    def critic_loss(self, obs, actions, next_obs, dones, is_expert):
        with torch.no_grad():
            y = (1 - dones) * self.gamma * self.value(self.q_target, next_obs)
        q = self.q(obs, actions)[0]
        reward = q - y  # the implicit reward
        softq = -reward[is_expert].mean()
        if self.value_loss == "value":
            value = (self.value(self.q, obs) - y).mean()
        else:  # v0: (1 - gamma) E[V(s)] on the expert's states
            value = (1 - self.gamma) * self.value(self.q, obs[is_expert]).mean()
        chi2_reward = reward
        if self.chi2_actions == "policy":  # on policy states, r at the current policy's action
            with torch.no_grad():
                policy_actions, _ = self.actor.sample(obs[~is_expert])
            on_policy = self.q(obs[~is_expert], policy_actions)[0] - y[~is_expert]
            chi2_reward = torch.cat([on_policy, reward[is_expert]])
        chi2 = self.chi2_coef * chi2_reward.pow(2).mean()
        terms = {"losses/softq": softq, "losses/value": value, "losses/chi2": chi2,
                 "losses/q_expert": q[is_expert].mean(), "losses/q_policy": q[~is_expert].mean(),
                 "reward/implicit_expert": reward[is_expert].mean(),
                 "reward/implicit_policy": reward[~is_expert].mean()}
        if self.chi2_actions == "policy":
            terms["reward/implicit_current_policy"] = on_policy.mean()  # the same states, the current policy's actions
        return softq + value + chi2, {name: term.detach() for name, term in terms.items()}

    def actor_loss(self, obs):
        actions, log_pi = self.actor.sample(obs)
        return (self.alpha * log_pi - self.q(obs, actions, detach_params=True)[0]).mean()

    def update(self, batch: "Batch", expert: dict) -> dict:
        """One critic step on policy + expert data, one actor step on both batches' states, then the target.
        `expert` holds as many expert transitions; `terminations` is the done flag of --timeout-done.
        Returns metric tensors keyed by their logged names."""
        keys = ("obs", "actions", "next_obs", "terminations")
        obs, actions, next_obs, dones = (torch.cat([getattr(batch, k), expert[k]]) for k in keys)
        is_expert = torch.zeros(len(obs), dtype=torch.bool, device=obs.device)
        is_expert[len(batch.obs):] = True
        critic_loss, metrics = self.critic_loss(obs, actions, next_obs, dones, is_expert)
        self.q_optimizer.zero_grad(set_to_none=False)
        critic_loss.backward()
        self.q_optimizer.step()
        actor_loss = self.actor_loss(obs)
        self.actor_optimizer.zero_grad(set_to_none=False)
        actor_loss.backward()
        self.actor_optimizer.step()
        with torch.no_grad():
            torch._foreach_lerp_(list(self.q_target.parameters()), list(self.q.parameters()), self.tau)
        return {"losses/critic": critic_loss.detach(), "losses/actor": actor_loss.detach()} | metrics


def apply_preset(args):
    """The value term, alpha, actor lr and chi^2 actions the flags leave open (header, choice 2)."""
    name = args.env_id.split("-")[0]
    if args.preset == "none":
        value_loss, alpha, policy_lr, chi2_actions = "value", 1e-2, 3e-4, "policy"  # IQ-Learn's agent, method configs
    elif name in PRESETS:
        value_loss, alpha, policy_lr, chi2_actions = *PRESETS[name], 3e-5, "policy"  # its paper's MuJoCo scripts
    else:
        value_loss, alpha, policy_lr, chi2_actions = "v0", 1e-2, 3e-4, "replay"  # measured on Pendulum-v1
    args.value_loss = args.value_loss or value_loss
    args.chi2_actions = args.chi2_actions or chi2_actions
    args.alpha = alpha if args.alpha is None else args.alpha
    args.policy_lr = policy_lr if args.policy_lr is None else args.policy_lr
    return args


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


# --- shared: critic ---
class TwinQ(nn.Module):
    """Two Q-networks as one module, each weight with a leading dimension of 2 (a batched matmul); Q of shape (2, B)."""

    def __init__(self, obs_dim: int, act_dim: int, hidden_dim: int = 256, num_q: int = 2):
        super().__init__()
        sizes = [obs_dim + act_dim, hidden_dim, hidden_dim, 1]
        self.weights, self.biases = nn.ParameterList(), nn.ParameterList()
        for fan_in, fan_out in zip(sizes[:-1], sizes[1:]):
            bound = 1.0 / np.sqrt(fan_in)  # nn.Linear's default initialisation
            self.weights.append(nn.Parameter(torch.empty(num_q, fan_in, fan_out).uniform_(-bound, bound)))
            self.biases.append(nn.Parameter(torch.empty(num_q, 1, fan_out).uniform_(-bound, bound)))

    def forward(self, obs, action, detach_params: bool = False):
        """detach_params: gradients flow to the input (the action) only."""
        x = torch.cat([obs, action], -1).unsqueeze(0).expand(len(self.weights[0]), -1, -1)
        for i, (w, b) in enumerate(zip(self.weights, self.biases)):
            x = torch.baddbmm(b.detach(), x, w.detach()) if detach_params else torch.baddbmm(b, x, w)
            x = F.relu(x) if i < len(self.weights) - 1 else x
        return x.squeeze(-1)
# --- end shared: critic ---


# --- shared: buffer ---
class Batch(NamedTuple):
    obs: torch.Tensor
    actions: torch.Tensor
    next_obs: torch.Tensor
    rewards: torch.Tensor  # the env's reward: logged and measured, never learned from by an imitation script
    terminations: torch.Tensor
    extra: torch.Tensor  # the columns a script adds (rile.py: the trainer's action)


class ReplayBuffer:
    """Preallocated transitions, one row each: [obs | action | next_obs | reward | terminated | extra]."""

    def __init__(self, obs_dim: int, act_dim: int, capacity: int, device, extra_dim: int = 0):
        self.obs_dim, self.act_dim, self.capacity, self.pos, self.size = obs_dim, act_dim, capacity, 0, 0
        self.storage = torch.zeros(capacity, 2 * obs_dim + act_dim + 2 + extra_dim, dtype=torch.float32, device=device)

    def add(self, obs, action, next_obs, reward, terminated, extra=()):
        row = np.concatenate([obs, action, next_obs, [reward, float(terminated)], extra]).astype(np.float32)
        self.storage[self.pos].copy_(torch.from_numpy(row))
        self.pos, self.size = (self.pos + 1) % self.capacity, min(self.size + 1, self.capacity)

    def indices(self, batch_size: int, recent: Optional[int] = None) -> torch.Tensor:
        """Uniform rows; with `recent`, only from the last `recent` added (a FIFO buffer of that size)."""
        window = self.size if recent is None else min(recent, self.size)
        idx = torch.randint(0, window, (batch_size,), device=self.storage.device)
        return (self.pos - 1 - idx) % self.capacity if window < self.size else idx

    def batch(self, idx) -> Batch:
        rows, o, a = self.storage[idx], self.obs_dim, self.act_dim
        return Batch(rows[:, :o], rows[:, o : o + a], rows[:, o + a : 2 * o + a], rows[:, 2 * o + a],
                     rows[:, 2 * o + a + 1], rows[:, 2 * o + a + 2 :])

    def sample(self, batch_size: int, recent: Optional[int] = None) -> Batch:
        return self.batch(self.indices(batch_size, recent))

    def state_dict(self) -> dict:
        return {"storage": self.storage[: self.size].cpu().clone(), "pos": self.pos, "size": self.size}

    def load_state_dict(self, state: dict) -> None:
        self.size, self.pos = state["size"], state["pos"]
        self.storage[: self.size].copy_(state["storage"])
# --- end shared: buffer ---


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
    args = apply_preset(args)
    torch.set_num_threads(args.threads)
    device = torch.device("cuda" if torch.cuda.is_available() and args.cuda else "cpu")
    seed_everything(args.seed, args.torch_deterministic)
    env = make_env(args.env_id, args.seed)
    obs_dim, act_dim = env.observation_space.shape[0], env.action_space.shape[0]
    low, high = env.action_space.low, env.action_space.high
    demos = load_demonstrations(args.expert_path or f"experts/{args.env_id}.npz", env, args.num_expert_trajs)
    dones = demos["terminations"] | (demos["truncations"] if args.timeout_done else False)
    expert = {name: torch.as_tensor(np.asarray(x, dtype=np.float32), device=device) for name, x in (
        ("obs", demos["observations"]), ("actions", demos["actions"]), ("next_obs", demos["next_observations"]),
        ("terminations", dones))}  # 'terminations': the done flag of --timeout-done, as in the replay buffer
    print(f"IQ-Learn: {args.value_loss} value term, alpha {args.alpha}, chi^2 at {args.chi2_actions} actions, "
          f"{'truncations count as done' if args.timeout_done else 'only terminations are done'}")

    # ALGO LOGIC: the agent and the online buffer ('terminated' holds the done flag of --timeout-done)
    agent = IQLearn(obs_dim, act_dim, low, high, args, device)
    rb = ReplayBuffer(obs_dim, act_dim, args.buffer_size, device)
    stateful = {"agent": agent, "q_optimizer": agent.q_optimizer, "actor_optimizer": agent.actor_optimizer,
                "replay_buffer": rb}
    run = Run(args, checkpoint, stateful, demos, device, checkpoint_freq=args.checkpoint_freq,
              learning_starts=args.learning_starts)

    # TRY NOT TO MODIFY: start the game
    obs, _ = env.reset(seed=args.seed + run.start_step)
    for global_step in range(run.start_step, args.total_timesteps):
        action = agent.actor.act(obs)  # no random warm-up (IQ-Learn's setting)
        next_obs, reward, terminated, truncated, info = env.step(action)
        rb.add(obs, action, next_obs, reward, terminated or (truncated and args.timeout_done))
        obs = next_obs
        if terminated or truncated:
            episode = info["episode"]
            run.log({"charts/episodic_return": episode["r"], "charts/episodic_length": episode["l"]}, global_step)
            obs, _ = env.reset()

        # ALGO LOGIC: training
        if rb.size >= args.learning_starts:
            batch = rb.sample(args.batch_size)
            idx = torch.randint(0, len(expert["obs"]), (args.batch_size,), device=device)
            metrics = agent.update(batch, {name: x[idx] for name, x in expert.items()})
            if global_step % 1000 == 0:
                run.log(metrics, global_step)
                if not all(torch.isfinite(value) for value in metrics.values()):
                    raise SystemExit(f"error: IQ-Learn's losses became NaN/inf at step {global_step}; try a larger "
                                     f"--alpha or the other --value-loss (IQ-Learn's critic is known to diverge)")
        run.end_step(global_step + 1, agent.actor.act)

    q_file = {"q": agent.q.state_dict(), "env_id": args.env_id, "obs_dim": obs_dim, "act_dim": act_dim,
              "hidden_dim": args.hidden_dim, "alpha": args.alpha, "gamma": args.gamma}
    run.finish(agent.actor.act, {"actor.pt": actor_file(agent.actor, args.env_id, training_steps=args.total_timesteps),
                                 "q.pt": q_file})
    env.close()
