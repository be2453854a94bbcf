"""robosuite's own recipes on ScoopGranular, unchanged: DataCollectionWrapper recording, the replay of
robosuite's playback_demonstrations_from_hdf5.py (model XML, flattened state, actions open loop), seeded
determinism and camera observations, for every food and every robot that carries the spoon; any saved model
loads back, adopted whatever the environment was made with; robosuite.make with the README's defaults, and one
plain warning for a controller the task was not tuned for."""

import glob
import json
import os
import re
import warnings

import mujoco
import numpy as np
import pytest
import robosuite
from helpers.env import make_env
from robosuite.controllers import load_composite_controller_config
from robosuite.wrappers import DataCollectionWrapper

from veragmil_suite.controllers.scoop_config import (
    UntunedControllerWarning,
    load_scoop_controller_config,
    untuned_controller_difference,
)
from veragmil_suite.environments import settling
from veragmil_suite.models import humanoid
from veragmil_suite.models.foods import FOODS
from veragmil_suite.models.scoop_task import PHYSICS_TIMESTEP_S, check_physics_timestep

ARMS = ["XArm7", "Panda", "Sawyer", "UR5e", "IIWA", "Kinova3", "Jaco"]
SPOON_ROBOTS = ARMS + (list(humanoid.G1_ROBOTS) if humanoid.robosuite_models_installed() else [])
CAMERA = dict(camera_names="overhead", camera_heights=32, camera_widths=32)
TINY = dict(n_grains=8, pile_variants=1, horizon=20)


def _record(env, directory, actions) -> tuple[list, list, int]:
    """robosuite's DataCollectionWrapper around env for one episode of ``actions``; returns the camera images seen,
    the episode folders written and the number of bodies of the scene recorded."""
    wrapped = DataCollectionWrapper(env, str(directory))
    wrapped.reset()
    nbody = env.sim.model.nbody
    images = [wrapped.step(a)[0]["overhead_image"] for a in actions]
    wrapped.close()
    return images, glob.glob(os.path.join(directory, "ep_*")), nbody


def _load_episode(folder) -> tuple[str, np.ndarray, np.ndarray]:
    """What robosuite's gather_demonstrations_as_hdf5 reads from an episode folder: model XML, states, actions."""
    states, actions = [], []
    for path in sorted(glob.glob(os.path.join(folder, "state_*.npz"))):
        saved = np.load(path, allow_pickle=True)
        states.extend(saved["states"])
        actions.extend(info["actions"] for info in saved["action_infos"])
    with open(os.path.join(folder, "model.xml")) as f:
        return f.read(), np.array(states), np.array(actions)


def _playback(env, xml, states, actions) -> list:
    """robosuite's playback_demonstrations_from_hdf5.py --use-actions: reload the XML, set the first state, replay
    the actions open loop and check each state reached; returns the camera images."""
    env.reset()
    env.reset_from_xml_string(xml)
    env.sim.reset()
    env.sim.set_state_from_flattened(states[0])
    env.sim.forward()
    images = []
    for j, action in enumerate(actions):
        images.append(env.step(action)[0]["overhead_image"])
        if j < len(actions) - 1:
            np.testing.assert_array_equal(env.sim.get_state().flatten(), states[j + 1], err_msg=f"step {j}")
    return images


@pytest.mark.parametrize(
    "food, robot", [(food, "XArm7") for food in sorted(FOODS)] + [("pasta", r) for r in SPOON_ROBOTS[1:]]
)
def test_data_collection_wrapper_records_and_robosuites_playback_replays_exactly(tmp_path, food, robot):
    env = make_env(food, robot=robot, has_offscreen_renderer=True, use_camera_obs=True, **CAMERA, **TINY)
    actions = np.random.default_rng(0).uniform(-0.5, 0.5, size=(6, env.action_dim))
    recorded_images, folders, nbody = _record(env, tmp_path, actions)
    assert len(folders) == 1
    xml, states, actions_read = _load_episode(folders[0])
    np.testing.assert_array_equal(actions_read, actions)
    assert len(states) == len(actions) + 1
    # the stored model is this scene's: its grains, and MuJoCo's rounded step run exactly as recorded
    assert mujoco.MjModel.from_xml_string(xml).nbody == nbody
    assert 'timestep="0.00416667"' in xml
    replayed_images = _playback(env, xml, states, actions)
    np.testing.assert_array_equal(replayed_images, recorded_images)
    assert replayed_images[0].shape == (32, 32, 3) and replayed_images[-1].std() > 0
    env.close()


