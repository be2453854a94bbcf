"""Frames and rotations for VR teleoperation: the WebXR frame, the robot's world frame, and the map between them.

WebXR reference spaces are right-handed with **x to the operator's right, y up and z toward the operator** (the
operator looks along -z when the session starts). robosuite's world frame is right-handed with **z up**; its x
axis points from the robot's base over the table. The fixed change of axes ``XR_TO_ROBOT`` maps an operator
standing behind the robot and looking along its +x axis:

    operator forward (-z_xr) -> +x_robot,   operator right (+x_xr) -> -y_robot,   up (+y_xr) -> +z_robot.

The operator does not look at the robot, though, but at a camera's image streamed into the headset. The
teleoperation map therefore also turns about the vertical so that the operator's forward becomes the camera's
*forward* (the horizontal direction in which a point moves up the image, for a camera looking down):

    M = Rz(camera_heading - operator_heading) @ XR_TO_ROBOT

With it, a hand moving forward moves the end-effector up the image and a hand moving right moves it to the
image's right, whatever way the camera looks down. Position deltas map as ``M @ dp``; rotation deltas (rotations
expressed in the fixed XR frame) map by conjugation, ``M @ R @ M.T``.

Quaternions are (x, y, z, w), as in WebXR and robosuite.
"""

from __future__ import annotations

import numpy as np

XR_TO_ROBOT = np.array(
    [
        [0.0, 0.0, -1.0],  # robot x = -xr z (operator forward)
        [-1.0, 0.0, 0.0],  # robot y = -xr x (operator left)
        [0.0, 1.0, 0.0],  # robot z = +xr y (up)
    ]
)

_EPS = 1e-9


def quat_normalize(q: np.ndarray) -> np.ndarray:
    """Unit quaternion with w >= 0 (one representative of the two that give the same rotation)."""
    q = np.asarray(q, dtype=float)
    q = q / np.linalg.norm(q)
    return -q if q[3] < 0 else q


