"""Bad arguments to the Python API are refused before anything is built, in one ValueError naming the argument and
what it takes: robosuite.make's keyword arguments (veragmil_suite.environments.arguments), an action, the Gymnasium
wrapper's, the dataset functions', a study's settings."""

import numpy as np
import pytest
import robosuite

import veragmil_suite  # noqa: F401
from veragmil_suite.data.datasets import drop_noops, merge_datasets, split_dataset
from veragmil_suite.data.replay import replay_demos
from veragmil_suite.evaluation.agents import check_foods
from veragmil_suite.models.foods import get_food, register_food
from veragmil_suite.study.settings import PipelineSettings
from veragmil_suite.wrappers.gym_env import ScoopGranularGymEnv

LIGHT = dict(robots="XArm7", food="pasta", n_grains=12, has_offscreen_renderer=False, use_camera_obs=False)

BAD_KWARGS = [
    ("horizon", 0, "horizon must be a positive integer, got 0"),
    ("horizon", "ten", "horizon must be a positive integer, got 'ten'"),
    ("camera_heights", 0, "camera_heights must be a size in pixels in [1, 4096] (or one per camera), got 0"),
    ("camera_widths", 2.5, "camera_widths must be a size in pixels"),
    ("camera_heights", [84, 100000], "camera_heights must be a size in pixels in [1, 4096] (or one per camera)"),
    ("table_full_size", (0.8,), "table_full_size must be 3 finite positive numbers"),
    ("reward_scale", "x", "reward_scale must be a finite number, got 'x'"),
    ("success_pos_tolerance", -1, "success_pos_tolerance must be a finite number in (0, inf), got -1"),
    ("success_tilt_tolerance_deg", 200, "in (0, 180]"),
    ("success_max_speed", "fast", "success_max_speed must be a finite number in (0, inf), got 'fast'"),
    ("max_spill_fraction", -0.1, "max_spill_fraction must be a finite number in [0, 1], got -0.1"),
    ("min_portion_cm3", -1, "min_portion_cm3 must be a finite number in [0, inf)"),
    ("min_portion_fraction", 0, "min_portion_fraction must be a finite number in (0, 1]"),
    ("bowl_x_range", (0, 5), "bowl_x_range must lie on the table, within +-0.4 m of its centre"),
    ("bowl_y_range", 0.1, "bowl_y_range must be 2 finite numbers, got 0.1"),
    ("bowl_x_range", (0.1, -0.1), "bowl_x_range must be (low, high) with low <= high"),
    ("pile_variants", 2.5, "pile_variants must be a positive integer, got 2.5"),
    ("pile_variants", "x", "pile_variants must be a positive integer, got 'x'"),
    ("n_grains", True, "n_grains must be a positive integer or None (the food's default), got True"),
    ("n_grains", 100000, "n_grains 100000 is more than a bowl of pasta settles in reasonable time"),
    ("physics_solver_options", {"iterations": "-3"}, "physics_solver_options['iterations'] must be a non-negative"),
    ("physics_solver_options", "CG", "physics_solver_options must be None or a dict"),
    ("robots", ["XArm7", "Panda"], "robots must be one robot's name (the task has one spoon arm)"),
    ("robots", 3, "robots must be one robot's name"),
    ("robots", [], "robots must be one robot's name"),
    ("seed", -1, "seed must be None or a non-negative integer, got -1"),
    ("seed", "x", "seed must be None or a non-negative integer, got 'x'"),
    ("pre_scoop_offset", (1, 2), "pre_scoop_offset must be 3 finite numbers, got (1, 2)"),
    ("camera_names", [], "camera_names must be a name or a list of names"),
    ("camera_names", ["nonexistent"], "no camera 'nonexistent' in this scene; its cameras: frontview, "),
    ("use_object_obs", "yes", "use_object_obs must be True or False, got 'yes'"),
    ("controller_configs", "bogus", "controller_configs must be None (the task's OSC_POSE) or a robosuite controller"),
    ("food", ["rice"], "Unknown food ['rice']; accepted foods: "),
]


@pytest.mark.parametrize("name,value,message", BAD_KWARGS, ids=[f"{c[0]}={c[1]!r}" for c in BAD_KWARGS])
def test_robosuite_make_refuses_a_bad_argument_by_name(name, value, message):
    with pytest.raises(ValueError) as refused:
        robosuite.make("ScoopGranular", **dict(LIGHT, **{name: value}))
    assert message in str(refused.value)
    assert "\n" not in str(refused.value)


