"""The scooping task model: arena, robot, bowl and a pile of grains, with solver settings that piles need."""

from __future__ import annotations

import xml.etree.ElementTree as ET

import numpy as np
from robosuite.models.tasks import ManipulationTask

from veragmil_suite.models.foods import CONTACT_TIMECONST_S, GrainModel
from veragmil_suite.models.grains import GrainPile

# MuJoCo's default Newton solver is unusable for piles (600 peas: 2.6 s per step). Conjugate gradient with an
# elliptic friction cone keeps a pile still and runs in real time; PGS jitters, noslip blows piles up. robosuite
# leaves the solver at MuJoCo's default, so the task sets it in its own XML (recorded with every demo).
# 1/240 s divides both the 20 Hz default and the paper's 60 Hz control period (12 and 4 substeps), and halves the
# cost of a simulated second against robosuite's 2 ms with piles as still (grain contacts use a 20 ms time
# constant, above MuJoCo's 2-step minimum).
PHYSICS_TIMESTEP_S = 1.0 / 240.0
_TABLE1_SOLVER_OPTIONS = {
    "solver": "CG",
    "iterations": "30",
    "ls_iterations": "10",
    "cone": "elliptic",
    # robosuite's base model sets impratio 20 for crisp finger grasps; with 30 iterations it starves the normal
    # forces and rice leaked through the bowl's floor (4 of 200 grains within 0.25 s).
    "impratio": "1",
}
# Solver settings by physics (veragmil_suite.models.foods.PHYSICS). Calibrated: soft friction (impratio 1) lets grains
# creep down a heap below their friction angle (rice heaped at 9 degrees); 10 heaps rice as 100 does (22-26 degrees).
# Stiffer friction needs more iterations to converge: 40 keep rice, buckwheat, barley, pasta and beans in the bowl
# under the spoon, which 30 did not for rice as a straight pair with rolling rows (its rows were the cost:
# results/calibration/RUN.md); a food that needs more names its own cap (GrainModel.solver_iterations).
PHYSICS_SOLVER_OPTIONS = {
    "table1": _TABLE1_SOLVER_OPTIONS,
    "calibrated": {**_TABLE1_SOLVER_OPTIONS, "iterations": "40", "impratio": "10"},
}


def pile_solver_options(grain: GrainModel, physics: str) -> dict[str, str]:
    """MuJoCo <option> attributes of a pile of ``grain`` (the grain model of ``physics``): the physics' solver settings,
    with the grain's own iteration cap where it has one."""
    options = dict(PHYSICS_SOLVER_OPTIONS[physics])
    if grain.solver_iterations is not None:
        options["iterations"] = str(grain.solver_iterations)
    return options


# MuJoCo's island sleeping (mjENBL_SLEEP, MuJoCo >= 3.8): a tree whose every velocity stays under this tolerance
# (m/s and rad/s, scaled by MuJoCo per degree of freedom) falls asleep and costs no collision or solver work until
# something awake touches its island. MuJoCo's default, 1e-4, is under a settled pile's own creep: no grain slept.
# 3e-3 is the largest measured at which the expert's success, load and spillage stay those of sleeping off
# (results/sleep_physics/).
GRAIN_SLEEP_TOLERANCE = 3e-3


def check_sleep_tolerance(value: object) -> float | None:
    """
    A sleep_tolerance as ScoopTask takes it: None (nothing sleeps) or a positive number.

    Raises:
        ValueError: [anything else; the message names the accepted values]
    """
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not value > 0:
        raise ValueError(
            f"sleep_tolerance must be a positive number (MuJoCo's, e.g. {GRAIN_SLEEP_TOLERANCE}) or None "
            f"(nothing sleeps), got {value!r}"
        )
    return float(value)


# MuJoCo saves real numbers to 6 significant digits (mj_saveLastXML: robosuite's sim.model.get_xml writes 1/240 s
# as 0.00416667): a step read back within this relative distance of a whole fraction of the control period is that
# fraction, as it was run
SAVED_STEP_RELATIVE_PRECISION = 1e-5


