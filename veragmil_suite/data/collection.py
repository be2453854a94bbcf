"""Recording demonstrations: one episode of an operator into the recorder, paced like robosuite's collection;
attempts run in this process or in worker processes (or Ray tasks) in seed order; the loop that keeps or discards
them into a DemoWriter; and the scripted recording as one function (what ``veragmil-collect --device scripted``
and the study's recording stage both run).
"""

from __future__ import annotations

import contextlib
import itertools
import signal
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
import robosuite

from veragmil_suite.controllers.scoop_config import load_scoop_controller_config
from veragmil_suite.data.recording import Episode, EpisodeRecorder
from veragmil_suite.data.schema import DatasetError, env_meta, provenance
from veragmil_suite.data.writer import DemoWriter
from veragmil_suite.devices.operators import ScriptedOperator, TeleopOperator
from veragmil_suite.environments import settling
from veragmil_suite.environments.episode import SUCCESS_HOLD_S, run_until_done
from veragmil_suite.utils.canonical import canonical
from veragmil_suite.utils.distributed import ray_session, run_pieces

if TYPE_CHECKING:
    from veragmil_suite.environments.scoop import ScoopGranular

KEEP_POLICIES = ("ask", "all", "success")


def print_now(line: str) -> None:
    """A collection's lines are read as they come (a study follows its recorder's log): flushed at once."""
    print(line, flush=True)


def recording_env_kwargs(
    robot: str,
    food: str,
    controller_config: dict | None = None,
    control_freq: float = 20,
    horizon: int = 400,
    n_grains: int | None = None,
    physics: str | None = None,
    cameras: tuple[str, ...] | list[str] = ("overhead",),
    image_size: tuple[int, int] = (84, 84),
    depth: bool = False,
    wrench: bool = False,
) -> dict:
    """robosuite.make keyword arguments (besides the env name) of a recording, JSON-serializable: they are stored in
    the dataset for robomimic to rebuild the env. ``controller_config``: the task's OSC_POSE when None; ``cameras``
    recorded as <name>_image (none: low-dim only), ``image_size`` (height, width); ``n_grains`` and ``physics``:
    the food's and the task's own when None; ``wrench``: the wrist force-torque sensor observed (``use_wrench_obs``)."""
    cameras = list(cameras)
    kwargs = dict(
        robots=robot,
        food=food,
        controller_configs=controller_config or load_scoop_controller_config("OSC_POSE", robot=robot),
        control_freq=control_freq,
        horizon=horizon,
        ignore_done=False,
        reward_shaping=False,
        use_object_obs=True,
        use_camera_obs=bool(cameras),
        has_offscreen_renderer=bool(cameras),
        camera_names=cameras or "overhead",
        camera_heights=image_size[0],
        camera_widths=image_size[1],
        camera_depths=bool(depth),
    )
    if n_grains is not None:
        kwargs["n_grains"] = n_grains
    if physics is not None:
        kwargs["physics"] = physics
    if wrench:
        kwargs["use_wrench_obs"] = True
    return kwargs


def open_writer(
    output: str,
    env_kwargs: dict,
    device: str,
    operator: str,
    seed: int | None = None,
    valid_ratio: float = 0.1,
    **provenance_extra: Any,
) -> tuple[DemoWriter, int]:
    """
    The DemoWriter of a collection into ``output`` (appended to when it exists) and its first attempt's seed:
    ``seed``, or the one after the file's last attempt (0 for a new file). ``provenance_extra`` is stored with the
    file and every demo beside who and what recorded it.

    Raises:
        DatasetError: [the file cannot be appended to (veragmil_suite.data.writer)]
        ValueError: [``seed`` would repeat the file's attempts: a seed gives the same episode again]
    """
    source = "scripted" if device == "scripted" else "human"
    about = provenance(
        device=device,
        operator=operator,
        food=env_kwargs["food"],
        robot=env_kwargs["robots"],
        source=source,
        control_freq=env_kwargs.get("control_freq", 20),
        **provenance_extra,
    )
    writer = DemoWriter(output, env_meta(env_kwargs), about, valid_ratio=valid_ratio)
    last = max(writer.seeds_used, default=None)
    if seed is not None and last is not None and seed <= last:
        writer.close()
        raise ValueError(
            f"{output} already holds attempts with seeds up to {last} (attempt k runs with seed SEED + k, and a "
            f"seed gives the same episode again): --seed {seed} would repeat them; omit --seed to continue "
            f"from {last + 1}, or pass a seed above {last}"
        )
    first = seed if seed is not None else 0 if last is None else last + 1
    writer.provenance["env_seed"] = first
    return writer, first


