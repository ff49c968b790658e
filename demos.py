"""Bring your own demonstrations: convert the formats researchers have into the project's npz.

    python demos.py convert SRC --env-id ENV [--out experts/ENV.npz] [--format auto] [--actions-unit env]
    python demos.py info FILE [--check] [--add-random-return]

SRC is one of (`--format auto` tells them apart by extension, content and layout):
  npz      a plain .npz of arrays with common key names: observations|obs|states, actions|acts,
           next_observations|next_obs|next_states, rewards|rews, terminals|terminations,
           timeouts|truncations, dones, episode_lengths|lengths (all optional but observations)
  pickle   a pickled dict of arrays with the same names (.pkl); IQ-Learn's expert pickles
           (dict of per-trajectory tuples: states, next_states, actions, rewards, dones, lengths) are
           recognised by their layout
  d4rl     a D4RL-style .hdf5: observations, actions, rewards, terminals, timeouts[, next_observations]
  minari   a Minari dataset present locally, by id (looked up under $MINARI_DATASETS_PATH or
           ~/.minari/datasets) or by path; never downloaded
  imitation  imitation's saved trajectories: its .npz (obs, acts, terminal, indices[, rews]) or, with
           the `datasets` library installed, its HuggingFace datasets directory

How episodes are built (one function, `build_episodes`, for every format):
  - Boundaries come from episode lengths where the source has them, else from terminals | timeouts;
    rows after the last flagged end form a final episode that was cut (a truncation).
  - A `dones` flag that mixes time limits with terminations (IQ-Learn, imitation, plain `dones`
    without `timeouts`) counts as a truncation when the episode is exactly the env's
    max_episode_steps long, and as a termination otherwise.
  - Without next observations, s' of a row is the next row's observation within its episode. The
    last row of every episode then has no known s' (after a time limit or a termination alike: the
    source's next row is the next episode's reset), so it is dropped and the shortened episode ends
    as a truncation. The summary says how many rows were dropped.
  - Without rewards, rewards and returns are NaN. Without actions the file is state-only: it has no
    `actions` key, for the state-only methods (gaifo.py, bco.py, rile.py and drail_disc.py --state-only).

The metadata also records the return of uniform random actions on the env (`random_return`, 10 episodes under
the scripts' evaluation protocol), the zero of every normalized score: (R - random) / (expert - random).

Before writing, the data are checked against `gym.make(ENV)`: observation and action dims, actions
inside the action box (`--actions-unit normalized` rescales [-1, 1] actions, as IQ-Learn stores
them), finite values, and for MuJoCo envs a replay: the simulator state is set from the first
observation (only where the env's own observation of that state reproduces it), the first actions
are stepped and the env's next observations and rewards compared with the data's. Any failure is a
one-line error and nothing is written. Pickles are unpickled with an allow-list (numpy arrays,
lists, dicts, tuples): a pickle that needs anything else is refused, not executed.
Details, with one example per format: docs/demonstrations.md
"""

import argparse
import json
import os
import pickle
import shlex
import sys
import tempfile
import time
import zipfile

import gymnasium as gym
import numpy as np

ALIASES = {  # common name -> key names found in the wild, first match wins
    "obs": ("observations", "obs", "states"),
    "actions": ("actions", "acts"),
    "next_obs": ("next_observations", "next_obs", "next_states"),
    "rewards": ("rewards", "rews"),
    "terminals": ("terminals", "terminations"),
    "timeouts": ("timeouts", "truncations"),
    "dones": ("dones",),
    "lengths": ("episode_lengths", "lengths"),
}
FORMATS = ("auto", "npz", "pickle", "d4rl", "minari", "imitation")
REPLAY_STEPS = 10
# relative error allowed in the replay. From a reset it is ~1e-7; from mid-episode rows, rewards differ by up to
# ~1% (Ant): after mj_step the body positions the env measures progress from are one substep old, which a state
# set from an observation cannot recreate. Wrong envs, action units or misaligned rows are far off.
REPLAY_TOL = 0.02


def fail(message: str):
    raise SystemExit(f"error: {message}")


# ---------------------------------------------------------------- readers
# Each returns the transitions flat, episodes concatenated, under the common names of ALIASES
# (`obs` required, every other key optional), plus "format" and an optional "dones_ambiguous".


