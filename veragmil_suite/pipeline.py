"""
The paper's pipeline from scripted data: record demonstrations, train robomimic on them, evaluate the checkpoints.

Each stage runs our own console programs in a child process (veragmil-collect, veragmil-train), exactly as a user
would type them, with its output kept in a log file beside its results; evaluation goes through
veragmil_suite.evaluation. veragmil-quickstart and veragmil-study are thin command lines over this module.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

from veragmil_suite.asset_paths import config_path
from veragmil_suite.foods import TRAINING_FOODS, UNSEEN_FOODS, get_food

# robomimic configs of configs/json per algorithm of the paper (low-dim observations)
ALGO_CONFIGS = {"bc": "bc", "bc_rnn": "bc_rnn", "bcq": "bcq"}
ALGO_LABELS = {"bc": "BC", "bc_rnn": "BC-RNN", "bcq": "BCQ"}

# Seeds of recorded episodes and of evaluation episodes never meet: evaluation bowls are not training bowls.
EVAL_SEED_OFFSET = 100_000
# Seeds of the foods' recordings are this far apart, so every demo of a dataset has its own bowl and pile.
FOOD_SEED_STRIDE = 1000


class StageError(RuntimeError):
    """A stage's child process failed; the message ends with the tail of its log."""


@dataclass
class PipelineSettings:
    """Sizes of one run: the small defaults finish in minutes on 2 cores; the paper's sizes are in the README."""

    output_dir: str
    profiles: list[str] = field(default_factory=lambda: ["expert"])
    algos: list[str] = field(default_factory=lambda: ["bc"])
    train_foods: list[str] = field(default_factory=lambda: list(TRAINING_FOODS))
    eval_foods: list[str] = field(default_factory=lambda: list(TRAINING_FOODS + UNSEEN_FOODS))
    demos_per_food: int = 2
    epochs: int = 20
    steps_per_epoch: int = 100
    episodes: int = 3
    processes: int = 2
    seed: int = 0
    horizon: int = 400
    n_grains: int | None = None
    score_demonstrators: bool = True

    def __post_init__(self):
        for food in [*self.train_foods, *self.eval_foods]:
            get_food(food)  # a ValueError naming the accepted foods
        unknown = sorted(set(self.algos) - set(ALGO_CONFIGS))
        if unknown:
            raise ValueError(f"unknown algorithm(s) {unknown}; accepted: {sorted(ALGO_CONFIGS)}")
        from veragmil_suite.expert import get_profile

        for profile in self.profiles:
            get_profile(profile)
        for name in ("demos_per_food", "epochs", "steps_per_epoch", "episodes", "processes", "horizon"):
            if int(getattr(self, name)) < 1:
                raise ValueError(f"{name} must be a positive integer, got {getattr(self, name)!r}")


def _run_logged(command: list[str], log_path: Path, what: str) -> float:
    """Runs a command with its output in ``log_path``; returns its wall time, raises StageError on failure."""
    env = dict(os.environ)
    env.setdefault("MUJOCO_GL", "osmesa")
    env.setdefault("PYNPUT_BACKEND", "dummy")
    start = time.perf_counter()
    with open(log_path, "w") as log:
        code = subprocess.call(command, stdout=log, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL, env=env)
    if code != 0:
        tail = log_path.read_text(errors="replace")[-3000:]
        raise StageError(f"{what} failed (exit {code}); log {log_path}:\n{tail}")
    return time.perf_counter() - start


def _console(name: str) -> list[str]:
    """A console program of this package, run with this interpreter (works without the venv on PATH)."""
    modules = {
        "veragmil-collect": "veragmil_suite.scripts.collect_human_demonstrations",
        "veragmil-train": "veragmil_suite.scripts.robomimic_entry",
    }
    command = [sys.executable, "-m", modules[name]]
    return [*command, "train"] if name == "veragmil-train" else command


def record_scripted_dataset(
    path: Path,
    foods: list[str],
    demos_per_food: int,
    profile: str = "expert",
    seed: int = 0,
    horizon: int = 400,
    n_grains: int | None = None,
    cameras: tuple[str, ...] = (),
) -> float:
    """Records ``demos_per_food`` successful scripted demos of each food into one HDF5 file; returns seconds."""
    path = Path(path)
    if path.exists():
        raise FileExistsError(f"{path} exists: the pipeline writes new datasets only (remove it or pick another)")
    elapsed = 0.0
    for i, food in enumerate(foods):
        command = [
            *_console("veragmil-collect"),
            *("--device", "scripted", "--profile", profile, "--food", food),
            *("--episodes", str(demos_per_food), "--output", str(path), "--seed", str(seed + i * FOOD_SEED_STRIDE)),
            *("--horizon", str(horizon), "--quiet", "--cameras", *cameras),
        ]
        if n_grains is not None:
            command += ["--n-grains", str(n_grains)]
        elapsed += _run_logged(command, path.with_suffix(f".{food}.log"), f"recording {food} ({profile})")
    return elapsed


