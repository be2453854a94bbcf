"""The episode loop veragmil-collect and veragmil-evaluate share, on a scripted fake env: how each end reason
comes about (success held, physics error, the agent stopping, the horizon or done), the stage and peak load it
tracks, and its per-step hooks."""

import numpy as np
import pytest

from veragmil_suite.environments.episode import SUCCESS_HOLD_S, run_until_done

CONTROL_FREQ = 20  # a hold of 0.1 s is 2 steps


class FakeEnv:
    """Steps through a list of infos; done after the last one, or after ``done_at`` steps."""

    def __init__(self, infos, done_at=None):
        self.infos = infos
        self.done_at = len(infos) if done_at is None else done_at
        self.actions = []

    def step(self, action):
        self.actions.append(action)
        n = len(self.actions)
        return {"n": n}, 0.0, n >= self.done_at, dict(self.infos[n - 1])


def _info(success=False, grains=0, stage="start", physics=""):
    return dict(success=success, grains_in_spoon=grains, stage=stage, physics_error=physics)


def _act(obs):
    return np.zeros(7)


def _run(infos, horizon=100, act=_act, done_at=None, **kwargs):
    env = FakeEnv(infos, done_at)
    return env, run_until_done(act, env.step, {"n": 0}, CONTROL_FREQ, horizon, **kwargs)


def test_success_must_hold_for_round_hold_times_rate_consecutive_steps():
    ok = _info(True, 3, "at post-scoop pose")
    infos = [_info(), ok, _info(False, 3, "lifted clear"), ok, ok, ok, _info()]
    env, end = _run(infos, success_hold_s=0.15)  # round(0.15 * 20) = 3 steps: the streak broken at step 3
    assert (end.reason, end.steps) == ("success", 6)
    assert end.stage == "held" and end.info["success"]
    _, end = _run(infos, success_hold_s=0.01)  # shorter than one step: the first success ends it
    assert (end.reason, end.steps) == ("success", 2)
    _, end = _run(infos, success_hold_s=SUCCESS_HOLD_S)  # 20 steps never come: the env's done ends it
    assert (end.reason, end.steps) == ("horizon", 7)


@pytest.mark.parametrize("hold", [0, -1.0, None])
def test_a_hold_of_zero_or_none_leaves_success_out_of_the_ending_rule(hold):
    infos = [_info(True, 3, "at post-scoop pose")] * 5
    _, end = _run(infos, success_hold_s=hold)
    assert (end.reason, end.steps) == ("horizon", 5) and end.stage == "held"


def test_a_physics_error_ends_the_episode_before_success_or_done():
    infos = [_info(True), _info(True, physics="qacc blew up")]
    _, end = _run(infos, success_hold_s=0.1)  # the 2-step hold would be met at step 2
    assert (end.reason, end.steps) == ("physics", 2)
    assert end.info["physics_error"] == "qacc blew up"


def test_an_agent_that_stops_ends_with_the_callers_reason():
    actions = iter([np.zeros(7), np.zeros(7), None])
    infos = [_info(False, 4, "reached pile"), _info(False, 9, "loaded spoon"), _info()]
    env, end = _run(infos, act=lambda obs: next(actions))
    assert (end.reason, end.steps) == ("gave up", 2) and len(env.actions) == 2
    assert end.stage == "loaded spoon" and end.peak_grains_in_spoon == 9  # the furthest stage, the largest load
    _, end = _run(infos, act=lambda obs: None, stopped="operator")  # a human who stops before any step
    assert (end.reason, end.steps, end.info) == ("operator", 0, {})
    assert end.stage == "start" and end.peak_grains_in_spoon == 0


def test_the_horizon_counts_steps_and_done_ends_as_the_horizon():
    infos = [_info(False, 5, "reached pile")] * 50
    _, end = _run(infos, horizon=10)  # the env would go on: the step count ends it
    assert (end.reason, end.steps) == ("horizon", 10) and end.peak_grains_in_spoon == 5
    _, end = _run(infos, horizon=10, done_at=4)  # the env's done (robosuite's own horizon) comes first
    assert (end.reason, end.steps) == ("horizon", 4)


def test_each_action_sees_the_last_observation_and_hooks_run_after_every_step():
    seen, hooked = [], []

    def act(obs):
        seen.append(obs["n"])
        return np.full(7, obs["n"], dtype=float)

    env, end = _run([_info()] * 3, act=act, on_step=lambda: hooked.append(len(seen)))
    assert seen == [0, 1, 2] and hooked == [1, 2, 3]
    assert [a[0] for a in env.actions] == [0, 1, 2]


def test_realtime_waits_out_the_rest_of_each_control_period(monkeypatch):
    from veragmil_suite.environments import episode

    waits = []
    monkeypatch.setattr(episode.time, "sleep", waits.append)
    _, end = _run([_info()] * 3, realtime=True)
    assert end.steps == 3 and len(waits) == 2  # no wait after the last step
    assert all(0.0 < w <= 1.0 / CONTROL_FREQ for w in waits)
    waits.clear()
    _run([_info()] * 3)
    assert waits == []
