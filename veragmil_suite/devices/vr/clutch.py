"""The clutch: when the operator's hand drives the end-effector, and how a hand pose becomes an end-effector pose.

Holding squeeze engages. On engaging, the clutch captures two anchors, the controller's pose and the commanded
end-effector pose, and from then on commands

    p = p_ee_anchor + scale * M (p_ctrl - p_ctrl_anchor)
    R = Exp(rot_scale * Log(M (R_ctrl R_ctrl_anchor^T) M^T)) R_ee_anchor

with M the XR-to-robot map of ``vr_frames`` (the operator's forward onto the camera's). The commanded pose starts
exactly where it was, so engaging never jumps. Releasing holds the last commanded pose. The command moves toward
that pose no faster than ``max_linear_speed`` / ``max_angular_speed`` (the velocity clamp), so a hand flung
faster than the robot should go (or an absolute-mode re-engage far from the robot) is followed at a safe speed.

Modes:

- ``relative`` (default): anchors are captured at every engage, so the operator can ratchet (release, move the
  hand back, squeeze again) to cover a workspace larger than the arm's reach.
- ``absolute``: anchors are captured at the first engage (and again after a recenter, a scale or mode change, an
  episode reset, or a tracking jump) and kept; re-engaging brings the end-effector back to where the hand says,
  at the clamped speed. The room and the workspace stay registered.

A forced release (stale messages, tracking lost, headset asleep) latches: squeeze must be let go and pressed
again before the hand drives the robot again, so a half-remembered grip never moves it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from veragmil_suite.devices.vr.filters import clamp_rotation, clamp_translation
from veragmil_suite.devices.vr.frames import (
    map_rotation,
    mat_to_quat,
    quat_conj,
    quat_mul,
    quat_normalize,
    quat_to_mat,
    quat_to_rotvec,
    rotvec_to_mat,
    xr_heading,
    xr_to_robot,
)

MODES = ("relative", "absolute")


@dataclass
class Pose:
    """A position (metres) and a unit quaternion (x, y, z, w)."""

    p: np.ndarray
    q: np.ndarray

    def copy(self) -> Pose:
        return Pose(np.array(self.p, dtype=float), quat_normalize(self.q))


class Clutch:
    """Engagement, anchors and the hand-to-end-effector map (see the module docstring).

    Args:
        pos_scale (float): end-effector metres per hand metre
        rot_scale (float): end-effector radians per hand radian (1: the spoon turns as the hand does)
        precision_factor (float): pos_scale multiplier while precision mode is on
        mode (str): "relative" or "absolute"
        max_linear_speed (float): velocity clamp on the commanded position (m/s, simulated time)
        max_angular_speed (float): velocity clamp on the commanded orientation (rad/s)
        camera_yaw (float): forward heading of the streamed camera (``vr_frames.camera_heading``)
    """

    def __init__(
        self,
        pos_scale: float = 1.0,
        rot_scale: float = 1.0,
        precision_factor: float = 0.25,
        mode: str = "relative",
        max_linear_speed: float = 0.5,
        max_angular_speed: float = 3.0,
        camera_yaw: float = 0.0,
    ):
        if mode not in MODES:
            raise ValueError(f"mode must be one of {MODES}, got {mode!r}")
        if pos_scale <= 0 or rot_scale < 0 or not 0 < precision_factor <= 1:
            raise ValueError("pos_scale must be positive, rot_scale non-negative, precision_factor in (0, 1]")
        self.pos_scale = float(pos_scale)
        self.rot_scale = float(rot_scale)
        self.precision_factor = float(precision_factor)
        self.mode = mode
        self.max_linear_speed = float(max_linear_speed)
        self.max_angular_speed = float(max_angular_speed)
        self.camera_yaw = float(camera_yaw)
        self.operator_yaw = 0.0  # the operator faces the XR space's -z until the first recenter
        self.map = xr_to_robot(self.camera_yaw, self.operator_yaw)
        self.precision = False
        self.reset()

    def reset(self) -> None:
        """New episode: forget anchors and the held pose (the next update holds the robot where it is)."""
        self.engaged = False
        self.latched = True  # a grip held through a reset must be released first
        self.target: Pose | None = None
        self._ctrl_anchor: Pose | None = None
        self._ee_anchor: Pose | None = None
        self._last_ctrl: Pose | None = None
        self._seen_discontinuities: int | None = None
        self.engage_count = 0
        self.forced_releases = 0

    @property
    def scale(self) -> float:
        """Translation scale in effect (precision mode included)."""
        return self.pos_scale * (self.precision_factor if self.precision else 1.0)

    def _reanchor(self) -> None:
        """Anchor at the current hand and commanded poses, so a change of map or scale does not move the robot."""
        if self.engaged and self._last_ctrl is not None and self.target is not None:
            self._ctrl_anchor, self._ee_anchor = self._last_ctrl.copy(), self.target.copy()
        else:
            self._ctrl_anchor = self._ee_anchor = None

    def set_pos_scale(self, scale: float) -> None:
        if scale <= 0:
            raise ValueError("scale must be positive")
        self.pos_scale = float(scale)
        self._reanchor()

    def toggle_precision(self) -> bool:
        self.precision = not self.precision
        self._reanchor()
        return self.precision

    def set_mode(self, mode: str) -> None:
        if mode not in MODES:
            raise ValueError(f"mode must be one of {MODES}, got {mode!r}")
        self.mode = mode
        self._reanchor()

    def toggle_mode(self) -> str:
        self.set_mode("absolute" if self.mode == "relative" else "relative")
        return self.mode

    def set_camera_yaw(self, camera_yaw: float) -> None:
        self.camera_yaw = float(camera_yaw)
        self.map = xr_to_robot(self.camera_yaw, self.operator_yaw)
        self._reanchor()

    def recenter(self, head_q_xr: np.ndarray) -> None:
        """Align the operator's current facing (headset orientation, XR frame) with the camera's forward."""
        self.operator_yaw = xr_heading(head_q_xr)
        self.map = xr_to_robot(self.camera_yaw, self.operator_yaw)
        self._reanchor()

    def mapped_pose(self, ctrl: Pose) -> Pose:
        """The end-effector pose the hand pose ctrl asks for under the current anchors (before the clamp)."""
        if self._ctrl_anchor is None or self._ee_anchor is None:
            raise RuntimeError("no anchors: the clutch is not engaged")
        p = self._ee_anchor.p + self.scale * (self.map @ (ctrl.p - self._ctrl_anchor.p))
        r_delta = map_rotation(self.map, quat_to_mat(quat_mul(ctrl.q, quat_conj(self._ctrl_anchor.q))))
        if self.rot_scale != 1.0:
            r_delta = rotvec_to_mat(self.rot_scale * quat_to_rotvec(mat_to_quat(r_delta)))
        return Pose(p, mat_to_quat(r_delta @ quat_to_mat(self._ee_anchor.q)))

    def update(
        self,
        squeeze: bool,
        available: bool,
        ctrl: Pose | None,
        ee: Pose,
        dt: float,
        discontinuities: int = 0,
    ) -> Pose:
        """Advance one control step and return the commanded end-effector pose (robot world frame).

        Args:
            squeeze (bool): the operator holds the engage button
            available (bool): the hand pose is fresh and tracked (else a forced release)
            ctrl (Pose or None): filtered controller pose in the XR frame
            ee (Pose): the end-effector's achieved pose (held when nothing was commanded yet)
            dt (float): control period (s) for the velocity clamp
            discontinuities (int): the pose filter's jump counter; a change re-anchors
        """
        if self.target is None:
            self.target = ee.copy()
        if ctrl is not None:
            self._last_ctrl = ctrl.copy()
        if not squeeze:
            self.latched = False
        if self.engaged and (not available or ctrl is None):
            self.engaged = False
            self.latched = True
            self.forced_releases += 1
        elif self.engaged and not squeeze:
            self.engaged = False
        elif not self.engaged and squeeze and available and ctrl is not None and not self.latched:
            self.engaged = True
            self.engage_count += 1
            if self.mode == "relative" or self._ctrl_anchor is None:
                self._reanchor()
        if self.engaged:
            if self._seen_discontinuities is not None and discontinuities != self._seen_discontinuities:
                self._reanchor()  # a tracking jump: follow from here, do not move by it
            want = self.mapped_pose(ctrl)
            p = clamp_translation(self.target.p, want.p, self.max_linear_speed * dt)
            q = clamp_rotation(self.target.q, want.q, self.max_angular_speed * dt)
            self.target = Pose(p, q)
        self._seen_discontinuities = discontinuities
        return self.target.copy()
