"""Reward-function dynamics (the RILe paper's RFDC, FS-RFDC and CPR) for rile.py, gail.py and airl.py alike.

rile.py and gail.py log them themselves (`--dynamics-freq`, runs/<run>/dynamics.json); airl.py does not. This
tool measures all three the same way, from outside: a run is trained in segments (`--resume` with a
larger `--total-timesteps` each time, the scripts' own code path), and after every segment its learned
reward (reward.pt), its actor (actor.pt) and the segment's transitions (the newest rows of the
checkpoint's replay buffer) are kept in runs/<run>/snapshots/<step>/. `measure` then applies the formulas
below (`RewardDynamics`, the same as rile.py's `reward_measures`) to them, so that for a rile.py run with
--dynamics-freq equal to the segment length it reproduces the run's dynamics.json (tests/test_maze.py checks it).

    python benchmarks/reward_dynamics.py train gail.py --run-name hop_gail --segment-steps 10000 --segments 20 \
        -- --env-id Hopper-v4
    python benchmarks/reward_dynamics.py measure runs/hop_gail     # writes runs/hop_gail/reward_dynamics.json
    python benchmarks/reward_dynamics.py plot runs/hop_rile runs/hop_gail runs/hop_airl --out dyn.png

What "the learned reward" is, per script (the reward its learner is trained with, on the interval's
stored transitions and on all expert transitions):
- rile.py: r_S, the trainer's deterministic action on (s, a_S) (with --termination-remedy survival, (1 + a_T) / 2);
- gail.py: its SAC reward, --reward-form of D's logit on (s, a);
- airl.py: f(s, a, s') = g(s, a) + gamma h(s') - h(s) (or g with --reward g).
"""

import argparse
import json
import os
import shutil
import subprocess
import sys

import numpy as np
import torch

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)
import airl  # noqa: E402
import gail  # noqa: E402
import rile  # noqa: E402

METRICS = ("rfdc", "fs_rfdc", "cpr")
LABELS = {"rfdc": "RFDC (W1 between consecutive intervals)", "fs_rfdc": "FS-RFDC (mean |change| on expert pairs)",
          "cpr": "CPR (Pearson with env reward)"}


# ---------------------------------------------------------------- training in segments


def train_segments(script: str, run_name: str, segment_steps: int, segments: int, extra=(), log=None) -> str:
    """Train `script` for segments x segment_steps env steps, one process per segment (the first starts the
    run, the others --resume it), keeping a snapshot after each. Returns the run directory. A segment whose
    snapshot exists is skipped, so an interrupted experiment continues where it stopped."""
    run_dir = os.path.join("runs", run_name)
    for k in range(1, segments + 1):
        steps = k * segment_steps
        if os.path.isdir(snapshot_dir(run_dir, steps)):
            continue
        cmd = [sys.executable, "-W", "ignore", os.path.join(ROOT, script), "--total-timesteps", str(steps), "--threads", "1"]
        resuming = os.path.exists(os.path.join(run_dir, "checkpoint.pt"))
        # a checkpoint at each segment's end (the last flag wins): the next segment resumes from it
        cmd += ["--resume", run_dir] if resuming else ["--run-name", run_name, *extra, "--checkpoint-freq", str(segment_steps)]
        out = subprocess.run(cmd, stdout=log, stderr=subprocess.STDOUT if log else None)
        if out.returncode != 0:
            raise SystemExit(f"error: {' '.join(cmd)} failed ({out.returncode})")
        keep_snapshot(run_dir, steps, segment_steps)
    return run_dir


def snapshot_dir(run_dir: str, step: int) -> str:
    return os.path.join(run_dir, "snapshots", f"{step:08d}")


def keep_snapshot(run_dir: str, step: int, interval: int) -> None:
    """Copy actor.pt and reward.pt aside and store the last `interval` rows of the replay buffer."""
    ckpt = torch.load(os.path.join(run_dir, "checkpoint.pt"), map_location="cpu", weights_only=False)
    if ckpt["step"] != step:
        raise SystemExit(f"error: {run_dir}'s checkpoint is at step {ckpt['step']}, expected {step}")
    rb = ckpt["replay_buffer"]
    if rb["pos"] < interval or rb["size"] > rb["pos"]:
        raise SystemExit(f"error: {run_dir}'s replay buffer wrapped around; give it --buffer-size above the run's length")
    folder = snapshot_dir(run_dir, step)
    os.makedirs(folder + ".tmp", exist_ok=True)
    for name in ("actor.pt", "reward.pt"):
        shutil.copy(os.path.join(run_dir, name), os.path.join(folder + ".tmp", name))
    np.save(os.path.join(folder + ".tmp", "interval_rows.npy"), rb["storage"][rb["pos"] - interval : rb["pos"]].numpy())
    os.replace(folder + ".tmp", folder)  # a snapshot exists whole or not at all


def snapshots(run_dir: str) -> list:
    """The steps of a run's snapshots, in order."""
    folder = os.path.join(run_dir, "snapshots")
    return sorted(int(name) for name in os.listdir(folder) if name.isdigit()) if os.path.isdir(folder) else []


