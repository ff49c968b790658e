"""The RILe paper's maze pictures: learned reward landscapes over training, and reward dynamics.

    python benchmarks/maze.py run          # demonstration, training, figures (from the repository root)
    python benchmarks/maze.py plot         # the figures again, from the runs already there

1. One demonstration of `benchmarks.maze_env:UMaze-v0` (a point in a U-shaped maze; see maze_env.py) from
   a planner: the shortest way through the maze's free cells (breadth-first search), followed waypoint by
   waypoint (cell centres) at full speed, then holding still on the goal's centre to the time limit. It is
   written as a plain npz and turned into the project's format by `demos.py convert` (its checks included),
   to experts/UMaze-v0.npz.
2. rile.py, gail.py and airl.py learn from it with their usual code paths and default settings, except
   the lengths and widths that keep the experiment short on a CPU (--learning-starts 1000, --eval-episodes 2,
   --hidden-dim 64 for the SAC networks and rile.py's trainer: a 2-D point needs no wider ones), in
   --segments segments of --segment-steps env steps (`reward_dynamics.py train`: one --resume per segment,
   the learned reward kept after each). rile.py runs twice: as it is (its trainer freezes at 3/4 of the run at the
   earliest), and with a trainer that freezes early (the rule before issue 28: the raw critic loss under 0.1, no
   window, no guard), to show what freezing the trainer early does to the picture.
3. Figure 1 (benchmarks/results/maze_rewards.png): one row per method, one column per quarter of
   training; each panel is the learned reward on a grid of positions (`Snapshot.state_reward`: at each
   position s, the reward of the pair (s, pi(s)) with pi(s) the same snapshot's deterministic action; for
   rile.py the trainer's action r_S = a_T(s, pi(s)), for gail.py its SAC reward of D(s, pi(s)), for
   airl.py its reward term g(s, pi(s))), its colours normalised per method over its four panels; the
   expert's path in white and the student's path (one deterministic episode of the snapshot's actor) in red.
4. Figure 2 (benchmarks/results/maze_dynamics.png): RFDC, FS-RFDC and CPR after every segment, measured
   the same way for every run (`reward_dynamics.measure`).
5. benchmarks/results/maze.json: per run and snapshot, the student's final distance to the goal and the
   mean reward over each cell of the way from start to goal; per run, the measured dynamics.
"""

import argparse
import json
import os
import sys
import tempfile
import time

import gymnasium as gym
import numpy as np
import torch

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)
from benchmarks import maze_env  # noqa: E402  (registers UMaze-v0)
from benchmarks.reward_dynamics import Snapshot, measure, plot_dynamics, snapshots, train_segments  # noqa: E402

ENV_ID = "benchmarks.maze_env:UMaze-v0"
EXPERT_PATH = os.path.join("experts", "UMaze-v0.npz")
RESULTS = os.path.join(ROOT, "benchmarks", "results")
METHODS = {  # name: (script, its flags beyond the shared ones)
    "rile": ("rile.py", []),
    # the rule before issue 28 (raw critic loss under 0.1, no window, no guard): freezes early
    "rile-frozen": ("rile.py", ["--trainer-freeze-stat", "loss", "--trainer-freeze-window", "0",
                                "--trainer-freeze-after", "0"]),
    "gail": ("gail.py", []),
    "airl": ("airl.py", []),
}


# ---------------------------------------------------------------- the demonstration


def planner_episode(seed: int) -> dict:
    """One episode of the planner: shortest cell path, then waypoint following (module docstring)."""
    env = gym.make(ENV_ID)
    obs, _ = env.reset(seed=seed)
    waypoints = [maze_env.centre(c) for c in maze_env.shortest_path(maze_env.find_cell("S"), maze_env.find_cell("G"))]
    steps = {k: [] for k in ("observations", "actions", "rewards", "next_observations", "terminals", "timeouts")}
    done = False
    while not done:
        while len(waypoints) > 1 and np.linalg.norm(waypoints[0] - obs) < 1e-3:
            waypoints.pop(0)  # reached: head for the next one
        action = np.clip((waypoints[0] - obs) / maze_env.STEP, -1.0, 1.0).astype(np.float32)
        next_obs, reward, terminated, truncated, _ = env.step(action)
        for key, value in zip(steps, (obs, action, reward, next_obs, terminated, truncated)):
            steps[key].append(value)
        obs, done = next_obs, terminated or truncated
    return {k: np.asarray(v, dtype=np.float32 if k not in ("terminals", "timeouts") else bool) for k, v in steps.items()}