def read_arrays(arrays: dict, src: str, fmt: str) -> dict:
    raw = {"format": fmt}
    for name, keys in ALIASES.items():
        key = next((k for k in keys if k in arrays), None)
        if key is not None:
            try:
                raw[name] = np.asarray(arrays[key])
            except (ValueError, TypeError) as e:
                fail(f"{src}: key '{key}' is not an array ({type(e).__name__})")
    if "obs" not in raw:
        fail(f"{src} has no observations (looked for {'/'.join(ALIASES['obs'])}; it has {sorted(arrays)})")
    if "dones" in raw:  # dones = terminations | time limits: split by `timeouts` when given
        if "timeouts" in raw and raw["timeouts"].shape != raw["dones"].shape:
            fail(f"{src}: dones has shape {raw['dones'].shape}, timeouts {raw['timeouts'].shape}")
        if "timeouts" in raw:
            raw.setdefault("terminals", raw["dones"].astype(bool) & ~raw["timeouts"].astype(bool))
        elif "terminals" not in raw:
            raw["terminals"], raw["dones_ambiguous"] = raw["dones"], True
    return raw


def read_npz(path: str) -> dict:
    with np.load(path, allow_pickle=False) as f:
        if "acts" in f.files and "indices" in f.files:
            return read_imitation_npz(f, path)
        raw = read_arrays({k: f[k] for k in f.files if k != "metadata"}, path, "npz")
        if "metadata" in f.files:  # a project file (re-checked, or for another env version): keep its story
            try:
                raw["source_metadata"] = json.loads(str(f["metadata"]))
            except ValueError:
                raw["source_metadata"] = str(f["metadata"])
        return raw


PICKLE_ALLOWED = frozenset(
    {("collections", "defaultdict"), ("collections", "OrderedDict"), ("numpy", "ndarray"), ("numpy", "dtype"),
     ("numpy.core.multiarray", "_reconstruct"), ("numpy.core.multiarray", "scalar"),
     ("numpy._core.multiarray", "_reconstruct"), ("numpy._core.multiarray", "scalar"),
     ("_codecs", "encode")}  # how protocols 0-2 store bytes
    | {(m, n) for m in ("builtins", "__builtin__")  # __builtin__: protocols 0-2
       for n in ("list", "dict", "tuple", "set", "int", "float", "bool", "complex")})


class AllowListUnpickler(pickle.Unpickler):
    """Unpickles numpy arrays and scalars and plain containers only; anything else is refused."""

    def find_class(self, module, name):
        if (module, name) in PICKLE_ALLOWED or (module == "numpy.dtypes" and name.endswith("DType")):
            return super().find_class(module, name)
        hint = (" (pickled imitation Trajectory objects: load them with imitation and save them with "
                "imitation.data.serialize.save)" if module.startswith("imitation") else "")
        fail(f"the pickle holds a {module}.{name} object; only dicts of arrays or lists are read{hint}")


def read_pickle(path: str) -> dict:
    try:
        with open(path, "rb") as f:
            data = AllowListUnpickler(f).load()
    except (pickle.UnpicklingError, EOFError, ValueError, TypeError, AttributeError) as e:
        fail(f"{path} is not a readable pickle ({type(e).__name__}: {e})")
    if not isinstance(data, dict):
        fail(f"{path} holds a pickled {type(data).__name__}, not a dict of arrays")
    if "lengths" in data and "states" in data and isinstance(data["states"], (list, tuple)):
        return read_iqlearn(data, path)
    return read_arrays(data, path, "pickle")


def from_episodes(episodes: list, fmt: str, dones_ambiguous: bool = False) -> dict:
    """Flatten episodes given as dicts with obs (T+1 rows: the final observation included), actions,
    rewards (each T rows, optional), terminal and truncated flags of the episode's end."""
    raw = {"format": fmt, "dones_ambiguous": dones_ambiguous}
    raw["obs"] = np.concatenate([np.asarray(e["obs"])[:-1] for e in episodes])
    raw["next_obs"] = np.concatenate([np.asarray(e["obs"])[1:] for e in episodes])
    raw["lengths"] = np.array([len(e["obs"]) - 1 for e in episodes])
    for name in ("actions", "rewards"):
        if all(e.get(name) is not None for e in episodes):
            raw[name] = np.concatenate([np.asarray(e[name]) for e in episodes])
    ends = np.cumsum(raw["lengths"]) - 1
    for name, flag in (("terminals", "terminal"), ("timeouts", "truncated")):
        raw[name] = np.zeros(len(raw["obs"]), bool)
        raw[name][ends] = [bool(e.get(flag, False)) for e in episodes]
    return raw