# ---------------------------------------------------------------- a snapshot's learned reward


class Snapshot:
    """One snapshot's actor and learned reward, rebuilt with the script's own classes.
    obs: env observations (without the absorbing indicator; it is added here where the run used it)."""

    def __init__(self, run_dir: str, step: int):
        folder = snapshot_dir(run_dir, step)
        with open(os.path.join(run_dir, "results.json")) as f:
            self.config = json.load(f)["config"]
        self.saved = torch.load(os.path.join(folder, "reward.pt"), map_location="cpu", weights_only=True)
        actor = torch.load(os.path.join(folder, "actor.pt"), map_location="cpu", weights_only=True)
        self.method = "rile" if "trainer_actor" in self.saved else "airl" if "g" in self.saved else "gail"
        self.obs_dim, self.act_dim = self.saved["obs_dim"], self.saved["act_dim"]
        self.absorbing = self.saved["termination_remedy"] == "absorbing"
        scale, bias = actor["actor"]["action_scale"], actor["actor"]["action_bias"]
        self.actor = rile.Actor(actor["obs_dim"], actor["act_dim"], bias - scale, bias + scale, actor["hidden_dim"])
        self.actor.load_state_dict(actor["actor"])
        if self.method == "rile":
            if self.saved["trainer_obs"] != "state-action":
                raise SystemExit("error: only rile.py runs with the (s, a_S) trainer are measured here")
            self.trainer = rile.Actor(self.obs_dim + self.absorbing + self.act_dim, 1, np.array([-1.0]), np.array([1.0]),
                                      self.saved["trainer_hidden_dim"])
            self.trainer.load_state_dict(self.saved["trainer_actor"])
        elif self.method == "gail":
            in_dim = self.obs_dim + self.absorbing + self.act_dim
            self.disc = gail.Discriminator(in_dim, self.saved["disc_hidden_dim"], 1e-3, 0.0)
            self.disc.load_state_dict(self.saved["disc"])
        else:
            hidden = self.saved.get("disc_hidden_dim", self.saved.get("hidden_dim"))  # the key of older airl.py files
            self.disc = airl.AIRLDiscriminator(self.obs_dim + self.absorbing, self.act_dim, hidden,
                                               self.config["gamma"], self.saved["state_only"], 1e-3, 0.0)
            self.disc.g.load_state_dict(self.saved["g"])
            self.disc.h.load_state_dict(self.saved["h"])

    def augment(self, obs: torch.Tensor) -> torch.Tensor:
        """Env observations as the run stored them: with the absorbing indicator column (0) where it used one."""
        return torch.cat([obs, torch.zeros(len(obs), 1)], -1) if self.absorbing else obs

    @torch.no_grad()
    def policy_action(self, obs: torch.Tensor) -> torch.Tensor:
        """The actor's deterministic (mean) action at env observations."""
        return self.actor.deterministic(obs)

    @torch.no_grad()
    def reward(self, obs_aug, actions, next_obs_aug, terminations) -> np.ndarray:
        """The reward the learner is trained with, on stored (augmented) transitions."""
        if self.method == "rile":
            obs_t = torch.cat([obs_aug, actions], -1)
            return rile.student_reward(self.trainer, obs_t, self.saved["termination_remedy"]).numpy()
        if self.method == "gail":
            return gail.gail_reward(self.disc(torch.cat([obs_aug, actions], -1)), self.saved["reward_form"]).numpy()
        if self.config["reward"] == "g":
            return self.disc.reward_g(obs_aug, actions).numpy()
        return self.disc(obs_aug, actions, next_obs_aug, terminations).numpy()

    @torch.no_grad()
    def state_reward(self, obs: torch.Tensor) -> np.ndarray:
        """The learned reward as a function of the state, for pictures: at a = the actor's deterministic action
        pi(s); rile.py: r_S(s, pi(s)); gail.py: its SAC reward of D(s, pi(s)); airl.py: g(s, pi(s)) (g(s) with
        --state-only), the reward term without AIRL's shaping h, which needs an s'."""
        obs_aug, actions = self.augment(obs), self.policy_action(obs)
        if self.method == "airl":
            return self.disc.reward_g(obs_aug, actions).numpy()
        return self.reward(obs_aug, actions, None, None)


# ---------------------------------------------------------------- the metrics


class RewardDynamics:
    """The paper's reward-function dynamics, one interval at a time: RFDC, the W1 distance between the learned
    rewards of consecutive intervals (each interval's transitions, scored at its end); FS-RFDC, the mean absolute
    change of the learned reward on all expert pairs; CPR, the Pearson correlation of the learned and the env
    rewards over the interval (None where undefined)."""

    def __init__(self):
        self.prev_interval, self.prev_expert, self.history = None, None, []

    def step(self, step: int, interval_rewards, interval_env_rewards, expert_rewards) -> dict:
        cpr = pearson(interval_rewards, interval_env_rewards)
        out = {"step": step, "cpr": None if np.isnan(cpr) else cpr,
               "rfdc": wasserstein_1d(interval_rewards, self.prev_interval) if self.prev_interval is not None else None,
               "fs_rfdc": float(np.abs(expert_rewards - self.prev_expert).mean())
               if self.prev_expert is not None and expert_rewards is not None else None}
        self.prev_interval, self.prev_expert = interval_rewards, expert_rewards
        self.history.append(out)
        return out


