"""
ScoopGranular demonstration files as a whole (robomimic's HDF5 schema, data.schema): what a file holds, merging,
train/valid splits, copies without no-op steps, cleaning after interrupted writes. The console programs of
veragmil_suite.scripts.dataset_tools print what these return.
"""

from __future__ import annotations

import hashlib
import json
from collections import Counter
from pathlib import Path

import h5py
import numpy as np

from veragmil_suite.data import safe_hdf5
from veragmil_suite.data.schema import (
    DamagedDataset,
    DatasetError,
    check_demo,
    check_valid_ratio,
    demo_names,
    demo_start,
    env_kwargs_variants,
    filter_key_demos,
    incompatible_kwargs,
    interrupted_writes,
    open_dataset,
    refresh_summary,
    remove_interrupted_writes,
    split_demos,
    write_masks,
)
from veragmil_suite.data.writer import action_limit, demo_problems, updated_file, write_lock
from veragmil_suite.utils.numbers import is_number
from veragmil_suite.utils.whole_files import same_file


def dataset_summary(path: str | Path) -> dict:
    """What a dataset holds: demos, lengths, foods, devices, success, spillage, obs keys, filter keys, provenance;
    what interrupted writes left (working copies beside it, or older versions' half-written demos in it), whether
    another process is writing it now, and the demos that read but are flagged (``demo_problems``)."""
    being_written = safe_hdf5.FileLock(path).in_use_elsewhere()
    with open_dataset(path) as f:
        data = f["data"]
        meta = json.loads(data.attrs["env_args"])
        kwargs = meta.get("env_kwargs", {})
        names = demo_names(f)
        limit = action_limit(kwargs)
        problems = {n: found for n in names if (found := demo_problems(data[n], limit))}
        control_freq = float(kwargs.get("control_freq", 20))
        lengths = np.array([int(data[n].attrs["num_samples"]) for n in names], dtype=int)
        demos = []
        for n in names:
            a = data[n].attrs
            demos.append(
                dict(
                    name=n,
                    steps=int(a["num_samples"]),
                    food=str(a.get("food", kwargs.get("food", ""))),
                    device=str(a.get("device", "")),
                    operator=str(a.get("operator", "")),
                    success=bool(a.get("success", False)) if "success" in a else None,
                    grains_spilled=int(a.get("grains_spilled", 0)),
                    spilled_volume_cm3=float(a.get("spilled_volume_cm3", 0.0)),
                    spill_fraction=float(a.get("spill_fraction", 0.0)),
                    completion_time_s=float(a.get("completion_time_s", 0.0)),
                )
            )
        obs_keys = {}
        if names:
            first = data[names[0]]
            obs_keys = {k: (list(d.shape[1:]), str(d.dtype)) for k, d in first.get("obs", {}).items()}
        masks = {k: len(f["mask"][k]) for k in f["mask"]} if "mask" in f else {}
        duplicates = _duplicate_demos(data, names)
        interrupted = interrupted_writes(f)
        if not being_written:
            interrupted += [p.name for p in safe_hdf5.working_copies(path)]
        attempts = json.loads(data.attrs.get("attempts", "[]"))
        variants = env_kwargs_variants(f)
        provenance = {k: _plain(data.attrs[k]) for k in data.attrs if k not in _SUMMARY_ATTRS}
    known = [d for d in demos if d["success"] is not None]
    success_times = [d["completion_time_s"] for d in known if d["success"]]
    per_food = {}
    for food in sorted({d["food"] for d in demos}):
        rows = [d for d in demos if d["food"] == food]
        ok = [d for d in rows if d["success"]]
        per_food[food] = dict(
            demos=len(rows),
            success=len(ok),
            mean_spilled=float(np.mean([d["grains_spilled"] for d in rows])),
            mean_spilled_cm3=float(np.mean([d["spilled_volume_cm3"] for d in rows])),
            mean_time_s=float(np.mean([d["completion_time_s"] for d in ok])) if ok else None,
        )
    return dict(
        path=str(path),
        env=dict(
            env_name=meta.get("env_name"),
            robot=kwargs.get("robots"),
            controller=_controller_name(kwargs.get("controller_configs")),
            control_freq=control_freq,
            horizon=kwargs.get("horizon"),
            cameras=kwargs.get("camera_names") if kwargs.get("use_camera_obs") else [],
            env_kwargs_variants=variants,
        ),
        demos=len(names),
        transitions=int(lengths.sum()),
        length_steps=dict(
            mean=float(lengths.mean()) if len(lengths) else 0.0,
            min=int(lengths.min()) if len(lengths) else 0,
            max=int(lengths.max()) if len(lengths) else 0,
        ),
        duration_s=float(lengths.sum() / control_freq),
        foods=dict(Counter(d["food"] for d in demos)),
        devices=dict(Counter(d["device"] for d in demos)),
        operators=dict(Counter(d["operator"] for d in demos)),
        success_rate=(sum(d["success"] for d in known) / len(known)) if known else None,
        attempts=len(attempts),
        attempt_success_rate=(sum(bool(a.get("success")) for a in attempts) / len(attempts)) if attempts else None,
        mean_grains_spilled=float(np.mean([d["grains_spilled"] for d in demos])) if demos else 0.0,
        mean_spilled_cm3=float(np.mean([d["spilled_volume_cm3"] for d in demos])) if demos else 0.0,
        mean_completion_time_s=float(np.mean(success_times)) if success_times else None,
        per_food=per_food,
        obs_keys=obs_keys,
        filter_keys=masks,
        duplicates=duplicates,
        interrupted_writes=interrupted,
        being_written=being_written,
        problems=problems,
        provenance=provenance,
        demo_list=demos,
    )


