"""MuJoCo's island sleeping in ScoopGranular: a settled pile falls asleep and stays put, the spoon wakes what it
touches and scoops as without sleeping, nothing is left asleep in the air, and replay stays exact."""

import re

import numpy as np
import pytest
from helpers.env import grain_positions, make_env
from helpers.programs import run_script

from veragmil_suite.devices.expert import ScriptedScooper
from veragmil_suite.learning.robomimic_obs import model_xml
from veragmil_suite.models.scoop_task import GRAIN_SLEEP_TOLERANCE

# control steps a settled pile is given to fall asleep (within 10 at GRAIN_SLEEP_TOLERANCE, 40 at 1e-3)
REST_STEPS = 40


def _asleep(env) -> np.ndarray:
    """Per grain: whether MuJoCo has it asleep."""
    return env.sim.data._data.body_awake[env.grain_body_ids] == 0


def _spoon_touches_a_sleeping_grain(env) -> bool:
    data = env.sim.data
    contacts = data.contact[: data.ncon]
    geoms = np.stack([contacts.geom1, contacts.geom2], axis=1)
    spoon = np.isin(geoms, env.spoon_geom_ids).any(axis=1)
    bodies = env.sim.model.geom_bodyid[geoms[spoon]].ravel()
    asleep = env.sim.data._data.body_awake[bodies] == 0
    return bool(np.any(asleep & np.isin(bodies, env.grain_body_ids)))


def test_sleeping_is_on_by_default_and_off_with_none():
    on, off = make_env("pasta", n_grains=12), make_env("pasta", n_grains=12, sleep_tolerance=None)
    on.reset(), off.reset()
    assert on.sim.model._model.opt.sleep_tolerance == GRAIN_SLEEP_TOLERANCE
    for _ in range(REST_STEPS):
        on.step(np.zeros(6)), off.step(np.zeros(6))
    assert _asleep(on).all() and not _asleep(off).any()
    on.close(), off.close()
    with pytest.raises(ValueError, match="sleep_tolerance must be a positive number .* or None"):
        make_env("pasta", sleep_tolerance=0)


def test_a_settled_pile_falls_asleep_and_stays_settled():
    # without sleeping a settled barley pile creeps (at most 1.5 mm in 40 steps, 5 mm in 200); asleep, it stops
    env = make_env("barley")
    env.reset()
    start = grain_positions(env)
    for _ in range(REST_STEPS):
        env.step(np.zeros(6))
    assert _asleep(env).all()
    asleep_at = grain_positions(env)
    assert np.linalg.norm(asleep_at - start, axis=1).max() < 2e-3
    for _ in range(REST_STEPS):
        env.step(np.zeros(6))
    np.testing.assert_array_equal(grain_positions(env), asleep_at)
    env.close()


def test_the_spoon_wakes_what_it_touches_and_leaves_nothing_asleep_in_the_air():
    env = make_env("barley")
    expert = ScriptedScooper(env, "expert", seed=0)
    obs = env.reset()
    for _ in range(REST_STEPS):
        obs, *_ = env.step(np.zeros(6))
    assert _asleep(env).all()
    touched_asleep, woke, info = 0, False, {}
    while not expert.done:
        obs, _, _, info = env.step(expert.executed(expert.act(obs)))
        touched_asleep += _spoon_touches_a_sleeping_grain(env)
        woke |= not _asleep(env).any()
    assert woke and touched_asleep == 0
    assert info["success"] and info["grains_in_spoon"] >= 5
    # the spoon holds still at the post-scoop pose: the pile falls asleep again
    assert _asleep(env).mean() > 0.5

    # the same state with sleeping off: a grain left asleep without support would now fall
    state, xml = env.sim.get_state().flatten(), model_xml(env)
    awake = make_env("barley", sleep_tolerance=None)
    awake.reset_from_xml_string(xml.replace('sleep="enable"', 'sleep="disable"'))
    awake.sim.set_state_from_flattened(state)
    awake.sim.forward()
    # the grains in the bowl (the arm, uncontrolled here, sags with the spoon's)
    bowl = ~env._scoop_metrics()["in_spoon"]
    before = grain_positions(awake)[bowl]
    for _ in range(10):
        awake.sim.step()
    assert np.linalg.norm(grain_positions(awake)[bowl] - before, axis=1).max() < 2e-3
    env.close(), awake.close()


