"""
Scoring agents on ScoopGranular and writing the paper's Tables II and III.

An agent is a robomimic checkpoint (``*.pth``), the scripted expert (``expert`` or ``expert:<profile>``) or a
recorded dataset (``dataset:<file.hdf5>``, e.g. human demonstrations: its demos' stored metrics, no rollouts).
Episode ``i`` of a food runs with env seed ``seed + i`` for every agent, so all agents meet the same bowls and piles.
Episodes run in parallel worker processes, or as Ray tasks (veragmil_suite.utils.distributed), one piece per (agent,
food, episode); Ray workers are handed the piles settled on the driver, so an episode's outcome does not depend on where
it ran.

An episode runs in the loop veragmil-collect records demonstrations with (veragmil_suite.environments.episode): it ends
once success has held for ``SUCCESS_HOLD_S``, at the horizon, when the agent gives up (the expert after its longest
hold) or at a physics error. Its success is that of the last step, as recorded demos store it. Each episode is one
EpisodeRecord, whose fields are the columns of episodes.csv and the keys of results.json and the journal.

Table II: success % per food, grouped seen (training) / unseen, with per-group and overall averages (each food
weighs the same). Table III: spilled pieces (mean +- std over all episodes) and completion time. The paper reports
the time of successful runs, so a failure's time (its episode length, kept in episodes.csv) is left out of the
mean; with no success the cell is "-" (NaN in table.csv).
"""

from __future__ import annotations

import contextlib
import copy
import csv
import io
import json
import math
import os
import time
import traceback
from collections.abc import Callable
from dataclasses import MISSING as MISSING_FIELD
from dataclasses import asdict, dataclass, field, fields, replace
from pathlib import Path

import numpy as np

from veragmil_suite.environments.episode import SUCCESS_HOLD_S, run_until_done
from veragmil_suite.models.foods import TRAINING_FOODS, UNSEEN_FOODS
from veragmil_suite.utils.distributed import Resources, WorkerLost, ray_session, run_pieces
from veragmil_suite.utils.rendering import use_headless_rendering

ALL_FOODS: tuple[str, ...] = TRAINING_FOODS + UNSEEN_FOODS
SEEN_LABEL = "seen (training)"
UNSEEN_LABEL = "unseen"
# the robot of the expert's environment (checkpoints bring their own env_args)
EXPERT_ROBOT = "XArm7"
VIDEO_SIZE = 256
DEFAULT_VIDEO_CAMERA = "overhead"
# env_kwargs of a checkpoint's training data that describe its food, not the robot: replaced per evaluated food
FOOD_KWARGS = ("food", "n_grains", "seed")
MISSING = "-"
# 95% two-sided normal quantile, for the Wilson intervals of success rates
WILSON_Z = 1.959964


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

    @classmethod
    def columns(cls) -> tuple[str, ...]:
        """The field names, in order: episodes.csv's header."""
        return tuple(f.name for f in fields(cls))

    def to_dict(self) -> dict:
        return asdict(self)

    @classmethod
    def from_dict(cls, values: dict) -> EpisodeRecord:
        """The record a to_dict gave (read back from the journal); KeyError names a missing field."""
        optional = {f.name for f in fields(cls) if f.default is not MISSING_FIELD}
        return cls(**{name: values[name] for name in cls.columns() if name in values or name not in optional})


class EvaluationError(RuntimeError):
    """An episode failed in a worker; the message carries the worker's traceback."""


# ---------------------------------------------------------------------------------------------------------------- #
# Agents                                                                                                           #
# ---------------------------------------------------------------------------------------------------------------- #


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
    from veragmil_suite.devices.expert import PROFILES

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
        from veragmil_suite.data.recording import open_dataset

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
    from veragmil_suite.models.foods import FOODS

    accepted = ", ".join(dict.fromkeys([*ALL_FOODS, *FOODS]))  # seen, unseen, then any registered later
    unknown = [f for f in foods if f not in FOODS]
    if unknown:
        raise ValueError(f"unknown food(s) {', '.join(unknown)}; accepted foods: {accepted}")
    if not foods:
        raise ValueError(f"no foods to evaluate; accepted foods: {accepted}")
    return list(dict.fromkeys(foods))


