"""airl.py: f's shaping term and its termination mask, the logit f - log pi, the loss and gradient penalty
by hand, relabelling from the current networks, and short runs through every update path."""

import json
import math

import numpy as np
import pytest
import torch
import torch.nn as nn
import torch.nn.functional as F

import airl
from conftest import ROOT


def linear_disc(gamma=0.9, gp_weight=1.0):
    """g(s, a) = sum(s) + sum(a); h(s) = 2 sum(s) + 1 (obs 2-d, action 1-d)."""
    disc = airl.AIRLDiscriminator(2, 1, 8, gamma, state_only=False, lr=1e-3, gp_weight=gp_weight)
    disc.g, disc.h = nn.Linear(3, 1), nn.Linear(2, 1)
    with torch.no_grad():
        disc.g.weight.fill_(1.0)
        disc.g.bias.zero_()
        disc.h.weight.fill_(2.0)
        disc.h.bias.fill_(1.0)
    return disc


def test_shaping_is_masked_by_terminations_not_truncations():
    disc = linear_disc()
    s, a, s_next = torch.tensor([[1.0, 2.0]]), torch.tensor([[0.5]]), torch.tensor([[3.0, 1.0]])
    g, h, h_next = 3.5, 7.0, 9.0
    terminated = disc(s, a, s_next, torch.tensor([1.0]))
    truncated = disc(s, a, s_next, torch.tensor([0.0]))  # a time-limit end is stored as not terminated
    assert terminated.item() == pytest.approx(g - h)
    assert truncated.item() == pytest.approx(g + 0.9 * h_next - h)
    assert disc.reward_g(s, a).item() == pytest.approx(g)


def test_loss_and_gradient_penalty_by_hand():
    disc = linear_disc(gamma=0.5)
    zero = torch.tensor([0.0])
    expert = (torch.tensor([[1.0, 0.0]]), torch.tensor([[0.0]]), torch.tensor([[0.0, 0.0]]), zero)
    policy = (torch.tensor([[0.0, 0.0]]), torch.tensor([[1.0]]), torch.tensor([[1.0, 1.0]]), zero)
    loss, bce, gp, expert_prob, policy_prob = disc.loss(expert, policy, torch.tensor([-1.0]), torch.tensor([0.5]))
    f_expert = 1.0 + 0.5 * 1.0 - 3.0  # g = 1, h(s') = 1, h(s) = 3
    f_policy = 1.0 + 0.5 * 5.0 - 1.0  # g = 1, h(s') = 5, h(s) = 1
    l_e, l_p = f_expert + 1.0, f_policy - 0.5  # logits: f - log pi
    want_bce = np.log1p(np.exp(-l_e)) + np.log1p(np.exp(l_p))
    # grad of f w.r.t. (s, a, s') = (1 - 2, 1 - 2, 1, 0.5 * 2, 0.5 * 2): norm sqrt(1 + 1 + 1 + 1 + 1)
    want_gp = (np.sqrt(5.0) - 1) ** 2
    assert bce.item() == pytest.approx(want_bce, rel=1e-6) and gp.item() == pytest.approx(want_gp, rel=1e-6)
    assert loss.item() == pytest.approx(want_bce + want_gp, rel=1e-6)
    assert expert_prob.item() == pytest.approx(1 / (1 + np.exp(-l_e)))


def make(monkeypatch, **kw):
    torch.manual_seed(0)
    args = airl.Args(hidden_dim=16, batch_size=8, disc_batch_size=4, disc_hidden_dim=8, **kw)
    agent = airl.SAC(2, 1, np.array([-0.4]), np.array([0.4]), args, "cpu")
    disc = airl.AIRLDiscriminator(2, 1, 8, args.gamma, args.state_only, args.disc_lr, args.disc_gp)
    rb = airl.ReplayBuffer(2, 1, 20, "cpu")
    for i in range(20):
        rb.add(np.array([i / 10, 0.0]), np.array([0.1]), np.array([i / 10 + 0.1, 0.0]), 5.0, i % 5 == 4)
    expert = {"obs": torch.randn(10, 2), "actions": torch.full((10, 1), 0.4),  # on the bound of the box
              "next_obs": torch.randn(10, 2), "terminations": torch.zeros(10)}
    seen = []

    def capture(obs, actions, next_obs, rewards, terminations, prefix):  # the networks as they are at the SAC update
        want = disc(obs, actions, next_obs, terminations) if args.reward == "f" else disc.reward_g(obs, actions)
        if args.reward == "softplus":  # -log(1 - D): D's logit with the current actor's log pi of the stored actions
            log_pi = airl.policy_log_prob(agent, obs, actions, args.disc_policy_mix)
            want = F.softplus(disc(obs, actions, next_obs, terminations) - log_pi)
        seen.append((rewards, want.detach()))
        return {}

    monkeypatch.setattr(agent, "update", capture)
    return args, agent, disc, rb, expert, seen


