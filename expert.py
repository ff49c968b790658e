"""Soft Actor-Critic experts for the MuJoCo tasks, and the demonstrations the imitation scripts learn from.

Paper: Haarnoja et al., "Soft Actor-Critic Algorithms and Applications", 2018, https://arxiv.org/abs/1812.05905

SAC learns a stochastic tanh-Gaussian policy and twin Q-functions off-policy, maximising return plus
entropy; the entropy temperature alpha is tuned so that the policy's entropy tracks -|A|. This script
trains it on the environment's own reward (`python expert.py --env-id Hopper-v4`), then records
demonstrations with the deterministic policy into `experts/<env-id>.npz` and copies the actor beside
them (`experts/<env-id>-actor.pt`). `python expert.py --env-id Hopper-v4 --record-from <actor.pt>`
records from any saved actor of this project without training.

The env, actor, SAC, demonstrations, evaluation and run blocks are gail.py's (see the `# --- shared:`
markers; tests/test_shared_blocks.py keeps the copies identical). What only this script needs comes
first: the fast update and acting paths, loading an actor, and recording demonstrations.

Implementation choices and deviations
1. Actor and critic are updated once per env step (the original SAC and SB3 cadence), not CleanRL's "policy every
   2 steps, twice". One learning rate (3e-4) for actor, critics and alpha, the RILe paper's; `--q-lr` sets the critics'.
2. The twin critics are one module whose weights carry a leading dimension of 2 (batched matmuls, one kernel per
   layer for both); the actor loss reads them through detached weights, so computes no gradient for them.
3. The replay buffer is one preallocated float tensor, a row [obs | action | next_obs | reward | terminated] per
   transition; only `terminated` stops bootstrapping (time-limit truncations keep it).
4. log pi of the squashed Gaussian uses log(1 - tanh(u)^2) = 2(log 2 - u - softplus(-2u)), exact and finite at
   the action bounds, instead of CleanRL's log(1 - tanh(u)^2 + 1e-6).
5. Speed flags: `--compile` (torch.compile of the update; off by default), `--cudagraphs` (GPU only: the whole
   update, optimiser steps included, and the acting step replayed from CUDA graphs), `--threads` (default 2).
6. `--resume runs/<run>` restores networks, optimisers, temperature, replay buffer, step, RNG states and evaluations;
   the episode in progress is cut (a new one starts), so a resumed run is deterministic but not bit-identical.
7. Demonstrations: the first `--num-demos` episodes of the deterministic policy on resets seeded `--demo-seed + i`,
   none filtered unless `--full-episodes-only` drops those ending before the time limit (metadata lists all tried).
8. Beside results.json the run keeps `actor_best.pt` (the actor of the best evaluation so far: experts are picked
   by it) and writes `actor.pt` with every checkpoint.

Logged metrics: charts/{episodic_return,episodic_length,SPS}, eval/{return,return_std,normalized_return},
losses/{qf_loss,qf_values,qf_target_var,actor_loss,alpha,alpha_loss,entropy}. Details: docs/expert.md
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
from typing import Annotated, NamedTuple, Optional

import gymnasium as gym
import numpy as np
import torch
import torch.nn as nn
import torch.nn.functional as F
import tyro


@dataclass
class Args:
    """SAC experts for the MuJoCo tasks: it trains SAC on the environment's own reward, then records demonstrations
    with the deterministic policy into experts/<env-id>.npz for the imitation scripts. Start it
    with `python expert.py --env-id Hopper-v4`; --record-from <actor.pt> records from a saved actor without training."""
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
    run_name: Annotated[Optional[str], tyro.conf.arg(
        help_behavior_hint="(default: {env_id}__{exp_name}__{seed}__{unix_time})")] = None
    """the run directory under runs/"""
    resume: Optional[str] = None
    """continue this run (directory or checkpoint) on its config; --total-timesteps, --cuda, speed flags may change"""
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
    """the replay buffer size"""
    gamma: float = 0.99
    """the discount factor"""
    tau: float = 0.005
    """the target smoothing coefficient"""
    batch_size: int = 256
    """the batch size of a SAC update"""
    learning_starts: int = 5_000
    """env steps of uniform random actions before any update"""
    policy_lr: float = 3e-4
    """the learning rate of the actor (and of alpha)"""
    q_lr: float = 3e-4
    """the learning rate of the critics"""
    alpha: float = 0.2
    """the entropy temperature (the initial value when autotuned)"""
    autotune: bool = True
    """tune the temperature towards -|A|"""
    hidden_dim: int = 256
    """width of the actor's and critics' two hidden layers"""
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
    demo_path: Annotated[Optional[str], tyro.conf.arg(help_behavior_hint="(default: experts/<env-id>.npz)")] = None
    """where to write the demonstrations"""
    full_episodes_only: bool = False
    """keep only episodes that reach the time limit, trying seeds from --demo-seed on until --num-demos are kept"""
    max_demo_tries: int = 200
    """with --full-episodes-only, give up after this many episodes"""
    no_actions: bool = False
    """write state-only demonstrations, without actions, as motion-capture data come (for gaifo.py, bco.py)"""


# What only expert.py needs: the fast update and acting paths (--compile, --cudagraphs), then the demonstrations
def make_update_fn(agent: "SAC", rb: "ReplayBuffer", args):
    """Returns step() -> metrics: one SAC update on a sampled batch with the env's reward, plain, compiled
    or replayed from a CUDA graph."""
    update = torch.compile(agent.update) if args.compile else agent.update
    learn = lambda batch: update(batch.obs, batch.actions, batch.next_obs, batch.rewards, batch.terminations)
    if not args.cudagraphs:
        return lambda: learn(rb.sample(args.batch_size))
    idx = torch.randint(0, rb.size, (args.batch_size,), device=rb.storage.device)  # the graph gathers these rows
    stream = torch.cuda.Stream()
    stream.wait_stream(torch.cuda.current_stream())
    with torch.cuda.stream(stream):  # warm-up on a side stream (these are real updates)
        for _ in range(3):
            learn(rb.batch(idx))
    torch.cuda.current_stream().wait_stream(stream)
    graph = torch.cuda.CUDAGraph()
    with torch.cuda.graph(graph):
        static_metrics = learn(rb.batch(idx))

    def step():
        torch.randint(0, rb.size, (args.batch_size,), device=idx.device, out=idx)
        graph.replay()
        return {name: value.clone() for name, value in static_metrics.items()}

    return step


def graphed_act(actor: "Actor", obs_dim: int, device):
    """actor.act with its two forward passes (sampled, mean) captured once in CUDA graphs and replayed."""
    static_obs = torch.zeros(1, obs_dim, device=device)
    graphs, outputs = {}, {}
    for det in (False, True):
        actor.act(np.zeros(obs_dim), det)  # warm-up
        graphs[det] = torch.cuda.CUDAGraph()
        with torch.no_grad(), torch.cuda.graph(graphs[det]):
            outputs[det] = actor.deterministic(static_obs) if det else actor.sample(static_obs)[0]

    def act(obs, deterministic=False):
        static_obs.copy_(torch.as_tensor(obs, dtype=torch.float32).unsqueeze(0))
        graphs[deterministic].replay()
        return outputs[deterministic][0].cpu().numpy()

    return act


def load_actor(path: str, env: gym.Env, device="cpu"):
    """Rebuild a saved actor (any script's actor.pt) for `env`, with clear errors for a missing file or
    another env's actor."""
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
    demos = {k: np.asarray(v, dtype=bool if k in ("terminations", "truncations") else np.float32)
             for k, v in buf.items()}
    demos.update(episode_starts=np.asarray(starts, dtype=np.int64), episode_lengths=np.asarray(lengths, dtype=np.int64),
                 episode_returns=np.asarray(returns, dtype=np.float64))
    return demos, tried


def save_demonstrations(path: str, demos: dict, metadata: dict) -> None:
    os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
    np.savez_compressed(path, **demos, metadata=np.array(json.dumps(metadata)))


def record_and_save(act, actor: "Actor", args, training_steps: int, source: str):
    """Record the demonstrations, write them with their metadata, copy the actor beside them, load them back."""
    import mujoco

    demo_path = args.demo_path or os.path.join("experts", f"{args.env_id}.npz")
    demos, tried = record_demonstrations(act, args.env_id, args.num_demos, args.demo_seed, args.full_episodes_only,
                                         args.max_demo_tries)
    if args.no_actions:
        del demos["actions"]
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
        "state_only": args.no_actions, "random_return": random_return(args.env_id),
        "actions": "none (state-only)" if args.no_actions else "env units (the env's action box), as sent to env.step",
        "created": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
    }
    save_demonstrations(demo_path, demos, metadata)
    actor_path = os.path.splitext(demo_path)[0] + "-actor.pt"
    if os.path.abspath(actor_path) != os.path.abspath(source):
        torch.save(actor_file(actor, args.env_id, training_steps=training_steps), actor_path)
    check = load_demonstrations(demo_path, make_env(args.env_id, args.seed), state_only=args.no_actions)  # round trip
    print(f"recorded {len(check['episode_lengths'])} episodes ({len(tried)} tried), {len(check['rewards'])} "
          f"transitions, return {returns.mean():.1f} +- {returns.std():.1f} (min {returns.min():.1f}) -> "
          f"{demo_path}, {actor_path}")


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


