"""WebXR -> robot frame conversion: axes, headings, the camera-following map, and the quaternion helpers."""

import numpy as np
import pytest

from veragmil_suite.devices.vr import frames as F

RNG = np.random.default_rng(0)


def random_quat():
    q = RNG.normal(size=4)
    return F.quat_normalize(q)


def xr_yaw_quat(angle):
    """Headset turned by angle about the XR up axis (+y); positive turns the operator to the left."""
    return np.array([0.0, np.sin(angle / 2), 0.0, np.cos(angle / 2)])


def camera_xmat(yaw, pitch_down):
    """A MuJoCo camera (x right, y up, looking along -z) looking along heading yaw, tilted down by pitch_down."""
    look = np.array([np.cos(pitch_down) * np.cos(yaw), np.cos(pitch_down) * np.sin(yaw), -np.sin(pitch_down)])
    horizontal_right = np.array([np.sin(yaw), -np.cos(yaw), 0.0])
    up = np.cross(horizontal_right, look)
    return np.column_stack([horizontal_right, up, -look])


def test_xr_to_robot_is_a_rotation_with_the_documented_axes():
    R = F.XR_TO_ROBOT
    np.testing.assert_allclose(R @ R.T, np.eye(3), atol=1e-12)
    assert np.linalg.det(R) == pytest.approx(1.0)
    np.testing.assert_allclose(R @ [0, 0, -1], [1, 0, 0])  # operator forward -> robot +x
    np.testing.assert_allclose(R @ [1, 0, 0], [0, -1, 0])  # operator right -> robot -y
    np.testing.assert_allclose(R @ [0, 1, 0], [0, 0, 1])  # up -> up


@pytest.mark.parametrize("yaw", np.radians([0, 30, 90, 180, -120]))
@pytest.mark.parametrize("pitch", np.radians([15, 45, 89.9, 90]))
def test_hand_moves_the_way_the_camera_image_shows(yaw, pitch):
    """Hand right -> image right, hand forward -> image up, hand up -> world up, for any camera heading and tilt."""
    cam = camera_xmat(yaw, pitch)
    M = F.xr_to_robot(F.camera_heading(cam))
    to_cam = cam.T  # world vector -> camera frame (x right, y up on the image)
    right = to_cam @ (M @ [1, 0, 0])
    assert right[0] > 0.999 and abs(right[1]) < 1e-9
    forward = to_cam @ (M @ [0, 0, -1])
    assert forward[1] > 0.25 and abs(forward[0]) < 1e-9
    np.testing.assert_allclose(M @ [0, 1, 0], [0, 0, 1], atol=1e-12)


def test_camera_heading_of_robosuites_agentview_points_back_at_the_robot():
    # agentview sits in front of the table and looks back at the robot (-x), tilted down
    quat_wxyz = np.array([0.653, 0.271, 0.271, 0.653])
    xmat = F.quat_to_mat(np.r_[quat_wxyz[1:], quat_wxyz[0]])
    assert np.cos(F.camera_heading(xmat)) == pytest.approx(-1.0, abs=1e-3)
    M = F.xr_to_robot(F.camera_heading(xmat))
    np.testing.assert_allclose(M @ [1, 0, 0], [0, 1, 0], atol=0.03)  # hand right -> +y (the image's right)


def test_heading_is_defined_for_every_view_but_upside_down_ones():
    look_down_45 = np.array([np.cos(np.pi / 4), 0.0, -np.sin(np.pi / 4)])
    up = np.array([np.sin(np.pi / 4), 0.0, np.cos(np.pi / 4)])
    assert F.view_heading(up, -look_down_45) == pytest.approx(0.0)
    # looking up (a head, not a table camera): forward is still where the face points
    assert F.view_heading(np.array([-0.6, 0.0, 0.8]), -np.array([0.8, 0.0, 0.6])) == pytest.approx(0.0)
    # rolled onto its side: the viewing direction alone
    assert F.view_heading(np.array([0.0, 1.0, 0.0]), -np.array([1.0, 0.0, 0.0])) == pytest.approx(np.pi / 4)
    with pytest.raises(ValueError):
        F.view_heading(-up, -look_down_45)  # upside down at 45 degrees: the two parts cancel