def read_iqlearn(data: dict, src: str) -> dict:
    """IQ-Learn's expert pickle (ALGORITHMS.md 2.1): per trajectory, tuples of states, next_states,
    actions, rewards, dones; `dones` is also True at the time limit."""
    missing = [k for k in ("states", "next_states", "actions", "dones", "lengths") if k not in data]
    if missing:
        fail(f"{src} looks like an IQ-Learn pickle but lacks {missing}")
    episodes = []
    for i, length in enumerate(data["lengths"]):
        states, next_states = np.asarray(data["states"][i]), np.asarray(data["next_states"][i])
        if len(states) != length or len(next_states) != length:
            fail(f"{src}: trajectory {i} has {len(states)} states, {len(next_states)} next_states, length {length}")
        rewards = data["rewards"][i] if "rewards" in data else None
        episodes.append({"obs": np.concatenate([states, next_states[-1:]]), "actions": np.asarray(data["actions"][i]),
                         "rewards": rewards, "terminal": bool(data["dones"][i][-1])})
        if not np.allclose(next_states[:-1], states[1:]):
            fail(f"{src}: trajectory {i}'s next_states are not its states shifted by one step")
    return from_episodes(episodes, "iqlearn", dones_ambiguous=True)


def read_d4rl(path: str) -> dict:
    import h5py

    try:
        with h5py.File(path, "r") as f:
            arrays = {k: f[k][()] for k in f if isinstance(f[k], h5py.Dataset)}
    except OSError as e:
        fail(f"{path} is not a readable HDF5 file ({e})")
    return read_arrays(arrays, path, "d4rl")


def read_minari(src: str) -> dict:
    try:
        import minari
    except ImportError:
        fail("reading Minari datasets needs minari: pip install 'minari[hdf5]'")
    root = os.environ.get("MINARI_DATASETS_PATH", os.path.join(os.path.expanduser("~"), ".minari", "datasets"))
    candidates = [os.path.join(src, "data"), src, os.path.join(root, src, "data")]
    data_dir = next((c for c in candidates if os.path.isfile(os.path.join(c, "metadata.json"))), None)
    if data_dir is None:
        fail(f"no file or local Minari dataset '{src}' (looked in {root}); datasets are not downloaded: "
             f"run `minari download {src}` where there is a network, or pass the dataset's path")
    dataset = minari.MinariDataset(data_dir)
    episodes = [{"obs": ep.observations, "actions": ep.actions, "rewards": ep.rewards,
                 "terminal": ep.terminations[-1], "truncated": ep.truncations[-1]}
                for ep in dataset.iterate_episodes()]
    if not episodes or not all(isinstance(e["obs"], np.ndarray) for e in episodes):
        fail(f"Minari dataset '{src}' is empty or has dict/tuple observations (flatten them first)")
    raw = from_episodes(episodes, "minari")
    spec = dataset.spec.env_spec
    raw["source_env_id"] = spec.id if spec is not None else None
    return raw


def read_imitation_npz(f, src: str) -> dict:
    """imitation's npz (imitation.data.types.save before 0.4): obs of every trajectory concatenated with
    its final observation (T+1 rows each), acts, `indices` = cumulative lengths but the last, one
    `terminal` flag per trajectory (an ended episode, time limit or not), rews when saved."""
    indices, terminal = f["indices"], f["terminal"]
    obs = np.split(f["obs"], indices + np.arange(1, len(indices) + 1))
    acts = np.split(f["acts"], indices)
    rews = np.split(f["rews"], indices) if "rews" in f.files else [None] * len(acts)
    if len(obs) != len(terminal) or any(len(o) != len(a) + 1 for o, a in zip(obs, acts)):
        fail(f"{src}: obs, acts and indices disagree (each trajectory needs one more obs than acts)")
    episodes = [{"obs": o, "actions": a, "rewards": r, "terminal": t} for o, a, r, t in zip(obs, acts, rews, terminal)]
    return from_episodes(episodes, "imitation", dones_ambiguous=True)