@pytest.mark.parametrize("reward,mix", [("f", 1.0), ("g", 0.0), ("softplus", 1.0), ("softplus", 0.0)])
def test_rewards_are_relabelled_from_the_current_networks(monkeypatch, reward, mix):
    args, agent, disc, rb, expert, seen = make(monkeypatch, reward=reward, disc_policy_mix=mix)
    for _ in range(3):
        out = airl.airl_update(agent, disc, rb, expert, args)
        rewards, want = seen[-1]
        assert torch.allclose(rewards, want) and not torch.any(rewards == 5.0)
        disc_metrics = [out[k] for k in ("losses/disc_loss", "losses/disc_gp", "disc/expert_prob", "disc/policy_prob")]
        assert torch.isfinite(torch.stack(disc_metrics)).all()  # expert actions on the bound: log pi stays finite


def test_state_only_reward_ignores_actions(monkeypatch):
    args, agent, disc, rb, expert, seen = make(monkeypatch, state_only=True)
    s = torch.randn(4, 2)
    assert torch.equal(disc.reward_g(s, torch.zeros(4, 1)), disc.reward_g(s, torch.ones(4, 1)))


def test_end_to_end(run, tmp_path):
    common = ["--env-id", "InvertedPendulum-v4", "--total-timesteps", "500", "--learning-starts", "200",
              "--eval-freq", "250", "--eval-episodes", "2", "--hidden-dim", "32", "--batch-size", "32",
              "--num-expert-trajs", "2", "--expert-path", str(ROOT / "experts/InvertedPendulum-v4.npz"),
              "--dynamics-freq", "250"]
    out = run("airl.py", *common, "--run-name", "a", "--expert-action-noise", "0.2", "--disc-policy-mix", "0.1").stdout
    assert "AIRL reward: softplus" in out  # the default, with terminations terminal
    out = run("airl.py", *common, "--run-name", "b", "--reward", "g", "--state-only", "--termination-remedy", "absorbing",
              "--disc-policy-mix", "0").stdout  # the paper's D: the policy's own log pi
    assert "AIRL reward: g (state-only g)" in out
    results = json.loads((tmp_path / "runs/b/results.json").read_text())
    assert results["finished"] and [e["step"] for e in results["evals"]] == [250, 500]
    keys = {"a": ("r_s_demos", "r_s_student", "d_demos", "d_student", "rfdc"), "b": ("r_s_absorbing", "fs_rfdc")}
    for name, keys in keys.items():
        measures = json.loads((tmp_path / f"runs/{name}/results.json").read_text())["reward_measures"]  # the paper's measures
        assert [m["step"] for m in measures] == [250, 500] and all(np.isfinite(measures[1][k]) for k in keys), name
    saved = torch.load(tmp_path / "runs/b/reward.pt", weights_only=True)
    assert saved["state_only"] and saved["g"]["0.weight"].shape[1] == 5  # g(s) of the 4-d state + absorbing indicator
    # the reward check reads the checkpoint: f on the demonstrations, on the learner, and what falling is worth
    out = run("benchmarks/airl_rewards.py", "runs/b").stdout
    assert "at step 500" in out and "f on the demonstrations" in out and "f on the learner's living" in out
    assert "log pi in the logit" in out
    assert ("worth of falling" in out) or ("no falls" in out)
    out = run("benchmarks/airl_rewards.py", "runs/a").stdout  # terminations terminal: the falling step, then 0
    assert "terminations none" in out and "SAC's reward on the demonstrations" in out
    assert "SAC's reward on the falling step" in out and "the last reward then 0" in out  # the pendulum falls early
    proc = run("airl.py", *common, "--run-name", "c", "--disc-policy-mix", "1.5", check=False)
    assert proc.returncode != 0 and "--disc-policy-mix 1.5 is not in [0, 1]" in proc.stderr


