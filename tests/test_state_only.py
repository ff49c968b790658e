"""Imitation from states only: demonstration files without actions, the loader's two modes, rile.py's
discriminator on (s, s') and its trainer's observation in both choices, end to end."""

import json
from dataclasses import replace

import numpy as np
import pytest
import torch

import gail
import rile
from conftest import ROOT
from test_rile import ACT, OBS, learners, recorder, tiny_args

PENDULUM = ROOT / "experts/InvertedPendulum-v4.npz"


def without_actions(path, out):
    """A copy of a project file as a state-only file: no `actions`, metadata saying so."""
    with np.load(path) as f:
        data = {k: f[k] for k in f.files if k != "actions"}
    data["metadata"] = np.array(json.dumps(json.loads(str(data["metadata"])) | {"state_only": True}))
    np.savez_compressed(out, **data)
    return out


# ---------------------------------------------------------------- the loader


def test_a_file_without_actions_loads_for_state_only_methods_only(tmp_path):
    env = gail.make_env("InvertedPendulum-v4", 0)
    path = str(without_actions(PENDULUM, tmp_path / "states.npz"))
    demos = gail.load_demonstrations(path, env, num_trajs=2, state_only=True)
    full = gail.load_demonstrations(str(PENDULUM), env, num_trajs=2)
    assert "actions" not in demos
    for k in ("observations", "next_observations", "terminations", "episode_lengths"):
        assert np.array_equal(demos[k], full[k])  # the first two episodes, as from the full file
    with pytest.raises(SystemExit, match="hold states only, and this method needs actions; .*--state-only"):
        gail.load_demonstrations(path, env)


def test_state_only_methods_never_see_actions_of_a_file_that_has_them():
    env = gail.make_env("InvertedPendulum-v4", 0)
    demos = gail.load_demonstrations(str(PENDULUM), env, state_only=True)
    assert "actions" not in demos
    args = rile.Args(state_only=True, termination_remedy="absorbing")
    expert = rile.absorbing_expert(rile.expert_tensors(demos, args.seed, "cpu"))
    assert set(expert) == {"obs", "next_obs", "terminations"}
    assert expert["obs"].shape[1] == OBS + 2  # InvertedPendulum: 4 dims and the indicator


def test_a_foreign_file_is_sent_to_demos_py(tmp_path):
    env = gail.make_env("InvertedPendulum-v4", 0)
    with np.load(PENDULUM) as f:
        np.savez(tmp_path / "plain.npz", **{k: f[k] for k in f.files if k != "metadata"})
    with pytest.raises(SystemExit, match=r"not in this project's format.*python demos.py convert .*plain.npz "
                                         r"--env-id InvertedPendulum-v4"):
        gail.load_demonstrations(str(tmp_path / "plain.npz"), env)


# ---------------------------------------------------------------- rile.py's update from states only


def state_only_learners(trainer_obs):
    args = tiny_args(state_only=True, trainer_obs=trainer_obs, termination_remedy="none")
    student, _, _, _, expert, state = learners(args)
    trainer = rile.make_trainer(OBS, ACT, args, "cpu")
    disc = rile.Discriminator(2 * OBS, args.disc_hidden_dim, args.disc_lr, args.disc_gp)
    # one stored trajectory per 7 steps: obs i, next obs i + 1, except at an episode's end (next obs 1000 + i)
    rb = rile.ReplayBuffer(OBS, ACT, 50, "cpu", extra_dim=1)
    for i in range(20):
        end = i % 7 == 6
        rb.add(np.full(OBS, i), np.full(ACT, 0.01 * i), np.full(OBS, 1000 + i if end else i + 1), 1.0, end and i < 10,
               extra=[0.02 * i - 0.2])
    del expert["actions"]
    return args, student, trainer, disc, rb, expert, state


def test_successor_of_each_stored_step_by_hand():
    *_, rb, _, _ = state_only_learners("transition")
    idx = torch.tensor([0, 5, 6, 13, 18, 19])
    s2 = rile.successor_next_obs(rb, idx, rb.batch(idx))[:, 0]
    # 0 -> 1 -> 2; 5 -> 6 -> 1006 (the episode ends there); 6 ended (terminated): its own s'; 13 ended at a time
    # limit: its own s'; 18 -> 19 -> 20; 19 is the last stored step: its own s'
    assert s2.tolist() == [2.0, 1006.0, 1006.0, 1013.0, 20.0, 20.0]