# ---------------------------------------------------------------------------------------------------------------- #
# One episode                                                                                                      #
# ---------------------------------------------------------------------------------------------------------------- #


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


_POLICIES: dict = {}  # per worker process: checkpoint path -> (RolloutPolicy, checkpoint dict)


def _init_worker() -> None:
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


def _checkpoint_base(env_meta: dict) -> dict:
    """A checkpoint's training env kwargs less those that describe its food."""
    return {k: v for k, v in env_meta["env_kwargs"].items() if k not in FOOD_KWARGS}


def _expert_env(task: EpisodeTask):
    import robosuite

    import veragmil_suite  # noqa: F401
    from veragmil_suite.devices.expert import ScriptedScooper

    kwargs = _env_kwargs(task, EXPERT_KWARGS)
    kwargs["has_offscreen_renderer"] = bool(task.video_path)
    env = robosuite.make("ScoopGranular", **kwargs)
    expert = ScriptedScooper(env, task.spec.target, seed=task.seed)
    obs = env.reset()
    expert.reset()
    return env, obs, expert.agent, env.step


def _policy(path: str):
    if path not in _POLICIES:
        import torch

        torch.set_num_threads(int(os.environ.get("VERAGMIL_TORCH_THREADS", "1")))

        from veragmil_suite.learning import robomimic_compat

        # robomimic's banner of observation keys, printed by every worker that loads a policy
        with contextlib.redirect_stdout(io.StringIO()):
            robomimic_compat.install()
            import robomimic.utils.file_utils as FileUtils

            _POLICIES[path] = FileUtils.policy_from_checkpoint(ckpt_path=path, device=torch.device("cpu"))
    return _POLICIES[path]


def _checkpoint_env(task: EpisodeTask):
    """robomimic's env of the checkpoint (its robot, controller and control rate) on the evaluated food."""
    import robomimic.utils.env_utils as EnvUtils
    import torch

    policy, ckpt = _policy(task.spec.target)
    meta = copy.deepcopy(ckpt["env_metadata"])
    meta["env_kwargs"] = _env_kwargs(task, _checkpoint_base(meta))
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


def run_episode(task: EpisodeTask) -> EpisodeRecord:
    """Runs one episode of a checkpoint or expert agent; returns its record."""
    from veragmil_suite.data.recording import episode_metrics

    start = time.perf_counter()
    make = _expert_env if task.spec.kind == "expert" else _checkpoint_env
    env, obs, act, step = make(task)
    frames = []

    def grab() -> None:
        import robosuite.macros

        frame = env.sim.render(camera_name=task.video_camera, width=VIDEO_SIZE, height=VIDEO_SIZE)
        frames.append(frame[::-1] if robosuite.macros.IMAGE_CONVENTION == "opengl" else frame)

    if task.video_path:
        grab()
    horizon = task.horizon if task.horizon is not None else int(env.horizon)
    end = run_until_done(act, step, obs, env.control_freq, horizon, SUCCESS_HOLD_S, grab if task.video_path else None)
    env.close()
    if task.video_path:
        import imageio

        Path(task.video_path).parent.mkdir(parents=True, exist_ok=True)
        imageio.mimsave(task.video_path, frames, fps=env.control_freq)
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
    )


