"""RILe: Reinforced Imitation Learning, with a SAC student, a SAC trainer and a GAIL-style discriminator.

Paper: Albaba, Christen, Langerak, Gebhardt, Hilliges, Black, "RILe: Reinforced Imitation Learning",
https://arxiv.org/abs/2406.08472 (no official code is public; this file follows the paper's text).

Three learners train together. A discriminator D(s, a) tells expert pairs (label 1) from the student's. A *trainer*,
itself a SAC agent, observes the student's pair o_T = (s, a_S) and acts with one scalar a_T in [-1, 1], rewarded
(default "exp-difference") with exp(-|(2D - 1) - a_T|), so that it learns to output v(D) = 2D - 1. The *student*, a
SAC agent on the env, is rewarded with the trainer's action, r_S = a_T. `diff gail.py rile.py` shows what RILe adds to
GAIL; `--student-reward discriminator` is the control that rewards the student with v(D) itself, with no trainer.

Implementation choices and deviations (the measurements behind each: docs/rile.md, one heading per choice)
1. Rewards are never stored: r_S is the current trainer's deterministic action on every sampled student batch, r_T
   comes from the current D on every trainer batch.
2. The trainer's transition is (o_T, a_T, o_T'), a_T sampled when the student acts; o_T' = (s', a'_S) with a'_S a
   fresh sample of the current student. Its episode ends where the student's does.
3. The trainer's and D's buffers (16,384 each) are windows over the newest of the student's transitions.
4. Discriminator: gail.py's (64-64 tanh, BCE, lr 3e-5, 32 + 32 pairs, one update per env step), the paper's gradient
   penalty weight 1 in DAC's one-centred form (the paper names no form); `--disc-gp-center 0`, `--disc-normalize`.
5. Freezing: the paper freezes the trainer "once its critic network converges" (threshold 0.1) and names no test.
   Ours: a moving average of the critic's TD loss beyond its targets' own variance, relative to r_T's variance, below
   0.1 for 10k steps, never before `--trainer-freeze-after` (3/4 of the run: 750k of the default 1M steps; on
   Hopper-v4 and HalfCheetah-v4 this guard, not the test, sets the step). A frozen trainer learns again once that
   error passes r_T's variance (`--trainer-release-threshold`; inf: the paper's one-way freeze); `--no-trainer-freeze`.
6. Termination bias (the paper is silent): r_S = a_T < 0 pays for ending episodes. `--termination-remedy absorbing`
   (default) adds DAC's absorbing states to student and expert data; `survival` pays (1 + a_T) / 2; `none`: the paper's.
7. Epsilon-greedy (`--epsilon` 0.2). The trainer's temperature is the paper's fixed 0.2; the student's is tuned
   towards -|A| (`--no-autotune`: the paper's 0.2).
8. A tenth of every trainer batch is expert pairs, each with a fresh a_T (`--trainer-expert-fraction 0.1`; 0 with
   --state-only). Kept: the paper's 0 did worse than both default seeds on HalfCheetah-v4 and Walker2d-v4.
9. The paper's experiments as flags: `--trainer-reward` (its six); `--expert-action-noise`, `--expert-state-noise`,
   drawn once per run from --seed, actions clipped unless `--no-expert-noise-clip` (its 0.2 and 0.5 on [-0.4, 0.4] are
   0.5 and 1.25 on [-1, 1]); covariate shift: `--reward-from` (a run's frozen trainer and D) with
   `--student-action-noise` (executed and stored); `--student-expert-fraction`.
10. From states only (`--state-only`): D scores (s, s') as in GAIfO; the trainer observes (s, a_S), or (s, s') with
   `--trainer-obs transition`.
11. The trainer's discount is 0.9 (`--trainer-gamma`). Its action does not change its next observation, so its best
   policy, a_T = v(D), is the same at any discount; the discount sets how far its critic bootstraps. Kept: at the
   paper's 0.99 its critic's error grew and Walker2d-v4 did worse than both default seeds.
12. The control (`--student-reward discriminator`, not in the paper): r_S = v(D) of the current D on every batch, no
   trainer, all else as the defaults. rile.py minus the control, 200k, 4 seeds, last quarter (normalized): Hopper-v4
   -0.019, HalfCheetah-v4 -0.015, Walker2d-v4 +0.008, every 95% interval across 0: no gain from the trainer shown.
13. The trainer's reward is the paper's exp-difference, of its six (`--trainer-reward`). On Hopper-v4 (seed 1, 200k)
   difference and multiplication, under which r_S also follows v(D), ended within 0.03 of it (final 0.96 and 1.00
   against 0.97, normalized), so it stays; sigmoid, a positive r_S rising with D, ended at 0.90; naive and exp-naive,
   which a_T does not enter, paid r_S of about 0 and taught nothing (final 0.05 and 0.32: a hopper that falls, one
   that stands still).

Logged: charts/*, eval/{return,normalized_return}, losses/{student,trainer}_*, losses/disc_*, disc/*_prob, reward/*,
trainer/{frozen,critic_loss_ema}; every --dynamics-freq steps the reward measures (r_S and D on demonstrations and
student, r_s_follows_d, the freeze statistics, RFDC, FS-RFDC, CPR) in results.json: docs/rile.md.
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


@dataclass
class Args:
    """RILe, reinforced imitation learning: a SAC student learns from the reward a second SAC agent, the trainer,
    gives it, and the trainer is rewarded by a discriminator that tells the expert's state-action pairs from the
    student's. Start it with `python rile.py --env-id Hopper-v4 --total-timesteps 200000` (demonstrations from
    experts/Hopper-v4.npz). "The paper" below is the RILe paper, arXiv 2406.08472."""
    exp_name: str = "rile"
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
    """save the actor (actor.pt) and the learned reward (reward.pt) in the run directory"""
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
    total_timesteps: int = 1_000_000
    """total env steps of training"""
    buffer_size: int = 1_000_000
    """the replay buffer size (the paper's)"""
    gamma: float = 0.99
    """the discount factor (the paper's)"""
    tau: float = 0.005
    """the target smoothing coefficient"""
    batch_size: int = 256
    """the batch size of a SAC update (the paper's)"""
    learning_starts: int = 5_000
    """env steps of uniform random actions before any update"""
    policy_lr: float = 3e-4
    """the learning rate of the actor (the paper's)"""
    q_lr: float = 3e-4
    """the learning rate of the critics (the paper's)"""
    alpha: float = 0.2
    """the entropy temperature (the paper's)"""
    autotune: bool = True
    """tune the student's temperature towards an entropy of -|A| (the paper's: --no-autotune, a fixed 0.2)"""
    hidden_dim: int = 256
    """width of the actor's and critics' two hidden layers (the paper's)"""
    epsilon: float = 0.2
    """probability that the student takes a uniform random action, epsilon-greedy (the paper's)"""
    termination_remedy: Literal["none", "survival", "absorbing"] = "absorbing"
    """absorbing: DAC's absorbing states for student and expert; survival: r_S = (1 + a_T) / 2; none (the paper's)"""
    eval_freq: int = 10_000
    """evaluate the deterministic policy every this many env steps"""
    eval_episodes: int = 10
    """episodes per evaluation"""

    # Trainer arguments
    student_reward: Literal["trainer", "discriminator"] = "trainer"
    """trainer: r_S = a_T (the paper's); discriminator: r_S = v(D) = 2D - 1 with no trainer, a control"""
    trainer_reward: Literal["difference", "exp-difference", "multiplication", "naive", "exp-naive",
                            "sigmoid"] = "exp-difference"
    """the trainer's reward, one of the paper's six; exp-difference: exp(-|v(D) - a_T|), v(D) = 2D - 1 (the paper's)"""
    trainer_buffer_size: int = 16_384
    """the trainer learns from this many most recent transitions (the paper's)"""
    trainer_batch_size: int = 256
    """the trainer's batch size (the paper's)"""
    trainer_hidden_dim: int = 256
    """width of the trainer's two hidden layers (the paper's)"""
    trainer_lr: float = 3e-4
    """the trainer's learning rate, actor and critics (the paper's)"""
    trainer_gamma: float = 0.9
    """the trainer's discount factor; its best action, v(D), does not depend on it (the paper's: 0.99)"""
    trainer_alpha: float = 0.2
    """the trainer's entropy temperature, fixed (the paper's)"""
    trainer_tau: float = 0.005
    """the trainer's target smoothing coefficient"""
    trainer_freeze: bool = True
    """freeze the trainer once its critic has converged (the paper's), by the --trainer-freeze-* test"""
    trainer_freeze_stat: Literal["relative", "reward", "excess", "loss"] = "excess"
    """freeze on critic loss L: excess (L - var targets)/var r_T, reward L/var r_T, relative L/var targets, loss L"""
    trainer_freeze_threshold: float = 0.1
    """freeze when the moving average (0.99) of --trainer-freeze-stat stays below this (the paper's)"""
    trainer_freeze_window: int = 10_000
    """env steps the statistic must stay below the threshold (0: the first crossing freezes)"""
    trainer_freeze_after: Annotated[Optional[int], tyro.conf.arg(
        help_behavior_hint="(default: 3/4 of --total-timesteps)")] = None
    """never freeze before this env step (on Hopper-v4 and HalfCheetah-v4 this, not the test, sets the step)"""
    trainer_freeze_min_updates: int = 10_000
    """never freeze before this many trainer updates"""
    trainer_release_threshold: float = 1.0
    """a frozen trainer learns again once the statistic on D's current rewards passes this (the paper's: inf, never)"""
    trainer_obs: Literal["state-action", "transition"] = "state-action"
    """what the trainer observes: the student's (s, a_S) (the paper's), or its (s, s') with --state-only"""

    # Discriminator arguments
    disc_hidden_dim: int = 64
    """width of the discriminator's two hidden layers (the paper's)"""
    disc_lr: float = 3e-5
    """the discriminator's learning rate (the paper's)"""
    disc_batch_size: int = 32
    """expert pairs and agent pairs per discriminator update, each (the paper's)"""
    disc_buffer_size: int = 16_384
    """the discriminator learns from this many most recent agent transitions (the paper's)"""
    disc_gp: float = 1.0
    """weight of the gradient penalty (the paper's)"""
    disc_gp_center: float = 1.0
    """the norm the gradient penalty pulls D's input gradient towards: 1, DAC's one-centred form, or 0, zero-centred"""
    disc_update_every: int = 1
    """one discriminator update every this many env steps (the paper's)"""
    disc_normalize: Literal["none", "demos", "pooled"] = "none"
    """standardise D's inputs: demos, by the demos' mean and std; pooled, by running ones; none (the paper's)"""

    # Imitation arguments
    expert_path: Annotated[Optional[str], tyro.conf.arg(help_behavior_hint="(default: experts/<env-id>.npz)")] = None
    """the demonstrations file"""
    num_expert_trajs: int = 25
    """use the first this many demonstration episodes (the paper's)"""
    state_only: bool = False
    """imitate from states only: D scores (s, s') instead of (s, a), and no demonstration actions are needed"""
    expert_action_noise: float = 0.0
    """std of Gaussian noise on the demonstrations' actions, drawn once per run from --seed, clipped to the box"""
    expert_noise_clip: bool = True
    """clip the noisy demonstration actions to the action box (--no-expert-noise-clip: leave them outside it)"""
    expert_state_noise: float = 0.0
    """std of Gaussian noise on the demonstrations' states and next states, drawn once per run from --seed"""
    student_expert_fraction: float = 0.0
    """share of every student batch drawn from expert pairs (the paper's; 0 to 1 in its expert-data experiment)"""
    trainer_expert_fraction: Annotated[Optional[float], tyro.conf.arg(
        help_behavior_hint="(default: 0.1, or 0 with --state-only)")] = None
    """share of every trainer batch drawn from expert pairs, each with a fresh a_T (the paper's: 0)"""
    reward_from: Optional[str] = None
    """covariate shift: a fresh student against this saved, frozen reward (runs/<run>/reward.pt)"""
    student_action_noise: float = 0.0
    """std of Gaussian noise on the actions the student executes while training, drawn every step (not in evaluation)"""
    dynamics_freq: int = 10_000
    """measure the learned reward (r_S, D, RFDC, FS-RFDC, CPR) into results.json every this many steps; 0 disables"""


# ALGO LOGIC: RILe's update and rewards (a block drail_disc.py shares), then the discriminator (gail.py's)
# --- shared: rile ---
def rile_update(student: "SAC", trainer: "SAC", disc: nn.Module, rb: "ReplayBuffer", expert: dict, args,
                state: dict, step: int) -> dict:
    """One round of the paper's Algorithm 2 at env step `step`: (1) the student learns from the current trainer's
    rewards, (2) the discriminator from expert pairs against the student's recent ones (every --disc-update-every
    steps), (3) the trainer from the current discriminator, and the freeze test. `state` (rile_state) holds
    frozen_at, reward_only (covariate shift: only the student learns) and the freeze statistic. `disc`: any
    discriminator with prob(x) and update(expert_x, policy_x) (gail.py's here, DRAIL's in drail_disc.py). `trainer`
    None: the control, whose student learns from v(D) itself (1) and which has no step (3)."""
    seen = "next_obs" if args.state_only else "actions"  # what D sees beside s: a_S, or s' with --state-only
    # (1) student: SAC on r_S = the current trainer's action on o_T = (s, a_S); with no trainer (the control), on v(D)
    batch = mix_expert(rb.sample(args.batch_size), expert, args.student_expert_fraction)
    if trainer is None:
        d_input = torch.cat([batch.obs, getattr(batch, seen)], -1)
        r_student = discriminator_reward(disc, d_input, args.termination_remedy)
    else:
        obs_trainer = trainer_input(batch.obs, batch.actions, batch.next_obs, args.trainer_obs)
        r_student = student_reward(trainer.actor, obs_trainer, args.termination_remedy)
    metrics = student.update(batch.obs, batch.actions, batch.next_obs, r_student, batch.terminations,
                             prefix="losses/student_")
    metrics["reward/learned_mean"] = r_student.mean()
    if state["reward_only"]:
        return metrics
    # (2) discriminator: expert pairs (label 1) against the most recent student pairs
    if step % args.disc_update_every == 0:
        idx = torch.randint(0, len(expert["obs"]), (args.disc_batch_size,), device=expert["obs"].device)
        policy = rb.sample(args.disc_batch_size, recent=args.disc_buffer_size)
        metrics |= disc.update(torch.cat([expert["obs"][idx], expert[seen][idx]], -1),
                               torch.cat([policy.obs, getattr(policy, seen)], -1))
    # (3) trainer: SAC on its recent transitions (o_T, a_T as stored, o_T'), r_T from the current discriminator, then
    # the freeze test. A frozen trainer is only watched, every 10 steps, on a forked random stream (as if unwatched)
    frozen = state["frozen_at"] is not None
    if trainer is None or (frozen and (step % 10 or args.trainer_release_threshold == float("inf"))):
        return metrics
    with torch.random.fork_rng([torch.cuda.current_device()] if rb.storage.is_cuda else [], enabled=frozen):
        idx = rb.indices(args.trainer_batch_size, recent=args.trainer_buffer_size)
        batch = mix_expert(rb.batch(idx), expert, args.trainer_expert_fraction, trainer, args.trainer_obs)
        obs_trainer, a_trainer = trainer_input(batch.obs, batch.actions, batch.next_obs, args.trainer_obs), batch.extra
        next_obs_trainer = lambda: trainer_next_obs(student, rb, idx, batch, args.trainer_obs)  # o_T' (choice 2)
        with torch.no_grad():
            d = disc.prob(torch.cat([batch.obs, getattr(batch, seen)], -1))
            r_trainer = TRAINER_REWARDS[args.trainer_reward](d, a_trainer.squeeze(-1))
            o_next = next_obs_trainer()
        transitions = (obs_trainer, a_trainer, o_next, r_trainer, batch.terminations)
        metrics |= watch(trainer, *transitions) if frozen else trainer.update(*transitions, prefix="losses/trainer_")
        metrics["reward/trainer_reward_mean"] = r_trainer.mean()
        track_freeze(trainer, metrics, r_trainer, batch.terminations, next_obs_trainer, args, state, step)
    return metrics


TRAINER_REWARDS = {  # the paper's six, for D's output d = D(s, a_S) in (0, 1) and the trainer's action a in [-1, 1]
    "difference": lambda d, a: -(2 * d - 1 - a).abs(),  # -|v(D) - a_T|, v(D) = 2D - 1
    "exp-difference": lambda d, a: torch.exp(-(2 * d - 1 - a).abs()),
    "multiplication": lambda d, a: (2 * d - 1) * a,
    "naive": lambda d, a: d,
    "exp-naive": lambda d, a: torch.exp(1 - d),
    "sigmoid": lambda d, a: d * torch.sigmoid(a),
}


def student_reward(trainer_actor, obs_trainer, remedy: str):
    """r_S: the trainer's deterministic action on its observation o_T; with remedy 'survival', mapped to [0, 1]."""
    with torch.no_grad():
        a_trainer = trainer_actor.deterministic(obs_trainer).squeeze(-1)
    return (1 + a_trainer) / 2 if remedy == "survival" else a_trainer


def discriminator_reward(disc: nn.Module, x, remedy: str):
    """The control's r_S, with no trainer: v(D) = 2D - 1 of the current discriminator on D's inputs x; with remedy
    'survival', mapped to [0, 1] as the trainer's action is (that is, D)."""
    v = 2 * disc.prob(x) - 1
    return (1 + v) / 2 if remedy == "survival" else v


def trainer_input(obs, actions, next_obs, trainer_obs: str):
    """What the trainer observes, o_T: the student's pair (s, a_S) (paper), or its transition (s, s')."""
    return torch.cat([obs, next_obs if trainer_obs == "transition" else actions], -1)


def make_trainer(obs_dim: int, act_dim: int, args, device) -> "SAC":
    """The trainer: a SAC agent on o_T whose one action a_T in [-1, 1] is the student's reward, with its own width,
    learning rate, discount and fixed temperature. It treats the absorbing state like any other observation."""
    trainer_args = replace(args, hidden_dim=args.trainer_hidden_dim, q_lr=args.trainer_lr, policy_lr=args.trainer_lr,
                           alpha=args.trainer_alpha, autotune=False, gamma=args.trainer_gamma, tau=args.trainer_tau)
    obs_trainer_dim = obs_dim + (obs_dim if args.trainer_obs == "transition" else act_dim)
    return SAC(obs_trainer_dim, 1, np.array([-1.0]), np.array([1.0]), trainer_args, device)


def trainer_acts(trainer: "SAC", obs, action, next_obs, terminated: bool, absorbing: bool, trainer_obs: str):
    """a_T for one env step of the student, sampled when the student acts and stored beside its transition; with
    absorbing states a termination leads to the absorbing state, and its self-loop gets an a_T too."""
    s_abs = absorbing_state(len(obs))
    indicated = (lambda s: np.append(s, 0.0)) if absorbing else (lambda s: s)  # env states: indicator 0
    sees = lambda s, a, s_next: np.concatenate([s, s_next if trainer_obs == "transition" else a])
    s_next = s_abs if absorbing and terminated else indicated(next_obs)
    a_trainer = trainer.actor.act(sees(indicated(obs), action, s_next))
    return a_trainer, trainer.actor.act(sees(s_abs, np.zeros_like(action), s_abs)) if absorbing and terminated else ()


def successor_next_obs(rb: "ReplayBuffer", idx, batch: "Batch"):
    """s'' for the trainer's next observation (s', s'') with --trainer-obs transition: the next_obs of the
    row stored after each sampled one where that row continues the episode (its obs is s'); at an episode's
    last stored step (a time limit) s' itself. With absorbing states a termination continues to the loop."""
    following = rb.batch((idx + 1) % rb.capacity)
    continues = (following.obs == batch.next_obs).all(-1, keepdim=True) & ((idx + 1) % rb.capacity != rb.pos)[:, None]
    return torch.where(continues, following.next_obs, batch.next_obs)


def trainer_next_obs(student: "SAC", rb: "ReplayBuffer", idx, batch: "Batch", trainer_obs: str):
    """o_T' for the trainer's batch: (s', a'_S) with a'_S a fresh sample of the current student (choice 2), or (s', s'')
    as the student went on with --trainer-obs transition."""
    if trainer_obs == "transition":
        return torch.cat([batch.next_obs, successor_next_obs(rb, idx, batch)], -1)
    return torch.cat([batch.next_obs, student.policy(batch.next_obs)[0]], -1)


def mix_expert(batch: "Batch", expert: dict, fraction: float, trainer: Optional["SAC"] = None, trainer_obs: str = ""):
    """Experiment (--student-expert-fraction, --trainer-expert-fraction): the first `fraction` of a batch's (obs,
    actions, next_obs, terminations) replaced by expert pairs; for the trainer's batch they get a fresh a_T."""
    n = int(round(fraction * len(batch.obs)))
    if n == 0:
        return batch
    idx = torch.randint(0, len(expert["obs"]), (n,), device=expert["obs"].device)
    keys = ("obs", "actions", "next_obs", "terminations")
    batch = batch._replace(**{k: torch.cat([expert[k][idx], getattr(batch, k)[n:]]) for k in keys})
    if trainer is not None:  # the trainer never acted on expert pairs
        with torch.no_grad():
            fresh = trainer.actor.sample(trainer_input(batch.obs, batch.actions, batch.next_obs, trainer_obs)[:n])[0]
        batch = batch._replace(extra=torch.cat([fresh, batch.extra[n:]]))
    return batch


def watch(trainer: "SAC", obs, actions, next_obs, rewards, terminations) -> dict:
    """A frozen trainer's critic loss on D's current rewards, without an update (what may release it: freeze_test)."""
    with torch.no_grad():
        loss, _, target_var = trainer.critic_loss(obs, actions, next_obs, rewards, terminations)
    return {"losses/trainer_qf_loss": loss, "losses/trainer_qf_target_var": target_var}


def track_freeze(trainer: "SAC", metrics: dict, r_trainer, terminations, next_obs_trainer, args, state: dict,
                 step: int) -> None:
    """The freeze's bookkeeping after each trainer update (or watch): every 10 steps the TD targets' own variance over
    a'_S and a'_T, a part of the TD loss no critic can remove, from two more draws on a forked random stream (so that
    they change nothing else in the run); then freeze_test."""
    if step % 10 == 0:
        with torch.random.fork_rng([torch.cuda.current_device()] if r_trainer.is_cuda else []), torch.no_grad():
            y1, y2 = (trainer.td_target(next_obs_trainer(), r_trainer, terminations) for _ in range(2))
        noise, prev = 0.5 * (y1 - y2).pow(2).mean(), state["target_noise_ema"]
        state["target_noise_ema"] = torch.where(prev.isfinite(), torch.lerp(prev, noise, 0.1), noise)
    loss, target_var = metrics["losses/trainer_qf_loss"], metrics["losses/trainer_qf_target_var"]
    freeze_test(loss, target_var, r_trainer.var(), args, state, step)


def freeze_test(critic_loss, target_var, reward_var, args, state: dict, step: int) -> None:
    """Freeze the trainer "once its critic network converges" (the paper's appendix; its threshold, not its test).
    The statistic (--trainer-freeze-stat, see freeze_statistic) is a moving average (0.99) over updates (over the
    watches, every 10 steps, while frozen) of the critics' TD loss: beyond its targets' own variance and relative to
    the variance of the trainer's reward r_T (`excess`), relative to r_T's variance (`reward`) or to the TD targets'
    (`relative`), or raw (`loss`). It must stay below the threshold for --trainer-freeze-window steps, and the
    freeze never comes before --trainer-freeze-after (3/4 of the run by default: the paper freezes "midway", its
    maze figure's reward still moves at 75 %, and the student is not to be confused "in the later stages of
    training"). A frozen trainer is watched (rile_update): once its critics' statistic on D's current rewards passes
    --trainer-release-threshold, it has stopped fitting them (the student has moved where the fixed reward is
    wrong), and it learns again."""
    ema = lambda name, x: torch.where(state[name].isfinite(), torch.lerp(state[name], x, 0.01), x)  # inf: none yet
    for name, x in (("critic_loss_ema", critic_loss), ("target_var_ema", target_var), ("reward_var_ema", reward_var)):
        state[name] = ema(name, x)
    state["trainer_updates"] += state["frozen_at"] is None
    if not args.trainer_freeze or step % 100:  # reading the statistic synchronises: every 100 steps
        return
    statistic = freeze_statistic(state, args.trainer_freeze_stat)
    if state["frozen_at"] is not None:  # watched: a critic that no longer fits what D says now has not converged
        if statistic > args.trainer_release_threshold:
            state["released_at"].append(step)
            state["frozen_at"] = state["below_since"] = None
            print(f"trainer released at step {step} ({args.trainer_freeze_stat} critic loss {statistic:.4f})",
                  flush=True)
        return
    if statistic >= args.trainer_freeze_threshold:
        state["below_since"] = None
        return
    state["below_since"] = step if state["below_since"] is None else state["below_since"]
    after = args.total_timesteps * 3 // 4 if args.trainer_freeze_after is None else args.trainer_freeze_after
    if (step - state["below_since"] >= args.trainer_freeze_window and step >= after
            and state["trainer_updates"] >= args.trainer_freeze_min_updates):
        state["frozen_at"] = step
        print(f"trainer frozen at step {step} ({args.trainer_freeze_stat} critic loss {statistic:.4f})", flush=True)


def freeze_statistic(state: dict, stat: str) -> float:
    """The trainer's critic loss (a moving average, two critics): raw, or relative to its targets' or its reward's
    variance; `excess`: the part of it beyond its targets' own variance, relative to its reward's variance."""
    loss = state["critic_loss_ema"].item()
    if stat == "excess":  # no estimate of the targets' variance yet (inf): not converged
        noise = state["target_noise_ema"].item()
        loss = loss - 2 * noise if noise < float("inf") else float("inf")
    scale = state["target_var_ema" if stat == "relative" else "reward_var_ema"].item()
    return loss if stat == "loss" else loss / max(2 * scale, 1e-8)


def rile_state(device) -> dict:
    """The trainer's bookkeeping, saved in every checkpoint."""
    inf = torch.tensor(float("inf"), device=device)
    return {"frozen_at": None, "reward_only": False, "trainer_updates": 0, "critic_loss_ema": inf,
            "target_var_ema": inf.clone(), "reward_var_ema": inf.clone(), "target_noise_ema": inf.clone(),
            "below_since": None, "released_at": []}


def check_rile_args(args):
    """What the flags rule out, as one-line errors; returns args with the defaults that depend on other flags set."""
    if args.trainer_expert_fraction is None:  # expert pairs in the trainer's batches need the expert's actions
        args = replace(args, trainer_expert_fraction=0.0 if args.state_only else 0.1)
    if args.trainer_obs == "transition" and not args.state_only:
        raise SystemExit("error: --trainer-obs transition goes with --state-only (a discriminator on transitions)")
    given = asdict(args)
    for name in ("epsilon", "student_expert_fraction", "trainer_expert_fraction"):
        if not 0.0 <= given[name] <= 1.0:
            raise SystemExit(f"error: --{name.replace('_', '-')} must lie in [0, 1]")
    for name in ("expert_action_noise", "student_expert_fraction", "trainer_expert_fraction"):
        if args.state_only and given[name] > 0:
            raise SystemExit(f"error: --{name.replace('_', '-')} needs the expert's actions, which --state-only "
                             "does not use")
    return args
# --- end shared: rile ---


# --- shared: discriminator ---
class Discriminator(nn.Module):
    """D(x) = sigmoid(logit(x)), expert = 1, trained with BCE and a gradient penalty on random interpolates of
    expert and policy inputs: one-centred (gp_center 1, DAC's) or zero-centred (gp_center 0). Inputs are
    standardised, (x - shift) / scale, and the penalty acts in those units: none by default; fixed `stats` (the
    demonstrations', `input_stats`); or `pooled`: the running mean and variance of every training batch, expert
    and policy inputs together, so that what separates the two is a few units whatever the env's scale."""

    def __init__(self, in_dim: int, hidden_dim: int, lr: float, gp_weight: float, gp_center: float = 1.0,
                 stats: Optional[tuple] = None, pooled: bool = False):
        super().__init__()
        self.net = nn.Sequential(
            nn.Linear(in_dim, hidden_dim), nn.Tanh(), nn.Linear(hidden_dim, hidden_dim), nn.Tanh(),
            nn.Linear(hidden_dim, 1)
        )
        shift, scale = stats if stats is not None else (torch.zeros(in_dim), torch.ones(in_dim))
        self.register_buffer("shift", torch.as_tensor(shift, dtype=torch.float32).clone())
        self.register_buffer("scale", torch.as_tensor(scale, dtype=torch.float32).clone())
        self.register_buffer("var", torch.ones(in_dim))  # pooled: the running variance behind `scale`
        self.register_buffer("updates", torch.zeros(()))
        self.gp_weight, self.gp_center, self.pooled = gp_weight, gp_center, pooled
        self.optimizer = torch.optim.Adam(self.parameters(), lr=lr)

    def forward(self, x):
        return self.net((x - self.shift) / self.scale).squeeze(-1)

    def load_state_dict(self, state: dict, strict: bool = True):
        """Files saved before inputs could be standardised have no statistics: none then."""
        none = {"shift": torch.zeros_like(self.shift), "scale": torch.ones_like(self.scale),
                "var": torch.ones_like(self.var), "updates": torch.zeros(())}
        return super().load_state_dict(none | dict(state), strict)

    @torch.no_grad()
    def update_stats(self, x):
        """pooled: move shift and scale towards the batch's mean and variance (a plain average over the first 1,000
        batches, then a moving average with rate 0.001); a column constant so far keeps scale 1."""
        self.updates += 1
        rate = (1.0 / self.updates).clamp(min=1e-3)
        self.shift.lerp_(x.mean(0), rate)
        self.var.lerp_(x.var(0), rate)
        self.scale.copy_(torch.where(self.var > 1e-12, self.var.sqrt(), 1.0))

    def loss(self, expert_x, policy_x):
        """BCE(D(expert), 1) + BCE(D(policy), 0) + gp_weight * E[(||grad_z logit(z_hat)|| - gp_center)^2], z the
        standardised inputs."""
        expert_z, policy_z = (expert_x - self.shift) / self.scale, (policy_x - self.shift) / self.scale
        expert_logits, policy_logits = self.net(expert_z).squeeze(-1), self.net(policy_z).squeeze(-1)
        bce = F.binary_cross_entropy_with_logits(expert_logits, torch.ones_like(expert_logits))
        bce = bce + F.binary_cross_entropy_with_logits(policy_logits, torch.zeros_like(policy_logits))
        eps = torch.rand(len(expert_x), 1, device=expert_x.device)
        z_hat = (eps * expert_z + (1 - eps) * policy_z).requires_grad_(True)
        grad = torch.autograd.grad(self.net(z_hat).sum(), z_hat, create_graph=True)[0]
        gp = (grad.norm(2, dim=1) - self.gp_center).pow(2).mean()
        expert_prob, policy_prob = torch.sigmoid(expert_logits).mean(), torch.sigmoid(policy_logits).mean()
        return bce + self.gp_weight * gp, bce, gp, expert_prob, policy_prob

    def update(self, expert_x, policy_x) -> dict:
        if self.pooled:
            self.update_stats(torch.cat([expert_x, policy_x]))
        loss, bce, gp, expert_prob, policy_prob = self.loss(expert_x, policy_x)
        self.optimizer.zero_grad(set_to_none=False)
        loss.backward()
        self.optimizer.step()
        metrics = {"losses/disc_loss": bce, "losses/disc_gp": gp, "disc/expert_prob": expert_prob,
                   "disc/policy_prob": policy_prob}
        return {name: value.detach() for name, value in metrics.items()}

    @torch.no_grad()
    def prob(self, x):
        return torch.sigmoid(self(x))


def input_stats(x):
    """Per-column mean and std of D's inputs on the demonstrations, for `--disc-normalize demos`; a column that is
    constant there (an absorbing indicator the demonstrations never set) is left as it is."""
    mean, std = x.mean(0), x.std(0)
    varies = std > 1e-6
    return torch.where(varies, mean, 0.0), torch.where(varies, std, 1.0)
# --- end shared: discriminator ---


# --- shared: reward measures ---
@torch.no_grad()
def reward_measures(reward, disc_prob, rb: "ReplayBuffer", expert: dict, absorbing: bool, measures: dict, step: int,
                    n: int, extra: Optional[dict] = None) -> dict:
    """The paper's measures of the learner's reward at `step`, r_S = reward(data) (None where `data`, a dict of obs,
    actions, next_obs, lacks what it needs) beside D = disc_prob(data): both on the demonstrations' pairs and on the
    learner's pairs of its last `n` steps (env states, not the absorbing loop), r_s_spread (demonstrations minus
    learner), r_s_follows_d (Pearson of r_S and v(D) = 2D - 1 on the learner's pairs), r_S at the absorbing state, and
    the reward dynamics as benchmarks/reward_dynamics.py defines them: RFDC (W1 between this interval's r_S and the
    previous one's), FS-RFDC (mean |change| of r_S on the demonstrations' pairs), CPR (Pearson correlation of r_S and
    the env reward over the interval). `measures` keeps the previous interval's rewards and the history, `extra`
    joins each entry."""
    recent = rb.batch((rb.pos - 1 - torch.arange(n, device=rb.storage.device)) % rb.capacity)._asdict()
    as_numpy = lambda x: None if x is None else x.cpu().numpy()
    live = lambda data: (data["obs"][:, -1] == 0).cpu().numpy() if absorbing else slice(None)  # env states
    mean = lambda x, rows: float(x[rows].mean()) if x is not None and len(x[rows]) else None
    r_student, d_student = as_numpy(reward(recent)), as_numpy(disc_prob(recent))
    r_demos, rows = as_numpy(reward(expert)), live(recent)
    with np.errstate(invalid="ignore", divide="ignore"):  # a constant reward has no correlation
        cpr = float(np.corrcoef(r_student, recent["rewards"].cpu().numpy())[0, 1])
        follows = float(np.corrcoef(r_student[rows], 2 * d_student[rows] - 1)[0, 1])
    last_student, last_demos = measures["interval"], measures["demos"]
    out = {"step": step, "r_s_demos": mean(r_demos, live(expert)), "r_s_student": mean(r_student, rows),
           "d_demos": mean(as_numpy(disc_prob(expert)), live(expert)), "d_student": mean(d_student, rows),
           "r_s_follows_d": None if np.isnan(follows) else follows, "r_s_absorbing": None, **(extra or {}),
           "rfdc": float(np.abs(np.sort(r_student) - np.sort(last_student)).mean())
           if last_student is not None and len(last_student) == n else None,
           "fs_rfdc": float(np.abs(r_demos - last_demos).mean())
           if last_demos is not None and r_demos is not None else None,
           "cpr": None if np.isnan(cpr) else cpr}
    if out["r_s_demos"] is not None:
        out["r_s_spread"] = out["r_s_demos"] - out["r_s_student"]
    if absorbing:  # the absorbing self-loop's reward: (s_abs, 0 action, s_abs)
        s_abs = torch.as_tensor(absorbing_state(rb.obs_dim - 1), device=rb.storage.device)[None]
        out["r_s_absorbing"] = float(reward({"obs": s_abs, "actions": torch.zeros_like(s_abs[:, : rb.act_dim]),
                                             "next_obs": s_abs, "terminations": s_abs[:, 0]})[0])
    measures.update(interval=r_student, demos=r_demos)
    measures["history"].append(out)
    return out
# --- end shared: reward measures ---


# --- shared: frozen reward ---
def saved_reward(path: str, script: str, env_id: str, obs_dim: int, act_dim: int, flags: dict) -> dict:
    """The reward.pt that --reward-from names: what a finished run of `script` saved on `env_id`, with the same dims and
    the same `flags` (the Args fields that shape its reward, as this run has them); else a one-line error naming which
    differs. Covariate shift: a fresh learner trains against it, frozen."""
    fail = lambda problem: SystemExit(f"error: reward '{path}' {problem}")
    if not os.path.isfile(path):
        raise fail(f"does not exist; a finished {script} run writes runs/<run>/reward.pt")
    try:
        saved = torch.load(path, map_location="cpu", weights_only=True)
    except Exception as e:
        raise fail(f"is unreadable ({type(e).__name__}: {e})") from None
    if saved.get("script") != script:
        raise fail(f"was saved by {saved.get('script', 'an older version')}, not {script}; train against it there")
    if saved["env_id"] != env_id:
        raise fail(f"was learned on {saved['env_id']}, not {env_id}")
    if (saved["obs_dim"], saved["act_dim"]) != (obs_dim, act_dim):
        raise fail(f"has obs/act dims {saved['obs_dim']}/{saved['act_dim']}, {env_id} has {obs_dim}/{act_dim}")
    for name, value in flags.items():
        if saved.get(name) != value:
            raise fail(f"was learned with --{name.replace('_', '-')} {saved.get(name)}; pass the same to train "
                       "against it")
    return saved
# --- end shared: frozen reward ---


def rile_measures(trainer: "SAC", disc: "Discriminator", rb: "ReplayBuffer", expert: dict, args, state: dict,
                  measures: dict, step: int) -> dict:
    """reward_measures for RILe's r_S (the trainer's action; r_s_follows_d: whether the trainer passes D on), with the
    freeze test's statistics, every --dynamics-freq steps."""
    seen = "next_obs" if args.state_only else "actions"
    d_input = lambda data: torch.cat([data["obs"], data[seen]], -1)

    def r_student(data):  # o_T needs the student's action, which the demonstrations lack with --state-only
        if trainer is None:  # the control: v(D)
            return discriminator_reward(disc, d_input(data), args.termination_remedy)
        if "actions" not in data and args.trainer_obs != "transition":
            return None
        o_t = trainer_input(data["obs"], data.get("actions"), data["next_obs"], args.trainer_obs)
        return student_reward(trainer.actor, o_t, args.termination_remedy)
    learning = state["trainer_updates"] > 0
    extra = {"trainer_frozen_at": state["frozen_at"],
             "critic_loss": state["critic_loss_ema"].item() if learning else None,
             "critic_loss_relative": freeze_statistic(state, "relative") if learning else None,
             "critic_loss_to_reward": freeze_statistic(state, "reward") if learning else None,
             "critic_excess_to_reward": x if learning and (x := freeze_statistic(state, "excess")) < float("inf")
             else None}
    return reward_measures(r_student, lambda data: disc.prob(d_input(data)), rb, expert,
                           args.termination_remedy == "absorbing", measures, step, min(args.dynamics_freq, rb.size),
                           extra)


REWARD_FLAGS = ("student_reward", "trainer_obs", "trainer_hidden_dim", "disc_hidden_dim", "termination_remedy",
                "state_only")  # what shapes the saved reward


def reward_file(trainer: Optional["SAC"], disc: "Discriminator", args, obs_dim: int, act_dim: int) -> dict:
    """What reward.pt holds: the learned reward (the trainer's actor gives r_S; the control's, None: D does) and the
    discriminator, which --reward-from freezes to train a fresh student against."""
    return {"script": "rile.py", "trainer_actor": trainer and trainer.actor.state_dict(), "disc": disc.state_dict(),
            "env_id": args.env_id, "obs_dim": obs_dim, "act_dim": act_dim,
            **{name: getattr(args, name) for name in REWARD_FLAGS}}


def load_reward(path: str, trainer: Optional["SAC"], disc: "Discriminator", args, obs_dim: int, act_dim: int) -> dict:
    """--reward-from: a rile.py reward.pt into `trainer` (none for the control) and `disc`, which no update changes from
    then on."""
    saved = saved_reward(path, "rile.py", args.env_id, obs_dim, act_dim, {k: getattr(args, k) for k in REWARD_FLAGS})
    if trainer is not None:
        trainer.actor.load_state_dict(saved["trainer_actor"])
    disc.load_state_dict(saved["disc"])
    return saved


# --- shared: absorbing ---
def absorbing_state(obs_dim: int) -> np.ndarray:
    """DAC's absorbing state for observations of `obs_dim`: zeros, then the indicator column set to 1."""
    return np.append(np.zeros(obs_dim, dtype=np.float32), np.float32(1.0))


def store(rb: "ReplayBuffer", obs, action, next_obs, reward, terminated, absorbing: bool, extra=(), absorbing_extra=()):
    """Store one env transition. With absorbing states (DAC, Kostrikov et al. 2019) observations get an indicator
    column (0); a termination leads to the absorbing state instead and is no longer terminal, and the row
    (absorbing state, zero action, absorbing state; extra columns `absorbing_extra`) follows it, so ending an
    episode is worth the learned reward of the absorbing state forever, not an implicit 0."""
    if not absorbing:
        return rb.add(obs, action, next_obs, reward, terminated, extra)
    s_abs = absorbing_state(len(obs))
    rb.add(np.append(obs, 0.0), action, s_abs if terminated else np.append(next_obs, 0.0), reward, False, extra)
    if terminated:
        rb.add(s_abs, np.zeros_like(action), s_abs, 0.0, False, absorbing_extra)


def absorbing_expert(expert: dict) -> dict:
    """store()'s treatment of the demonstrations (a dict of tensors): the indicator column, terminal transitions
    lead to the absorbing state, one absorbing self-loop (zero action) per termination."""
    obs, next_obs, term = expert["obs"], expert["next_obs"], expert["terminations"] > 0
    s_abs = torch.as_tensor(absorbing_state(obs.shape[1]), device=obs.device)
    loops = s_abs.expand(int(term.sum()), -1)
    next_obs = torch.where(term.unsqueeze(-1), s_abs, F.pad(next_obs, (0, 1)))
    out = {**expert, "obs": torch.cat([F.pad(obs, (0, 1)), loops]), "next_obs": torch.cat([next_obs, loops]),
           "terminations": obs.new_zeros(len(obs) + len(loops))}
    if "actions" in expert:
        out["actions"] = F.pad(expert["actions"], (0, 0, 0, len(loops)))
    return out
# --- end shared: absorbing ---


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


# --- shared: expert data ---
def expert_tensors(demos: dict, seed: int, device, state_noise: float = 0.0, action_noise: float = 0.0,
                   action_low=None, action_high=None) -> dict:
    """The expert transitions as tensors, the noise-robustness experiment's noise added once (actions in the box)."""
    rng = np.random.default_rng(seed + 1)
    obs, next_obs, actions = demos["observations"], demos["next_observations"], demos.get("actions")
    if state_noise > 0:
        obs = obs + rng.normal(0, state_noise, obs.shape).astype(np.float32)
        next_obs = next_obs + rng.normal(0, state_noise, next_obs.shape).astype(np.float32)
    if action_noise > 0:
        actions = np.clip(actions + rng.normal(0, action_noise, actions.shape), action_low, action_high)
    as_tensor = lambda x: torch.as_tensor(np.asarray(x, dtype=np.float32), device=device)
    expert = {"obs": as_tensor(obs), "next_obs": as_tensor(next_obs), "terminations": as_tensor(demos["terminations"])}
    return expert if actions is None else expert | {"actions": as_tensor(actions)}
# --- end shared: expert data ---


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
    args = check_rile_args(args)
    torch.set_num_threads(args.threads)
    device = torch.device("cuda" if torch.cuda.is_available() and args.cuda else "cpu")
    seed_everything(args.seed, args.torch_deterministic)
    env = make_env(args.env_id, args.seed)
    obs_dim, act_dim = env.observation_space.shape[0], env.action_space.shape[0]
    low, high = env.action_space.low, env.action_space.high
    demos = load_demonstrations(args.expert_path or f"experts/{args.env_id}.npz", env, args.num_expert_trajs,
                                args.state_only)
    clip = (low, high) if args.expert_noise_clip else (-np.inf, np.inf)  # where noisy expert actions may lie
    expert = expert_tensors(demos, args.seed, device, args.expert_state_noise, args.expert_action_noise, *clip)
    absorbing = args.termination_remedy == "absorbing"
    if absorbing:
        expert = absorbing_expert(expert)

    # ALGO LOGIC: the student, the trainer, the discriminator and one buffer (a_T in its extra column)
    aug_dim = obs_dim + absorbing  # with absorbing states, every stored observation has the indicator column
    student = SAC(aug_dim, act_dim, low, high, args, device, absorbing=absorbing)
    trainer = make_trainer(aug_dim, act_dim, args, device) if args.student_reward == "trainer" else None  # the control
    seen = "next_obs" if args.state_only else "actions"  # what D sees beside s
    stats = input_stats(torch.cat([expert["obs"], expert[seen]], -1)) if args.disc_normalize == "demos" else None
    disc = Discriminator(aug_dim + (aug_dim if args.state_only else act_dim), args.disc_hidden_dim, args.disc_lr,
                         args.disc_gp, args.disc_gp_center, stats, args.disc_normalize == "pooled").to(device)
    rb = ReplayBuffer(aug_dim, act_dim, args.buffer_size, device, extra_dim=int(trainer is not None))
    state = rile_state(device) | {"reward_only": bool(args.reward_from)}
    if args.reward_from:  # covariate shift: a frozen learned reward, only the student learns
        load_reward(args.reward_from, trainer, disc, args, obs_dim, act_dim)
        state["frozen_at"] = 0
    measures = {"interval": None, "demos": None, "history": []}  # reward_measures' memory
    stateful = {"student": student, "disc": disc, "disc_optimizer": disc.optimizer, "replay_buffer": rb, "rile": state,
                "measures": measures} | ({"trainer": trainer} if trainer is not None else {})
    run = Run(args, checkpoint, stateful, demos, device, checkpoint_freq=args.checkpoint_freq,
              learning_starts=args.learning_starts)
    run.extra = {"trainer_frozen_at": state["frozen_at"], "trainer_released_at": state["released_at"],
                 "reward_measures": measures["history"]}

    # TRY NOT TO MODIFY: start the game
    obs, _ = env.reset(seed=args.seed + run.start_step)
    for global_step in range(run.start_step, args.total_timesteps):
        if global_step < args.learning_starts or random.random() < args.epsilon:
            action = env.action_space.sample()
        else:
            action = student.actor.act(obs)
        if args.student_action_noise > 0:  # covariate shift: the env executes, and the buffer stores, a noisy action
            noise = np.random.normal(0, args.student_action_noise, act_dim)
            action = np.clip(action + noise, low, high).astype(np.float32)
        next_obs, reward, terminated, truncated, info = env.step(action)
        a_trainer, a_trainer_absorbing = (), ()  # the control: no trainer acts
        if trainer is not None:
            a_trainer, a_trainer_absorbing = trainer_acts(trainer, obs, action, next_obs, terminated, absorbing,
                                                          args.trainer_obs)
        store(rb, obs, action, next_obs, reward, terminated, absorbing, a_trainer, a_trainer_absorbing)  # reward: CPR
        obs = next_obs
        if terminated or truncated:
            episode = info["episode"]
            run.log({"charts/episodic_return": episode["r"], "charts/episodic_length": episode["l"]}, global_step)
            obs, _ = env.reset()

        # ALGO LOGIC: training
        if global_step >= args.learning_starts:
            metrics = rile_update(student, trainer, disc, rb, expert, args, state, global_step)
            if global_step % 1000 == 0:
                frozen = float(state["frozen_at"] is not None)
                metrics |= {"trainer/critic_loss_ema": state["critic_loss_ema"], "trainer/frozen": frozen}
                run.log(metrics, global_step)

        step = global_step + 1
        if args.dynamics_freq and step % args.dynamics_freq == 0 and step > args.learning_starts:
            out = rile_measures(trainer, disc, rb, expert, args, state, measures, step)
            run.log({f"dynamics/{key}": value for key, value in out.items() if key != "step"}, step)
            run.extra["trainer_frozen_at"] = state["frozen_at"]
            save_file(os.path.join(run.dir, "dynamics.json"), measures["history"])
        run.end_step(step, student.actor.act)

    run.extra["trainer_frozen_at"] = state["frozen_at"]
    actor = actor_file(student.actor, args.env_id, training_steps=args.total_timesteps)
    run.finish(student.actor.act, {"actor.pt": actor,
                                   "reward.pt": reward_file(trainer, disc, args, obs_dim, act_dim)})
    env.close()
