"""The Unitree G1 humanoid in ScoopGranular: where it stands, how its right hand holds the spoon, what the rest holds.

robosuite 1.5 gets the G1 from the optional robosuite-models package (``pip install 'veragmil_suite[humanoid]'``;
robosuite imports it by itself when it is installed). Its arms have five joints each (shoulder pitch, roll and yaw,
elbow pitch, forearm roll), one short of a spoon's six pose coordinates. The task needs the spoon's position, its
tilt (level, or dipped 45 degrees about its sideways axis) and not its heading (the rotation about the vertical:
success looks at tilt only), so the G1's spoon arm controls position and tilt and leaves the heading free
(veragmil_suite.controllers.scoop_config, veragmil_suite.utils.kinematics, ScriptedScooper).

How the hand holds the spoon: the spoon's sideways axis runs along the forearm, so the forearm roll alone turns
the spoon from its dipped (pre-scoop) to its level (post-scoop) attitude, and the arm works as a person's does
when scooping in front of the chest: upper arm forward, forearm across, fist at shoulder height. The G1's elbow
cannot straighten past 103 degrees, so the fist stays within 0.29 m of the shoulder; the robot stands with its
right shoulder behind and to the right of the bowl, close to the table, the bowl near the table's edge.
Everything here is measured from the bowl's nominal place (its rim centre), so the arm's reach does not depend on
the table's size.
"""

from __future__ import annotations

import importlib.util
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from robosuite.models.robots.robot_model import REGISTERED_ROBOTS
from robosuite.robots import ROBOT_CLASS_MAPPING

if TYPE_CHECKING:
    import xml.etree.ElementTree as ET

# robosuite-models 1.0.0's G1 variants the task supports: a fixed base (the legs do not balance anything)
G1_ROBOTS = ("G1FixedLowerBody", "G1ArmsOnly")
# ... and the ones it refuses: free-standing legs that would need a balance controller, or a floating base
UNSUPPORTED_G1_ROBOTS = ("G1", "G1FloatingBody")
HUMANOID_EXTRA = "pip install 'veragmil_suite[humanoid]' (robosuite-models==1.0.0)"

# The spoon arm is robosuite's "right" arm; the other arm holds nothing
SPOON_ARM = "right"
# Contacts are dropped between a link and the bodies up to this many joints above it (see self_contact_excludes)
SHOULDER_JOINTS = 3


@dataclass(frozen=True)
class HumanoidLayout:
    """Where a humanoid stands at the table and how it holds the spoon (lengths in m, angles in rad).

    Attributes:
        base_from_bowl_m: the robot's base (floor point under its pelvis) from the bowl's nominal rim centre, (x, y).
        bowl_from_table_edge_m: the bowl's nominal centre from the table's near edge (the robot's side); with the
            base offset it leaves the torso 2 cm clear of the table and the bowl's skirt 4 cm inside its edge at the
            bowl's nearest random place.
        spoon_mount_quat_wxyz: the spoon's mount (flange) in the hand's frame: the spoon's sideways axis along the
            forearm, so that forearm roll tilts the spoon.
        held_qpos: joint positions (rad) the parts outside the spoon arm hold, by robosuite part name, in the
            order of the part's joints.
        arm_ik_start: the spoon arm's joints at which the pre-scoop inverse kinematics starts (the posture above:
            upper arm forward, forearm across, fist at shoulder height).
    """

    base_from_bowl_m: tuple[float, float]
    bowl_from_table_edge_m: float
    spoon_mount_quat_wxyz: tuple[float, float, float, float]
    held_qpos: dict[str, tuple[float, ...]]
    arm_ik_start: tuple[float, ...]