def _run_task(piles: dict | None, task: EpisodeTask) -> EpisodeRecord:
    """Worker entry: the record, or an EvaluationError carrying this process's traceback. ``piles``: the driver's
    settled piles (on Ray), which the episode's environment takes instead of settling its own."""
    from veragmil_suite.environments import settling

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
    import robosuite

    import veragmil_suite  # noqa: F401

    bases: dict[str, dict] = {}
    built: set[str] = set()
    piles: dict = {}
    for task in tasks:
        target = task.spec.target
        if target not in bases:
            bases[target] = EXPERT_KWARGS if task.spec.kind == "expert" else _checkpoint_base(_env_metadata(target))
        kwargs = _env_kwargs(task, bases[target])
        # the seed draws one variant; settled_piles settles them all
        kwargs.update(seed=0, has_renderer=False, has_offscreen_renderer=False, use_camera_obs=False)
        key = json.dumps(kwargs, sort_keys=True, default=str)
        if key in built:
            continue
        built.add(key)
        env = robosuite.make("ScoopGranular", **kwargs)
        piles.update(env.settled_piles())
        env.close()
    return piles


def _env_metadata(path: str) -> dict:
    """A checkpoint's env metadata, read without building its policy."""
    from veragmil_suite.learning import robomimic_compat

    robomimic_compat.install()
    import robomimic.utils.file_utils as FileUtils

    return FileUtils.load_dict_from_checkpoint(path)["env_metadata"]


def dataset_episodes(name: str, path: str, foods: list[str]) -> list[EpisodeRecord]:
    """A recorded dataset's demos as episode records (their stored metrics), for the foods evaluated."""
    from veragmil_suite.data.recording import demo_names, open_dataset

    out = []
    with open_dataset(path) as f:
        data = f["data"]
        file_food = json.loads(data.attrs["env_args"]).get("env_kwargs", {}).get("food", "")
        counts: dict[str, int] = {}
        for demo in demo_names(f):
            a = data[demo].attrs
            food = _text(a.get("food", file_food))
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
                    end_reason=_text(a.get("end_reason", "recorded")),
                    physics_error=_text(a.get("physics_error", "")),
                    grains_in_spoon=int(a.get("grains_in_spoon", 0)),
                    spill_fraction=float(a.get("spill_fraction", 0.0)),
                    stage=_text(a.get("stage", MISSING)),
                    peak_grains_in_spoon=None,
                    wall_s=0.0,
                    spilled_mass_g=float(a.get("spilled_mass_g", math.nan)),
                    spoon_mass_g=float(a.get("spoon_mass_g", math.nan)),
                )
            )
    return out


def _text(value) -> str:
    return value.decode() if isinstance(value, bytes) else str(value)


# ---------------------------------------------------------------------------------------------------------------- #
# Summaries and tables                                                                                             #
# ---------------------------------------------------------------------------------------------------------------- #


def wilson_interval(successes: int, n: int, z: float = WILSON_Z) -> tuple[float, float]:
    """The Wilson score interval of a success rate (95% by default), as fractions; (nan, nan) for n = 0.

    Unlike the normal approximation it stays inside [0, 1] and is not empty at 0 or n successes, which 20
    episodes often give.
    """
    if n <= 0:
        return math.nan, math.nan
    p = successes / n
    centre = (p + z * z / (2 * n)) / (1 + z * z / n)
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / (1 + z * z / n)
    return max(0.0, centre - half), min(1.0, centre + half)


def summarize(episodes: list[EpisodeRecord]) -> dict[tuple[str, str], dict]:
    """Per (agent, food): success rate, spilled pieces mean and std (all episodes), completion time over successes."""
    out = {}
    for key in dict.fromkeys((e.agent, e.food) for e in episodes):
        rows = [e for e in episodes if (e.agent, e.food) == key]
        ok = [e for e in rows if e.success]
        spilled = np.array([e.grains_spilled for e in rows], dtype=float)
        times = np.array([e.completion_time_s for e in ok], dtype=float)
        out[key] = dict(
            agent=key[0],
            food=key[1],
            episodes=len(rows),
            successes=len(ok),
            success_rate=len(ok) / len(rows),
            success_ci95=wilson_interval(len(ok), len(rows)),
            grains_spilled_mean=float(spilled.mean()),
            grains_spilled_std=float(spilled.std()),
            spilled_volume_cm3_mean=float(np.mean([e.spilled_volume_cm3 for e in rows])),
            spilled_mass_g_mean=float(np.mean([e.spilled_mass_g for e in rows])),
            spoon_mass_g_mean=float(np.mean([e.spoon_mass_g for e in rows])),
            completion_time_s_mean=float(times.mean()) if ok else math.nan,
            completion_time_s_std=float(times.std()) if ok else math.nan,
            physics_errors=sum(bool(e.physics_error) for e in rows),
            stages={stage: sum(e.stage == stage for e in rows) for stage in _stage_columns(rows)},
        )
    return out


