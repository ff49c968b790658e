"""Covariate shift, alike in rile.py, gail.py and airl.py: `--reward-from runs/<run>/reward.pt` trains a fresh learner
against the reward a finished run of the same script saved, frozen, with `--student-action-noise` on the actions it
executes (and stores) while training; evaluations run without noise. A file from another script, env, dims or reward
flags, or no file: one line saying which."""

import json
from dataclasses import replace

import numpy as np
import pytest
import torch

import airl
import gail
import rile
from benchmarks import frozen_reward_rollouts
from conftest import ROOT

PENDULUM = ["--env-id", "InvertedPendulum-v4", "--learning-starts", "200", "--eval-freq", "300", "--eval-episodes", "2",
            "--hidden-dim", "32", "--batch-size", "32", "--disc-batch-size", "16", "--num-expert-trajs", "2",
            "--dynamics-freq", "300", "--expert-path", str(ROOT / "experts/InvertedPendulum-v4.npz")]
SCRIPTS = {"rile.py": rile, "gail.py": gail, "airl.py": airl}
OBS, ACT = 3, 2


def source(name: str, **kw):
    """A learner and a reward of script `name` (small networks), with a buffer of 20 transitions."""
    torch.manual_seed(kw.pop("seed", 0))
    module = SCRIPTS[name]
    args = module.Args(hidden_dim=16, batch_size=8, disc_batch_size=4, disc_hidden_dim=8, **kw)
    agent = module.SAC(OBS, ACT, -np.ones(ACT), np.ones(ACT), args, "cpu")
    if name == "airl.py":
        disc = airl.AIRLDiscriminator(OBS, ACT, 8, args.gamma, args.state_only, args.disc_lr, args.disc_gp,
                                      level_lr=args.disc_level_lr)
        with torch.no_grad():
            disc.level.fill_(0.7)
    else:
        disc = module.Discriminator(OBS + ACT, 8, args.disc_lr, args.disc_gp)
    rb = module.ReplayBuffer(OBS, ACT, 20, "cpu")
    for i in range(20):
        rb.add(np.full(OBS, i / 10), np.full(ACT, 0.3), np.full(OBS, i / 10 + 0.1), 9.0, i % 7 == 6)
    return args, agent, disc, rb


@pytest.mark.parametrize("name", ["gail.py", "airl.py"])
def test_the_frozen_reward_is_the_saved_one(name, tmp_path, monkeypatch):
    """The saved reward loaded into another learner's networks gives, on the batches it learns from, the rewards the
    saved networks give (that no reward parameter moves in a run is checked end to end below)."""
    module = SCRIPTS[name]
    args, agent, disc, rb = source(name)
    torch.save(module.reward_file(disc, args, OBS, ACT), tmp_path / "reward.pt")
    _, fresh_agent, frozen, _ = source(name, seed=5)  # other weights until the file is loaded
    module.load_reward(str(tmp_path / "reward.pt"), frozen, args, OBS, ACT)
    seen = []
    monkeypatch.setattr(fresh_agent, "update", lambda *batch, prefix: seen.append(batch) or {})
    for _ in range(3):
        if name == "gail.py":
            gail.gail_update(fresh_agent, frozen, rb, None, args, update_disc=False)
        else:
            airl.airl_update(fresh_agent, frozen, rb, None, args, update_disc=False)
    for obs, actions, next_obs, rewards, terminations in seen:
        with torch.no_grad():
            if name == "gail.py":
                want = gail.gail_reward(disc(torch.cat([obs, actions], -1)), args.reward_form)
            else:  # softplus of the saved logit f + b - log pi, log pi of the uniform box (--disc-policy-mix 1)
                log_pi = airl.policy_log_prob(fresh_agent, obs, actions, args.disc_policy_mix)
                want = airl.sac_reward(disc, airl.Batch(obs, actions, next_obs, None, terminations, None), args.reward,
                                       False, log_pi)
        assert torch.allclose(rewards, want, atol=1e-6) and not torch.any(rewards == 9.0)