def read_imitation_hf(path: str) -> dict:
    """imitation's current format (imitation.data.serialize.save): a HuggingFace datasets directory,
    one row per trajectory with obs (T+1), acts, infos, terminal[, rews]."""
    try:
        import datasets
    except ImportError:
        fail(f"{path} is a HuggingFace datasets directory (imitation >= 0.4); reading it needs: pip install datasets")
    dataset = datasets.load_from_disk(path).with_format("numpy")
    episodes = [{"obs": row["obs"], "actions": row["acts"], "rewards": row.get("rews"), "terminal": row["terminal"]}
                for row in dataset]
    return from_episodes(episodes, "imitation", dones_ambiguous=True)


def read_source(src: str, fmt: str) -> dict:
    if fmt == "minari" or (fmt == "auto" and not os.path.exists(src)):
        return read_minari(src)
    if not os.path.exists(src):
        fail(f"no such file: {src}")
    if os.path.isdir(src):
        if fmt in ("auto", "imitation") and os.path.isfile(os.path.join(src, "dataset_info.json")):
            return read_imitation_hf(src)
        if fmt != "auto":
            fail(f"{src} is a directory, not a {fmt} file")
        return read_minari(src)
    ext = os.path.splitext(src)[1].lower()
    if fmt == "d4rl" or (fmt == "auto" and ext in (".hdf5", ".h5")):
        return read_d4rl(src)
    if fmt == "pickle" or (fmt == "auto" and ext in (".pkl", ".pickle")):
        return read_pickle(src)
    try:
        return read_npz(src)
    except (OSError, ValueError, zipfile.BadZipFile) as e:
        fail(f"{src} is not a readable npz ({type(e).__name__}: {e}); pass --format if it is another format")


# ---------------------------------------------------------------- episodes


def build_episodes(raw: dict, max_steps) -> tuple[dict, list]:
    """The project's arrays from a reader's flat dict (rules in the module docstring); also notes."""
    obs = raw["obs"]
    n = len(obs)
    if obs.ndim != 2 or not np.issubdtype(obs.dtype, np.number):
        fail(f"observations must be a 2-D numeric array (transitions x dims), got shape {obs.shape} {obs.dtype}")
    for name in ("actions", "next_obs", "rewards", "terminals", "timeouts", "dones"):
        if name in raw and len(raw[name]) != n:
            fail(f"{name} has {len(raw[name])} rows, observations {n}")
    terminals = raw.get("terminals", np.zeros(n)).astype(bool).reshape(n)
    timeouts = raw.get("timeouts", np.zeros(n)).astype(bool).reshape(n)
    if "lengths" in raw:
        lengths = np.asarray(raw["lengths"], dtype=np.int64)
        if lengths.sum() != n or (lengths <= 0).any():
            fail(f"episode lengths sum to {lengths.sum()} (or hold a zero), observations have {n} rows")
    else:
        ends = np.flatnonzero(terminals | timeouts) + 1
        if len(ends) == 0 or ends[-1] != n:
            ends = np.append(ends, n)
        lengths = np.diff(ends, prepend=0)
    episode = np.repeat(np.arange(len(lengths)), lengths)
    is_end = np.zeros(n, bool)
    is_end[np.cumsum(lengths) - 1] = True
    if ((terminals | timeouts) & ~is_end).any():
        fail(f"terminal/timeout flags inside episodes (row {np.flatnonzero((terminals | timeouts) & ~is_end)[0]}) "
             f"disagree with the episode lengths")
    notes = []
    if raw.get("dones_ambiguous"):  # a done at exactly the time limit is a truncation (never without a limit)
        at_limit = is_end & terminals & (lengths[episode] == max_steps)
        terminals, timeouts = terminals & ~at_limit, timeouts | at_limit
        notes.append(f"`dones` mix terminations and time limits: episodes that end at the env's limit of {max_steps} "
                     f"steps read as truncated ({int(at_limit.sum())}), the others as terminated "
                     f"({int((is_end & terminals).sum())})")
    timeouts |= is_end & ~terminals  # an end that is neither was cut: a truncation
    keep = np.ones(n, bool)
    if "next_obs" in raw:
        next_obs = raw["next_obs"]
    else:
        next_obs = np.concatenate([obs[1:], obs[-1:]])
        keep &= ~is_end
        notes.append(f"no next observations: s' taken from the next row; the last transition of each episode "
                     f"({int(is_end.sum())} rows, with {int((is_end & terminals).sum())} terminations) dropped, "
                     f"its episode ending as a truncation; returns count the kept rows only")
        timeouts, terminals = np.roll(is_end, -1) & ~is_end, np.zeros(n, bool)
    new_lengths = np.bincount(episode[keep], minlength=len(lengths))
    if (new_lengths == 0).any():
        notes.append(f"{int((new_lengths == 0).sum())} one-step episodes left empty and removed")
    new_lengths = new_lengths[new_lengths > 0]
    if len(new_lengths) == 0:
        fail("no transitions left (every episode is one step long and has no next observation)")
    demos = {"observations": obs[keep], "next_observations": next_obs[keep]}
    if "actions" in raw:
        demos["actions"] = raw["actions"][keep].reshape(int(keep.sum()), -1)
    rewards = raw["rewards"].reshape(n) if "rewards" in raw else np.full(n, np.nan)
    demos["rewards"] = rewards[keep]
    demos = {k: np.asarray(v, dtype=np.float32) for k, v in demos.items()}
    demos["terminations"], demos["truncations"] = terminals[keep], timeouts[keep]
    demos["episode_lengths"] = new_lengths.astype(np.int64)
    demos["episode_starts"] = (np.cumsum(new_lengths) - new_lengths).astype(np.int64)
    demos["episode_returns"] = np.add.reduceat(demos["rewards"].astype(np.float64), demos["episode_starts"])
    return demos, notes


