"""demos.py: every source format, written here from the same three InvertedPendulum-v4 episodes, converts
to the same arrays; bad input is one line and writes nothing; `info` prints the summary."""

import collections
import json
import pickle

import gymnasium as gym
import h5py
import numpy as np
import pytest

import demos
from conftest import ROOT, run_script

ENV_ID = "InvertedPendulum-v4"  # obs = (qpos, qvel): the replay check runs; 1000-step time limit; action box [-3, 3]


@pytest.fixture(scope="module")
def episodes():
    """The shipped expert's first episode (1000 steps, cut by the time limit) and two random-action
    episodes that fall (terminate) within a few steps. Each: obs (T+1 rows), actions, rewards, terminated."""
    with np.load(ROOT / "experts" / f"{ENV_ID}.npz") as f:
        n = int(f["episode_lengths"][0])
        eps = [{"obs": np.concatenate([f["observations"][:n], f["next_observations"][n - 1:n]]),
                "actions": f["actions"][:n], "rewards": f["rewards"][:n], "terminated": False}]
    env = gym.make(ENV_ID)
    env.action_space.seed(0)
    for seed in (1, 2):
        obs, _ = env.reset(seed=seed)
        ep = {"obs": [obs], "actions": [], "rewards": [], "terminated": True}
        terminated = False
        while not terminated:
            action = env.action_space.sample()
            obs, reward, terminated, truncated, _ = env.step(action)
            assert not truncated
            ep["obs"].append(obs), ep["actions"].append(action), ep["rewards"].append(reward)
        eps.append({k: np.asarray(v, dtype=np.float32) if k != "terminated" else v for k, v in ep.items()})
    return eps


def flat(eps):
    """The episodes as the project's arrays, built independently of demos.py."""
    lengths = np.array([len(e["actions"]) for e in eps])
    ends = np.cumsum(lengths) - 1
    out = {"observations": np.concatenate([e["obs"][:-1] for e in eps]),
           "next_observations": np.concatenate([e["obs"][1:] for e in eps]),
           "actions": np.concatenate([e["actions"] for e in eps]),
           "rewards": np.concatenate([e["rewards"] for e in eps]).astype(np.float32),
           "terminations": np.zeros(lengths.sum(), bool), "truncations": np.zeros(lengths.sum(), bool),
           "episode_starts": ends + 1 - lengths, "episode_lengths": lengths}
    out["terminations"][ends] = [e["terminated"] for e in eps]
    out["truncations"][ends] = [not e["terminated"] for e in eps]
    out["episode_returns"] = np.array([e["rewards"].astype(np.float32).astype(np.float64).sum() for e in eps])
    return out


def assert_same(got: dict, want: dict):
    assert sorted(got) == sorted(want)
    for k, v in want.items():
        assert got[k].shape == v.shape and got[k].dtype == (v.dtype if k != "rewards" else np.float32), k
        np.testing.assert_allclose(got[k], v, rtol=1e-6, atol=1e-6, err_msg=k)


def load(path):
    with np.load(path, allow_pickle=False) as f:
        data = {k: f[k] for k in f.files}
    return data, json.loads(str(data.pop("metadata")))


# ---------------------------------------------------------------- one writer per format


def write_project_npz(tmp_path, eps):
    path = tmp_path / "project.npz"
    np.savez_compressed(path, **flat(eps), metadata=np.array(json.dumps({"env_id": ENV_ID})))
    return str(path), []


def write_common_npz(tmp_path, eps):
    f = flat(eps)
    path = tmp_path / "common.npz"
    np.savez(path, obs=f["observations"], acts=f["actions"], next_obs=f["next_observations"], rews=f["rewards"],
             terminals=f["terminations"], timeouts=f["truncations"])
    return str(path), []


def write_dones_npz(tmp_path, eps):
    """Only `dones`: the 1000-step episode (the env's limit) must come out truncated, the others terminated."""
    f = flat(eps)
    path = tmp_path / "dones.npz"
    np.savez(path, observations=f["observations"], actions=f["actions"], next_observations=f["next_observations"],
             rewards=f["rewards"], dones=f["terminations"] | f["truncations"])
    return str(path), []


def write_pickle(tmp_path, eps):
    f = flat(eps)
    path = tmp_path / "dict.pkl"
    with open(path, "wb") as fh:  # `dones` (both kinds of end) split by `timeouts`
        pickle.dump({"states": f["observations"], "actions": f["actions"], "next_states": f["next_observations"],
                     "rewards": f["rewards"].astype(np.float64), "dones": f["terminations"] | f["truncations"],
                     "timeouts": f["truncations"]}, fh)
    return str(path), []