def test_log_pi_with_absorbing_states():
    """The logit's log pi(a|s): the actor's on the state without its indicator, 0 at the absorbing state."""
    torch.manual_seed(0)
    agent = airl.SAC(3, 1, -np.ones(1), np.ones(1), airl.Args(hidden_dim=8), "cpu", absorbing=True)
    obs = torch.tensor([[0.3, -0.4, 0.0], [0.0, 0.0, 1.0]])
    actions = torch.tensor([[0.2], [0.0]])
    log_pi = airl.policy_log_prob(agent, obs, actions)
    assert log_pi[0].item() == pytest.approx(agent.actor.log_prob(obs[:1, :2], actions[:1]).item()) and log_pi[1].item() == 0.0


def test_log_pi_mixed_with_uniform_by_hand():
    """--disc-policy-mix m: log((1 - m) pi(a|s) + m / box volume), by hand for a 1-d Gaussian squashed into [-2, 2]."""
    agent = airl.SAC(3, 1, -2 * np.ones(1), 2 * np.ones(1), airl.Args(hidden_dim=8), "cpu", absorbing=True)
    for p in agent.actor.parameters():
        nn.init.zeros_(p)  # mean 0, log std = (LOG_STD_MIN + LOG_STD_MAX) / 2 = -1.5 everywhere
    obs = torch.tensor([[0.3, -0.4, 0.0], [0.0, 0.0, 1.0]])
    actions = torch.tensor([[1.0], [0.0]])
    std, u = math.exp(-1.5), math.atanh(0.5)  # a = 2 tanh(u)
    log_pi = (-0.5 * (u / std) ** 2 - math.log(std) - 0.5 * math.log(2 * math.pi)
              - math.log(1 - 0.5 ** 2) - math.log(2))  # Gaussian in u, minus log |da/du| = log(2 (1 - tanh(u)^2))
    assert airl.policy_log_prob(agent, obs, actions)[0].item() == pytest.approx(log_pi, rel=1e-5)
    mixed = airl.policy_log_prob(agent, obs, actions, mix=0.1)
    assert mixed[0].item() == pytest.approx(math.log(0.9 * math.exp(log_pi) + 0.1 / 4), rel=1e-5)
    assert mixed[1].item() == 0.0  # the absorbing state's only action
    far = airl.policy_log_prob(agent, obs[:1], torch.tensor([[1.99]]), mix=0.1)  # far in the tail: the uniform's floor
    assert far.item() == pytest.approx(math.log(0.1 / 4), abs=1e-3)
    uniform = airl.policy_log_prob(agent, obs, actions, mix=1.0)  # the uniform alone: D no longer sees pi
    assert uniform[0].item() == pytest.approx(-math.log(4), rel=1e-6) and uniform[1].item() == 0.0


