"""
The paper's pipeline from scripted data: record demonstrations, train robomimic on them, evaluate the checkpoints.

Each stage runs our own console programs in a child process (veragmil-collect, veragmil-train), exactly as a user
would type them, with its output kept in a log file beside its results; evaluation goes through
veragmil_suite.evaluation. veragmil-quickstart and veragmil-study are thin command lines over this module.

A run resumes in its output directory: every piece that is complete is skipped (and said so), so an interrupted
or partial grid continues where it stopped and a larger one reuses the pieces of a smaller one.

- Recording: one file per profile and food, ``data/<profile>/<food>.hdf5``, complete once it holds the demos
  asked for (a shorter one, from a killed run, is recorded again: attempts are seeded, so the demos are the same).
  The foods' files are merged into ``data/<profile>.hdf5`` with a mask ``first<N>`` per demo count: the first N
  demos of each food, so smaller datasets are prefixes of larger ones.
- Training: ``runs/<profile>_<algo>_<N>demos_<steps>steps`` (``_seed<S>`` added for a training seed other than the
  default, ``seed + 1``), complete once its last checkpoint exists and its
  config equals the one asked for (a different one is refused: pick another output directory).
- Evaluation: every finished episode is journaled (veragmil_suite.evaluation.evaluate), and only the missing ones run.

With ``ray`` (veragmil-study --ray [ADDRESS]) the same pieces run as Ray tasks (veragmil_suite.utils.distributed): each
recording attempt and evaluation episode on one CPU, each training run on its torch threads' CPUs (and a GPU when
the cluster has one), all training runs at once. The driver keeps the bookkeeping (files, journal, skips), so a
study resumes the same way; the output directory must be one path that every node sees (a shared filesystem).
"""

from __future__ import annotations

import contextlib
import json
import os
import re
import shutil
import subprocess
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from veragmil_suite.learning.observation_sets import (
    DEFAULT_OBSERVATION_SET,
    check_observation_set,
    with_observation_set,
)
from veragmil_suite.models.foods import FOODS, TRAINING_FOODS, UNSEEN_FOODS, get_food, with_recorded_physics
from veragmil_suite.utils.asset_paths import config_path
from veragmil_suite.utils.distributed import Resources, ray_session, run_pieces
from veragmil_suite.utils.rendering import use_headless_rendering

# robomimic configs of configs/json per algorithm: the paper's three and Diffusion Policy (low-dim observations)
ALGO_CONFIGS = {"bc": "bc", "bc_rnn": "bc_rnn", "bcq": "bcq", "diffusion_policy": "diffusion_policy"}
ALGO_LABELS = {"bc": "BC", "bc_rnn": "BC-RNN", "bcq": "BCQ", "diffusion_policy": "Diffusion Policy"}

# Seeds of recorded episodes and of evaluation episodes never meet: evaluation bowls are not training bowls.
EVAL_SEED_OFFSET = 100_000
# torch threads of a training run unless $VERAGMIL_TORCH_THREADS says otherwise (robomimic's train() sets 2)
ROBOMIMIC_TORCH_THREADS = 2
# Seeds of the foods' recordings are this far apart (by the food's place in the catalog, seen foods first), so
# every demo of a dataset has its own bowl and pile, whichever foods a run records.
FOOD_SEED_STRIDE = 1000
# what eval/ holds beside the evaluation's own tables: learning curves, and the tables over training seeds
CURVE_FILES = ("curves.csv", "curves.png")
SEED_FILES = ("seeds.csv", "seeds.md", "seeds")


class StageError(RuntimeError):
    """A stage's child process failed; the message ends with the tail of its log."""


