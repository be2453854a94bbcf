"""The scripted expert: it succeeds on seen foods, follows the bowl, and its 3D-mouse profile moves one axis at a
time with coarse input."""

import json

import numpy as np
import pytest
from helpers.recording import make_env, tiny_env_kwargs

from veragmil_suite.controllers.scoop_config import load_scoop_controller_config
from veragmil_suite.devices.expert import DRIFT_CORRECTION_MAX_S, PROFILES, QUANTIZE_FULL_SCALE, ScriptedScooper
from veragmil_suite.scripts.measure_expert import compare, run_expert_episode


def test_expert_succeeds_on_a_seen_food_over_seeds():
    # buckwheat: the expert's steadiest training food on the calibrated grains (pasta, the fastest scene, drops one
    # piece in 15-30% of episodes); the full per-food measurement is python -m veragmil_suite.scripts.measure_expert
    results = [run_expert_episode("buckwheat", seed) for seed in range(3)]
    assert sum(r["success"] for r in results) >= 2, results
    for r in results:
        assert r["physics_error"] == ""
        if r["success"]:
            assert r["end_reason"] == "success"
            assert r["spill_fraction"] < 0.05
            assert 5.0 < r["completion_time_s"] < 20.0


def test_expert_follows_a_displaced_bowl():
    """Closed loop on the observed bowl: a bowl 4 cm off its usual place is scooped all the same."""
    moved = dict(bowl_x_range=(0.03, 0.03), bowl_y_range=(-0.04, -0.04))
    result = run_expert_episode("rice", 5, env_kwargs=moved)
    assert result["success"], result
    assert result["grains_in_spoon"] >= 10


def test_spacemouse_profile_moves_one_axis_at_a_time_with_coarse_input():
    env = make_env(tiny_env_kwargs(cameras=()))
    obs = env.reset()
    mouse = ScriptedScooper(env, "spacemouse", seed=0)
    step = QUANTIZE_FULL_SCALE / PROFILES["spacemouse"].input_levels
    actions = []
    for _ in range(60):
        action = mouse.act(obs)
        obs, _, _, _ = env.step(action)
        actions.append(action)
    actions = np.array(actions)
    assert ((actions != 0).sum(axis=1) <= 1).all()  # one axis at a time
    np.testing.assert_allclose(actions / step, np.round(actions / step), atol=1e-9)  # coarse levels
    assert (np.abs(actions).sum(axis=1) == 0).any()  # lets go now and then
    assert len({int(np.flatnonzero(a)[0]) for a in actions if a.any()}) >= 2  # but uses more than one axis
    assert mouse.phase_index >= 1  # and gets somewhere: past the approach

    # the expert's own profile moves several axes at once, with fine input
    obs = env.reset()
    expert = ScriptedScooper(env, "expert", seed=0)
    smooth = []
    for _ in range(10):
        action = expert.act(obs)
        obs, _, _, _ = env.step(action)
        smooth.append(action)
    assert ((np.array(smooth) != 0).sum(axis=1) > 1).any()
    env.close()


def test_bad_profile_and_controller_are_named():
    env = make_env(tiny_env_kwargs(cameras=()))
    with pytest.raises(ValueError, match="accepted profiles: .*spacemouse"):
        ScriptedScooper(env, "sloppy")
    env.close()
    ik = make_env(tiny_env_kwargs(cameras=(), controller_configs=load_scoop_controller_config("IK_POSE", "XArm7")))
    with pytest.raises(ValueError, match="OSC_POSE controller with delta input"):
        ScriptedScooper(ik, "expert")
    ik.close()


def test_spacemouse_profile_scoops_a_seen_food():
    """One axis at a time still gets a portion to the post-scoop pose: turns in the pile stop for drift
    corrections, and the hand comes off the input at the pose (coarse nudges there would never hold still)."""
    mouse = run_expert_episode("buckwheat", 0, "spacemouse")
    assert mouse["success"], mouse
    assert mouse["end_reason"] == "success"
    assert mouse["spill_fraction"] < 0.05


