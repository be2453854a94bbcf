"""The benchmarks' one timing helper (veragmil_suite.utils.timing)."""

import time

import pytest

from veragmil_suite.utils.timing import per_call, stopwatch


def test_a_stopwatch_times_its_block_in_wall_and_cpu_seconds():
    with stopwatch() as waited:
        time.sleep(0.05)
    assert 0.05 <= waited.wall_s < 1.0
    assert waited.cpu_s < waited.wall_s  # asleep: no CPU spent
    with stopwatch() as busy:
        sum(range(2_000_000))
    assert busy.cpu_s > 0


def test_per_call_is_the_mean_of_the_timed_calls_after_the_untimed_warmup():
    calls = []

    def call():
        time.sleep(0.2 if not calls else 0.01)  # the first call pays a one-off cost
        calls.append(1)

    cost = per_call(call, 5, warmup=1)
    assert len(calls) == 6
    assert 0.01 <= cost.wall_s < 0.1  # the warm-up's 0.2 s is not in the mean
    with pytest.raises(ValueError, match="calls must be a positive integer"):
        per_call(call, 0)
