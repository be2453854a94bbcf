"""The arm's mass matrix read as a block of MuJoCo's sparse inertia is exactly the dense matrix's block."""

import mujoco
import numpy as np
import pytest
from helpers.env import make_env

from veragmil_suite.controllers.fast_control import mass_matrix_block, mass_matrix_index


def _dense(env) -> np.ndarray:
    model, data = env.sim.model._model, env.sim.data._data
    full = np.zeros((model.nv, model.nv))
    mujoco.mj_fullM(model, full, data.qM)
    return full


@pytest.mark.parametrize("robot", ["XArm7", "G1FixedLowerBody"])
def test_every_controller_reads_the_dense_matrix_block_exactly(robot):
    env = make_env("pasta", robot=robot, n_grains=12)
    env.reset()
    rng = np.random.default_rng(0)
    for _ in range(3):
        env.step(rng.uniform(-1, 1, env.action_dim))
    controllers = [c for c in env.robots[0].composite_controller.part_controllers.values() if len(c.qvel_index)]
    assert controllers
    for controller in controllers:
        controller.update(force=True)  # a forward at the state reached, as robosuite's own update
        dofs = np.asarray(controller.qvel_index)
        np.testing.assert_array_equal(controller.mass_matrix, _dense(env)[np.ix_(dofs, dofs)])
    env.close()


def test_dofs_on_separate_branches_have_no_entry_between_them():
    # a root free body with two hinged children: the two hinges descend from the root, not from each other
    model = mujoco.MjModel.from_xml_string(
        """<mujoco><worldbody><body><freejoint/><geom size="0.1"/>
        <body pos="0.2 0 0"><joint type="hinge"/><geom size="0.05"/></body>
        <body pos="-0.2 0 0"><joint type="hinge" axis="0 1 0"/><geom size="0.05"/></body>
        </body></worldbody></mujoco>"""
    )
    data = mujoco.MjData(model)
    data.qpos[3:7] = [0.9, 0.1, 0.3, 0.2]
    data.qpos[7:] = [0.4, -0.7]
    mujoco.mj_forward(model, data)
    full = np.zeros((model.nv, model.nv))
    mujoco.mj_fullM(model, full, data.qM)
    dofs = np.array([2, 6, 7])
    block = mass_matrix_block(data.qM, len(dofs), mass_matrix_index(model, dofs))
    np.testing.assert_array_equal(block, full[np.ix_(dofs, dofs)])
    assert block[1, 2] == 0.0 and np.all(np.diag(block) > 0)
