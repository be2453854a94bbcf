"""veragmil_suite: scooping and carrying granular food with a spoon, as a robosuite task plugin.

Importing the package registers the ScoopGranular environment (robosuite registers every environment class
when it is defined) and the SpoonGripper (gripper_types="SpoonGripper").
"""

__version__ = "0.1.0"

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