def test_absorbing_anchor_by_hand():
    """--absorbing-anchor min: h(s_abs) = 0 in f, and SAC's reward at s_abs is the batch's lowest living g."""
    disc = airl.AIRLDiscriminator(3, 1, 8, 0.9, state_only=False, lr=1e-3, gp_weight=1.0, zero_absorbing_potential=True)
    disc.g, disc.h = nn.Linear(4, 1), nn.Linear(3, 1)  # g(s, a) = sum(s) + sum(a); h(s) = 2 sum(s) + 1
    with torch.no_grad():
        disc.g.weight.fill_(1.0)
        disc.g.bias.zero_()
        disc.h.weight.fill_(2.0)
        disc.h.bias.fill_(1.0)
    s_abs = [0.0, 0.0, 1.0]
    batch = airl.Batch(obs=torch.tensor([[1.0, 2.0, 0.0], [1.0, 0.0, 0.0], s_abs]),  # living, falling, absorbed
                       actions=torch.tensor([[0.5], [1.0], [0.0]]),
                       next_obs=torch.tensor([[3.0, 1.0, 0.0], s_abs, s_abs]), rewards=torch.zeros(3),
                       terminations=torch.zeros(3), extra=torch.zeros(3, 0))
    # g = 3.5, 2, 1; h(s) = 7, 3, 0 (absorbing); h(s') = 9, 0, 0
    f = [3.5 + 0.9 * 9 - 7, 2 - 3, 1.0]
    assert disc(batch.obs, batch.actions, batch.next_obs, batch.terminations).tolist() == pytest.approx(f)
    g_min = 2.0  # the lowest g among the living transitions (the first two)
    assert airl.sac_reward(disc, batch, "f", anchor=True).tolist() == pytest.approx([f[0], f[1], g_min])
    assert airl.sac_reward(disc, batch, "g", anchor=True).tolist() == pytest.approx([3.5, 2.0, g_min])
    assert airl.sac_reward(disc, batch, "f", anchor=False).tolist() == pytest.approx(f)  # learned: f as it is
    log_pi = torch.tensor([-1.0, 0.5, 0.0])  # softplus: -log(1 - D) of the logit f - log pi (no level here)
    paid = [math.log1p(math.exp(f[0] + 1.0)), math.log1p(math.exp(f[1] - 0.5))]
    assert airl.sac_reward(disc, batch, "softplus", anchor=True, log_pi=log_pi).tolist() == pytest.approx(
        paid + [min(paid)])  # the anchor: the lowest reward paid on a living transition
    disc.zero_absorbing_potential = False  # DAC's learned absorbing state: h(s_abs) = 2 + 1 = 3 is learned too
    assert disc(batch.obs, batch.actions, batch.next_obs, batch.terminations).tolist() == pytest.approx(
        [f[0], 2 + 0.9 * 3 - 3, 1 + 0.9 * 3 - 3])


def test_free_level_enters_the_logit_not_the_reward():
    """--disc-level-lr: logit f + b - log pi, b learned with its own rate; SAC's reward is f alone."""
    disc = linear_disc(gamma=0.5)
    disc.register_parameter("level", nn.Parameter(torch.tensor(2.0)))
    disc.optimizer = torch.optim.Adam([{"params": list(disc.g.parameters()) + list(disc.h.parameters()), "lr": 0.0},
                                       {"params": [disc.level], "lr": 0.1}])
    zero = torch.tensor([0.0])
    expert = (torch.tensor([[1.0, 0.0]]), torch.tensor([[0.0]]), torch.tensor([[0.0, 0.0]]), zero)
    policy = (torch.tensor([[0.0, 0.0]]), torch.tensor([[1.0]]), torch.tensor([[1.0, 1.0]]), zero)
    loss, bce, gp, expert_prob, policy_prob = disc.loss(expert, policy, torch.tensor([-1.0]), torch.tensor([0.5]))
    f_expert, f_policy = -1.5, 2.5  # as in test_loss_and_gradient_penalty_by_hand
    l_e, l_p = f_expert + 2.0 + 1.0, f_policy + 2.0 - 0.5
    assert bce.item() == pytest.approx(np.log1p(np.exp(-l_e)) + np.log1p(np.exp(l_p)), rel=1e-6)
    metrics = disc.update(expert, policy, torch.tensor([-1.0]), torch.tensor([0.5]))
    assert disc.level.item() == pytest.approx(2.0 - 0.1)  # Adam's first step: lr times the gradient's sign (D(policy) high)
    assert metrics["disc/level"].item() == pytest.approx(1.9)
    batch = airl.Batch(*policy[:3], torch.zeros(1), policy[3], torch.zeros(1, 0))
    assert airl.sac_reward(disc, batch, "f", anchor=False).item() == pytest.approx(f_policy)  # b is never paid
    softplus = airl.sac_reward(disc, batch, "softplus", anchor=False, log_pi=torch.tensor([0.5]))  # except inside D
    assert softplus.item() == pytest.approx(math.log1p(math.exp(f_policy + 1.9 - 0.5)), rel=1e-6)
