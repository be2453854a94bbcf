"""Agents and their episodes on ScoopGranular: what an agent spec names, and one episode of one agent on one food.

An agent is a robomimic checkpoint (``*.pth``), the scripted expert (``expert`` or ``expert:<profile>``) or a
recorded dataset (``dataset:<file.hdf5>``, e.g. human demonstrations: its demos' stored metrics, no rollouts).
Episode ``i`` of a food runs with env seed ``seed + i`` for every agent, so all agents meet the same bowls and piles.

An episode runs in the loop veragmil-collect records demonstrations with (veragmil_suite.environments.episode): it ends
once success has held for ``SUCCESS_HOLD_S``, at the horizon, when the agent gives up (the expert after its longest
hold) or at a physics error. Its success is that of the last step, as recorded demos store it. Each episode is one
EpisodeRecord, whose fields are the columns of episodes.csv and the keys of results.json and the journal.
"""

from __future__ import annotations

import contextlib
import copy
import inspect
import io
import json
import math
import os
import time
import traceback
from collections.abc import Callable
from dataclasses import MISSING as MISSING_FIELD
from dataclasses import asdict, dataclass, field, fields
from pathlib import Path

import numpy as np
import robosuite
import robosuite.macros

from veragmil_suite.data.recording import episode_metrics
from veragmil_suite.data.schema import VARIANTS_KEY, attr_text, demo_names, open_dataset
from veragmil_suite.devices.expert import PROFILES, ScriptedScooper
from veragmil_suite.environments import settling
from veragmil_suite.environments.episode import SUCCESS_HOLD_S, run_until_done
from veragmil_suite.environments.scoop import HEADLESS, ScoopGranular, headless
from veragmil_suite.environments.task_state import DEFAULT_SPILL_LIMIT
from veragmil_suite.learning import robomimic_compat
from veragmil_suite.learning.checkpoints import read_checkpoint, with_rnn_horizon
from veragmil_suite.learning.observation_sets import WRENCH_OBSERVATIONS
from veragmil_suite.models.foods import (
    FOODS,
    PRE_CALIBRATION_PHYSICS,
    TRAINING_FOODS,
    UNSEEN_FOODS,
    with_recorded_physics,
)
from veragmil_suite.utils.canonical import canonical
from veragmil_suite.utils.rendering import use_headless_rendering
from veragmil_suite.utils.whole_files import written_whole

ALL_FOODS: tuple[str, ...] = TRAINING_FOODS + UNSEEN_FOODS
# the robot of the expert's environment (checkpoints bring their own env_args)
EXPERT_ROBOT = "XArm7"
VIDEO_SIZE = 256
DEFAULT_VIDEO_CAMERA = "overhead"
# env_kwargs of a checkpoint's training data that describe its food, not the robot: replaced per evaluated food
FOOD_KWARGS = ("food", "n_grains", "seed")
MISSING = "-"


@dataclass(frozen=True)
class EpisodeRecord:
    """
    One scored episode. Its fields, in this order, are the columns of episodes.csv and the keys of an episode in
    results.json and in the journal (episodes.jsonl), so the three cannot drift apart.
    """

    agent: str
    food: str
    episode: int
    seed: int | None  # None: a recorded demo without a stored seed
    success: bool
    grains_spilled: int
    spilled_volume_cm3: float
    completion_time_s: float
    steps: int
    end_reason: str
    physics_error: str
    grains_in_spoon: int
    spill_fraction: float
    stage: str
    peak_grains_in_spoon: int | None  # None: a recorded demo (its steps' loads are not stored)
    wall_s: float
    spilled_mass_g: float = math.nan  # NaN: recorded before masses were
    spoon_mass_g: float = math.nan
    physics: str = PRE_CALIBRATION_PHYSICS  # the grain models it ran on; records that name none predate the choice
    spill_limit_of: str = DEFAULT_SPILL_LIMIT  # what the success rule's spill limit was a fraction of (as physics)
    pile: str = ""  # the settled pile's cache key (settling.pile_key); "": unknown (a demo, or recorded before)

    @classmethod
    def columns(cls) -> tuple[str, ...]:
        """The field names, in order: episodes.csv's header."""
        return tuple(f.name for f in fields(cls))

    def to_dict(self) -> dict:
        return asdict(self)

    @classmethod
    def from_dict(cls, values: dict, env_kwargs: dict | None = None) -> EpisodeRecord:
        """The record a to_dict gave (read back from a journal or results.json); KeyError names a missing field.
        A record written before its spill limit was recorded takes the one of ``env_kwargs`` (those it ran with)."""
        values = {"spill_limit_of": (env_kwargs or {}).get("spill_limit_of", DEFAULT_SPILL_LIMIT), **values}
        optional = {f.name for f in fields(cls) if f.default is not MISSING_FIELD}
        return cls(**{name: values[name] for name in cls.columns() if name in values or name not in optional})