def wasserstein_1d(x: np.ndarray, y: np.ndarray) -> float:
    """W1 between two empirical distributions of the same size: mean |sorted x - sorted y|."""
    assert len(x) == len(y), "RFDC compares intervals of equal length"
    return float(np.abs(np.sort(x) - np.sort(y)).mean())


def pearson(x: np.ndarray, y: np.ndarray) -> float:
    x, y = x - x.mean(), y - y.mean()
    denom = np.sqrt((x * x).sum() * (y * y).sum())
    return float((x * y).sum() / denom) if denom > 0 else float("nan")


def expert_transitions(config: dict, snap: Snapshot) -> dict:
    """All expert transitions of the run's demonstrations, as its learner saw them (absorbing states added)."""
    import gymnasium as gym

    env = gym.make(config["env_id"])
    demos = rile.load_demonstrations(config["expert_path"] or f"experts/{config['env_id']}.npz", env,
                                     config["num_expert_trajs"])
    low, high = env.action_space.low, env.action_space.high
    expert = rile.expert_tensors(demos, config["seed"], torch.device("cpu"), config.get("expert_state_noise", 0.0),
                                 config.get("expert_action_noise", 0.0), low, high)
    return rile.absorbing_expert(expert) if snap.absorbing else expert


def measure(run_dir: str) -> list:
    """RewardDynamics over a run's snapshots; written to runs/<run>/reward_dynamics.json."""
    steps = snapshots(run_dir)
    if not steps:
        raise SystemExit(f"error: {run_dir} has no snapshots; train it with `reward_dynamics.py train`")
    dynamics, expert = RewardDynamics(), None
    for step in steps:
        snap = Snapshot(run_dir, step)
        expert = expert if expert is not None else expert_transitions(snap.config, snap)
        o, a = snap.obs_dim + snap.absorbing, snap.act_dim
        rows = torch.as_tensor(np.load(os.path.join(snapshot_dir(run_dir, step), "interval_rows.npy")))
        obs, actions, next_obs = rows[:, :o], rows[:, o : o + a], rows[:, o + a : 2 * o + a]
        env_rewards, terminations = rows[:, 2 * o + a].numpy(), rows[:, 2 * o + a + 1]
        learned = snap.reward(obs, actions, next_obs, terminations)
        on_expert = snap.reward(expert["obs"], expert["actions"], expert["next_obs"], expert["terminations"])
        dynamics.step(step, learned, env_rewards, on_expert)
    with open(os.path.join(run_dir, "reward_dynamics.json"), "w") as f:
        json.dump(dynamics.history, f, indent=1)
    return dynamics.history


def plot_dynamics(histories: dict, path: str, title: str = "") -> None:
    """One panel per metric (RFDC, FS-RFDC, CPR) over env steps, one line per run; `histories` is
    {label: [{"step", "rfdc", "fs_rfdc", "cpr"}, ...]} (None where a metric is undefined)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 3, figsize=(12, 3.2))
    for label, history in histories.items():
        for ax, key in zip(axes, METRICS):
            points = [(h["step"], h[key]) for h in history if h.get(key) is not None]
            if points:
                ax.plot(*zip(*points), marker="o", ms=3, label=label)
    for ax, key in zip(axes, METRICS):
        ax.set(title=LABELS[key], xlabel="env steps")
        ax.title.set_fontsize(9)
    axes[2].axhline(0, color="k", lw=0.5)
    axes[0].legend(fontsize=8)
    if title:
        fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = parser.add_subparsers(dest="command", required=True)
    p = sub.add_parser("train", help="train a script in segments, keeping a snapshot after each; flags this tool "
                       "does not know (after --) go to the script", allow_abbrev=False)
    p.add_argument("script")
    p.add_argument("--run-name", required=True)
    p.add_argument("--segment-steps", type=int, default=10_000)
    p.add_argument("--segments", type=int, default=10)
    p = sub.add_parser("measure", help="RFDC, FS-RFDC and CPR of a run's snapshots")
    p.add_argument("run_dir")
    p = sub.add_parser("plot", help="plot the measured dynamics of several runs")
    p.add_argument("run_dirs", nargs="+")
    p.add_argument("--out", required=True)
    p.add_argument("--title", default="")
    args, extra = parser.parse_known_args(argv)
    extra = [a for a in extra if a != "--"]
    if extra and args.command != "train":
        parser.error(f"unrecognized arguments: {' '.join(extra)}")
    torch.set_num_threads(1)
    if args.command == "train":
        print(train_segments(args.script, args.run_name, args.segment_steps, args.segments, extra))
    elif args.command == "measure":
        for h in measure(args.run_dir):
            print(json.dumps(h))
    else:
        plot_dynamics({os.path.basename(d.rstrip("/")): measure(d) for d in args.run_dirs}, args.out, args.title)
        print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
