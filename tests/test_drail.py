"""drail_disc.py: the cosine schedule and forward noising by hand, antithetic timesteps, D as a
probability that learns, the DRAIL-RILe trainer reward equal to rile.py's, and runs of both variants."""

import json
import math

import numpy as np
import pytest
import torch

import drail_disc
import rile
from conftest import ROOT


def test_cosine_schedule_by_hand():
    T, s = 4, 0.008
    f = [math.cos(((t / T) + s) / (1 + s) * math.pi / 2) ** 2 for t in range(T + 1)]
    betas = [min(max(1 - f[t + 1] / f[t], 1e-4), 0.9999) for t in range(T)]
    want = np.cumprod([1 - b for b in betas])
    assert drail_disc.cosine_alpha_bar(T).tolist() == pytest.approx(want.tolist(), rel=1e-6)
    ab = drail_disc.cosine_alpha_bar(1000)
    assert ab[0].item() == pytest.approx(1 - max(1 - f1_over_f0(1000), 1e-4), rel=1e-6)  # beta_0 is clipped up to 1e-4
    assert (ab[1:] < ab[:-1]).all() and ab[-1] < 1e-4


def f1_over_f0(T, s=0.008):
    f = lambda t: math.cos(((t / T) + s) / (1 + s) * math.pi / 2) ** 2
    return f(1) / f(0)


def disc(**kw):
    torch.manual_seed(0)
    base = dict(in_dim=3, hidden_dim=32, num_steps=100, lr=1e-3, x_mean=np.zeros(3), x_std=np.ones(3))  # (s, a): 2 + 1
    return drail_disc.DiffusionDiscriminator(**(base | kw))


def test_forward_noising_by_hand():
    d = disc()
    x0, noise, t = torch.tensor([[1.0, -2.0, 0.5]]), torch.tensor([[0.3, 0.1, -1.0]]), torch.tensor([7])
    a = d.alpha_bar[7].item()
    want = math.sqrt(a) * x0 + math.sqrt(1 - a) * noise
    assert torch.allclose(d.noised(x0, t, noise), want)


def test_antithetic_timesteps():
    t = drail_disc.antithetic_timesteps(10, 1000, "cpu")
    assert torch.equal(t[5:], 999 - t[:5]) and (t >= 0).all() and (t < 1000).all()
    with pytest.raises(ValueError, match="even batch"):
        drail_disc.antithetic_timesteps(7, 1000, "cpu")


def test_states_are_standardised_with_the_same_statistics_for_everyone():
    d = disc(x_mean=np.array([10.0, -5.0, 0.0]), x_std=np.array([2.0, 0.0, 1.0]))  # a zero std is floored
    assert d.shift.tolist() == [10.0, -5.0, 0.0] and d.scale.tolist() == pytest.approx([2.0, 1e-3, 1.0])


def test_d_is_a_probability_that_learns_which_class_is_the_expert():
    d = disc(hidden_dim=64)
    expert_x = torch.randn(64, 3) * 0.1 + torch.tensor([1.0, 1.0, 0.5])
    agent_x = torch.randn(64, 3) * 0.1 - torch.tensor([1.0, 1.0, 0.5])
    p = d.prob(torch.cat([expert_x, agent_x]))
    assert ((p > 0) & (p < 1)).all()
    for _ in range(400):
        metrics = d.update(expert_x, agent_x)
    d.num_draws = 16  # average the single-draw estimate for the check
    assert d.prob(expert_x).mean() > 0.9 and d.prob(agent_x).mean() < 0.1
    assert metrics["disc/expert_prob"] > metrics["disc/policy_prob"]  # logged D(expert) > D(agent)
    # the logit is the difference of the two labels' denoising errors
    torch.manual_seed(3)
    t, noise = drail_disc.antithetic_timesteps(64, 100, "cpu"), torch.randn(64, 3)
    gap = d.denoising_error(expert_x, False, t, noise) - d.denoising_error(expert_x, True, t, noise)
    assert gap.mean() > 0  # the expert label denoises expert pairs better