def _stage_columns(rows: list[EpisodeRecord]) -> list[str]:
    """SCOOP_STAGES, and "-" for recorded demos that predate stage labels (only when there are any)."""
    from veragmil_suite.environments.scoop import SCOOP_STAGES

    return [*SCOOP_STAGES] + ([MISSING] if any(r.stage not in SCOOP_STAGES for r in rows) else [])


def stage_table(summary: dict, agents: list[str], foods: list[str], fmt: str = "markdown") -> str:
    """
    Where episodes stopped: per agent and food, how many ended at each furthest stage (SCOOP_STAGES, "held" being
    success), as markdown or CSV.
    """
    columns = list(dict.fromkeys(c for s in summary.values() for c in s["stages"]))
    rows = [(a, f, summary[(a, f)]) for a in agents for f in foods if (a, f) in summary]
    if fmt == "csv":
        buf = io.StringIO()
        writer = csv.writer(buf, lineterminator="\n")
        writer.writerow(["agent", "food", "episodes", *columns])
        for a, f, s in rows:
            writer.writerow([a, f, s["episodes"], *(s["stages"].get(c, 0) for c in columns)])
        return buf.getvalue()
    lines = [
        "Furthest stage reached (episodes per agent and food; 'held' is success)",
        "",
        "| agent | food | episodes | " + " | ".join(columns) + " |",
        "|---|---|---:|" + "---:|" * len(columns),
    ]
    for a, f, s in rows:
        counts = " | ".join(str(s["stages"].get(c, 0)) for c in columns)
        lines.append(f"| {a} | {f if f in TRAINING_FOODS else f + ' (unseen)'} | {s['episodes']} | {counts} |")
    return "\n".join(lines) + "\n"


def _mean(values: list[float]) -> float:
    values = [v for v in values if not math.isnan(v)]
    return float(np.mean(values)) if values else math.nan


def _groups(foods: list[str]) -> list[tuple[str, list[str]]]:
    seen = [f for f in foods if f in TRAINING_FOODS]
    unseen = [f for f in foods if f not in TRAINING_FOODS]
    return [(label, group) for label, group in ((SEEN_LABEL, seen), (UNSEEN_LABEL, unseen)) if group]


def table_rows(summary: dict, agents: list[str], foods: list[str]) -> dict[str, list[dict]]:
    """
    Both tables as rows of numbers (NaN where an agent has no entry or no success): "table2" success % per food
    (with its successes and episodes), "table3" spilled pieces mean/std and completion time mean per food. Each
    group of foods is followed by its average row, and the overall average closes the table; averages weigh each
    food the same, and their successes and episodes are the group's totals.
    """
    table2, table3 = [], []
    per_group = _groups(foods)
    for label, group in per_group:
        for food in group:
            s = {a: summary.get((a, food)) for a in agents}
            row = dict(group=label, food=food)
            for a in agents:
                row[a] = 100 * s[a]["success_rate"] if s[a] else math.nan
                row[f"{a} successes"] = s[a]["successes"] if s[a] else 0
                row[f"{a} episodes"] = s[a]["episodes"] if s[a] else 0
            table2.append(row)
            row = dict(group=label, food=food)
            for a in agents:
                row[f"{a} spilled"] = s[a]["grains_spilled_mean"] if s[a] else math.nan
                row[f"{a} spilled std"] = s[a]["grains_spilled_std"] if s[a] else math.nan
                row[f"{a} spilled g"] = s[a].get("spilled_mass_g_mean", math.nan) if s[a] else math.nan
                row[f"{a} carried g"] = s[a].get("spoon_mass_g_mean", math.nan) if s[a] else math.nan
                row[f"{a} time"] = s[a]["completion_time_s_mean"] if s[a] else math.nan
            table3.append(row)
        table2.append(_average_row(table2, label, group, f"{label} average"))
        table3.append(_average_row(table3, label, group, f"{label} average"))
    if len(per_group) > 1:
        table2.append(_average_row(table2, "all", foods, "overall average"))
        table3.append(_average_row(table3, "all", foods, "overall average"))
    return dict(table2=table2, table3=table3)