class EvaluationError(RuntimeError):
    """An episode failed in a worker; the message carries the worker's traceback."""


@dataclass(frozen=True)
class AgentSpec:
    """What an agent column scores: kind "checkpoint", "expert" or "dataset", and its path or profile."""

    kind: str
    target: str

    @property
    def default_name(self) -> str:
        if self.kind == "expert":
            return "expert" if self.target == "expert" else f"expert:{self.target}"
        return Path(self.target).stem


SPEC_HELP = "a robomimic checkpoint (*.pth), 'expert', 'expert:<profile>' or 'dataset:<file.hdf5>'"


def parse_spec(spec: str) -> AgentSpec:
    """An agent SPEC, checked now so a bad one fails before any work; ValueError names the accepted forms."""
    spec = str(spec).strip()
    if spec == "expert" or spec.startswith("expert:"):
        profile = spec.partition(":")[2] or "expert"
        if profile not in PROFILES:
            accepted = ", ".join(PROFILES)
            raise ValueError(f"unknown expert profile {profile!r} in {spec!r}; accepted profiles: {accepted}")
        return AgentSpec("expert", profile)
    if spec.startswith("dataset:"):
        path = spec[len("dataset:") :]
        if not Path(path).is_file():
            raise ValueError(f"dataset {path!r} not found (agent {spec!r}); an agent is {SPEC_HELP}")
        try:
            open_dataset(path).close()
        except Exception as e:  # noqa: BLE001 - any unreadable file is a bad agent, named with the reason
            raise ValueError(f"agent {spec!r}: {e}") from e
        return AgentSpec("dataset", path)
    if spec.endswith(".pth"):
        if not Path(spec).is_file():
            raise ValueError(f"checkpoint {spec!r} not found; an agent is {SPEC_HELP}")
        return AgentSpec("checkpoint", spec)
    raise ValueError(f"unrecognized agent {spec!r}; an agent is {SPEC_HELP}")


def parse_agent_argument(text: str) -> tuple[str, str]:
    """``NAME=SPEC`` or ``SPEC`` (named after the checkpoint's file stem, "expert" or the dataset's stem) as
    (name, SPEC), the SPEC checked."""
    name, sep, spec = text.partition("=")
    if not sep or not name or name.startswith(("dataset:", "expert:")) or "/" in name:
        return parse_spec(text).default_name, text
    parse_spec(spec)
    return name, spec


def check_foods(foods: list[str]) -> list[str]:
    """The foods to evaluate, each known; ValueError names the accepted ones."""
    accepted = ", ".join(dict.fromkeys([*ALL_FOODS, *FOODS]))  # seen, unseen, then any registered later
    if isinstance(foods, str):
        raise ValueError(f"foods must be a list of food names, got one name: {foods!r} (give [{foods!r}])")
    unknown = [f for f in foods if not isinstance(f, str) or f not in FOODS]
    if unknown:
        raise ValueError(f"unknown food(s) {', '.join(unknown)}; accepted foods: {accepted}")
    if not foods:
        raise ValueError(f"no foods to evaluate; accepted foods: {accepted}")
    return list(dict.fromkeys(foods))


@dataclass(frozen=True)
class EpisodeTask:
    """One (agent, food, episode) for a worker."""

    agent: str
    spec: AgentSpec
    food: str
    episode: int
    seed: int
    horizon: int | None = None
    env_kwargs: dict = field(default_factory=dict)
    video_path: str | None = None
    video_camera: str = DEFAULT_VIDEO_CAMERA
    policy_device: str = "cpu"
    rnn_horizon: int | None = None  # a recurrent checkpoint's hidden-state reset period (None: its config's)


