"""Demonstrations in robomimic's HDF5 schema, written directly, one episode at a time.

One file layout, defined here and nowhere else (robomimic's, plus our provenance)::

    data                      attrs: env_args (robomimic env meta, JSON), total, provenance (see DemoWriter)
      demo_N                  attrs: num_samples, model_file, env_args, provenance and the episode's metrics
        actions (T, 6)        OSC_POSE deltas within the controller's input range ([-1, 1]), T >= 1
        states (T, S)         flattened MuJoCo state *before* each action (robomimic's convention)
        rewards (T,), dones (T,)   dones: 1 where the next state is a success, and at the last step
        obs/<key>, next_obs/<key>  robomimic's observation dict: robot0_* proprioception, ``object`` (robosuite's
                                   object-state), the task's object keys one by one, camera images upright
    mask/train, mask/valid, mask/<food>, mask/success   robomimic filter keys (demo names)

Each demo's env_args are those it was recorded with; ``data``'s are the first recording's, plus, once demos of
another food, grain count or other env_kwargs are appended or merged in, ``env_kwargs_variants``
(:func:`env_kwargs_variants`): what differs between the demos, and how many demos have each.

Every change to a file is atomic (veragmil_suite.data.safe_hdf5): an episode is written into a working copy that
replaces the file once complete, so killing the collecting process at any instant, a full disk or an I/O error
leaves every episode written before readable; a DemoWriter holds the file's write lock for its whole session, so
a second writer is refused before it records. Appending continues the numbering. Recording starts from
robomimic's ``reset_to(get_state())`` (:func:`veragmil_suite.learning.robomimic_obs.restart_from_current_state`), so
replaying the actions open loop reproduces the recorded states exactly; observations and model XML come from
veragmil_suite.learning.robomimic_obs.
"""

from __future__ import annotations

import contextlib
import datetime
import errno
import json
import platform
import re
import signal
import subprocess
import threading
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

import h5py
import mujoco
import numpy as np
import robosuite

import veragmil_suite
from veragmil_suite.data import safe_hdf5
from veragmil_suite.environments.scoop import StageTracker
from veragmil_suite.learning import robomimic_obs
from veragmil_suite.models.foods import DEFAULT_PHYSICS

ENV_NAME = "ScoopGranular"
ROBOSUITE_ENV_TYPE = 1  # robomimic's EnvType.ROBOSUITE_TYPE
# the writer files name (data.attrs["writer"]): a format's name, not a module path, so files of every version append
WRITER = "veragmil_suite.recording"
FORMAT_VERSION = 1
DEMO_PREFIX = "demo_"
# where older versions wrote a demo before moving it into data/ (a kill left it there): a root group, and before
# that data/ under this prefix; what they left is removed at the next write or by veragmil-dataset-info --clean
PENDING_GROUP = "incomplete"
_PENDING_PREFIX = "incomplete_"
IMAGE_COMPRESSION = dict(compression="gzip", compression_opts=4, shuffle=True)
# the key of data's env_args that lists the env_kwargs its demos differ in (env_kwargs_variants)
VARIANTS_KEY = "env_kwargs_variants"
# env_kwargs that must agree for demos to share a file: they fix the action and observation spaces
COMPATIBLE_KWARGS = ("robots", "controller_configs", "control_freq", "camera_names", "camera_heights", "camera_widths")
METRIC_KEYS = (
    "success",
    "grains_in_spoon",
    "grains_spilled",
    "spilled_volume_cm3",
    "spill_fraction",
    "scooped_volume_cm3",
    "spoon_volume_cm3",
    "spoon_mass_g",
    "spilled_mass_g",
    "completion_time_s",
    "physics_error",
    "stage",
)


class DatasetError(ValueError):
    """A file that is not a ScoopGranular dataset, is corrupt, or does not match what is written to it."""


class DamagedDataset(DatasetError):
    """A ScoopGranular dataset with a part that does not read or is not a valid demo: veragmil-dataset-info --clean
    rebuilds it from the demos that do (veragmil_suite.data.datasets.salvage_dataset)."""


SALVAGE_HINT = "veragmil-dataset-info --clean keeps the demos that still read"


# ---------------------------------------------------------------------------------------------------------------- #
# Environment metadata                                                                                             #
# ---------------------------------------------------------------------------------------------------------------- #


