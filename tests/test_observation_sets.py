"""The observation sets: what ScoopGranular's ``object`` holds, and a set without grain counts that the grains do not
change."""

import numpy as np
import pytest
import robosuite
import robosuite.utils.transform_utils as T

import veragmil_suite  # noqa: F401 - registers ScoopGranular
from veragmil_suite.environments.start_pose import POST_SCOOP_EEF_ROT, rotation_to_post_scoop
from veragmil_suite.learning import robomimic_obs
from veragmil_suite.learning.observation_sets import (
    OBJECT_OBSERVABLES,
    OBSERVATION_SETS,
    PRIVILEGED_OBSERVATIONS,
    WRENCH_OBSERVATIONS,
    check_observation_set,
    needs_wrench,
    with_observation_set,
)


@pytest.fixture(scope="module")
def env():
    env = robosuite.make(
        "ScoopGranular", robots="XArm7", food="pasta", n_grains=12, pile_variants=1, has_renderer=False,
        has_offscreen_renderer=False, use_camera_obs=False,
    )  # fmt: skip
    env.reset(seed=0)
    yield env
    env.close()


def test_object_concatenates_the_listed_observables_grain_counts_among_them(env):
    task = [name for name, observable in env._observables.items() if observable.modality == "object"]
    assert tuple(task) == OBJECT_OBSERVABLES
    obs = robomimic_obs.observation(env)
    np.testing.assert_array_equal(obs["object"], np.concatenate([obs[k] for k in OBJECT_OBSERVABLES]))
    assert "spoon_load" in OBJECT_OBSERVABLES and "spoon_load" in PRIVILEGED_OBSERVATIONS


def test_the_no_load_set_holds_no_grain_counts_and_no_grain_moves_it(env):
    keys = OBSERVATION_SETS["no-load"]
    assert not set(keys) & set(PRIVILEGED_OBSERVATIONS)
    before = robomimic_obs.observation(env)
    assert set(keys) <= set(before)
    # every grain carried out of the bowl: the counts change, the no-load observations do not
    qpos = env.sim.data.qpos
    qpos[env.grain_qpos_adr] += 0.5
    after = robomimic_obs.observation(env, robomimic_obs.observe(env))
    assert after["spoon_load"][1] == 12 and before["spoon_load"][1] == 0
    for key in keys:
        np.testing.assert_array_equal(after[key], before[key], err_msg=key)


def test_a_config_takes_a_sets_low_dim_keys_and_an_unknown_set_is_named():
    config = {"observation": {"modalities": {"obs": {"low_dim": ["object"], "rgb": ["overhead_image"]}}}}
    out = with_observation_set(config, "no-load")["observation"]["modalities"]["obs"]
    assert out == {"low_dim": list(OBSERVATION_SETS["no-load"]), "rgb": ["overhead_image"]}
    with pytest.raises(
        ValueError,
        match=r"unknown observation set 'counts'; accepted: "
        r"\['no-load', 'no-load-rot', 'no-load-size', 'object', 'wrench'\]",
    ):
        check_observation_set("counts")


def test_the_wrench_set_adds_the_wrist_sensor_which_reads_the_spoons_weight_at_rest(env):
    keys = OBSERVATION_SETS["wrench"]
    assert keys == OBSERVATION_SETS["no-load"] + WRENCH_OBSERVATIONS
    assert not set(keys) & set(PRIVILEGED_OBSERVATIONS)
    assert needs_wrench(["object", "wrench"]) and not needs_wrench(["object", "no-load"])
    # off by default: every observation of a default dataset can be extracted from its states
    assert not set(WRENCH_OBSERVATIONS) & set(env._observables)
    felt = robosuite.make(
        "ScoopGranular", robots="XArm7", food="pasta", n_grains=12, pile_variants=1, has_renderer=False,
        has_offscreen_renderer=False, use_camera_obs=False, use_wrench_obs=True,
    )  # fmt: skip
    felt.reset(seed=0)
    felt.step(np.zeros(felt.action_dim))  # a step: the sensors read the accelerations of a simulated step
    obs = robomimic_obs.observation(felt)
    assert obs["robot0_eef_force"].shape == obs["robot0_eef_torque"].shape == (3,)
    assert set(WRENCH_OBSERVATIONS) <= set(robomimic_obs.TORQUE_DEPENDENT_OBSERVATIONS)
    # the spoon hangs in the air at the start: the sensor carries the weight of the bodies below its frame
    model = felt.sim.model._model
    sensor = model.sensor(felt.robots[0].gripper["right"].important_sensors["force_ee"])
    weight = model.body_subtreemass[model.site_bodyid[sensor.objid[0]]] * np.linalg.norm(model.opt.gravity)
    assert weight > 0.5
    assert np.linalg.norm(obs["robot0_eef_force"]) == pytest.approx(weight, rel=0.1)
    felt.close()


