"""veragmil_suite: scooping and carrying granular food with a spoon, as a robosuite task plugin.

Importing the package registers the ScoopGranular environment (robosuite registers every environment class
when it is defined) and the SpoonGripper (gripper_types="SpoonGripper").
"""

import os

__version__ = "0.1.0"

# Headless, MuJoCo's EGL contexts crashed at random in rollouts here while OSMesa (software) was reliable. Only a
# default: it must precede robosuite's import, so import veragmil_suite first (or set MUJOCO_GL yourself).
if not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")):
    os.environ.setdefault("MUJOCO_GL", "osmesa")
    os.environ.setdefault("PYOPENGL_PLATFORM", os.environ["MUJOCO_GL"])

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
