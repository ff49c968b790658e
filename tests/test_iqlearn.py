"""iqlearn.py: the loss terms against hand-computed values for both value variants, the presets, the done
semantics, and a short run through every update path."""

import json

import numpy as np
import pytest
import torch

import iqlearn
from conftest import ROOT


def constant_q(q, value):
    with torch.no_grad():
        for w, b in zip(q.weights, q.biases):
            w.zero_()
            b.zero_()
        q.biases[-1].fill_(value)


def agent_with(monkeypatch, value_loss):
    args = iqlearn.apply_preset(iqlearn.Args(hidden_dim=8, value_loss=value_loss, alpha=0.1, gamma=0.9))
    agent = iqlearn.IQLearn(2, 1, -np.ones(1), np.ones(1), args, "cpu")
    constant_q(agent.q, 2.0)  # Q(s, a) = 2
    constant_q(agent.q_target, 3.0)  # Q_targ(s, a) = 3
    monkeypatch.setattr(agent.actor, "sample", lambda obs: (torch.zeros(len(obs), 1), torch.full((len(obs),), -1.0)))
    return agent


@pytest.mark.parametrize("value_loss", ["value", "v0"])
def test_loss_terms_by_hand(monkeypatch, value_loss):
    agent = agent_with(monkeypatch, value_loss)
    obs, actions, next_obs = torch.zeros(4, 2), torch.zeros(4, 1), torch.zeros(4, 2)
    dones = torch.tensor([0.0, 1.0, 0.0, 1.0])  # rows 0, 1: policy; rows 2, 3: expert
    is_expert = torch.tensor([False, False, True, True])
    loss, terms = agent.critic_loss(obs, actions, next_obs, dones, is_expert)
    v_targ = 3.0 - 0.1 * -1.0  # Q_targ - alpha log pi = 3.1
    y = np.array([0.9 * v_targ, 0.0, 0.9 * v_targ, 0.0])
    r = 2.0 - y  # implicit rewards: 2 - 2.79 = -0.79 where not done, 2 where done
    softq = -r[2:].mean()
    v = 2.0 + 0.1  # V(s) = Q - alpha log pi
    value = (v - y).mean() if value_loss == "value" else (1 - 0.9) * v
    chi2 = 1 / (4 * 0.5) * (r**2).mean()
    got = {name: term.item() for name, term in terms.items()}
    assert got["losses/softq"] == pytest.approx(softq) and got["losses/value"] == pytest.approx(value)
    assert got["losses/chi2"] == pytest.approx(chi2)
    assert got["losses/q_expert"] == pytest.approx(2.0) and got["losses/q_policy"] == pytest.approx(2.0)
    assert got["reward/implicit_expert"] == pytest.approx(r[2:].mean())
    assert got["reward/implicit_policy"] == pytest.approx(r[:2].mean())
    assert loss.item() == pytest.approx(softq + value + chi2)


class ActionQ(torch.nn.Module):
    """Q(s, a) = sum(a) + c, shaped like the critic block's output (1, batch)."""

    def __init__(self, c):
        super().__init__()
        self.c = torch.nn.Parameter(torch.tensor(c))

    def forward(self, obs, actions, detach_params=False):
        return (actions.sum(-1) + (self.c.detach() if detach_params else self.c)).unsqueeze(0)


@pytest.mark.parametrize("chi2_actions", ["policy", "replay"])
def test_chi2_on_policy_states_takes_the_current_policys_action(monkeypatch, chi2_actions):
    """The authors' online regulariser: on policy states r = Q(s, a~pi(s)) - y, not Q(s, a_replay) - y."""
    args = iqlearn.apply_preset(iqlearn.Args(hidden_dim=8, value_loss="value", alpha=0.1, gamma=0.9,
                                             chi2_actions=chi2_actions))
    agent = iqlearn.IQLearn(2, 1, -np.ones(1), np.ones(1), args, "cpu")
    agent.q, agent.q_target = ActionQ(2.0), ActionQ(3.0)
    pi_action = 0.5  # the current policy's action everywhere, log pi = -1
    monkeypatch.setattr(agent.actor, "sample",
                        lambda obs: (torch.full((len(obs), 1), pi_action), torch.full((len(obs),), -1.0)))
    obs, next_obs = torch.zeros(4, 2), torch.zeros(4, 2)
    actions = torch.tensor([[-1.0], [0.25], [1.0], [0.0]])  # rows 0, 1: replay (old policies); rows 2, 3: expert
    dones = torch.tensor([0.0, 1.0, 0.0, 0.0])
    is_expert = torch.tensor([False, False, True, True])
    loss, terms = agent.critic_loss(obs, actions, next_obs, dones, is_expert)
    y = np.array([0.9, 0.0, 0.9, 0.9]) * (3.0 + pi_action + 0.1)  # gamma (1 - d) (Q_targ(s', a') - alpha log pi)
    q_replay = 2.0 + actions[:, 0].numpy()
    r = q_replay - y
    r_chi2 = np.concatenate([2.0 + pi_action - y[:2], r[2:]]) if chi2_actions == "policy" else r
    assert terms["losses/chi2"].item() == pytest.approx(0.5 * (r_chi2**2).mean(), abs=1e-5)
    assert terms["reward/implicit_policy"].item() == pytest.approx(r[:2].mean(), abs=1e-5)  # logged at replay actions
    assert terms["losses/softq"].item() == pytest.approx(-r[2:].mean(), abs=1e-5)
    if chi2_actions == "policy":
        assert terms["reward/implicit_current_policy"].item() == pytest.approx((2.0 + pi_action - y[:2]).mean(), abs=1e-5)