def _average_row(rows: list[dict], group: str, foods: list[str], label: str) -> dict:
    """Mean over the rows of ``foods``, a food without an entry (NaN) left out; no std (it would mix foods); counts
    (successes, episodes) summed."""
    food_rows = [r for r in rows if r["food"] in foods]
    row = dict(group=group, food=label)
    for c in (k for k in food_rows[0] if k not in ("group", "food")):
        if c.endswith((" successes", " episodes")):
            row[c] = sum(r[c] for r in food_rows)
        else:
            row[c] = math.nan if c.endswith(" std") else _mean([r[c] for r in food_rows])
    return row


def _ci_percent(row: dict, agent: str) -> tuple[float, float]:
    low, high = wilson_interval(row[f"{agent} successes"], row[f"{agent} episodes"])
    return 100 * low, 100 * high


def _rate_cell(row: dict, agent: str) -> str:
    """A success rate with its 95% Wilson interval, e.g. "70 (48-85)"."""
    if math.isnan(row[agent]):
        return MISSING
    low, high = _ci_percent(row, agent)
    return f"{row[agent]:.0f} ({low:.0f}-{high:.0f})"


def _fmt(value: float, digits: int = 1) -> str:
    return MISSING if value is None or math.isnan(value) else f"{value:.{digits}f}"


