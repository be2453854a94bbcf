"""The clutch and the hand-to-end-effector map: engaging never jumps, release holds, modes, scaling, clamps."""

import numpy as np
import pytest

from veragmil_suite.devices.vr import frames as F
from veragmil_suite.devices.vr.clutch import Clutch, Pose

DT = 0.05  # 20 Hz control
EE = Pose(np.array([0.1, 0.0, 1.0]), F.mat_to_quat(np.diag([1.0, -1.0, -1.0])))  # a spoon pointing down
HAND = np.array([0.2, 1.1, -0.4])
IDENTITY = np.array([0.0, 0.0, 0.0, 1.0])


def hand(dp=(0, 0, 0), q=IDENTITY):
    return Pose(HAND + np.asarray(dp, float), np.asarray(q, float))


def yaw_xr(angle):
    return np.array([0.0, np.sin(angle / 2), 0.0, np.cos(angle / 2)])


def run(clutch, ctrl, steps=1, squeeze=True, available=True, disc=0):
    for _ in range(steps):
        target = clutch.update(squeeze, available, ctrl, EE, DT, disc)
    return target


def engaged_clutch(**kwargs):
    c = Clutch(**kwargs)
    run(c, hand(), squeeze=False)  # a release first: the clutch starts latched
    run(c, hand())
    assert c.engaged
    return c


def test_released_clutch_holds_the_robot_wherever_the_hand_goes():
    c = Clutch()
    first = run(c, hand(), squeeze=False)
    np.testing.assert_allclose(first.p, EE.p)
    moved = run(c, hand((0.3, 0.2, 0.1), yaw_xr(1.0)), steps=10, squeeze=False)
    np.testing.assert_allclose(moved.p, EE.p)
    assert F.quat_angle(moved.q, EE.q) < 1e-12


def test_engaging_never_jumps():
    c = Clutch()
    run(c, hand((0.3, -0.2, 0.1), yaw_xr(2.0)), squeeze=False)
    target = run(c, hand((0.3, -0.2, 0.1), yaw_xr(2.0)))  # squeeze with the hand far from any "home"
    assert c.engaged
    np.testing.assert_allclose(target.p, EE.p, atol=1e-12)
    assert F.quat_angle(target.q, EE.q) < 1e-9


@pytest.mark.parametrize("camera_yaw", np.radians([0, 90, 180, -45]))
def test_engaged_hand_motion_maps_through_the_camera_map(camera_yaw):
    c = engaged_clutch(camera_yaw=camera_yaw)
    dp = np.array([0.05, 0.02, -0.04])
    target = run(c, hand(dp), steps=20)
    np.testing.assert_allclose(target.p - EE.p, F.xr_to_robot(camera_yaw) @ dp, atol=1e-12)


def test_release_holds_and_relative_mode_ratchets():
    c = engaged_clutch()
    run(c, hand((0.1, 0, 0)), steps=10)  # right 10 cm
    held = run(c, hand((0.0, 0, 0)), steps=10, squeeze=False)  # release, bring the hand back
    np.testing.assert_allclose(held.p - EE.p, F.XR_TO_ROBOT @ [0.1, 0, 0], atol=1e-12)
    again = run(c, hand((0.0, 0, 0)))  # squeeze again: no jump back
    np.testing.assert_allclose(again.p, held.p, atol=1e-12)
    final = run(c, hand((0.1, 0, 0)), steps=10)  # a second stroke adds up
    np.testing.assert_allclose(final.p - EE.p, F.XR_TO_ROBOT @ [0.2, 0, 0], atol=1e-12)


def test_absolute_mode_keeps_the_registration_and_returns_at_the_clamped_speed():
    c = engaged_clutch(mode="absolute", max_linear_speed=0.5)
    run(c, hand((0.1, 0, 0)), steps=10)
    run(c, hand((0.0, 0, 0)), steps=3, squeeze=False)  # the hand goes back while released; the robot holds
    path = [run(c, hand((0.0, 0, 0))).p for _ in range(10)]  # re-engage: back to where the hand says
    steps = np.linalg.norm(np.diff(np.vstack([EE.p + F.XR_TO_ROBOT @ [0.1, 0, 0]] + path), axis=0), axis=1)
    assert steps.max() <= 0.5 * DT + 1e-12
    np.testing.assert_allclose(path[-1], EE.p, atol=1e-12)


