"""Inverse kinematics for start poses: damped least squares on a copy of the model's data."""

from __future__ import annotations

import mujoco
import numpy as np
import robosuite.utils.transform_utils as T

IK_MAX_ITERATIONS = 500
IK_DAMPING = 1e-3
IK_POS_TOLERANCE_M = 1e-4
IK_ROT_TOLERANCE_RAD = 1e-3


def align_heading(target_rot: np.ndarray, current_rot: np.ndarray) -> np.ndarray:
    """``target_rot`` turned about the world's vertical to the heading closest to ``current_rot``'s.

    A five-joint arm controls a pose up to its heading: the turn that brings the target nearest (in the Frobenius
    norm) is Rz(psi) with tan psi = (B10 - B01) / (B00 + B11), B = current target^T.
    """
    b = np.asarray(current_rot) @ np.asarray(target_rot).T
    psi = np.arctan2(b[1, 0] - b[0, 1], b[0, 0] + b[1, 1])
    c, s = np.cos(psi), np.sin(psi)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]) @ target_rot


def turn_to(target_rot: np.ndarray, current_rot: np.ndarray) -> np.ndarray:
    """Axis times angle (world frame, rad) that turns ``current_rot`` into ``target_rot``: the form of the OSC's
    rotation actions. The angle is at most pi: robosuite's mat2quat keeps the quaternion's w non-negative."""
    return T.quat2axisangle(T.mat2quat(np.asarray(target_rot) @ np.asarray(current_rot).T))


def solve_pose_ik(
    model: mujoco.MjModel,
    joint_names: list[str],
    site_name: str,
    target_pos: np.ndarray,
    target_rot: np.ndarray,
    q_init: np.ndarray,
    free_heading: bool = False,
    other_qpos: dict[str, float] | None = None,
) -> np.ndarray:
    """Joint positions that put ``site_name`` at ``target_pos`` with orientation ``target_rot`` (3x3).

    Solved once per robot and kept, so its speed does not matter; the caller's simulation is not touched.

    Args:
        free_heading: match the orientation up to a turn about the world's vertical (see align_heading): a
            five-joint arm cannot match all six pose coordinates
        other_qpos: positions of joints not solved for, by name (the rest stay at the model's qpos0)

    Raises:
        RuntimeError: the pose is out of the robot's reach.
    """
    data = mujoco.MjData(model)
    for name, value in (other_qpos or {}).items():
        data.qpos[model.joint(name).qposadr[0]] = value
    # the rows of the error driven to zero: all six, or all but the rotation about the vertical
    rows = np.array([True] * 5 + [not free_heading])
    qadr = np.array([model.joint(n).qposadr[0] for n in joint_names])
    dadr = np.array([model.joint(n).dofadr[0] for n in joint_names])
    lo, hi = model.jnt_range[[model.joint(n).id for n in joint_names]].T
    limited = model.jnt_limited[[model.joint(n).id for n in joint_names]].astype(bool)
    site = model.site(site_name).id
    q = np.array(q_init, dtype=float)
    jacp = np.zeros((3, model.nv))
    jacr = np.zeros((3, model.nv))
    target_quat = np.zeros(4)
    target_rot = np.asarray(target_rot, dtype=float)
    for _ in range(IK_MAX_ITERATIONS):
        data.qpos[qadr] = q
        mujoco.mj_kinematics(model, data)
        mujoco.mj_comPos(model, data)
        err_pos = target_pos - data.site_xpos[site]
        site_rot = data.site_xmat[site].reshape(3, 3)
        mujoco.mju_mat2Quat(target_quat, (align_heading(target_rot, site_rot) if free_heading else target_rot).ravel())
        site_quat = np.zeros(4)
        mujoco.mju_mat2Quat(site_quat, data.site_xmat[site])
        conj = np.zeros(4)
        mujoco.mju_negQuat(conj, site_quat)
        diff = np.zeros(4)
        mujoco.mju_mulQuat(diff, target_quat, conj)
        err_rot = np.zeros(3)
        mujoco.mju_quat2Vel(err_rot, diff, 1.0)
        if free_heading:
            err_rot[2] = 0.0
        if np.linalg.norm(err_pos) < IK_POS_TOLERANCE_M and np.linalg.norm(err_rot) < IK_ROT_TOLERANCE_RAD:
            return q
        mujoco.mj_jacSite(model, data, jacp, jacr, site)
        jac = np.vstack([jacp[:, dadr], jacr[:, dadr]])[rows]
        err = np.concatenate([err_pos, err_rot])[rows]
        dq = jac.T @ np.linalg.solve(jac @ jac.T + IK_DAMPING * np.eye(len(err)), err)
        q = q + dq
        q[limited] = np.clip(q[limited], lo[limited], hi[limited])
    raise RuntimeError(
        f"no joint configuration reaches {np.round(target_pos, 3)} with the requested orientation "
        f"(residual {np.linalg.norm(err_pos):.4f} m, {np.linalg.norm(err_rot):.4f} rad)"
    )


def quat_mul_wxyz(q: np.ndarray, p: np.ndarray) -> np.ndarray:
    """q * p for one (w, x, y, z) quaternion q and an (n, 4) array p."""
    w0, x0, y0, z0 = q
    w1, x1, y1, z1 = p.T
    return np.stack(
        [
            w0 * w1 - x0 * x1 - y0 * y1 - z0 * z1,
            w0 * x1 + x0 * w1 + y0 * z1 - z0 * y1,
            w0 * y1 - x0 * z1 + y0 * w1 + z0 * x1,
            w0 * z1 + x0 * y1 - y0 * x1 + z0 * w1,
        ],
        axis=1,
    )
