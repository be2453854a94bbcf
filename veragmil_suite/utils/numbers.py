"""What an argument that takes a number accepts: a real, finite number or an integer, never a bool (True is an int
to Python, and would be taken as 1)."""

from __future__ import annotations

import math
from typing import Any

import numpy as np


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