def quat_mul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton product a * b (apply b, then a)."""
    ax, ay, az, aw = a
    bx, by, bz, bw = b
    return np.array(
        [
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
            aw * bw - ax * bx - ay * by - az * bz,
        ]
    )


def quat_conj(q: np.ndarray) -> np.ndarray:
    """Inverse of a unit quaternion."""
    return np.array([-q[0], -q[1], -q[2], q[3]])


def quat_to_mat(q: np.ndarray) -> np.ndarray:
    """Rotation matrix of a unit quaternion."""
    x, y, z, w = q
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )


def mat_to_quat(m: np.ndarray) -> np.ndarray:
    """Unit quaternion (w >= 0) of a rotation matrix; branches on the largest diagonal term for accuracy."""
    m = np.asarray(m, dtype=float)
    tr = m[0, 0] + m[1, 1] + m[2, 2]
    if tr > 0:
        s = 2.0 * np.sqrt(tr + 1.0)
        q = [(m[2, 1] - m[1, 2]) / s, (m[0, 2] - m[2, 0]) / s, (m[1, 0] - m[0, 1]) / s, 0.25 * s]
    elif m[0, 0] > m[1, 1] and m[0, 0] > m[2, 2]:
        s = 2.0 * np.sqrt(1.0 + m[0, 0] - m[1, 1] - m[2, 2])
        q = [0.25 * s, (m[0, 1] + m[1, 0]) / s, (m[0, 2] + m[2, 0]) / s, (m[2, 1] - m[1, 2]) / s]
    elif m[1, 1] > m[2, 2]:
        s = 2.0 * np.sqrt(1.0 + m[1, 1] - m[0, 0] - m[2, 2])
        q = [(m[0, 1] + m[1, 0]) / s, 0.25 * s, (m[1, 2] + m[2, 1]) / s, (m[0, 2] - m[2, 0]) / s]
    else:
        s = 2.0 * np.sqrt(1.0 + m[2, 2] - m[0, 0] - m[1, 1])
        q = [(m[0, 2] + m[2, 0]) / s, (m[1, 2] + m[2, 1]) / s, 0.25 * s, (m[1, 0] - m[0, 1]) / s]
    return quat_normalize(np.array(q))


def quat_to_rotvec(q: np.ndarray) -> np.ndarray:
    """Axis times angle (radians, in [0, pi]) of a unit quaternion."""
    q = quat_normalize(q)
    s = np.linalg.norm(q[:3])
    if s < _EPS:
        return 2.0 * q[:3]  # first order: the axis is undefined, the rotation tiny
    angle = 2.0 * np.arctan2(s, q[3])
    return q[:3] / s * angle


def rotvec_to_quat(v: np.ndarray) -> np.ndarray:
    """Unit quaternion of an axis-angle vector."""
    v = np.asarray(v, dtype=float)
    angle = np.linalg.norm(v)
    if angle < _EPS:
        return quat_normalize(np.array([0.5 * v[0], 0.5 * v[1], 0.5 * v[2], 1.0]))
    half = 0.5 * angle
    return np.concatenate([v / angle * np.sin(half), [np.cos(half)]])


def mat_to_rotvec(m: np.ndarray) -> np.ndarray:
    """Axis times angle of a rotation matrix."""
    return quat_to_rotvec(mat_to_quat(m))


def rotvec_to_mat(v: np.ndarray) -> np.ndarray:
    """Rotation matrix of an axis-angle vector."""
    return quat_to_mat(rotvec_to_quat(v))


def quat_angle(a: np.ndarray, b: np.ndarray) -> float:
    """Angle (radians) of the rotation taking a to b."""
    d = abs(float(np.dot(a, b)) / (np.linalg.norm(a) * np.linalg.norm(b)))
    return 2.0 * float(np.arccos(min(1.0, d)))


def quat_slerp(a: np.ndarray, b: np.ndarray, t: float) -> np.ndarray:
    """Spherical interpolation from a (t=0) to b (t=1) along the shorter arc."""
    a = quat_normalize(a)
    b = quat_normalize(b)
    d = float(np.dot(a, b))
    if d < 0.0:
        b, d = -b, -d
    if d > 0.9995:  # nearly equal: linear interpolation is exact to float precision and avoids 0/0
        return quat_normalize(a + t * (b - a))
    theta = np.arccos(d)
    s = np.sin(theta)
    return quat_normalize((np.sin((1.0 - t) * theta) * a + np.sin(t * theta) * b) / s)


def yaw_matrix(angle: float) -> np.ndarray:
    """Rotation about the robot's vertical (z) axis."""
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def view_heading(up: np.ndarray, back: np.ndarray) -> float:
    """Yaw (robot frame, radians) of a viewer's forward direction, from its up and backward axes.

    Forward is the horizontal part of the viewing direction (-back) plus that of the up axis when looking down
    (the top of a tilted-down view leans forward) or minus it when looking up. Looking level only the viewing
    direction counts, looking straight down only the up axis (the top of the image), so the heading is defined
    for every view but upside-down ones.
    """
    look = -np.asarray(back, dtype=float)
    up = np.asarray(up, dtype=float)
    f = look[:2] + (up[:2] if look[2] <= 0 else -up[:2])
    if np.linalg.norm(f) < 1e-6:
        raise ValueError("the view is upside down: its forward direction is undefined")
    return float(np.arctan2(f[1], f[0]))


def camera_heading(cam_xmat: np.ndarray) -> float:
    """Forward yaw of a MuJoCo camera (its frame: x right, y up, looking along -z): the horizontal direction in
    which a point moves up its image, for the cameras that look down on a table."""
    r = np.asarray(cam_xmat, dtype=float).reshape(3, 3)
    return view_heading(r[:, 1], r[:, 2])


def xr_heading(q_xr: np.ndarray) -> float:
    """Forward yaw, in the robot frame under ``XR_TO_ROBOT``, of a headset at orientation q_xr."""
    r = XR_TO_ROBOT @ quat_to_mat(quat_normalize(q_xr))
    return view_heading(r[:, 1], r[:, 2])


def xr_to_robot(camera_yaw: float, operator_yaw: float = 0.0) -> np.ndarray:
    """The teleoperation map M: the operator's forward (heading ``operator_yaw``) onto the camera's forward."""
    return yaw_matrix(camera_yaw - operator_yaw) @ XR_TO_ROBOT


def map_rotation(m: np.ndarray, r_xr: np.ndarray) -> np.ndarray:
    """A rotation expressed in the XR frame, expressed in the robot frame through the map m."""
    return m @ r_xr @ m.T