def env_meta(env_kwargs: dict) -> dict:
    """robomimic's env metadata (``data`` attribute ``env_args``) for ScoopGranular made with ``env_kwargs``.

    ``env_kwargs`` are the keyword arguments given to ``robosuite.make`` besides the env name (robomimic passes
    them back to it); they must be JSON-serializable (a catalog food name, not a FoodSpec).
    """
    kwargs = {k: v for k, v in env_kwargs.items() if k not in ("env_name", "seed")}
    kwargs.setdefault("physics", DEFAULT_PHYSICS)  # stored by name, so a later default cannot change it
    try:
        json.dumps(kwargs)
    except TypeError as e:
        raise DatasetError(f"env_kwargs must be JSON-serializable to be stored in the dataset: {e}") from None
    return dict(env_name=ENV_NAME, env_version=robosuite.__version__, type=ROBOSUITE_ENV_TYPE, env_kwargs=kwargs)


# ---------------------------------------------------------------------------------------------------------------- #
# Recording one episode                                                                                            #
# ---------------------------------------------------------------------------------------------------------------- #


@dataclass
class Episode:
    """One recorded episode, robomimic arrays plus what replays it."""

    actions: np.ndarray
    states: np.ndarray
    rewards: np.ndarray
    dones: np.ndarray
    obs: dict
    next_obs: dict
    model_file: str
    metrics: dict
    attrs: dict = field(default_factory=dict)
    executed_actions: np.ndarray | None = None  # when not the actions stored for learning (injected noise)
    action_bounds: tuple[np.ndarray, np.ndarray] | None = None  # the env's action space (low, high), when known

    @property
    def num_samples(self) -> int:
        return int(self.actions.shape[0])


class EpisodeRecorder:
    """
    Steps a ScoopGranular env and keeps what the dataset needs: the state before each action, the action, reward,
    observations before and after, and the final metrics.

    Args:
        env (ScoopGranular): the environment to record
    """

    def __init__(self, env):
        self.env = env
        self._clear()

    def _clear(self):
        self._states, self._actions, self._rewards, self._successes = [], [], [], []
        self._executed = []
        self._obs, self._next_obs = [], []
        self._info = {}
        self._stages = StageTracker()
        self.model_file = None
        self.obs = None
        self._converted = None

    def reset(self, seed: int | None = None) -> dict:
        """Reset the env (seeded first when ``seed`` is given) and restart it as playback will; returns robosuite's
        observation."""
        self._clear()
        self.env.reset(seed=seed)
        raw, self.model_file = robomimic_obs.restart_from_current_state(self.env)
        self.obs = raw
        self._converted = robomimic_obs.observation(self.env, raw)
        return raw

    def step(self, action: np.ndarray, label: np.ndarray | None = None):
        """
        env.step(action), recorded. Returns (obs, reward, done, info), obs that of the state reached.

        An action outside the env's action space is clipped to it before it is executed, as the controller clips
        its input: what is executed and stored is what the robot applied. ``label`` is the action stored for
        learning when it is not the one executed (injected noise), clipped alike: the executed one is kept as well,
        in executed_actions, so the demo still replays. A non-finite action is not executed (env.step ends the
        episode with a physics_error that says why) and not stored; the episode's metrics carry that error.
        """
        if self.obs is None:
            raise RuntimeError("EpisodeRecorder.reset() must come before step()")
        if label is not None and not np.isfinite(np.asarray(label, dtype=np.float64)).all():
            raise ValueError(f"non-finite action label {np.asarray(label).tolist()}: labels must be finite numbers")
        action = self._clipped(action)
        stored = action if label is None else self._clipped(label)
        state = self.env.sim.get_state().flatten()
        raw, reward, done, info = self.env.step(action)
        if not np.isfinite(action).all():
            self._info = info  # not executed, not stored: the episode ends here, and its metrics say why
            return raw, reward, done, info
        after = robomimic_obs.observation(self.env, raw)
        self._states.append(state)
        self._executed.append(action.copy())
        self._actions.append(stored.copy())
        self._rewards.append(float(reward))
        self._successes.append(bool(info.get("success", False)))
        self._obs.append(self._converted)
        self._next_obs.append(after)
        self._info = info
        self._stages.update(info)
        self.obs, self._converted = raw, after
        return raw, reward, done, info

    def _clipped(self, action) -> np.ndarray:
        """``action`` within the env's action space (one of another size is left to env.step to refuse)."""
        action = np.asarray(action, dtype=np.float64)
        low, high = self.env.action_spec
        if action.shape != np.shape(low) or not np.isfinite(action).all():
            return action  # env.step refuses it, or ends the episode saying why
        return np.clip(action, low, high)

    @property
    def num_steps(self) -> int:
        return len(self._actions)

    def episode(self, attrs: dict | None = None) -> Episode:
        """The episode so far, as arrays (robomimic's done_mode 2: done at success and at the end)."""
        if not self._actions:
            raise RuntimeError("no steps recorded")
        dones = np.array(self._successes, dtype=np.int64)
        dones[-1] = 1
        actions, executed = np.stack(self._actions), np.stack(self._executed)
        return Episode(
            actions=actions,
            executed_actions=None if np.array_equal(actions, executed) else executed,
            states=np.stack(self._states),
            rewards=np.array(self._rewards, dtype=np.float64),
            dones=dones,
            obs={k: np.stack([o[k] for o in self._obs]) for k in self._obs[0]},
            next_obs={k: np.stack([o[k] for o in self._next_obs]) for k in self._next_obs[0]},
            model_file=self.model_file,
            metrics=episode_metrics(self._info, self._stages.stage),
            attrs=dict(attrs or {}),
            action_bounds=tuple(np.asarray(b, dtype=np.float64) for b in self.env.action_spec),
        )


