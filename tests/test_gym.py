"""The Gymnasium environment (veragmil/ScoopGranular-v0): Gymnasium's own checker, seeded resets, termination on
held success and physics errors, truncation at the horizon, camera observations, bad arguments, and a
Gymnasium-driven episode written to and read back from our HDF5 schema."""

import warnings

import gymnasium
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env
from helpers.env import grain_positions
from helpers.env import make_env as make_robosuite_env

import veragmil_suite
from veragmil_suite.controllers.scoop_config import load_scoop_controller_config
from veragmil_suite.data.schema import check_schema, demo_names, env_meta, open_dataset, provenance
from veragmil_suite.data.writer import DemoWriter
from veragmil_suite.devices.expert import ScriptedScooper
from veragmil_suite.environments.episode import SUCCESS_HOLD_S

# a light scene: a dozen pasta pieces, one pile variant (tests/helpers/recording.py's)
TINY = dict(food="pasta", n_grains=12, pile_variants=1)
OBJECT_STATE_DIM = 15  # desired_pose 7, bowl_pos 3, spoon_to_desired_pos 3, spoon_load 2: first in the state vector


def make(**kwargs):
    return gymnasium.make(veragmil_suite.GYM_ENV_ID, **{**TINY, **kwargs})


def test_gymnasium_env_checker_passes():
    env = make()
    assert isinstance(env.action_space, gymnasium.spaces.Box) and env.action_space.shape == (6,)
    assert isinstance(env.observation_space, gymnasium.spaces.Box) and env.observation_space.dtype == np.float64
    assert env.unwrapped.robosuite_env.food.name == "pasta"
    # seeded resets, deterministic steps, fresh data; render ("rgb_array") and close on new envs from the spec
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        check_env(env.unwrapped)
    # nothing to warn about but the state's unbounded Box (joint velocities and accelerations have no bound)
    assert all("infinity" in str(w.message) for w in caught), [str(w.message) for w in caught]
    env.close()


def test_the_same_seed_gives_the_same_bowl_pile_and_first_observation():
    a, b = make(pile_variants=2), make(pile_variants=2)
    obs_a, info_a = a.reset(seed=7)
    obs_b, _ = b.reset(seed=7)
    np.testing.assert_array_equal(obs_a, obs_b)
    env_a, env_b = a.unwrapped.robosuite_env, b.unwrapped.robosuite_env
    assert env_a.pile_variant == env_b.pile_variant
    np.testing.assert_array_equal(grain_positions(env_a), grain_positions(env_b))
    assert info_a["is_success"] is False and info_a["grains_in_spoon"] == 0

    # after steps and other seeds, the seed gives that episode again; another seed gives another bowl
    for _ in range(3):
        a.step(a.action_space.sample())
    assert not np.array_equal(a.reset(seed=8)[0], obs_a)
    np.testing.assert_array_equal(a.reset(seed=7)[0], obs_a)

    # and it is ScoopGranular's own reset(seed): the bowl of veragmil-collect's attempt of that seed
    raw = make_robosuite_env(**{**TINY, "pile_variants": 2}, seed=0)
    np.testing.assert_array_equal(raw.reset(seed=7)["object-state"], obs_a[:OBJECT_STATE_DIM])
    for env in (a, b, raw):
        env.close()


def test_held_success_terminates_and_is_success_is_the_suites_rule():
    """The scripted expert, driven through the Gymnasium env: terminated once success has held SUCCESS_HOLD_S.

    Seeds are tried in turn until one episode succeeds: whether one seed's scoop does is a property of the CPU (a
    pile is chaotic), the termination rule checked on it is not.
    """
    env = make(horizon=400)
    inner = env.unwrapped
    for seed in range(4):
        env.reset(seed=seed)
        expert = ScriptedScooper(inner.robosuite_env, "expert", seed=seed)
        successes, terminated, truncated = [], False, False
        while not (terminated or truncated or expert.done):
            obs, reward, terminated, truncated, info = env.step(expert.act(inner.robosuite_obs))
            successes.append(info["success"])
            assert info["is_success"] == terminated  # success held is the only way this episode terminates
        if terminated:
            break
    assert terminated and not truncated and info["is_success"], info
    assert info["physics_error"] == "" and info["grains_in_spoon"] >= 1
    hold = round(SUCCESS_HOLD_S * inner.robosuite_env.control_freq)
    assert inner.hold.steps == hold
    assert all(successes[-hold:]) and (len(successes) == hold or not successes[-hold - 1])
    assert reward == 1.0  # robosuite's sparse reward on a successful step
    env.close()


def test_truncated_at_the_horizon_and_terminated_at_a_physics_error():
    env = make(horizon=5)
    env.reset(seed=1)
    ends = [env.step(np.zeros(6))[2:4] for _ in range(5)]
    assert ends == [(False, False)] * 4 + [(False, True)]

    env.reset(seed=1)
    _, reward, terminated, truncated, info = env.step(np.full(6, np.nan))  # ScoopGranular refuses it as a blow-up
    assert (terminated, truncated, info["is_success"]) == (True, False, False)
    assert "non-finite action" in info["physics_error"] and reward == 0.0
    env.close()


