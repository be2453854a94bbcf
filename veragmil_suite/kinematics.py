"""Inverse kinematics for start poses: damped least squares on a copy of the model's data."""

from __future__ import annotations

import mujoco
import numpy as np

IK_MAX_ITERATIONS = 500
IK_DAMPING = 1e-3
IK_POS_TOLERANCE_M = 1e-4
IK_ROT_TOLERANCE_RAD = 1e-3


def solve_pose_ik(
    model: mujoco.MjModel,
    joint_names: list[str],
    site_name: str,
    target_pos: np.ndarray,
    target_rot: np.ndarray,
    q_init: np.ndarray,
) -> np.ndarray:
    """Joint positions that put ``site_name`` at ``target_pos`` with orientation ``target_rot`` (3x3).

    Solved once per robot and kept, so its speed does not matter; the caller's simulation is not touched.

    Raises:
        RuntimeError: the pose is out of the robot's reach.
    """
    data = mujoco.MjData(model)
    qadr = np.array([model.joint(n).qposadr[0] for n in joint_names])
    dadr = np.array([model.joint(n).dofadr[0] for n in joint_names])
    lo, hi = model.jnt_range[[model.joint(n).id for n in joint_names]].T
    limited = model.jnt_limited[[model.joint(n).id for n in joint_names]].astype(bool)
    site = model.site(site_name).id
    q = np.array(q_init, dtype=float)
    jacp = np.zeros((3, model.nv))
    jacr = np.zeros((3, model.nv))
    target_quat = np.zeros(4)
    mujoco.mju_mat2Quat(target_quat, np.asarray(target_rot, dtype=float).ravel())
    for _ in range(IK_MAX_ITERATIONS):
        data.qpos[qadr] = q
        mujoco.mj_kinematics(model, data)
        mujoco.mj_comPos(model, data)
        err_pos = target_pos - data.site_xpos[site]
        site_quat = np.zeros(4)
        mujoco.mju_mat2Quat(site_quat, data.site_xmat[site])
        conj = np.zeros(4)
        mujoco.mju_negQuat(conj, site_quat)
        diff = np.zeros(4)
        mujoco.mju_mulQuat(diff, target_quat, conj)
        err_rot = np.zeros(3)
        mujoco.mju_quat2Vel(err_rot, diff, 1.0)
        if np.linalg.norm(err_pos) < IK_POS_TOLERANCE_M and np.linalg.norm(err_rot) < IK_ROT_TOLERANCE_RAD:
            return q
        mujoco.mj_jacSite(model, data, jacp, jacr, site)
        jac = np.vstack([jacp[:, dadr], jacr[:, dadr]])
        err = np.concatenate([err_pos, err_rot])
        dq = jac.T @ np.linalg.solve(jac @ jac.T + IK_DAMPING * np.eye(6), err)
        q = q + dq
        q[limited] = np.clip(q[limited], lo[limited], hi[limited])
    raise RuntimeError(
        f"no joint configuration reaches {np.round(target_pos, 3)} with the requested orientation "
        f"(residual {np.linalg.norm(err_pos):.4f} m, {np.linalg.norm(err_rot):.4f} rad)"
    )