def episode_metrics(info: dict, stage: str) -> dict:
    """The paper's per-episode metrics from the last step's info (success, spilled pieces and volume, time), and
    the furthest stage the episode reached (environments.scoop.StageTracker)."""
    out = {"stage": str(stage)}
    for key in METRIC_KEYS:
        if key == "stage":
            continue
        value = info.get(key, "" if key == "physics_error" else 0)
        if isinstance(value, (bool, np.bool_)):
            out[key] = bool(value)
        elif isinstance(value, (int, np.integer)):
            out[key] = int(value)
        elif isinstance(value, (float, np.floating)):
            out[key] = float(value)
        else:
            out[key] = str(value)
    return out


# ---------------------------------------------------------------------------------------------------------------- #
# The file                                                                                                         #
# ---------------------------------------------------------------------------------------------------------------- #


def demo_names(f: h5py.File) -> list[str]:
    """Finished demos of an open dataset, in numeric order."""
    names = [n for n in f["data"].keys() if re.fullmatch(DEMO_PREFIX + r"\d+", n)]
    return sorted(names, key=lambda n: int(n[len(DEMO_PREFIX) :]))


def open_dataset(path: str | Path, mode: str = "r") -> h5py.File:
    """Open a ScoopGranular dataset, with a clear error for anything else.

    Raises:
        DatasetError: [missing file, not HDF5 or corrupt, not a robomimic dataset, another env, a damaged demo]
    """
    path = Path(path)
    if path.is_dir():
        raise DatasetError(f"{path}: is a directory, not a dataset file")
    if not path.is_file():
        raise DatasetError(f"{path}: no such file")
    try:
        f = h5py.File(path, mode)
    except OSError as e:
        if e.errno == errno.EAGAIN or "unable to lock file" in str(e):
            raise DatasetError(
                f"{path} is in use by another process, which holds it open for writing ({_first_line(e)})"
            ) from None
        raise DatasetError(
            f"{path} cannot be read as HDF5: it is corrupt, truncated, or not an HDF5 file ({_first_line(e)})"
        ) from None
    try:
        check_schema(f, path)
    except BaseException:
        f.close()
        raise
    return f


