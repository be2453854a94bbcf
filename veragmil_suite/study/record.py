"""The study's recording stage: one scripted dataset per profile and food, checked, then merged per profile with
a ``first<N>`` mask per demo count (smaller datasets are prefixes of larger ones), and, when the study asks, a copy
of the merged file without its no-op steps.
"""

from __future__ import annotations

import functools
import json
import os
from collections.abc import Callable
from pathlib import Path

import h5py

from veragmil_suite.data.collection import record_scripted, recording_env_kwargs
from veragmil_suite.data.datasets import drop_noops, merge_datasets
from veragmil_suite.data.schema import (
    DEMO_START,
    DatasetError,
    attr_text,
    demo_names,
    demo_start,
    open_dataset,
    seeds_used,
)
from veragmil_suite.data.writer import updated_file
from veragmil_suite.learning.observation_sets import WRENCH_OBSERVATIONS, needs_wrench
from veragmil_suite.models.foods import (
    DEFAULT_PHYSICS,
    FOODS,
    TRAINING_FOODS,
    UNSEEN_FOODS,
    get_food,
    with_recorded_physics,
)
from veragmil_suite.study.logged_run import RECORDING_PROGRESS, LogProgress, run_logged_call
from veragmil_suite.study.settings import FOOD_SEED_STRIDE, PipelineSettings, StageError
from veragmil_suite.utils.canonical import canonical


def food_seed(seed: int, food: str) -> int:
    """First attempt seed of ``food``'s recording: apart from every other food's, whichever foods a run records."""
    order = list(dict.fromkeys([*TRAINING_FOODS, *UNSEEN_FOODS, *FOODS]))
    return seed + FOOD_SEED_STRIDE * order.index(get_food(food).name)


def _recorded(path: Path) -> dict:
    """What a food's file holds: demos, and the settings it was recorded with."""
    with open_dataset(path) as f:
        kwargs = with_recorded_physics(json.loads(f["data"].attrs["env_args"])["env_kwargs"])
        names = demo_names(f)
        first = f["data"][names[0]].attrs if names else {}
        tried = seeds_used(f)
        piles = {attr_text(f["data"][name].attrs.get("pile", "")) for name in names}
        observed = {key: value.shape[1:] for key, value in f["data"][names[0]]["obs"].items()} if names else {}
        return dict(
            next_seed=max(tried) + 1 if tried else None,
            demos=len(names),
            food=kwargs.get("food"),
            n_grains=kwargs.get("n_grains"),
            physics=kwargs["physics"],
            # what the demos hold, whatever the env kwargs say
            wrench=bool(names) and set(WRENCH_OBSERVATIONS) <= set(f["data"][names[0]]["obs"]),
            horizon=kwargs.get("horizon"),
            robot=kwargs.get("robots"),
            cameras=kwargs.get("camera_names") if kwargs.get("use_camera_obs") else [],
            profile=str(first.get("profile", "")),
            seed=int(first["env_seed"]) if "env_seed" in first else None,
            start=demo_start(f["data"].attrs),
            # the settled piles its demos name ("": recorded before demos named them, taken as they are)
            piles=piles - {""},
            observed=observed,
            env_kwargs=kwargs,
        )


