"""rile.py: the trainer rewards, the student's reward, the trainer's transitions, freezing, expert
fractions, noise, the reward-dynamics metrics, the discriminator loss, the saved reward, end to end."""

import json
import re
from dataclasses import replace
from types import SimpleNamespace

import numpy as np
import pytest
import torch
import torch.nn as nn

import airl
import gail
import rile
from benchmarks import policy_modes, reward_dynamics
from conftest import ROOT

OBS, ACT = 3, 2


def tiny_args(**kw):
    base = dict(hidden_dim=16, trainer_hidden_dim=16, batch_size=8, trainer_batch_size=8, disc_batch_size=4,
                disc_hidden_dim=8, trainer_buffer_size=6, disc_buffer_size=6, trainer_expert_fraction=0.0,
                termination_remedy="survival")  # learners() below has no absorbing indicator
    return rile.Args(**(base | kw))


def learners(args):
    torch.manual_seed(0)
    student = rile.SAC(OBS, ACT, -np.ones(ACT), np.ones(ACT), args, "cpu")
    trainer = rile.make_trainer(OBS, ACT, args, "cpu")
    disc = rile.Discriminator(OBS + ACT, args.disc_hidden_dim, args.disc_lr, args.disc_gp)
    rb = rile.ReplayBuffer(OBS, ACT, 50, "cpu", extra_dim=1)
    for i in range(20):  # obs encode the row index, so batches can be traced back to rows
        rb.add(np.full(OBS, i), np.full(ACT, 0.01 * i), np.full(OBS, i + 0.5), 1.0, i % 7 == 6, extra=[0.02 * i - 0.2])
    expert = {"obs": torch.full((10, OBS), 100.0) + torch.arange(10.0)[:, None], "actions": torch.full((10, ACT), 0.5),
              "next_obs": torch.full((10, OBS), 200.0), "terminations": torch.zeros(10)}
    state = rile.rile_state("cpu")
    return student, trainer, disc, rb, expert, state


def recorder(seen: dict, name: str):
    """A stand-in for SAC.update that records the batch it is given and returns a critic loss of 0."""
    def update(*batch, prefix):
        seen.setdefault(name, batch)
        return {prefix + "qf_loss": torch.tensor(0.0), prefix + "qf_target_var": torch.tensor(1.0)}
    return update


# ---------------------------------------------------------------- rewards


def test_policy_modes_finds_a_halfcheetah_on_its_back():
    # the step after which |torso pitch| first exceeds pi/2, counted from 1; none while it stays upright
    assert policy_modes.turned_over(np.array([0.0, 1.0, -1.6, 0.2])) == 3
    assert policy_modes.turned_over(np.array([3.2])) == 1 and policy_modes.turned_over(np.array([0.1, -1.5])) is None
    # the index it reads is the torso's pitch: set the root's rotation and read it back from the observation
    env = rile.make_env("HalfCheetah-v4", 0)
    env.reset(seed=0)
    qpos, qvel = env.unwrapped.data.qpos.copy(), env.unwrapped.data.qvel.copy()
    qpos[2] = 3.0  # rootx, rootz, rooty: the pitch
    env.unwrapped.set_state(qpos, qvel)
    assert env.unwrapped._get_obs()[policy_modes.TORSO_PITCH["HalfCheetah-v4"]] == pytest.approx(3.0)


def test_trainer_rewards_against_hand_computed_values():
    d, a = torch.tensor([0.2, 0.9]), torch.tensor([0.5, -1.0])  # v(D) = 2D - 1 = (-0.6, 0.8)
    want = {
        "difference": [-1.1, -1.8],
        "exp-difference": [np.exp(-1.1), np.exp(-1.8)],
        "multiplication": [-0.3, -0.8],
        "naive": [0.2, 0.9],
        "exp-naive": [np.exp(0.8), np.exp(0.1)],
        "sigmoid": [0.2 / (1 + np.exp(-0.5)), 0.9 / (1 + np.exp(1.0))],
    }
    assert set(want) == set(rile.TRAINER_REWARDS)
    for name, values in want.items():
        assert rile.TRAINER_REWARDS[name](d, a).tolist() == pytest.approx(values, rel=1e-6), name


def test_exp_difference_is_maximised_at_v_of_d():
    d = torch.tensor(0.8)
    actions = torch.linspace(-1, 1, 201)
    best = actions[rile.TRAINER_REWARDS["exp-difference"](d, actions).argmax()]
    assert best.item() == pytest.approx(0.6, abs=1e-6)


def test_what_each_trainer_reward_teaches_a_trainer_on_a_fixed_discriminator():
    """docs/rile.md's predictions for the six trainer rewards, on a fixed D (sigmoid(3 x) of o_T's first entry, so that
    v(D) = 2D - 1 spans [-0.98, 0.98] over the grid) after 400 updates of a small trainer at the paper's fixed
    temperature 0.2 on uniform a_T. Its deterministic action, what pays the student: v(D) for difference and
    exp-difference; for multiplication, whose entropy-free best action is sign(v(D)), a steeper v(D) of the same sign;
    near 0 whatever D says for naive and exp-naive, which a_T does not enter; for sigmoid, whose entropy-free best
    action is +1, a rise from about 0 where D is 0 to about 0.5 where D is 1."""
    d_of = lambda o: torch.sigmoid(3 * o[:, 0])
    grid = torch.stack([torch.linspace(-1.5, 1.5, 101), torch.zeros(101)], -1)  # o_T = (s, a_S), one dim each
    v = 2 * d_of(grid) - 1
    learned = {}
    for name, reward in rile.TRAINER_REWARDS.items():
        torch.manual_seed(0)
        trainer = rile.make_trainer(1, 1, rile.Args(trainer_hidden_dim=32, trainer_lr=3e-3, trainer_tau=0.05), "cpu")
        for _ in range(400):
            o, a, o_next = torch.rand(64, 2) * 3 - 1.5, torch.rand(64, 1) * 2 - 1, torch.rand(64, 2) * 3 - 1.5
            trainer.update(o, a, o_next, reward(d_of(o), a.squeeze(-1)), torch.zeros(64), prefix="trainer/")
        with torch.no_grad():
            learned[name] = trainer.actor.deterministic(grid).squeeze(-1)
    corr = lambda x: float(np.corrcoef(x.numpy(), v.numpy())[0, 1])
    for name in ("difference", "exp-difference"):
        assert corr(learned[name]) > 0.98 and (learned[name] - v).abs().mean() < 0.2, name
    steep, far = learned["multiplication"], v.abs() > 0.2
    assert (steep.sign() == v.sign())[far].all() and (steep.abs() > v.abs())[(v.abs() > 0.2) & (v.abs() < 0.6)].all()
    for name in ("naive", "exp-naive"):
        assert learned[name].abs().max() < 0.15, name
    rising = learned["sigmoid"]
    assert rising[:10].abs().max() < 0.15 and 0.3 < rising[-10:].min() and rising.max() < 0.7 and corr(rising) > 0.9


def test_student_reward_is_the_trainers_action_on_that_batch():
    args = tiny_args()
    student, trainer, disc, rb, expert, state = learners(args)
    obs, actions = torch.randn(5, OBS), torch.rand(5, ACT)
    a_t = trainer.actor.deterministic(torch.cat([obs, actions], -1)).squeeze(-1)
    obs_t = rile.trainer_input(obs, actions, None, "state-action")
    assert torch.equal(rile.student_reward(trainer.actor, obs_t, "none"), a_t)
    assert torch.allclose(rile.student_reward(trainer.actor, obs_t, "survival"), (1 + a_t) / 2)


