"""Recording attempts: one episode of an operator into the recorder, paced like robosuite's collection, and attempts
run in this process or in worker processes (or Ray tasks) in seed order.
"""

from __future__ import annotations

import contextlib
import itertools
import signal
import time

import robosuite

from veragmil_suite.data.recording import EpisodeRecorder
from veragmil_suite.devices.operators import ScriptedOperator
from veragmil_suite.environments import settling
from veragmil_suite.environments.episode import run_until_done
from veragmil_suite.utils.canonical import canonical
from veragmil_suite.utils.distributed import ray_session, run_pieces


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
    env,
    recorder,
    operator,
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
    env, recorder, operator, args, seed: int, render: bool = False, realtime: bool = False, pace: FrameCap | None = None
):
    """One attempt with ``seed``: (seed, why it ended, the Episode, or None when no step was taken)."""
    reason = run_episode(env, recorder, operator, args.success_hold, render, realtime, seed=seed, pace=pace)
    if not recorder.num_steps:
        return seed, reason, None
    return seed, reason, recorder.episode(attrs=dict(end_reason=reason, pile_variant=int(env.pile_variant), seed=seed))


def local_attempts(env, recorder, operator, args, render: bool, realtime: bool, pace: FrameCap | None = None):
    """Attempts in this process, one at a time, seeds SEED, SEED + 1, ...: yields record_attempt's tuples."""
    seed = args.seed
    while True:
        yield record_attempt(env, recorder, operator, args, seed, render, realtime, pace)
        seed += 1


_WORKER: dict = {}  # per recording worker process: its env, recorder and operator, and the settings they were built for


def _ignore_sigint() -> None:
    """Local recording workers leave Ctrl-C to the parent, which stops the pool."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)


def _worker_attempt(context: tuple, seed: int):
    """One attempt in a recording worker, whose env and scripted operator are built at its first attempt.
    ``context``: (arguments, env kwargs, the driver's settled piles or None)."""
    import veragmil_suite  # noqa: F401

    args, env_kwargs, piles = context
    settling.use_shipped_piles(piles)
    settings = canonical([vars(args), env_kwargs])
    if _WORKER.get("settings") != settings:
        if "env" in _WORKER:
            _WORKER["env"].close()
        env = robosuite.make("ScoopGranular", **env_kwargs, has_renderer=False, seed=args.seed)
        operator = ScriptedOperator(env, args.profile, args.seed)
        _WORKER.update(env=env, recorder=EpisodeRecorder(env), operator=operator, settings=settings)
    return record_attempt(_WORKER["env"], _WORKER["recorder"], _WORKER["operator"], args, seed)


def parallel_attempts(args, env_kwargs: dict, piles: dict | None = None):
    """
    Scripted attempts in ``args.processes`` processes, or as Ray tasks (``args.ray``) on the driver's settled
    ``piles``, yielded in seed order like local_attempts (a few attempts run ahead; those not needed are cancelled
    or dropped when the caller stops).
    """
    with ray_session(args.ray) as address:
        on_ray = address is not None
        attempts = run_pieces(
            _worker_attempt,
            itertools.count(args.seed),
            context=(args, env_kwargs, piles),
            processes=args.processes,
            on_ray=on_ray,
            ordered=True,
            setup=None if on_ray else _ignore_sigint,
        )
        with contextlib.closing(attempts):
            for _, attempt in attempts:
                yield attempt
