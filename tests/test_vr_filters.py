"""Filters: One-Euro on position, adaptive slerp on orientation, jump rejection, velocity clamp."""

import numpy as np
import pytest

from veragmil_suite.devices.vr import frames as F
from veragmil_suite.devices.vr.filters import (
    OneEuroFilter,
    PoseFilter,
    SlerpFilter,
    clamp_rotation,
    clamp_translation,
    smoothing_factor,
)

RATE = 90.0  # Quest 2 default refresh
T = np.arange(0, 3, 1 / RATE)


def test_smoothing_factor_is_a_weight_that_grows_with_cutoff_and_interval():
    a = smoothing_factor(1 / 90, 1.0)
    assert 0 < a < smoothing_factor(1 / 90, 10.0) < 1
    assert a < smoothing_factor(1 / 30, 1.0)


def test_one_euro_removes_jitter_of_a_still_hand():
    rng = np.random.default_rng(1)
    raw = np.array([0.1, 1.2, -0.3]) + rng.normal(scale=0.001, size=(len(T), 3))  # 1 mm tracking noise
    f = OneEuroFilter(min_cutoff=1.0, beta=8.0)
    out = np.array([f(x, t) for x, t in zip(raw, T)])
    assert out[90:].std(axis=0).max() < 0.3 * raw[90:].std(axis=0).min()


def test_one_euro_lags_less_when_moving_fast_than_a_plain_low_pass():
    """The point of One-Euro: same smoothing at rest, much less lag at 0.5 m/s than a fixed cutoff."""
    ramp = np.stack([0.5 * T, 0 * T, 0 * T], axis=1)
    fixed = OneEuroFilter(min_cutoff=1.0, beta=0.0)
    adaptive = OneEuroFilter(min_cutoff=1.0, beta=8.0)
    lag_fixed = ramp[-1, 0] - [fixed(x, t) for x, t in zip(ramp, T)][-1][0]
    lag_adaptive = ramp[-1, 0] - [adaptive(x, t) for x, t in zip(ramp, T)][-1][0]
    assert lag_adaptive < 0.2 * lag_fixed
    assert lag_adaptive < 0.02  # under 40 ms behind at 0.5 m/s


def test_one_euro_settles_on_a_step_and_ignores_repeated_timestamps():
    f = OneEuroFilter(min_cutoff=1.5, beta=8.0)
    f(np.zeros(3), 0.0)
    for t in T[1:]:
        y = f(np.array([0.05, 0, 0]), t)
    assert y[0] == pytest.approx(0.05, abs=1e-4)
    assert np.array_equal(f(np.array([9.0, 9, 9]), T[-1]), y)  # not after the last sample: no change


def test_one_euro_restarts_after_a_pause():
    f = OneEuroFilter(min_cutoff=1.0, beta=0.0, max_gap=0.5)
    f(np.zeros(3), 0.0)
    np.testing.assert_allclose(f(np.ones(3), 1.0), np.ones(3))  # 1 s gap: no blending with the stale value
    f.reset()
    assert f.value is None


def yaw_q(angle):
    return np.array([0.0, np.sin(angle / 2), 0.0, np.cos(angle / 2)])


def test_slerp_filter_smooths_orientation_jitter_and_settles():
    rng = np.random.default_rng(2)
    f = SlerpFilter(min_cutoff=1.0, beta=2.0)
    errors_in, errors_out = [], []
    for t in T:
        noisy = F.quat_mul(F.rotvec_to_quat(rng.normal(scale=0.01, size=3)), yaw_q(0.3))
        out = f(noisy, t)
        if t > 1:
            errors_in.append(F.quat_angle(noisy, yaw_q(0.3)))
            errors_out.append(F.quat_angle(out, yaw_q(0.3)))
    assert np.mean(errors_out) < 0.3 * np.mean(errors_in)


def test_slerp_filter_is_blind_to_the_quaternion_sign():
    f = SlerpFilter(min_cutoff=1.5, beta=1.0)
    q = yaw_q(0.5)
    for i, t in enumerate(T[:50]):
        out = f(q if i % 2 else -q, t)  # WebXR may send either sign of the same rotation
        assert F.quat_angle(out, q) < 1e-9


def test_slerp_filter_follows_a_turn_with_little_lag():
    f = SlerpFilter(min_cutoff=1.0, beta=2.0)
    for t in T:
        out = f(yaw_q(2.0 * t), t)  # turning at 2 rad/s
    assert F.quat_angle(out, yaw_q(2.0 * T[-1])) < 0.05  # 25 ms behind
    for t in T + T[-1] + 1 / RATE:
        out = f(yaw_q(2.0 * T[-1]), t)  # then still
    assert F.quat_angle(out, yaw_q(2.0 * T[-1])) < np.radians(0.1)


def test_pose_filter_rejects_jumps_and_counts_them():
    f = PoseFilter()
    q = np.array([0, 0, 0, 1.0])
    for t in T[:30]:
        p, _, jumped = f(np.array([0.0, 1.0, 0.0]), q, t)
        assert not jumped
    p, _, jumped = f(np.array([0.5, 1.0, 0.0]), q, T[30])  # tracking lost and found half a metre away
    assert jumped and f.discontinuities == 1
    np.testing.assert_allclose(p, [0.5, 1.0, 0.0])  # restarted at the new pose, not smeared toward it
    _, _, jumped = f(np.array([0.5, 1.0, 0.0]), yaw_q(1.2), T[31])  # a 70-degree flip in one frame
    assert jumped and f.discontinuities == 2
    _, _, jumped = f(np.array([0.51, 1.0, 0.0]), yaw_q(1.22), T[32])  # ordinary motion
    assert not jumped and f.discontinuities == 2


def test_clamps_limit_each_step_along_the_way():
    p = clamp_translation(np.zeros(3), np.array([0.3, 0.4, 0.0]), 0.1)
    np.testing.assert_allclose(p, [0.06, 0.08, 0.0])
    np.testing.assert_allclose(clamp_translation(np.zeros(3), np.array([0.01, 0, 0]), 0.1), [0.01, 0, 0])
    q = clamp_rotation(yaw_q(0.0), yaw_q(1.0), 0.25)
    assert F.quat_angle(q, yaw_q(0.25)) < 1e-9
    assert F.quat_angle(clamp_rotation(yaw_q(0.0), yaw_q(0.1), 0.25), yaw_q(0.1)) < 1e-9