@dataclass
class PipelineSettings:
    """Sizes of one run: the small defaults finish in minutes on 2 cores; the paper's sizes are in docs/study.md.

    ``demos_per_food`` and ``eval_steps`` may list several values (learning curves): each demo count trains its
    own model on the first N demos of each food, and each model is evaluated at every step count of
    ``eval_steps`` (gradient steps, multiples of ``steps_per_epoch``; by default only at the end of training).
    ``algo_epochs`` (algorithm -> epochs) gives an algorithm its own budget instead of ``epochs``: BC-RNN costs 7x
    BC's time per gradient step. Each algorithm is evaluated at the end of its own training, and at the listed
    ``eval_steps`` its training reaches.
    ``agents`` (name -> agent SPEC of veragmil_suite.evaluation.agents) are evaluated beside the run's own, on the same
    bowls: a pretrained checkpoint, another operator profile, a recorded dataset.
    ``train_seeds`` (default: ``seed + 1`` alone) trains each model once per seed, on the same data: the spread
    between training seeds of one recipe is as large as the differences between recipes, so comparisons need it.
    ``obs_sets`` (veragmil_suite.learning.observation_sets) trains each model once per observation set, on the same
    data; every model's column names its set.
    """

    output_dir: str
    profiles: list[str] = field(default_factory=lambda: ["expert"])
    algos: list[str] = field(default_factory=lambda: ["bc"])
    train_foods: list[str] = field(default_factory=lambda: list(TRAINING_FOODS))
    eval_foods: list[str] = field(default_factory=lambda: list(TRAINING_FOODS + UNSEEN_FOODS))
    demos_per_food: list[int] = field(default_factory=lambda: [2])
    epochs: int = 20
    steps_per_epoch: int = 100
    eval_steps: list[int] | None = None
    algo_epochs: dict[str, int] = field(default_factory=dict)
    episodes: int = 3
    processes: int = 2
    seed: int = 0
    horizon: int = 400
    n_grains: int | None = None
    robot: str = "XArm7"  # records, trains and evaluates with this robot (veragmil_suite.models.humanoid: the G1)
    score_demonstrators: bool = True
    train_seeds: list[int] | None = None
    obs_sets: list[str] = field(default_factory=lambda: [DEFAULT_OBSERVATION_SET])
    agents: dict[str, str] = field(default_factory=dict)
    ray: str | None = None  # None: local processes; else a Ray cluster's address (distributed.THIS_MACHINE: here)

    def __post_init__(self):
        for food in [*self.train_foods, *self.eval_foods]:
            get_food(food)  # a ValueError naming the accepted foods
        from veragmil_suite.models.humanoid import check_robot

        check_robot(self.robot)
        unknown = sorted(set(self.algos) - set(ALGO_CONFIGS))
        if unknown:
            raise ValueError(f"unknown algorithm(s) {unknown}; accepted: {sorted(ALGO_CONFIGS)}")
        from veragmil_suite.devices.expert import get_profile

        for profile in self.profiles:
            get_profile(profile)
        if isinstance(self.demos_per_food, int):
            self.demos_per_food = [self.demos_per_food]
        self.demos_per_food = sorted(set(int(n) for n in self.demos_per_food))
        for name in ("epochs", "steps_per_epoch", "episodes", "processes", "horizon"):
            if int(getattr(self, name)) < 1:
                raise ValueError(f"{name} must be a positive integer, got {getattr(self, name)!r}")
        if not self.demos_per_food or self.demos_per_food[0] < 1:
            raise ValueError(f"demos_per_food must be positive integers, got {self.demos_per_food!r}")
        unknown = sorted(set(self.algo_epochs) - set(ALGO_CONFIGS))
        if unknown:
            raise ValueError(f"algo_epochs names unknown algorithm(s) {unknown}; accepted: {sorted(ALGO_CONFIGS)}")
        for algo, epochs in self.algo_epochs.items():
            if int(epochs) < 1:
                raise ValueError(f"algo_epochs of {algo} must be a positive integer, got {epochs!r}")
        total = max(self.total_steps_of(algo) for algo in self.algos)
        steps = sorted(set(int(k) for k in (self.eval_steps or [])))
        bad = [k for k in steps if k < 1 or k > total or k % self.steps_per_epoch]
        if bad:
            raise ValueError(
                f"eval_steps {bad} are not checkpoints of this training: multiples of steps_per_epoch "
                f"({self.steps_per_epoch}) up to epochs x steps_per_epoch ({total})"
            )
        self.eval_steps = steps or None
        if isinstance(self.train_seeds, int):
            self.train_seeds = [self.train_seeds]
        self.train_seeds = list(dict.fromkeys(int(s) for s in self.train_seeds or [self.seed + 1]))
        if any(s < 0 for s in self.train_seeds):
            raise ValueError(f"train_seeds must be integers >= 0 (torch's seeds), got {self.train_seeds!r}")
        if isinstance(self.obs_sets, str):
            self.obs_sets = [self.obs_sets]
        self.obs_sets = list(dict.fromkeys(check_observation_set(name) for name in self.obs_sets))
        if not self.obs_sets:
            raise ValueError("obs_sets must name at least one observation set")
        from veragmil_suite.evaluation.agents import parse_spec

        own = set(self.own_agents())
        for name, spec in self.agents.items():
            parse_spec(spec)  # a ValueError naming the accepted forms
            if name in own:
                raise ValueError(
                    f"agent name {name!r} is taken by one of this run's own; name it otherwise (NAME=SPEC)"
                )

    def epochs_of(self, algo: str) -> int:
        return int(self.algo_epochs.get(algo, self.epochs))

    def total_steps_of(self, algo: str) -> int:
        return self.epochs_of(algo) * self.steps_per_epoch

    def steps_of(self, algo: str) -> list[int]:
        """The gradient steps at which ``algo``'s checkpoints are evaluated."""
        total = self.total_steps_of(algo)
        if self.eval_steps is None:
            return [total]
        own_end = {total} if algo in self.algo_epochs else set()
        return sorted({k for k in self.eval_steps if k <= total} | own_end)

    @property
    def sweeps_steps(self) -> bool:
        """Whether the run's checkpoints are evaluated at more than one step count."""
        return len({k for algo in self.algos for k in self.steps_of(algo)}) > 1

    def model_label(
        self,
        profile: str,
        algo: str,
        demos_per_food: int,
        steps: int,
        train_seed: int | None = None,
        obs_set: str = DEFAULT_OBSERVATION_SET,
    ) -> str:
        """A trained checkpoint's column: profile, algorithm and observation set, plus demos and steps when the run
        sweeps them (or its algorithms train for different budgets), plus the training seed when there are several
        (without ``train_seed``: the recipe's label, which names all its seeds)."""
        label = f"{profile} {ALGO_LABELS[algo]} {obs_set} obs"
        label += f" {demos_per_food} demos" if len(self.demos_per_food) > 1 else ""
        label += f" {_steps_label(steps)} steps" if self.sweeps_steps else ""
        label += f" seed {train_seed}" if train_seed is not None and len(self.train_seeds) > 1 else ""
        return label

    def run_name(
        self, profile: str, algo: str, demos_per_food: int, train_seed: int, obs_set: str = DEFAULT_OBSERVATION_SET
    ) -> str:
        """A training run's folder; the default seed's and observation set's have no suffix, so studies from before
        seeds and observation sets resume."""
        name = f"{profile}_{algo}_{demos_per_food}demos_{self.total_steps_of(algo)}steps"
        name += f"_obs-{obs_set}" if obs_set != DEFAULT_OBSERVATION_SET else ""
        return name if train_seed == self.seed + 1 else f"{name}_seed{train_seed}"

    def own_agents(self) -> list[str]:
        """The columns this run makes itself: each profile's operator (when scored) and each checkpoint."""
        names = [f"{p} operator" for p in self.profiles] if self.score_demonstrators else []
        for profile in self.profiles:
            names += [
                self.model_label(profile, algo, n, k, s, obs)
                for algo in self.algos
                for obs in self.obs_sets
                for n in self.demos_per_food
                for s in self.train_seeds
                for k in self.steps_of(algo)
            ]
        return names