def check_recording(
    path: Path,
    food: str,
    profile: str = "expert",
    seed: int = 0,
    horizon: int = 400,
    n_grains: int | None = None,
    cameras: tuple[str, ...] = (),
    robot: str = "XArm7",
    physics: str = DEFAULT_PHYSICS,
    wrench: bool = False,
) -> dict | None:
    """
    What ``path`` holds (``_recorded``) when it may be continued with these settings; None when there is no file.
    A file with the wrist sensor observed serves a study that does not ask for it; not the other way round.

    Raises:
        StageError: [the file was recorded with other settings, or is not a dataset]
    """
    path = Path(path)
    if not path.exists():
        return None
    try:
        held = _recorded(path)
    except DatasetError as error:
        raise StageError(str(error)) from None
    wanted = dict(
        food=food,
        n_grains=n_grains,
        horizon=horizon,
        cameras=list(cameras),
        profile=profile,
        seed=seed,
        robot=robot,
        physics=physics,
        start=DEMO_START,
    )
    differ = {k: (held[k], v) for k, v in wanted.items() if held[k] != v and held["demos"]}
    if wrench and not held["wrench"] and held["demos"]:
        differ["wrench"] = (False, True)
    if differ:
        described = ", ".join(f"{k} {a!r} (asked: {b!r})" for k, (a, b) in differ.items())
        raise StageError(f"{path} was recorded with other settings: {described}; use another output directory")
    if held["demos"]:
        _check_made_by_this_code(path, held)
    return held


@functools.cache
def _made_by_this_code(env_kwargs: str) -> tuple[frozenset[str], dict[str, tuple]]:
    """The settled piles a recording with these env kwargs (canonical JSON) can start on and the shapes of the
    observations it stores, without cameras: built once per process (a study checks each food's file twice)."""
    from veragmil_suite.environments.scoop import headless
    from veragmil_suite.learning.robomimic_obs import observation

    with headless(json.loads(env_kwargs)) as env:
        return frozenset(env.pile_keys()), {key: value.shape for key, value in observation(env).items()}


def _check_made_by_this_code(path: Path, held: dict) -> None:
    """
    Refuses a recording that this code would not continue alike: demos on settled piles it no longer draws (another
    grain model, lattice, settling or solver), or observed otherwise than it records (an observation added or
    reshaped since); its demos and new ones could not be merged or trained on as one recording.

    Raises:
        StageError: [naming what differs]
    """
    drawn, made = _made_by_this_code(canonical(held["env_kwargs"]))
    cameras = set(held["cameras"])
    observed = {k: v for k, v in held["observed"].items() if k.rsplit("_", 1)[0] not in cameras}
    why = []
    if stale := held["piles"] - drawn:
        why.append(f"on {len(stale)} settled piles this code no longer draws (its grains, lattice, settling or solver)")
    if observed != made:
        differ = sorted(
            set(observed) ^ set(made) | {k for k in observed.keys() & made.keys() if observed[k] != made[k]}
        )
        why.append(f"observed otherwise than this code records ({', '.join(differ)})")
    if why:
        raise StageError(
            f"{path} holds demos {' and '.join(why)}; move the file away to record them again, or use another "
            "output directory"
        )


def record_food(
    path: Path,
    food: str,
    demos: int,
    profile: str = "expert",
    seed: int = 0,
    horizon: int = 400,
    n_grains: int | None = None,
    cameras: tuple[str, ...] = (),
    workers: int = 1,
    ray: str | None = None,
    robot: str = "XArm7",
    progress: bool = False,
    echo: bool = False,
    physics: str = DEFAULT_PHYSICS,
    wrench: bool = False,
) -> float | None:
    """
    Records ``demos`` successful scripted demos of ``food`` into ``path`` (attempt seeds from ``seed``, in
    ``workers`` processes, or on the Ray cluster at ``ray``; with ``progress``, a bar of the demos kept, and with
    ``echo`` the collector's own lines); returns the seconds taken, or None when the file already holds them
    (recorded with the same settings). A file with fewer (a killed or smaller recording) is continued from the seed
    after its last attempt: the demos are those one uninterrupted recording would have kept.

    Raises:
        StageError: [the file was recorded with other settings, or recording failed]
    """
    path = Path(path)
    held = check_recording(path, food, profile, seed, horizon, n_grains, cameras, robot, physics, wrench)
    if held is not None:
        if held["demos"] >= demos:
            return None
        if held["next_seed"] is None:
            path.unlink()  # killed before its first attempt ended: nothing to continue
        else:
            demos, seed = demos - held["demos"], held["next_seed"]
            wrench = wrench or held["wrench"]  # its demos alike: the sensor in all or none
    path.parent.mkdir(parents=True, exist_ok=True)
    env_kwargs = recording_env_kwargs(
        robot, food, horizon=horizon, n_grains=n_grains, physics=physics, cameras=cameras, wrench=wrench
    )
    call = dict(output=str(path), env_kwargs=env_kwargs, episodes=demos, profile=profile, seed=seed)
    call.update(processes=workers, ray=ray)
    log = path.with_name(f"{path.stem}.seed{seed}.log")
    bar = LogProgress(demos, RECORDING_PROGRESS, f"{profile} {food}", "demo", echo) if progress else None
    return run_logged_call(_record, call, log, f"recording {food} ({profile})", progress=bar)