def write_d4rl(tmp_path, eps):
    f = flat(eps)
    path = tmp_path / "d4rl.hdf5"
    with h5py.File(path, "w") as h:
        for key, value in (("observations", f["observations"]), ("actions", f["actions"]), ("rewards", f["rewards"]),
                           ("terminals", f["terminations"]), ("timeouts", f["truncations"]),
                           ("next_observations", f["next_observations"])):
            h.create_dataset(key, data=value)
        h.create_dataset("infos/qpos", data=f["observations"][:, :2])  # groups are ignored
    return str(path), []


def write_minari(tmp_path, eps, dataset_id="test/pendulum/expert-v0"):
    minari = pytest.importorskip("minari")
    from minari.data_collector.episode_buffer import EpisodeBuffer

    buffers = [EpisodeBuffer(id=i, observations=list(e["obs"]), actions=list(e["actions"]), rewards=list(e["rewards"]),
                             terminations=[False] * (len(e["actions"]) - 1) + [e["terminated"]],
                             truncations=[False] * (len(e["actions"]) - 1) + [not e["terminated"]])
               for i, e in enumerate(eps)]
    minari.create_dataset_from_buffers(dataset_id, buffers, env=ENV_ID, data_format="hdf5")
    return dataset_id, []


def write_iqlearn(tmp_path, eps):
    """IQ-Learn's layout: defaultdict of per-trajectory tuples, dones True at the time limit too,
    actions in [-1, 1] units."""
    data = collections.defaultdict(list)
    for e in eps:
        states = [np.asarray(o, dtype=np.float64) for o in e["obs"]]
        data["states"].append(tuple(states[:-1]))
        data["next_states"].append(tuple(states[1:]))
        data["actions"].append(tuple(np.asarray(a / 3.0, dtype=np.float32) for a in e["actions"]))
        data["rewards"].append(tuple(float(r) for r in e["rewards"]))
        data["dones"].append(tuple([False] * (len(e["actions"]) - 1) + [True]))
        data["lengths"].append(len(e["actions"]))
    path = tmp_path / "Pendulum_3.pkl"
    with open(path, "wb") as fh:
        pickle.dump(data, fh)
    return str(path), ["--actions-unit", "normalized"]


def write_imitation_npz(tmp_path, eps):
    """imitation's npz: obs with each trajectory's final observation, `indices` split points, one
    `terminal` per trajectory (True for the time-limited one too), infos as an object array."""
    lengths = [len(e["actions"]) for e in eps]
    infos = np.empty(sum(lengths), dtype=object)
    infos[:] = [{} for _ in range(sum(lengths))]
    path = tmp_path / "imitation.npz"
    np.savez_compressed(path, obs=np.concatenate([e["obs"] for e in eps]),
                        acts=np.concatenate([e["actions"] for e in eps]), infos=infos, terminal=np.array([True] * len(eps)),
                        indices=np.cumsum(lengths[:-1]),
                        rews=np.concatenate([e["rewards"] for e in eps]))
    return str(path), []


def write_imitation_hf(tmp_path, eps):
    datasets = pytest.importorskip("datasets")
    rows = {"obs": [e["obs"] for e in eps], "acts": [e["actions"] for e in eps],
            "infos": [["{}"] * len(e["actions"]) for e in eps], "terminal": [True] * len(eps),
            "rews": [e["rewards"] for e in eps]}
    path = tmp_path / "imitation_hf"
    datasets.Dataset.from_dict(rows).save_to_disk(str(path))
    return str(path), []


WRITERS = {"project-npz": write_project_npz, "common-npz": write_common_npz, "dones-npz": write_dones_npz,
           "pickle": write_pickle,
           "d4rl": write_d4rl, "minari": write_minari, "iqlearn": write_iqlearn, "imitation-npz": write_imitation_npz,
           "imitation-hf": write_imitation_hf}


@pytest.fixture
def minari_root(tmp_path, monkeypatch):
    monkeypatch.setenv("MINARI_DATASETS_PATH", str(tmp_path / "minari"))


def convert(src, out, *extra):
    demos.main(["convert", src, "--env-id", ENV_ID, "--out", str(out), *extra])