def check_schema(f: h5py.File, path: str | Path = "") -> dict:
    """Check that an open file is a ScoopGranular robomimic dataset; returns its env metadata."""
    where = str(path or f.filename)
    try:
        data = f.get("data")
        if not isinstance(data, h5py.Group) or "env_args" not in data.attrs:
            raise DatasetError(
                f"{where} is an HDF5 file but not a robomimic dataset (no 'data' group with an 'env_args' attribute)"
            )
        try:
            meta = json.loads(data.attrs["env_args"])
        except (TypeError, ValueError):
            raise DatasetError(f"{where}: data/env_args is not JSON") from None
        if meta.get("env_name") != ENV_NAME:
            raise DatasetError(
                f"{where} holds demonstrations of {meta.get('env_name')!r}, not {ENV_NAME}: "
                "not a veragmil_suite dataset"
            )
        for name in demo_names(f):
            check_demo(data[name], f"{where}:data/{name}")
        for key in f.get("mask", {}):
            f["mask"][key][()]  # robomimic reads its filter keys
    except DamagedDataset as e:
        raise DamagedDataset(f"{e}; {SALVAGE_HINT}") from None
    except (OSError, KeyError, RuntimeError) as e:
        raise DamagedDataset(f"{where} is damaged ({_first_line(e)}); {SALVAGE_HINT}") from None
    return meta


def check_demo(g: h5py.Group, where: str) -> None:
    """Refuse a stored demo that is incomplete, empty, has non-finite actions or arrays of other lengths.

    Raises:
        DamagedDataset: [naming what is wrong]
    """
    for key in ("actions", "states", "rewards", "dones"):
        if not isinstance(g.get(key), h5py.Dataset):
            raise DamagedDataset(f"{where} is incomplete: no {key!r} dataset")
    n = g["actions"].shape[0]
    if "num_samples" not in g.attrs or int(g.attrs["num_samples"]) != n or "model_file" not in g.attrs:
        raise DamagedDataset(f"{where} is incomplete: num_samples or model_file missing or wrong")
    if n == 0:
        raise DamagedDataset(f"{where} has no steps: a demo holds at least one transition")
    if not np.isfinite(g["actions"][()]).all():
        raise DamagedDataset(f"{where} has non-finite actions")
    for key in ("states", "rewards", "dones"):
        if g[key].shape[0] != n:
            raise DamagedDataset(f"{where}: {key} has {g[key].shape[0]} steps, actions {n}")
    for group in ("obs", "next_obs"):
        for k, d in g.get(group, {}).items():
            if d.shape[0] != n:
                raise DamagedDataset(f"{where}: {group}/{k} has {d.shape[0]} steps, actions {n}")


def provenance(device: str, operator: str, food: str, robot: str, **extra) -> dict:
    """Who and what made the demonstrations: device, operator, food, robot, software versions, date."""
    out = dict(
        device=device,
        operator=operator,
        food=food,
        robot=robot,
        mujoco_version=mujoco.__version__,
        robosuite_version=robosuite.__version__,
        robomimic_version=_version("robomimic"),
        veragmil_suite_version=veragmil_suite.__version__,
        veragmil_suite_commit=_git_commit(),
        numpy_version=np.__version__,
        python_version=platform.python_version(),
        date=datetime.datetime.now().astimezone().isoformat(timespec="seconds"),
    )
    out.update(extra)
    return out