_POLICIES: dict = {}  # per worker process: (checkpoint path, device, rnn horizon) -> (RolloutPolicy, checkpoint dict)
POLICY_DEVICES = ("cpu", "cuda")  # where a worker runs a checkpoint's networks (EpisodeTask.policy_device)


def init_worker() -> None:
    """Each worker runs one episode at a time on one core: one torch thread (set when a checkpoint first imports
    torch, so expert-only workers start without it), software rendering."""
    use_headless_rendering(force=True)
    os.environ["VERAGMIL_TORCH_THREADS"] = "1"
    os.environ["OMP_NUM_THREADS"] = "1"


EXPERT_KWARGS = dict(robots=EXPERT_ROBOT, has_renderer=False, use_camera_obs=False)


def _env_kwargs(task: EpisodeTask, base: dict) -> dict:
    """robosuite.make keyword arguments of a task's environment: ``base`` (the expert's robot, or the env of a
    checkpoint's training data less its food), the task's env_kwargs, then its food, seed and horizon."""
    kwargs = dict(base)
    kwargs.update(task.env_kwargs)
    kwargs.update(food=task.food, seed=task.seed)
    if task.horizon is not None:
        kwargs["horizon"] = task.horizon
    return kwargs


def checkpoint_base_kwargs(env_meta: dict) -> dict:
    """A checkpoint's training env kwargs less those that describe its food, with its physics named (a checkpoint
    that names none was trained on PRE_CALIBRATION_PHYSICS, whatever the default is now)."""
    return {k: v for k, v in with_recorded_physics(env_meta["env_kwargs"]).items() if k not in FOOD_KWARGS}


def episode_settings(env_meta: dict | None, horizon: int | None, env_kwargs: dict) -> dict:
    """The horizon and physics an agent's episodes run with when given ``horizon`` and ``env_kwargs``: those asked
    for, else its environment's own (``env_meta``, a checkpoint's training env; None: ScoopGranular's defaults,
    as the expert runs)."""
    base = EXPERT_KWARGS if env_meta is None else checkpoint_base_kwargs(env_meta)
    kwargs = {**base, **env_kwargs}
    defaults = inspect.signature(ScoopGranular.__init__).parameters
    if horizon is None:
        horizon = kwargs.get("horizon", defaults["horizon"].default)
    return dict(horizon=int(horizon), physics=kwargs.get("physics", defaults["physics"].default))


def _expert_env(task: EpisodeTask):
    import veragmil_suite  # noqa: F401  (registers ScoopGranular in a worker; the package imports this module)

    kwargs = _env_kwargs(task, EXPERT_KWARGS)
    kwargs["has_offscreen_renderer"] = bool(task.video_path)
    env = robosuite.make("ScoopGranular", **kwargs)
    expert = ScriptedScooper(env, task.spec.target, seed=task.seed)
    obs = env.reset()
    expert.reset()
    return env, obs, expert.agent, env.step


def _policy(path: str, device: str = "cpu", rnn_horizon: int | None = None):
    key = (path, device, rnn_horizon)
    if key not in _POLICIES:
        import torch  # heavy: torch, only when used

        torch.set_num_threads(int(os.environ.get("VERAGMIL_TORCH_THREADS", "1")))
        ckpt = None if rnn_horizon is None else with_rnn_horizon(read_checkpoint(path), rnn_horizon)

        # robomimic's banner of observation keys, printed by every worker that loads a policy
        with contextlib.redirect_stdout(io.StringIO()):
            robomimic_compat.install()
            import robomimic.utils.file_utils as FileUtils  # heavy: robomimic, imports torch

            _POLICIES[key] = FileUtils.policy_from_checkpoint(
                ckpt_path=path, ckpt_dict=ckpt, device=torch.device(device)
            )
    return _POLICIES[key]