@pytest.mark.parametrize("fmt", WRITERS)
def test_every_format_converts_to_the_same_arrays(fmt, episodes, tmp_path, minari_root, capsys):
    src, extra = WRITERS[fmt](tmp_path, episodes)
    convert(src, tmp_path / "out.npz", *extra)
    got, meta = load(tmp_path / "out.npz")
    assert_same(got, flat(episodes))
    assert meta["env_id"] == ENV_ID and meta["state_only"] is False
    assert meta["converted_by"].startswith("python demos.py convert ")
    assert any(c.startswith("replay: 10 steps") for c in meta["checks"]), meta["checks"]
    printed = capsys.readouterr().out
    assert f"3 episodes, {len(got['rewards'])} transitions, with actions" in printed
    assert "2 end in a termination, 1 in a truncation" in printed


def test_minari_dataset_by_path(episodes, tmp_path, minari_root):
    write_minari(tmp_path, episodes, "test/pendulum/other-v0")
    convert(str(tmp_path / "minari" / "test" / "pendulum" / "other-v0"), tmp_path / "out.npz", "--format", "minari")
    assert_same(load(tmp_path / "out.npz")[0], flat(episodes))


def test_without_next_observations_each_episode_loses_its_last_step(episodes, tmp_path, capsys):
    f = flat(episodes)
    np.savez(tmp_path / "src.npz", observations=f["observations"], actions=f["actions"], rewards=f["rewards"],
             terminations=f["terminations"], truncations=f["truncations"])
    convert(str(tmp_path / "src.npz"), tmp_path / "out.npz")
    # what survives: every row but each episode's last, with s' the next row; every episode now ends cut
    shortened = [dict(e, obs=e["obs"][:-1], actions=e["actions"][:-1], rewards=e["rewards"][:-1], terminated=False)
                 for e in episodes]
    assert_same(load(tmp_path / "out.npz")[0], flat(shortened))
    assert "last transition of each episode (3 rows, with 2 terminations) dropped" in capsys.readouterr().out


def test_state_only_and_rewardless_source(episodes, tmp_path, capsys):
    f = flat(episodes)
    np.savez(tmp_path / "src.npz", obs=f["observations"], next_obs=f["next_observations"],
             terminals=f["terminations"], timeouts=f["truncations"])
    convert(str(tmp_path / "src.npz"), tmp_path / "out.npz")
    got, meta = load(tmp_path / "out.npz")
    assert "actions" not in got and meta["state_only"] is True
    assert np.isnan(got["rewards"]).all() and np.isnan(got["episode_returns"]).all()
    np.testing.assert_array_equal(got["observations"], f["observations"])
    printed = capsys.readouterr().out
    assert "state-only (no actions)" in printed and "returns: none" in printed
    assert "replay skipped: no actions" in printed


def test_info_prints_the_summary(episodes, tmp_path):
    convert(write_d4rl(tmp_path, episodes)[0], tmp_path / "out.npz")
    proc = run_script("demos.py", "info", str(tmp_path / "out.npz"), "--check", cwd=tmp_path)
    lines = proc.stdout.splitlines()
    assert lines[0].endswith(f"{ENV_ID}, 3 episodes, {len(flat(episodes)['rewards'])} transitions, with actions")
    assert "return: mean" in proc.stdout and "source: d4rl" in proc.stdout and "check: replay: 10 steps" in proc.stdout


def test_a_shipped_expert_file_is_summarised(capsys):
    demos.main(["info", str(ROOT / "experts" / f"{ENV_ID}.npz")])
    assert "25 episodes, 25000 transitions, with actions" in capsys.readouterr().out


# ---------------------------------------------------------------- bad input: one line, nothing written


def bad_sources(tmp_path, eps):
    f = flat(eps)
    np.savez(tmp_path / "no_obs.npz", actions=f["actions"])
    np.savez(tmp_path / "short_actions.npz", observations=f["observations"], actions=f["actions"][:-5],
             terminations=f["terminations"])
    np.savez(tmp_path / "outside_box.npz", **{k: f[k] for k in ("observations", "next_observations", "terminations")},
             actions=f["actions"] * 0 + 5.0)
    broken = dict(f, next_observations=f["next_observations"] + 0.5)
    np.savez(tmp_path / "replay.npz", **broken)
    np.savez(tmp_path / "no_ends.npz", observations=f["observations"], actions=f["actions"], episode_lengths=[4, 4])
    (tmp_path / "evil.pkl").write_bytes(pickle.dumps(Evil()))
    (tmp_path / "corrupt.npz").write_bytes(b"not a zip")
    return [  # (source, env id, what the error names)
        ("no_obs.npz", ENV_ID, "no observations"),
        ("short_actions.npz", ENV_ID, "actions has"),
        ("outside_box.npz", ENV_ID, "--actions-unit normalized"),
        ("replay.npz", ENV_ID, "replay: step 0"),
        ("no_ends.npz", ENV_ID, "episode lengths sum to 8"),
        ("evil.pkl", ENV_ID, "only dicts of arrays or lists are read"),
        ("corrupt.npz", ENV_ID, "not a readable npz"),
        ("project.npz", "Hopper-v4", "observations have 4 dims, Hopper-v4 has 11"),
        ("no/such/minari-v0", ENV_ID, "datasets are not downloaded"),
        ("project.npz", "NoSuchEnv-v0", "cannot make environment"),
    ]