@pytest.mark.parametrize("name", ["rile.py", "gail.py", "airl.py"])
def test_a_file_that_does_not_fit_is_refused_in_one_line(name, tmp_path):
    module = SCRIPTS[name]
    args, agent, disc, rb = source(name)
    trainer = (rile.make_trainer(OBS, ACT, args, "cpu"),) if name == "rile.py" else ()
    torch.save(module.reward_file(*trainer, disc, args, OBS, ACT), tmp_path / "reward.pt")
    other = "gail.py" if name != "gail.py" else "rile.py"
    args_other, _, disc_other, _ = source(other)
    trainer_other = (rile.make_trainer(OBS, ACT, args_other, "cpu"),) if other == "rile.py" else ()
    torch.save(SCRIPTS[other].reward_file(*trainer_other, disc_other, args_other, OBS, ACT), tmp_path / "other.pt")
    flag, value = {"rile.py": ("termination_remedy", "none"), "gail.py": ("reward_form", "logit"),
                   "airl.py": ("disc_policy_mix", 0.0)}[name]
    load = lambda path, a=args, obs=OBS: module.load_reward(str(tmp_path / path), *trainer, disc, a, obs, ACT)
    cases = [(lambda: load("missing.pt"), f"reward '{tmp_path / 'missing.pt'}' does not exist; a finished {name} run"),
             (lambda: load("other.pt"), f"was saved by {other}, not {name}"),
             (lambda: load("reward.pt", a=replace(args, env_id="Walker2d-v4")), "was learned on Hopper-v4, not Walker2d-v4"),
             (lambda: load("reward.pt", obs=OBS + 1), f"has obs/act dims {OBS}/{ACT}, Hopper-v4 has {OBS + 1}/{ACT}"),
             (lambda: load("reward.pt", a=replace(args, **{flag: value})), f"was learned with --{flag.replace('_', '-')} ")]
    for call, message in cases:
        with pytest.raises(SystemExit) as error:
            call()
        assert message in str(error.value) and "\n" not in str(error.value)


@pytest.mark.parametrize("name", ["rile.py", "gail.py", "airl.py"])
def test_a_fresh_learner_against_a_frozen_reward_acts_with_noise_and_is_evaluated_without(name, run, tmp_path):
    """End to end: a source run saves its reward; a fresh run against it stores noisy executed actions (std 10 on a
    [-3, 3] box: most at the bounds, where the actor's tanh never is), keeps every reward parameter as saved, and
    evaluates the actor it saves without noise."""
    extra = ["--trainer-hidden-dim", "32", "--trainer-batch-size", "32"] if name == "rile.py" else []
    run(name, *PENDULUM, *extra, "--total-timesteps", "400", "--run-name", "src")
    run(name, *PENDULUM, *extra, "--total-timesteps", "600", "--run-name", "cs", "--reward-from", "runs/src/reward.pt",
        "--student-action-noise", "10", "--checkpoint-freq", "300")
    saved = torch.load(tmp_path / "runs/src/reward.pt", weights_only=True)
    after = torch.load(tmp_path / "runs/cs/reward.pt", weights_only=True)
    networks = ["trainer_actor", "disc"] if name == "rile.py" else ["disc"] if name == "gail.py" else ["g", "h"]
    for key in networks:
        assert saved[key].keys() == after[key].keys() and all(torch.equal(saved[key][k], after[key][k]) for k in saved[key])
    if name == "airl.py":
        assert torch.equal(saved["level"], after["level"])
    ckpt = torch.load(tmp_path / "runs/cs/checkpoint.pt", weights_only=False)
    assert not ckpt["disc_optimizer"]["state"]  # D never stepped
    storage = ckpt["replay_buffer"]["storage"][:300]
    obs_dim = 5 if name == "rile.py" else 4  # rile.py's absorbing indicator column
    actions = storage[:, obs_dim]
    assert (actions.abs() == 3.0).float().mean() > 0.6 and actions.abs().max() <= 3.0  # clipped, mostly at the bounds
    results = json.loads((tmp_path / "runs/cs/results.json").read_text())
    actor_file = torch.load(tmp_path / "runs/cs/actor.pt", weights_only=True)
    actor = rile.Actor(4, 1, np.array([-3.0]), np.array([3.0]), actor_file["hidden_dim"])
    actor.load_state_dict(actor_file["actor"])
    returns = rile.evaluate(actor.act, "InvertedPendulum-v4", 2, seed=1 + 100_000)  # the scripts' evaluation, no noise
    assert results["evals"][-1]["mean"] == pytest.approx(float(np.mean(returns)))
    # benchmarks/frozen_reward_rollouts.py on the fresh learner: its mean-action episodes are the evaluation's
    run("benchmarks/frozen_reward_rollouts.py", "runs/src/reward.pt", "runs/cs", "--episodes", "2", "--seed", "100001",
        "--out", "rollouts.json")
    rows = json.loads((tmp_path / "rollouts.json").read_text())["rows"]
    assert [row["action"] for row in rows] == ["mean", "sampled"] and rows[0]["return"] == pytest.approx(returns)
    assert all(len(row["frozen_per_step"]) == 2 and np.isfinite(row["frozen_discounted"]).all() for row in rows)