@pytest.mark.parametrize("trainer_obs", ["state-action", "transition"])
def test_discriminator_and_trainer_inputs_from_states_only(monkeypatch, trainer_obs):
    args, student, trainer, disc, rb, expert, state = state_only_learners(trainer_obs)
    seen = {}
    monkeypatch.setattr(trainer, "update", recorder(seen, "trainer"))
    monkeypatch.setattr(disc, "update", lambda expert_x, policy_x: seen.setdefault("disc", (expert_x, policy_x)) and {})
    torch.manual_seed(1)
    rile.rile_update(student, trainer, disc, rb, expert, args, state, 1)
    expert_x, policy_x = seen["disc"]
    assert expert_x.shape[1] == policy_x.shape[1] == 2 * OBS  # D scores (s, s') for the expert and the student
    assert ((expert_x[:, OBS:] == 200.0).all()) and (expert_x[:, :OBS] >= 100).all()
    rows = policy_x[:, 0].long()
    assert torch.equal(policy_x[:, OBS:], rb.batch(rows).next_obs)
    obs_t, a_t, next_obs_t, r_t, terminated = seen["trainer"]
    rows = obs_t[:, 0].long()
    batch = rb.batch(rows)
    assert torch.allclose(a_t.squeeze(-1), 0.02 * rows.float() - 0.2)  # the stored trainer action
    assert torch.equal(next_obs_t[:, :OBS], batch.next_obs)
    if trainer_obs == "transition":  # o_T = (s, s'), o_T' = (s', s'')
        assert torch.equal(obs_t[:, OBS:], batch.next_obs)
        assert torch.equal(next_obs_t[:, OBS:], rile.successor_next_obs(rb, rows, batch))
    else:  # o_T = (s, a_S), o_T' = (s', a'_S) with a fresh a'_S inside the box
        assert torch.allclose(obs_t[:, OBS:], batch.actions)
        assert (next_obs_t[:, OBS:].abs() <= 1).all()
    d = disc.prob(torch.cat([batch.obs, batch.next_obs], -1))  # r_T from D(s, s') in both choices
    assert torch.allclose(r_t, torch.exp(-((2 * d - 1) - a_t.squeeze(-1)).abs()))


def test_the_control_from_states_only_rewards_the_student_with_v_of_d_on_its_transitions(monkeypatch):
    """--student-reward discriminator --state-only: r_S = 2 D(s, s') - 1 on the student's batch, no trainer."""
    args, student, _, disc, rb, expert, state = state_only_learners("state-action")
    args = replace(args, student_reward="discriminator", termination_remedy="none")
    seen = []
    monkeypatch.setattr(student, "update", lambda obs, actions, next_obs, rewards, terminations, prefix: seen.append(
        (rewards, 2 * disc.prob(torch.cat([obs, next_obs], -1)) - 1)) or {})
    rile.rile_update(student, None, disc, rb, expert, args, state, 1)
    assert torch.allclose(*seen[0]) and state["trainer_updates"] == 0


# ---------------------------------------------------------------- end to end


TINY = ["--env-id", "InvertedPendulum-v4", "--learning-starts", "200", "--eval-freq", "300", "--eval-episodes", "2",
        "--hidden-dim", "32", "--trainer-hidden-dim", "32", "--batch-size", "32", "--trainer-batch-size", "32",
        "--disc-batch-size", "16", "--dynamics-freq", "200", "--num-expert-trajs", "2", "--total-timesteps", "600",
        "--trainer-freeze-min-updates", "200", "--trainer-freeze-threshold", "1e9",
        "--trainer-freeze-window", "0", "--trainer-freeze-after", "0"]