# --- shared: sac ---
class SAC:
    """Actor, twin critics, target critics and the temperature, with their optimisers; one `update` per env step.
    absorbing=True (DAC's absorbing states): observations carry a last indicator column, 1 at the absorbing state
    after a termination, which the actor never sees; there the only action is zero: no entropy, actor or alpha loss."""

    def __init__(self, obs_dim, act_dim, action_low, action_high, args, device, absorbing: bool = False):
        self.absorbing, self.gamma, self.tau, self.target_entropy = absorbing, args.gamma, args.tau, -float(act_dim)
        self.actor = Actor(obs_dim - absorbing, act_dim, action_low, action_high, args.hidden_dim).to(device)
        self.qf = TwinQ(obs_dim, act_dim, args.hidden_dim).to(device)
        self.qf_target = TwinQ(obs_dim, act_dim, args.hidden_dim).to(device).requires_grad_(False)
        self.qf_target.load_state_dict(self.qf.state_dict())
        self.log_alpha = torch.tensor(float(np.log(args.alpha)), device=device, requires_grad=args.autotune)
        self.q_optimizer = torch.optim.Adam(self.qf.parameters(), lr=args.q_lr, fused=True)
        self.actor_optimizer = torch.optim.Adam(self.actor.parameters(), lr=args.policy_lr, fused=True)
        self.alpha_optimizer = (torch.optim.Adam([self.log_alpha], lr=args.policy_lr, fused=True) if args.autotune
                                else None)

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
        """Both critics' squared TD errors, the mean Q-value, and the variance of the TD targets (their scale)."""
        q, target = self.qf(obs, actions), self.td_target(next_obs, rewards, terminations)
        return (q - target).pow(2).mean(1).sum(), q.mean(), target.var()

    def actor_loss(self, obs):
        actions, log_pi = self.policy(obs)
        q = self.qf(obs, actions, detach_params=True).min(0).values
        mean = torch.mean
        if self.absorbing:  # nothing to learn at the absorbing state: average over the other states
            live = 1.0 - obs[:, -1]
            mean = lambda x: (x * live).sum() / live.sum().clamp_min(1.0)
        alpha_loss = -mean(self.log_alpha.exp() * (log_pi.detach() + self.target_entropy))
        return mean(self.log_alpha.detach().exp() * log_pi - q), alpha_loss, -mean(log_pi.detach())

    def update(self, obs, actions, next_obs, rewards, terminations, prefix: str = "losses/") -> dict:
        """One SAC step: critics, then actor and temperature on the updated critics, then targets.
        Returns metric tensors keyed by their logged names (no .item() here: reading one synchronises)."""
        qf_loss, q_mean, target_var = self.critic_loss(obs, actions, next_obs, rewards, terminations)
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
        metrics = dict(qf_loss=qf_loss, qf_values=q_mean, qf_target_var=target_var, actor_loss=actor_loss,
                       alpha_loss=alpha_loss, entropy=entropy, alpha=self.log_alpha.exp())
        return {prefix + name: value.detach() for name, value in metrics.items()}

    def state_dict(self) -> dict:
        """Networks, optimisers and temperature: all a resumed run needs (CORL's pattern)."""
        parts = {name: part.state_dict() for name, part in vars(self).items() if hasattr(part, "load_state_dict")}
        return parts | {"log_alpha": self.log_alpha.detach()}

    def load_state_dict(self, state: dict) -> None:
        for name, part in vars(self).items():
            if hasattr(part, "load_state_dict"):
                part.load_state_dict(state[name])
        self.log_alpha.data.copy_(state["log_alpha"])
