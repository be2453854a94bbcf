"""veragmil_suite: scooping and carrying granular food with a spoon, as a robosuite task plugin.

Importing the package registers the ScoopGranular environment (robosuite registers every environment class
when it is defined) and the SpoonGripper (gripper_types="SpoonGripper").
"""

import os

from veragmil_suite.rendering import use_headless_rendering

__version__ = "0.1.0"

# Without a display, OSMesa by default (why: veragmil_suite.rendering). Only a default: it must precede robosuite's
# import, so import veragmil_suite first (or set MUJOCO_GL yourself).
if not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")):
    use_headless_rendering()

from veragmil_suite.environments.scoop import ScoopGranular  # noqa: E402
from veragmil_suite.foods import FOODS, TRAINING_FOODS, UNSEEN_FOODS, FoodSpec, get_food, register_food  # noqa: E402
from veragmil_suite.models.spoon_gripper import SpoonGripper  # noqa: E402

__all__ = [
    "FOODS",
    "TRAINING_FOODS",
    "UNSEEN_FOODS",
    "FoodSpec",
    "ScoopGranular",
    "SpoonGripper",
    "get_food",
    "register_food",
]
