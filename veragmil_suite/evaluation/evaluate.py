"""Scoring agents on ScoopGranular food by food: evaluate() runs every (agent, food, episode) and writes the tables.

Episodes run in parallel worker processes, or as Ray tasks (veragmil_suite.utils.distributed), one piece per (agent,
food, episode); Ray workers are handed the piles settled on the driver, so an episode's outcome does not depend on where
it ran. Each record is journaled as it arrives, so a killed evaluation resumes where it stopped.
"""

from __future__ import annotations

import contextlib
import hashlib
import itertools
import json
import os
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path

from tqdm import tqdm

from veragmil_suite.environments.episode import SUCCESS_HOLD_S
from veragmil_suite.evaluation.agents import (
    DEFAULT_VIDEO_CAMERA,
    EXPERT_ROBOT,
    POLICY_DEVICES,
    SPEC_HELP,
    EpisodeRecord,
    EpisodeTask,
    EvaluationError,
    check_foods,
    dataset_episodes,
    driver_piles,
    env_metadata,
    episode_settings,
    init_worker,
    parse_spec,
    run_task,
    stale_pile_tasks,
)
from veragmil_suite.evaluation.reporting import EvaluationResult, json_safe, video_name
from veragmil_suite.learning.checkpoints import read_checkpoint, rnn_horizon_of
from veragmil_suite.models.humanoid import check_robot
from veragmil_suite.utils.canonical import canonical
from veragmil_suite.utils.distributed import Resources, WorkerLost, ray_session, run_pieces
from veragmil_suite.utils.host import host, outcome_platform, versions
from veragmil_suite.utils.numbers import seed_span_problem
from veragmil_suite.utils.whole_files import append_line, json_lines, write_text_whole


