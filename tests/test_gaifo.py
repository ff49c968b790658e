"""gaifo.py: the discriminator sees (s, s') pairs only, never across an episode boundary, and its reward
is recomputed for every batch; a short run through every update path."""

import json

import numpy as np
import torch

import gaifo
from conftest import ROOT


def setup(monkeypatch):
    torch.manual_seed(0)
    args = gaifo.Args(hidden_dim=16, batch_size=16, disc_batch_size=64, disc_hidden_dim=8, disc_buffer_size=40)
    agent = gaifo.SAC(2, 1, -np.ones(1), np.ones(1), args, "cpu")
    disc = gaifo.Discriminator(4, 8, args.disc_lr, args.disc_gp)
    rb = gaifo.ReplayBuffer(2, 1, 100, "cpu")
    for i in range(40):  # episodes of 10 steps; the step after an end is a reset (obs -1000)
        end = i % 10 == 9
        rb.add(np.array([i, 0.0]), np.zeros(1), np.array([i + 1, 1.0 if end else 0.0]), 0.0, False)
    # two expert episodes: (0..4) and (100..104); the second starts far from where the first ends
    demo_obs = np.array([[t, 0.0] for t in range(5)] + [[100 + t, 0.0] for t in range(5)], dtype=np.float32)
    demo_next = demo_obs + np.array([1.0, 0.0], dtype=np.float32)
    demo_next[4, 1] = demo_next[9, 1] = 1.0  # true final states
    demos = {"observations": demo_obs, "next_observations": demo_next, "terminations": np.zeros(10, bool)}  # no actions
    expert = gaifo.expert_tensors(demos, args.seed, "cpu", args.expert_state_noise)
    seen = {}
    monkeypatch.setattr(disc, "update", lambda e, p: seen.update(expert_x=e, policy_x=p) or {})
    monkeypatch.setattr(agent, "update", lambda *b, prefix: seen.update(batch=b) or {})
    return args, agent, disc, rb, expert, seen


def test_pairs_are_consecutive_states_of_one_episode(monkeypatch):
    args, agent, disc, rb, expert, seen = setup(monkeypatch)
    gaifo.gail_update(agent, disc, rb, expert, args, state_only=True)
    s, s_next = seen["expert_x"][:, :2], seen["expert_x"][:, 2:]
    assert torch.equal(s_next[:, 0], s[:, 0] + 1)  # never (4, 100): the pair ends in the true final state
    s, s_next = seen["policy_x"][:, :2], seen["policy_x"][:, 2:]
    assert torch.equal(s_next[:, 0], s[:, 0] + 1)  # the learner's true next state, also at episode ends
    assert torch.equal(s_next[:, 1], (s[:, 0] % 10 == 9).float())


def test_reward_comes_from_the_current_state_pair_discriminator(monkeypatch):
    args, agent, disc, rb, expert, seen = setup(monkeypatch)
    gaifo.gail_update(agent, disc, rb, expert, args, state_only=True)
    obs, actions, next_obs, rewards, _ = seen["batch"]
    assert torch.allclose(rewards, gaifo.gail_reward(disc(torch.cat([obs, next_obs], -1)), "softplus"))
    assert not hasattr(gaifo.Args(), "expert_action_noise")  # the expert's actions are never used


def test_end_to_end(run, tmp_path):
    out = run("gaifo.py", "--env-id", "InvertedPendulum-v4", "--total-timesteps", "500", "--learning-starts", "200",
              "--eval-freq", "250", "--eval-episodes", "2", "--hidden-dim", "32", "--batch-size", "32",
              "--num-expert-trajs", "2", "--expert-path", str(ROOT / "experts/InvertedPendulum-v4.npz"),
              "--expert-state-noise", "0.05", "--run-name", "g", "--termination-remedy", "absorbing",
              "--dynamics-freq", "250").stdout
    assert "GAIfO reward: softplus" in out
    results = json.loads((tmp_path / "runs/g/results.json").read_text())
    assert results["finished"] and [e["step"] for e in results["evals"]] == [250, 500]
    measured = results["reward_measures"][-1]  # the paper's measures, on (s, s') pairs: the demonstrations' need no actions
    assert all(np.isfinite(measured[k]) for k in ("r_s_demos", "r_s_student", "r_s_absorbing", "d_demos", "rfdc", "fs_rfdc"))
    ckpt = torch.load(tmp_path / "runs/g/checkpoint.pt", weights_only=False)
    assert ckpt["disc"]["net.0.weight"].shape[1] == 2 * (4 + 1) and ckpt["disc_optimizer"]["state"]  # (s, s') + indicators