@dataclass(frozen=True)
class LogProgress:
    """A progress bar a child's log drives: ``pattern``'s first group, in the last line that matches, is the count
    done out of ``total``; with ``echo``, the log's lines are shown above the bar as they come."""

    total: int
    pattern: str
    desc: str
    unit: str
    echo: bool = False


# veragmil-collect's line per episode kept ("  saved as demo_3 (2/5)"); robomimic's train.py's line per epoch
RECORDING_PROGRESS = r"saved as demo_\d+ \((\d+)/\d+\)"
TRAINING_PROGRESS = r"^Train Epoch (\d+)$"
LOG_POLL_S = 0.5


def _run_logged(
    command: list[str],
    log_path: Path,
    what: str,
    environ: dict[str, str] | None = None,
    progress: LogProgress | None = None,
) -> float:
    """Runs a command (with ``environ`` added to this environment) with its output in ``log_path``, advancing a
    progress bar from the log when ``progress`` is given; returns its wall time, raises StageError on failure."""
    env = dict(os.environ, **(environ or {}))
    use_headless_rendering(environ=env)
    env.setdefault("PYNPUT_BACKEND", "dummy")
    start = time.perf_counter()
    with (
        open(log_path, "w") as log,
        subprocess.Popen(command, stdout=log, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL, env=env) as child,
    ):
        try:
            code = child.wait() if progress is None else _follow(child, log_path, progress)
        except BaseException:  # interrupted: the child goes too, as subprocess.call would see to
            child.kill()
            raise
    if code != 0:
        tail = log_path.read_text(errors="replace")[-3000:]
        raise StageError(f"{what} failed (exit {code}); log {log_path}:\n{tail}")
    return time.perf_counter() - start


def _follow(child: subprocess.Popen, log_path: Path, progress: LogProgress) -> int:
    """Waits for ``child``, its progress read from the lines it writes to ``log_path``; returns its exit code."""
    from tqdm import tqdm

    pattern = re.compile(progress.pattern, re.MULTILINE)
    bar = tqdm(total=progress.total, desc=progress.desc, unit=progress.unit)
    with open(log_path, errors="replace") as log, bar:
        pending = ""
        while True:
            code = child.poll()
            pending += log.read()
            complete, _, pending = pending.rpartition("\n")
            found = pattern.findall(complete)
            if progress.echo and complete:
                bar.write(complete)
            if found:
                bar.update(min(int(found[-1]), progress.total) - bar.n)
            if code is not None:
                return code
            time.sleep(LOG_POLL_S)


def _console(name: str) -> list[str]:
    """A console program of this package, run with this interpreter (works without the venv on PATH)."""
    modules = {
        "veragmil-collect": "veragmil_suite.scripts.collect_human_demonstrations",
        "veragmil-train": "veragmil_suite.scripts.robomimic_entry",
    }
    command = [sys.executable, "-m", modules[name]]
    return [*command, "train"] if name == "veragmil-train" else command


# ---------------------------------------------------------------------------------------------------------------- #
# Recording                                                                                                        #
# ---------------------------------------------------------------------------------------------------------------- #


def food_seed(seed: int, food: str) -> int:
    """First attempt seed of ``food``'s recording: apart from every other food's, whichever foods a run records."""
    order = list(dict.fromkeys([*TRAINING_FOODS, *UNSEEN_FOODS, *FOODS]))
    return seed + FOOD_SEED_STRIDE * order.index(get_food(food).name)