def evaluate(
    agents: dict[str, str],
    foods: list[str],
    episodes: int,
    processes: int = 2,
    seed: int = 0,
    horizon: int | None = None,
    videos: int = 0,
    output_dir: str | None = None,
    progress: bool = True,
    env_kwargs: dict | None = None,
    video_camera: str = DEFAULT_VIDEO_CAMERA,
    resume: bool = False,
    say: Callable[[str], None] | None = None,
    ray: str | None = None,
    robot: str | None = None,
    policy_device: str = "cpu",
    rnn_horizon: int | None = None,
    on_episode: Callable[[int], None] | None = None,
) -> EvaluationResult:
    """
    Scores each agent (name -> SPEC, see parse_spec) for ``episodes`` episodes per food, env seeds ``seed + i``.

    Every agent scoops with one robot: ``robot``, or by default the one the checkpoints were trained with
    (EXPERT_ROBOT when there are none); the scripted operators run on it.

    ``env_kwargs`` go to every environment (e.g. n_grains for a cheap scene); ``videos`` first episodes per
    (agent, food) are saved as mp4 under ``output_dir``/videos. Writes the outputs when ``output_dir`` is given,
    and journals each finished episode in ``output_dir``/episodes.jsonl as it ends: with ``resume``, episodes
    the journal holds (same agent SPEC, food, seed, horizon, env_kwargs and rnn horizon; their video, if asked
    for, on disk) are taken from it instead of run again, whatever the agent is named now, unless their record
    names a settled pile the environment no longer draws (agents.stale_pile_tasks): those run again.

    Episodes run in ``processes`` worker processes, or with ``ray`` (a cluster's address, or
    distributed.THIS_MACHINE) as Ray tasks of one CPU each, on the piles settled here; either way the journal and
    the outputs are written here as episodes end. Their checkpoints' networks run on ``policy_device`` (POLICY_DEVICES).
    With ``rnn_horizon`` the recurrent checkpoints (BC-RNN) reset their hidden state every ``rnn_horizon`` steps instead
    of their config's ``algo.rnn.horizon`` (robomimic's BC-RNN resets it every ``train.seq_length`` steps by default);
    the others run as they are. ``on_episode(journaled)`` runs after each episode this run scores and journals, with
    the number of episodes the journal held before this run: a caller that times the evaluation as it goes keeps the
    time of a run killed before its end (veragmil-study's timings.json).

    Raises:
        ValueError: [unknown food, bad agent SPEC, non-positive sizes, videos without output_dir, checkpoints of
            another robot, an unknown policy device, an rnn_horizon without a recurrent checkpoint]
        EvaluationError: [an episode failed in a worker (its traceback in the message)]
    """
    foods = check_foods(list(foods))
    specs = {name: parse_spec(spec) for name, spec in agents.items()}
    if not specs:
        raise ValueError(f"no agents to evaluate; an agent is {SPEC_HELP}")
    if int(episodes) < 1 or int(processes) < 1:
        raise ValueError(f"episodes and processes must be positive integers, got {episodes} and {processes}")
    if horizon is not None and int(horizon) < 1:
        raise ValueError(f"horizon must be a positive integer, got {horizon}")
    seeds_problem = seed_span_problem(seed, episodes)
    if seeds_problem:
        raise ValueError(seeds_problem)
    if videos and output_dir is None:
        raise ValueError("videos need an output_dir to be written to")
    if int(videos) > int(episodes):
        raise ValueError(f"videos {videos} is more than the {episodes} episodes per agent and food: give at most that")
    if policy_device not in POLICY_DEVICES:
        raise ValueError(f"policy device {policy_device!r}; accepted: {', '.join(POLICY_DEVICES)}")
    metas = {name: env_metadata(spec.target) for name, spec in specs.items() if spec.kind == "checkpoint"}
    rnn_horizons = _rnn_horizons(specs, rnn_horizon)
    robot = _evaluated_robot(metas, robot)
    if robot != EXPERT_ROBOT:
        env_kwargs = {**(env_kwargs or {}), "robots": robot}
    video_dir = Path(output_dir) / "videos" if output_dir is not None else None
    records: list[EpisodeRecord] = []
    tasks = []
    # episode-major order: every agent and food progresses together, and a slow food does not come last
    for i in range(int(episodes)):
        for name, spec in specs.items():
            if spec.kind == "dataset":
                continue
            for food in foods:
                video = str(video_dir / video_name(name, food, i)) if i < videos else None
                task = EpisodeTask(
                    name,
                    spec,
                    food,
                    i,
                    seed + i,
                    horizon,
                    dict(env_kwargs or {}),
                    video,
                    video_camera,
                    policy_device,
                    rnn_horizons.get(name),
                )
                tasks.append(task)
    for name, spec in specs.items():
        if spec.kind == "dataset":
            records += dataset_episodes(name, spec.target, foods)
    journal = Journal(Path(output_dir) / JOURNAL_NAME, resume) if output_dir is not None else None
    journaled = len(journal.records) if journal is not None else 0  # any agent's, from the runs before this one
    if journal is not None and journal.set_aside is not None and say is not None:
        say(journal.describe_set_aside())
    if journal is not None and resume:
        done = [(t, journal.get(t)) for t in tasks]
        stale = {id(t) for t in stale_pile_tasks([(t, r) for t, r in done if r is not None])}
        if stale and say is not None:
            say(
                f"{len(stale)} episodes journaled in {journal.path} ran on settled piles this code no longer draws "
                "(the lattice or the settling changed since): running them again"
            )
        reused = [replace(record, agent=t.agent) for t, record in done if record is not None and id(t) not in stale]
        tasks = [t for t, record in done if record is None or id(t) in stale]
        if reused and say is not None:
            say(f"skipping {len(reused)} evaluation episodes journaled in {journal.path}; {len(tasks)} to run")
        records += reused
    episodes_run = len(tasks)
    if tasks:
        with ray_session(ray) as address:
            done = (lambda: on_episode(journaled)) if on_episode is not None else None
            records += _run_parallel(tasks, int(processes), progress, journal, address is not None, done)
    order = {name: i for i, name in enumerate(specs)}
    records.sort(key=lambda r: (order[r.agent], foods.index(r.food), r.episode))
    horizon, env_kwargs = _recorded_settings(specs, metas, horizon, dict(env_kwargs or {}))
    config = dict(
        agents={name: str(spec) for name, spec in agents.items()},
        foods=foods,
        episodes=int(episodes),
        seed=int(seed),
        horizon=horizon,
        processes=int(processes),
        ray=ray is not None,
        videos=int(videos),
        video_camera=video_camera,
        env_kwargs=env_kwargs,
        robot=robot,
        success_hold_s=SUCCESS_HOLD_S,
        episodes_run=episodes_run,
        episodes_journaled=journaled,
        versions=versions(),
        host=host(),  # the machine that drove the evaluation (and, without Ray, ran its episodes)
    )
    if rnn_horizons:  # only when asked: the recurrent agents' reset period, by agent
        config["rnn_horizon"] = rnn_horizons
    result = EvaluationResult(records, list(specs), foods, config)
    if output_dir is not None:
        result.write(output_dir)
    return result


