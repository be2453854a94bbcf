"""Writing demonstrations into a file (data.schema), one episode at a time.

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
import json
import signal
import threading
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from veragmil_suite.data import safe_hdf5
from veragmil_suite.data.recording import Episode
from veragmil_suite.data.schema import (
    DEMO_PREFIX,
    DEMO_START,
    FORMAT_VERSION,
    IMAGE_COMPRESSION,
    WRITER,
    DatasetError,
    attr_text,
    demo_names,
    demo_start,
    incompatible_kwargs,
    open_dataset,
    refresh_summary,
    remove_interrupted_writes,
    seeds_used,
)


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
        if demo_start(data.attrs) != DEMO_START:
            raise DatasetError(
                f"{self.path} holds demos whose first step {demo_start(data.attrs)} (recorded before 2026-12-01); "
                f"new demos start {DEMO_START}: write to a new file instead"
            )
        theirs = json.loads(data.attrs["env_args"])["env_kwargs"]
        ours = self.env_meta["env_kwargs"]
        differ = incompatible_kwargs(theirs, ours)
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

    def visit(node: Any) -> None:
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
    if attr_text(g.attrs.get("end_reason", "")) == "physics" and not attr_text(g.attrs.get("physics_error", "")):
        problems.append("ended at a physics error but its physics_error is empty")
    return problems


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
