"""bc.py: the loss at and near the action bounds, the held-out split, a short run, its actor as a
valid checkpoint for the other scripts, and a resumed run that goes on exactly as an uninterrupted one."""

import json

import numpy as np
import pytest
import torch

import bc
from conftest import ROOT


@pytest.mark.parametrize("kind", ["nll", "mse"])
def test_loss_at_and_near_the_bounds_is_finite(kind):
    torch.manual_seed(0)
    actor = bc.Actor(3, 2, np.array([-0.4, 0.0]), np.array([0.4, 2.0]), 16)
    obs = torch.randn(6, 3)
    actions = torch.tensor([[0.4, 2.0], [-0.4, 0.0], [0.4 - 1e-7, 2.0 - 1e-7], [0.3999, 1e-6], [0.0, 1.0], [0.41, 2.1]])
    loss = bc.bc_loss(actor, obs, actions, kind)
    loss.backward()
    assert torch.isfinite(loss) and all(torch.isfinite(p.grad).all() for p in actor.parameters() if p.grad is not None)


def test_loss_values():
    actor = bc.Actor(1, 1, np.array([-2.0]), np.array([2.0]), 8)
    with torch.no_grad():
        actor.fc_mean.weight.zero_()
        actor.fc_mean.bias.fill_(50.0)  # tanh(mean) = 1: the deterministic action is the upper bound, 2
    obs, actions = torch.zeros(2, 1), torch.tensor([[1.0], [-2.0]])
    assert bc.bc_loss(actor, obs, actions, "mse").item() == pytest.approx(((2 - 1) ** 2 + (2 + 2) ** 2) / 2)
    assert bc.bc_loss(actor, obs, actions, "nll").item() == pytest.approx(-actor.log_prob(obs, actions).mean().item())
    with pytest.raises(ValueError):
        bc.bc_loss(actor, obs, actions, "nope")


def test_holdout_split_keeps_whole_episodes():
    demos = {"episode_starts": np.array([0, 3, 7, 12]), "episode_lengths": np.array([3, 4, 5, 6])}
    train, held = bc.holdout_split(demos, 0.25)
    assert train.tolist() == list(range(12)) and held.tolist() == list(range(12, 18))
    train, held = bc.holdout_split({"episode_starts": np.array([0]), "episode_lengths": np.array([10])}, 0.1)
    assert train.tolist() == list(range(9)) and held.tolist() == [9]


def test_end_to_end_and_the_actor_is_a_project_checkpoint(run, tmp_path):
    out = run("bc.py", "--env-id", "InvertedPendulum-v4", "--total-timesteps", "400", "--eval-freq", "200",
              "--eval-episodes", "2", "--hidden-dim", "32", "--num-expert-trajs", "3", "--run-name", "b",
              "--expert-path", str(ROOT / "experts/InvertedPendulum-v4.npz")).stdout
    assert "on 2000 expert pairs, 1000 held out" in out
    results = json.loads((tmp_path / "runs/b/results.json").read_text())
    assert results["finished"] and [e["step"] for e in results["evals"]] == [200, 400]
    assert all("holdout_loss" in e for e in results["evals"])
    out = run("expert.py", "--env-id", "InvertedPendulum-v4", "--record-from", "runs/b/actor_best.pt", "--num-demos", "2",
              "--demo-path", "demos.npz").stdout  # BC's actor records demonstrations like any expert
    assert "recorded 2 episodes" in out


def test_resumed_run_equals_an_uninterrupted_one(run, tmp_path):
    common = ["--env-id", "InvertedPendulum-v4", "--eval-freq", "100", "--eval-episodes", "2", "--hidden-dim", "32",
              "--num-expert-trajs", "3", "--expert-path", str(ROOT / "experts/InvertedPendulum-v4.npz")]
    run("bc.py", *common, "--total-timesteps", "300", "--run-name", "whole")
    run("bc.py", *common, "--total-timesteps", "200", "--run-name", "split")
    out = run("bc.py", "--resume", "runs/split", "--total-timesteps", "300").stdout
    assert "resumed runs/split at step 200" in out
    results = {name: json.loads((tmp_path / f"runs/{name}/results.json").read_text()) for name in ("whole", "split")}
    assert [e["step"] for e in results["split"]["evals"]] == [100, 200, 300] and results["split"]["finished"]
    assert results["split"]["evals"] == results["whole"]["evals"]
    actors = {name: torch.load(tmp_path / f"runs/{name}/actor.pt", weights_only=True)["actor"] for name in ("whole", "split")}
    assert all(torch.equal(actors["whole"][k], actors["split"][k]) for k in actors["whole"])