def _duplicate_demos(data, names: list[str]) -> list[list[str]]:
    """Groups of demos with identical actions from the same start state (one episode recorded twice: the same
    seed again). The first state stands for the rest: reading every state of a large file would take minutes."""
    groups: dict[str, list[str]] = {}
    for name in names:
        digest = hashlib.sha256(np.ascontiguousarray(data[name]["actions"][()]).tobytes())
        if "states" in data[name] and len(data[name]["states"]):
            digest.update(np.ascontiguousarray(data[name]["states"][0]).tobytes())
        groups.setdefault(digest.hexdigest(), []).append(name)
    return [group for group in groups.values() if len(group) > 1]


_SUMMARY_ATTRS = ("env_args", "attempts", "total", "foods", "devices", "operators", "merged_from")


def _controller_name(config) -> str:
    if not isinstance(config, dict):
        return str(config)
    part = config.get("body_parts", {}).get("right", config)
    return str(part.get("type", config.get("type", "")))


def _plain(value):
    if isinstance(value, bytes):
        return value.decode()
    if isinstance(value, np.generic):
        return value.item()
    return value


def merge_datasets(inputs: list[str | Path], output: str | Path, valid_ratio: float = 0.1) -> int:
    """Merge ``inputs`` into a new file ``output``; returns the number of demos. Each demo keeps its provenance.

    Raises:
        DatasetError: [an input is not a ScoopGranular dataset, or inputs differ in robot, controller, control
            rate, cameras or observation keys]
    """
    if isinstance(inputs, (str, Path)):
        raise DatasetError(f"inputs must be a list of dataset files, got one path: {inputs!r} (give [{inputs!r}])")
    check_valid_ratio(valid_ratio)
    output = Path(output)
    if any(same_file(i, output) for i in inputs):
        raise DatasetError(f"{output} is also an input: merge into a new file")
    first_meta, first_obs, attempts, sources = None, None, [], []
    with updated_file(output, new=True) as working:
        fout = working.file
        data_out = fout.create_group("data")
        index = 0
        for path in inputs:
            with open_dataset(path) as fin:
                data_in = fin["data"]
                meta = json.loads(data_in.attrs["env_args"])
                names = demo_names(fin)
                obs = {k: d.shape[1:] for k, d in data_in[names[0]]["obs"].items()} if names else None
                if first_meta is None:
                    first_meta = meta
                    for key, value in data_in.attrs.items():
                        data_out.attrs[key] = value
                else:
                    differ = incompatible_kwargs(meta["env_kwargs"], first_meta["env_kwargs"])
                    if differ:
                        raise DatasetError(f"{path} was recorded with other {', '.join(differ)} than {inputs[0]}")
                    if demo_start(data_in.attrs) != demo_start(data_out.attrs):
                        raise DatasetError(
                            f"{path}'s demos start otherwise than {inputs[0]}'s (their first step "
                            f"{demo_start(data_in.attrs)}, not {demo_start(data_out.attrs)}): "
                            "merge files recorded alike"
                        )
                if obs is not None:
                    if first_obs is None:
                        first_obs = obs
                    elif obs != first_obs:
                        raise DatasetError(f"{path} has other observation keys or shapes than the files before it")
                for name in names:
                    new = f"demo_{index}"
                    fin.copy(data_in[name], data_out, name=new)
                    g = data_out[new]
                    g.attrs["merged_from"] = f"{path}:{name}"
                    if "env_args" not in g.attrs:
                        g.attrs["env_args"] = json.dumps(meta)
                    if "food" not in g.attrs and "food" in meta["env_kwargs"]:
                        g.attrs["food"] = meta["env_kwargs"]["food"]
                    index += 1
                for entry in json.loads(data_in.attrs.get("attempts", "[]")):
                    attempts.append(dict(entry, source=str(path)))
                sources.append(str(path))
            working.check()
        if first_meta is None:
            raise DatasetError("no input files")
        data_out.attrs["attempts"] = json.dumps(attempts)
        data_out.attrs["merged_from"] = json.dumps(sources)
        refresh_summary(fout, valid_ratio)
    return index