def training_config(
    algo: str, dataset: Path, output_dir: Path, name: str, epochs: int, steps_per_epoch: int, seed: int = 1
) -> dict:
    """Our stock config of ``algo`` (configs/json) shortened to ``epochs`` x ``steps_per_epoch`` gradient steps.

    Rollouts during training are off (the evaluation scores the last checkpoint on every food afterwards) and the
    last epoch is saved.
    """
    if algo not in ALGO_CONFIGS:
        raise ValueError(f"unknown algorithm {algo!r}; accepted: {sorted(ALGO_CONFIGS)}")
    with open(config_path(ALGO_CONFIGS[algo])) as f:
        config = json.load(f)
    experiment = config["experiment"]
    experiment.update(name=name, epoch_every_n_steps=steps_per_epoch, validate=False, render_video=False)
    experiment["rollout"]["enabled"] = False
    experiment["save"].update(enabled=True, every_n_epochs=epochs, on_best_rollout_success_rate=False)
    config["train"].update(data=str(dataset), output_dir=str(output_dir), num_epochs=epochs, seed=seed)
    return config


def train_checkpoint(config: dict, work_dir: Path) -> tuple[Path, float]:
    """Trains with veragmil-train; returns the last checkpoint and the wall time."""
    work_dir = Path(work_dir)
    name = config["experiment"]["name"]
    config_file = work_dir / f"{name}.json"
    config_file.write_text(json.dumps(config, indent=4))
    seconds = _run_logged(
        [*_console("veragmil-train"), "--config", str(config_file)], work_dir / f"{name}.log", f"training {name}"
    )
    checkpoints = sorted(
        Path(config["train"]["output_dir"]).glob(f"{name}/*/models/*.pth"), key=lambda p: p.stat().st_mtime
    )
    if not checkpoints:
        raise StageError(f"training {name} wrote no checkpoint under {config['train']['output_dir']}/{name}")
    return checkpoints[-1], seconds


def run_pipeline(settings: PipelineSettings, progress: bool = True):
    """Records one dataset per profile, trains every algorithm on each, evaluates them and the scripted operators.

    Returns the evaluation result (veragmil_suite.evaluation.EvaluationResult); everything is written under
    ``settings.output_dir``: data/, runs/, eval/ and timings.json.
    """
    from veragmil_suite.evaluation import evaluate

    out = Path(settings.output_dir)
    (out / "data").mkdir(parents=True, exist_ok=True)
    (out / "runs").mkdir(parents=True, exist_ok=True)
    timings: dict[str, float] = {}
    agents: dict[str, str] = {}

    def say(message: str) -> None:
        if progress:
            print(f"[veragmil] {message}", flush=True)

    for profile in settings.profiles:
        dataset = out / "data" / f"{profile}.hdf5"
        say(f"recording {settings.demos_per_food} scripted '{profile}' demos of each of {settings.train_foods}")
        timings[f"record {profile}"] = record_scripted_dataset(
            dataset,
            settings.train_foods,
            settings.demos_per_food,
            profile=profile,
            seed=settings.seed,
            horizon=settings.horizon,
            n_grains=settings.n_grains,
        )
        if settings.score_demonstrators:
            # the demonstrator itself, live on every evaluated food: the paper's Human column (scripted here)
            agents[f"{profile} operator"] = f"expert:{profile}"
        for algo in settings.algos:
            name = f"{profile}_{algo}"
            config = training_config(
                algo, dataset, out / "runs", name, settings.epochs, settings.steps_per_epoch, seed=settings.seed + 1
            )
            steps = f"{settings.epochs} x {settings.steps_per_epoch}"
            say(f"training {ALGO_LABELS[algo]} on {dataset.name} ({steps} gradient steps)")
            checkpoint, timings[f"train {name}"] = train_checkpoint(config, out / "runs")
            agents[f"{profile} {ALGO_LABELS[algo]}"] = str(checkpoint)

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
        **kwargs,
    )
    timings["evaluate"] = time.perf_counter() - start
    (out / "timings.json").write_text(json.dumps({k: round(v, 1) for k, v in timings.items()}, indent=2))
    return result
