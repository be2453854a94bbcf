"""One grain on an inclined plane: how far it creeps or rolls, the single-grain face of the angle of repose.

Below its friction angle a real grain stays put, and a pea stops rolling on a gentle slope; soft friction (MuJoCo's
impratio 1) lets a grain creep, and a contact without rolling friction (condim 3) lets a sphere roll forever.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET

import mujoco
import numpy as np

from veragmil_suite.calibration.scene import calibration_scene
from veragmil_suite.models.foods import FoodSpec
from veragmil_suite.models.grains import GrainPile


def slope_travel_m(
    food: FoodSpec, physics: str, slope_deg: float, duration_s: float = 2.0, seed: int = 0, along: bool = False
) -> float:
    """Distance (m) one grain of ``food`` travels down a plane of the grain's own friction tilted ``slope_deg``.

    The grain starts at rest lying on its long side across the slope (a rolling position for round grains), or with
    its long axis down the slope if ``along``.
    """
    pile = GrainPile(food, 1, np.random.default_rng(seed), physics=physics)
    tilt = math.radians(slope_deg)
    root, world = calibration_scene("slope", physics, tilt_rad=tilt, grain=pile.grain)
    world.append(pile.bodies()[0])
    model = mujoco.MjModel.from_xml_string(ET.tostring(root, encoding="unicode"))
    data = mujoco.MjData(model)
    adr = model.joint(pile.joint_names[0]).qposadr[0]
    # the long axis across the slope (y) or down it (x): a capsule's is z, every other grain's x
    c = math.cos(math.pi / 4)
    capsule = pile.geoms[0][0]["type"] == "capsule"
    if along:
        heading = np.array([c, 0.0, c, 0.0]) if capsule else np.array([1.0, 0.0, 0.0, 0.0])
    else:
        heading = np.array([c, c, 0.0, 0.0]) if capsule else np.array([c, 0.0, 0.0, c])
    tilt_q = np.array([math.cos(-tilt / 2), 0.0, math.sin(-tilt / 2), 0.0])
    quat = np.zeros(4)
    mujoco.mju_mulQuat(quat, tilt_q, heading)
    data.qpos[adr + 3 : adr + 7] = quat
    data.qpos[adr : adr + 3] = [0.0, 0.0, float(pile.thickness_radii[0]) / math.cos(tilt) + 1e-4]
    mujoco.mj_forward(model, data)
    steps = int(round(0.2 / model.opt.timestep))  # let it sink into its contact first
    mujoco.mj_step(model, data, nstep=steps)
    start = data.qpos[adr : adr + 3].copy()
    mujoco.mj_step(model, data, nstep=int(round(duration_s / model.opt.timestep)))
    return float(np.linalg.norm(data.qpos[adr : adr + 3] - start))
