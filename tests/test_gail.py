"""gail.py: the reward forms against hand-computed values, relabelling from the current discriminator,
and a short run through every update path."""

import json

import numpy as np
import pytest
import torch

import gail
from conftest import ROOT


def test_reward_forms_against_hand_computed_values():
    logits = torch.tensor([-2.0, 0.0, 3.0])
    d = 1 / (1 + np.exp(-logits.numpy().astype(np.float64)))
    want = {"softplus": -np.log(1 - d), "logit": np.log(d) - np.log(1 - d), "log-d": np.log(d)}
    for form, values in want.items():
        assert gail.gail_reward(logits, form).tolist() == pytest.approx(values.tolist(), rel=1e-6), form
    assert (gail.gail_reward(logits, "softplus") >= 0).all() and (gail.gail_reward(logits, "log-d") <= 0).all()
    big = torch.tensor([-100.0, 100.0])  # no overflow at saturated logits
    assert torch.isfinite(gail.gail_reward(big, "softplus")).all() and torch.isfinite(gail.gail_reward(big, "log-d")).all()
    with pytest.raises(ValueError):
        gail.gail_reward(logits, "nope")


def test_rewards_are_relabelled_from_the_current_discriminator(monkeypatch):
    torch.manual_seed(0)
    args = gail.Args(hidden_dim=16, batch_size=8, disc_batch_size=4, disc_hidden_dim=8, reward_form="logit")
    agent = gail.SAC(3, 2, -np.ones(2), np.ones(2), args, "cpu")
    disc = gail.Discriminator(5, 8, args.disc_lr, args.disc_gp)
    rb = gail.ReplayBuffer(3, 2, 20, "cpu")
    for i in range(20):
        rb.add(np.full(3, i / 10), np.full(2, 0.5), np.zeros(3), 7.0, False)  # env reward 7: never used
    expert = {"obs": torch.ones(10, 3), "actions": torch.zeros(10, 2)}
    seen = []

    def capture(obs, actions, next_obs, rewards, terminations, prefix):
        seen.append((rewards.clone(), disc(torch.cat([obs, actions], -1)).detach()))
        return {}

    monkeypatch.setattr(agent, "update", capture)
    gail.gail_update(agent, disc, rb, expert, args)
    with torch.no_grad():
        disc.net[-1].bias.add_(5.0)  # a different discriminator: the same transitions get other rewards
    gail.gail_update(agent, disc, rb, expert, args)
    for rewards, logits in seen:
        assert torch.allclose(rewards, logits) and not torch.any(rewards == 7.0)
    assert seen[1][0].mean() > seen[0][0].mean() + 4


def test_end_to_end(run, tmp_path):
    out = run("gail.py", "--env-id", "InvertedPendulum-v4", "--total-timesteps", "500", "--learning-starts", "200",
              "--eval-freq", "250", "--eval-episodes", "2", "--hidden-dim", "32", "--batch-size", "32",
              "--num-expert-trajs", "2", "--expert-path", str(ROOT / "experts/InvertedPendulum-v4.npz"),
              "--reward-form", "logit", "--expert-state-noise", "0.1", "--run-name", "g",
              "--termination-remedy", "absorbing").stdout  # DAC's combination: logit reward, absorbing states
    assert "GAIL reward: logit" in out
    results = json.loads((tmp_path / "runs/g/results.json").read_text())
    assert results["finished"] and [e["step"] for e in results["evals"]] == [250, 500]
    assert results["expert_return"] == pytest.approx(1000.0)
    with np.load(ROOT / "experts/InvertedPendulum-v4.npz") as f:  # normalized: random actions 0, the expert 1
        random = json.loads(str(f["metadata"]))["random_return"]
    last = results["evals"][-1]
    assert results["random_return"] == random
    assert last["normalized"] == pytest.approx((last["mean"] - random) / (1000.0 - random))
    ckpt = torch.load(tmp_path / "runs/g/checkpoint.pt", weights_only=False)
    assert ckpt["disc_optimizer"]["state"] and ckpt["agent"]["q_optimizer"]["state"]
    assert ckpt["disc"]["net.0.weight"].shape[1] == 4 + 1 + 1  # (s, indicator, a) of InvertedPendulum
    storage = ckpt["replay_buffer"]["storage"]
    assert len(storage) > 500 and (storage[:, 4] == 1).sum() == len(storage) - 500  # one absorbing row per fall
    assert (tmp_path / "runs/g/reward.pt").exists() and (tmp_path / "runs/g/actor.pt").exists()
