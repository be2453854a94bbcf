"""What an argument that takes a number accepts: a real, finite number or an integer, never a bool (True is an int
to Python, and would be taken as 1); the seeds a run derives from its first; an item a list of settings repeats."""

from __future__ import annotations

import math
import operator
from collections.abc import Callable
from typing import Any

import numpy as np

SEED_MAX = 2**32 - 1  # numpy's largest seed


def is_number(value: Any) -> bool:
    """A real, finite number (not a bool), Python's or NumPy's."""
    return (
        not isinstance(value, (bool, np.bool_))
        and isinstance(value, (int, float, np.integer, np.floating))
        and (math.isfinite(value))
    )


def is_whole(value: Any) -> bool:
    """An integer (not a bool), Python's or NumPy's."""
    return not isinstance(value, (bool, np.bool_)) and isinstance(value, (int, np.integer))


def first_repeated(items: list, same: Callable[[Any, Any], bool] = operator.eq) -> Any:
    """The first item of ``items`` that repeats an earlier one (``same``), None when none does."""
    return next((item for i, item in enumerate(items) if any(same(item, earlier) for earlier in items[:i])), None)


def seed_span_problem(first: int, count: int, what: str = "episode") -> str | None:
    """What is wrong with the ``count`` consecutive seeds from ``first`` that a run gives its ``what``s (the k-th
    runs with seed ``first`` + k): None when all are numpy's."""
    last = int(first) + int(count) - 1
    if last <= SEED_MAX:
        return None
    return (
        f"seed {first}: its {count} {what} seeds run to {last}, past numpy's largest seed {SEED_MAX}; "
        f"give a seed of at most {SEED_MAX - int(count) + 1}"
    )