class FrameCap:
    """Paces a loop at no more than ``rate`` steps per second (robosuite's --max_fr): call it once per step."""

    def __init__(self, rate: float):
        self.period = 1.0 / rate
        self.last: float | None = None

    def __call__(self) -> None:
        now = time.perf_counter()
        if self.last is not None and now - self.last < self.period:
            time.sleep(self.period - (now - self.last))
        self.last = time.perf_counter()


def run_episode(
    env: ScoopGranular,
    recorder: EpisodeRecorder,
    operator: ScriptedOperator | TeleopOperator,
    success_hold_s: float,
    render: bool,
    realtime: bool,
    seed: int | None = None,
    pace: FrameCap | None = None,
) -> str:
    """Record one episode (env and operator seeded with ``seed``) through the shared episode loop
    (veragmil_suite.environments.episode); returns why it ended: "success", "horizon", "operator" (a human stopped),
    "gave up" (the scripted operator did) or "physics". A ``success_hold_s`` <= 0 leaves success out of the ending rule.
    ``pace`` caps the steps per second (--max-fr)."""
    obs = recorder.reset(seed=seed)
    operator.begin(seed=seed)
    hooks = [hook for hook in (env.render if render else None, pace) if hook is not None]
    end = run_until_done(
        operator.action,
        lambda action: recorder.step(action, label=operator.label),
        obs,
        env.control_freq,
        env.horizon,
        success_hold_s=success_hold_s,
        on_step=(lambda: [hook() for hook in hooks]) if hooks else None,
        realtime=realtime,
        stopped="operator" if operator.source == "human" else "gave up",
    )
    return end.reason


def record_attempt(
    env: ScoopGranular,
    recorder: EpisodeRecorder,
    operator: ScriptedOperator | TeleopOperator,
    seed: int,
    success_hold_s: float = SUCCESS_HOLD_S,
    render: bool = False,
    realtime: bool = False,
    pace: FrameCap | None = None,
) -> tuple[int, str, Episode | None]:
    """One attempt with ``seed``: (seed, why it ended, the Episode, or None when no step was taken)."""
    reason = run_episode(env, recorder, operator, success_hold_s, render, realtime, seed=seed, pace=pace)
    if not recorder.num_steps:
        return seed, reason, None
    return seed, reason, recorder.episode(attrs=dict(end_reason=reason, pile_variant=int(env.pile_variant), seed=seed))


def local_attempts(
    env: ScoopGranular,
    recorder: EpisodeRecorder,
    operator: ScriptedOperator | TeleopOperator,
    first_seed: int,
    success_hold_s: float = SUCCESS_HOLD_S,
    render: bool = False,
    realtime: bool = False,
    pace: FrameCap | None = None,
) -> Iterator[tuple]:
    """Attempts in this process, one at a time, seeds ``first_seed``, ``first_seed`` + 1, ...: yields
    record_attempt's tuples."""
    for seed in itertools.count(first_seed):
        yield record_attempt(env, recorder, operator, seed, success_hold_s, render, realtime, pace)


_WORKER: dict = {}  # per recording worker process: its env, recorder and operator, and the settings they were built for