def test_rile_from_a_file_without_actions_then_covariate_shift(run, tmp_path):
    states = str(without_actions(PENDULUM, tmp_path / "states.npz"))
    out = run("rile.py", *TINY, "--expert-path", states, "--state-only", "--run-name", "s").stdout
    assert "trainer frozen at step 400" in out and "done: 600 steps" in out
    dynamics = json.loads((tmp_path / "runs/s/dynamics.json").read_text())
    assert dynamics[1]["rfdc"] is not None and all(d["fs_rfdc"] is None for d in dynamics)  # no expert actions
    saved = torch.load(tmp_path / "runs/s/reward.pt", weights_only=True)
    assert saved["state_only"] and saved["disc"]["net.0.weight"].shape[1] == 2 * 5  # (s, s'), with the indicator
    out = run("benchmarks/rile_rewards.py", "runs/s").stdout  # what r_S pays, without expert actions
    assert "r_S on the demonstrations:               not defined" in out and "r_S of the student's action" in out
    assert "D at the absorbing state" not in out  # D sees (s, s') here: no (s_abs, 0) pair to ask it about
    out = run("rile.py", *TINY, "--expert-path", states, "--state-only", "--run-name", "cs",
              "--reward-from", "runs/s/reward.pt").stdout
    assert "done: 600 steps" in out
    proc = run("rile.py", *TINY, "--expert-path", states, "--run-name", "x", check=False)
    assert proc.returncode != 0 and "hold states only" in proc.stderr  # the paper's D(s, a) needs actions
    proc = run("rile.py", *TINY, "--expert-path", str(PENDULUM), "--reward-from", "runs/s/reward.pt", check=False)
    assert proc.returncode != 0 and "learned with --state-only True" in proc.stderr


def test_rile_trainer_observing_transitions(run, tmp_path):
    out = run("rile.py", *TINY, "--expert-path", str(PENDULUM), "--state-only", "--trainer-obs", "transition",
              "--run-name", "t").stdout
    assert "trainer frozen at step 400" in out
    dynamics = json.loads((tmp_path / "runs/t/dynamics.json").read_text())
    assert dynamics[1]["fs_rfdc"] is not None  # the trainer scores expert transitions
    ckpt = torch.load(tmp_path / "runs/t/checkpoint.pt", weights_only=False)
    assert ckpt["trainer"]["actor"]["net.0.weight"].shape[1] == 2 * 5
    out = run("benchmarks/rile_rewards.py", "runs/t").stdout  # r_S on (s, s'): defined on the demonstrations too
    assert "r_S on the demonstrations:               mean" in out and "r_S of the student's action" not in out
    trainer = rile.Actor(2 * 5, 1, np.array([-1.0]), np.array([1.0]), ckpt["config"]["trainer_hidden_dim"])
    trainer.load_state_dict(ckpt["trainer"]["actor"])
    s_abs = [0.0, 0.0, 0.0, 0.0, 1.0]
    r_abs = trainer.deterministic(torch.tensor([s_abs + s_abs])).item()  # (s_abs, s_abs): the absorbing loop
    assert f"r_S at the absorbing state:               {r_abs:7.3f};" in out


@pytest.mark.parametrize("flags, message", [
    (["--student-expert-fraction", "0.25"], "--student-expert-fraction needs the expert's actions"),
    (["--expert-action-noise", "0.1"], "--expert-action-noise needs the expert's actions"),
])
def test_what_needs_expert_actions_is_refused(run, flags, message):
    proc = run("rile.py", *TINY, "--expert-path", str(PENDULUM), "--state-only", *flags, check=False)
    assert proc.returncode != 0 and message in proc.stderr and "Traceback" not in proc.stderr


def test_trainer_on_transitions_needs_state_only(run):
    proc = run("rile.py", *TINY, "--expert-path", str(PENDULUM), "--trainer-obs", "transition", check=False)
    assert proc.returncode != 0 and "--trainer-obs transition goes with --state-only" in proc.stderr


# ---------------------------------------------------------------- the other state-only methods, and writing such a file