def record_demonstration(path: str = EXPERT_PATH, seed: int = 0) -> None:
    """The planner's episode, in the project's format through `demos.py convert`."""
    import demos

    with tempfile.TemporaryDirectory() as tmp:
        raw = os.path.join(tmp, "planner.npz")
        np.savez(raw, **planner_episode(seed))
        demos.main(["convert", raw, "--env-id", "UMaze-v0", "--out", path, "--force"])


# ---------------------------------------------------------------- rewards on a grid


def reward_grid(reward_fn, resolution: int = 40):
    """reward_fn (an (N, 2) float32 tensor of positions -> N rewards) on the centres of a grid of
    `resolution` points per cell side over the maze; NaN inside walls. Returns (xs, ys, values[y, x])."""
    width, height = len(maze_env.MAZE[0]), len(maze_env.MAZE)
    xs = (np.arange(width * resolution) + 0.5) / resolution
    ys = (np.arange(height * resolution) + 0.5) / resolution
    gx, gy = np.meshgrid(xs, ys)
    points = np.stack([gx.ravel(), gy.ravel()], -1)
    free = np.array([maze_env.cell_of(p) in maze_env.free_cells() for p in points])
    values = np.full(len(points), np.nan)
    values[free] = np.asarray(reward_fn(torch.as_tensor(points[free], dtype=torch.float32)), dtype=np.float64)
    return xs, ys, values.reshape(gy.shape)


def rollout(actor, seed: int = 0) -> np.ndarray:
    """The positions of one deterministic episode of `actor` (start included)."""
    env = gym.make(ENV_ID)
    obs, _ = env.reset(seed=seed)
    path, done = [obs], False
    while not done:
        with torch.no_grad():
            action = actor.deterministic(torch.as_tensor(obs)[None])[0].numpy()
        obs, _, terminated, truncated, _ = env.step(action)
        path.append(obs)
        done = terminated or truncated
    return np.asarray(path)


def cell_means(grid) -> list:
    """The mean of a reward grid over each free cell, in the order of the shortest way from start to goal."""
    xs, ys, values = grid
    way = maze_env.shortest_path(maze_env.find_cell("S"), maze_env.find_cell("G"))
    in_cell = lambda coords, k: (coords >= k) & (coords < k + 1)
    return [round(float(values[np.ix_(in_cell(ys, j), in_cell(xs, i))].mean()), 3) for i, j in way]