def test_update_relabels_the_student_batch_with_the_current_trainer(monkeypatch):
    args = tiny_args()
    student, trainer, disc, rb, expert, state = learners(args)
    seen = []

    def capture(obs, actions, next_obs, rewards, terminations, prefix):  # the trainer as it is when the student learns
        expected = (1 + trainer.actor.deterministic(torch.cat([obs, actions], -1)).squeeze(-1)) / 2
        seen.append((rewards, expected.detach()))
        return {}

    monkeypatch.setattr(student, "update", capture)
    rile.rile_update(student, trainer, disc, rb, expert, args, state, 1)
    rile.rile_update(student, trainer, disc, rb, expert, args, state, 1)  # the trainer changed in between
    for rewards, expected in seen:
        assert torch.allclose(rewards, expected)
    assert not torch.allclose(seen[0][1], seen[1][1])


def test_the_control_rewards_the_student_with_v_of_d_and_has_no_trainer(monkeypatch):
    """--student-reward discriminator: r_S = 2D - 1 of D as it is when the student learns (D then takes its step), no
    trainer step; with --termination-remedy survival, (1 + v(D)) / 2 = D."""
    for remedy, of_d in (("none", lambda d: 2 * d - 1), ("survival", lambda d: d)):
        args = tiny_args(termination_remedy=remedy, student_reward="discriminator")
        student, _, disc, rb, expert, state = learners(args)
        seen = []

        def capture(obs, actions, next_obs, rewards, terminations, prefix):
            seen.append((rewards, of_d(torch.sigmoid(disc(torch.cat([obs, actions], -1))))))
            return {}

        monkeypatch.setattr(student, "update", capture)
        before = params(disc)
        out = rile.rile_update(student, None, disc, rb, expert, args, state, 1)
        assert changed(before, disc)  # D learns as in RILe
        rile.rile_update(student, None, disc, rb, expert, args, state, 1)  # and the reward follows it
        for rewards, expected in seen:
            assert torch.allclose(rewards, expected)
        assert not torch.allclose(seen[0][1], seen[1][1]) and len(seen[0][0]) == args.batch_size
        assert state["trainer_updates"] == 0 and not any(key.startswith(("losses/trainer_", "reward/trainer")) for key in out)
    d = SimpleNamespace(prob=lambda x: x)  # a D whose output is its input
    assert rile.discriminator_reward(d, torch.tensor([0.0, 0.25, 1.0]), "none").tolist() == [-1.0, -0.5, 1.0]
    assert rile.discriminator_reward(d, torch.tensor([0.0, 0.25, 1.0]), "survival").tolist() == [0.0, 0.25, 1.0]


def test_trainer_transition_layout(monkeypatch):
    args = tiny_args(termination_remedy="none")
    student, trainer, disc, rb, expert, state = learners(args)
    seen = {}
    monkeypatch.setattr(trainer, "update", recorder(seen, "trainer"))
    torch.manual_seed(1)
    rile.rile_update(student, trainer, disc, rb, expert, args, state, 1)
    obs_t, a_t, next_obs_t, r_t, terminated = seen["trainer"]
    rows = obs_t[:, 0].long()
    assert set(rows.tolist()) <= set(range(14, 20))  # the trainer's window: the 6 most recent rows
    assert torch.equal(obs_t[:, :OBS], rows[:, None].float().expand(-1, OBS))  # o_T = (s, a_S)
    assert torch.allclose(obs_t[:, OBS:], 0.01 * rows[:, None].float().expand(-1, ACT))
    assert torch.allclose(a_t.squeeze(-1), 0.02 * rows.float() - 0.2)  # the stored trainer action
    assert torch.equal(next_obs_t[:, :OBS], rows[:, None].float().expand(-1, OBS) + 0.5)  # o_T' = (s', a'_S)
    assert (next_obs_t[:, OBS:].abs() <= 1).all()  # a'_S: the student's fresh action, inside the box
    assert torch.equal(terminated, (rows % 7 == 6).float())  # the student's episode ends
    d = disc.prob(obs_t)
    assert torch.allclose(r_t, torch.exp(-((2 * d - 1) - a_t.squeeze(-1)).abs()))


def test_the_trainer_discounts_by_its_own_gamma_at_a_fixed_temperature():
    args = rile.Args()
    trainer = rile.make_trainer(OBS, ACT, args, "cpu")
    assert (trainer.gamma, args.gamma) == (0.9, 0.99) and trainer.alpha_optimizer is None
    next_obs, rewards, terminated = torch.randn(5, OBS + ACT), torch.rand(5), torch.tensor([0.0, 0, 1, 0, 1])
    torch.manual_seed(0)
    a_next, log_pi = trainer.policy(next_obs)
    soft_q = trainer.qf_target(next_obs, a_next).min(0).values - 0.2 * log_pi
    torch.manual_seed(0)
    target = trainer.td_target(next_obs, rewards, terminated)
    assert torch.allclose(target, rewards + 0.9 * (1 - terminated) * soft_q)


# ---------------------------------------------------------------- freezing and expert data


def params(module):
    return [p.detach().clone() for p in module.parameters()]


def changed(before, module):
    return any(not torch.equal(b, p) for b, p in zip(before, module.parameters()))


def test_freezing_stops_trainer_updates_and_only_those():
    args = tiny_args()
    student, trainer, disc, rb, expert, state = learners(args)
    rile.rile_update(student, trainer, disc, rb, expert, args, state, 1)
    assert state["trainer_updates"] == 1
    state["frozen_at"] = 1
    before = {name: params(m) for name, m in (("student", student.actor), ("student_qf", student.qf),
                                              ("trainer", trainer.actor), ("trainer_qf", trainer.qf), ("disc", disc))}
    out = rile.rile_update(student, trainer, disc, rb, expert, args, state, 1)
    assert not changed(before["trainer"], trainer.actor) and not changed(before["trainer_qf"], trainer.qf)
    assert state["trainer_updates"] == 1 and not any(key.startswith("losses/trainer_") for key in out)
    assert changed(before["student"], student.actor) and changed(before["student_qf"], student.qf)
    assert changed(before["disc"], disc)
    state["reward_only"] = True  # covariate shift: only the student learns
    before_disc = params(disc)
    rile.rile_update(student, trainer, disc, rb, expert, args, state, 1)
    assert not changed(before_disc, disc)


def freeze_step(critic_loss: float, target_var: float, total: int = 1000, reward_var: float = 1.0, state=None, **kw):
    """The step at which freeze_test freezes a trainer whose critic loss and target and reward variances stay constant
    (and whose TD targets have no variance of their own unless `state` gives one)."""
    args = tiny_args(total_timesteps=total, **({"trainer_freeze_min_updates": 0, "trainer_freeze_window": 200} | kw))
    state = rile.rile_state("cpu") | {"target_noise_ema": torch.tensor(0.0)} | (state or {})
    for step in range(1, total + 1):
        rile.freeze_test(torch.tensor(critic_loss), torch.tensor(target_var), torch.tensor(reward_var), args, state, step)
        if state["frozen_at"] is not None:
            return state["frozen_at"]


def test_freeze_waits_for_three_quarters_of_the_run_and_a_held_window():
    # relative statistic 0.01 / (2 x 1) = 0.005 < 0.1 from the first check at step 100
    assert freeze_step(0.01, 1.0) == 800  # the first check (every 100) after 3/4 of the 1000 steps (--trainer-freeze-after)
    assert freeze_step(0.01, 1.0, trainer_freeze_after=0, trainer_freeze_window=300) == 400  # below since 100
    assert freeze_step(0.01, 1.0, trainer_freeze_min_updates=900) == 900


