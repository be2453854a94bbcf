"""
The paper's pipeline from scripted data: record demonstrations, train robomimic on them, evaluate the checkpoints.

Recording and training each run in a child process, their output kept in a log file beside their results:
recording calls, in a fresh interpreter, the function ``veragmil-collect --device scripted`` runs
(veragmil_suite.data.collection.record_scripted); training runs veragmil-train (robomimic's train.py) as a user
would type it. Evaluation goes through veragmil_suite.evaluation. veragmil-quickstart and veragmil-study are thin
command lines over this module.

A run resumes in its output directory: every piece that is complete is skipped (and said so), so an interrupted
or partial grid continues where it stopped and a larger one reuses the pieces of a smaller one.

- Recording: one file per profile and food, ``data/<profile>/<food>.hdf5``, complete once it holds the demos
  asked for (a shorter one, from a killed run, is recorded again: attempts are seeded, so the demos are the same).
  The foods' files are merged into ``data/<profile>.hdf5`` with a mask ``first<N>`` per demo count: the first N
  demos of each food, so smaller datasets are prefixes of larger ones. With ``drop_noops``, the models train on
  ``data/<profile>-no-noops.hdf5``, the merged file without its no-op steps, made again when the merged file changes.
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
import shutil
import time
from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING

from veragmil_suite.evaluation.evaluate import evaluate
from veragmil_suite.evaluation.reporting import write_learning_curves, write_seed_tables
from veragmil_suite.learning.algorithms import ALGORITHMS
from veragmil_suite.study.record import check_recordings, demo_mask, drop_noops_once, record_scripted_dataset
from veragmil_suite.study.settings import EVAL_SEED_OFFSET, PipelineSettings
from veragmil_suite.study.training import (
    finished_training,
    train_piece,
    trained_on_other_data,
    training_config,
    training_resources,
)
from veragmil_suite.utils.distributed import Resources, cluster_resources, ray_session, run_pieces
from veragmil_suite.utils.whole_files import write_text_whole

if TYPE_CHECKING:
    from veragmil_suite.evaluation.reporting import EvaluationResult

# what eval/ holds beside the evaluation's own tables: learning curves, and the tables over training seeds
CURVE_FILES = ("curves.csv", "curves.png")
SEED_FILES = ("seeds.csv", "seeds.md", "seeds")


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
                            out / "data" / settings.training_data(profile),
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
        check_recordings(settings, profile, out / "data" / f"{profile}.hdf5")
    for run in runs:
        finished_training(run["config"], out / "runs")


def run_pipeline(settings: PipelineSettings, progress: bool = True, verbose: bool = False) -> EvaluationResult:
    """Records one dataset per profile, trains every algorithm on each, evaluates them and the scripted operators,
    skipping every piece a previous run in the same output directory completed; with ``settings.ray``, on Ray.
    ``progress``: a line per stage and progress bars; ``verbose``: also what the recorders and trainings print.

    Returns the evaluation result (veragmil_suite.evaluation.reporting.EvaluationResult); everything is written under
    ``settings.output_dir``: data/, runs/, eval/ and timings.json.
    """
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
            write_text_whole(timings_file, json.dumps(timings, indent=2))

    with ray_session(settings.ray) as address:
        if address is not None:
            held = cluster_resources()
            cpus, gpus = held.get("CPU", 0), held.get("GPU", 0)
            say(f"running the pieces on Ray at {address} ({cpus:g} CPUs, {gpus:g} GPUs)")
        for profile in settings.profiles:
            counts = settings.demos_per_food
            say(f"recording {max(counts)} scripted '{profile}' demos of each of {settings.train_foods}")
            seconds = record_scripted_dataset(
                out / "data" / f"{profile}.hdf5",
                settings,
                profile,
                say=say,
                ray=address,
                progress=progress,
                echo=verbose,
            )
            note(f"record {profile}", seconds or None)
            if settings.drop_noops:
                drop_noops_once(out / "data" / f"{profile}.hdf5", out / "data" / settings.training_data(profile), say)
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
        # every agent on the study's physics (a checkpoint's own is the physics it was trained on, the same here)
        env_kwargs = {"physics": settings.physics}
        if settings.n_grains is not None:
            env_kwargs["n_grains"] = settings.n_grains
        # the evaluation's time over its pieces: a run that adds episodes to a journal (another seed, a resumed kill)
        # adds its time to the earlier runs'; a fully journaled evaluation keeps theirs; a fresh journal starts anew.
        # Noted after each episode, so a run killed mid-way leaves the time it spent.
        before = timings.get("evaluate", 0.0)
        start = time.perf_counter()

        def timed(journaled: int) -> None:
            note("evaluate", (before if journaled else 0.0) + time.perf_counter() - start)

        kwargs = dict(env_kwargs=env_kwargs, rnn_horizon=settings.rnn_horizon, on_episode=timed)
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
    if result.config["episodes_run"]:
        timed(result.config["episodes_journaled"])
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
            if trained_on_other_data(config, work_dir):
                say(f"training {name} again: {config['train']['data']} changed since it was trained")
            todo.append(run)

    def announced(todo: list[dict]) -> Iterator[dict]:
        for run in todo:
            steps = f"{run['config']['train']['num_epochs']} x {settings.steps_per_epoch}"
            dataset = Path(run["config"]["train"]["data"]).name
            label = f"{ALGORITHMS[run['algo']].label} ({run['obs_set']} obs)"
            say(f"training {label} on {run['demos_per_food']} demos per food of {dataset} ({steps} gradient steps)")
            yield run["config"]

    on_ray = address is not None
    resources = training_resources() if on_ray else Resources()
    # on Ray a run takes as many torch threads as it holds CPUs; here, those of $VERAGMIL_TORCH_THREADS or robomimic
    context = (work_dir, int(resources.cpus) if on_ray else None, progress and not on_ray, echo and not on_ray)
    pieces = run_pieces(train_piece, announced(todo), context=context, processes=0, on_ray=on_ray, resources=resources)
    with contextlib.closing(pieces):
        for config, (found, seconds) in pieces:
            checkpoints[config["experiment"]["name"]] = found
            note(f"train {config['experiment']['name']}", seconds)
    return checkpoints