def _recorded(path: Path) -> dict:
    """What a food's file holds: demos, and the settings it was recorded with."""
    from veragmil_suite.data.recording import demo_names, open_dataset, seeds_used

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
) -> dict | None:
    """
    What ``path`` holds (``_recorded``) when it may be continued with these settings; None when there is no file.

    Raises:
        StageError: [the file was recorded with other settings, or is not a dataset]
    """
    from veragmil_suite.data.recording import DatasetError

    path = Path(path)
    if not path.exists():
        return None
    try:
        held = _recorded(path)
    except DatasetError as error:
        raise StageError(str(error)) from None
    wanted = dict(
        food=food, n_grains=n_grains, horizon=horizon, cameras=list(cameras), profile=profile, seed=seed, robot=robot
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
    held = check_recording(path, food, profile, seed, horizon, n_grains, cameras, robot)
    if held is not None:
        if held["demos"] >= demos:
            return None
        if held["next_seed"] is None:
            path.unlink()  # killed before its first attempt ended: nothing to continue
        else:
            demos, seed = demos - held["demos"], held["next_seed"]
    path.parent.mkdir(parents=True, exist_ok=True)
    command = [
        *_console("veragmil-collect"),
        *("--device", "scripted", "--profile", profile, "--food", food),
        *("--episodes", str(demos), "--output", str(path), "--seed", str(seed), "--workers", str(workers)),
        *("--horizon", str(horizon), "--robot", robot, "--quiet", "--cameras", *cameras),
    ]
    if n_grains is not None:
        command += ["--n-grains", str(n_grains)]
    if ray is not None:
        command += ["--ray", ray]
    log = path.with_name(f"{path.stem}.seed{seed}.log")
    bar = LogProgress(demos, RECORDING_PROGRESS, f"{profile} {food}", "demo", echo) if progress else None
    return _run_logged(command, log, f"recording {food} ({profile})", progress=bar)


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
    import h5py

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
    import h5py

    from veragmil_suite.data.datasets import merge_datasets
    from veragmil_suite.data.recording import updated_file

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
        )
        if seconds is None:
            say(f"skipping recording {profile} {food}: {file} holds its {max(demo_counts)} demos")
        else:
            elapsed += seconds
        files.append(file)
    merge_profile_dataset(path, files, demo_counts)
    return elapsed


# ---------------------------------------------------------------------------------------------------------------- #
# Training                                                                                                         #
# ---------------------------------------------------------------------------------------------------------------- #


def training_config(
    algo: str,
    dataset: Path,
    output_dir: Path,
    name: str,
    epochs: int,
    steps_per_epoch: int,
    seed: int = 1,
    filter_key: str | None = None,
    save_epochs: list[int] | None = None,
    obs_set: str | None = None,
) -> dict:
    """Our stock config of ``algo`` (configs/json) shortened to ``epochs`` x ``steps_per_epoch`` gradient steps,
    trained on the demos of ``filter_key`` (all when None), with the low-dim observations of ``obs_set``
    (veragmil_suite.learning.observation_sets; None: the config's own).

    Rollouts during training are off (the evaluation scores checkpoints on every food afterwards); the last epoch
    and ``save_epochs`` are saved.
    """
    if algo not in ALGO_CONFIGS:
        raise ValueError(f"unknown algorithm {algo!r}; accepted: {sorted(ALGO_CONFIGS)}")
    with open(config_path(ALGO_CONFIGS[algo])) as f:
        config = json.load(f)
    experiment = config["experiment"]
    experiment.update(name=name, epoch_every_n_steps=steps_per_epoch, validate=False, render_video=False)
    experiment["rollout"]["enabled"] = False
    experiment["save"].update(enabled=True, every_n_epochs=epochs, on_best_rollout_success_rate=False)
    experiment["save"]["epochs"] = sorted(set(save_epochs or []) - {epochs})
    config["train"].update(data=str(dataset), output_dir=str(output_dir), num_epochs=epochs, seed=seed)
    config["train"]["hdf5_filter_key"] = filter_key
    return with_observation_set(config, obs_set) if obs_set is not None else config


def _checkpoints(config: dict) -> dict[int, Path]:
    """The saved checkpoints of a training run by epoch (its newest run folder)."""
    name = config["experiment"]["name"]
    runs = sorted(Path(config["train"]["output_dir"]).glob(f"{name}/*/models"), key=lambda p: p.stat().st_mtime)
    if not runs:
        return {}
    return {int(p.stem.split("_")[-1]): p for p in runs[-1].glob("model_epoch_*.pth")}


def _without_save_epochs(config: dict) -> dict:
    """The config less its extra checkpoint epochs, which change what is saved, not what is trained."""
    out = json.loads(json.dumps(config))
    if isinstance(out, dict):
        out.get("experiment", {}).get("save", {}).pop("epochs", None)
    return out


