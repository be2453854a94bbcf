"""A level spoonful: grains poured onto the task's spoon held level, struck off at the rim, weighed.

The real value it answers to is the spoon's volume times the food's measured bulk density; the simulated one counts
the grains the spoon really holds (grains the size of the spoon's depth pack worse than in bulk, as real ones do).
Striking off is done as by hand: a straight blade drawn across the rim, its edge on the rim's plane, sweeps away every
grain that stands above it. The spoonful is the grains then in the spoon's bowl with their centre under the rim
(DishShape.holds); grains poured over the side that came to rest on the table under the spoon are not in it.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET

import mujoco
import numpy as np
from robosuite.utils.mjcf_utils import array_to_string

from veragmil_suite.calibration.scene import calibration_scene, run_until_rest
from veragmil_suite.models import contact_groups
from veragmil_suite.models.dish import DishShape
from veragmil_suite.models.foods import SPOON_SURFACE, FoodSpec
from veragmil_suite.models.grains import GrainPile
from veragmil_suite.models.spoon_gripper import SPOON_SHAPE, spoon_contact

RIM_HEIGHT_M = 0.05  # the spoon's rim plane above the table
BLADE_SPEED_M_S = 0.05  # the strike-off blade's sweep across the rim
BLADE_HALF_SIZE_M = (0.002, 0.04, 0.015)  # thickness, length along the rim's minor axis, height (all halves)


def dish_volume_m3(shape: DishShape) -> float:
    """Volume below the rim plane of a dish whose elliptic cross-section widens linearly from floor to rim."""
    a1, b1 = shape.rim_semi_axes
    a0, b0 = shape.floor_semi_axes
    mean_area = a0 * b0 + (a0 * (b1 - b0) + b0 * (a1 - a0)) / 2 + (a1 - a0) * (b1 - b0) / 3
    return math.pi * shape.depth * mean_area


def level_spoonful_g(
    food: FoodSpec, physics: str, seed: int = 0, solver_options: dict | None = None, max_settle_s: float = 6.0
) -> tuple[float, int]:
    """Grams (and grains) a level spoonful of ``food`` holds: twice the spoon's volume poured, struck off at the rim."""
    grain = food.grain(physics)
    n = max(6, int(2.0 * dish_volume_m3(SPOON_SHAPE) * 0.6 / grain.piece_volume_m3()))
    pile = GrainPile(food, n, np.random.default_rng(seed), physics=physics)
    root, world = calibration_scene("spoonful", physics, solver_options, grain=pile.grain)
    spoon = ET.SubElement(world, "body", name="spoon", pos=f"0 0 {RIM_HEIGHT_M}")
    for g in SPOON_SHAPE.geoms():
        geom = ET.SubElement(spoon, "geom", name="spoon_" + g["name"], type=g["type"])
        geom.set("size", array_to_string(g["size"]))
        geom.set("pos", array_to_string(g["pos"]))
        geom.set("quat", array_to_string(g["quat"]))
        geom.set("friction", array_to_string((SPOON_SURFACE.friction, 0.005, 0.0001)))
        for key, value in {**contact_groups.SHELL, **spoon_contact(physics)}.items():
            geom.set(key, str(value))
    t, w, h = BLADE_HALF_SIZE_M
    blade_start_x = -(SPOON_SHAPE.rim_semi_axes[0] + 2 * t + 2 * grain.size_range_m[1])
    blade = ET.SubElement(world, "body", name="blade", mocap="true", pos=f"{blade_start_x} 0 {RIM_HEIGHT_M + h}")
    ET.SubElement(blade, "geom", name="blade", type="box", size=f"{t} {w} {h}", friction="0.01 0 0", **{
        key: str(value) for key, value in contact_groups.SHELL.items()
    })  # fmt: skip
    for body in pile.bodies():
        world.append(body)
    model = mujoco.MjModel.from_xml_string(ET.tostring(root, encoding="unicode"))
    data = mujoco.MjData(model)
    adr = np.array([model.joint(j).qposadr[0] for j in pile.joint_names])
    rim = np.array([0.0, 0.0, RIM_HEIGHT_M])
    data.qpos[adr[:, None] + np.arange(7)] = pile.lattice_qpos(SPOON_SHAPE, rim_center=rim)
    ids = np.array([model.body(name).id for name in pile.body_names])
    run_until_rest(model, data, ids, max_settle_s, min_s=0.5)
    while data.mocap_pos[0, 0] < -blade_start_x:
        data.mocap_pos[0, 0] += BLADE_SPEED_M_S * model.opt.timestep
        mujoco.mj_step(model, data)
    data.mocap_pos[0, 2] = 5.0  # out of the way
    run_until_rest(model, data, ids, max_settle_s)
    # in the spoon's bowl, centre under the rim: not a grain that fell beside it, nor one under it on the table
    held = SPOON_SHAPE.holds(data.xpos[ids] - rim, margin=float(pile.radii.max()))
    return float(model.body_mass[ids][held].sum() * 1000.0), int(held.sum())