def _recorded_settings(
    specs: dict, metas: dict, horizon: int | None, env_kwargs: dict
) -> tuple[int | dict | None, dict]:
    """The horizon and env kwargs an evaluation records: those its episodes ran with, defaults resolved, so that two
    evaluations whose episodes are alike record alike however they were asked. A setting the agents do not share is
    recorded per agent ({name: value}). The episodes' journal keys keep the values as asked."""
    settings = {n: episode_settings(metas.get(n), horizon, env_kwargs) for n, s in specs.items() if s.kind != "dataset"}
    if not settings:
        return horizon, env_kwargs

    def shared(key: str) -> int | dict | str | None:
        values = {n: s[key] for n, s in settings.items()}
        return next(iter(values.values())) if len(set(values.values())) == 1 else values

    return shared("horizon"), {**env_kwargs, "physics": shared("physics")}


def _rnn_horizons(specs: dict, rnn_horizon: int | None) -> dict[str, int]:
    """The recurrent checkpoints' hidden-state reset periods by agent, when ``rnn_horizon`` overrides their
    configs'; a ValueError for a non-positive one or when no agent is a recurrent checkpoint."""
    if rnn_horizon is None:
        return {}
    if int(rnn_horizon) < 1:
        raise ValueError(f"rnn horizon must be a positive integer, got {rnn_horizon}")
    checkpoints = {n: s.target for n, s in specs.items() if s.kind == "checkpoint"}
    recurrent = [n for n, path in checkpoints.items() if rnn_horizon_of(read_checkpoint(path, weights=False))]
    if not recurrent:
        raise ValueError(
            "an rnn horizon applies to recurrent checkpoints (BC-RNN: algo.rnn.enabled), and no agent is one"
        )
    return {name: int(rnn_horizon) for name in recurrent}


def _evaluated_robot(metas: dict, robot: str | None) -> str:
    """The one robot of an evaluation: ``robot`` or the checkpoints' (``metas``: their env metadata by agent); a
    ValueError when a checkpoint's differs."""
    trained = {}
    for name, meta in metas.items():
        robots = meta["env_kwargs"].get("robots", EXPERT_ROBOT)
        trained[name] = robots[0] if isinstance(robots, (list, tuple)) else robots
    if robot is None:
        robot = next(iter(trained.values()), EXPERT_ROBOT)
    else:
        check_robot(robot)
    other = {name: r for name, r in trained.items() if r != robot}
    if other:
        described = ", ".join(f"{name} ({r})" for name, r in other.items())
        raise ValueError(
            f"every agent scoops with one robot, {robot}, but these checkpoints were trained with another: "
            f"{described}; evaluate them with --robot set to their robot, in a run of their own"
        )
    return robot


JOURNAL_NAME = "episodes.jsonl"


