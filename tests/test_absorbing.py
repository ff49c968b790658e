"""DAC's absorbing states (`--termination-remedy absorbing` of rile.py, gail.py, airl.py, gaifo.py): the
shared `absorbing` block (tested through rile.py; test_shared_blocks keeps the copies identical) and
the SAC block's handling of the absorbing state (tested through gail.py, the reference copy)."""

import numpy as np
import pytest
import torch

import gail
import rile

OBS, ACT = 3, 2


def test_store_sends_terminations_to_the_absorbing_state():
    rb = rile.ReplayBuffer(OBS + 1, ACT, 10, "cpu", extra_dim=1)
    s, a, s2 = np.array([1.0, 2, 3]), np.array([0.5, -0.5]), np.array([4.0, 5, 6])
    rile.store(rb, s, a, s2, 7.0, False, True, [0.1], [0.9])  # an ordinary step (or a truncation)
    rile.store(rb, s, a, s2, 8.0, True, True, [0.2], [0.9])  # a termination: two rows
    obs, actions, next_obs, rewards, terms, extra = rb.batch(torch.arange(rb.size))
    s_abs = torch.tensor([0.0, 0, 0, 1])
    assert rb.size == 3 and not terms.any()  # nothing is terminal any more
    assert torch.equal(obs[0], torch.tensor([1.0, 2, 3, 0])) and torch.equal(next_obs[0], torch.tensor([4.0, 5, 6, 0]))
    assert torch.equal(obs[1], torch.tensor([1.0, 2, 3, 0])) and torch.equal(next_obs[1], s_abs)
    assert rewards[1] == 8.0 and torch.equal(actions[1], torch.tensor([0.5, -0.5]))
    assert torch.equal(obs[2], s_abs) and torch.equal(next_obs[2], s_abs) and torch.equal(actions[2], torch.zeros(ACT))
    assert rewards[2] == 0.0 and torch.equal(extra.squeeze(-1), torch.tensor([0.1, 0.2, 0.9]))


def test_store_without_absorbing_keeps_the_termination():
    rb = rile.ReplayBuffer(OBS, ACT, 10, "cpu")
    rile.store(rb, np.ones(OBS), np.zeros(ACT), np.full(OBS, 2.0), 1.0, True, False)
    obs, _, next_obs, _, terms, _ = rb.batch(torch.arange(rb.size))
    assert rb.size == 1 and terms[0] == 1.0 and torch.equal(next_obs[0], torch.full((OBS,), 2.0))


def test_expert_data_gets_the_same_treatment_as_the_agents():
    """Agent and expert data must look alike to the discriminator: absorbing_expert on demonstrations
    gives the rows store() writes for the same transitions (up to their order)."""
    g = torch.Generator().manual_seed(0)
    n = 6
    demo = {"obs": torch.randn(n, OBS, generator=g), "actions": torch.rand(n, ACT, generator=g) * 2 - 1,
            "next_obs": torch.randn(n, OBS, generator=g), "terminations": torch.tensor([0.0, 0, 1, 0, 0, 1])}
    out = rile.absorbing_expert(demo)
    rb = rile.ReplayBuffer(OBS + 1, ACT, 20, "cpu")
    for i in range(n):
        rile.store(rb, demo["obs"][i].numpy(), demo["actions"][i].numpy(), demo["next_obs"][i].numpy(), 0.0,
                   bool(demo["terminations"][i]), True)
    obs, actions, next_obs, _, terms, _ = rb.batch(torch.arange(rb.size))
    as_rows = lambda o, a, o2, t: sorted(map(tuple, torch.cat([o, a, o2, t[:, None]], 1).tolist()))
    assert len(out["obs"]) == n + 2 and not out["terminations"].any()
    assert as_rows(out["obs"], out["actions"], out["next_obs"], out["terminations"]) == as_rows(obs, actions, next_obs, terms)


def sac(absorbing, autotune=False):
    torch.manual_seed(0)
    args = gail.Args(hidden_dim=16, autotune=autotune)
    return gail.SAC(OBS + absorbing, ACT, -np.ones(ACT), np.ones(ACT), args, "cpu", absorbing=absorbing)


def test_actor_never_sees_the_indicator_and_acts_zero_at_the_absorbing_state():
    agent = sac(True)
    assert agent.actor.net[0].in_features == OBS and agent.qf.weights[0].shape[1] == OBS + 1 + ACT
    live = torch.tensor([[0.3, -0.2, 0.1, 0.0]])
    absorbing = torch.tensor([[0.0, 0, 0, 1]])
    torch.manual_seed(1)
    a, log_pi = agent.policy(live)
    torch.manual_seed(1)
    a_ref, log_pi_ref = agent.actor.sample(live[:, :-1])
    assert torch.equal(a, a_ref) and torch.equal(log_pi, log_pi_ref)
    a, log_pi = agent.policy(absorbing)
    assert torch.equal(a, torch.zeros(1, ACT)) and log_pi.item() == 0.0
    plain = sac(False)
    assert plain.policy(torch.randn(4, OBS))[0].shape == (4, ACT)


def test_td_target_at_the_absorbing_state_by_hand():
    """r + gamma min_i Q'_i(s_abs, 0): zero action, no entropy term, and it always bootstraps."""
    agent = sac(True)
    s_abs = torch.tensor([[0.0, 0, 0, 1]])
    target = agent.td_target(s_abs, torch.tensor([0.5]), torch.tensor([0.0]))
    q = agent.qf_target(s_abs, torch.zeros(1, ACT)).min(0).values
    assert target.item() == pytest.approx(0.5 + 0.99 * q.item(), rel=1e-6)


@pytest.mark.parametrize("autotune", [False, True])
def test_actor_and_temperature_losses_ignore_absorbing_rows(autotune, monkeypatch):
    agent = sac(True, autotune)
    # a deterministic stand-in for the sampled policy, so that two batches can be compared row by row
    monkeypatch.setattr(agent.actor, "sample", lambda o: (torch.tanh(o[:, :ACT]), o.sum(-1)))
    live = torch.cat([torch.randn(5, OBS), torch.zeros(5, 1)], 1)
    absorbing = torch.tensor([[0.0, 0, 0, 1]]).expand(3, -1)
    mixed, alone = agent.actor_loss(torch.cat([live, absorbing])), agent.actor_loss(live)
    for x, y in zip(mixed, alone):
        assert x.item() == pytest.approx(y.item(), rel=1e-5)
