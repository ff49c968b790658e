"""bco.py: inverse-model pairs never span an episode boundary, inferred actions stay in the box, the
env-step budget is counted, and a short run reaches every phase."""

import json

import numpy as np
import torch

import bco
from conftest import ROOT


def test_collected_pairs_never_span_an_episode_boundary():
    env = bco.make_env("InvertedPendulum-v4", 0)
    obs, _ = env.reset(seed=0)
    (s, a, s_next), _ = bco.collect(env, None, 300, obs, "cpu")  # random actions: many short episodes
    assert len(s) == 300 and (a.abs() <= 3).all()
    continuing = torch.all(s_next[:-1] == s[1:], dim=1)
    ends = torch.nonzero(~continuing).flatten()
    assert len(ends) > 5  # random actions drop the pole within a few dozen steps
    # at an episode end the pair keeps the true terminal state (pole angle beyond 0.2 rad, which is what
    # ended the episode), while the next row starts from a reset state (all coordinates within 0.01)
    assert (s_next[ends, 1].abs() > 0.2).all()
    assert (s[ends + 1].abs() <= 0.01 + 1e-6).all()


def test_inferred_actions_stay_in_the_box():
    torch.manual_seed(0)
    low, high = np.array([-0.4, 0.0]), np.array([0.4, 2.0])
    model = bco.InverseDynamics(3, 2, low, high, 16)
    with torch.no_grad():
        model.net[-2].bias.fill_(100.0)  # saturate
        out = model(torch.randn(50, 3) * 100, torch.randn(50, 3) * 100)
    assert (out >= torch.tensor(low, dtype=torch.float32)).all() and (out <= torch.tensor(high, dtype=torch.float32)).all()


def test_inverse_loss_is_unit_scaled_mse():
    model = bco.InverseDynamics(1, 2, np.array([-2.0, 0.0]), np.array([2.0, 1.0]), 8)
    with torch.no_grad():
        model.net[-2].weight.zero_()
        model.net[-2].bias.zero_()  # predicts the middle of the box: (0, 0.5)
    loss = model.loss(torch.zeros(1, 1), torch.tensor([[2.0, 1.0]]), torch.zeros(1, 1))
    assert loss.item() == torch.tensor((2.0 / 2.0) ** 2 + (0.5 / 0.5) ** 2).item()


def test_end_to_end_counts_every_env_step(run, tmp_path):
    out = run("bco.py", "--env-id", "InvertedPendulum-v4", "--pre-demo-steps", "600", "--alpha", "0.25",
              "--total-timesteps", "900", "--inverse-steps", "100", "--bc-steps", "100", "--inverse-steps-per-iteration",
              "50", "--bc-steps-per-iteration", "50", "--hidden-dim", "32", "--eval-episodes", "2", "--num-expert-trajs",
              "2", "--inverse-data", "finetune", "--run-name", "b",
              "--expert-path", str(ROOT / "experts/InvertedPendulum-v4.npz")).stdout
    assert "then 2 iterations of 150 env steps: 900 env steps in all" in out
    results = json.loads((tmp_path / "runs/b/results.json").read_text())
    assert results["finished"] and [e["step"] for e in results["evals"]] == [600, 750, 900]
    assert [e["iteration"] for e in results["evals"]] == [0, 1, 2] and results["config"]["total_timesteps"] == 900
    assert (tmp_path / "runs/b/inverse_model.pt").exists()


def test_a_budget_below_the_exploration_phase_is_refused(run, tmp_path):
    """--total-timesteps 15000 with the default 50,000 exploration steps once ran 50,000 env steps and recorded 15,000."""
    proc = run("bco.py", "--env-id", "InvertedPendulum-v4", "--total-timesteps", "500", "--pre-demo-steps", "600",
               "--expert-path", str(ROOT / "experts/InvertedPendulum-v4.npz"), check=False)
    assert proc.returncode != 0 and "below --pre-demo-steps 600" in proc.stderr and not (tmp_path / "runs").exists()