def test_a_flat_target_does_not_pass_for_convergence():
    # a critic loss of 0.01 on targets and a reward that barely vary: under the raw threshold, not under the relative ones
    assert freeze_step(0.01, 0.001, reward_var=0.001) is None
    assert freeze_step(0.01, 0.001, reward_var=0.001, trainer_freeze_stat="relative") is None
    assert freeze_step(0.01, 0.001, trainer_freeze_stat="loss") == 800
    # the earlier rule: the raw loss, the first crossing after --trainer-freeze-min-updates, at any point of the run
    assert freeze_step(0.01, 0.001, trainer_freeze_stat="loss", trainer_freeze_window=0, trainer_freeze_after=0,
                       trainer_freeze_min_updates=150) == 200


def test_a_critic_whose_error_exceeds_the_reward_s_variation_has_not_converged():
    # Hopper-v4's trainer at 124k: TD loss 0.077 (two critics), targets' variance 1.65, r_T's 0.023
    assert freeze_step(0.077, 1.65, reward_var=0.023, trainer_freeze_stat="relative") == 800  # 0.023: frozen at the guard
    assert freeze_step(0.077, 1.65, reward_var=0.023) is None  # the default, relative to r_T's variance: 1.67, learning
    assert freeze_step(0.001, 1.65, reward_var=0.023) == 800  # 0.022: resolved


def test_freeze_statistic_is_a_moving_average_of_its_parts():
    state, args = rile.rile_state("cpu"), tiny_args(total_timesteps=10)
    rile.freeze_test(torch.tensor(4.0), torch.tensor(1.0), torch.tensor(8.0), args, state, 1)  # the first sets the averages
    rile.freeze_test(torch.tensor(5.0), torch.tensor(2.0), torch.tensor(9.0), args, state, 2)
    assert state["critic_loss_ema"].item() == pytest.approx(4.01) and state["target_var_ema"].item() == pytest.approx(1.01)
    assert rile.freeze_statistic(state, "relative") == pytest.approx(4.01 / 2.02)
    assert rile.freeze_statistic(state, "reward") == pytest.approx(4.01 / (2 * 8.01))
    assert rile.freeze_statistic(state, "loss") == pytest.approx(4.01) and state["trainer_updates"] == 2
    assert rile.freeze_statistic(state, "excess") == float("inf")  # no estimate of the targets' variance yet
    state["target_noise_ema"] = torch.tensor(1.5)
    assert rile.freeze_statistic(state, "excess") == pytest.approx((4.01 - 2 * 1.5) / (2 * 8.01))


def test_a_converged_critic_at_its_targets_noise_floor_passes_only_the_excess_test():
    # Walker2d-v4's trainer at 200k (discount 0.9): TD loss 2 x 0.00475, of it 2 x 0.00384 the targets' own variance,
    # r_T's variance 0.0218: 0.218 relative to r_T's variance, 0.04 beyond the floor
    noise = {"target_noise_ema": torch.tensor(0.00384)}
    assert freeze_step(0.0095, 0.03, reward_var=0.0218, state=noise, trainer_freeze_stat="reward") is None  # 0.218: never
    assert freeze_step(0.0095, 0.03, reward_var=0.0218, state=noise) == 800  # the default, excess: 0.042


def test_a_frozen_trainer_is_watched_without_changing_the_run_and_released_once_its_critic_no_longer_fits():
    out, rng, student_after = {}, {}, {}
    for threshold in (float("inf"), 1e9):  # not watched; watched every 10 steps and never released
        args = tiny_args(trainer_release_threshold=threshold)
        student, trainer, disc, rb, expert, state = learners(args)
        state["frozen_at"] = 5
        before = params(trainer.actor), params(trainer.qf)
        torch.manual_seed(1)
        out[threshold] = rile.rile_update(student, trainer, disc, rb, expert, args, state, 100)
        rng[threshold], student_after[threshold] = torch.get_rng_state(), params(student.actor)
        assert not changed(before[0], trainer.actor) and not changed(before[1], trainer.qf) and state["frozen_at"] == 5
    assert torch.equal(rng[float("inf")], rng[1e9])
    assert all(torch.equal(a, b) for a, b in zip(student_after[float("inf")], student_after[1e9]))
    assert "losses/trainer_qf_loss" in out[1e9] and "losses/trainer_qf_loss" not in out[float("inf")]
    # by hand: excess statistic (loss - 2 x noise) / (2 x r_T's variance) = (0.5 - 0.1) / 0.4 = 1.0, not above 1: frozen
    args = tiny_args(total_timesteps=2000)
    state = rile.rile_state("cpu") | {"frozen_at": 800, "trainer_updates": 900, "critic_loss_ema": torch.tensor(0.5),
                                      "target_var_ema": torch.tensor(1.0), "reward_var_ema": torch.tensor(0.2),
                                      "target_noise_ema": torch.tensor(0.05)}
    rile.freeze_test(torch.tensor(0.5), torch.tensor(1.0), torch.tensor(0.2), args, state, 1000)
    assert state["frozen_at"] == 800 and state["released_at"] == []
    # a loss of 0.6 moves the average to 0.501: (0.501 - 0.1) / 0.4 = 1.0025, released; no update counted while frozen
    rile.freeze_test(torch.tensor(0.6), torch.tensor(1.0), torch.tensor(0.2), args, state, 1100)
    assert state["frozen_at"] is None and state["released_at"] == [1100] and state["trainer_updates"] == 900


def test_the_targets_noise_estimate_by_hand_and_the_random_stream_it_leaves_alone():
    args = tiny_args(termination_remedy="none", trainer_buffer_size=20)
    after = {}
    for step in (10, 11):  # every 10th step estimates the noise; the other steps of the run draw the same numbers
        student, trainer, disc, rb, expert, state = learners(args)
        torch.manual_seed(1)
        rile.rile_update(student, trainer, disc, rb, expert, args, state, step)
        after[step] = (torch.get_rng_state(), state["target_noise_ema"].item())
    assert torch.equal(after[10][0], after[11][0]) and after[11][1] == float("inf")
    # by hand: two draws of the TD target, a'_S and a'_T fresh, on the trainer batch the update used
    student, trainer, disc, rb, expert, state = learners(args)
    seen, original = {}, trainer.update

    def update(*batch, prefix):  # the trainer's batch, and the random stream where the two draws start
        metrics = original(*batch, prefix=prefix)
        seen.update(batch=batch, rng=torch.get_rng_state())
        return metrics
    trainer.update = update
    torch.manual_seed(1)
    rile.rile_update(student, trainer, disc, rb, expert, args, state, 10)
    _, _, next_obs_t, r_t, terminated = seen["batch"]
    s_next = next_obs_t[:, :OBS]
    torch.set_rng_state(seen["rng"])
    y1, y2 = (trainer.td_target(torch.cat([s_next, student.policy(s_next)[0]], -1), r_t, terminated) for _ in range(2))
    assert not torch.equal(y1, y2) and after[10][1] == pytest.approx(0.5 * (y1 - y2).pow(2).mean().item())


def test_discriminator_updates_every_n_steps():
    args = tiny_args(disc_update_every=2)
    student, trainer, disc, rb, expert, state = learners(args)
    before = params(disc)
    out = rile.rile_update(student, trainer, disc, rb, expert, args, state, 1)
    assert not changed(before, disc) and "disc/policy_prob" not in out
    out = rile.rile_update(student, trainer, disc, rb, expert, args, state, 2)
    assert changed(before, disc) and "disc/policy_prob" in out