class DemoWriter:
    """
    Writes episodes to a robomimic-schema HDF5 file, each one in one atomic change of the file (safe_hdf5), holding
    the file's write lock from construction to close().

    Args:
        path (str or Path): the file; appended to if it exists (numbering continues), else created with the first
            episode written or discarded (a collection that fails to start leaves nothing behind)
        env_meta (dict): robomimic env metadata of the env recorded (:func:`env_meta`)
        provenance (dict): attributes stored with the file and every demo (:func:`provenance`): device, operator,
            food, robot, versions, date, ...
        valid_ratio (float): fraction of demos in mask/valid (the split is redone at every write)

    Raises:
        DatasetError: [the file is in use by another process, is not a ScoopGranular dataset of ours, is corrupt,
            or its env differs; its folder cannot be written]
    """

    def __init__(self, path: str | Path, env_meta: dict, provenance: dict, valid_ratio: float = 0.1):
        if not 0 <= valid_ratio < 1:
            raise ValueError(f"valid_ratio must lie in [0, 1), got {valid_ratio!r}")
        self.path = Path(path)
        self.env_meta = env_meta
        self.provenance = dict(provenance)
        self.valid_ratio = valid_ratio
        self.written: list[str] = []  # demos written by this writer, in order
        self.seeds_used: set[int] = set()  # env seeds of the file's attempts, kept or discarded
        self.next_index = 0
        self._lock = safe_hdf5.FileLock(self.path)
        self._made_folders = [p for p in (self.path.parent, *self.path.parent.parents) if not p.exists()]
        try:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            self._lock.acquire()
            if self.path.exists():
                with open_dataset(self.path) as f:
                    self._check_appendable(f)
                    self.next_index = self._next_index(f)
                    self.seeds_used = seeds_used(f)
        except (safe_hdf5.FileInUse, safe_hdf5.WriteFailed) as e:
            self.close()
            raise DatasetError(str(e)) from None
        except OSError as e:
            self.close()
            raise DatasetError(f"{self.path}: cannot make its folder ({e.strerror or e})") from None
        except BaseException:
            self.close()
            raise

    def close(self) -> None:
        """Release the file's write lock (and remove the folders made for a file that was never written)."""
        self._lock.release()
        if not self.path.exists():
            for folder in self._made_folders:
                with contextlib.suppress(OSError):
                    folder.rmdir()

    def __enter__(self) -> DemoWriter:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    @contextlib.contextmanager
    def _update(self) -> Iterator[h5py.File]:
        """The file open for one atomic change (created with its file attributes when new), Ctrl-C held."""
        safe_hdf5.remove_working_copies(self.path)  # what writes killed before this session left
        with _deferred_sigint(), updated_file(self.path, lock=self._lock) as working:
            f = working.file
            if "data" not in f:
                data = f.create_group("data")
                data.attrs["env_args"] = json.dumps(self.env_meta, indent=4)
                data.attrs["total"] = 0
                data.attrs["writer"] = WRITER
                data.attrs["format_version"] = FORMAT_VERSION
                for key, value in self.provenance.items():
                    data.attrs[key] = _attr(value)
                data.attrs["attempts"] = "[]"
            remove_interrupted_writes(f)
            yield f

    def _check_appendable(self, f: h5py.File) -> None:
        data = f["data"]
        if data.attrs.get("writer") != WRITER:
            raise DatasetError(
                f"{self.path} is a robomimic dataset not written by veragmil_suite: refusing to append to it"
            )
        theirs = json.loads(data.attrs["env_args"])["env_kwargs"]
        ours = self.env_meta["env_kwargs"]
        differ = [k for k in COMPATIBLE_KWARGS if _canonical(theirs.get(k)) != _canonical(ours.get(k))]
        if differ:
            raise DatasetError(
                f"{self.path} was recorded with other {', '.join(differ)} "
                f"({', '.join(f'{k}={theirs.get(k)!r}' for k in differ if k != 'controller_configs')}): "
                "write to a new file instead"
            )

    @staticmethod
    def _next_index(f: h5py.File) -> int:
        names = demo_names(f)
        return int(names[-1][len(DEMO_PREFIX) :]) + 1 if names else 0

    @property
    def num_demos(self) -> int:
        if not self.path.exists():
            return 0
        with open_dataset(self.path) as f:
            return len(demo_names(f))

    def write(self, episode: Episode) -> str:
        """
        Append one episode as the next demo_N in one atomic change of the file; returns the demo's name.

        Raises:
            DatasetError: [the episode is not a valid demo (check_episode), its observations differ from the
                file's, or the disk refused the write: the file is then as it was]
        """
        check_episode(episode, self.env_meta, where=f"{self.path}: the episode")
        name = f"{DEMO_PREFIX}{self.next_index}"
        with self._update() as f:
            data = f["data"]
            first = demo_names(f)[:1]
            if first:
                self._check_same_obs(data[first[0]], episode)
            g = data.create_group(name)
            g.create_dataset("actions", data=episode.actions)
            if episode.executed_actions is not None:
                g.create_dataset("executed_actions", data=episode.executed_actions)
            g.create_dataset("states", data=episode.states, compression="gzip", compression_opts=4, shuffle=True)
            g.create_dataset("rewards", data=episode.rewards)
            g.create_dataset("dones", data=episode.dones)
            for group_name, obs in (("obs", episode.obs), ("next_obs", episode.next_obs)):
                og = g.create_group(group_name)
                for key, value in obs.items():
                    options = IMAGE_COMPRESSION if value.ndim >= 3 else {}
                    og.create_dataset(key, data=value, **options)
            g.attrs["model_file"] = episode.model_file
            g.attrs["env_args"] = json.dumps(self.env_meta)
            for key, value in {**self.provenance, **episode.attrs, **episode.metrics}.items():
                g.attrs[key] = _attr(value)
            g.attrs["num_samples"] = episode.num_samples
            self._log(data, dict(demo=name, kept=True, **episode.attrs, **episode.metrics))
            refresh_summary(f, self.valid_ratio)
        self.next_index += 1
        self.written.append(name)
        return name

    def log_discarded(self, metrics: dict, attrs: dict | None = None) -> None:
        """Store the metrics of an episode the operator discarded (success rates must count every attempt)."""
        with self._update() as f:
            self._log(f["data"], dict(demo=None, kept=False, **(attrs or {}), **metrics))
            if "mask" not in f:
                refresh_summary(f, self.valid_ratio)

    def _log(self, data: h5py.Group, entry: dict) -> None:
        attempts = json.loads(data.attrs.get("attempts", "[]"))
        attempts.append({k: _jsonable(v) for k, v in {**_short_provenance(self.provenance), **entry}.items()})
        data.attrs["attempts"] = json.dumps(attempts)

    def _check_same_obs(self, first: h5py.Group, episode: Episode) -> None:
        theirs = {k: first["obs"][k].shape[1:] for k in first["obs"]}
        ours = {k: v.shape[1:] for k, v in episode.obs.items()}
        if theirs != ours:
            raise DatasetError(
                f"{self.path}: this episode's observations differ from the file's "
                f"(file: {sorted(theirs.items())}; episode: {sorted(ours.items())})"
            )