def finished_training(config: dict, work_dir: Path) -> dict[int, Path] | None:
    """
    The checkpoints by epoch of a finished run of this config that holds every checkpoint asked for; None when it
    is to be trained.

    Raises:
        StageError: [the run's folder holds another config]
    """
    config_file = Path(work_dir) / f"{config['experiment']['name']}.json"
    if not config_file.exists():
        return None
    held = json.loads(config_file.read_text())
    if _without_save_epochs(held) != _without_save_epochs(config):
        name = config["experiment"]["name"]
        raise StageError(f"{config_file} holds another config for {name}; use another output directory")
    found = _checkpoints(config)
    wanted = {int(config["train"]["num_epochs"]), *config["experiment"]["save"].get("epochs", [])}
    return found if wanted <= set(found) else None


def train_checkpoint(
    config: dict,
    work_dir: Path,
    say=print,
    torch_threads: int | None = None,
    progress: bool = False,
    echo: bool = False,
) -> tuple[dict[int, Path], float | None]:
    """
    Trains with veragmil-train (with ``torch_threads`` torch threads when given, else $VERAGMIL_TORCH_THREADS or
    robomimic's 2; with ``progress``, a bar of its epochs, and with ``echo`` robomimic's output) unless a finished
    run of the same config holding every checkpoint asked for is there; returns the checkpoints by epoch and the
    wall time (None when skipped).

    Raises:
        StageError: [training failed or wrote no last checkpoint, or the run's folder holds another config]
    """
    work_dir = Path(work_dir)
    name = config["experiment"]["name"]
    config_file = work_dir / f"{name}.json"
    epochs = int(config["train"]["num_epochs"])
    wanted = {epochs, *config["experiment"]["save"].get("epochs", [])}
    found = finished_training(config, work_dir)
    if found is not None:
        say(f"skipping training {name}: its checkpoints are there ({found[epochs].parent})")
        return found, None
    if config_file.exists():
        # killed, or saved at other epochs: train again, saving both
        held = json.loads(config_file.read_text())
        saved = set(held["experiment"]["save"].get("epochs", [])) | set(config["experiment"]["save"]["epochs"])
        config = json.loads(json.dumps(config))
        config["experiment"]["save"]["epochs"] = sorted(saved - {epochs})
        shutil.rmtree(Path(config["train"]["output_dir"]) / name, ignore_errors=True)
    config_file.write_text(json.dumps(config, indent=4))
    environ = {}
    if torch_threads is not None:
        environ = {"VERAGMIL_TORCH_THREADS": str(torch_threads), "OMP_NUM_THREADS": str(torch_threads)}
    command = [*_console("veragmil-train"), "--config", str(config_file)]
    bar = LogProgress(epochs, TRAINING_PROGRESS, name, "epoch", echo) if progress else None
    seconds = _run_logged(command, work_dir / f"{name}.log", f"training {name}", environ=environ, progress=bar)
    found = _checkpoints(config)
    if not wanted <= set(found):
        raise StageError(f"training {name} wrote no last checkpoint under {config['train']['output_dir']}/{name}")
    return found, seconds


def _train_piece(context: tuple[Path, int | None, bool, bool], config: dict) -> tuple[dict[int, Path], float | None]:
    """A training run as a piece (veragmil_suite.utils.distributed): ``context`` is (work_dir, torch threads, whether to
    show a progress bar, whether to show robomimic's output)."""
    work_dir, threads, progress, echo = context
    return train_checkpoint(config, work_dir, say=lambda _: None, torch_threads=threads, progress=progress, echo=echo)


def training_resources() -> Resources:
    """What a training run holds on a Ray node: a CPU per torch thread ($VERAGMIL_TORCH_THREADS, else robomimic's
    2), and a GPU when the cluster has one (robomimic trains on it)."""
    from veragmil_suite.utils.distributed import cluster_resources

    threads = int(os.environ.get("VERAGMIL_TORCH_THREADS") or ROBOMIMIC_TORCH_THREADS)
    return Resources(cpus=threads, gpus=1 if cluster_resources().get("GPU", 0) >= 1 else 0)


# ---------------------------------------------------------------------------------------------------------------- #
# The grid                                                                                                         #
# ---------------------------------------------------------------------------------------------------------------- #


def _steps_label(steps: int) -> str:
    return f"{steps // 1000}k" if steps % 1000 == 0 else str(steps)