def _record(**kwargs) -> None:
    """A food's recording in the stage's child process (record_scripted); fails when fewer demos were kept."""
    outcome = record_scripted(**kwargs)
    if (summary := outcome.summary()) is not None:
        print(summary, flush=True)
    if outcome.failed is not None or outcome.kept < outcome.requested:
        raise StageError(outcome.failed or f"saved {outcome.kept} of {outcome.requested} requested demos")


def demo_mask(n: int) -> str:
    """The mask (robomimic filter key) of the first ``n`` demos of each food."""
    return f"first{n}"


def check_merged(path: Path, food_files: list[Path]) -> None:
    """
    Refuses a merged dataset of other foods' files than ``food_files``: the runs trained on it would be taken for
    runs on these. The same files changed (more demos recorded) are merged again.

    Raises:
        StageError: [``path`` merges other foods' files, or cannot be read]
    """
    if not Path(path).exists():
        return
    try:
        with h5py.File(path, "r") as f:
            stamp = f["data"].attrs.get("merged_inputs")
    except (OSError, KeyError) as error:
        raise StageError(f"{path} cannot be read ({error}); use another output directory") from None
    if stamp is None:
        return  # merged, and stopped before it was stamped: merged again
    held = [Path(source).name for source, _ in json.loads(stamp)]
    asked = [Path(source).name for source in food_files]
    if held != asked:
        raise StageError(
            f"{path} merges {', '.join(held)} (asked: {', '.join(asked)}); its training runs would be taken for "
            "runs on the foods asked: use another output directory"
        )


def merge_profile_dataset(path: Path, food_files: list[Path], demo_counts: list[int]) -> None:
    """
    Merges the foods' files into ``path`` (again when the inputs changed) and writes a mask per demo count: the
    first N demos of each food (its first N seeds). The stamp of the inputs names them relative to ``path``'s
    folder, so a study folder moved or copied with its files' times is not merged again; a file already merged
    from these inputs with these masks is left as it is.
    """
    path = Path(path)
    stamp = json.dumps([[os.path.relpath(p, path.parent), os.path.getmtime(p)] for p in food_files])
    current = None
    if path.exists():
        with h5py.File(path, "r") as f:
            current = f["data"].attrs.get("merged_inputs")
    if current != stamp:
        merge_datasets([str(p) for p in food_files], path)
    with h5py.File(path, "r") as f:
        masks = {key: [bytes(name).decode() for name in f["mask"][key][()]] for key in f.get("mask", {})}
        by_food: dict[str, list[str]] = {}
        for name in sorted(f["data"].keys(), key=lambda n: int(n.split("_")[-1])):
            by_food.setdefault(str(f["data"][name].attrs["food"]), []).append(name)
    wanted = {demo_mask(n): [name for demos in by_food.values() for name in demos[:n]] for n in demo_counts}
    if current == stamp and all(masks.get(key) == names for key, names in wanted.items()):
        return
    with updated_file(path) as working:
        f = working.file
        f["data"].attrs["merged_inputs"] = stamp
        for key, names in wanted.items():
            if f"mask/{key}" in f:
                del f[f"mask/{key}"]
            f.create_dataset(f"mask/{key}", data=[name.encode() for name in names])