@contextlib.contextmanager
def updated_file(
    path: str | Path, new: bool = False, lock: safe_hdf5.FileLock | None = None
) -> Iterator[safe_hdf5.WorkingCopy]:
    """
    ``path`` open for one atomic change (safe_hdf5.replaced; with ``new``, written anew): the one way a dataset
    file is written; the WorkingCopy's ``file`` is the h5py File. A change that raises, and a disk that refuses a
    write, leave the file as it was.

    Raises:
        DatasetError: [the file is in use by another process, or the disk refused the write]
    """
    try:
        with safe_hdf5.replaced(path, new=new, lock=lock) as working:
            yield working
    except (safe_hdf5.FileInUse, safe_hdf5.WriteFailed) as e:
        raise DatasetError(str(e)) from None


@contextlib.contextmanager
def write_lock(path: str | Path) -> Iterator[safe_hdf5.FileLock]:
    """The write lock of ``path``, held for the block (several changes, or cleaning beside the file).

    Raises:
        DatasetError: [another process writes the file, or its folder cannot be written]
    """
    lock = safe_hdf5.FileLock(path)
    try:
        lock.acquire()
    except (safe_hdf5.FileInUse, safe_hdf5.WriteFailed) as e:
        raise DatasetError(str(e)) from None
    try:
        yield lock
    finally:
        lock.release()


def check_episode(episode: Episode, env_meta: dict | None = None, where: str = "the episode") -> None:
    """
    Refuse an episode that is not a valid demo: no steps, arrays of other lengths, non-finite actions, states or
    rewards, actions outside the action space (the episode's own, else that of ``env_meta``'s controller), or an
    episode that ended at a physics error without saying which.

    Raises:
        DatasetError: [naming what is wrong]
    """
    n = episode.num_samples
    if n < 1:
        raise DatasetError(f"{where} has no steps: a demo holds at least one transition")
    arrays = dict(states=episode.states, rewards=episode.rewards, dones=episode.dones)
    arrays.update({f"obs/{k}": v for k, v in episode.obs.items()})
    arrays.update({f"next_obs/{k}": v for k, v in episode.next_obs.items()})
    if episode.executed_actions is not None:
        arrays["executed_actions"] = episode.executed_actions
    for key, value in arrays.items():
        if len(value) != n:
            raise DatasetError(f"{where}: {key} has {len(value)} steps, actions {n}")
    for key in ("actions", "executed_actions", "states", "rewards"):
        value = getattr(episode, key)
        if value is not None and not np.isfinite(value).all():
            raise DatasetError(f"{where} has non-finite {key}")
    if episode.action_bounds is not None:
        low, high = episode.action_bounds
    else:
        limit = action_limit((env_meta or {}).get("env_kwargs", {}))
        low, high = -limit, limit
    for key in ("actions", "executed_actions"):
        value = getattr(episode, key)
        if value is not None and ((value < low).any() or (value > high).any()):
            raise DatasetError(
                f"{where} has {key} outside the action space ({np.min(low):g} to {np.max(high):g}): "
                f"{float(np.min(value)):g} to {float(np.max(value)):g}"
            )
    if episode.attrs.get("end_reason") == "physics" and not episode.metrics.get("physics_error"):
        raise DatasetError(f"{where} ended at a physics error but does not say which (empty physics_error)")