def _storage_of(d: h5py.Dataset) -> dict:
    """How ``d`` is compressed, for a dataset written from it (camera images stay gzipped)."""
    return dict(compression=d.compression, compression_opts=d.compression_opts, shuffle=d.shuffle)


def noop_steps(actions: np.ndarray, threshold: float = 0.0) -> np.ndarray:
    """The steps whose every action component is at most ``threshold`` in magnitude (a boolean per step): a
    teleoperator's released input, which a policy would learn as holding still."""
    return np.abs(actions).reshape(len(actions), -1).max(axis=1, initial=0.0) <= threshold


def success_reward(data: h5py.Group) -> float | None:
    """The reward of a step at which the recorded task succeeds: robosuite's ``reward_scale`` of its env (1 when
    it names none, as robosuite's tasks default; None when it is not positive, so no step can be told)."""
    kwargs = json.loads(data.attrs.get("env_args", "{}")).get("env_kwargs", {})
    scale = kwargs.get("reward_scale", 1.0)
    scale = 1.0 if scale is None else float(scale)
    return scale if scale > 0 else None


def held_steps(rewards: np.ndarray, reward: float | None) -> np.ndarray:
    """The steps at which the task's success held (a boolean per step): a robosuite task's reward is ``reward``
    (its reward_scale) there and below it elsewhere, shaped or not."""
    rewards = np.asarray(rewards, dtype=float).reshape(-1)
    return np.zeros(len(rewards), bool) if reward is None else rewards >= reward * (1 - 1e-9)


