"""The maze pictures (issue 17): the env, the planner's demonstration, rewards on a grid against hand-made
rewards, the dynamics measured from snapshots, and the plots on tiny data."""

import json
import os

import gymnasium as gym
import numpy as np
import pytest
import torch

import gail
import rile
from benchmarks import maze, maze_env, reward_dynamics
from benchmarks.reward_dynamics import Snapshot


@pytest.fixture(autouse=True)
def in_tmp(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # runs/ and experts/ land here
    monkeypatch.setenv("TMPDIR", str(tmp_path))
    torch.set_num_threads(1)


def test_env_walls_slide_and_limit():
    env = gym.make(maze.ENV_ID)
    obs, _ = env.reset(seed=0)
    assert maze_env.cell_of(obs) == maze_env.find_cell("S") == (1, 3)
    env.unwrapped.pos = np.array([1.5, 3.1])  # just above the wall under the start cell
    obs, reward, terminated, truncated, _ = env.step(np.array([0.0, -1.0]))  # into the wall: no move
    np.testing.assert_allclose(obs, [1.5, 3.1], atol=1e-6)
    obs, *_ = env.step(np.array([1.0, -1.0]))  # diagonally into the wall: slides right along it
    np.testing.assert_allclose(obs, [1.5 + maze_env.STEP, 3.1], atol=1e-6)
    obs, *_ = env.step(np.array([-5.0, 0.5]))  # actions are clipped to the box
    np.testing.assert_allclose(obs, [1.5, 3.1 + 0.5 * maze_env.STEP], atol=1e-6)
    assert reward == pytest.approx(-6.4)  # at (1.5, 3.1): 6 cells from the start cell to the goal, 0.4 from its centre
    rng, steps = np.random.default_rng(0), 3
    while not (terminated or truncated):
        obs, reward, terminated, truncated, _ = env.step(rng.uniform(-1, 1, 2))
        assert maze_env.cell_of(obs) in maze_env.free_cells()
        steps += 1
    assert steps == maze_env.MAX_STEPS and truncated and not terminated
    u = maze_env.UMaze()
    assert u.distance_to_goal(maze_env.centre(u.goal)) == 0.0
    assert u.distance_to_goal(maze_env.centre(u.start)) == 6.0  # right 2, down 2, left 2


def test_planner_reaches_the_goal_and_its_file_loads(tmp_path):
    episode = maze.planner_episode(seed=0)
    assert len(episode["observations"]) == maze_env.MAX_STEPS and episode["timeouts"][-1]
    np.testing.assert_allclose(episode["next_observations"][-1], maze_env.centre(maze_env.find_cell("G")), atol=1e-4)
    assert np.abs(episode["actions"]).max() <= 1.0
    assert all(maze_env.cell_of(p) in maze_env.free_cells() for p in episode["next_observations"])
    assert [maze_env.cell_of(p) for p in episode["next_observations"][:31:5]] == [
        (1, 3), (2, 3), (3, 3), (3, 2), (3, 1), (2, 1), (1, 1)]  # along the U, 30 steps
    path = str(tmp_path / "demo.npz")
    maze.record_demonstration(path)
    demos = rile.load_demonstrations(path, gym.make(maze.ENV_ID), 1)
    np.testing.assert_allclose(demos["actions"], episode["actions"])


def test_reward_grid_against_a_hand_made_reward():
    xs, ys, values = maze.reward_grid(lambda p: p[:, 0] + 10 * p[:, 1], resolution=4)
    assert values.shape == (20, 20) and len(xs) == 20 and xs[0] == 0.125
    assert np.isfinite(values).sum() == 7 * 16  # 7 free cells of 4 x 4 points
    assert np.isnan(values[0, 0]) and np.isnan(values[9, 5])  # outer wall; the wall inside the U (cell (1, 2))
    np.testing.assert_allclose(values[13, 6], xs[6] + 10 * ys[13])  # (1.625, 3.375), in the start cell


def tiny_run(run_dir, step: int, method: str, reward_scale: float = 1.0) -> None:
    """A run directory holding one snapshot whose networks compute a hand-made reward of the position x:
    rile: r_S = tanh(0.1 * scale * x); gail: softplus(tanh(tanh(scale * x))); airl: g = tanh(tanh(scale * x)).
    The actor's weights are zero, so pi(s) = 0 everywhere."""
    folder = reward_dynamics.snapshot_dir(str(run_dir), step)
    os.makedirs(folder)
    config = {"gamma": 0.99, "reward": "f", "env_id": maze.ENV_ID, "expert_path": "experts/UMaze-v0.npz",
              "num_expert_trajs": 1, "seed": 1}
    with open(os.path.join(run_dir, "results.json"), "w") as f:
        json.dump({"config": config}, f)
    actor = rile.Actor(2, 2, -np.ones(2), np.ones(2), 8)
    with torch.no_grad():
        for p in actor.parameters():
            p.zero_()
    torch.save(rile.actor_file(actor, maze.ENV_ID), os.path.join(folder, "actor.pt"))
    common = {"env_id": maze.ENV_ID, "obs_dim": 2, "act_dim": 2}
    if method == "rile":  # absorbing: the trainer sees (x, y, indicator, a0, a1)
        net = rile.Actor(5, 1, np.array([-1.0]), np.array([1.0]), 8)
        layers = [net.net[0], net.net[2], net.fc_mean]
        saved = {"trainer_actor": net, "trainer_hidden_dim": 8, "termination_remedy": "absorbing",
                 "trainer_obs": "state-action", "disc_hidden_dim": 8, "state_only": False}
    else:
        net = gail.Discriminator(4, 8, 1e-3, 0.0) if method == "gail" else torch.nn.Module()
        if method == "airl":
            net.g, net.h = reward_dynamics.airl.mlp(4, 8), reward_dynamics.airl.mlp(2, 8)
        layers = [net.net[0], net.net[2], net.net[4]] if method == "gail" else [net.g[0], net.g[2], net.g[4]]
        saved = ({"disc": net, "disc_hidden_dim": 8, "reward_form": "softplus", "termination_remedy": "none"}
                 if method == "gail" else {"g": net.g, "h": net.h, "disc_hidden_dim": 8, "state_only": False,
                                           "termination_remedy": "none"})
    with torch.no_grad():
        for p in net.parameters():
            p.zero_()
        for layer in layers:
            layer.weight[0, 0] = 1.0
        layers[0].weight[0, 0] = reward_scale
        if method == "rile":
            layers[-1].weight[0, 0] = 0.1
    saved = {k: v.state_dict() if isinstance(v, torch.nn.Module) else v for k, v in saved.items()}
    torch.save(common | saved, os.path.join(folder, "reward.pt"))


HAND_MADE = {"rile": lambda x: np.tanh(0.1 * x), "gail": lambda x: np.log1p(np.exp(np.tanh(np.tanh(x)))),
             "airl": lambda x: np.tanh(np.tanh(x))}


@pytest.mark.parametrize("method", ["rile", "gail", "airl"])
def test_snapshot_state_reward_on_the_grid(tmp_path, method):
    tiny_run(tmp_path, 1000, method)
    snap = Snapshot(str(tmp_path), 1000)
    assert snap.method == method and snap.absorbing == (method == "rile")
    xs, ys, values = maze.reward_grid(snap.state_reward, resolution=2)
    expected = HAND_MADE[method](np.broadcast_to(xs, values.shape))
    free = np.isfinite(values)
    assert free.sum() == 7 * 4
    np.testing.assert_allclose(values[free], expected[free], rtol=1e-5)


def test_measure_constant_rewards_by_hand(tmp_path):
    """Two gail snapshots, softplus(0) = log 2 everywhere, then softplus(tanh(tanh(x))): on the stored rows
    (x = 0) both give log 2, so RFDC is 0 and CPR undefined (a constant reward); FS-RFDC on the expert's
    states is the mean of |softplus(tanh(tanh(x))) - log 2|."""
    maze.record_demonstration("experts/UMaze-v0.npz")
    run_dir = tmp_path / "run"
    for step, scale in ((100, 0.0), (200, 1.0)):
        tiny_run(run_dir, step, "gail", reward_scale=scale)
        rows = np.zeros((10, 2 + 2 + 2 + 2), np.float32)  # obs at x = 0 (outside the maze, but a valid input)
        rows[:, 6] = np.arange(10)  # env rewards
        np.save(os.path.join(reward_dynamics.snapshot_dir(str(run_dir), step), "interval_rows.npy"), rows)
    history = reward_dynamics.measure(str(run_dir))
    assert [h["step"] for h in history] == [100, 200] and history[0]["rfdc"] is None
    assert history[1]["rfdc"] == pytest.approx(0.0)  # every stored row has x = 0: the same reward twice
    expert_x = np.load("experts/UMaze-v0.npz")["observations"][:, 0]
    fs = np.mean(np.abs(np.log1p(np.exp(np.tanh(np.tanh(expert_x)))) - np.log(2.0)))
    assert history[1]["fs_rfdc"] == pytest.approx(fs, rel=1e-5)
    assert history[0]["cpr"] is None and history[1]["cpr"] is None


def test_segments_reproduce_rile_dynamics(tmp_path):
    """rile.py trained in two resume segments: the snapshots' measured dynamics equal its own dynamics.json."""
    maze.record_demonstration("experts/UMaze-v0.npz")
    flags = ["--env-id", maze.ENV_ID, "--expert-path", "experts/UMaze-v0.npz", "--num-expert-trajs", "1",
             "--learning-starts", "100", "--hidden-dim", "16", "--trainer-hidden-dim", "16", "--batch-size", "16",
             "--trainer-batch-size", "16", "--eval-episodes", "1", "--buffer-size", "1000", "--dynamics-freq", "300",
             "--checkpoint-freq", "0"]  # segments need a checkpoint at each end whatever the flags say
    with open(os.devnull, "w") as devnull:
        run_dir = reward_dynamics.train_segments("rile.py", "tiny", 300, 2, flags, log=devnull)
    assert reward_dynamics.snapshots(run_dir) == [300, 600]
    own = json.load(open(os.path.join(run_dir, "dynamics.json")))
    measured = reward_dynamics.measure(run_dir)
    for a, b in zip(own, measured, strict=True):
        for key in ("rfdc", "fs_rfdc", "cpr"):
            assert (a[key] is None) == (b[key] is None)
            if a[key] is not None:
                assert b[key] == pytest.approx(a[key], rel=1e-4, abs=1e-6)


def test_plots_on_tiny_data(tmp_path):
    grid = maze.reward_grid(lambda p: p[:, 1], resolution=2)
    student = np.array([[1.5, 3.5], [2.5, 3.5], [3.5, 3.0]])
    rows = {"a": [("25%", grid, student), ("50%", grid, student)], "b": [("25%", grid, student), ("50%", grid, student)]}
    maze.plot_landscapes(rows, student, str(tmp_path / "land.png"))
    history = [{"step": 1, "rfdc": None, "fs_rfdc": None, "cpr": 0.5}, {"step": 2, "rfdc": 0.1, "fs_rfdc": 0.2, "cpr": None}]
    reward_dynamics.plot_dynamics({"a": history, "b": history[:1]}, str(tmp_path / "dyn.png"), title="tiny")
    for name in ("land.png", "dyn.png"):
        assert (tmp_path / name).stat().st_size > 1000


def test_train_command_passes_the_scripts_flags(monkeypatch):
    calls = []
    monkeypatch.setattr(reward_dynamics, "train_segments", lambda *a: calls.append(a) or "runs/x")
    reward_dynamics.main(["train", "gail.py", "--run-name", "x", "--segments", "3", "--",
                          "--env-id", "Hopper-v4", "--seed", "2"])
    assert calls == [("gail.py", "x", 10_000, 3, ["--env-id", "Hopper-v4", "--seed", "2"])]
    with pytest.raises(SystemExit):
        reward_dynamics.main(["measure", "runs/x", "--seed", "2"])


def test_cell_means_follow_the_way_to_the_goal():
    grid = maze.reward_grid(lambda p: p[:, 0] + 10 * p[:, 1], resolution=4)
    assert maze.cell_means(grid) == [36.5, 37.5, 38.5, 28.5, 18.5, 17.5, 16.5]  # centres' x + 10 y, S to G


def test_run_gives_each_method_its_flags_last(monkeypatch, tmp_path):
    """rile.py's runs get the default's guard (3/4 of all segments, not of the first), and a method's own flags
    come after it, so that `rile-frozen` really runs without the guard (the last flag wins)."""
    calls = []
    monkeypatch.setattr(maze, "train_segments", lambda script, name, steps, segments, extra: calls.append(extra))
    monkeypatch.setattr(maze, "figures", lambda methods, seed: {})
    monkeypatch.setattr(maze, "RESULTS", str(tmp_path))
    maze.main(["run", "--methods", "rile", "rile-frozen", "gail", "--segments", "4", "--segment-steps", "1000"])
    guard = lambda extra: [v for k, v in zip(extra, extra[1:]) if k == "--trainer-freeze-after"]
    assert [guard(extra) for extra in calls] == [["3000"], ["3000", "0"], []]