class Journal:
    """Finished episodes, one JSON line each, keyed by what decides their outcome (not the agent's name).

    The platform that scored them (veragmil_suite.utils.host.outcome_platform) is kept beside the journal
    (<journal>.platform.json): resuming on another platform sets the journal aside under a name of its own (its
    episodes can end otherwise here) and starts a new one. A journal without it is taken as this machine's. A run
    that does not resume sets an earlier run's journal aside too (``<stem>.replaced.jsonl``): finished episodes
    are never deleted.
    """

    def __init__(self, path: Path, resume: bool):
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self.records: dict[str, EpisodeRecord] = {}
        self.platform = outcome_platform()
        # (where, the platform that wrote it; None: set aside because this run does not resume)
        self.set_aside: tuple[Path, dict | None] | None = None
        if resume and self.path.exists():
            written_on = self._written_on()
            if written_on != self.platform:
                tag = hashlib.sha1(canonical(written_on).encode()).hexdigest()[:8]
                self.set_aside = (self._move_aside(tag, written_on), written_on)
            else:
                self._read()
        elif self.path.exists() and self.path.stat().st_size > 0:
            self.set_aside = (self._move_aside("replaced", self._written_on()), None)
        elif self.path.exists():
            self.path.unlink()
        write_text_whole(self._platform_path(self.path), json.dumps(self.platform, sort_keys=True) + "\n")

    @staticmethod
    def _platform_path(path: Path) -> Path:
        return path.with_name(path.name + ".platform.json")

    def _written_on(self) -> dict:
        platform_path = self._platform_path(self.path)
        if not platform_path.is_file():
            return self.platform
        try:
            return json.loads(platform_path.read_text())
        except ValueError:
            return {"platform": "unreadable"}

    def _move_aside(self, tag: str, written_on: dict) -> Path:
        names = (f"{self.path.stem}.{tag}{f'.{n}' if n else ''}{self.path.suffix}" for n in itertools.count())
        aside = next(p for p in map(self.path.with_name, names) if not p.exists())
        # the platform's record first: a kill between the two leaves no journal set aside without it
        write_text_whole(self._platform_path(aside), json.dumps(written_on, sort_keys=True) + "\n")
        self.path.rename(aside)
        return aside

    def _read(self) -> None:
        for entry in json_lines(self.path):  # an episode whose line is damaged runs again
            parts = json.loads(entry["key"])
            env_kwargs = parts[5]  # Journal.key's sixth part
            self.records[self._canonical_key(parts)] = EpisodeRecord.from_dict(entry["record"], env_kwargs)

    def describe_set_aside(self) -> str:
        """One line on a journal set aside: where it went, and how its platform differs from this one."""
        aside, written_on = self.set_aside
        if written_on is None:
            finished = len(aside.read_text().splitlines())
            return (
                f"{self.path} held {finished} episodes of an earlier run: kept as {aside}, not used "
                "(--resume takes them instead of running them again)"
            )
        differs = ", ".join(
            f"{k} {written_on.get(k, 'unknown')} (here {v})" for k, v in self.platform.items() if written_on.get(k) != v
        )
        return f"{self.path} was scored on another platform ({differs}): kept as {aside}, not resumed"

    @staticmethod
    def key(task: EpisodeTask) -> str:
        # _read takes the episode's env kwargs back from the sixth part
        parts = [task.spec.kind, task.spec.target, task.food, task.seed, task.horizon, task.env_kwargs]
        if task.video_path:
            parts += [task.video_path, task.video_camera]
        if task.policy_device != "cpu":
            parts += [task.policy_device]
        if task.rnn_horizon is not None:
            parts += [{"rnn_horizon": task.rnn_horizon}]
        return Journal._canonical_key(parts)

    @staticmethod
    def _canonical_key(parts: list) -> str:
        """The key with its files' paths absolute: a checkpoint or video named relative or absolute is one file."""
        parts = list(parts)
        if parts[0] != "expert":  # a checkpoint's or dataset's path, not a profile
            parts[1] = os.path.abspath(parts[1])
        if len(parts) >= 8 and str(parts[6]).endswith(".mp4"):  # a video's path and camera follow the env kwargs
            parts[6] = os.path.abspath(parts[6])
        return canonical(parts)

    def get(self, task: EpisodeTask) -> EpisodeRecord | None:
        record = self.records.get(self.key(task))
        if record is None or (task.video_path and not Path(task.video_path).is_file()):
            return None
        return replace(record, episode=task.episode)

    def add(self, task: EpisodeTask, record: EpisodeRecord) -> None:
        self.records[self.key(task)] = record
        append_line(self.path, json.dumps(dict(key=self.key(task), record=json_safe(record.to_dict()))))


def _run_parallel(
    tasks: list[EpisodeTask],
    processes: int,
    progress: bool,
    journal: Journal | None = None,
    on_ray: bool = False,
    on_episode: Callable[[], None] | None = None,
) -> list[EpisodeRecord]:
    """Runs the tasks in ``processes`` fresh worker processes, or as Ray tasks on the piles settled here, journaling
    each record as it arrives (then calling ``on_episode``); the first failure stops the run and is raised."""
    piles = driver_piles(tasks) if on_ray else None
    records = []
    pieces = run_pieces(
        run_task,
        tasks,
        context=piles,
        processes=min(processes, len(tasks)),  # no worker started for nothing to do
        on_ray=on_ray,
        setup=init_worker,
        resources=Resources(cpus=1),
    )
    with tqdm(total=len(tasks), desc="episodes", unit="ep", disable=not progress) as bar, contextlib.closing(pieces):
        try:
            for task, record in pieces:
                records.append(record)
                if journal is not None:
                    journal.add(task, record)
                if on_episode is not None:
                    on_episode()
                bar.update(1)
        except EvaluationError as error:
            bar.write(f"evaluation failed, stopping the workers: {error}")
            raise EvaluationError(str(error)) from None
        except WorkerLost as error:
            bar.write(f"evaluation failed, stopping the workers: {error}")
            raise EvaluationError(f"a worker process failed: {error}") from error
    return records