# ---------------------------------------------------------------- checks


def check(demos: dict, env: gym.Env, skip_replay: bool = False) -> list:
    """Dims, action box, finiteness, replay against `env`; a list of what was checked, or a one-line error."""
    env_id = env.spec.id
    obs_dim, act_dim = env.observation_space.shape[0], env.action_space.shape[0]
    if demos["observations"].shape[1] != obs_dim:
        fail(f"observations have {demos['observations'].shape[1]} dims, {env_id} has {obs_dim}: wrong --env-id?")
    for k in ("observations", "next_observations", "actions"):
        if k in demos and not np.isfinite(demos[k]).all():
            fail(f"{k} hold NaN or inf values")
    done = [f"obs dim {obs_dim} matches {env_id}"]
    if "actions" not in demos:
        return done + ["state-only: no action checks; replay skipped: no actions"]
    actions, low, high = demos["actions"], env.action_space.low, env.action_space.high
    if actions.shape[1] != act_dim:
        fail(f"actions have {actions.shape[1]} dims, {env_id} has {act_dim}: wrong --env-id?")
    tol = 1e-4 * (high - low) + 1e-6
    if (actions < low - tol).any() or (actions > high + tol).any():
        fail(f"actions span [{actions.min():.3g}, {actions.max():.3g}], outside {env_id}'s action box "
             f"[{low.min():.3g}, {high.max():.3g}]; if they are in [-1, 1] units, pass --actions-unit normalized")
    done.append(f"act dim {act_dim} matches, actions inside the action box")
    return done + [replay(demos, env) if not skip_replay else "replay skipped: --skip-replay"]


def replay(demos: dict, env: gym.Env) -> str:
    """Set the simulator to the first observation, step the first actions, compare with the data."""
    sim = env.unwrapped
    if not hasattr(sim, "set_state") or not hasattr(sim, "_get_obs"):
        return f"replay skipped: {env.spec.id} is not a MuJoCo env whose state can be set"
    env.reset(seed=0)
    nq, nv, obs0 = sim.model.nq, sim.model.nv, demos["observations"][0].astype(np.float64)
    for hidden in (0, 1, 2):  # positions left out of the observation (x, or x and y): dynamics ignore them
        if len(obs0) >= nq - hidden + nv:
            qpos = np.concatenate([sim.init_qpos[:hidden], obs0[:nq - hidden]])
            qvel = obs0[nq - hidden:nq - hidden + nv]
            sim.set_state(qpos, qvel)
            if np.allclose(sim._get_obs(), obs0, rtol=1e-5, atol=1e-5):
                break
    else:
        return "replay skipped: the first observation does not determine the simulator state (qpos, qvel)"
    steps = min(REPLAY_STEPS, int(demos["episode_lengths"][0]))
    obs_err = rew_err = 0.0
    for t in range(steps):
        next_obs, reward, terminated, _, _ = env.step(demos["actions"][t])
        want = demos["next_observations"][t]
        obs_err = max(obs_err, float(np.max(np.abs(next_obs - want) / (1 + np.abs(want)))))
        if not np.isnan(demos["rewards"][t]):
            rew_err = max(rew_err, abs(reward - float(demos["rewards"][t])) / (1 + abs(reward)))
        if obs_err > REPLAY_TOL or rew_err > REPLAY_TOL or terminated != demos["terminations"][t]:
            fail(f"replay: step {t} of the first episode on {env.spec.id} does not reproduce the data (relative error "
                 f"obs {obs_err:.2g}, reward {rew_err:.2g}, terminated {terminated}): wrong env or version? "
                 f"--skip-replay writes the file anyway")
    what = "next observations and rewards" if not np.isnan(demos["rewards"][0]) else "next observations"
    error = max(obs_err, rew_err)
    return f"replay: {steps} steps of the first episode reproduce its {what} (max relative error {error:.1g})"