def _checkpoint_env(task: EpisodeTask):
    """robomimic's env of the checkpoint (its robot, controller and control rate) on the evaluated food."""
    robomimic_compat.install()
    import robomimic.utils.env_utils as EnvUtils  # heavy: robomimic, imports torch
    import torch  # heavy: torch, only when used

    policy, ckpt = _policy(task.spec.target, task.policy_device, task.rnn_horizon)
    meta = copy.deepcopy(ckpt["env_metadata"])
    meta["env_kwargs"] = _env_kwargs(task, checkpoint_base_kwargs(meta))
    if set(ckpt["shape_metadata"]["all_obs_keys"]) & set(WRENCH_OBSERVATIONS):
        meta["env_kwargs"]["use_wrench_obs"] = True  # a policy that reads the wrist sensor, whatever its data named
    # a multi-food dataset's variants make robomimic's rollouts take its foods in turn at each reset; an evaluated
    # episode is on its own food
    meta.pop(VARIANTS_KEY, None)
    use_images = bool(ckpt["shape_metadata"]["use_images"])
    with contextlib.redirect_stdout(io.StringIO()):  # robomimic prints each env it creates
        env = EnvUtils.create_env_from_metadata(
            env_meta=meta, render=False, render_offscreen=bool(task.video_path), use_image_obs=use_images
        )
    torch.manual_seed(task.seed)
    np.random.seed(task.seed)
    policy.start_episode()
    obs = env.reset()
    return env.env, obs, lambda o: policy(ob=o), env.step


def episode_env(
    task: EpisodeTask,
) -> tuple[ScoopGranular, dict, Callable[[dict], np.ndarray | None], Callable[[np.ndarray], tuple]]:
    """A task's environment reset for its episode, its first observation, the agent's act(obs) and the env's step:
    the scripted operator's or the checkpoint's (what run_episode runs; probes step it themselves)."""
    return (_expert_env if task.spec.kind == "expert" else _checkpoint_env)(task)


def run_episode(task: EpisodeTask) -> EpisodeRecord:
    """Runs one episode of a checkpoint or expert agent; returns its record."""
    start = time.perf_counter()
    env, obs, act, step = episode_env(task)
    if env.food.name != task.food:
        raise RuntimeError(f"{task.agent}'s environment holds {env.food.name} where the task asked for {task.food}")
    frames = []

    def grab() -> None:
        frame = env.sim.render(camera_name=task.video_camera, width=VIDEO_SIZE, height=VIDEO_SIZE)
        frames.append(frame[::-1] if robosuite.macros.IMAGE_CONVENTION == "opengl" else frame)

    if task.video_path:
        grab()
    horizon = task.horizon if task.horizon is not None else int(env.horizon)
    end = run_until_done(act, step, obs, env.control_freq, horizon, SUCCESS_HOLD_S, grab if task.video_path else None)
    env.close()
    if task.video_path:
        import imageio  # imageio takes ~80 ms to import: only when writing videos

        Path(task.video_path).parent.mkdir(parents=True, exist_ok=True)
        with written_whole(task.video_path, keep_suffix=True) as partial:
            imageio.mimsave(partial, frames, fps=env.control_freq)
    metrics = episode_metrics(end.info, end.stage)
    return EpisodeRecord(
        agent=task.agent,
        food=task.food,
        episode=task.episode,
        seed=task.seed,
        success=metrics["success"],
        grains_spilled=metrics["grains_spilled"],
        spilled_volume_cm3=metrics["spilled_volume_cm3"],
        completion_time_s=metrics["completion_time_s"],
        steps=end.steps,
        end_reason=end.reason,
        physics_error=metrics["physics_error"],
        grains_in_spoon=metrics["grains_in_spoon"],
        spill_fraction=metrics["spill_fraction"],
        stage=metrics["stage"],
        peak_grains_in_spoon=end.peak_grains_in_spoon,
        wall_s=time.perf_counter() - start,
        spilled_mass_g=metrics["spilled_mass_g"],
        spoon_mass_g=metrics["spoon_mass_g"],
        physics=env.physics,
        spill_limit_of=env.spill_limit_of,
        pile=env.pile_key,
    )


def run_task(piles: dict | None, task: EpisodeTask) -> EpisodeRecord:
    """Worker entry: the record, or an EvaluationError carrying this process's traceback. ``piles``: the driver's
    settled piles (on Ray), which the episode's environment takes instead of settling its own."""
    try:
        settling.use_shipped_piles(piles)
        return run_episode(task)
    except Exception as e:  # noqa: BLE001 - re-raised in the parent with the worker's traceback
        where = f"{task.agent} on {task.food}, episode {task.episode} (seed {task.seed})"
        raise EvaluationError(f"{where} failed in a worker:\n{traceback.format_exc()}") from e