def test_one_axis_drift_correction_interrupts_a_turn_and_gives_it_back():
    env = make_env(tiny_env_kwargs(cameras=()))
    env.reset()
    mouse = ScriptedScooper(env, "spacemouse", seed=0)
    limit = PROFILES["spacemouse"].turn_drift_m
    turn = np.array([0.0, 0.0, 0.0, 0.0, 0.5, 0.0])  # 0.5 rad to turn about y: a turn is due
    assert mouse._one_axis(turn, 0.0).argmax() == 4
    # drifted past the limit: the position comes first, for DRIFT_CORRECTION_MAX_S at most
    drifted = turn + np.array([0.0, 0.0, 2 * limit, 0.0, 0.0, 0.0])
    axes = [int(mouse._one_axis(drifted, 2 * limit).argmax()) for _ in range(40)]
    max_steps = int(DRIFT_CORRECTION_MAX_S * env.control_freq)
    assert axes[:max_steps] == [2] * max_steps
    assert 4 in axes[max_steps:]  # a spoon stalled in the pile turns on
    env.close()


def test_measure_expert_compares_runs_seed_by_seed(tmp_path):
    def episode(food, seed, load, success=True, wall_s=10.0):
        return dict(
            food=food,
            seed=seed,
            grains_in_spoon=load,
            success=success,
            grains_spilled=0,
            completion_time_s=9.0,
            steps=200,
            wall_s=wall_s,
        )

    before = dict(mujoco="3.3.7", sleep_tolerance=None, episodes=[episode("rice", 0, 20), episode("rice", 1, 30)])
    after = dict(
        mujoco="3.8.1",
        sleep_tolerance=3e-3,
        solver={"iterations": "20"},
        episodes=[episode("rice", 0, 20, wall_s=5.0), episode("rice", 1, 26, False, wall_s=5.0)],
    )
    paths = []
    for name, run in (("before", before), ("after", after)):
        paths.append(tmp_path / f"{name}.json")
        paths[-1].write_text(json.dumps(run))
    table = compare([str(p) for p in paths])
    assert "| rice | 2/2, 25.0 +- 5.0, 0.0, 9.00 s, 20.0/s | 1/2, 23.0 +- 3.0, 0.0, 9.00 s, 40.0/s |" in table
    assert "mujoco 3.3.7, sleep off" in table and "mujoco 3.8.1, sleep 0.003, step 1/240 s, iterations=20" in table
    assert "rice -2.0 (same load 1/2)" in table
    # a run of fewer foods (here one at another physics step) leaves the others' cells empty
    after.update(physics_timestep_s=1 / 200, episodes=[episode("peas", 0, 40)])
    paths[1].write_text(json.dumps(after))
    before["episodes"].append(episode("peas", 0, 40))
    paths[0].write_text(json.dumps(before))
    table = compare([str(p) for p in paths])
    assert "| rice | 2/2, 25.0 +- 5.0, 0.0, 9.00 s, 20.0/s | not run |" in table
    assert "step 1/200 s, iterations=20" in table and "peas +0.0 (same load 1/1)" in table


def test_a_registered_profile_is_an_operator_and_a_name_registers_once():
    from veragmil_suite.devices.expert import OperatorProfile, get_profile, register_profile
    from veragmil_suite.utils import cli

    assert cli.profile("expert") == "expert"  # a parser used before the profile is registered takes it after
    profile = register_profile(OperatorProfile("test-slow", speed=0.5))  # called with a profile, as a plugin may
    try:
        assert get_profile("test-slow") is profile
        assert cli.profile("test-slow") == "test-slow"  # --profile takes it
        with pytest.raises(ValueError, match="registered already"):
            register_profile(OperatorProfile("test-slow"))

        @register_profile
        def test_fast() -> OperatorProfile:
            """Registered by decorator, as the package's own profiles are."""
            return OperatorProfile("test-fast", speed=2.0)

        assert callable(test_fast) and get_profile("test-fast").speed == 2.0
        with pytest.raises(TypeError, match="must give an entry of type OperatorProfile"):
            register_profile(lambda: "test-none")
    finally:
        PROFILES.pop("test-slow", None)
        PROFILES.pop("test-fast", None)