def random_return(env_id: str, num_episodes: int = 10, seed: int = 100_000) -> float:
    """The mean return of uniform random actions under the scripts' evaluation protocol (episode i reset with
    seed + i, the action space seeded with seed): where a normalized score reads 0. The scripts' own
    `random_return` gives the same number (tests/test_demos.py)."""
    env = gym.make(env_id)
    env.action_space.seed(seed)
    returns = []
    for i in range(num_episodes):
        env.reset(seed=seed + i)
        done, total = False, 0.0
        while not done:
            _, reward, terminated, truncated, _ = env.step(env.action_space.sample())
            total, done = total + float(reward), terminated or truncated
        returns.append(total)
    env.close()
    return float(np.mean(returns))


# ---------------------------------------------------------------- writing and summary


def write(path: str, demos: dict, metadata: dict) -> None:
    """Compressed, written to a temporary file first: a failure leaves nothing behind."""
    folder = os.path.dirname(os.path.abspath(path))
    os.makedirs(folder, exist_ok=True)
    fd, tmp = tempfile.mkstemp(suffix=".tmp", dir=folder)
    try:
        with os.fdopen(fd, "wb") as f:
            np.savez_compressed(f, **demos, metadata=np.array(json.dumps(metadata)))
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)  # as open() would have made it (mkstemp makes it private)
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.remove(tmp)


def summary(path: str, demos: dict, meta: dict) -> str:
    lengths, returns = demos["episode_lengths"], demos["episode_returns"]
    ends = demos["episode_starts"] + lengths - 1
    kind = "state-only (no actions)" if "actions" not in demos else "with actions"
    lines = [f"{path}: {meta.get('env_id')}, {len(lengths)} episodes, {int(lengths.sum())} transitions, {kind}",
             (f"  lengths: min {lengths.min()}, mean {lengths.mean():.1f}, max {lengths.max()}; "
              f"{int(demos['terminations'][ends].sum())} end in a termination, "
              f"{int((demos['truncations'][ends] & ~demos['terminations'][ends]).sum())} in a truncation")]
    if np.isnan(returns).any():
        lines.append("  returns: none (the source has no rewards)")
    else:
        lines.append(f"  return: mean {returns.mean():.1f} +- {returns.std():.1f}, min {returns.min():.1f}, "
                     f"max {returns.max():.1f}")
    if "random_return" in meta:
        lines.append(f"  random policy's return: {meta['random_return']:.1f} (uniform actions, 10 episodes)")
    else:
        lines.append("  random policy's return: not recorded (the scripts measure it on loading; "
                     "`demos.py info FILE --add-random-return` stores it)")
    if "source" in meta:
        lines.append(f"  source: {meta['source']['format']} {meta['source']['path']}")
    lines += [f"  note: {n}" for n in meta.get("notes", [])] + [f"  check: {c}" for c in meta.get("checks", [])]
    return "\n".join(lines)


def load_project_file(path: str) -> tuple[dict, dict]:
    try:
        with np.load(path, allow_pickle=False) as f:
            demos = {k: f[k] for k in f.files}
    except (OSError, ValueError, zipfile.BadZipFile) as e:
        fail(f"{path} is not a readable npz ({type(e).__name__}: {e})")
    if "metadata" not in demos:
        fail(f"{path} is not a project file (no metadata key); convert it: python demos.py convert {path} --env-id ENV")
    missing = [k for k in ("observations", "episode_lengths", "episode_starts", "episode_returns",
                           "terminations", "truncations") if k not in demos]
    if missing:
        fail(f"{path} lacks {missing}")
    return demos, json.loads(str(demos.pop("metadata")))


# ---------------------------------------------------------------- commands