def _ignore_sigint() -> None:
    """Local recording workers leave Ctrl-C to the parent, which stops the pool."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)


def _worker_attempt(context: tuple, seed: int):
    """One attempt in a recording worker, whose env and scripted operator are built at its first attempt.
    ``context``: (env kwargs, profile, first seed, success hold, the driver's settled piles or None)."""
    env_kwargs, profile, first_seed, success_hold_s, piles = context
    settling.use_shipped_piles(piles)
    settings = canonical([env_kwargs, profile, first_seed])
    if _WORKER.get("settings") != settings:
        if "env" in _WORKER:
            _WORKER["env"].close()
        env = robosuite.make("ScoopGranular", **env_kwargs, has_renderer=False, seed=first_seed)
        operator = ScriptedOperator(env, profile, first_seed)
        _WORKER.update(env=env, recorder=EpisodeRecorder(env), operator=operator, settings=settings)
    return record_attempt(_WORKER["env"], _WORKER["recorder"], _WORKER["operator"], seed, success_hold_s)


def parallel_attempts(
    env: ScoopGranular,
    env_kwargs: dict,
    profile: str,
    first_seed: int,
    success_hold_s: float = SUCCESS_HOLD_S,
    processes: int = 1,
    ray: str | None = None,
) -> Iterator[tuple]:
    """
    Scripted attempts of ``profile`` in ``processes`` processes, or as Ray tasks (on the cluster at ``ray``), yielded
    in seed order like local_attempts (a few attempts run ahead; those not needed are cancelled or dropped when the
    caller stops). ``env``, the driver's, has settled the piles and is closed here: Ray workers are handed its piles,
    local workers read them from the disk cache.
    """
    piles = env.settled_piles() if ray is not None else None
    env.close()
    return _attempts_in_workers(env_kwargs, profile, first_seed, success_hold_s, processes, ray, piles)


def _attempts_in_workers(
    env_kwargs: dict,
    profile: str,
    first_seed: int,
    success_hold_s: float,
    processes: int,
    ray: str | None,
    piles: dict | None,
) -> Iterator[tuple]:
    with ray_session(ray) as address:
        on_ray = address is not None
        attempts = run_pieces(
            _worker_attempt,
            itertools.count(first_seed),
            context=(env_kwargs, profile, first_seed, success_hold_s, piles),
            processes=processes,
            on_ray=on_ray,
            ordered=True,
            setup=None if on_ray else _ignore_sigint,
        )
        with contextlib.closing(attempts):
            for _, attempt in attempts:
                yield attempt


def ask_keep(prompt: str) -> bool:
    """The terminal's verdict on an episode: yes by default; no when there is no terminal to ask."""
    while True:
        try:
            answer = input(prompt).strip().lower()
        except EOFError:
            return False
        if answer in ("", "y", "yes"):
            return True
        if answer in ("n", "no"):
            return False


def episode_line(n: int, metrics: dict, steps: int, reason: str) -> str:
    """The line printed after attempt ``n``: outcome, grains in the spoon and spilled, time."""
    m = metrics
    line = (
        f"episode {n}: {'SUCCESS' if m['success'] else 'failure'} ({reason}), {steps} steps; "
        f"in spoon {m['grains_in_spoon']} ({m['spoon_volume_cm3']:.2f} cm3); "
        f"spilled {m['grains_spilled']} pieces, {m['spilled_volume_cm3']:.2f} cm3 "
        f"({100 * m['spill_fraction']:.1f}% of scooped); time {m['completion_time_s']:.2f} s"
    )
    return line + (f"; physics: {m['physics_error']}" if m["physics_error"] else "")


@dataclass
class CollectionOutcome:
    """What a collection did: demos kept, every attempt's metrics, and why it stopped early (if it did)."""

    path: str
    requested: int
    kept: int = 0
    attempts: list[dict] = field(default_factory=list)
    failed: str | None = None  # the write the disk refused: the collection stopped there
    interrupted: bool = False

    def summary(self) -> str | None:
        """One line over every attempt (None before the first)."""
        if not self.attempts:
            return None
        success = np.mean([r["success"] for r in self.attempts])
        spill = np.mean([r["grains_spilled"] for r in self.attempts])
        spill_vol = np.mean([r["spilled_volume_cm3"] for r in self.attempts])
        times = [r["completion_time_s"] for r in self.attempts if r["success"]]
        return (
            f"{len(self.attempts)} attempts, {self.kept} saved to {self.path}: success {100 * success:.0f}%, "
            f"spilled {spill:.1f} pieces ({spill_vol:.2f} cm3) on average"
            + (f", completion {np.mean(times):.2f} s on success" if times else "")
        )


def collect(
    writer: DemoWriter,
    attempts: Iterator[tuple],
    episodes: int,
    keep_policy: str = "success",
    max_attempts: int | None = None,
    operator: ScriptedOperator | TeleopOperator | None = None,
    say: Callable[[str], None] = print_now,
) -> CollectionOutcome:
    """
    Draws ``attempts`` (local_attempts or parallel_attempts) until ``episodes`` are kept or ``max_attempts`` ran,
    keeping each by ``keep_policy`` ("ask": the operator's or the terminal's verdict; "all"; "success") into
    ``writer``; discarded attempts are logged too, so success rates count every attempt. A write the disk refuses
    stops it (``failed``); Ctrl-C drops the episode in progress (``interrupted``). Closes ``attempts``, not the
    writer.
    """
    if keep_policy not in KEEP_POLICIES:
        raise ValueError(f"keep policy {keep_policy!r}; accepted: {', '.join(KEEP_POLICIES)}")
    outcome = CollectionOutcome(path=str(writer.path), requested=episodes)
    teleop = operator if isinstance(operator, TeleopOperator) else None
    n, discarded = 0, 0  # n: the attempt drawn, from 1
    try:
        while outcome.kept < episodes and (max_attempts is None or n < max_attempts):
            n += 1
            if teleop is not None:
                teleop.show_progress(
                    f"episode {n} | kept {outcome.kept}/{episodes} | discarded {discarded} | {writer.path.name}"
                )
            seed, reason, episode = next(attempts)
            if episode is None:  # no step taken
                continue
            episode.attrs["attempt"] = n
            metrics = episode.metrics
            say(episode_line(n, metrics, episode.num_samples, reason))
            said = operator.command if operator is not None else None
            if keep_policy == "ask" and said not in ("keep", "discard", "reset"):
                verdict = teleop.wait_for_verdict() if teleop is not None else None
                said = verdict or ("keep" if ask_keep("keep this episode? [Y/n] ") else "discard")
            keep = {"all": True, "success": bool(metrics["success"]), "ask": said == "keep"}[keep_policy]
            if teleop is not None:
                teleop.end()
            outcome.attempts.append(metrics)
            try:
                if keep:
                    name = writer.write(episode)
                else:
                    writer.log_discarded(metrics, attrs=dict(attempt=n, end_reason=reason, seed=seed))
            except DatasetError as e:
                outcome.failed = (
                    f"{e}: episode {n} (seed {seed}) is not saved; all saved before it are ({outcome.kept} here)"
                )
                break
            if keep:
                outcome.kept += 1
                say(f"  saved as {name} ({outcome.kept}/{episodes})")
            else:
                discarded += 1
                say("  discarded")
    except KeyboardInterrupt:
        outcome.kept = len(writer.written)
        outcome.interrupted = True
        say(f"\ninterrupted: the episode in progress is dropped; {outcome.kept} episodes saved to {writer.path}")
    finally:
        attempts.close()
    return outcome


def record_scripted(
    output: str,
    env_kwargs: dict,
    episodes: int,
    profile: str = "expert",
    seed: int | None = None,
    processes: int = 1,
    ray: str | None = None,
    success_hold_s: float = SUCCESS_HOLD_S,
    max_attempts: int | None = None,
    keep_policy: str = "success",
    valid_ratio: float = 0.1,
    controller: str = "OSC_POSE",
    say: Callable[[str], None] = print_now,
) -> CollectionOutcome:
    """
    Records ``episodes`` demos of the scripted operator ``profile`` into ``output`` (``recording_env_kwargs``), at
    most ``max_attempts`` attempts (default 3 x episodes + 2), in this process, in ``processes`` worker processes or
    on the Ray cluster at ``ray`` (one demo is recorded here: a pool gains nothing on it): what ``veragmil-collect
    --device scripted`` runs, and the study's recording stage. Attempt k runs with seed ``seed`` + k (default: after
    the file's last attempt), so the file is the same for any number of processes.

    Raises:
        DatasetError: [``output`` cannot be appended to]
        ValueError: [a setting the env refuses, or ``seed`` would repeat the file's attempts]
    """
    writer, first = open_writer(
        output, env_kwargs, "scripted", f"scripted-{profile}", seed, valid_ratio, controller=controller, profile=profile
    )
    with writer:
        # built here in every case: a bad setting is refused before anything is recorded; with workers it settles
        # the piles for them
        env = robosuite.make("ScoopGranular", **env_kwargs, has_renderer=False, seed=first)
        try:
            # one demo in a pool would start its workers and an attempt run ahead that is dropped once it succeeds
            if min(processes, episodes) > 1 or ray is not None:
                attempts = parallel_attempts(env, env_kwargs, profile, first, success_hold_s, processes, ray)
                env = None
            else:
                operator = ScriptedOperator(env, profile, first)
                attempts = local_attempts(env, EpisodeRecorder(env), operator, first, success_hold_s)
            limit = max_attempts if max_attempts is not None else 3 * episodes + 2
            return collect(writer, attempts, episodes, keep_policy, limit, say=say)
        finally:
            if env is not None:
                env.close()