def test_the_orientation_error_turns_the_spoon_into_the_post_scoop_orientation_and_leaves_object_as_it_was(env):
    keys = OBSERVATION_SETS["no-load-rot"]
    assert keys == OBSERVATION_SETS["no-load"] + ("spoon_to_desired_rot",)
    obs = robomimic_obs.observation(env)
    turn = obs["spoon_to_desired_rot"]
    spoon = env.sim.data.site_xmat[env.eef_site_id].reshape(3, 3)
    applied = T.quat2mat(T.axisangle2quat(turn)) @ spoon
    np.testing.assert_allclose(applied, POST_SCOOP_EEF_ROT, atol=1e-6)
    # the start's spoon is the pre-scoop one: 45 degrees about the world's y from the post-scoop one
    assert np.degrees(np.linalg.norm(turn)) == pytest.approx(45.0, abs=10.0)
    assert env._observables["spoon_to_desired_rot"].modality != "object"
    np.testing.assert_array_equal(obs["object"], np.concatenate([obs[k] for k in OBJECT_OBSERVABLES]))
    # at the pose it is zero, and the angle never exceeds pi (the shorter way round)
    np.testing.assert_allclose(rotation_to_post_scoop(POST_SCOOP_EEF_ROT), 0.0, atol=1e-9)
    flipped = T.quat2mat(np.array([0.0, 0.0, 1.0, 0.0])) @ POST_SCOOP_EEF_ROT
    assert np.linalg.norm(rotation_to_post_scoop(flipped)) == pytest.approx(np.pi, abs=1e-6)


def test_the_piece_size_is_the_piles_largest_piece_and_follows_a_loaded_pile_of_another_food(env):
    """piece_size: the largest piece's length and thickness, what a camera sees of the food (the scripted operator's
    reach into the pile depends on it); another food's saved scene loaded into the environment brings its size."""
    keys = OBSERVATION_SETS["no-load-size"]
    assert keys == OBSERVATION_SETS["no-load"] + ("piece_size",) and "piece_size" not in PRIVILEGED_OBSERVATIONS
    size = robomimic_obs.observation(env)["piece_size"]
    assert size.shape == (2,) and env._observables["piece_size"].modality != "object"
    assert size[0] == pytest.approx(2 * env.grain_pile.radii.max()) and size[0] > size[1] > 0
    assert 0.015 < size[0] < 0.04  # a piece of pasta (macaroni, penne): 2-3.5 cm long
    rice = robosuite.make(
        "ScoopGranular", robots="XArm7", food="rice", n_grains=12, pile_variants=1, has_renderer=False,
        has_offscreen_renderer=False, use_camera_obs=False,
    )  # fmt: skip
    rice.reset(seed=0)
    rice_size = robomimic_obs.observation(rice)["piece_size"]
    assert rice_size[0] < 0.5 * size[0]
    rice.reset_from_xml_string(env.sim.model.get_xml())
    rice.sim.set_state_from_flattened(env.sim.get_state().flatten())
    rice.sim.forward()
    np.testing.assert_allclose(robomimic_obs.observation(rice)["piece_size"], size, rtol=1e-5)
    rice.close()
