"""How the benchmarks time their work: the wall and CPU seconds of a block, and the mean cost of a call repeated
after its one-off costs are paid."""

from __future__ import annotations

import contextlib
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass


@dataclass
class Elapsed:
    """Seconds of wall-clock time (``time.perf_counter``) and of this process's CPU time (``time.process_time``)."""

    wall_s: float = 0.0
    cpu_s: float = 0.0


@contextlib.contextmanager
def stopwatch() -> Iterator[Elapsed]:
    """Times the block: the Elapsed it yields is filled in when the block ends."""
    elapsed = Elapsed()
    wall, cpu = time.perf_counter(), time.process_time()
    try:
        yield elapsed
    finally:
        elapsed.wall_s = time.perf_counter() - wall
        elapsed.cpu_s = time.process_time() - cpu


def per_call(fn: Callable[[], object], calls: int, warmup: int = 1) -> Elapsed:
    """The mean cost of one of ``calls`` calls of ``fn``, timed after ``warmup`` untimed ones (the first calls pay
    one-off costs: compiling, allocating, loading)."""
    if calls < 1:
        raise ValueError(f"calls must be a positive integer, got {calls!r}")
    for _ in range(warmup):
        fn()
    with stopwatch() as elapsed:
        for _ in range(calls):
            fn()
    return Elapsed(elapsed.wall_s / calls, elapsed.cpu_s / calls)