@pytest.mark.parametrize("fraction", [0.0, 0.25, 0.5, 1.0])
def test_expert_fractions_put_that_share_of_expert_pairs_in_the_batches(monkeypatch, fraction):
    args = tiny_args(student_expert_fraction=fraction, trainer_expert_fraction=fraction)
    student, trainer, disc, rb, expert, state = learners(args)
    seen = {}
    monkeypatch.setattr(student, "update", recorder(seen, "student"))
    monkeypatch.setattr(trainer, "update", recorder(seen, "trainer"))
    rile.rile_update(student, trainer, disc, rb, expert, args, state, 1)
    is_expert = seen["student"][0][:, 0] >= 100
    assert is_expert.sum().item() == round(fraction * args.batch_size) and is_expert[: int(is_expert.sum())].all()
    trainer_obs = seen["trainer"][0]
    n = round(fraction * args.trainer_batch_size)
    assert (trainer_obs[:n, 0] >= 100).all() and (trainer_obs[n:, 0] < 100).all()
    assert torch.allclose(trainer_obs[:n, OBS:], torch.full((n, ACT), 0.5))  # expert actions in o_T


def test_the_trainer_sees_a_tenth_of_expert_pairs_unless_it_cannot():
    """The default share of expert pairs in the trainer's batches (header, choice 8): 0.1, and 0 with --state-only, where
    the trainer's o_T = (s, a_S) has no expert action to take; a share given on the command line stays as it is."""
    assert rile.check_rile_args(rile.Args()).trainer_expert_fraction == 0.1
    assert rile.check_rile_args(rile.Args(state_only=True)).trainer_expert_fraction == 0.0
    assert rile.check_rile_args(rile.Args(trainer_expert_fraction=0.0)).trainer_expert_fraction == 0.0
    with pytest.raises(SystemExit, match="--trainer-expert-fraction needs the expert's actions"):
        rile.check_rile_args(rile.Args(state_only=True, trainer_expert_fraction=0.1))


def test_demonstration_noise_is_one_noisy_demonstrator_per_run():
    """--expert-action-noise and --expert-state-noise: drawn once per run from --seed (the same seed gives the same noisy
    demonstrations, another seed others), zero-mean with the given std, noisy actions clipped to the action box, states
    noised on observations and next observations (independently); nothing else changes."""
    n, low, high = 20_000, -np.ones(ACT), np.ones(ACT)
    demos = {"observations": np.zeros((n, OBS), np.float32), "next_observations": np.ones((n, OBS), np.float32),
             "actions": np.zeros((n, ACT), np.float32), "terminations": np.arange(n) % 100 == 99}
    tensors = lambda seed, **noise: rile.expert_tensors(demos, seed, "cpu", action_low=low, action_high=high, **noise)
    clean, acted, stated = tensors(1), tensors(1, action_noise=0.3), tensors(1, state_noise=0.5)
    for noisy, again in ((acted, tensors(1, action_noise=0.3)), (stated, tensors(1, state_noise=0.5))):
        assert all(torch.equal(noisy[k], again[k]) for k in noisy)  # fixed by the seed
    assert not torch.equal(acted["actions"], tensors(2, action_noise=0.3)["actions"])
    assert not torch.equal(stated["obs"], tensors(2, state_noise=0.5)["obs"])
    for diff, std in ((acted["actions"] - clean["actions"], 0.3), (stated["obs"] - clean["obs"], 0.5),
                      (stated["next_obs"] - clean["next_obs"], 0.5)):
        assert abs(diff.mean().item()) < 0.01 and diff.std().item() == pytest.approx(std, rel=0.02)
    assert not torch.equal(stated["obs"] - clean["obs"], stated["next_obs"] - clean["next_obs"])
    for same in ("obs", "next_obs", "terminations"):
        assert torch.equal(acted[same], clean[same])
    assert torch.equal(stated["actions"], clean["actions"]) and torch.equal(stated["terminations"], clean["terminations"])
    heavy = rile.expert_tensors(demos | {"actions": np.full((n, ACT), 0.9, np.float32)}, 1, "cpu", action_noise=1.25,
                                action_low=low, action_high=high)["actions"]
    assert heavy.abs().max() <= 1.0  # clipped to the box: P(0.9 + e > 1) = 0.47, P(0.9 + e < -1) = 0.06
    assert (heavy == 1.0).float().mean().item() == pytest.approx(0.47, abs=0.02)
    assert (heavy == -1.0).float().mean().item() == pytest.approx(0.064, abs=0.01)
    unclipped = rile.expert_tensors(demos | {"actions": np.full((n, ACT), 0.9, np.float32)}, 1, "cpu", action_noise=1.25,
                                    action_low=-np.inf, action_high=np.inf)["actions"]  # --no-expert-noise-clip
    assert (unclipped.clamp(-1, 1) == heavy).all() and (unclipped > 1).float().mean().item() == pytest.approx(0.47, abs=0.02)