def _playback_start(env, xml: str, state: np.ndarray) -> None:
    """robosuite's playback recipe: XML + flattened state, then the actions open loop."""
    env.reset_from_xml_string(xml)
    env.sim.reset()
    env.sim.set_state_from_flattened(state)
    env.sim.forward()


def test_open_loop_replay_through_sleep_and_wake_is_exact():
    a = make_env("pasta", n_grains=20, seed=3)
    a.reset()
    xml, start = model_xml(a), a.sim.get_state().flatten()
    _playback_start(a, xml, start)
    rng = np.random.default_rng(0)
    # still (the pile falls asleep), then the spoon pushed down into it (it wakes)
    actions = np.concatenate([np.zeros((REST_STEPS, 6)), np.tile([0.0, 0.0, -0.5, 0, 0, 0], (15, 1))])
    actions[REST_STEPS:, :2] = rng.uniform(-0.2, 0.2, size=(15, 2))
    states, asleep = [], []
    for act in actions:
        a.step(act)
        states.append(a.sim.get_state().flatten())
        asleep.append(_asleep(a).mean())
    assert max(asleep) == 1.0 and asleep[-1] < 1.0  # it did sleep, and woke
    b = make_env("pasta", n_grains=20, seed=3)
    _playback_start(b, xml, start)
    for act, expected in zip(actions, states):
        b.step(act)
        np.testing.assert_array_equal(b.sim.get_state().flatten(), expected)
    a.close(), b.close()


def test_benchmark_reports_how_much_of_an_episode_the_whole_pile_is_awake(capsys):
    """The speed benchmark's expert table: both settings' episodes are counted (successes off/on) and the pile is
    awake for part of the episode only (asleep before the spoon arrives), the share sleeping cannot make cheaper."""
    from veragmil_suite.scripts import bench

    bench.main(["--foods", "pasta", "--scales", "1", "--steps", "3", "--episodes", "1"])
    out = capsys.readouterr().out
    header, _, row = out.split("Whole expert episodes")[1].strip().splitlines()[1:4]
    assert header.split()[-6:] == ["pile", "up", "up", "time", "ceiling", "mujoco"]
    assert re.fullmatch(r"[01]/[01]", row.split()[6])
    steps, time_share, ceiling, mujoco_share = (float(cell.rstrip("%x")) for cell in row.split()[-4:])
    assert 0 < steps < 100 and 0 < time_share < 100 and 0 < mujoco_share <= 100
    assert time_share > steps  # the steps with the whole pile awake are the dear ones
    gain = float(row.split()[3].rstrip("x"))
    assert ceiling >= gain
    assert re.search(r"slowest training food over whole episodes: pasta .* sleeping's ceiling \d+\.\d\dx", out)


def test_sleeping_ceiling_counts_only_the_steps_with_the_whole_pile_awake():
    from veragmil_suite.scripts.bench import sleeping_ceiling

    # off: 0.1 s a step; on: 0.05 s a step, half of it in steps with the pile awake (0.025 s a step)
    assert sleeping_ceiling({"rate": 10.0}, {"rate": 20.0, "pile_awake_time": 0.5}) == pytest.approx(4.0)
    assert sleeping_ceiling({"rate": 10.0}, {"rate": 20.0, "pile_awake_time": 0.0}) == float("inf")


def test_pile_up_bench_times_the_same_steps_with_sleeping_on_and_off():
    """results/awake_pile/bench_pile_up.py (the premise of the ceiling column): one row per seed, with the steps that
    end with the whole pile awake counted and timed in both runs, and a clear error for a food it does not know."""
    script = "results/awake_pile/bench_pile_up.py"
    row = run_script(script, "--foods", "pasta", "--seeds", "1").stdout.strip().splitlines()[-1].split()
    assert row[:2] == ["pasta", "0"]
    pile_up, times = int(row[3]), [float(cell) for cell in row[4:8]]
    assert pile_up > 0 and all(t > 0 for t in times)
    result = run_script(script, "--foods", "soup", check=False)
    assert result.returncode == 2 and "unknown food(s) soup; accepted foods: rice" in result.stderr
