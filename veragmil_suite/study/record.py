"""The study's recording stage: one scripted dataset per profile and food, checked, then merged per profile with
a ``first<N>`` mask per demo count (smaller datasets are prefixes of larger ones).
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import h5py

from veragmil_suite.data.datasets import merge_datasets
from veragmil_suite.data.schema import DatasetError, demo_names, open_dataset, seeds_used
from veragmil_suite.data.writer import updated_file
from veragmil_suite.models.foods import (
    DEFAULT_PHYSICS,
    FOODS,
    TRAINING_FOODS,
    UNSEEN_FOODS,
    get_food,
    with_recorded_physics,
)
from veragmil_suite.study.logged_run import RECORDING_PROGRESS, LogProgress, console, run_logged
from veragmil_suite.study.settings import FOOD_SEED_STRIDE, StageError


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
        return dict(
            next_seed=max(tried) + 1 if tried else None,
            demos=len(names),
            food=kwargs.get("food"),
            n_grains=kwargs.get("n_grains"),
            physics=kwargs["physics"],
            horizon=kwargs.get("horizon"),
            robot=kwargs.get("robots"),
            cameras=kwargs.get("camera_names") if kwargs.get("use_camera_obs") else [],
            profile=str(first.get("profile", "")),
            seed=int(first["env_seed"]) if "env_seed" in first else None,
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
) -> dict | None:
    """
    What ``path`` holds (``_recorded``) when it may be continued with these settings; None when there is no file.

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
    )
    differ = {k: (held[k], v) for k, v in wanted.items() if held[k] != v and held["demos"]}
    if differ:
        described = ", ".join(f"{k} {a!r} (asked: {b!r})" for k, (a, b) in differ.items())
        raise StageError(f"{path} was recorded with other settings: {described}; use another output directory")
    return held


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
    held = check_recording(path, food, profile, seed, horizon, n_grains, cameras, robot, physics)
    if held is not None:
        if held["demos"] >= demos:
            return None
        if held["next_seed"] is None:
            path.unlink()  # killed before its first attempt ended: nothing to continue
        else:
            demos, seed = demos - held["demos"], held["next_seed"]
    path.parent.mkdir(parents=True, exist_ok=True)
    command = [
        *console("veragmil-collect"),
        *("--device", "scripted", "--profile", profile, "--food", food),
        *("--episodes", str(demos), "--output", str(path), "--seed", str(seed), "--workers", str(workers)),
        *("--horizon", str(horizon), "--robot", robot, "--physics", physics, "--quiet", "--cameras", *cameras),
    ]
    if n_grains is not None:
        command += ["--n-grains", str(n_grains)]
    if ray is not None:
        command += ["--ray", ray]
    log = path.with_name(f"{path.stem}.seed{seed}.log")
    bar = LogProgress(demos, RECORDING_PROGRESS, f"{profile} {food}", "demo", echo) if progress else None
    return run_logged(command, log, f"recording {food} ({profile})", progress=bar)


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
    first N demos of each food (its first N seeds).
    """
    sources = [str(p) for p in food_files]
    stamp = json.dumps([[s, os.path.getmtime(s)] for s in sources])
    current = None
    if path.exists():
        with h5py.File(path, "r") as f:
            current = f["data"].attrs.get("merged_inputs")
    if current != stamp:
        merge_datasets(sources, path)
    with updated_file(path) as working:
        f = working.file
        f["data"].attrs["merged_inputs"] = stamp
        by_food: dict[str, list[str]] = {}
        for name in sorted(f["data"].keys(), key=lambda n: int(n.split("_")[-1])):
            by_food.setdefault(str(f["data"][name].attrs["food"]), []).append(name)
        for n in demo_counts:
            names = [name for demos in by_food.values() for name in demos[:n]]
            key = f"mask/{demo_mask(n)}"
            if key in f:
                del f[key]
            f.create_dataset(key, data=[name.encode() for name in names])


def food_files(path: Path, foods: list[str]) -> list[Path]:
    """The per-food recordings merged into ``path``: ``<path without .hdf5>/<food>.hdf5``."""
    return [Path(path).with_suffix("") / f"{food}.hdf5" for food in foods]


def record_scripted_dataset(
    path: Path,
    foods: list[str],
    demo_counts: list[int],
    profile: str = "expert",
    seed: int = 0,
    horizon: int = 400,
    n_grains: int | None = None,
    cameras: tuple[str, ...] = (),
    workers: int = 1,
    say=print,
    ray: str | None = None,
    robot: str = "XArm7",
    progress: bool = False,
    echo: bool = False,
    physics: str = DEFAULT_PHYSICS,
) -> float:
    """Records (or finds complete) max(``demo_counts``) scripted demos of each food, one file per food beside
    ``path`` (with ``progress``, a bar per food; with ``echo``, the collectors' lines), and merges them into
    ``path`` with a mask per demo count; returns the seconds spent recording."""
    path = Path(path)
    elapsed = 0.0
    files = []
    for food, file in zip(foods, food_files(path, foods)):
        seconds = record_food(
            file,
            food,
            max(demo_counts),
            profile=profile,
            seed=food_seed(seed, food),
            horizon=horizon,
            n_grains=n_grains,
            cameras=cameras,
            workers=workers,
            ray=ray,
            robot=robot,
            progress=progress,
            echo=echo,
            physics=physics,
        )
        if seconds is None:
            say(f"skipping recording {profile} {food}: {file} holds its {max(demo_counts)} demos")
        else:
            elapsed += seconds
        files.append(file)
    merge_profile_dataset(path, files, demo_counts)
    return elapsed
