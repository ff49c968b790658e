"""A saved policy with its mean action and with sampled actions: returns, episode lengths, falls and turnovers.

Every script evaluates the mean action; its student was trained, and judged by its discriminator, on sampled ones.
Where a run's evaluations swing while its training episodes hold, this tells which policy falls and where.

    python benchmarks/policy_modes.py runs/bench__Walker2d-v4__rile-paperD__1/actor.pt --episodes 10

Episode i starts from reset(seed=seed + i); the default seed is the one the scripts' evaluations use for seed 1.
HalfCheetah never terminates: a cheetah that turns onto its back (torso pitch beyond 90 degrees) stays there and
scores near nothing, so for it the step of each turnover is shown too.
"""

import argparse
import os
import pickle
import sys

import numpy as np
import torch

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
import rile  # noqa: E402  (the actor and env blocks are the same in every script)


TORSO_PITCH = {"HalfCheetah-v4": 1, "HalfCheetah-v5": 1}  # the observation's torso pitch (radians), where it can turn


def turned_over(pitch: np.ndarray):
    """The first step (counted from 1) after which |torso pitch| exceeds pi/2 (on its back), or None."""
    over = np.flatnonzero(np.abs(pitch) > np.pi / 2)
    return int(over[0]) + 1 if len(over) else None


def rollouts(actor: rile.Actor, env_id: str, episodes: int, seed: int, deterministic: bool):
    """(return, length, terminated, first step on its back or None) of each episode."""
    env, out = rile.make_env(env_id, seed), []
    torch.manual_seed(seed)  # the sampled actions' noise
    for i in range(episodes):
        obs, _ = env.reset(seed=seed + i)
        ret, length, terminated, truncated, pitch = 0.0, 0, False, False, []
        while not (terminated or truncated):
            obs, reward, terminated, truncated, _ = env.step(actor.act(obs, deterministic=deterministic))
            ret, length = ret + float(reward), length + 1
            pitch.append(obs[TORSO_PITCH[env_id]] if env_id in TORSO_PITCH else 0.0)
        out.append((ret, length, terminated, turned_over(np.array(pitch))))
    env.close()
    return out


def load_actor(path: str) -> tuple:
    """(actor, env id) of an actor.pt any script wrote, or of a run directory holding one; else a one-line error."""
    file = os.path.join(path, "actor.pt") if os.path.isdir(path) else path
    try:
        saved = torch.load(file, map_location="cpu", weights_only=False)
        env = rile.make_env(saved["env_id"], 0)
        actor = rile.Actor(saved["obs_dim"], saved["act_dim"], env.action_space.low, env.action_space.high,
                           saved["hidden_dim"])
        actor.load_state_dict(saved["actor"])
    except (OSError, KeyError, RuntimeError, EOFError, pickle.UnpicklingError) as e:
        sys.exit(f"error: {file} is not a readable actor.pt ({type(e).__name__}: {e})")
    return actor, saved["env_id"]


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("actor", help="an actor.pt written by any of the scripts")
    parser.add_argument("--episodes", type=int, default=10)
    parser.add_argument("--seed", type=int, default=100_001)
    cli = parser.parse_args()
    torch.set_num_threads(1)
    actor, env_id = load_actor(cli.actor)
    print(f"{cli.actor}: {env_id}, {cli.episodes} episodes from reset seed {cli.seed}")
    for name, det in (("mean action", True), ("sampled", False)):
        eps = rollouts(actor, env_id, cli.episodes, cli.seed, det)
        rets, lens = np.array([e[0] for e in eps]), np.array([e[1] for e in eps])
        falls = [int(e[1]) for e in eps if e[2]]
        print(f"{name:11s}: return {rets.mean():8.1f} +- {rets.std():6.1f} (min {rets.min():.0f}, max {rets.max():.0f}), "
              f"return per step {rets.sum() / lens.sum():.2f}, {len(falls)} of {len(eps)} terminated"
              + (f" at steps {sorted(falls)}" if falls else ""))
        if env_id in TORSO_PITCH:
            over = [e[3] for e in eps if e[3] is not None]
            print(f"{'':13s}{len(over)} of {len(eps)} turned onto its back"
                  + (f", first at steps {sorted(over)}" if over else ""))


if __name__ == "__main__":
    main()