def test_expert_writes_a_state_only_file_that_state_only_methods_read(run, tmp_path):
    actor = str(ROOT / "experts/InvertedPendulum-v4-actor.pt")
    out = run("expert.py", "--env-id", "InvertedPendulum-v4", "--record-from", actor,
              "--num-demos", "2", "--no-actions", "--demo-path", "states.npz").stdout
    assert "recorded 2 episodes" in out
    with np.load(tmp_path / "states.npz") as f:
        assert "actions" not in f.files and json.loads(str(f["metadata"]))["state_only"]
    run("gaifo.py", "--env-id", "InvertedPendulum-v4", "--expert-path", "states.npz", "--num-expert-trajs", "2",
        "--total-timesteps", "300",
        "--learning-starts", "200", "--eval-freq", "300", "--eval-episodes", "1", "--hidden-dim", "32", "--batch-size", "32")
    run("bco.py", "--env-id", "InvertedPendulum-v4", "--expert-path", "states.npz", "--num-expert-trajs", "2",
        "--pre-demo-steps", "200",
        "--total-timesteps", "300", "--inverse-steps", "50", "--bc-steps", "50", "--inverse-steps-per-iteration", "20",
        "--bc-steps-per-iteration", "20", "--hidden-dim", "32", "--eval-episodes", "1")
    for script in ("gail.py", "airl.py", "iqlearn.py", "bc.py"):  # they need the expert's actions
        proc = run(script, "--env-id", "InvertedPendulum-v4", "--expert-path", "states.npz", "--total-timesteps", "10",
                   check=False)
        assert proc.returncode != 0 and "hold states only, and this method needs actions" in proc.stderr, script
        assert "Traceback" not in proc.stderr


DRAIL = ["--env-id", "InvertedPendulum-v4", "--learning-starts", "200", "--total-timesteps", "400", "--eval-freq", "400",
         "--eval-episodes", "1", "--hidden-dim", "32", "--trainer-hidden-dim", "32", "--batch-size", "32",
         "--trainer-batch-size", "32", "--disc-batch-size", "16", "--disc-hidden-dim", "32", "--diffusion-steps", "100",
         "--num-expert-trajs", "2", "--trainer-freeze-min-updates", "100", "--trainer-freeze-threshold", "1e9",
         "--trainer-freeze-window", "0", "--trainer-freeze-after", "0",
         "--state-only"]


@pytest.mark.parametrize("variant", [["--student-reward", "gail"], ["--student-reward", "rile"],
                                     ["--student-reward", "rile", "--trainer-obs", "transition"]])
def test_drail_from_states_only(run, tmp_path, variant):
    states = str(without_actions(PENDULUM, tmp_path / "states.npz"))
    out = run("drail_disc.py", *DRAIL, "--expert-path", states, *variant, "--run-name", "d").stdout
    assert "done: 400 steps" in out
    if "rile" in variant:
        assert "trainer frozen at step 300" in out
    disc = torch.load(tmp_path / "runs/d/disc.pt", weights_only=False)["disc"]
    half = len(disc["shift"]) // 2  # x = (s, s'), both halves standardised with the expert's state statistics
    assert len(disc["shift"]) == 2 * 5 and torch.equal(disc["shift"][:half], disc["shift"][half:])


def test_demonstrations_from_elsewhere_without_actions_or_rewards(run, tmp_path):
    """The path of motion-capture-like data: a plain npz of states and episode ends, converted by demos.py,
    imitated by gaifo.py; with no rewards there is no expert return to normalise by."""
    with np.load(PENDULUM) as f:
        end = int(f["episode_lengths"][:2].sum())
        np.savez(tmp_path / "mocap.npz", observations=f["observations"][:end], next_observations=f["next_observations"][:end],
                 terminals=f["terminations"][:end], timeouts=f["truncations"][:end])
    out = run("demos.py", "convert", "mocap.npz", "--env-id", "InvertedPendulum-v4", "--out", "states.npz").stdout
    assert "state-only" in out
    run("gaifo.py", "--env-id", "InvertedPendulum-v4", "--expert-path", "states.npz", "--num-expert-trajs", "2",
        "--total-timesteps", "300", "--learning-starts", "200", "--eval-freq", "300", "--eval-episodes", "1",
        "--hidden-dim", "32", "--batch-size", "32", "--run-name", "m")
    results = json.loads((tmp_path / "runs/m/results.json").read_text())
    assert results["finished"] and results["expert_return"] is None and results["final_normalized_return"] is None