def driver_piles(tasks: list[EpisodeTask]) -> dict:
    """
    Every pile variant the tasks' environments can draw, settled on this machine (or read from its cache), by
    cache key: Ray workers score their episodes on these, whatever their CPU (settling.use_shipped_piles).
    """
    piles: dict = {}
    for _, env in _task_environments(tasks):
        piles.update(env.settled_piles())
    return piles


def stale_pile_tasks(done: list[tuple[EpisodeTask, EpisodeRecord]]) -> list[EpisodeTask]:
    """The journaled episodes (``done``: task and record) whose record names a settled pile that the task's
    environment no longer draws: a change to the lattice or the settling since they ran. Records that name no pile
    (journaled before piles were named) are taken as they are."""
    named = {id(task): record.pile for task, record in done if record.pile}
    stale = []
    for group, env in _task_environments([task for task, _ in done if id(task) in named]):
        drawn = env.pile_keys()
        stale += [task for task in group if named[id(task)] not in drawn]
    return stale


def _task_environments(tasks: list[EpisodeTask]):
    """One environment per distinct setting of the tasks' environments (any seed: the seed draws one of the
    variants, which settled_piles and pile_keys cover), yielded with its tasks and closed after."""
    import veragmil_suite  # noqa: F401  (registers ScoopGranular in a worker; the package imports this module)

    bases: dict[str, dict] = {}
    groups: dict[str, tuple[dict, list[EpisodeTask]]] = {}
    for task in tasks:
        target = task.spec.target
        if target not in bases:
            bases[target] = (
                EXPERT_KWARGS if task.spec.kind == "expert" else checkpoint_base_kwargs(env_metadata(target))
            )
        kwargs = _env_kwargs(task, bases[target])
        groups.setdefault(canonical({**kwargs, **HEADLESS}), (kwargs, []))[1].append(task)
    for kwargs, group in groups.values():
        with headless(kwargs) as env:
            yield group, env


def env_metadata(path: str) -> dict:
    """A checkpoint's env metadata, read without building its policy or importing robomimic (a resumed study with
    nothing left to do spent 6-7 of its 10 s importing robomimic for this)."""
    return read_checkpoint(path, weights=False)["env_metadata"]


def dataset_episodes(name: str, path: str, foods: list[str]) -> list[EpisodeRecord]:
    """A recorded dataset's demos as episode records (their stored metrics), for the foods evaluated."""
    out = []
    with open_dataset(path) as f:
        data = f["data"]
        file_kwargs = with_recorded_physics(json.loads(data.attrs["env_args"]).get("env_kwargs", {}))
        file_food = file_kwargs.get("food", "")
        counts: dict[str, int] = {}
        for demo in demo_names(f):
            a = data[demo].attrs
            food = attr_text(a.get("food", file_food))
            if food not in foods:
                continue
            index = counts[food] = counts.get(food, -1) + 1
            steps = int(a["num_samples"])
            out.append(
                EpisodeRecord(
                    agent=name,
                    food=food,
                    episode=index,
                    seed=int(a["seed"]) if "seed" in a else None,
                    success=bool(a.get("success", False)),
                    grains_spilled=int(a.get("grains_spilled", 0)),
                    spilled_volume_cm3=float(a.get("spilled_volume_cm3", 0.0)),
                    completion_time_s=float(a.get("completion_time_s", 0.0)),
                    steps=steps,
                    end_reason=attr_text(a.get("end_reason", "recorded")),
                    physics_error=attr_text(a.get("physics_error", "")),
                    grains_in_spoon=int(a.get("grains_in_spoon", 0)),
                    spill_fraction=float(a.get("spill_fraction", 0.0)),
                    stage=attr_text(a.get("stage", MISSING)),
                    peak_grains_in_spoon=None,
                    wall_s=0.0,
                    spilled_mass_g=float(a.get("spilled_mass_g", math.nan)),
                    spoon_mass_g=float(a.get("spoon_mass_g", math.nan)),
                    physics=file_kwargs["physics"],
                    spill_limit_of=file_kwargs.get("spill_limit_of", DEFAULT_SPILL_LIMIT),
                )
            )
    return out
