"""Does a frozen reward rank policies as the env does? Each actor is rolled out (mean action, then sampled) and every
step is scored with the frozen reward exactly as a fresh learner against it is paid (the script's defaults with the
file's reward flags; with absorbing states, a fall leads to the absorbing state, whose reward then repeats forever).

The covariate-shift experiment (docs/experiments.md) trains fresh students against a finished run's reward.pt. A
reward that transfers pays the demonstrator more than the source run's student, and that student more than a fresh
one that hops worse; where a fresh student earns more of the frozen reward than the source's student while the env
pays it less, the student optimised the reward and the reward does not transfer.

    python benchmarks/frozen_reward_rollouts.py benchmarks/rewards/Hopper-v4/gail-paperD-autotune__1.pt \\
        experts/Hopper-v4-actor.pt runs/source__Hopper-v4__gail-paperD-autotune__1 \\
        runs/bench__Hopper-v4__gail-paperD-autotune-shift0__1 --episodes 3

An actor is an actor.pt or a run directory holding one. Episode i starts from reset(seed=seed + i) for every actor;
the discounted frozen return (the student's gamma) is from the reset state and stops at the time limit. With `--out
FILE` the numbers also go to a json file; `sweep.py --report` reads those under
benchmarks/results/<env-id>/frozen-rollouts/<algo>.json into the covariate-shift section.
"""

import argparse
import json
import os
import pickle
import sys
from types import SimpleNamespace

import numpy as np
import torch

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
import airl  # noqa: E402
import gail  # noqa: E402
import rile  # noqa: E402  (the actor and env blocks are the same in every script)
from benchmarks.policy_modes import load_actor  # noqa: E402

SCRIPTS = {"rile.py": rile, "gail.py": gail, "airl.py": airl}


def frozen_reward(path: str, env_id: str, obs_dim: int, act_dim: int):
    """(absorbing, gamma, reward(batch, actor)) of a saved reward: the reward a learner of its script with default flags
    and the file's reward flags is paid on a batch dict (obs with the absorbing indicator column where the run used
    absorbing states, actions, next_obs, terminations); `actor` is the learner whose log pi airl.py's softplus reads."""
    try:
        saved = torch.load(path, map_location="cpu", weights_only=True)
        module = SCRIPTS[saved["script"]]
    except (OSError, KeyError, RuntimeError, EOFError, pickle.UnpicklingError) as e:
        sys.exit(f"error: {path} is not a reward.pt of rile.py, gail.py or airl.py ({type(e).__name__}: {e})")
    args = module.Args(env_id=env_id, **{name: saved[name] for name in module.REWARD_FLAGS})
    absorbing = args.termination_remedy == "absorbing"
    aug_dim = obs_dim + absorbing
    if module is airl:
        disc = airl.AIRLDiscriminator(aug_dim, act_dim, args.disc_hidden_dim, args.gamma, args.state_only, args.disc_lr,
                                      args.disc_gp, zero_absorbing_potential=absorbing and args.absorbing_anchor == "min",
                                      level_lr=args.disc_level_lr)
        airl.load_reward(path, disc, args, obs_dim, act_dim)
        anchor = absorbing and args.absorbing_anchor == "min"

        def reward(b, actor):
            learner = SimpleNamespace(actor=actor, absorbing=absorbing)  # what policy_log_prob reads of a SAC agent
            log_pi = airl.policy_log_prob(learner, b["obs"], b["actions"], args.disc_policy_mix)
            batch = airl.Batch(b["obs"], b["actions"], b["next_obs"], None, b["terminations"], None)
            return airl.sac_reward(disc, batch, args.reward, anchor, log_pi)
        return absorbing, args.gamma, reward
    seen = "next_obs" if getattr(args, "state_only", False) else "actions"
    disc = module.Discriminator(aug_dim + (aug_dim if seen == "next_obs" else act_dim), args.disc_hidden_dim,
                                args.disc_lr, args.disc_gp, args.disc_gp_center, None, args.disc_normalize == "pooled")
    d_input = lambda b: torch.cat([b["obs"], b[seen]], -1)
    if module is gail:
        gail.load_reward(path, disc, args, obs_dim, act_dim)
        return absorbing, args.gamma, lambda b, actor: gail.gail_reward(disc(d_input(b)), args.reward_form)
    trainer = rile.make_trainer(aug_dim, act_dim, args, "cpu") if args.student_reward == "trainer" else None
    rile.load_reward(path, trainer, disc, args, obs_dim, act_dim)
    if trainer is None:  # the control: v(D)
        return absorbing, args.gamma, lambda b, actor: rile.discriminator_reward(disc, d_input(b), args.termination_remedy)
    o_t = lambda b: rile.trainer_input(b["obs"], b["actions"], b["next_obs"], args.trainer_obs)
    return absorbing, args.gamma, lambda b, actor: rile.student_reward(trainer.actor, o_t(b), args.termination_remedy)