def training_runs(settings: PipelineSettings) -> list[dict]:
    """Every training run of the grid, in its order: profile, algorithm, observation set, demos per food, training
    seed and config."""
    out = Path(settings.output_dir)
    runs = []
    for profile in settings.profiles:
        for algo in settings.algos:
            for obs in settings.obs_sets:
                for n in settings.demos_per_food:
                    for train_seed in settings.train_seeds:
                        config = training_config(
                            algo,
                            out / "data" / f"{profile}.hdf5",
                            out / "runs",
                            settings.run_name(profile, algo, n, train_seed, obs),
                            settings.epochs_of(algo),
                            settings.steps_per_epoch,
                            seed=train_seed,
                            filter_key=demo_mask(n),
                            save_epochs=[k // settings.steps_per_epoch for k in settings.steps_of(algo)],
                            obs_set=obs,
                        )
                        run = dict(profile=profile, algo=algo, obs_set=obs, demos_per_food=n, train_seed=train_seed)
                        runs.append(dict(run, config=config))
    return runs


def check_output_dir(settings: PipelineSettings, runs: list[dict]) -> None:
    """
    Everything a run in ``settings.output_dir`` would refuse, checked before it writes anything: a food's recording
    made with other settings, a merged dataset of other foods, a training run's folder holding another config.

    Raises:
        StageError: [naming the first piece that belongs to another study]
    """
    out = Path(settings.output_dir)
    for profile in settings.profiles:
        dataset = out / "data" / f"{profile}.hdf5"
        files = food_files(dataset, settings.train_foods)
        for food, file in zip(settings.train_foods, files):
            check_recording(
                file,
                food,
                profile=profile,
                seed=food_seed(settings.seed, food),
                horizon=settings.horizon,
                n_grains=settings.n_grains,
                robot=settings.robot,
            )
        check_merged(dataset, files)
    for run in runs:
        finished_training(run["config"], out / "runs")


def run_pipeline(settings: PipelineSettings, progress: bool = True, verbose: bool = False):
    """Records one dataset per profile, trains every algorithm on each, evaluates them and the scripted operators,
    skipping every piece a previous run in the same output directory completed; with ``settings.ray``, on Ray.
    ``progress``: a line per stage and progress bars; ``verbose``: also what the recorders and trainings print.

    Returns the evaluation result (veragmil_suite.evaluation.reporting.EvaluationResult); everything is written under
    ``settings.output_dir``: data/, runs/, eval/ and timings.json.
    """
    from veragmil_suite.evaluation.evaluate import evaluate

    out = Path(settings.output_dir)
    runs = training_runs(settings)  # every training run, in the grid's order
    check_output_dir(settings, runs)  # a run refused is refused here, before it writes anything
    (out / "data").mkdir(parents=True, exist_ok=True)
    (out / "runs").mkdir(parents=True, exist_ok=True)
    timings_file = out / "timings.json"
    timings: dict[str, float] = json.loads(timings_file.read_text()) if timings_file.exists() else {}

    def say(message: str) -> None:
        if progress:
            print(f"[veragmil] {message}", flush=True)

    def note(key: str, seconds: float | None) -> None:
        if seconds is not None:
            timings[key] = round(seconds, 1)
            timings_file.write_text(json.dumps(timings, indent=2))

    with ray_session(settings.ray) as address:
        if address is not None:
            from veragmil_suite.utils.distributed import cluster_resources

            held = cluster_resources()
            cpus, gpus = held.get("CPU", 0), held.get("GPU", 0)
            say(f"running the pieces on Ray at {address} ({cpus:g} CPUs, {gpus:g} GPUs)")
        for profile in settings.profiles:
            counts = settings.demos_per_food
            say(f"recording {max(counts)} scripted '{profile}' demos of each of {settings.train_foods}")
            seconds = record_scripted_dataset(
                out / "data" / f"{profile}.hdf5",
                settings.train_foods,
                counts,
                profile=profile,
                seed=settings.seed,
                horizon=settings.horizon,
                n_grains=settings.n_grains,
                workers=settings.processes,
                say=say,
                ray=address,
                robot=settings.robot,
                progress=progress,
                echo=verbose,
            )
            note(f"record {profile}", seconds or None)
        checkpoints = _train_runs(runs, settings, out / "runs", address, say, note, progress, verbose)

        agents: dict[str, str] = {}
        points: list[dict] = []
        for profile in settings.profiles:
            if settings.score_demonstrators:
                # the demonstrator itself, live on every evaluated food: the paper's Human column (scripted here)
                agents[f"{profile} operator"] = f"expert:{profile}"
            for run in (r for r in runs if r["profile"] == profile):
                saved = checkpoints[run["config"]["experiment"]["name"]]
                algo, obs, n, train_seed = run["algo"], run["obs_set"], run["demos_per_food"], run["train_seed"]
                for k in settings.steps_of(algo):
                    label = settings.model_label(profile, algo, n, k, train_seed, obs)
                    agents[label] = str(saved[k // settings.steps_per_epoch])
                    recipe = settings.model_label(profile, algo, n, k, obs_set=obs)
                    points.append(dict(agent=label, recipe=recipe, profile=profile, algo=algo, obs_set=obs,
                                       demos_per_food=n, steps=k, train_seed=train_seed))  # fmt: skip
        agents.update(settings.agents)
        say(f"evaluating {len(agents)} agents x {settings.episodes} episodes on {settings.eval_foods}")
        env_kwargs = {"n_grains": settings.n_grains} if settings.n_grains is not None else None
        start = time.perf_counter()
        kwargs = dict(env_kwargs=env_kwargs) if env_kwargs else {}
        result = evaluate(
            agents,
            foods=settings.eval_foods,
            episodes=settings.episodes,
            processes=settings.processes,
            seed=settings.seed + EVAL_SEED_OFFSET,
            horizon=settings.horizon,
            output_dir=str(out / "eval"),
            progress=progress,
            resume=True,
            say=say,
            ray=address,
            robot=settings.robot,
            **kwargs,
        )
    if result.config["episodes_run"]:  # a fully journaled evaluation keeps the time of the run that did it
        note("evaluate", time.perf_counter() - start)
    eval_dir = out / "eval"
    if len(settings.demos_per_food) > 1 or settings.sweeps_steps:
        write_learning_curves(result, points, eval_dir)
    else:
        _remove_derived(eval_dir, CURVE_FILES, say)
    if len(settings.train_seeds) > 1:
        write_seed_tables(result, points, eval_dir)
    else:
        _remove_derived(eval_dir, SEED_FILES, say)
    return result


def _remove_derived(eval_dir: Path, names: tuple[str, ...], say) -> None:
    """Tables an earlier run of the folder derived and this one does not: left in place they would describe
    other agents than the tables beside them."""
    import shutil

    for name in names:
        path = eval_dir / name
        if path.is_dir():
            shutil.rmtree(path)
        elif path.exists():
            path.unlink()
        else:
            continue
        say(f"removed {path}: an earlier run's table that this run does not make")


def _train_runs(
    runs: list[dict],
    settings: PipelineSettings,
    work_dir: Path,
    address: str | None,
    say,
    note,
    progress: bool,
    echo: bool,
):
    """Every training run of ``runs`` that is not finished, one after another here (with ``progress``, a bar of
    each one's epochs; with ``echo``, robomimic's output) or all at once on Ray (at ``address``); returns each
    run's checkpoints by epoch, by run name."""
    checkpoints: dict[str, dict[int, Path]] = {}
    todo = []
    for run in runs:
        config = run["config"]
        name = config["experiment"]["name"]
        found = finished_training(config, work_dir)
        if found is not None:
            last = int(config["train"]["num_epochs"])
            say(f"skipping training {name}: its checkpoints are there ({found[last].parent})")
            checkpoints[name] = found
        else:
            todo.append(run)

    def announced(todo: list[dict]):
        for run in todo:
            steps = f"{run['config']['train']['num_epochs']} x {settings.steps_per_epoch}"
            dataset = Path(run["config"]["train"]["data"]).name
            label = f"{ALGO_LABELS[run['algo']]} ({run['obs_set']} obs)"
            say(f"training {label} on {run['demos_per_food']} demos per food of {dataset} ({steps} gradient steps)")
            yield run["config"]

    on_ray = address is not None
    resources = training_resources() if on_ray else Resources()
    # on Ray a run takes as many torch threads as it holds CPUs; here, those of $VERAGMIL_TORCH_THREADS or robomimic
    context = (work_dir, int(resources.cpus) if on_ray else None, progress and not on_ray, echo and not on_ray)
    pieces = run_pieces(_train_piece, announced(todo), context=context, processes=0, on_ray=on_ray, resources=resources)
    with contextlib.closing(pieces):
        for config, (found, seconds) in pieces:
            checkpoints[config["experiment"]["name"]] = found
            note(f"train {config['experiment']['name']}", seconds)
    return checkpoints


def _average_rows(result) -> dict[str, dict]:
    """Table II's average rows of ``result`` by group, "seen", "unseen" and "overall" (those its foods have)."""
    from veragmil_suite.evaluation.reporting import SEEN_LABEL, UNSEEN_LABEL, table_rows

    names = {SEEN_LABEL: "seen", UNSEEN_LABEL: "unseen", "all": "overall"}
    rows = table_rows(result.summary, result.agents, result.foods)["table2"]
    return {names[r["group"]]: r for r in rows if r["food"].endswith(" average")}


def learning_curves(result, points: list[dict]) -> list[dict]:
    """Success on seen and unseen foods (each food weighing the same, 95% Wilson intervals of the group's totals)
    per checkpoint of a sweep: ``points`` name each checkpoint agent's profile, algo, demos per food and steps."""
    from veragmil_suite.evaluation.reporting import wilson_interval

    averages = _average_rows(result)
    out = []
    for point in points:
        row = dict(point)
        for key in ("seen", "unseen"):
            group = averages.get(key)
            if group is None:
                continue
            a = point["agent"]
            low, high = wilson_interval(group[f"{a} successes"], group[f"{a} episodes"])
            row.update({f"{key} success %": group[a], f"{key} ci95 low": 100 * low, f"{key} ci95 high": 100 * high})
        out.append(row)
    return out


def write_learning_curves(result, points: list[dict], out_dir: Path) -> None:
    """curves.csv and curves.png: success against gradient steps (one line per demo count) and against demos
    per food (one line per step count), seen and unseen foods."""
    import csv

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows = learning_curves(result, points)
    columns = list(dict.fromkeys(k for r in rows for k in r))
    with open(out_dir / "curves.csv", "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=columns)
        writer.writeheader()
        writer.writerows(rows)
    axes_of = [("steps", "gradient steps", "demos_per_food", "demos/food"), ("demos_per_food", "demos per food",
               "steps", "steps")]  # fmt: skip
    axes_of = [a for a in axes_of if len({r[a[0]] for r in rows}) > 1]
    fig, axes = plt.subplots(1, len(axes_of), figsize=(5.5 * len(axes_of), 3.8), squeeze=False)
    several_seeds = len({r["train_seed"] for r in rows}) > 1
    for ax, (x_key, x_label, line_key, line_label) in zip(axes[0], axes_of):
        by_line = _groups_by(rows, ("profile", "algo", "obs_set", line_key, "train_seed"))
        for (profile, algo, obs, line, seed), group in by_line.items():
            group = sorted(group, key=lambda r: r[x_key])
            x = [r[x_key] for r in group]
            for key, style in (("seen", "-o"), ("unseen", "--s")):
                if f"{key} success %" not in group[0]:
                    continue
                y = np.array([r[f"{key} success %"] for r in group])
                err = np.array([[y_ - r[f"{key} ci95 low"], r[f"{key} ci95 high"] - y_] for y_, r in zip(y, group)]).T
                seed_label = f", seed {seed}" if several_seeds else ""
                name = f"{profile} {ALGO_LABELS[algo]} {obs} obs, {line} {line_label}{seed_label}, {key}"
                ax.errorbar(x, y, yerr=err, fmt=style, capsize=3, label=name)
        ax.set_xscale("log")
        ax.minorticks_off()
        ax.set_xticks(sorted({r[x_key] for r in rows}), [str(v) for v in sorted({r[x_key] for r in rows})])
        ax.set_xlabel(x_label)
        ax.set_ylabel("success (%, 95% CI)")
        ax.set_ylim(0, 100)
        ax.legend(fontsize="x-small")
    fig.tight_layout()
    fig.savefig(out_dir / "curves.png", dpi=100)
    plt.close(fig)


def seed_spread(result, points: list[dict]) -> list[dict]:
    """Success on seen, unseen and all foods (each food weighing the same) of every training seed of each recipe
    (``points`` name each checkpoint agent's recipe and training seed), then the recipe's mean, lowest and highest
    over its seeds."""
    averages = _average_rows(result)
    out = []
    for (recipe,), seeds in _groups_by(points, ("recipe",)).items():
        per_seed = [
            dict(
                recipe=recipe,
                train_seed=p["train_seed"],
                **{f"{g} success %": averages[g][p["agent"]] for g in averages},
            )
            for p in seeds
        ]
        out += per_seed
        for stat, reduce in (("mean", np.mean), ("lowest", np.min), ("highest", np.max)):
            values = {f"{g} success %": float(reduce([r[f"{g} success %"] for r in per_seed])) for g in averages}
            out.append(dict(recipe=recipe, train_seed=stat, **values))
    return out


def seed_markdown(rows: list[dict]) -> str:
    """The seed table: per recipe, its mean success and the range over its training seeds, then each seed's."""
    groups = [g for g in ("seen", "unseen", "overall") if f"{g} success %" in rows[0]]
    lines = [
        "Success over training seeds (%, each food weighing the same; mean and lowest-highest over the seeds, "
        "every seed's model scored on the same episodes)",
        "",
        "| model | training seeds | " + " | ".join(groups) + " | " + " | ".join(f"{g} per seed" for g in groups) + " |",
        "|---|---|" + "---:|" * (2 * len(groups)),
    ]
    for (recipe,), group in _groups_by(rows, ("recipe",)).items():
        stats = {r["train_seed"]: r for r in group if isinstance(r["train_seed"], str)}
        seeds = [r for r in group if not isinstance(r["train_seed"], str)]
        cells = [
            f"{stats['mean'][f'{g} success %']:.0f} ({stats['lowest'][f'{g} success %']:.0f}-"
            f"{stats['highest'][f'{g} success %']:.0f})"
            for g in groups
        ]
        cells += [", ".join(f"{r[f'{g} success %']:.0f}" for r in seeds) for g in groups]
        lines.append(f"| {recipe} | {', '.join(str(r['train_seed']) for r in seeds)} | " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def write_seed_tables(result, points: list[dict], out_dir: Path) -> None:
    """seeds.md and seeds.csv (seed_spread), and seeds/: the tables, stages and chart with each recipe's seeds
    pooled into one column (its episodes of every seed; intervals over the pooled episodes)."""
    import csv
    from dataclasses import replace

    from veragmil_suite.evaluation.reporting import EvaluationResult

    rows = seed_spread(result, points)
    with open(out_dir / "seeds.csv", "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    (out_dir / "seeds.md").write_text(seed_markdown(rows))
    recipe_of = {p["agent"]: p["recipe"] for p in points}
    pooled = EvaluationResult(
        episodes=[replace(e, agent=recipe_of.get(e.agent, e.agent)) for e in result.episodes],
        agents=list(dict.fromkeys(recipe_of.get(a, a) for a in result.agents)),
        foods=result.foods,
        config=dict(result.config, pooled_training_seeds=sorted({p["train_seed"] for p in points})),
    )
    pooled.write(str(out_dir / "seeds"))


def _groups_by(rows: list[dict], keys: tuple[str, ...]) -> dict[tuple, list[dict]]:
    out: dict[tuple, list[dict]] = {}
    for r in rows:
        out.setdefault(tuple(r[k] for k in keys), []).append(r)
    return out