def test_drail_rile_gives_the_trainer_rile_py_reward(monkeypatch):
    dvals, a_t = torch.tensor([0.1, 0.6, 0.95]), torch.tensor([0.2, -0.3, 0.9])
    for name in rile.TRAINER_REWARDS:
        assert torch.equal(drail_disc.TRAINER_REWARDS[name](dvals, a_t), rile.TRAINER_REWARDS[name](dvals, a_t))
    # inside the update: the trainer is rewarded from this discriminator's D, exactly as rile.py does
    args = drail_disc.Args(hidden_dim=8, trainer_hidden_dim=8, batch_size=4, trainer_batch_size=4, disc_batch_size=4)
    student = drail_disc.SAC(2, 1, -np.ones(1), np.ones(1), args, "cpu")
    trainer = drail_disc.SAC(3, 1, -np.ones(1), np.ones(1), args, "cpu")
    d = disc()
    monkeypatch.setattr(d, "prob", lambda x: torch.full((len(x),), 0.8))
    rb = drail_disc.ReplayBuffer(2, 1, 10, "cpu", extra_dim=1)
    for i in range(10):
        rb.add(np.full(2, i), np.zeros(1), np.full(2, i + 1), 0.0, False, extra=[0.5])
    seen = {}
    losses = {"qf_loss": torch.tensor(0.0), "qf_target_var": torch.tensor(1.0)}
    monkeypatch.setattr(trainer, "update", lambda *b, prefix: seen.update(b=b) or {prefix + k: v for k, v in losses.items()})
    expert = {"obs": torch.zeros(5, 2), "actions": torch.zeros(5, 1), "next_obs": torch.zeros(5, 2),
              "terminations": torch.zeros(5)}
    drail_disc.rile_update(student, trainer, d, rb, expert, args, drail_disc.rile_state("cpu"), 1)
    r_t = seen["b"][3]
    assert torch.allclose(r_t, rile.TRAINER_REWARDS["exp-difference"](torch.full((4,), 0.8), torch.full((4,), 0.5)))


@pytest.mark.parametrize("variant", ["gail", "rile"])
def test_end_to_end(run, tmp_path, variant):
    out = run("drail_disc.py", "--student-reward", variant, "--env-id", "InvertedPendulum-v4", "--total-timesteps", "400",
              "--learning-starts", "200", "--eval-freq", "200", "--eval-episodes", "2", "--hidden-dim", "32",
              "--trainer-hidden-dim", "32", "--batch-size", "32", "--trainer-batch-size", "32", "--disc-hidden-dim", "64",
              "--disc-batch-size", "16", "--num-expert-trajs", "2", "--trainer-freeze-min-updates", "100",
              "--trainer-freeze-threshold", "1e9", "--trainer-freeze-window", "0", "--trainer-freeze-after", "0",
              "--expert-path", str(ROOT / "experts/InvertedPendulum-v4.npz"),
              "--run-name", "d", *(["--termination-remedy", "none"] if variant == "gail" else [])).stdout
    assert f"DRAIL-{'RILe' if variant == 'rile' else 'GAIL'}" in out
    assert ("trainer frozen at step 300" in out) == (variant == "rile")
    results = json.loads((tmp_path / "runs/d/results.json").read_text())
    assert results["finished"] and [e["step"] for e in results["evals"]] == [200, 400]
    ckpt = torch.load(tmp_path / "runs/d/checkpoint.pt", weights_only=False)
    assert ckpt["disc_optimizer"]["state"] and (ckpt["rile"]["trainer_updates"] > 0) == (variant == "rile")
    absorbing = variant == "rile"  # the default; DRAIL-GAIL ran with none
    assert ckpt["disc"]["inp.weight"].shape[1] == 4 + absorbing + 1 + drail_disc.DiffusionDiscriminator.LABEL_DIM
    storage = ckpt["replay_buffer"]["storage"]
    assert (len(storage) > 400) == absorbing  # InvertedPendulum falls often: one absorbing row per fall
    if absorbing:  # the indicator column is not standardised
        assert ckpt["disc"]["shift"][4] == 0.0 and ckpt["disc"]["scale"][4] == 1.0


def test_odd_discriminator_batch_is_refused(run):
    proc = run("drail_disc.py", "--disc-batch-size", "7", "--expert-path", str(ROOT / "experts/Hopper-v4.npz"), check=False)
    assert proc.returncode != 0 and "must be even" in proc.stderr and "Traceback" not in proc.stderr