def check_physics_timestep(timestep_s: object, control_freq: float) -> float:
    """
    A physics step the task runs: positive, at most half the grains' contact time constant (MuJoCo's stability
    rule for soft contacts; a longer step stiffens them), and a whole number of steps per control period. A step
    within the precision of a saved XML of such a step is that step (returned exactly).

    Raises:
        ValueError: [anything else; the message names the accepted steps and control frequencies]
    """
    limit = CONTACT_TIMECONST_S / 2
    if isinstance(timestep_s, bool) or not isinstance(timestep_s, (int, float)) or not 0 < timestep_s <= limit:
        raise ValueError(
            f"physics_timestep_s must be a positive number of seconds, at most {limit * 1000:g} ms (half the grains' "
            f"contact time constant), e.g. {PHYSICS_TIMESTEP_S!r} (1/240), got {timestep_s!r}"
        )
    period = 1.0 / control_freq
    substeps = max(1, round(period / timestep_s))
    step = period / substeps
    # robosuite counts substeps as int(control period / step): a ratio a rounding under the whole number loses one
    if int(period / step) != substeps:
        step = float(np.nextafter(step, 0.0))
    if abs(timestep_s - step) > SAVED_STEP_RELATIVE_PRECISION * step:
        frequencies = [f"{1 / (timestep_s * k):.5g}" for k in range(1, 7)]  # to the precision of a saved step
        steps = [f"1/{control_freq * k:g}" for k in range(1, 1000) if 1 / (control_freq * k) <= limit]
        raise ValueError(
            f"control_freq={control_freq} Hz does not divide the {timestep_s * 1000:.4g} ms physics step: a control "
            f"period must be a whole number of physics steps; accepted control frequencies (Hz) at this step, "
            f"1/(n x step) for a whole n: {', '.join(frequencies)}, ...; accepted physics steps (s) at "
            f"{control_freq} Hz: {', '.join(steps[:6])}, ..."
        )
    return step


# Software (osmesa) rendering: no multisampling, coarse tessellation and no shadow map render 300 grains at
# 140 fps at 84x84, against 3.6 fps at MuJoCo's default quality.
FAST_RENDER_QUALITY = {"offsamples": "0", "numslices": "8", "numstacks": "4", "shadowsize": "0"}


class ScoopTask(ManipulationTask):
    """
    robosuite's ManipulationTask plus a grain pile: the grains are free bodies at the world's top level (MuJoCo
    allows free joints only there), so they are merged as raw bodies rather than as one MujocoObject each, which
    would cost seconds of XML work for hundreds of grains.

    Args:
        mujoco_arena (Arena): MJCF model of robot workspace
        mujoco_robots (RobotModel or list of RobotModel): MJCF model of robot model(s) (list)
        mujoco_objects (None or MujocoObject or list of MujocoObject): a list of MJCF models of physical objects
        grain_pile (GrainPile): the food
        grain_home_qpos (None or np.array): (n, 7) grain poses written into the XML (see GrainPile.bodies)
        solver_options (dict): MuJoCo <option> attributes set on the model
        fast_rendering (bool): trade anti-aliasing and shadows for offscreen rendering speed
        sleep_tolerance (None or float): MuJoCo's sleep_tolerance with island sleeping on; None: never sleep
        timestep_s (float): the physics step (s); see check_physics_timestep
    """

    def __init__(
        self,
        mujoco_arena,
        mujoco_robots,
        mujoco_objects,
        grain_pile: GrainPile,
        grain_home_qpos=None,
        solver_options=None,
        fast_rendering: bool = True,
        sleep_tolerance: float | None = GRAIN_SLEEP_TOLERANCE,
        timestep_s: float = PHYSICS_TIMESTEP_S,
    ):
        super().__init__(mujoco_arena=mujoco_arena, mujoco_robots=mujoco_robots, mujoco_objects=mujoco_objects)
        self.grain_pile = grain_pile
        for body in grain_pile.bodies(home_qpos=grain_home_qpos):
            self.worldbody.append(body)
        option = self.root.find("option")
        option.set("timestep", repr(float(timestep_s)))
        # Joint damping (the robot's, and the grains' spin damping) is integrated explicitly: every damping here is
        # far below the explicit stability limit, and the implicit update's factorisation cost 15% of a step.
        flag = option.find("flag")
        if flag is None:
            flag = ET.SubElement(option, "flag")
        flag.set("eulerdamp", "disable")
        if sleep_tolerance is not None:
            flag.set("sleep", "enable")
            option.set("sleep_tolerance", repr(float(sleep_tolerance)))
        for key, value in (
            pile_solver_options(grain_pile.grain, grain_pile.physics) if solver_options is None else solver_options
        ).items():
            option.set(key, str(value))
        if fast_rendering:
            visual = self.root.find("visual")
            quality = visual.find("quality")
            if quality is None:
                quality = ET.SubElement(visual, "quality")
            for key, value in FAST_RENDER_QUALITY.items():
                quality.set(key, value)
            for light in self.worldbody.iter("light"):
                light.set("castshadow", "false")
