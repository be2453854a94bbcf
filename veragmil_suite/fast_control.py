"""The arm's mass matrix without the whole model's: robosuite's controllers, made cheap beside a pile of grains.

robosuite's part controllers build MuJoCo's dense nv x nv mass matrix at every physics substep, only to read the
arm's 7 x 7 block. With 200 free grains nv is about 1200, and that alone took 1.1 ms per substep (13 ms of a
20 Hz env step). Each grain's block is independent of the arm's, so the arm's block is the same read straight
from MuJoCo's sparse mass matrix with a few matrix-vector products. The controller's update is otherwise
unchanged (same order, same fields); only where the mass matrix comes from differs.
"""

from __future__ import annotations

import types

import mujoco
import numpy as np


def mass_matrix_block(model: mujoco.MjModel, data: mujoco.MjData, dofs: np.ndarray) -> np.ndarray:
    """M[dofs][:, dofs] from the sparse inertia in ``data.qM``, in O(len(dofs) * nnz(M))."""
    unit = np.zeros(model.nv)
    column = np.zeros(model.nv)
    block = np.empty((len(dofs), len(dofs)))
    for i, dof in enumerate(dofs):
        unit[dof] = 1.0
        mujoco.mj_mulM(model, data, column, unit)
        unit[dof] = 0.0
        block[:, i] = column[dofs]
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
        self.mass_matrix = mass_matrix_block(self.sim.model._model, self.sim.data._data, np.asarray(self.qvel_index))
        self.new_update = False


def use_block_mass_matrix(robot) -> None:
    """Makes every part controller of ``robot`` read its mass matrix as a block (see module docstring)."""
    for controller in robot.composite_controller.part_controllers.values():
        if getattr(controller, "qvel_index", None) is not None and len(controller.qvel_index) > 0:
            controller.update = types.MethodType(_update, controller)
