"""What every calibration model shares: the task's solver settings, a support under the grains, and a rest rule.

Each test (lifting cylinder, spoonful, slope) builds its own container on this, so that its grains meet the same
solver and the same support as in the others.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET

import mujoco
import numpy as np

from veragmil_suite.models import contact_groups
from veragmil_suite.models.foods import GrainModel
from veragmil_suite.models.scoop_task import PHYSICS_SOLVER_OPTIONS, PHYSICS_TIMESTEP_S, pile_solver_options

REST_SPEED_M_S = 0.002  # every grain slower than this: at rest (the tests' stopping rule)
EJECTED_SPEED_M_S = 3.0  # faster than any fall in the tests (2 m/s from 20 cm): a grain the solver threw


def calibration_scene(
    name: str, physics: str, solver_options: dict | None = None, tilt_rad: float = 0.0, grain: GrainModel | None = None
) -> tuple[ET.Element, ET.Element]:
    """The root and worldbody of a model under the task's solver settings for ``physics`` (those of a pile of ``grain``
    where given: scoop_task.pile_solver_options) and timestep (``solver_options``, MuJoCo's ``<option>`` attributes,
    update either), with a support whose top passes through the origin, tilted ``tilt_rad`` about y (downhill is +x).

    The support's friction is below every grain's, so a grain's own friction acts (MuJoCo takes the larger).
    """
    task_options = PHYSICS_SOLVER_OPTIONS[physics] if grain is None else pile_solver_options(grain, physics)
    option = {"timestep": repr(PHYSICS_TIMESTEP_S), **task_options, **(solver_options or {})}
    root = ET.Element("mujoco", model=name)
    # angles in radians, as in robosuite's models (MuJoCo's own default is degrees)
    ET.SubElement(root, "compiler", angle="radian")
    opt = ET.SubElement(root, "option", **{k: str(v) for k, v in option.items()})
    ET.SubElement(opt, "flag", eulerdamp="disable")  # as in ScoopTask
    world = ET.SubElement(root, "worldbody")
    support = ET.SubElement(world, "geom", name="support", type="box", size="0.5 0.5 0.01")
    support.set("pos", f"0 0 {-0.01 / math.cos(tilt_rad)}")
    support.set("euler", f"0 {-tilt_rad} 0")
    support.set("friction", "0.01 0 0")
    for key, value in contact_groups.SUPPORT.items():
        support.set(key, str(value))
    return root, world


def run_until_rest(
    model: mujoco.MjModel, data: mujoco.MjData, ids: np.ndarray, max_s: float, min_s: float = 0.3
) -> tuple[bool, int]:
    """Steps until every grain of ``ids`` is slower than REST_SPEED_M_S (at least ``min_s``, at most ``max_s`` of
    simulated time); returns (came to rest, most grains seen faster than EJECTED_SPEED_M_S at one check)."""
    start = data.time
    fast = 0
    while data.time - start < max_s:
        mujoco.mj_step(model, data, nstep=24)
        speed = np.linalg.norm(data.cvel[ids, 3:], axis=1)
        if not np.isfinite(speed).all():
            raise RuntimeError("the grains blew up (non-finite velocities)")
        fast = max(fast, int((speed > EJECTED_SPEED_M_S).sum()))
        if data.time - start >= min_s and speed.max() < REST_SPEED_M_S:
            return True, fast
    return False, fast