def drop_noops(
    path: str | Path, output: str | Path, threshold: float = 0.0, keep_held: bool = False
) -> tuple[int, int, int, int]:
    """Copy a dataset without its no-op steps (``noop_steps``): every per-step array of a demo keeps the other
    steps, ``next_obs`` of a kept step becomes the observation of the next kept one (the demo's last ``next_obs``
    stays its own), and a demo of no-ops only is left out, of the masks too. Policies trained on teleoperated data
    with its pauses learn to stall where the operator paused; dropping the pauses is the usual cure (OpenVLA's
    LIBERO datasets). States stay valid states, but replaying the kept actions no longer reproduces them.

    With ``keep_held``, a no-op at which the task's success held (``held_steps``) is kept: holding still at the
    goal is what success asks there. Measured on the spacemouse data (results/grid_calibrated_spacemouse_held/),
    BC-RNN then fails the hold less often but loses more loads, and scores less on the seen foods: off by default.

    Returns:
        (demos kept, steps before, steps after, held no-op steps kept)
    """
    if not (is_number(threshold) and 0 <= threshold < 1):
        raise DatasetError(f"the no-op threshold must lie in [0, 1) (a fraction of full scale), got {threshold!r}")
    output = Path(output)
    if same_file(path, output):
        raise DatasetError(f"{output} is also the input: write the copy to a new file")
    before = after = 0
    with open_dataset(path) as fin, updated_file(output, new=True) as working:
        fout = working.file
        data_in, data_out = fin["data"], fout.create_group("data")
        data_out.attrs.update(data_in.attrs)
        names, kept_demos, held_kept = demo_names(fin), set(), 0
        reward = success_reward(data_in) if keep_held else None
        for name in names:
            g = data_in[name]
            check_demo(g, f"{path}:{name}")
            n = int(g.attrs["num_samples"])
            noop = noop_steps(g["actions"][()], threshold)
            held = noop & held_steps(g["rewards"][()], reward) if "rewards" in g else np.zeros(n, bool)
            keep = np.flatnonzero(~noop | held)
            before, after, held_kept = before + n, after + len(keep), held_kept + int(held.sum())
            if not len(keep):
                continue
            out = data_out.create_group(name)
            out.attrs.update(g.attrs)
            out.attrs["num_samples"] = len(keep)
            out.attrs["noop_steps_dropped"] = n - len(keep)
            out.attrs["held_noop_steps_kept"] = int(held.sum())
            for key, d in g.items():
                if isinstance(d, h5py.Dataset):
                    values = d[()][keep]
                    if key == "dones":
                        values[-1] = d[n - 1]  # the episode still ends where it ended
                    out.create_dataset(key, data=values, **_storage_of(d))
            obs = {key: d[()] for key, d in g["obs"].items()} if "obs" in g else {}
            for key, values in obs.items():
                out.create_dataset(f"obs/{key}", data=values[keep], **_storage_of(g["obs"][key]))
            for key, d in g.get("next_obs", {}).items():
                # a kept step's next observation is the next kept step's observation; the last keeps its own
                joined = np.concatenate([obs[key][keep[1:]], d[n - 1 : n]]) if key in obs else d[()][keep]
                out.create_dataset(f"next_obs/{key}", data=joined, **_storage_of(d))
            kept_demos.add(name)
            working.check()  # a full disk stops the copy at the demo it refused
        if "mask" in fin:
            masks = fout.create_group("mask")
            for key, d in fin["mask"].items():
                members = [m for m in d[()] if m.decode() in kept_demos]
                masks.create_dataset(key, data=np.array(members, dtype="S"))
        data_out.attrs["total"] = after
        data_out.attrs["noops_dropped"] = json.dumps(
            dict(
                source=str(path),
                threshold=threshold,
                keep_held=keep_held,
                held_noop_steps_kept=held_kept,
                steps_before=before,
                steps_after=after,
                demos=len(names),
                demos_kept=len(kept_demos),
            )
        )
    return len(kept_demos), before, after, held_kept


def split_dataset(path: str | Path, ratio: float, seed: int = 0, filter_key: str | None = None) -> tuple[int, int]:
    """Rewrite the train/valid masks of ``path`` (``<filter_key>_train/_valid`` within a filter key)."""
    check_valid_ratio(ratio)
    open_dataset(path).close()  # a clear error for a file that is not a dataset
    with updated_file(path) as working:
        f = working.file
        if filter_key is None:
            names, prefix = demo_names(f), ""
        else:
            names, prefix = filter_key_demos(f, filter_key, where=path), filter_key + "_"
        train, valid = split_demos(names, ratio, seed)
        if "mask" not in f:
            write_masks(f)
        for key, members in (("train", train), ("valid", valid)):
            if prefix + key in f["mask"]:
                del f["mask"][prefix + key]
            f["mask"].create_dataset(prefix + key, data=np.array(members, dtype="S"))
    return len(train), len(valid)


