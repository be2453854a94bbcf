"""
ScoopGranular's keyword arguments, checked before anything is built.

robosuite takes most of its arguments as they come and fails, if at all, steps later and deep inside (a horizon of
"ten" at the first step's comparison, a camera height of 0 as empty images, a second arm as a 12-D action). The
task's own numbers (tolerances, ranges, offsets) would be taken as nonsense. Each argument here has one check; a
wrong value is a ValueError naming the argument, what it takes and what it got.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

from veragmil_suite.models.foods import FoodSpec
from veragmil_suite.utils.numbers import is_number, is_whole


def _refuse(name: str, accepted: str, value: Any) -> ValueError:
    return ValueError(f"{name} must be {accepted}, got {value!r}")


def _number(low: float, high: float = math.inf, open_low: bool = True, open_high: bool = False) -> Callable:
    left, right = "(" if open_low else "[", ")" if open_high or high == math.inf else "]"
    accepted = f"a finite number in {left}{low:g}, {high:g}{right}"

    def check(name: str, value: Any) -> None:
        if not is_number(value):
            raise _refuse(name, accepted, value)
        inside_low = value > low if open_low else value >= low
        inside_high = value < high if open_high else value <= high
        if not (inside_low and inside_high):
            raise _refuse(name, accepted, value)

    return check


def _optional(check: Callable) -> Callable:
    def optional(name: str, value: Any) -> None:
        if value is not None:
            check(name, value)

    return optional


def _positive_whole(name: str, value: Any) -> None:
    if not (is_whole(value) and value > 0):
        raise _refuse(name, "a positive integer", value)


def _finite(name: str, value: Any) -> None:
    if not is_number(value):
        raise _refuse(name, "a finite number", value)


def _grains(name: str, value: Any) -> None:
    if value is not None and not (is_whole(value) and value > 0):
        raise _refuse(name, "a positive integer or None (the food's default)", value)


def _seed(name: str, value: Any) -> None:
    if value is not None and not (is_whole(value) and value >= 0):
        raise _refuse(name, "None or a non-negative integer", value)


def _numbers(count: int, positive: bool = False) -> Callable:
    accepted = f"{count} finite{' positive' if positive else ''} numbers"

    def check(name: str, value: Any) -> None:
        items = list(value) if isinstance(value, (list, tuple)) or hasattr(value, "__array__") else None
        if items is None or len(items) != count or not all(map(is_number, items)):
            raise _refuse(name, accepted, value)
        if positive and min(items) <= 0:
            raise _refuse(name, accepted, value)

    return check


def _range(name: str, value: Any) -> None:
    _numbers(2)(name, value)
    if value[0] > value[1]:
        raise _refuse(name, "(low, high) with low <= high", value)


def _per_camera(name: str, value: Any) -> None:
    for item in value if isinstance(value, (list, tuple)) else [value]:
        if not (is_whole(item) and 0 < item <= MAX_IMAGE_SIDE_PX):
            raise _refuse(name, f"a size in pixels in [1, {MAX_IMAGE_SIDE_PX}] (or one per camera)", value)


def _names(name: str, value: Any) -> None:
    items = value if isinstance(value, (list, tuple)) else [value]
    if not items or not all(isinstance(item, str) and item for item in items):
        raise _refuse(name, "a name or a list of names", value)


def _robots(name: str, value: Any) -> None:
    items = [value] if isinstance(value, str) else value if isinstance(value, (list, tuple)) else None
    if items is None or len(items) != 1 or not isinstance(items[0], str):
        raise _refuse(name, "one robot's name (the task has one spoon arm), e.g. 'XArm7'", value)


def _controller(name: str, value: Any) -> None:
    if value is not None and not isinstance(value, dict):
        raise _refuse(name, "None (the task's OSC_POSE) or a robosuite controller config dict", value)


# the largest image side a camera renders: robosuite grows its offscreen buffer to the image asked for (4 bytes a
# pixel and more for depth), so 100,000 pixels a side would ask for tens of gigabytes part-way through a run
MAX_IMAGE_SIDE_PX = 4096
# the slowest control rate accepted: a control period longer than a second is neither teleoperation nor a policy,
# and robosuite runs period / physics step substeps per control step (control_freq=1e-9 would never return)
MIN_CONTROL_FREQ_HZ = 1.0


def _control_freq(name: str, value: Any) -> None:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not (MIN_CONTROL_FREQ_HZ <= value < math.inf):
        raise _refuse(
            name, f"a number of Hz of at least {MIN_CONTROL_FREQ_HZ:g} (20 Hz default, 60 Hz as in the paper)", value
        )


def _flag(name: str, value: Any) -> None:
    if not isinstance(value, bool):
        raise _refuse(name, "True or False", value)


def _solver_options(name: str, value: Any) -> None:
    """MuJoCo <option> attributes, as text (as the MJCF has them) or numbers: the counts whole and >= 0, the ratios
    and tolerances positive."""
    if value is None:
        return
    if not isinstance(value, dict) or not all(isinstance(key, str) for key in value):
        raise _refuse(name, "None or a dict of MuJoCo <option> attributes", value)
    for key, option in value.items():
        text = str(option).strip() if isinstance(option, str) or is_number(option) else ""
        if key in ("iterations", "ls_iterations", "noslip_iterations", "ccd_iterations"):
            if not text.isdigit():
                raise _refuse(f"{name}[{key!r}]", "a non-negative integer", option)
        elif key in ("impratio", "tolerance", "ls_tolerance", "noslip_tolerance"):
            try:
                number = float(text)
            except ValueError:
                number = math.nan
            if not (math.isfinite(number) and number > 0):
                raise _refuse(f"{name}[{key!r}]", "a positive number", option)


# each argument's check: (name, value) -> None, raising ValueError. The food, physics, robot's name, grain count's
# limit, physics step, sleep tolerance and spill limit have theirs where their catalogs are (foods, robots, the task
# model).
CHECKS: dict[str, Callable[[str, Any], None]] = {
    "robots": _robots,
    "controller_configs": _controller,
    "n_grains": _grains,
    "pile_variants": _positive_whole,
    "bowl_x_range": _range,
    "bowl_y_range": _range,
    "pre_scoop_offset": _numbers(3),
    "post_scoop_offset": _numbers(3),
    "success_pos_tolerance": _number(0),
    "success_tilt_tolerance_deg": _number(0, 180),
    "success_max_speed": _number(0),
    "min_portion_fraction": _number(0, 1),
    "min_portion_cm3": _optional(_number(0, open_low=False)),
    "max_spill_fraction": _number(0, 1, open_low=False),
    "table_full_size": _numbers(3, positive=True),
    "reward_scale": _optional(_finite),
    "physics_solver_options": _solver_options,
    "horizon": _positive_whole,
    "control_freq": _control_freq,
    "camera_names": _names,
    "camera_heights": _per_camera,
    "camera_widths": _per_camera,
    "seed": _seed,
    **{
        flag: _flag
        for flag in (
            "use_camera_obs",
            "use_object_obs",
            "use_food_params_obs",
            "use_wrench_obs",
            "reward_shaping",
            "fast_rendering",
            "has_renderer",
            "has_offscreen_renderer",
            "lite_physics",
            "ignore_done",
            "hard_reset",
        )
    },
}


# the largest grain count accepted, as a multiple of the food's default (veragmil_suite.scripts.bench times 1x, 2x and
# 4x)
MAX_GRAINS_PER_DEFAULT = 4


def check_grain_count(n_grains: int | None, food: FoodSpec, physics: str) -> int:
    """The grains a bowl of ``food`` gets: ``n_grains``, or the food's default for None; ValueError for a count that
    is not a positive integer or more than MAX_GRAINS_PER_DEFAULT times the default, which settles too slowly."""
    _grains("n_grains", n_grains)
    default = food.grain(physics).default_grains
    if n_grains is None:
        return default
    limit = MAX_GRAINS_PER_DEFAULT * default
    if n_grains > limit:
        raise ValueError(
            f"n_grains {n_grains} is more than a bowl of {food.name} settles in reasonable time: at most {limit} "
            f"({MAX_GRAINS_PER_DEFAULT}x its default of {default})"
        )
    return int(n_grains)


def check_arguments(arguments: dict[str, Any]) -> None:
    """Raises ValueError naming the first of ``arguments`` (ScoopGranular's, by name) whose value its check refuses."""
    for name, value in arguments.items():
        if name in CHECKS:
            CHECKS[name](name, value)