@pytest.fixture(scope="module")
def env():
    env = robosuite.make("ScoopGranular", **LIGHT)
    env.reset()
    yield env
    env.close()


@pytest.mark.parametrize(
    "action",
    [np.zeros(5), np.zeros(7), 0.0, ["a"] * 6, None, np.zeros((2, 3)), np.zeros(6, complex), {"x": 1}],
    ids=["5 numbers", "7 numbers", "a scalar", "strings", "None", "a 2x3 array", "complex", "a dict"],
)
def test_a_step_refuses_what_is_not_an_action(env, action):
    with pytest.raises(ValueError, match=r"an action must be 6 real numbers \(env.action_spec\), got "):
        env.step(action)
    _, _, done, info = env.step(np.zeros(6))  # the episode goes on
    assert not done and not info.get("physics_error")


def test_a_reset_refuses_a_bad_seed(env):
    for seed in (-1, "x", 2.5):
        with pytest.raises(ValueError, match="seed must be None or a non-negative integer"):
            env.reset(seed=seed)


@pytest.mark.parametrize(
    "kwargs,message",
    [
        (dict(render_size=(0, -1)), "render_size must be (height, width), two positive integers"),
        (dict(success_hold_s="x"), "success_hold_s must be None or a finite number of seconds, got 'x'"),
        (dict(robots=["XArm7"], horizon=0), "horizon must be a positive integer"),
        (dict(robots="Bogus"), "Unknown robot 'Bogus'"),
    ],
)
def test_the_gym_wrapper_refuses_bad_arguments(kwargs, message):
    with pytest.raises(ValueError) as refused:
        ScoopGranularGymEnv(**dict(dict(food="pasta", n_grains=12), **kwargs))
    assert message in str(refused.value)


def test_the_dataset_functions_refuse_bad_numbers_before_touching_a_file(tmp_path):
    missing = tmp_path / "never_read.hdf5"
    cases = [
        (lambda: merge_datasets(str(missing), tmp_path / "out.hdf5"), "inputs must be a list of dataset files"),
        (lambda: merge_datasets([missing], tmp_path / "out.hdf5", valid_ratio=-0.5), "must lie in [0, 1), got -0.5"),
        (lambda: merge_datasets([missing], tmp_path / "out.hdf5", valid_ratio=float("nan")), "got nan"),
        (lambda: split_dataset(missing, "0.1"), "the validation ratio must lie in [0, 1), got '0.1'"),
        (lambda: drop_noops(missing, tmp_path / "out.hdf5", threshold=float("nan")), "no-op threshold"),
        (lambda: drop_noops(missing, tmp_path / "out.hdf5", threshold=-1), "must lie in [0, 1)"),
        (lambda: replay_demos(missing, None, n=-1), "n must be a positive integer or None (all), got -1"),
        (lambda: replay_demos(missing, None, skip=0), "skip must be a positive integer, got 0"),
        (lambda: replay_demos(missing, None, height=0), "height must be a positive integer, got 0"),
    ]
    for call, message in cases:
        with pytest.raises(ValueError) as refused:
            call()
        assert message in str(refused.value)
    assert list(tmp_path.iterdir()) == []


def test_a_name_where_a_list_is_expected_is_refused_not_spelled_out():
    with pytest.raises(ValueError, match=r"foods must be a list of food names, got one name: 'rice'"):
        check_foods("rice")
    with pytest.raises(ValueError, match=r"train_foods must be a non-empty list of names, got 'rice'"):
        PipelineSettings(output_dir="unused", train_foods="rice")
    with pytest.raises(TypeError, match="register_food takes a FoodSpec"):
        register_food("rice")
    with pytest.raises(ValueError, match="Unknown food"):
        get_food(["rice"])


@pytest.mark.parametrize(
    "kwargs,message",
    [
        (dict(algos=[]), "algos must be a non-empty list of names, got []"),
        (dict(horizon="ten"), "horizon must be a positive integer, got 'ten'"),
        (dict(epochs=2.5), "epochs must be a positive integer, got 2.5"),
        (dict(n_grains=-5), "n_grains must be a positive integer or None"),
        (dict(n_grains=10**9), "n_grains 1000000000 is more than a bowl of rice settles"),
        (dict(seed=-1), "seed must be a non-negative integer, got -1"),
        (dict(eval_foods=[]), "eval_foods must be a non-empty list of names"),
    ],
)
def test_a_study_refuses_bad_settings_when_made(kwargs, message):
    with pytest.raises(ValueError) as refused:
        PipelineSettings(output_dir="unused", **kwargs)
    assert message in str(refused.value)