def markdown_tables(summary: dict, agents: list[str], foods: list[str]) -> str:
    """Tables II and III as markdown (the paper's layout: rows are foods, one column per agent)."""
    tables = table_rows(summary, agents, foods)
    lines = [
        "Table II: success rate (%, 95% Wilson interval in brackets)",
        "",
        "| food | " + " | ".join(agents) + " |",
    ]
    lines.append("|---|" + "---:|" * len(agents))
    group = None
    for row in tables["table2"]:
        if row["group"] != group and row["group"] != "all":
            group = row["group"]
            lines.append(f"| **{group}** |" + " |" * len(agents))
        food = row["food"] if row["food"] in foods else f"*{row['food']}*"
        lines.append(f"| {food} | " + " | ".join(_rate_cell(row, a) for a in agents) + " |")
    lines += [
        "",
        "Table III: spillage (pieces, mean ± std over all episodes; grams, mean), food carried at the end (g, mean)"
        " and completion time (s, mean over successes)",
        "",
        "| food | "
        + " | ".join(f"{a} spillage | {a} spilled (g) | {a} carried (g) | {a} time (s)" for a in agents)
        + " |",
        "|---|" + "---:|---:|---:|---:|" * len(agents),
    ]
    group = None
    for row in tables["table3"]:
        if row["group"] != group and row["group"] != "all":
            group = row["group"]
            lines.append(f"| **{group}** |" + " | | | |" * len(agents))
        is_food = row["food"] in foods
        cells = []
        for a in agents:
            spilled = _fmt(row[f"{a} spilled"])
            if is_food and spilled != MISSING:
                spilled += f" ± {_fmt(row[f'{a} spilled std'])}"
            cells += [spilled, _fmt(row[f"{a} spilled g"], 2), _fmt(row[f"{a} carried g"], 2), _fmt(row[f"{a} time"])]
        lines.append(f"| {row['food'] if is_food else '*' + row['food'] + '*'} | " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def csv_tables(summary: dict, agents: list[str], foods: list[str]) -> str:
    """Tables II and III as one CSV: a table column, then group, food and one column per agent and metric."""
    tables = table_rows(summary, agents, foods)
    columns = ["group", "food"]
    columns += [f"{a} {m}" for a in agents for m in ("success %", "success % ci95 low", "success % ci95 high")]
    columns += [
        f"{a} {m}"
        for a in agents
        for m in ("spilled pieces mean", "spilled pieces std", "spilled g mean", "carried g mean", "time s mean")
    ]
    buf = io.StringIO()
    writer = csv.writer(buf, lineterminator="\n")
    writer.writerow(columns)
    for r2, r3 in zip(tables["table2"], tables["table3"]):
        values = [r2["group"], r2["food"]]
        for a in agents:
            low, high = _ci_percent(r2, a) if not math.isnan(r2[a]) else (math.nan, math.nan)
            values += [_csv_number(r2[a]), _csv_number(low), _csv_number(high)]
        for a in agents:
            values += [_csv_number(r3[f"{a} spilled"]), _csv_number(r3[f"{a} spilled std"])]
            values += [_csv_number(r3[f"{a} spilled g"]), _csv_number(r3[f"{a} carried g"])]
            values += [_csv_number(r3[f"{a} time"])]
        writer.writerow(values)
    return buf.getvalue()


def _csv_number(value: float) -> str:
    return "NaN" if math.isnan(value) else f"{value:.4g}"


def _json_safe(value):
    if isinstance(value, float) and math.isnan(value):
        return None
    if isinstance(value, dict):
        return {k: _json_safe(v) for k, v in value.items()}
    if isinstance(value, list):
        return [_json_safe(v) for v in value]
    return value


def plot_success(summary: dict, agents: list[str], foods: list[str], path: str) -> None:
    """Bar chart of success % per food: one group of bars per food, one bar per agent, with 95% Wilson intervals."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    width = 0.8 / max(1, len(agents))
    x = np.arange(len(foods))
    fig, ax = plt.subplots(figsize=(max(4.0, 1.2 * len(foods) + 1), 3.5))
    for i, agent in enumerate(agents):
        entries = [summary.get((agent, f)) for f in foods]
        rates = np.array([100 * e["success_rate"] if e else 0.0 for e in entries])
        bounds = np.array([100 * np.array(e["success_ci95"]) if e else (0.0, 0.0) for e in entries])
        # clipped: an interval's end at 0 or 100 can miss the rate by a rounding error, and matplotlib refuses < 0
        errors = np.clip(np.stack([rates - bounds[:, 0], bounds[:, 1] - rates]), 0.0, None)
        ax.bar(x + (i - (len(agents) - 1) / 2) * width, rates, width, label=agent, yerr=errors, capsize=2)
    ax.set_xticks(x, [f if f in TRAINING_FOODS else f"{f}\n(unseen)" for f in foods])
    ax.set_ylabel("success (%, 95% CI)")
    ax.set_ylim(0, 100)
    ax.legend(fontsize="small")
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


@dataclass
class EvaluationResult:
    """Every episode, the per (agent, food) summary, and the run's configuration."""

    episodes: list[EpisodeRecord]
    agents: list[str]
    foods: list[str]
    config: dict = field(default_factory=dict)
    summary: dict = field(init=False)

    def __post_init__(self):
        self.summary = summarize(self.episodes)

    def markdown(self) -> str:
        return markdown_tables(self.summary, self.agents, self.foods)

    def stages_markdown(self) -> str:
        return stage_table(self.summary, self.agents, self.foods)

    def write(self, output_dir: str) -> dict[str, str]:
        """Writes episodes.csv, results.json, table.md, table.csv, stages.md, stages.csv and success.png; returns
        their paths."""
        out = Path(output_dir)
        out.mkdir(parents=True, exist_ok=True)
        names = ("episodes.csv", "results.json", "table.md", "table.csv", "stages.md", "stages.csv")
        paths = {name: str(out / name) for name in names}
        with open(paths["episodes.csv"], "w", newline="") as f:
            writer = csv.DictWriter(f, fieldnames=EpisodeRecord.columns())
            writer.writeheader()
            writer.writerows(e.to_dict() for e in self.episodes)
        episodes = [e.to_dict() for e in self.episodes]
        results = dict(config=self.config, summary=list(self.summary.values()), episodes=episodes)
        Path(paths["results.json"]).write_text(json.dumps(_json_safe(results), indent=2))
        Path(paths["table.md"]).write_text(self.markdown())
        Path(paths["table.csv"]).write_text(csv_tables(self.summary, self.agents, self.foods))
        Path(paths["stages.md"]).write_text(self.stages_markdown())
        Path(paths["stages.csv"]).write_text(stage_table(self.summary, self.agents, self.foods, fmt="csv"))
        paths["success.png"] = str(out / "success.png")
        plot_success(self.summary, self.agents, self.foods, paths["success.png"])
        for e in self.episodes:  # this run's videos only, not those an earlier run left in the folder
            video = out / "videos" / _video_name(e.agent, e.food, e.episode)
            if e.episode < self.config.get("videos", 0) and video.is_file():
                paths[f"videos/{video.name}"] = str(video)
        return paths


# ---------------------------------------------------------------------------------------------------------------- #
# Running                                                                                                          #
# ---------------------------------------------------------------------------------------------------------------- #


def _versions() -> dict[str, str]:
    from importlib.metadata import PackageNotFoundError, version

    out = {}
    for package in ("veragmil_suite", "robosuite", "robomimic", "mujoco", "torch", "numpy"):
        try:
            out[package] = version(package)
        except PackageNotFoundError:
            out[package] = "not installed"
    return out


def _video_name(agent: str, food: str, episode: int) -> str:
    safe = "".join(c if c.isalnum() or c in "-_." else "_" for c in agent)
    return f"{safe}_{food}_{episode}.mp4"


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
) -> EvaluationResult:
    """
    Scores each agent (name -> SPEC, see parse_spec) for ``episodes`` episodes per food, env seeds ``seed + i``.

    Every agent scoops with one robot: ``robot``, or by default the one the checkpoints were trained with
    (EXPERT_ROBOT when there are none); the scripted operators run on it.

    ``env_kwargs`` go to every environment (e.g. n_grains for a cheap scene); ``videos`` first episodes per
    (agent, food) are saved as mp4 under ``output_dir``/videos. Writes the outputs when ``output_dir`` is given,
    and journals each finished episode in ``output_dir``/episodes.jsonl as it ends: with ``resume``, episodes
    the journal holds (same agent SPEC, food, seed, horizon and env_kwargs; their video, if asked for, on disk)
    are taken from it instead of run again, whatever the agent is named now.

    Episodes run in ``processes`` worker processes, or with ``ray`` (a cluster's address, or
    distributed.THIS_MACHINE) as Ray tasks of one CPU each, on the piles settled here; either way the journal and
    the outputs are written here as episodes end.

    Raises:
        ValueError: [unknown food, bad agent SPEC, non-positive sizes, videos without output_dir, checkpoints of
            another robot]
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
    if videos and output_dir is None:
        raise ValueError("videos need an output_dir to be written to")
    robot = _evaluated_robot(specs, robot)
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
                video = str(video_dir / _video_name(name, food, i)) if i < videos else None
                task = EpisodeTask(name, spec, food, i, seed + i, horizon, dict(env_kwargs or {}), video, video_camera)
                tasks.append(task)
    for name, spec in specs.items():
        if spec.kind == "dataset":
            records += dataset_episodes(name, spec.target, foods)
    journal = Journal(Path(output_dir) / JOURNAL_NAME, resume) if output_dir is not None else None
    if journal is not None and resume:
        done = [(t, journal.get(t)) for t in tasks]
        reused = [replace(record, agent=t.agent) for t, record in done if record is not None]
        tasks = [t for t, record in done if record is None]
        if reused and say is not None:
            say(f"skipping {len(reused)} evaluation episodes journaled in {journal.path}; {len(tasks)} to run")
        records += reused
    episodes_run = len(tasks)
    if tasks:
        with ray_session(ray) as address:
            records += _run_parallel(tasks, int(processes), progress, journal, on_ray=address is not None)
    order = {name: i for i, name in enumerate(specs)}
    records.sort(key=lambda r: (order[r.agent], foods.index(r.food), r.episode))
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
        env_kwargs=dict(env_kwargs or {}),
        robot=robot,
        success_hold_s=SUCCESS_HOLD_S,
        episodes_run=episodes_run,
        versions=_versions(),
    )
    result = EvaluationResult(records, list(specs), foods, config)
    if output_dir is not None:
        result.write(output_dir)
    return result


def _evaluated_robot(specs: dict, robot: str | None) -> str:
    """The one robot of an evaluation: ``robot`` or the checkpoints'; a ValueError when a checkpoint's differs."""
    trained = {}
    for name, spec in specs.items():
        if spec.kind == "checkpoint":
            robots = _env_metadata(spec.target)["env_kwargs"].get("robots", EXPERT_ROBOT)
            trained[name] = robots[0] if isinstance(robots, (list, tuple)) else robots
    if robot is None:
        robot = next(iter(trained.values()), EXPERT_ROBOT)
    else:
        from veragmil_suite.models.humanoid import check_robot

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
    """Finished episodes, one JSON line each, keyed by what decides their outcome (not the agent's name)."""

    def __init__(self, path: Path, resume: bool):
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self.records: dict[str, EpisodeRecord] = {}
        if resume and self.path.exists():
            for line in self.path.read_text().splitlines():
                try:
                    entry = json.loads(line)
                except ValueError:
                    continue  # the last line of a killed run
                self.records[entry["key"]] = EpisodeRecord.from_dict(entry["record"])
        elif self.path.exists():
            self.path.unlink()

    @staticmethod
    def key(task: EpisodeTask) -> str:
        parts = [task.spec.kind, task.spec.target, task.food, task.seed, task.horizon, task.env_kwargs]
        if task.video_path:
            parts += [task.video_path, task.video_camera]
        return json.dumps(parts, sort_keys=True)

    def get(self, task: EpisodeTask) -> EpisodeRecord | None:
        record = self.records.get(self.key(task))
        if record is None or (task.video_path and not Path(task.video_path).is_file()):
            return None
        return replace(record, episode=task.episode)

    def add(self, task: EpisodeTask, record: EpisodeRecord) -> None:
        self.records[self.key(task)] = record
        with open(self.path, "a") as f:
            f.write(json.dumps(dict(key=self.key(task), record=_json_safe(record.to_dict()))) + "\n")


def _run_parallel(
    tasks: list[EpisodeTask], processes: int, progress: bool, journal: Journal | None = None, on_ray: bool = False
) -> list[EpisodeRecord]:
    """Runs the tasks in ``processes`` fresh worker processes, or as Ray tasks on the piles settled here, journaling
    each record as it arrives; the first failure stops the run and is raised."""
    from tqdm import tqdm

    piles = driver_piles(tasks) if on_ray else None
    records = []
    pieces = run_pieces(
        _run_task,
        tasks,
        context=piles,
        processes=processes,
        on_ray=on_ray,
        setup=_init_worker,
        resources=Resources(cpus=1),
    )
    with tqdm(total=len(tasks), desc="episodes", unit="ep", disable=not progress) as bar, contextlib.closing(pieces):
        try:
            for task, record in pieces:
                records.append(record)
                if journal is not None:
                    journal.add(task, record)
                bar.update(1)
        except EvaluationError as error:
            bar.write(f"evaluation failed, stopping the workers: {error}")
            raise EvaluationError(str(error)) from None
        except WorkerLost as error:
            bar.write(f"evaluation failed, stopping the workers: {error}")
            raise EvaluationError(f"a worker process failed: {error}") from error
    return records