def action_limit(env_kwargs: dict) -> float:
    """The largest action magnitude the stored controller takes (its parts' input_max and input_min; 1 when it
    names none, robosuite's default)."""
    limits: list[float] = []

    def visit(node) -> None:
        if isinstance(node, dict):
            for key, value in node.items():
                if key in ("input_max", "input_min"):
                    with contextlib.suppress(TypeError, ValueError):
                        limits.extend(np.abs(np.asarray(value, dtype=np.float64)).ravel().tolist())
                else:
                    visit(value)

    visit(env_kwargs.get("controller_configs"))
    return max(limits, default=1.0)


def demo_problems(g: h5py.Group, limit: float) -> list[str]:
    """What is wrong with a stored demo that still reads (veragmil-dataset-info flags it): actions beyond the
    controller's ``limit``, or an end at a physics error that does not say which."""
    problems = []
    actions = g["actions"][()]
    if actions.size and np.abs(actions).max() > limit:
        problems.append(f"actions outside the action space (|a| up to {np.abs(actions).max():g}, limit {limit:g})")
    if _text(g.attrs.get("end_reason", "")) == "physics" and not _text(g.attrs.get("physics_error", "")):
        problems.append("ended at a physics error but its physics_error is empty")
    return problems


def interrupted_writes(f: h5py.File) -> list[str]:
    """Demos whose writing was interrupted (the writer killed): never part of the dataset, safe to remove."""
    pending = []
    if PENDING_GROUP in f:
        try:
            pending = [f"{PENDING_GROUP}/{name}" for name in f[PENDING_GROUP]] or [PENDING_GROUP]
        except (KeyError, OSError, RuntimeError):  # a kill left the group itself unreadable: it goes whole
            pending = [PENDING_GROUP]
    return pending + [f"data/{name}" for name in f["data"] if name.startswith(_PENDING_PREFIX)]


def remove_interrupted_writes(f: h5py.File) -> list[str]:
    """Delete what interrupted writes left (``interrupted_writes``); returns what was removed."""
    removed = interrupted_writes(f)
    if PENDING_GROUP in f:
        del f[PENDING_GROUP]
    for path in removed:
        if not path.startswith(PENDING_GROUP):
            del f[path]
    return removed


def seeds_used(f: h5py.File) -> set[int]:
    """The env seeds of a file's attempts: its demos' and its attempts log's (discarded attempts too)."""
    seeds = {int(f["data"][name].attrs["seed"]) for name in demo_names(f) if "seed" in f["data"][name].attrs}
    for attempt in json.loads(f["data"].attrs.get("attempts", "[]")):
        if attempt.get("seed") is not None:
            seeds.add(int(attempt["seed"]))
    return seeds


def refresh_summary(f: h5py.File, valid_ratio: float = 0.1, seed: int = 0) -> None:
    """Recompute what summarizes the demos: ``total``, the foods, devices and operators seen, the env_kwargs
    variants in ``env_args`` (:func:`env_kwargs_variants`), and the masks."""
    data = f["data"]
    names = demo_names(f)
    data.attrs["total"] = int(sum(int(data[n].attrs["num_samples"]) for n in names))
    for key in ("food", "device", "operator"):
        values = sorted({str(data[n].attrs.get(key, "")) for n in names} - {""})
        data.attrs[key + "s"] = json.dumps(values)
    meta = json.loads(data.attrs["env_args"])
    variants = env_kwargs_variants(f)
    if variants != meta.get(VARIANTS_KEY):
        if variants:
            meta[VARIANTS_KEY] = variants
        else:
            meta.pop(VARIANTS_KEY, None)
        data.attrs["env_args"] = json.dumps(meta, indent=4)
    write_masks(f, valid_ratio, seed)


