"""veragmil_suite: scooping and carrying granular food with a spoon, as a robosuite task plugin.

Importing the package registers the ScoopGranular environment (robosuite registers every environment class
when it is defined), the SpoonGripper (gripper_types="SpoonGripper") and the Gymnasium id
"veragmil/ScoopGranular-v0" (veragmil_suite.wrappers.gym_env), and our robomimic algorithms (algo_name
"diffusion_policy") as soon as robomimic is imported (veragmil_suite.learning.algos).
"""

from veragmil_suite.utils.rendering import has_display, use_headless_rendering
from veragmil_suite.utils.upstream_logging import drop_missing_examples_warning

__version__ = "0.1.0"

# robosuite's warning that its wheel lacks its examples package, logged at its import
# (veragmil_suite.utils.upstream_logging)
drop_missing_examples_warning()

# Without a display, OSMesa by default (why: veragmil_suite.utils.rendering). Only a default: it must precede
# robosuite's import, so import veragmil_suite first (or set MUJOCO_GL yourself).
if not has_display():
    use_headless_rendering()

from veragmil_suite.environments.scoop import ScoopGranular  # noqa: E402
from veragmil_suite.learning.algos import register_on_import  # noqa: E402
from veragmil_suite.models.foods import FOODS, TRAINING_FOODS, UNSEEN_FOODS, FoodSpec, get_food, register_food  # noqa: E402
from veragmil_suite.models.spoon_gripper import SpoonGripper  # noqa: E402
from veragmil_suite.wrappers.gym_env import GYM_ENV_ID, ScoopGranularGymEnv, register_gym_env  # noqa: E402

register_gym_env()
register_on_import()

__all__ = [
    "FOODS",
    "GYM_ENV_ID",
    "TRAINING_FOODS",
    "UNSEEN_FOODS",
    "FoodSpec",
    "ScoopGranular",
    "ScoopGranularGymEnv",
    "SpoonGripper",
    "get_food",
    "register_food",
]