def test_pixels_mode_returns_upright_camera_images_in_a_dict_space():
    env = make(
        obs_mode="pixels",
        camera_names=["overhead", "agentview"],
        camera_heights=32,
        camera_widths=40,
        camera_depths=True,
        render_mode="rgb_array",
        render_camera="overhead",
        render_size=(32, 40),
    )
    space = env.observation_space
    assert isinstance(space, gymnasium.spaces.Dict)
    assert set(space) == {"state", "overhead_image", "overhead_depth", "agentview_image", "agentview_depth"}
    for camera in ("overhead", "agentview"):
        assert (space[f"{camera}_image"].shape, space[f"{camera}_image"].dtype) == ((32, 40, 3), np.uint8)
        assert space[f"{camera}_depth"].shape == (32, 40, 1)
        assert np.issubdtype(space[f"{camera}_depth"].dtype, np.floating)
    obs, _ = env.reset(seed=2)
    assert obs in space
    proprio = env.unwrapped.robosuite_obs["robot0_proprio-state"]
    assert space["state"].shape == (OBJECT_STATE_DIM + proprio.size,)  # the low-dim vector of obs_mode "state"
    assert obs["overhead_image"].std() > 0  # a picture, not a blank
    # upright, as datasets store images (robosuite renders them upside down), and as render() shows the camera
    raw = env.unwrapped.robosuite_obs["overhead_image"]
    np.testing.assert_array_equal(obs["overhead_image"], raw[::-1])
    np.testing.assert_array_equal(env.render(), obs["overhead_image"])
    obs, *_ = env.step(np.zeros(6))
    assert obs in space
    env.close()


def test_bad_arguments_name_the_accepted_values():
    with pytest.raises(ValueError, match="accepted foods: .*rice"):
        make(food="porridge")
    with pytest.raises(ValueError, match="accepted obs modes: state, pixels"):
        make(obs_mode="video")
    with pytest.raises(ValueError, match="use_camera_obs is set by obs_mode"):
        make(use_camera_obs=True)
    with pytest.raises(ValueError, match="accepted render modes: None, rgb_array"):
        veragmil_suite.ScoopGranularGymEnv(**TINY, render_mode="human")


def test_a_gymnasium_episode_is_recorded_in_our_schema(tmp_path):
    env = make(record=True)
    inner = env.unwrapped
    obs, _ = env.reset(seed=3)
    env.action_space.seed(3)
    actions, observations = [], [obs]
    for _ in range(8):
        actions.append(env.action_space.sample())
        obs, *_ = env.step(actions[-1])
        observations.append(obs)
    path = tmp_path / "gym.hdf5"
    meta = env_meta(inner.env_kwargs)
    writer = DemoWriter(path, meta, provenance(device="gymnasium", operator="random", food="pasta", robot="XArm7"))
    writer.write(inner.recorder.episode(attrs=dict(seed=3)))
    env.close()

    with open_dataset(path) as f:
        env_kwargs = check_schema(f)["env_kwargs"]
        assert env_kwargs["food"] == "pasta"
        # the controller the episode was driven with, as veragmil-collect stores it
        assert env_kwargs["controller_configs"] == load_scoop_controller_config("OSC_POSE", robot="XArm7")
        assert demo_names(f) == ["demo_0"]
        demo = f["data/demo_0"]
        assert demo.attrs["num_samples"] == 8 and demo.attrs["seed"] == 3
        np.testing.assert_array_equal(demo["actions"][()], np.array(actions, dtype=np.float64))
        # what the Gymnasium agent saw is what was recorded, before and after each action
        np.testing.assert_array_equal(demo["obs/object"][()], np.array(observations[:-1])[:, :OBJECT_STATE_DIM])
        np.testing.assert_array_equal(demo["next_obs/object"][()], np.array(observations[1:])[:, :OBJECT_STATE_DIM])


def test_an_action_outside_the_action_space_is_stored_as_the_robot_applied_it(tmp_path):
    """The controller clips its input to the action space; the recorder stores the clipped action it executed,
    so the file holds only valid actions and they replay the recorded states exactly."""
    from veragmil_suite.data.replay import replay_demos

    env = make(record=True)
    inner = env.unwrapped
    env.reset(seed=1)
    wild = np.array([5.0, -3.0, 0.2, 0.0, 1.5, 0.0])
    for action in (wild, np.zeros(6), -wild):
        env.step(action)
    episode = inner.recorder.episode()
    np.testing.assert_array_equal(episode.actions[0], np.clip(wild, -1, 1))
    np.testing.assert_array_equal(episode.actions[2], np.clip(-wild, -1, 1))
    path = tmp_path / "gym.hdf5"
    with DemoWriter(path, env_meta(inner.env_kwargs), provenance("gymnasium", "wild", "pasta", "XArm7")) as writer:
        writer.write(episode)
    env.close()
    (replayed,) = replay_demos(path, None, use_actions=True)
    assert replayed["max_state_error"] == 0.0
