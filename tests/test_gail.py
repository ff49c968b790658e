"""gail.py: the reward forms against hand-computed values, relabelling from the current discriminator,
and a short run through every update path."""

import json

import numpy as np
import pytest
import torch

import gail
import sweep
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


def test_reward_measures_by_hand():
    """Rows i = 0..29, obs (i, indicator 0), env reward i. With D = sigmoid(i - 10) and r_S = -log(1 - D) = log(1 + e^(i - 10))
    the measures over the newest 10 rows are sums by hand; the absorbing state (0, 1) reads i = 0."""
    softplus, sigmoid = lambda x: np.log1p(np.exp(x)), lambda x: 1 / (1 + np.exp(-x))
    logit = lambda data: data["obs"][:, 0] - 10
    rb = gail.ReplayBuffer(2, 1, 40, "cpu")
    expert = {"obs": torch.tensor([[12.0, 0.0], [0.0, 1.0]]), "actions": torch.zeros(2, 1), "next_obs": torch.zeros(2, 2)}
    memory, outs = {"interval": None, "demos": None, "history": []}, []
    for end in (20, 30):
        for i in range(rb.size, end):
            rb.add(np.array([i, 0.0]), np.zeros(1), np.array([i + 1, 0.0]), float(i), False)
        outs.append(gail.reward_measures(lambda d: torch.nn.functional.softplus(logit(d)), lambda d: torch.sigmoid(logit(d)),
                                         rb, expert, True, memory, end, 10))
    i = np.arange(10, 20, dtype=np.float64)
    first, second = outs
    assert first["d_student"] == pytest.approx(sigmoid(i - 10).mean(), rel=1e-5)
    assert first["r_s_student"] == pytest.approx(softplus(i - 10).mean(), rel=1e-5)
    assert first["d_demos"] == pytest.approx(sigmoid(2.0), rel=1e-5)  # the live demonstration row only
    assert first["r_s_spread"] == pytest.approx(softplus(2.0) - softplus(i - 10).mean(), rel=1e-5)
    assert first["r_s_absorbing"] == pytest.approx(softplus(-10.0), rel=1e-4)
    assert first["cpr"] == pytest.approx(np.corrcoef(softplus(i - 10), i)[0, 1], rel=1e-5)
    assert first["rfdc"] is None and first["fs_rfdc"] is None
    assert second["rfdc"] == pytest.approx((softplus(i) - softplus(i - 10)).mean(), rel=1e-5)  # W1 of the two intervals
    assert second["fs_rfdc"] == 0.0 and memory["history"] == outs


def test_end_to_end(run, tmp_path):
    out = run("gail.py", "--env-id", "InvertedPendulum-v4", "--total-timesteps", "500", "--learning-starts", "200",
              "--eval-freq", "250", "--eval-episodes", "2", "--hidden-dim", "32", "--batch-size", "32",
              "--num-expert-trajs", "2", "--expert-path", str(ROOT / "experts/InvertedPendulum-v4.npz"),
              "--reward-form", "logit", "--expert-state-noise", "0.1", "--expert-action-noise", "0.5",
              "--no-expert-noise-clip", "--run-name", "g", "--dynamics-freq", "250",
              "--termination-remedy", "absorbing").stdout  # DAC's combination: logit reward, absorbing states
    assert "GAIL reward: logit" in out
    results = json.loads((tmp_path / "runs/g/results.json").read_text())
    assert results["finished"] and [e["step"] for e in results["evals"]] == [250, 500]
    measures = results["reward_measures"]
    assert [m["step"] for m in measures] == [250, 500]
    assert measures == json.loads((tmp_path / "runs/g/dynamics.json").read_text())
    for key in ("r_s_demos", "r_s_student", "r_s_absorbing", "d_demos", "rfdc", "fs_rfdc"):
        assert np.isfinite(measures[1][key]), key
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
    # benchmarks/d_on_actions.py: D on the noisy pairs it trained on, as computed here; then a D blind to actions
    env = gail.make_env("InvertedPendulum-v4", 1)
    demos = gail.load_demonstrations(str(ROOT / "experts/InvertedPendulum-v4.npz"), env, 2)
    noisy = gail.expert_tensors(demos, ckpt["config"]["seed"], "cpu", 0.1, 0.5, -np.inf, np.inf)
    disc = gail.Discriminator(6, ckpt["config"]["disc_hidden_dim"], 1e-3, 1.0)
    disc.load_state_dict(ckpt["disc"])
    d_noisy = disc.prob(torch.cat([noisy["obs"], torch.zeros(len(noisy["obs"]), 1), noisy["actions"]], -1)).mean()
    read = lambda out, label: float(out.split(label)[1].split()[0])
    out = run("benchmarks/d_on_actions.py", "runs/g", "--out", "probe.json").stdout
    probe = json.loads((tmp_path / "probe.json").read_text())  # what sweep.py --report reads
    assert {f"demonstrations: {k}" for k in sweep.D_ON_ACTIONS} < set(probe["d"]) and probe["step"] == 500
    assert probe["d"]["demonstrations: actions D trained on"] == pytest.approx(d_noisy.item(), abs=1e-6)
    clean = gail.expert_tensors(demos, 1, "cpu")  # the expert's clean states with its clean actions
    d_clean = disc.prob(torch.cat([clean["obs"], torch.zeros(len(clean["obs"]), 1), clean["actions"]], -1)).mean()
    assert probe["d"]["clean: the expert's clean actions"] == pytest.approx(d_clean.item(), abs=1e-6) != d_noisy.item()
    edge = lambda a: (a.abs() > 0.95 * 3.0).float().mean().item()  # InvertedPendulum's box: [-3, 3]
    assert probe["edge"]["demonstrations D trained on"] == pytest.approx(edge(noisy["actions"]))
    assert probe["edge"]["clean demonstrations"] == pytest.approx(edge(clean["actions"]))
    assert probe["spread"]["demonstrations D trained on"] == pytest.approx(noisy["actions"].std(0).mean().item())
    assert "std 0.5 (unclipped)" in out and read(out, "actions D trained on") == pytest.approx(d_noisy.item(), abs=6e-4)
    labels = ("actions D trained on", "expert's clean actions", "mean action", "other states", "uniform random actions")
    assert len({read(out, label) for label in labels}) > 1  # a D that reads actions scores them apart
    ckpt["disc"]["net.0.weight"][:, -1] = 0.0  # blind to the action column
    torch.save(ckpt, tmp_path / "runs/g/checkpoint.pt")
    out = run("benchmarks/d_on_actions.py", "runs/g").stdout
    assert len({read(out, label) for label in labels}) == 1 and "action columns 0.000" in out