def test_actor_loss_uses_both_batches_and_leaves_q_alone(monkeypatch):
    agent = agent_with(monkeypatch, "value")
    loss = agent.actor_loss(torch.zeros(6, 2))
    assert loss.item() == pytest.approx(0.1 * -1.0 - 2.0)
    torch.manual_seed(0)
    fresh_args = iqlearn.apply_preset(iqlearn.Args(hidden_dim=8, value_loss="v0", alpha=0.1))
    fresh = iqlearn.IQLearn(2, 1, -np.ones(1), np.ones(1), fresh_args, "cpu")
    fresh.actor_loss(torch.randn(5, 2)).backward()
    assert all(p.grad is None for p in fresh.q.parameters())


def test_update_steps_the_critic_actor_and_target():
    torch.manual_seed(0)
    args = iqlearn.apply_preset(iqlearn.Args(hidden_dim=8, value_loss="value", alpha=0.01))
    agent = iqlearn.IQLearn(2, 1, -np.ones(1), np.ones(1), args, "cpu")
    before = [p.clone() for p in agent.q_target.parameters()]
    policy = iqlearn.Batch(torch.randn(4, 2), torch.rand(4, 1), torch.randn(4, 2), torch.zeros(4), torch.zeros(4),
                           torch.zeros(4, 0))
    expert = {"obs": torch.randn(4, 2), "actions": torch.rand(4, 1), "next_obs": torch.randn(4, 2),
              "terminations": torch.zeros(4)}
    metrics = agent.update(policy, expert)
    assert set(metrics) == {"losses/critic", "losses/actor", "losses/softq", "losses/value", "losses/chi2", "losses/q_expert",
                            "losses/q_policy", "reward/implicit_expert", "reward/implicit_policy",
                            "reward/implicit_current_policy"}
    assert all(torch.isfinite(value) for value in metrics.values())
    for old, online, new in zip(before, agent.q.parameters(), agent.q_target.parameters()):
        assert torch.allclose(new, 0.995 * old + 0.005 * online, atol=1e-6)


def test_presets():
    a = iqlearn.apply_preset(iqlearn.Args(env_id="Hopper-v4"))
    assert (a.value_loss, a.alpha, a.policy_lr, a.chi2_actions) == ("v0", 1e-2, 3e-5, "policy")  # Hopper's runs stand
    a = iqlearn.apply_preset(iqlearn.Args(env_id="HalfCheetah-v4", alpha=0.5))
    assert (a.value_loss, a.alpha, a.policy_lr) == ("value", 0.5, 3e-5)  # explicit flags win
    a = iqlearn.apply_preset(iqlearn.Args(env_id="Humanoid-v4", preset="none"))
    assert (a.value_loss, a.alpha, a.policy_lr, a.chi2_actions) == ("value", 1e-2, 3e-4, "policy")  # IQ-Learn's generic
    a = iqlearn.apply_preset(iqlearn.Args(env_id="Pendulum-v1"))
    assert (a.value_loss, a.alpha, a.policy_lr, a.chi2_actions) == ("v0", 1e-2, 3e-4, "replay")  # an env it does not list
    a = iqlearn.apply_preset(iqlearn.Args(env_id="Pendulum-v1", policy_lr=1e-3, value_loss="value", chi2_actions="policy"))
    assert (a.value_loss, a.policy_lr, a.chi2_actions) == ("value", 1e-3, "policy")


@pytest.mark.parametrize("timeout_done", [False, True])
def test_end_to_end_and_done_semantics(run, tmp_path, timeout_done):
    out = run("iqlearn.py", "--env-id", "InvertedPendulum-v4", "--total-timesteps", "1300", "--learning-starts", "300",
              "--eval-freq", "650", "--eval-episodes", "2", "--hidden-dim", "32", "--batch-size", "32",
              "--num-expert-trajs", "2", "--expert-path", str(ROOT / "experts/InvertedPendulum-v4.npz"), "--run-name", "iq",
              *(["--timeout-done"] if timeout_done else [])).stdout
    assert ("truncations count as done" if timeout_done else "only terminations are done") in out
    results = json.loads((tmp_path / "runs/iq/results.json").read_text())
    assert results["finished"] and [e["step"] for e in results["evals"]] == [650, 1300]
    ckpt = torch.load(tmp_path / "runs/iq/checkpoint.pt", weights_only=False)
    assert ckpt["q_optimizer"]["state"] and ckpt["actor_optimizer"]["state"] and ckpt["step"] == 1300