class Evil:
    def __reduce__(self):
        return (print, ("this pickle ran code",))


def test_bad_input_is_one_line_and_writes_nothing(episodes, tmp_path, minari_root, capsys):
    write_project_npz(tmp_path, episodes)
    for name, env_id, message in bad_sources(tmp_path, episodes):
        src = name if name.startswith("no/") else str(tmp_path / name)
        with pytest.raises(SystemExit) as e:
            demos.main(["convert", src, "--env-id", env_id, "--out", str(tmp_path / "out" / "x.npz")])
        text = str(e.value.code)
        assert text.startswith("error: ") and "\n" not in text and message in text, (name, text)
        assert not (tmp_path / "out").exists(), name
    assert "this pickle ran code" not in capsys.readouterr().out


def test_existing_output_is_kept_without_force(episodes, tmp_path):
    src, _ = write_project_npz(tmp_path, episodes)
    (tmp_path / "out.npz").write_bytes(b"keep me")
    with pytest.raises(SystemExit, match="exists; pass --force"):
        convert(src, tmp_path / "out.npz")
    assert (tmp_path / "out.npz").read_bytes() == b"keep me"
    convert(src, tmp_path / "out.npz", "--force")
    assert_same(load(tmp_path / "out.npz")[0], flat(episodes))


def test_info_refuses_a_file_without_metadata(episodes, tmp_path):
    src, _ = write_common_npz(tmp_path, episodes)
    with pytest.raises(SystemExit, match="not a project file .* python demos.py convert"):
        demos.main(["info", src])


# ---------------------------------------------------------------- the normalized score's zero


@pytest.mark.parametrize("env_id", ["InvertedPendulum-v4", "Pendulum-v1"])
def test_random_return_is_the_scripts_evaluation_protocol(env_id):
    """demos.py writes the scripts' own random_return (uniform actions, evaluate()'s seeds) into the metadata."""
    import gail

    value = demos.random_return(env_id)
    assert value == gail.random_return(env_id)
    assert (-1500 < value < -900) if env_id == "Pendulum-v1" else (0 < value < 30)  # Pendulum's rewards are negative


def test_scripts_and_report_normalise_alike():
    import sweep
    import gail

    for ret, random, expert in [(-496.0, -1200.0, -170.0), (-280.0, -276.7, 5034.9), (2683.3, 19.0, 3168.0),
                                (5.0, 5.0, 5.0), (1.0, None, 3.0), (1.0, 2.0, None)]:
        assert gail.normalized_score(ret, random, expert) == sweep.normalized_score(ret, random, expert)
    assert gail.normalized_score(-496.0, -1200.0, -170.0) == pytest.approx(704 / 1030)  # not 2.91 "x expert"


def test_a_file_without_the_random_return_gets_it_measured_on_loading(tmp_path, capsys):
    import gail

    with np.load(ROOT / "experts/InvertedPendulum-v4.npz") as f:
        data = {k: f[k] for k in f.files}
    meta = json.loads(str(data.pop("metadata")))
    del meta["random_return"]
    np.savez(tmp_path / "old.npz", **data, metadata=np.array(json.dumps(meta)))
    loaded = gail.load_demonstrations(str(tmp_path / "old.npz"), gail.make_env("InvertedPendulum-v4", 0), 2)
    assert loaded["metadata"]["random_return"] == gail.random_return("InvertedPendulum-v4")
    assert "no random-policy return in its metadata" in capsys.readouterr().out


def test_info_adds_the_random_return(tmp_path):
    path = tmp_path / "copy.npz"
    path.write_bytes((ROOT / "experts/InvertedPendulum-v4.npz").read_bytes())
    out = run_script("demos.py", "info", str(path), "--add-random-return", cwd=tmp_path).stdout
    assert "random policy's return:" in out
    with np.load(path) as f:
        assert json.loads(str(f["metadata"]))["random_return"] == demos.random_return("InvertedPendulum-v4")