def test_velocity_clamp_limits_translation_and_rotation_per_step():
    c = engaged_clutch(max_linear_speed=0.4, max_angular_speed=2.0)
    before = run(c, hand())
    after = run(c, hand((0.0, 0.07, 0.0), yaw_xr(0.9)))  # within the jump threshold, faster than allowed
    assert np.linalg.norm(after.p - before.p) == pytest.approx(0.4 * DT)
    assert F.quat_angle(after.q, before.q) == pytest.approx(2.0 * DT)
    final = run(c, hand((0.0, 0.07, 0.0), yaw_xr(0.9)), steps=20)
    np.testing.assert_allclose(final.p - EE.p, [0, 0, 0.07], atol=1e-12)


def test_rotation_is_one_to_one_and_scalable():
    for rot_scale, expected in [(1.0, 30.0), (0.5, 15.0)]:
        c = engaged_clutch(rot_scale=rot_scale)
        target = run(c, hand(q=yaw_xr(np.radians(30))), steps=5)
        delta = F.quat_to_mat(target.q) @ F.quat_to_mat(EE.q).T  # applied in the world frame
        np.testing.assert_allclose(delta, F.yaw_matrix(np.radians(expected)), atol=1e-9)
        np.testing.assert_allclose(target.p, EE.p, atol=1e-12)  # turning the hand in place does not move the spoon


def test_scale_and_precision_change_only_what_follows():
    c = engaged_clutch(pos_scale=2.0, precision_factor=0.25)
    run(c, hand((0.0, 0.01, 0)), steps=5)
    assert c.scale == 2.0
    mid = run(c, hand((0.0, 0.01, 0)))
    assert c.toggle_precision() is True and c.scale == 0.5
    np.testing.assert_allclose(run(c, hand((0.0, 0.01, 0))).p, mid.p, atol=1e-12)  # no jump
    end = run(c, hand((0.0, 0.05, 0)), steps=5)
    np.testing.assert_allclose(end.p - mid.p, [0, 0, 0.5 * 0.04], atol=1e-12)
    c.set_pos_scale(1.0)
    np.testing.assert_allclose(run(c, hand((0.0, 0.05, 0))).p, end.p, atol=1e-12)
    with pytest.raises(ValueError):
        c.set_pos_scale(0.0)


def test_forced_release_latches_until_squeeze_is_let_go():
    c = engaged_clutch()
    held = run(c, hand((0.02, 0, 0)), steps=3)
    lost = run(c, hand((0.05, 0, 0)), steps=3, available=False)  # stale messages, squeeze still "held"
    assert not c.engaged and c.latched and c.forced_releases == 1
    np.testing.assert_allclose(lost.p, held.p)
    run(c, hand((0.08, 0, 0)), steps=5)  # messages back, squeeze still held: stays released
    assert not c.engaged
    run(c, hand((0.08, 0, 0)), squeeze=False)
    run(c, hand((0.08, 0, 0)))
    assert c.engaged and c.engage_count == 2
    np.testing.assert_allclose(run(c, hand((0.08, 0, 0))).p, held.p, atol=1e-12)


def test_lost_tracking_releases_too():
    c = engaged_clutch()
    run(c, None)
    assert not c.engaged and c.latched


def test_tracking_jump_reanchors_instead_of_moving():
    c = engaged_clutch()
    before = run(c, hand((0.01, 0, 0)), steps=3)
    after = run(c, hand((0.6, 0, 0)), disc=1)  # the filter reported a discontinuity with this sample
    np.testing.assert_allclose(after.p, before.p, atol=1e-12)
    moved = run(c, hand((0.62, 0, 0)), steps=3, disc=1)
    np.testing.assert_allclose(moved.p - before.p, F.XR_TO_ROBOT @ [0.02, 0, 0], atol=1e-12)


def test_recenter_aligns_the_operators_new_forward_with_the_camera():
    c = engaged_clutch(camera_yaw=np.radians(90))
    turned = yaw_xr(np.radians(60))  # the operator turned 60 degrees to the left
    c.recenter(turned)
    start = run(c, hand(q=IDENTITY))
    forward = F.quat_to_mat(turned) @ [0, 0, -0.05]  # a step along the operator's new forward
    end = run(c, hand(forward), steps=5)
    np.testing.assert_allclose(end.p - start.p, [0, 0.05, 0], atol=1e-12)  # camera forward is world +y


def test_mode_toggle_and_validation():
    c = Clutch()
    assert c.toggle_mode() == "absolute" and c.toggle_mode() == "relative"
    with pytest.raises(ValueError):
        Clutch(mode="velocity")
    with pytest.raises(RuntimeError):
        c.mapped_pose(hand())