def test_the_frozen_rewards_tool_saves_each_sources_reward_with_its_provenance(run, tmp_path):
    """benchmarks/frozen_rewards.py (here 300 steps of InvertedPendulum-v4, no learning yet): the source's reward.pt,
    byte for byte, under <out>/<env-id>/<algo>__1.pt, a README line naming the command and the commit, and the source
    run's results file under the tag `source`."""
    out = tmp_path / "rewards"
    (tmp_path / "experts").symlink_to(ROOT / "experts")  # the default demonstrations, as from the repository root
    run("benchmarks/frozen_rewards.py", "--env-id", "InvertedPendulum-v4", "--methods", "gail-paperD-autotune", "airl",
        "--total-timesteps", "300", "--out", str(out), "--results-dir", str(tmp_path / "results"))
    for method in ("gail-paperD-autotune", "airl"):
        source = tmp_path / f"runs/source__InvertedPendulum-v4__{method}__1/reward.pt"
        assert (out / f"InvertedPendulum-v4/{method}__1.pt").read_bytes() == source.read_bytes()
    lines = (out / "README.md").read_text().splitlines()
    airl_line = next(line for line in lines if line.startswith("- `InvertedPendulum-v4/airl__1.pt`"))
    assert "python airl.py --env-id InvertedPendulum-v4 --seed 1 --total-timesteps 300" in airl_line
    assert " at commit " in airl_line
    source = json.loads((tmp_path / "results/InvertedPendulum-v4/airl-source__1.json").read_text())  # the source row
    assert source["finished"] and source["command"].startswith("python airl.py --env-id InvertedPendulum-v4 --seed 1 ")
    assert (tmp_path / "results/InvertedPendulum-v4/gail-paperD-autotune-source__1.json").exists()


def test_the_rollout_tool_discounts_from_reset_with_the_absorbing_tail():
    """benchmarks/frozen_reward_rollouts.py by hand: rewards 1, 2, 3 with gamma 0.5 are 1 + 0.5*2 + 0.25*3 = 2.75;
    with 3 the absorbing state's reward, repeated from step 2 on: 1 + 0.5*2 + 0.25*3 / (1 - 0.5) = 3.5. An episode
    that falls is stored as the learner stores it: with absorbing states the indicator column, the fall leading to
    the absorbing state and its zero-action self-loop; without, the last row terminal."""
    assert frozen_reward_rollouts.discounted(np.array([1.0, 2.0, 3.0]), 0.5, False) == pytest.approx(2.75)
    assert frozen_reward_rollouts.discounted(np.array([1.0, 2.0, 3.0]), 0.5, True) == pytest.approx(3.5)
    obs, actions, next_obs = np.ones((2, OBS)), np.full((2, ACT), 0.5), np.full((2, OBS), 2.0)
    b = frozen_reward_rollouts.episode_batch(obs, actions, next_obs, True, absorbing=True)
    s_abs = torch.tensor([0.0] * OBS + [1.0])
    assert b["obs"].shape == (3, OBS + 1) and torch.equal(b["obs"][2], s_abs) and torch.equal(b["next_obs"][1], s_abs)
    assert torch.equal(b["next_obs"][2], s_abs) and torch.equal(b["next_obs"][0], torch.tensor([2.0] * OBS + [0.0]))
    assert torch.equal(b["actions"][2], torch.zeros(ACT)) and not b["terminations"].any()
    b = frozen_reward_rollouts.episode_batch(obs, actions, next_obs, True, absorbing=False)
    assert b["obs"].shape == (2, OBS) and b["terminations"].tolist() == [0.0, 1.0]


@pytest.mark.parametrize("name,student_reward", [("rile.py", "trainer"), ("rile.py", "discriminator"),
                                                 ("gail.py", None), ("airl.py", None)])
def test_the_rollout_tool_pays_what_a_learner_against_the_file_is_paid(name, student_reward, tmp_path, monkeypatch):
    """The tool's frozen reward of a reward.pt, on a batch, is what the script's update hands a fresh learner against
    that file (rile.py: absorbing states, so its observations carry the indicator column)."""
    module = SCRIPTS[name]
    kw = {"student_reward": student_reward, "trainer_hidden_dim": 8} if name == "rile.py" else {}
    args, agent, disc, rb = source(name, **kw)
    env_obs = OBS - (args.termination_remedy == "absorbing")  # the env's dims; rile.py adds the indicator
    trainer = rile.make_trainer(OBS, ACT, args, "cpu") if student_reward == "trainer" else None
    torch.save(module.reward_file(*((trainer,) if name == "rile.py" else ()), disc, args, env_obs, ACT),
               tmp_path / "reward.pt")
    absorbing, gamma, reward = frozen_reward_rollouts.frozen_reward(str(tmp_path / "reward.pt"), "Hopper-v4", env_obs, ACT)
    assert absorbing == (name == "rile.py") and gamma == args.gamma
    seen = []
    monkeypatch.setattr(agent, "update", lambda *batch, prefix: seen.append(batch) or {})
    for _ in range(3):
        if name == "rile.py":
            state = rile.rile_state("cpu") | {"reward_only": True}
            rile.rile_update(agent, trainer, disc, rb, None, args, state, 0)
        elif name == "gail.py":
            gail.gail_update(agent, disc, rb, None, args, update_disc=False)
        else:
            airl.airl_update(agent, disc, rb, None, args, update_disc=False)
    for obs, actions, next_obs, rewards, terminations in seen:
        batch = {"obs": obs, "actions": actions, "next_obs": next_obs, "terminations": terminations}
        with torch.no_grad():
            assert torch.allclose(reward(batch, agent.actor), rewards, atol=1e-6) and not torch.any(rewards == 9.0)