def convert(args, argv) -> None:
    out = args.out or os.path.join("experts", f"{args.env_id}.npz")
    if os.path.exists(out) and not args.force:
        fail(f"{out} exists; pass --force to replace it or --out to write elsewhere")
    try:
        env = gym.make(args.env_id)
    except (gym.error.Error, ImportError) as e:
        fail(f"cannot make environment '{args.env_id}' ({e})")
    if not isinstance(env.action_space, gym.spaces.Box) or not isinstance(env.observation_space, gym.spaces.Box):
        fail(f"'{args.env_id}' needs Box observation and action spaces")
    raw = read_source(args.src, args.format)
    demos, notes = build_episodes(raw, env.spec.max_episode_steps)
    if args.actions_unit == "normalized" and "actions" in demos:
        low, high = env.action_space.low, env.action_space.high
        if np.abs(demos["actions"]).max() > 1 + 1e-6:
            fail(f"--actions-unit normalized, but actions reach {np.abs(demos['actions']).max():.3g} outside [-1, 1]")
        demos["actions"] = (low + (demos["actions"] + 1) / 2 * (high - low)).astype(np.float32)
        notes.append("actions rescaled from [-1, 1] to the env's action box (--actions-unit normalized)")
    if raw.get("source_env_id") not in (None, args.env_id):
        notes.append(f"the source was recorded on {raw['source_env_id']}, converted for {args.env_id}")
    checks = check(demos, env, args.skip_replay)
    returns = demos["episode_returns"]
    import mujoco

    metadata = {
        "env_id": args.env_id, "source": {"format": raw["format"], "path": os.path.abspath(args.src)},
        "converted_by": "python " + shlex.join(argv), "state_only": "actions" not in demos,
        "num_episodes": len(returns), "selection": "every episode of the source, in the source's order",
        "actions": "env units (the env's action box), as sent to env.step" if "actions" in demos else "none",
        "notes": notes, "checks": checks, "gymnasium_version": gym.__version__, "mujoco_version": mujoco.__version__,
        "created": time.strftime("%Y-%m-%dT%H:%M:%S%z"), "random_return": random_return(args.env_id),
    }
    if "source_metadata" in raw:
        metadata["source_metadata"] = raw["source_metadata"]
    if not np.isnan(returns).any():
        metadata.update(return_mean=float(returns.mean()), return_std=float(returns.std()),
                        return_min=float(returns.min()), return_max=float(returns.max()))
    write(out, demos, metadata)
    print(summary(out, demos, metadata))


def info(args) -> None:
    demos, meta = load_project_file(args.file)
    if args.check:
        try:
            env = gym.make(meta.get("env_id"))
        except (gym.error.Error, ImportError) as e:
            fail(f"cannot make the file's environment '{meta.get('env_id')}' ({e})")
        meta["checks"] = check(demos, env)
    if args.add_random_return:
        meta["random_return"] = random_return(meta.get("env_id"))
        write(args.file, demos, meta)
    print(summary(args.file, demos, meta))


def main(argv=None) -> None:
    argv = sys.argv if argv is None else ["demos.py", *argv]
    parser = argparse.ArgumentParser(prog="demos.py", description=__doc__.split("\n")[0])
    commands = parser.add_subparsers(dest="command", required=True)
    p = commands.add_parser("convert", help="write the project's npz from another format, checked against the env")
    p.add_argument("src", help="file, directory, or local Minari dataset id")
    p.add_argument("--env-id", required=True, help="the gymnasium env the demonstrations belong to")
    p.add_argument("--out", help="output path (default experts/<env-id>.npz)")
    p.add_argument("--format", choices=FORMATS, default="auto", help="source format (default: guessed)")
    p.add_argument("--actions-unit", choices=("env", "normalized"), default="env",
                   help="'normalized': the source's actions are in [-1, 1] and are rescaled to the env's box")
    p.add_argument("--skip-replay", action="store_true", help="write even if replaying the first steps disagrees")
    p.add_argument("--force", action="store_true", help="replace an existing output file")
    p = commands.add_parser("info", help="summarise a project demonstration file")
    p.add_argument("file")
    p.add_argument("--check", action="store_true", help="also check the file against its env (dims, box, replay)")
    p.add_argument("--add-random-return", action="store_true",
                   help="measure the random policy's return on the file's env and store it in the file's metadata")
    args = parser.parse_args(argv[1:])
    convert(args, argv) if args.command == "convert" else info(args)


if __name__ == "__main__":
    main()