def env_kwargs_variants(f: h5py.File) -> list[dict]:
    """
    The env_kwargs in which a file's demos differ from the file's env_args (each demo's own env_args; the file's
    for a demo without), one entry per combination, in the order of the demos:
    ``[{"env_kwargs": {"food": "rice", "n_grains": null}, "demos": 2}, ...]`` (null: not given, the default).
    Empty when every demo was recorded with the file's env_kwargs.
    """
    data = f["data"]
    ours = json.loads(data.attrs["env_args"]).get("env_kwargs", {})
    per_demo = [
        json.loads(data[n].attrs["env_args"]).get("env_kwargs", {}) if "env_args" in data[n].attrs else ours
        for n in demo_names(f)
    ]
    keys = sorted(
        {k for kwargs in per_demo for k in {*kwargs, *ours} if _canonical(kwargs.get(k)) != _canonical(ours.get(k))}
    )
    variants: dict[str, dict] = {}
    for kwargs in per_demo:
        values = {k: kwargs.get(k) for k in keys}
        entry = variants.setdefault(_canonical(values), dict(env_kwargs=values, demos=0))
        entry["demos"] += 1
    return list(variants.values()) if keys else []


def write_masks(f: h5py.File, valid_ratio: float = 0.1, seed: int = 0) -> dict[str, list[str]]:
    """(Re)write robomimic's filter keys: train/valid split, one per food, and the successful demos."""
    names = demo_names(f)
    masks = dict(zip(("train", "valid"), split_demos(names, valid_ratio, seed)))
    data = f["data"]
    for name in names:
        food = str(data[name].attrs.get("food", ""))
        if food:
            masks.setdefault(food, []).append(name)
        if bool(data[name].attrs.get("success", False)):
            masks.setdefault("success", []).append(name)
    masks.setdefault("success", [])
    if "mask" in f:
        del f["mask"]
    mask = f.create_group("mask")
    for key, members in masks.items():
        mask.create_dataset(key, data=np.array(members, dtype="S"))
    return masks


def split_demos(names: list[str], valid_ratio: float, seed: int = 0) -> tuple[list[str], list[str]]:
    """Train and valid demo names: a seeded shuffle, at least one valid demo once there are two."""
    n = len(names)
    n_valid = int(round(n * valid_ratio))
    if valid_ratio > 0 and n >= 2:
        n_valid = min(max(n_valid, 1), n - 1)
    order = np.random.default_rng(seed).permutation(n)
    valid = set(order[:n_valid].tolist())
    return [x for i, x in enumerate(names) if i not in valid], [x for i, x in enumerate(names) if i in valid]


# ---------------------------------------------------------------------------------------------------------------- #
# Helpers                                                                                                          #
# ---------------------------------------------------------------------------------------------------------------- #


@contextlib.contextmanager
def _deferred_sigint():
    """Hold Ctrl-C while an episode is written, so an interrupt cannot cut a write in half."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    caught = []
    previous = signal.signal(signal.SIGINT, lambda *args: caught.append(args))
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)
        if caught and callable(previous):
            previous(*caught[0])
        elif caught and previous != signal.SIG_IGN:
            raise KeyboardInterrupt


def _attr(value):
    if isinstance(value, (dict, list, tuple)):
        return json.dumps(value)
    if value is None:
        return ""
    return value


def _jsonable(value):
    if isinstance(value, (np.integer,)):
        return int(value)
    if isinstance(value, (np.floating,)):
        return float(value)
    if isinstance(value, np.bool_):
        return bool(value)
    return value


def _short_provenance(p: dict) -> dict:
    return {k: p[k] for k in ("device", "operator", "food") if k in p}


def _canonical(value) -> str:
    return json.dumps(value, sort_keys=True)


def _text(value) -> str:
    return value.decode() if isinstance(value, bytes) else str(value)


def _first_line(e: BaseException) -> str:
    text = str(e).strip()
    return text.splitlines()[0] if text else type(e).__name__


def _version(module: str) -> str:
    try:
        from importlib.metadata import version

        return version(module)
    except Exception:
        return ""


def _git_commit() -> str:
    try:
        root = Path(veragmil_suite.__file__).resolve().parent.parent
        out = subprocess.run(
            ["git", "-C", str(root), "rev-parse", "--short", "HEAD"], capture_output=True, text=True, timeout=5
        )
        return out.stdout.strip() if out.returncode == 0 else ""
    except (OSError, subprocess.SubprocessError):
        return ""