# the spoon's sideways (flange y) axis along the G1 hand's forearm (the hand frame's x): a quarter turn about x
_G1_SPOON_MOUNT = (float(np.cos(np.pi / 4)), float(np.sin(np.pi / 4)), 0.0, 0.0)
# The left arm folded down and back, clear of the table's edge and of the hips: shoulder pitch (back), roll
# (out), yaw, elbow pitch (opened), forearm roll
_G1_LEFT_ARM_HELD = (1.0, 0.25, 0.0, -0.2, 0.0)
_G1_COMMON = dict(
    base_from_bowl_m=(-0.2675, -0.064),
    bowl_from_table_edge_m=0.16,
    spoon_mount_quat_wxyz=_G1_SPOON_MOUNT,
    arm_ik_start=(-1.75, -0.19, 1.31, 0.27, 1.72),
)
HUMANOID_LAYOUTS: dict[str, HumanoidLayout] = {
    "G1FixedLowerBody": HumanoidLayout(held_qpos={"left": _G1_LEFT_ARM_HELD, "torso": (0.0,)}, **_G1_COMMON),
    "G1ArmsOnly": HumanoidLayout(held_qpos={"left": _G1_LEFT_ARM_HELD}, **_G1_COMMON),
}


def robosuite_models_installed() -> bool:
    """Whether robosuite-models (the G1 and other extra robots) is installed."""
    return importlib.util.find_spec("robosuite_models") is not None


def humanoid_layout(robot: str) -> HumanoidLayout | None:
    """The layout of a supported humanoid, None for a single-arm robot."""
    return HUMANOID_LAYOUTS.get(robot)


def check_robot(robot: str) -> None:
    """Raises a ValueError naming the problem and the accepted robots when ``robot`` cannot scoop here."""
    known = ROBOT_CLASS_MAPPING
    if robot not in known:
        if robot in G1_ROBOTS + UNSUPPORTED_G1_ROBOTS:
            raise ValueError(f"robot {robot!r} comes with robosuite-models, which is not installed: {HUMANOID_EXTRA}")
        extra = "" if robosuite_models_installed() else f"; the G1 ({', '.join(G1_ROBOTS)}) needs {HUMANOID_EXTRA}"
        raise ValueError(f"Unknown robot {robot!r}; robosuite's robots: {', '.join(sorted(known))}{extra}")
    if robot in UNSUPPORTED_G1_ROBOTS:
        raise ValueError(
            f"robot {robot!r} stands on its own legs or a floating base, which nothing here balances; "
            f"the G1 scoops as {' or '.join(G1_ROBOTS)}"
        )
    arms = len(REGISTERED_ROBOTS[robot].arms)
    if arms > 1 and robot not in HUMANOID_LAYOUTS:
        raise ValueError(
            f"robot {robot!r} has {arms} arms, and the task knows where to stand only these "
            f"two-armed robots: {', '.join(HUMANOID_LAYOUTS)}; or use a single-arm robot (XArm7 by default)"
        )


def self_contact_excludes(worldbody: ET.Element) -> list[tuple[str, str]]:
    """
    Body pairs of the robot that must not touch: each body with every body with geoms up to SHOULDER_JOINTS joints
    above it.

    MuJoCo drops contacts between a jointed body and its parent only, and not at all when the parent is welded to
    the world, and it collides meshes as their convex hulls. Bolted down, the G1 kept its torso pressed on its
    pelvis (G1FixedLowerBody) or its shoulders on its torso (G1ArmsOnly), and the constraint solver, shared with
    the pile, answered with impulses that threw grains out of the bowl; and the torso's hull, which covers the
    shoulders, caught the upper arm as the spoon was carried across the chest. The shoulder's three joints act as
    one ball joint, so its links and the torso never touch; the elbow and forearm still meet the body.

    Args:
        worldbody: the robot model's <worldbody> element
    """
    pairs = []

    def has(body: ET.Element, tag: str) -> bool:
        return any(child.tag == tag for child in body)

    def walk(body: ET.Element, above: list) -> None:
        # above: (ancestor, joints between it and ``body``'s parent) for each ancestor, nearest last
        joints = int(has(body, "joint") or has(body, "freejoint"))
        pairs.extend(
            (body.get("name"), other.get("name"))
            for other, count in above
            if has(other, "geom") and 0 < count + joints <= SHOULDER_JOINTS
        )
        below = [(other, count + joints) for other, count in above] + [(body, 0)]
        for child in body.findall("body"):
            walk(child, below)

    for root in worldbody.findall("body"):
        walk(root, [])
    return pairs