@pytest.mark.parametrize("angle", np.radians([0, 45, 90, -135, 179]))
def test_xr_heading_follows_the_operator_turning(angle):
    assert np.cos(F.xr_heading(xr_yaw_quat(angle)) - angle) == pytest.approx(1.0)


def test_looking_down_keeps_the_heading():
    pitch_down = np.array([-np.sin(np.radians(35)), 0.0, 0.0, np.cos(np.radians(35))])  # about XR x: nose down 70 deg
    q = F.quat_mul(xr_yaw_quat(np.radians(40)), pitch_down)
    assert F.xr_heading(q) == pytest.approx(np.radians(40), abs=1e-9)


def test_recentered_map_sends_the_operators_forward_to_the_cameras_forward():
    operator_yaw = np.radians(70)
    M = F.xr_to_robot(camera_yaw=np.radians(-20), operator_yaw=F.xr_heading(xr_yaw_quat(operator_yaw)))
    forward_xr = F.quat_to_mat(xr_yaw_quat(operator_yaw)) @ [0, 0, -1]
    np.testing.assert_allclose(M @ forward_xr, [np.cos(np.radians(-20)), np.sin(np.radians(-20)), 0], atol=1e-12)


def test_rotation_about_xr_up_is_the_same_rotation_about_robot_up():
    angle = np.radians(30)
    R_xr = F.quat_to_mat(xr_yaw_quat(angle))
    for cam_yaw in np.radians([0, 77, -150]):
        R = F.map_rotation(F.xr_to_robot(cam_yaw), R_xr)
        np.testing.assert_allclose(R, F.yaw_matrix(angle), atol=1e-12)


def test_quaternion_helpers_agree_with_matrices():
    for _ in range(50):
        a, b = random_quat(), random_quat()
        np.testing.assert_allclose(F.quat_to_mat(F.quat_mul(a, b)), F.quat_to_mat(a) @ F.quat_to_mat(b), atol=1e-12)
        np.testing.assert_allclose(F.mat_to_quat(F.quat_to_mat(a)), a, atol=1e-12)
        np.testing.assert_allclose(F.quat_to_mat(F.quat_conj(a)), F.quat_to_mat(a).T, atol=1e-12)
        v = F.quat_to_rotvec(a)
        assert np.linalg.norm(v) <= np.pi + 1e-12
        np.testing.assert_allclose(F.rotvec_to_quat(v), a, atol=1e-12)
        assert F.quat_angle(a, b) == pytest.approx(
            np.linalg.norm(F.mat_to_rotvec(F.quat_to_mat(b) @ F.quat_to_mat(a).T))
        )
    np.testing.assert_allclose(F.quat_to_rotvec(np.array([0, 0, 0, 1.0])), 0)
    np.testing.assert_allclose(F.rotvec_to_mat([0, 0, np.pi / 2]), F.yaw_matrix(np.pi / 2), atol=1e-12)


def test_slerp_ends_midpoint_and_shorter_arc():
    a, b = random_quat(), random_quat()
    np.testing.assert_allclose(F.quat_slerp(a, b, 0.0), a, atol=1e-12)
    assert F.quat_angle(F.quat_slerp(a, b, 1.0), b) < 1e-6
    mid = F.quat_slerp(a, b, 0.5)
    assert F.quat_angle(a, mid) == pytest.approx(F.quat_angle(a, b) / 2, abs=1e-9)
    # -b is the same rotation: the interpolation must not take the long way round
    assert F.quat_angle(a, F.quat_slerp(a, -b, 0.5)) == pytest.approx(F.quat_angle(a, b) / 2, abs=1e-9)
