"""The spoon's start: its pre-scoop and post-scoop orientations, and the joints that put it above the bowl."""

from __future__ import annotations

import numpy as np
import robosuite.utils.transform_utils as T

from veragmil_suite.models.humanoid import (
    SPOON_ARM,
)
from veragmil_suite.utils.kinematics import solve_pose_ik, turn_to

# Spoon orientations in the world, as rotation matrices of the flange (eef) frame. Pre-scoop: the tool points
# straight down, so the bent spoon's tip points down at 45 degrees along +x (away from the robot), its bowl
# facing up and forward. Post-scoop: the same turned 45 degrees about y, so the spoon's bowl is level.
PRE_SCOOP_EEF_ROT = np.array([[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0]])
_LEVEL_TURN = T.quat2mat(T.axisangle2quat(np.array([0.0, -np.pi / 4, 0.0])))
POST_SCOOP_EEF_ROT = _LEVEL_TURN @ PRE_SCOOP_EEF_ROT

_PRE_SCOOP_CACHE: dict[tuple, np.ndarray] = {}


def rotation_to_post_scoop(eef_rot: np.ndarray) -> np.ndarray:
    """The turn (axis times angle, world frame, rad, at most pi) from a spoon at orientation ``eef_rot`` (the eef
    site's in the world, 3 x 3 or flat) to the post-scoop orientation, so a policy's turn toward the pose is the same
    function of it wherever the spoon stands."""
    return turn_to(POST_SCOOP_EEF_ROT, np.asarray(eef_rot).reshape(3, 3))


class StartPoseMixin:
    """ScoopGranular's start pose, solved once per robot, bowl and table by inverse kinematics (cached)."""

    def _pre_scoop_qpos(self) -> np.ndarray:
        """
        Joint configuration (of all the robot's joints) that puts the spoon at its pre-scoop pose above the nominal
        bowl (cached). A humanoid solves for its spoon arm alone, with the heading free (its arm has five joints),
        and its other parts take the pose their controllers hold.
        """
        robot = self.robots[0]
        model = robot.robot_model
        # everything the pose depends on: the arm, what it holds, and where the bowl's rim is
        key = (
            type(model).__name__,
            type(robot.gripper[SPOON_ARM]).__name__,
            repr(self.bowl_shape),
            tuple(self.pre_scoop_offset),
            tuple(self.table_full_size),
            tuple(np.round(self.table_offset, 9)),
            tuple(np.round(self.bowl_nominal_xy, 9)),
        )
        if key not in _PRE_SCOOP_CACHE:
            target_pos = self._nominal_rim_center() + self.pre_scoop_offset
            site = robot.gripper[SPOON_ARM].important_sites["grip_site"]
            if self.humanoid is None:
                _PRE_SCOOP_CACHE[key] = solve_pose_ik(
                    self.sim.model._model,
                    joint_names=model.joints,
                    site_name=site,
                    target_pos=target_pos,
                    target_rot=PRE_SCOOP_EEF_ROT,
                    q_init=np.array(model.init_qpos, dtype=float),
                )
            else:
                held = self._held_joint_qpos()
                arm = self._spoon_arm_joints()
                q_arm = solve_pose_ik(
                    self.sim.model._model,
                    joint_names=arm,
                    site_name=site,
                    target_pos=target_pos,
                    target_rot=PRE_SCOOP_EEF_ROT,
                    q_init=np.array(self.humanoid.arm_ik_start, dtype=float),
                    free_heading=True,
                    other_qpos=held,
                )
                held.update(zip(arm, q_arm))
                _PRE_SCOOP_CACHE[key] = np.array([held[name] for name in model.joints])
        return _PRE_SCOOP_CACHE[key].copy()

    def _spoon_arm_joints(self) -> list[str]:
        """The spoon arm's joint names (robosuite lists the right arm's first and splits the arm joints evenly)."""
        robot = self.robots[0]
        joints = robot.robot_model.arm_joints
        return list(joints[: len(joints) // len(robot.arms)])

    def _held_joint_qpos(self) -> dict[str, float]:
        """A humanoid's held joint positions by joint name: the other arm's and the torso's (the layout's)."""
        model = self.robots[0].robot_model
        spoon_arm = self._spoon_arm_joints()
        joints = {"left": list(model.arm_joints[len(spoon_arm) :]), "torso": list(model.torso_joints)}
        return {
            name: float(value)
            for part, values in self.humanoid.held_qpos.items()
            for name, value in zip(joints[part], values, strict=True)
        }

    def _nominal_rim_center(self) -> np.ndarray:
        return np.array(
            [self.bowl_nominal_xy[0], self.bowl_nominal_xy[1], self.table_offset[2] + self.bowl_shape.height]
        )