def plot_landscapes(rows: dict, expert_path: np.ndarray, path: str) -> None:
    """rows: {method: [(label, (xs, ys, values), student_path), ...]}, one figure row per method; the colour
    scale is shared by a method's panels (its min..max over them), walls grey."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    ncols = max(len(panels) for panels in rows.values())
    fig, axes = plt.subplots(len(rows), ncols, figsize=(2.6 * ncols, 2.5 * len(rows)), squeeze=False)
    for r, (method, panels) in enumerate(rows.items()):
        lo = min(np.nanmin(grid[2]) for _, grid, _ in panels)
        hi = max(np.nanmax(grid[2]) for _, grid, _ in panels)
        for c, (label, (xs, ys, values), student) in enumerate(panels):
            ax = axes[r, c]
            ax.set_facecolor("0.35")
            im = ax.imshow(np.ma.masked_invalid(values), origin="lower", cmap="viridis", vmin=lo,
                           vmax=hi if hi > lo else lo + 1, extent=(0, xs[-1] + xs[0], 0, ys[-1] + ys[0]))
            ax.plot(expert_path[:, 0], expert_path[:, 1], color="white", lw=2, label="expert")
            ax.plot(student[:, 0], student[:, 1], color="red", lw=1.2, label="student")
            ax.plot(*student[-1], "o", color="red", ms=3)
            ax.set_xticks([]), ax.set_yticks([])
            ax.set_title(f"{method}: {label}", fontsize=9)
        fig.colorbar(im, ax=axes[r, len(panels) - 1], fraction=0.046)
    axes[0, 0].legend(fontsize=7, loc="lower right")
    fig.tight_layout()
    fig.savefig(path, dpi=80)
    plt.close(fig)


# ---------------------------------------------------------------- the experiment


def run_name(method: str, seed: int) -> str:
    return f"maze__{method}__{seed}"


def figures(methods, seed: int, quarters: int = 4) -> dict:
    """Both figures from the runs' snapshots; returns the numbers quoted in the README."""
    if not os.path.exists(EXPERT_PATH):
        raise SystemExit(f"error: no {EXPERT_PATH} here; run `python benchmarks/maze.py run` from the repository root")
    expert = np.load(EXPERT_PATH)
    expert_path = np.concatenate([expert["observations"][:1], expert["next_observations"]])
    rows, histories, summary = {}, {}, {}
    for method in methods:
        run_dir = os.path.join("runs", run_name(method, seed))
        steps = snapshots(run_dir)
        if len(steps) < quarters:
            raise SystemExit(f"error: {run_dir} has {len(steps)} snapshots, the figure needs {quarters}; "
                             f"train it with `python benchmarks/maze.py run --methods {method}` (--segments >= {quarters})")
        chosen = [steps[round((q + 1) * len(steps) / quarters) - 1] for q in range(quarters)]
        rows[method], summary[method] = [], {}
        for q, step in enumerate(chosen):
            snap = Snapshot(run_dir, step)
            student = rollout(snap.actor)
            grid = reward_grid(snap.state_reward)
            end = maze_env.UMaze().distance_to_goal(student[-1])
            rows[method].append((f"{100 * (q + 1) // quarters}% ({step / 1000:g}k steps)", grid, student))
            summary[method][step] = {"student_final_distance_to_goal": round(float(end), 3),
                                     "mean_reward_per_cell_start_to_goal": cell_means(grid)}
        histories[method] = measure(run_dir)
        summary[method]["dynamics"] = histories[method]
    plot_landscapes(rows, expert_path, os.path.join(RESULTS, "maze_rewards.png"))
    plot_dynamics(histories, os.path.join(RESULTS, "maze_dynamics.png"), title="UMaze-v0, one demonstration")
    return summary


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("command", choices=("run", "plot"))
    parser.add_argument("--methods", nargs="+", default=list(METHODS), choices=METHODS)
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--segment-steps", type=int, default=4000)
    parser.add_argument("--segments", type=int, default=8)
    parser.add_argument("--learning-starts", type=int, default=1000)
    parser.add_argument("--hidden-dim", type=int, default=64, help="width of the SAC (and rile.py's trainer) networks")
    args = parser.parse_args(argv)
    torch.set_num_threads(1)
    if args.command == "run":
        if not os.path.exists(EXPERT_PATH):
            record_demonstration()
        total = args.segment_steps * args.segments
        for method in args.methods:
            start, (script, flags) = time.time(), METHODS[method]
            train_segments(script, run_name(method, args.seed), args.segment_steps, args.segments,
                           ["--env-id", ENV_ID, "--expert-path", EXPERT_PATH, "--num-expert-trajs", "1", "--seed",
                            str(args.seed), "--learning-starts", str(args.learning_starts), "--eval-freq",
                            str(args.segment_steps), "--eval-episodes", "2", "--buffer-size", str(total + 1),
                            "--hidden-dim", str(args.hidden_dim)]
                           + (["--dynamics-freq", str(args.segment_steps), "--trainer-hidden-dim", str(args.hidden_dim),
                               "--trainer-freeze-after", str(total * 3 // 4)]  # 3/4 of all segments, not of the first
                              if script == "rile.py" else []) + flags)  # a method's own flags last: they win
            print(f"{method}: {total} steps in {time.time() - start:.0f} s", flush=True)
    summary = figures(args.methods, args.seed)
    with open(os.path.join(RESULTS, "maze.json"), "w") as f:
        json.dump(summary, f, indent=1)
    print(f"wrote {os.path.join(RESULTS, 'maze_rewards.png')}, maze_dynamics.png and maze.json")


if __name__ == "__main__":
    main()