def food_files(path: Path, foods: list[str]) -> list[Path]:
    """The per-food recordings merged into ``path``: ``<path without .hdf5>/<food>.hdf5``."""
    return [Path(path).with_suffix("") / f"{food}.hdf5" for food in foods]


def recording_settings(settings: PipelineSettings) -> dict:
    """What a study's every recording is made with (record_food's and check_recording's keyword arguments)."""
    return dict(
        horizon=settings.horizon,
        n_grains=settings.n_grains,
        robot=settings.robot,
        physics=settings.physics,
        wrench=needs_wrench(settings.obs_sets),
    )


def check_recordings(settings: PipelineSettings, profile: str, dataset: Path) -> None:
    """
    Refuses a study whose recordings of ``profile`` (merged into ``dataset``) were made with other settings or
    merge other foods, before anything is written.

    Raises:
        StageError: [naming the first file that belongs to another study]
    """
    files = food_files(dataset, settings.train_foods)
    for food, file in zip(settings.train_foods, files):
        seed = food_seed(settings.seed, food)
        check_recording(file, food, profile=profile, seed=seed, **recording_settings(settings))
    check_merged(dataset, files)


def record_scripted_dataset(
    path: Path,
    settings: PipelineSettings,
    profile: str = "expert",
    say: Callable[[str], None] = print,
    ray: str | None = None,
    progress: bool = False,
    echo: bool = False,
) -> float:
    """Records (or finds complete) the study's largest demo count of ``profile``'s scripted demos of each training
    food, one file per food beside ``path``, in ``settings.processes`` processes or on the Ray cluster at ``ray``
    (with ``progress``, a bar per food; with ``echo``, the recorders' lines), and merges them into ``path`` with a
    mask per demo count; returns the seconds spent recording."""
    path = Path(path)
    counts = settings.demos_per_food
    elapsed = 0.0
    files = food_files(path, settings.train_foods)
    for food, file in zip(settings.train_foods, files):
        seconds = record_food(
            file,
            food,
            max(counts),
            profile=profile,
            seed=food_seed(settings.seed, food),
            workers=settings.processes,
            ray=ray,
            progress=progress,
            echo=echo,
            **recording_settings(settings),
        )
        if seconds is None:
            say(f"skipping recording {profile} {food}: {file} holds its {max(counts)} demos")
        else:
            elapsed += seconds
    merge_profile_dataset(path, files, counts)
    return elapsed


def _recording_of(path: Path) -> tuple[tuple, dict | None]:
    """The recording a dataset holds: merge_profile_dataset's stamp of its inputs (which a copy without no-ops
    keeps), its steps and demos before any were dropped; and for such a copy, what it dropped (drop_noops)."""
    with open_dataset(path) as f:
        attrs = f["data"].attrs
        dropped = json.loads(attrs["noops_dropped"]) if "noops_dropped" in attrs else None
        if dropped is None:
            return (attrs.get("merged_inputs"), int(attrs.get("total", -1)), len(demo_names(f))), None
        return (attrs.get("merged_inputs"), dropped["steps_before"], dropped["demos"]), dropped


def drop_noops_once(merged: Path, path: Path, say: Callable[[str], None] = print) -> None:
    """Writes ``path``: ``merged`` without its no-op steps (veragmil-drop-noops), unless ``path`` is such a copy of
    ``merged`` as it is now (the same merged inputs, steps and demos, every no-op dropped)."""
    if path.exists():
        try:
            made, dropped = _recording_of(path)
        except DatasetError:
            made, dropped = None, None  # unreadable: written again
        if dropped is not None and not dropped.get("keep_held", False) and made == _recording_of(merged)[0]:
            say(f"skipping dropping no-op steps: {path} holds {merged.name} without them")
            return
    demos, before, after, _ = drop_noops(merged, path)
    say(f"dropped {before - after} no-op steps of {before} from {merged.name} into {path.name} ({demos} demos)")