def test_every_consumer_sees_the_noisy_pairs(monkeypatch):
    """The noisy tensors are the ones used: each script's main makes them once and passes them on (and nothing else of
    the demonstrations but their returns); D's expert batches in rile.py, gail.py and airl.py and the trainer's expert
    share in rile.py are rows of them."""
    for script in ("rile.py", "gail.py", "airl.py"):
        main = (ROOT / script).read_text().split('if __name__ == "__main__":')[1]
        made = "expert = expert_tensors(demos, args.seed, device, args.expert_state_noise, args.expert_action_noise, *"
        assert made in main, script
        rest = [line.strip() for line in main.split(made)[1].splitlines()[1:] if re.search(r'(?<!")\bdemos\b', line)]
        assert all(line.startswith("run = Run(args, checkpoint, stateful, demos,") for line in rest), (script, rest)
    demos = {"observations": 100 + np.arange(40.0)[:, None].repeat(OBS, 1), "actions": np.full((40, ACT), 0.5),
             "next_observations": np.full((40, OBS), 200.0), "terminations": np.zeros(40)}
    noisy = rile.expert_tensors(demos, 1, "cpu", 0.1, 0.2, -np.ones(ACT), np.ones(ACT))
    pairs = torch.cat([noisy["obs"], noisy["actions"]], -1)
    is_noisy_pair = lambda x: (x[:, None, :] == pairs[None]).all(-1).any(1).all().item()

    def record(disc, seen):
        update = disc.update
        monkeypatch.setattr(disc, "update", lambda expert_x, *rest: seen.append(expert_x) or update(expert_x, *rest))

    args = tiny_args(trainer_expert_fraction=0.5)
    student, trainer, disc, rb, _, state = learners(args)
    seen, disc_seen = {}, []
    monkeypatch.setattr(trainer, "update", recorder(seen, "trainer"))
    record(disc, disc_seen)
    rile.rile_update(student, trainer, disc, rb, noisy, args, state, 1)
    assert is_noisy_pair(disc_seen[0]) and is_noisy_pair(seen["trainer"][0][: args.trainer_batch_size // 2])

    args = gail.Args(hidden_dim=16, batch_size=8, disc_batch_size=4, disc_hidden_dim=8)
    agent, disc = gail.SAC(OBS, ACT, -np.ones(ACT), np.ones(ACT), args, "cpu"), gail.Discriminator(OBS + ACT, 8, 1e-3, 1)
    monkeypatch.setattr(agent, "update", lambda *batch, prefix: {})
    record(disc, disc_seen)
    gail.gail_update(agent, disc, rb, noisy, args)
    assert is_noisy_pair(disc_seen[1])

    args = airl.Args(hidden_dim=16, batch_size=8, disc_batch_size=4, disc_hidden_dim=8)
    agent = airl.SAC(OBS, ACT, -np.ones(ACT), np.ones(ACT), args, "cpu")
    disc = airl.AIRLDiscriminator(OBS, ACT, 8, args.gamma, False, args.disc_lr, args.disc_gp)
    monkeypatch.setattr(agent, "update", lambda *batch, prefix: {})
    record(disc, disc_seen)
    airl.airl_update(agent, disc, rb, noisy, args)
    assert is_noisy_pair(torch.cat(disc_seen[2][:2], -1))


# ---------------------------------------------------------------- reward dynamics


def test_rfdc_fs_rfdc_and_cpr_against_scipy():
    from scipy import stats
    rng = np.random.default_rng(0)
    x, y = rng.normal(size=100), rng.normal(1.0, 2.0, size=100)
    assert reward_dynamics.wasserstein_1d(x, y) == pytest.approx(stats.wasserstein_distance(x, y))
    assert reward_dynamics.pearson(x, 3 * x + y) == pytest.approx(stats.pearsonr(x, 3 * x + y)[0])
    dyn = reward_dynamics.RewardDynamics()
    first = dyn.step(10, x, 2 * x + 1, np.array([0.0, 1.0]))
    assert first["rfdc"] is None and first["fs_rfdc"] is None and first["cpr"] == pytest.approx(1.0)
    second = dyn.step(20, y, -y, np.array([0.5, -1.0]))
    assert second["rfdc"] == pytest.approx(stats.wasserstein_distance(y, x))
    assert second["fs_rfdc"] == pytest.approx((0.5 + 2.0) / 2) and second["cpr"] == pytest.approx(-1.0)
    assert dyn.step(30, np.ones(100), np.ones(100), np.zeros(2))["cpr"] is None  # constant rewards


# ---------------------------------------------------------------- discriminator and saved reward


def test_discriminator_loss_and_gradient_penalty_by_hand():
    disc = rile.Discriminator(2, 8, lr=1e-3, gp_weight=1.0)
    disc.net = nn.Linear(2, 1)
    with torch.no_grad():
        disc.net.weight.copy_(torch.tensor([[3.0, 4.0]]))
        disc.net.bias.zero_()
    loss, bce, gp, expert_prob, policy_prob = disc.loss(torch.tensor([[1.0, 0.0]]), torch.tensor([[0.0, 1.0]]))
    # logits 3 (expert) and 4 (policy): BCE = softplus(-3) + softplus(4); |grad| = |(3, 4)| = 5: GP = (5 - 1)^2
    want_bce = np.log1p(np.exp(-3.0)) + np.log1p(np.exp(4.0))
    assert bce.item() == pytest.approx(want_bce, rel=1e-6) and gp.item() == pytest.approx(16.0)
    assert loss.item() == pytest.approx(want_bce + 16.0, rel=1e-6)
    assert expert_prob.item() == pytest.approx(1 / (1 + np.exp(-3.0)))
    assert policy_prob.item() == pytest.approx(1 / (1 + np.exp(-4.0)))


def test_zero_centred_gradient_penalty_by_hand():
    disc = rile.Discriminator(2, 8, lr=1e-3, gp_weight=10.0, gp_center=0.0)
    disc.net = nn.Linear(2, 1)
    with torch.no_grad():
        disc.net.weight.copy_(torch.tensor([[3.0, 4.0]]))
        disc.net.bias.zero_()
    loss, bce, gp, _, _ = disc.loss(torch.tensor([[1.0, 0.0]]), torch.tensor([[0.0, 1.0]]))
    assert gp.item() == pytest.approx(25.0) and loss.item() == pytest.approx(bce.item() + 250.0, rel=1e-6)  # |(3, 4)|^2


def test_standardised_inputs_and_their_statistics():
    x = torch.tensor([[1.0, 5.0, 0.0], [3.0, 5.0, 0.0], [5.0, 5.0, 0.0]])  # column 1 and 2 constant in the demonstrations
    shift, scale = rile.input_stats(x)
    assert shift.tolist() == [3.0, 0.0, 0.0] and scale.tolist() == [2.0, 1.0, 1.0]
    disc = rile.Discriminator(3, 8, lr=1e-3, gp_weight=1.0, gp_center=0.0, stats=(shift, scale))
    disc.net = nn.Linear(3, 1)
    with torch.no_grad():
        disc.net.weight.copy_(torch.tensor([[1.0, 2.0, 4.0]]))
        disc.net.bias.zero_()
    assert disc(torch.tensor([[7.0, 1.0, 1.0]])).item() == pytest.approx(2.0 + 2.0 + 4.0)  # (7 - 3) / 2 = 2
    # the penalty acts on the standardised input: |grad_z| = |(1, 2, 4)|, zero-centred: 21
    _, _, gp, _, _ = disc.loss(torch.tensor([[1.0, 0.0, 0.0]]), torch.tensor([[0.0, 1.0, 0.0]]))
    assert gp.item() == pytest.approx(21.0)
    assert {"shift", "scale"} <= set(disc.state_dict())  # saved with the reward
    old = {k: v for k, v in disc.state_dict().items() if k not in ("shift", "scale")}  # a file from before
    disc.load_state_dict(old)
    assert disc.shift.tolist() == [0.0] * 3 and disc.scale.tolist() == [1.0] * 3


def test_pooled_statistics_follow_both_sources():
    """--disc-normalize pooled: shift and scale are the running mean and std of each update's expert and agent
    inputs together, a plain average over the first 1,000 updates, then a moving average with rate 0.001."""
    disc = rile.Discriminator(2, 8, lr=1e-3, gp_weight=0.0, pooled=True)
    disc.update_stats(torch.tensor([[0.0, 5.0], [2.0, 5.0]]))  # rate 1: this batch's mean (1, 5) and variance (2, 0)
    assert disc.shift.tolist() == [1.0, 5.0] and disc.scale.tolist() == pytest.approx([2 ** 0.5, 1.0])  # constant: 1
    disc.update_stats(torch.tensor([[3.0, 5.0], [3.0, 7.0]]))  # rate 1/2: mean (3, 6), variance (0, 2)
    assert disc.shift.tolist() == [2.0, 5.5] and disc.var.tolist() == [1.0, 1.0] and disc.scale.tolist() == [1.0, 1.0]
    disc.updates.fill_(5_000)
    disc.update_stats(torch.tensor([[2.0, 5.5], [4.0, 5.5]]))  # rate 0.001: mean (3, 5.5), variance (2, 0)
    assert disc.shift.tolist() == pytest.approx([2.001, 5.5]) and disc.var.tolist() == pytest.approx([1.001, 0.999])
    expert, agent = torch.tensor([[1.0, 1.0]]), torch.tensor([[3.0, 3.0]])
    before = disc.shift.clone()
    disc.update(expert, agent)  # update() refreshes the statistics first
    assert not torch.equal(disc.shift, before)
    fixed = rile.Discriminator(2, 8, lr=1e-3, gp_weight=0.0)
    fixed.update(expert, agent)
    assert fixed.shift.tolist() == [0.0, 0.0] and fixed.scale.tolist() == [1.0, 1.0]  # none by default


def test_discriminator_learns_to_separate():
    torch.manual_seed(0)
    disc = rile.Discriminator(2, 16, lr=1e-2, gp_weight=1.0)
    expert_x, policy_x = torch.randn(64, 2) + 2, torch.randn(64, 2) - 2
    for _ in range(200):
        disc.update(expert_x, policy_x)
    assert disc.prob(expert_x).mean() > 0.9 and disc.prob(policy_x).mean() < 0.1


def test_reward_measures_by_hand(monkeypatch):
    """learners()' rows encode their index i in obs: with D = sigmoid(i - 10) and r_S = +-(2D - 1) exactly, the
    last 10 rows (i = 10..19) give D and r_S means by hand, and r_S follows v(D) with correlation +1 or -1."""
    args = tiny_args(dynamics_freq=10)
    student, trainer, disc, rb, expert, state = learners(args)
    prob = lambda x: torch.sigmoid(x[:, 0] - 10)  # D and the trainer both see (s, a): column 0 is i
    monkeypatch.setattr(disc, "prob", prob)
    for sign in (1.0, -1.0):
        monkeypatch.setattr(rile, "student_reward", lambda actor, o_t, remedy: sign * (2 * prob(o_t) - 1))
        memory = {"interval": None, "demos": None, "history": []}
        out = rile.rile_measures(trainer, disc, rb, expert, args, state, memory, 20)
        i = np.arange(10)
        assert out["d_student"] == pytest.approx(np.mean(1 / (1 + np.exp(-i))), rel=1e-5)
        assert out["r_s_student"] == pytest.approx(sign * np.mean(np.tanh(i / 2)), rel=1e-5)  # 2 sigmoid(x) - 1 = tanh(x / 2)
        assert out["r_s_follows_d"] == pytest.approx(sign, abs=1e-6)
        assert out["r_s_demos"] == pytest.approx(sign, abs=1e-6) and out["cpr"] is None  # D = 1 on demos; env reward flat


def test_saved_reward_round_trip(tmp_path):
    args = tiny_args()
    student, trainer, disc, rb, expert, state = learners(args)
    torch.save(rile.reward_file(trainer, disc, args, OBS, ACT), tmp_path / "reward.pt")
    _, trainer2, disc2, *_ = learners(tiny_args(seed=5))
    with torch.no_grad():
        for p in list(trainer2.actor.parameters()) + list(disc2.parameters()):
            p.add_(1.0)
    rile.load_reward(str(tmp_path / "reward.pt"), trainer2, disc2, args, OBS, ACT)
    x = torch.randn(7, OBS + ACT)
    assert torch.equal(trainer2.actor.deterministic(x), trainer.actor.deterministic(x)) and torch.equal(disc2(x), disc(x))
    with pytest.raises(SystemExit, match="learned on Hopper-v4, not Walker2d-v4"):
        rile.load_reward(str(tmp_path / "reward.pt"), trainer2, disc2, tiny_args(env_id="Walker2d-v4"), OBS, ACT)
    with pytest.raises(SystemExit, match="learned with --state-only False"):
        rile.load_reward(str(tmp_path / "reward.pt"), trainer2, disc2, tiny_args(state_only=True), OBS, ACT)


# ---------------------------------------------------------------- end to end


TINY = ["--env-id", "InvertedPendulum-v4", "--learning-starts", "200", "--eval-freq", "300", "--eval-episodes", "2",
        "--hidden-dim", "32", "--trainer-hidden-dim", "32", "--batch-size", "32", "--trainer-batch-size", "32",
        "--disc-batch-size", "16", "--dynamics-freq", "200", "--num-expert-trajs", "2",
        "--expert-path", str(ROOT / "experts/InvertedPendulum-v4.npz")]


def test_end_to_end_every_update_path_then_covariate_shift(run, tmp_path):
    out = run("rile.py", *TINY, "--total-timesteps", "600", "--run-name", "r", "--trainer-freeze-min-updates", "200",
              "--trainer-freeze-threshold", "1e9", "--trainer-freeze-window", "0", "--trainer-freeze-after", "0",
              "--trainer-freeze-stat", "loss", "--student-expert-fraction", "0.25", "--trainer-expert-fraction", "0.25",
              "--expert-action-noise", "0.1").stdout
    assert "trainer frozen at step 400" in out  # 200 trainer updates after learning starts at 200
    assert out.startswith("runs/r at step 0 of 600 | InvertedPendulum-v4 | 2 demonstration episodes, return 1000.0 | cpu")
    results = json.loads((tmp_path / "runs/r/results.json").read_text())
    assert results["finished"] and results["expert_return"] == pytest.approx(1000.0)
    assert [e["step"] for e in results["evals"]] == [300, 600]
    dynamics = json.loads((tmp_path / "runs/r/dynamics.json").read_text())
    assert [d["step"] for d in dynamics] == [400, 600] and dynamics[1]["rfdc"] is not None
    assert results["trainer_frozen_at"] == 400 and results["reward_measures"] == dynamics
    measured = dynamics[1]
    for key in ("r_s_demos", "r_s_student", "r_s_absorbing", "d_demos", "d_student", "critic_loss", "critic_loss_relative",
                "critic_loss_to_reward", "critic_excess_to_reward", "r_s_follows_d"):
        assert np.isfinite(measured[key]), key
    assert measured["r_s_spread"] == pytest.approx(measured["r_s_demos"] - measured["r_s_student"])
    assert 0 < measured["d_demos"] < 1 and measured["trainer_frozen_at"] == 400
    ckpt = torch.load(tmp_path / "runs/r/checkpoint.pt", weights_only=False)
    assert ckpt["rile"]["trainer_updates"] > 0 and ckpt["disc_optimizer"]["state"] and ckpt["trainer"]["q_optimizer"]["state"]
    out = run("rile.py", *TINY, "--total-timesteps", "400", "--run-name", "cs", "--reward-from", "runs/r/reward.pt",
              "--student-action-noise", "0.2").stdout
    assert "done: 400 steps" in out
    shifted = torch.load(tmp_path / "runs/cs/checkpoint.pt", weights_only=False)
    assert shifted["rile"]["trainer_updates"] == 0 and not shifted["disc_optimizer"]["state"]


def test_the_control_end_to_end_without_a_trainer_then_covariate_shift(run, tmp_path):
    out = run("rile.py", *TINY, "--total-timesteps", "400", "--run-name", "ctl", "--student-reward", "discriminator").stdout
    assert "done: 400 steps" in out
    ckpt = torch.load(tmp_path / "runs/ctl/checkpoint.pt", weights_only=False)
    assert "trainer" not in ckpt and ckpt["rile"]["trainer_updates"] == 0 and ckpt["disc_optimizer"]["state"]
    # buffer rows: obs and next obs with the absorbing indicator (4 + 1 each), the action, reward, termination; no a_T
    assert ckpt["replay_buffer"]["storage"].shape[1] == 2 * 5 + 1 + 2
    saved = torch.load(tmp_path / "runs/ctl/reward.pt", weights_only=True)
    assert saved["trainer_actor"] is None and saved["student_reward"] == "discriminator"
    results = json.loads((tmp_path / "runs/ctl/results.json").read_text())
    measured = results["reward_measures"][-1]  # the same measures, of v(D)
    assert measured["r_s_follows_d"] == pytest.approx(1.0, abs=1e-5) and results["trainer_frozen_at"] is None
    assert measured["r_s_demos"] == pytest.approx(2 * measured["d_demos"] - 1, abs=1e-5)
    assert measured["critic_loss"] is None and np.isfinite(measured["r_s_absorbing"])
    out = run("benchmarks/rile_rewards.py", "runs/ctl").stdout  # what v(D) pays, the absorbing state included
    r_abs, d_abs = (float(out.split(f"{name} at the absorbing state:")[1].split(";")[0]) for name in ("r_S", "D"))
    assert "no trainer (the control" in out and r_abs == pytest.approx(2 * d_abs - 1, abs=2e-3)
    proc = run("benchmarks/rile_follows_d.py", "runs/ctl", check=False)
    assert proc.returncode != 0 and "run of the control" in proc.stderr and "Traceback" not in proc.stderr
    out = run("rile.py", *TINY, "--total-timesteps", "300", "--run-name", "ctl-cs", "--reward-from", "runs/ctl/reward.pt",
              "--student-reward", "discriminator").stdout  # covariate shift: a fresh student against the control's D
    assert "done: 300 steps" in out
    assert not torch.load(tmp_path / "runs/ctl-cs/checkpoint.pt", weights_only=False)["disc_optimizer"]["state"]
    proc = run("rile.py", *TINY, "--total-timesteps", "300", "--reward-from", "runs/ctl/reward.pt", check=False)
    assert proc.returncode != 0 and "learned with --student-reward discriminator" in proc.stderr


def test_demonstrations_of_another_env_are_refused(run):
    proc = run("rile.py", "--env-id", "Hopper-v4", "--expert-path", str(ROOT / "experts/InvertedPendulum-v4.npz"),
               "--total-timesteps", "10", check=False)
    assert proc.returncode != 0 and "recorded on InvertedPendulum-v4, not Hopper-v4" in proc.stderr
    assert "Traceback" not in proc.stderr


def test_resume_continues_the_run(run, tmp_path):
    # survival: one buffer row per step
    run("rile.py", *TINY, "--total-timesteps", "300", "--run-name", "res", "--termination-remedy", "survival")
    out = run("rile.py", *TINY, "--resume", "runs/res", "--total-timesteps", "600").stdout
    assert "resumed runs/res at step 300" in out
    results = json.loads((tmp_path / "runs/res/results.json").read_text())
    assert results["finished"] and [e["step"] for e in results["evals"]] == [300, 600]
    ckpt = torch.load(tmp_path / "runs/res/checkpoint.pt", weights_only=False)
    assert ckpt["step"] == 600 and ckpt["replay_buffer"]["size"] == 600 and ckpt["rile"]["trainer_updates"] == 400


def test_a_resume_that_extends_the_run_keeps_its_freeze(run, tmp_path):
    """Frozen at 300 of 400 steps (3/4 of the run); extended to 800, whose 3/4 is 600, the trainer stays frozen at 300
    (the freeze is in the checkpoint), and the test does not freeze it anew."""
    freeze = ["--trainer-freeze-min-updates", "50", "--trainer-freeze-threshold", "1e9", "--trainer-freeze-window", "0",
              "--trainer-release-threshold", "inf", "--termination-remedy", "survival"]
    out = run("rile.py", *TINY, *freeze, "--total-timesteps", "400", "--run-name", "fr").stdout
    assert "trainer frozen at step 300" in out
    out = run("rile.py", *TINY, "--resume", "runs/fr", "--total-timesteps", "800").stdout
    assert "resumed runs/fr at step 400" in out and "trainer frozen" not in out
    results = json.loads((tmp_path / "runs/fr/results.json").read_text())
    assert results["finished"] and results["trainer_frozen_at"] == 300 and results["config"]["total_timesteps"] == 800
    assert torch.load(tmp_path / "runs/fr/checkpoint.pt", weights_only=False)["rile"]["trainer_updates"] == 101


def test_a_run_says_what_it_runs_then_shows_progress(tmp_path, monkeypatch, capsys):
    """The start line (run directory, step, env, demonstrations, device, threads); on a terminal a progress line every
    10 s rewritten in place, kept at each evaluation; elsewhere one line per evaluation only."""
    monkeypatch.chdir(tmp_path)
    args = tiny_args(env_id="InvertedPendulum-v4", total_timesteps=100, eval_freq=50, eval_episodes=1, run_name="alive")
    demos = {"episode_returns": np.array([1000.0, 990.0]), "metadata": {"random_return": 5.0}}
    run = rile.Run(args, None, {}, demos, "cpu")
    out = capsys.readouterr().out
    assert out.startswith("runs/alive at step 0 of 100 | InvertedPendulum-v4 | 2 demonstration episodes, return 995.0 | "
                          "cpu, threads ") and run.expert_return == 995.0 and run.random_return == 5.0
    act = lambda obs, deterministic: np.zeros(1, dtype=np.float32)
    run.tty = True
    run.end_step(1, act)  # nothing shown yet: a progress line at once
    run.end_step(2, act)  # within 10 s of it: nothing
    progress = capsys.readouterr().out
    assert progress.startswith("\rstep 1/100 | ") and progress.endswith("SPS: measuring\033[K") and "\n" not in progress
    run.end_step(50, act)  # an evaluation: its line stays
    evaluation = capsys.readouterr().out
    assert evaluation.startswith("\rstep 50/100 | ") and "| eval at 50: return " in evaluation and evaluation.endswith("\n")
    run.tty, run.shown = False, 0.0  # not a terminal (a log): evaluations only
    run.end_step(51, act)
    assert capsys.readouterr().out == ""
    run.end_step(100, act)
    line = capsys.readouterr().out
    assert line.startswith("step 100/100 | ") and "eval at 100: return " in line and " normalized" in line
    run.writer.close()


def test_time_left_comes_from_recent_learning_steps_not_the_warm_up_nor_before_a_resume(tmp_path, monkeypatch, capsys):
    """A fake clock: 5,000 random-action steps at 1,000 a second, then learning at 40 a second with a 15 s evaluation
    every 10k steps, then 60 a second from 75k (as when RILe's trainer freezes). SPS and time left appear after a
    minute of learning, from learning steps only; the time left shown from then to mid-run is within 25 % of the time
    the run then took; the rate follows the last 10 minutes; a resumed run measures afresh."""
    monkeypatch.chdir(tmp_path)
    clock = [0.0]
    monkeypatch.setattr(rile.time, "perf_counter", lambda: clock[0])
    args = tiny_args(env_id="InvertedPendulum-v4", total_timesteps=100_000, eval_freq=10_000, eval_episodes=1,
                     learning_starts=5_000, run_name="eta")
    run, act = rile.Run(args, None, {}, None, "cpu", learning_starts=5_000), lambda obs, deterministic: np.zeros(1)
    run.tty, _ = True, capsys.readouterr()  # the start line

    def seconds(step):  # the step's duration, and an evaluation's after the step that makes one
        return (0.001 if step <= 5_000 else 1 / 40 if step <= 75_000 else 1 / 60) + 15 * (step % 10_000 == 0)

    finish, shown = sum(seconds(step) for step in range(1, 100_001)), {}
    for step in range(1, 100_001):
        clock[0] += seconds(step) - 15 * (step % 10_000 == 0)
        run.end_step(step, act)
        clock[0] += 15 * (step % 10_000 == 0)
        if out := capsys.readouterr().out:
            shown[step] = (clock[0], out)
    assert all("SPS: measuring" in out for t, out in shown.values() if t < 5 + 60)  # warm-up, first minute
    timed = {step: (t, out) for step, (t, out) in shown.items() if "min left" in out}
    sps_and_left = lambda out: [float(x) for x in out.split(" | ")[2].replace(" SPS,", "").split()[:2]]
    first = min(timed)
    assert 5_000 + 60 * 40 <= first <= 5_000 + 71 * 40 and sps_and_left(timed[first][1])[0] == 40  # no warm-up
    checked = [step for step in timed if step <= 50_000]
    for step in checked[:: len(checked) // 10]:
        t, out = timed[step]
        truth = finish - t
        assert abs(sps_and_left(out)[1] * 60 - truth) <= 0.25 * truth, (step, sps_and_left(out), truth)
    assert 48 <= sps_and_left(shown[100_000][1])[0] < 60  # the last 10 min (since learning began: 41 a second)
    run.writer.close()
    resumed = rile.Run(replace(args, run_name="eta2"), None, {}, None, "cpu", learning_starts=5_000)
    resumed.start_step, resumed.tty, _ = 40_000, True, capsys.readouterr()  # as a checkpoint sets it; measured anew
    resumed.end_step(40_001, act)
    assert "SPS: measuring" in capsys.readouterr().out and resumed.marks == [(40_001, clock[0])]
    resumed.writer.close()


def test_absorbing_states_end_to_end(run, tmp_path):
    """InvertedPendulum terminates often under random actions: every termination adds one absorbing row,
    nothing stays terminal, and a reward learned this way is refused for a student without them."""
    out = run("rile.py", *TINY, "--total-timesteps", "400", "--run-name", "abs", "--termination-remedy", "absorbing").stdout
    assert "done: 400 steps" in out
    buf = torch.load(tmp_path / "runs/abs/checkpoint.pt", weights_only=False)["replay_buffer"]
    rb = rile.ReplayBuffer(5, 1, len(buf["storage"]), "cpu", extra_dim=1)
    rb.load_state_dict(buf)
    obs, _, next_obs, _, terms, _ = rb.batch(torch.arange(rb.size))
    n_absorbing = int((obs[:, -1] == 1).sum())
    assert n_absorbing > 0 and rb.size == 400 + n_absorbing and not terms.any()
    assert int((next_obs[:, -1] == 1).sum()) == 2 * n_absorbing  # the termination and the self-loop
    proc = run("rile.py", *TINY, "--total-timesteps", "300", "--reward-from", "runs/abs/reward.pt",
               "--termination-remedy", "survival", check=False)
    assert proc.returncode != 0 and "learned with --termination-remedy absorbing" in proc.stderr
    # benchmarks/rile_rewards.py reads the checkpoint: r_S at the absorbing state is the trainer's action on (s_abs, 0)
    out = run("benchmarks/rile_rewards.py", "runs/abs").stdout
    assert "at step 400" in out and "r_S on the demonstrations" in out and "one deterministic episode" in out
    ckpt = torch.load(tmp_path / "runs/abs/checkpoint.pt", weights_only=False)
    trainer = rile.Actor(5 + 1, 1, np.array([-1.0]), np.array([1.0]), ckpt["config"]["trainer_hidden_dim"])
    trainer.load_state_dict(ckpt["trainer"]["actor"])
    r_abs = trainer.deterministic(torch.tensor([[0.0, 0.0, 0.0, 0.0, 1.0, 0.0]])).item()
    assert f"r_S at the absorbing state:               {r_abs:7.3f};" in out
    disc = rile.Discriminator(5 + 1, ckpt["config"]["disc_hidden_dim"], 1e-3, 0.0)
    disc.load_state_dict(ckpt["disc"])
    d_abs = disc.prob(torch.tensor([[0.0, 0.0, 0.0, 0.0, 1.0, 0.0]])).item()
    assert f"D at the absorbing state:                 {d_abs:7.3f};" in out and f"absorbing rows: {n_absorbing} of" in out
    # ... and the student's critic against what r_S pays: its Q at (s_abs, 0) is the smaller of the twin critics there,
    # and the episode's discounted r_S lies between its steps' smallest and largest r_S summed over the episode
    qf = rile.TwinQ(4 + 1, 1, ckpt["config"]["hidden_dim"])
    qf.load_state_dict(ckpt["student"]["qf"])
    q_abs = qf(torch.tensor([[0.0, 0.0, 0.0, 0.0, 1.0]]), torch.zeros(1, 1)).min(0).values.item()
    assert f"at the absorbing state {q_abs:.3f} against {r_abs * 100:.3f}" in out  # gamma 0.99: 1 / (1 - gamma) = 100
    episode = out.split("one deterministic episode: ")[1]
    steps, fell = int(episode.split(" steps")[0]), "fell" in episode.split("\n")[0]
    low, high = (float(episode.split(k)[1].split(",")[0].split(")")[0]) for k in ("(min ", "max "))
    paid = float(out.split("this episode's discounted r_S ")[1].split(";")[0])
    span, tail = (1 - 0.99**steps) / 0.01, 0.99**steps * r_abs * 100 * fell
    assert (low - 5e-4) * span + tail - 5e-4 <= paid <= (high + 5e-4) * span + tail + 5e-4, (low, high, steps, paid)
    # benchmarks/rile_follows_d.py: each of the run's 400 live pairs falls in one v(D) bin
    out = run("benchmarks/rile_follows_d.py", "runs/abs", "--recent", "100000").stdout
    live = ckpt["step"]  # one live row per env step; the absorbing loops are left out
    binned = [line.split("student")[1].split("pairs")[0] for line in out.splitlines() if line.startswith("v(D) in")]
    assert "student's pairs: r_S =" in out and len(binned) == 8 and sum(map(int, binned)) == live
    assert "(the freeze test's statistic), to r_T's variance" in out
    split = out.split("the targets' own variance ")[1]
    assert float(split.split(",")[0]) > 0 and float(split.split("beyond it ")[1].split(" ")[0]) >= 0
    # the value the critics bootstrap from, over the window: five ordered quantiles, then the eight lowest rows
    quantiles = [float(x) for x in out.split("1.0): ")[1].split(";")[0].split()]
    assert len(quantiles) == 5 and quantiles == sorted(quantiles)
    lowest = [float(x.split(": ")[1]) for x in out.split("lowest rows (buffer row: value): ")[1].strip().split(", ")]
    assert len(lowest) == 8 and lowest == sorted(lowest) and abs(lowest[0] - quantiles[0]) < 0.05
    # benchmarks/policy_modes.py replays the saved actor: its mean action on the evaluation's resets scores what the
    # run's last evaluation did
    out = run("benchmarks/policy_modes.py", "runs/abs/actor.pt", "--episodes", "2").stdout
    final = json.loads((tmp_path / "runs/abs/results.json").read_text())["evals"][-1]["mean"]
    assert abs(float(out.split("mean action: return")[1].split("+-")[0]) - final) < 0.06 and "sampled    : return" in out
    proc = run("benchmarks/policy_modes.py", "runs/abs/config.json", check=False)
    assert proc.returncode != 0 and "is not a readable actor.pt" in proc.stderr and "Traceback" not in proc.stderr
    run("rile.py", *TINY, "--total-timesteps", "210", "--run-name", "surv", "--termination-remedy", "survival")
    proc = run("benchmarks/rile_rewards.py", "runs/surv", check=False)  # not an absorbing-state run
    assert proc.returncode != 0 and "--termination-remedy survival" in proc.stderr
    proc = run("benchmarks/rile_follows_d.py", "runs/surv", check=False)
    assert proc.returncode != 0 and "not a run with --termination-remedy absorbing" in proc.stderr


def test_reward_measures_table(tmp_path, capsys):
    from benchmarks import reward_measures
    measure = {"step": 10, "r_s_demos": 0.5, "r_s_student": -0.25, "r_s_spread": 0.75, "r_s_absorbing": None,
               "d_demos": 0.7, "d_student": 0.3, "critic_loss_relative": 0.05, "critic_loss_to_reward": 2.0,
               "critic_excess_to_reward": 0.04, "fs_rfdc": None, "cpr": 0.1, "trainer_frozen_at": None}
    results = {"evals": [{"step": 10, "normalized": 0.123}], "reward_measures": [measure, measure | {"step": 20,
                                                                                                 "trainer_frozen_at": 15}]}
    rows = reward_measures.table(results).splitlines()
    assert rows[1].split("\t") == ["10", "0.12", "0.500", "-0.250", "0.750", "-", "0.700", "0.300", "-", "0.050", "2.000",
                                   "0.040", "-", "0.100", "learning"]
    assert rows[2].split("\t")[1] == "-" and rows[2].endswith("frozen at 15")
    (tmp_path / "old.json").write_text(json.dumps({"evals": []}))
    with pytest.raises(SystemExit, match="no reward_measures"):
        reward_measures.main([str(tmp_path / "old.json")])