def episode_batch(obs, actions, next_obs, terminated: bool, absorbing: bool) -> dict:
    """One episode as the learner's buffer stores it: with absorbing states the indicator column, a fall leading to
    the absorbing state and its self-loop (zero action) as the last row."""
    obs, actions, next_obs = (np.asarray(x, dtype=np.float32) for x in (obs, actions, next_obs))
    terms = np.zeros(len(obs), dtype=np.float32)
    if absorbing:
        s_abs = rile.absorbing_state(obs.shape[1])
        obs, next_obs = (np.concatenate([x, np.zeros((len(x), 1), np.float32)], 1) for x in (obs, next_obs))
        if terminated:
            next_obs[-1] = s_abs
            obs, next_obs = np.vstack([obs, s_abs]), np.vstack([next_obs, s_abs])
            actions, terms = np.vstack([actions, np.zeros_like(actions[:1])]), np.append(terms, 0.0)
    else:
        terms[-1] = float(terminated)
    return {k: torch.as_tensor(v) for k, v in
            {"obs": obs, "actions": actions, "next_obs": next_obs, "terminations": terms}.items()}


def discounted(rewards: np.ndarray, gamma: float, absorbing_tail: bool) -> float:
    """sum_t gamma^t r_t from the reset state; with `absorbing_tail` the last reward is the absorbing state's, which
    repeats forever from there."""
    steps = rewards[:-1] if absorbing_tail else rewards
    total = float(np.sum(gamma ** np.arange(len(steps)) * steps))
    return total + (gamma ** len(steps) * rewards[-1] / (1 - gamma) if absorbing_tail else 0.0)


def score(actor: rile.Actor, env_id: str, reward, absorbing: bool, gamma: float, episodes: int, seed: int,
          deterministic: bool) -> dict:
    """Env return, length, falls, frozen reward per env step and discounted frozen return of each episode."""
    env, out = rile.make_env(env_id, seed), {"return": [], "length": [], "terminated": [], "frozen_per_step": [],
                                             "frozen_discounted": [], "frozen_absorbing": None}
    torch.manual_seed(seed)  # the sampled actions' noise
    for i in range(episodes):
        obs, _ = env.reset(seed=seed + i)
        rows, ret, terminated, truncated = [], 0.0, False, False
        while not (terminated or truncated):
            action = actor.act(obs, deterministic=deterministic)
            next_obs, r, terminated, truncated, _ = env.step(action)
            rows.append((obs, action, next_obs))
            obs, ret = next_obs, ret + float(r)
        with torch.no_grad():
            rewards = reward(episode_batch(*zip(*rows), terminated, absorbing), actor).numpy().astype(np.float64)
        tail = absorbing and terminated
        out["return"].append(ret), out["length"].append(len(rows)), out["terminated"].append(bool(terminated))
        out["frozen_per_step"].append(float(rewards[:len(rows)].mean()))
        out["frozen_discounted"].append(discounted(rewards, gamma, tail))
        if tail:
            out["frozen_absorbing"] = float(rewards[-1])
    env.close()
    return out


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("reward", help="a reward.pt (runs/<run>/reward.pt, or one under benchmarks/rewards/)")
    parser.add_argument("actors", nargs="+", help="actor.pt files or run directories holding one")
    parser.add_argument("--episodes", type=int, default=3)
    parser.add_argument("--seed", type=int, default=100_001)
    parser.add_argument("--out", help="also write the numbers to this json file")
    cli = parser.parse_args()
    torch.set_num_threads(1)
    actors = [(path, *load_actor(path)) for path in cli.actors]
    env_id = actors[0][2]
    if any(e != env_id for _, _, e in actors):
        sys.exit(f"error: the actors are of different envs ({', '.join(sorted({e for _, _, e in actors}))})")
    obs_dim, act_dim = actors[0][1].net[0].in_features, actors[0][1].fc_mean.out_features
    absorbing, gamma, reward = frozen_reward(cli.reward, env_id, obs_dim, act_dim)
    print(f"{cli.reward} on {env_id}: {cli.episodes} episodes per actor from reset seed {cli.seed}, gamma {gamma}"
          + (", absorbing states" if absorbing else ""))
    print("actor | action | env return | steps | falls | frozen reward per step | discounted frozen return")
    results = []
    for path, actor, _ in actors:
        for mode, det in (("mean", True), ("sampled", False)):
            s = score(actor, env_id, reward, absorbing, gamma, cli.episodes, cli.seed, det)
            results.append({"actor": path, "action": mode, **s})
            print(f"{path} | {mode} | {np.mean(s['return']):.1f} | {np.mean(s['length']):.0f} | "
                  f"{sum(s['terminated'])} of {cli.episodes} | {np.mean(s['frozen_per_step']):.3f} | "
                  f"{np.mean(s['frozen_discounted']):.2f}"
                  + (f" (absorbing state {s['frozen_absorbing']:.2f})" if s["frozen_absorbing"] is not None else ""))
    if cli.out:
        os.makedirs(os.path.dirname(cli.out) or ".", exist_ok=True)
        with open(cli.out, "w") as f:
            json.dump({"reward": cli.reward, "env_id": env_id, "episodes": cli.episodes, "seed": cli.seed,
                       "gamma": gamma, "absorbing": absorbing, "machine": rile.machine("cpu"),
                       "command": " ".join(["python", os.path.relpath(__file__)] + sys.argv[1:]), "rows": results},
                      f, indent=1)


if __name__ == "__main__":
    main()