def clean_dataset(path: str | Path) -> list[str]:
    """
    Remove what interrupted writes left (never a finished demo that reads): working copies beside ``path``, the
    half-written demos older versions left in it, and, in a file damaged by a write cut short in place (older
    versions, other programs), whatever no longer reads: the file is then rebuilt from its complete demos
    (salvage_dataset). Returns what was removed.

    Raises:
        DatasetError: [not a dataset, in use by another process, or nothing of it can be read]
    """
    path = Path(path)
    if not path.is_file():
        open_dataset(path)  # the clear error for a missing file or a folder
    with write_lock(path) as lock:
        removed = [p.name for p in safe_hdf5.remove_working_copies(path)]
        try:
            with open_dataset(path) as f:
                inside = interrupted_writes(f)
            if inside:
                with updated_file(path, lock=lock) as working:
                    remove_interrupted_writes(working.file)
        except (DamagedDataset, KeyError, OSError, RuntimeError):
            inside = salvage_dataset(path, lock)
    return inside + removed


def salvage_dataset(path: str | Path, lock: safe_hdf5.FileLock) -> list[str]:
    """
    Rebuild ``path`` (its write lock ``lock`` held) from what still reads: the file's attributes, every demo that
    reads whole and passes the schema check, the filter keys that read (less the demos dropped), and the standard
    masks redone. Returns what was dropped.

    Raises:
        DatasetError: [the file's data group or its env_args cannot be read: nothing to salvage]
    """
    dropped = []
    try:
        fin = h5py.File(path, "r")
    except OSError as error:
        raise DatasetError(f"{path} cannot be read as HDF5 at all: nothing to salvage ({error})") from None
    with fin, updated_file(path, new=True, lock=lock) as working:
        fout = working.file
        try:
            data_in = fin["data"]
            names = demo_names(fin)
            json.loads(data_in.attrs["env_args"])
        except (KeyError, OSError, RuntimeError, TypeError, ValueError) as error:
            raise DatasetError(
                f"{path}: its data group or env_args cannot be read: nothing to salvage ({error})"
            ) from None
        data_out = fout.create_group("data")
        for key in data_in.attrs:
            try:
                data_out.attrs[key] = data_in.attrs[key]
            except (KeyError, OSError, RuntimeError):
                dropped.append(f"data attribute {key} (damaged)")
        kept = []
        for name in names:
            try:
                g = data_in[name]
                check_demo(g, name)
                g.visititems(lambda _, d: d[()] if isinstance(d, h5py.Dataset) else None)
                fin.copy(g, data_out, name=name)
                kept.append(name)
            except (DamagedDataset, KeyError, OSError, RuntimeError) as error:
                dropped.append(f"data/{name} ({str(error).removeprefix(name).strip(' :')})")
        dropped += [f"data/{n}" for n in data_in if n not in names] + [k for k in fin if k not in ("data", "mask")]
        masks = {}
        try:
            keys = list(fin["mask"]) if "mask" in fin else []
        except (KeyError, OSError, RuntimeError):
            keys = []
            dropped.append("mask (damaged)")
        for key in keys:
            try:
                masks[key] = [m for m in fin["mask"][key][()] if m.decode() in kept]
            except (KeyError, OSError, RuntimeError):
                dropped.append(f"mask/{key} (damaged)")
        ratio = len(masks.get("valid", [])) / max(1, len(masks.get("valid", [])) + len(masks.get("train", [])))
        refresh_summary(fout, ratio if masks.get("train") else 0.1)
        for key, members in masks.items():
            if key not in fout["mask"]:
                fout["mask"].create_dataset(key, data=np.array(members, dtype="S"))
    return dropped
