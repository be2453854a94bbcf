"""The arm's mass matrix without the whole model's: robosuite's controllers, made cheap beside a pile of grains.

robosuite's part controllers build MuJoCo's dense nv x nv mass matrix at every physics substep, only to read the
arm's 7 x 7 block. With 200 free grains nv is about 1200, and that alone took 1.1 ms per substep (13 ms of a
20 Hz env step). Each grain's block is independent of the arm's, so the arm's block is read straight from MuJoCo's
sparse mass matrix ``data.qM``, whose entries are the very numbers the dense matrix is filled with. The
controller's update is otherwise unchanged (same order, same fields); only where the mass matrix comes from differs.
"""

from __future__ import annotations

import types
from typing import TYPE_CHECKING

import mujoco
import numpy as np

if TYPE_CHECKING:
    from robosuite.robots.robot import Robot


def mass_matrix_index(model: mujoco.MjModel, dofs: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Rows, columns and ``qM`` addresses of the nonzero lower-triangle entries of M[dofs][:, dofs].

    MuJoCo keeps row i of its sparse inertia at ``dof_Madr[i]``: the diagonal, then the entries of i's ancestor
    dofs, nearest first (``dof_parentid``); entries between dofs neither of which descends from the other are zero.
    """
    position = {int(dof): k for k, dof in enumerate(dofs)}
    rows, cols, addresses = [], [], []
    for k, dof in enumerate(dofs):
        address, ancestor = int(model.dof_Madr[dof]), int(dof)
        while ancestor >= 0:
            if ancestor in position:
                rows.append(k)
                cols.append(position[ancestor])
                addresses.append(address)
            address += 1
            ancestor = int(model.dof_parentid[ancestor])
    return np.array(rows, dtype=int), np.array(cols, dtype=int), np.array(addresses, dtype=int)


def mass_matrix_block(qM: np.ndarray, n: int, index: tuple[np.ndarray, np.ndarray, np.ndarray]) -> np.ndarray:
    """M[dofs][:, dofs] (n dofs) from the sparse inertia ``qM`` and that block's ``mass_matrix_index``."""
    rows, cols, addresses = index
    block = np.zeros((n, n))
    block[rows, cols] = qM[addresses]
    block[cols, rows] = qM[addresses]
    return block


def _update(self, force=False):
    # robosuite.controllers.parts.controller.Controller.update, with the mass matrix read as a block
    if self.new_update or force:
        if not (self.lite_physics and not force):
            self.sim.forward()
        if self.ref_name is not None:
            self.update_reference_data()
        self.joint_pos = np.array(self.sim.data.qpos[self.qpos_index])
        self.joint_vel = np.array(self.sim.data.qvel[self.qvel_index])
        self.mass_matrix = mass_matrix_block(self.sim.data._data.qM, len(self.qvel_index), self._mass_matrix_index)
        self.new_update = False


def use_block_mass_matrix(robot: Robot) -> None:
    """Makes every part controller of ``robot`` read its mass matrix as a block (see module docstring)."""
    model = robot.sim.model._model
    for controller in robot.composite_controller.part_controllers.values():
        if getattr(controller, "qvel_index", None) is not None and len(controller.qvel_index) > 0:
            controller._mass_matrix_index = mass_matrix_index(model, np.asarray(controller.qvel_index))
            controller.update = types.MethodType(_update, controller)
