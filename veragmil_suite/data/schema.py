"""The demonstration file: robomimic's HDF5 schema as we write it, its checks, masks and provenance.

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

"""

from __future__ import annotations

import datetime
import errno
import json
import platform
import re
import subprocess
from importlib.metadata import version
from pathlib import Path
from typing import Any

import h5py
import mujoco
import numpy as np
import robosuite

import veragmil_suite
from veragmil_suite.models.foods import DEFAULT_PHYSICS, with_recorded_physics
from veragmil_suite.utils.canonical import canonical
from veragmil_suite.utils.numbers import is_number, is_whole

ENV_NAME = "ScoopGranular"
ROBOSUITE_ENV_TYPE = 1  # robomimic's EnvType.ROBOSUITE_TYPE
# the writer files name (data.attrs["writer"]): a format's name, not a module path, so files of every version append
WRITER = "veragmil_suite.recording"
FORMAT_VERSION = 1
# how each demo's first step starts (the "start" attribute of data and of each demo): where the env's reset put the
# arm, its controllers aimed there (ScoopGranular.hold_restored_pose), as an evaluated episode starts. Files recorded
# before 2026-12-01 (9f84426) name none: their first step pulled the arm toward the noise-free start pose.
DEMO_START = "held where the reset put the arm"
EARLIER_START = "pulled toward the noise-free start pose"
DEMO_PREFIX = "demo_"
# where a file of an in-place writer holds a demo its killed writer never finished: the root group PENDING_GROUP,
# or a data/ group under _PENDING_PREFIX; removed at the next write or by veragmil-dataset-info --clean
PENDING_GROUP = "incomplete"
_PENDING_PREFIX = "incomplete_"
IMAGE_COMPRESSION = dict(compression="gzip", compression_opts=4, shuffle=True)
# the key of data's env_args that lists the env_kwargs its demos differ in (env_kwargs_variants)
VARIANTS_KEY = "env_kwargs_variants"
# env_kwargs every demo of one dataset shares: they fix the action and observation spaces, and the physics
COMPATIBLE_KWARGS = (
    "robots",
    "controller_configs",
    "control_freq",
    "camera_names",
    "camera_heights",
    "camera_widths",
    "physics",
)
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


def incompatible_kwargs(theirs: dict, ours: dict) -> list[str]:
    """The COMPATIBLE_KWARGS in which two recordings' env_kwargs differ (metadata that names no physics was recorded
    on PRE_CALIBRATION_PHYSICS)."""
    theirs, ours = with_recorded_physics(theirs), with_recorded_physics(ours)
    return [k for k in COMPATIBLE_KWARGS if canonical(theirs.get(k)) != canonical(ours.get(k))]


def demo_names(f: h5py.File) -> list[str]:
    """Finished demos of an open dataset, in numeric order."""
    names = [n for n in f["data"].keys() if re.fullmatch(DEMO_PREFIX + r"\d+", n)]
    return sorted(names, key=lambda n: int(n[len(DEMO_PREFIX) :]))


def filter_key_demos(f: h5py.File, filter_key: str, where: str | Path | None = None) -> list[str]:
    """The demo names robomimic's filter key ``filter_key`` (``mask/<key>``) lists, in its order; ``where`` names
    the file in a refusal (a working copy's own name would mean nothing to the user).

    Raises:
        DatasetError: [the file has no such filter key; the message lists those it has]
    """
    keys = sorted(f["mask"]) if isinstance(f.get("mask"), h5py.Group) else []
    if filter_key not in keys:
        have = ", ".join(keys) or "none"
        raise DatasetError(f"{where or f.filename} has no filter key {filter_key!r}; its filter keys: {have}")
    return [x.decode() if isinstance(x, bytes) else str(x) for x in f["mask"][filter_key][()]]


def missing_observations(path: str | Path, keys: list[str]) -> list[str]:
    """Those of ``keys`` that some demo of the robomimic dataset at ``path`` holds no observations of (none when the
    file cannot be read: the dataset's own checks name that)."""
    try:
        with h5py.File(path, "r") as f:
            held = [set(g["obs"].keys()) if "obs" in g else set() for g in (f["data"][n] for n in demo_names(f))]
    except (OSError, KeyError, AttributeError):  # not HDF5, no data group, obs not a group
        return []
    return [key for key in dict.fromkeys(keys) if any(key not in obs for obs in held)]


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


def demo_start(attrs: h5py.AttributeManager | dict) -> str:
    """How the demos of a file (its data group's attributes) or one demo (its attributes) start: DEMO_START, or
    EARLIER_START for those recorded before the attribute was written."""
    return attr_text(attrs.get("start", EARLIER_START))


def provenance(device: str, operator: str, food: str, robot: str, **extra: Any) -> dict:
    """Who and what made the demonstrations: device, operator, food, robot, how each demo starts, software
    versions, date."""
    out = dict(
        device=device,
        operator=operator,
        food=food,
        robot=robot,
        start=DEMO_START,
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
        {k for kwargs in per_demo for k in {*kwargs, *ours} if canonical(kwargs.get(k)) != canonical(ours.get(k))}
    )
    variants: dict[str, dict] = {}
    for kwargs in per_demo:
        values = {k: kwargs.get(k) for k in keys}
        entry = variants.setdefault(canonical(values), dict(env_kwargs=values, demos=0))
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


def check_valid_ratio(valid_ratio: float) -> float:
    """The share of demos in mask/valid: a number in [0, 1). DatasetError otherwise."""
    if not (is_number(valid_ratio) and 0 <= valid_ratio < 1):
        raise DatasetError(f"the validation ratio must lie in [0, 1), got {valid_ratio!r}")
    return float(valid_ratio)


def split_demos(names: list[str], valid_ratio: float, seed: int = 0) -> tuple[list[str], list[str]]:
    """Train and valid demo names: a seeded shuffle, at least one valid demo once there are two."""
    check_valid_ratio(valid_ratio)
    if not is_whole(seed) or seed < 0:
        raise DatasetError(f"the split's seed must be a non-negative integer, got {seed!r}")
    n = len(names)
    n_valid = int(round(n * valid_ratio))
    if valid_ratio > 0 and n >= 2:
        n_valid = min(max(n_valid, 1), n - 1)
    order = np.random.default_rng(seed).permutation(n)
    valid = set(order[:n_valid].tolist())
    return [x for i, x in enumerate(names) if i not in valid], [x for i, x in enumerate(names) if i in valid]


def attr_text(value: bytes | str) -> str:
    """An HDF5 attribute as text (h5py gives bytes or str)."""
    return value.decode() if isinstance(value, bytes) else str(value)


def _first_line(e: BaseException) -> str:
    text = str(e).strip()
    return text.splitlines()[0] if text else type(e).__name__


def _version(module: str) -> str:
    try:
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