def test_a_saved_model_of_another_food_and_grain_count_is_adopted(tmp_path):
    """The playback environment was made for rice: the recorded pasta model is loaded as it is."""
    recording = make_env("pasta", **TINY)
    actions = np.random.default_rng(1).uniform(-0.5, 0.5, size=(4, recording.action_dim))
    wrapped = DataCollectionWrapper(recording, str(tmp_path))
    wrapped.reset()
    for a in actions:
        wrapped.step(a)
    wrapped.close()
    xml, states, _ = _load_episode(glob.glob(os.path.join(tmp_path, "ep_*"))[0])
    player = make_env("rice", n_grains=10, pile_variants=1)
    player.reset()
    player.reset_from_xml_string(xml)
    assert (player.food.name, player.n_grains, player.pile_variant) == ("pasta", 8, recording.pile_variant)
    np.testing.assert_array_equal(player.grain_volumes_m3, recording.grain_volumes_m3)
    assert player.model_timestep == PHYSICS_TIMESTEP_S
    player.sim.set_state_from_flattened(states[0])
    player.sim.forward()
    for a, expected in zip(actions, states[1:]):
        player.step(a)
        np.testing.assert_array_equal(player.sim.get_state().flatten(), expected)
    # its next fresh model is the food it was made with again
    player.reset()
    assert (player.food.name, player.n_grains) == ("rice", 10)
    recording.close(), player.close()


def test_get_xml_is_this_environments_model_whatever_was_compiled_since(tmp_path, monkeypatch):
    """robosuite's sim.model.get_xml() saves MuJoCo's last parsed XML: settling an uncached pile and making another
    environment parse models of their own."""
    monkeypatch.setenv("VERAGMIL_CACHE_DIR", str(tmp_path))
    monkeypatch.setattr(settling, "_MEMORY", {})
    env = make_env("barley", seed=77, n_grains=10)
    env.reset()  # settles a pile in a model of its own
    saved = mujoco.MjModel.from_xml_string(env.sim.model.get_xml())
    assert (saved.nbody, saved.ngeom) == (env.sim.model.nbody, env.sim.model.ngeom)
    other = make_env("pasta", n_grains=8)
    saved = mujoco.MjModel.from_xml_string(env.sim.model.get_xml())
    assert (saved.nbody, saved.ngeom) == (env.sim.model.nbody, env.sim.model.ngeom)
    np.testing.assert_allclose(saved.geom_size, env.sim.model.geom_size, rtol=1e-5)
    env.close(), other.close()


def test_same_seed_same_model_states_and_camera_images():
    """Seeded determinism as robosuite users check it: robosuite.make(..., seed=s) twice, the same actions."""
    a, b = (make_env("buckwheat", seed=5, use_camera_obs=True, has_offscreen_renderer=True, **CAMERA, **TINY)
            for _ in range(2))  # fmt: skip
    obs_a, obs_b = a.reset(), b.reset()
    assert a.sim.model.get_xml() == b.sim.model.get_xml()
    np.testing.assert_array_equal(obs_a["overhead_image"], obs_b["overhead_image"])
    for action in np.random.default_rng(2).uniform(-0.5, 0.5, size=(4, a.action_dim)):
        obs_a, obs_b = a.step(action)[0], b.step(action)[0]
        np.testing.assert_array_equal(a.sim.get_state().flatten(), b.sim.get_state().flatten())
        np.testing.assert_array_equal(obs_a["overhead_image"], obs_b["overhead_image"])
    a.close(), b.close()


def test_a_step_saved_to_six_digits_is_the_step_it_was():
    assert check_physics_timestep(0.00416667, 20) == PHYSICS_TIMESTEP_S
    assert check_physics_timestep(0.00416667, 60) == PHYSICS_TIMESTEP_S
    assert check_physics_timestep(0.005, 20) == 0.005
    with pytest.raises(ValueError, match=r"accepted control frequencies \(Hz\) at this step, .*: 240, 120, 80, 60"):
        check_physics_timestep(0.00416667, 7)
    with pytest.raises(ValueError, match="accepted physics steps"):
        check_physics_timestep(0.0042, 20)
    env = robosuite.make("ScoopGranular", robots="XArm7", food="pasta", **TINY, has_offscreen_renderer=False,
                         use_camera_obs=False, physics_timestep_s=0.00416667)  # fmt: skip
    assert env.sim.model.opt.timestep == env.model_timestep == PHYSICS_TIMESTEP_S
    env.close()


def test_robosuite_make_with_the_readmes_defaults():
    with warnings.catch_warnings():
        warnings.simplefilter("error", UntunedControllerWarning)
        env = robosuite.make("ScoopGranular")
    assert (env.robots[0].name, env.food.name, env.action_dim) == ("XArm7", "rice", 6)
    env.close()


def test_an_untuned_controller_is_said_once_at_make_time():
    """robosuite's usual config gives the arm robosuite's stiffness and action scale, not the task's."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        env = make_env("pasta", controller_configs=load_composite_controller_config(controller="BASIC", robot="XArm7"))
    said = [w for w in caught if issubclass(w.category, UntunedControllerWarning)]
    assert len(said) == 1
    assert re.search(r"kp 150 \(tuned: 2000\); right arm output_max \[0.05, .*\(tuned: \[0.01851", str(said[0].message))
    env.close()
    # the task's own configs, as datasets store them (JSON), are the tuned ones
    for name in ("OSC_POSE", "IK_POSE"):
        stored = json.loads(json.dumps(load_scoop_controller_config(name, robot="Panda")))
        assert untuned_controller_difference(stored, "Panda") == ""
    assert untuned_controller_difference(load_scoop_controller_config(robot="G1ArmsOnly"), "G1ArmsOnly") == ""