# --- end shared: sac ---


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
    keep = ("total_timesteps", "cuda", "threads", "compile", "cudagraphs")  # what a resumed run may change
    args, checkpoint = resume(args, keep) if args.resume else (args, None)
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
        record_and_save(actor.act, actor, args, ckpt.get("training_steps", -1), args.record_from)
        sys.exit(0)

    # ALGO LOGIC: the agent and its replay buffer
    agent = SAC(obs_dim, act_dim, env.action_space.low, env.action_space.high, args, device)
    if args.cudagraphs:  # the optimiser steps are captured in the update's CUDA graph: capturable optimisers
        adam = dict(capturable=True, fused=True)
        agent.q_optimizer = torch.optim.Adam(agent.qf.parameters(), lr=args.q_lr, **adam)
        agent.actor_optimizer = torch.optim.Adam(agent.actor.parameters(), lr=args.policy_lr, **adam)
        if args.autotune:
            agent.alpha_optimizer = torch.optim.Adam([agent.log_alpha], lr=args.policy_lr, **adam)
    rb = ReplayBuffer(obs_dim, act_dim, args.buffer_size, device)
    refill_until = 0
    if checkpoint and "replay_buffer" not in checkpoint:  # saved without its buffer: refill it before updating
        checkpoint["replay_buffer"], refill_until = rb.state_dict(), checkpoint["step"] + args.learning_starts
        print(f"warning: the checkpoint holds no replay buffer; the current policy refills it for "
              f"{args.learning_starts} steps before updates resume")
    run = Run(args, checkpoint, {"agent": agent, "replay_buffer": rb}, None, device,
              checkpoint_freq=args.checkpoint_freq, learning_starts=args.learning_starts)
    act = graphed_act(agent.actor, obs_dim, device) if args.cudagraphs else agent.actor.act
    update_step = None  # built when learning starts (CUDA graphs capture real batches)

    # TRY NOT TO MODIFY: start the game
    obs, _ = env.reset(seed=args.seed + run.start_step)
    for global_step in range(run.start_step, args.total_timesteps):
        if global_step < args.learning_starts:
            action = env.action_space.sample()
        else:
            action = act(obs)
        next_obs, reward, terminated, truncated, info = env.step(action)
        rb.add(obs, action, next_obs, reward, terminated)  # next_obs is the true one, also at truncation
        obs = next_obs
        if terminated or truncated:
            episode = info["episode"]
            run.log({"charts/episodic_return": episode["r"], "charts/episodic_length": episode["l"]}, global_step)
            obs, _ = env.reset()

        # ALGO LOGIC: training
        if global_step >= max(args.learning_starts, refill_until):
            update_step = update_step or make_update_fn(agent, rb, args)
            metrics = update_step()
            if global_step % 1000 == 0:
                run.log(metrics, global_step)

        step = global_step + 1
        if run.checkpoints.due(step):  # the newest actor beside each checkpoint
            torch.save(actor_file(agent.actor, args.env_id, training_steps=step), os.path.join(run.dir, "actor.pt"))
        run.end_step(step, act)
        if run.evals and run.evals[-1]["step"] == step:  # just evaluated: log the spread, keep the best actor
            run.log({"eval/return_std": run.evals[-1]["std"]}, step)
            if run.evals[-1]["mean"] >= max(e["mean"] for e in run.evals):
                torch.save(actor_file(agent.actor, args.env_id, training_steps=step, eval_return=run.evals[-1]["mean"]),
                           os.path.join(run.dir, "actor_best.pt"))

    run.finish(act, {"actor.pt": actor_file(agent.actor, args.env_id, training_steps=args.total_timesteps)})
    if args.record_demos:
        record_and_save(act, agent.actor, args, args.total_timesteps, os.path.join(run.dir, "actor.pt"))
    env.close()
