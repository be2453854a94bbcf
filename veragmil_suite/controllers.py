"""Controller configurations for the scooping task: robosuite's own composite controllers, with our defaults."""

from __future__ import annotations

import copy

from robosuite.controllers import load_composite_controller_config, load_part_controller_config
from robosuite.controllers.parts.arm.ik import SUPPORTED_IK_ROBOTS

ARM_CONTROLLERS = ("OSC_POSE", "IK_POSE")


def load_scoop_controller_config(controller: str = "OSC_POSE", robot: str = "XArm7") -> dict:
    """robosuite's BASIC composite controller for ``robot`` with ``controller`` driving the arm.

    OSC_POSE (default) takes delta end-effector poses; IK_POSE is robosuite's inverse-kinematics controller, as
    the paper used. Either gives 6-D actions: the spoon has no gripper DoF.
    """
    if controller not in ARM_CONTROLLERS:
        raise ValueError(f"Unknown arm controller {controller!r}; accepted: {', '.join(ARM_CONTROLLERS)}")
    if controller == "IK_POSE" and robot not in SUPPORTED_IK_ROBOTS:
        raise ValueError(
            f"robosuite's IK_POSE controller supports only {', '.join(sorted(SUPPORTED_IK_ROBOTS))}, not {robot!r}; "
            "use OSC_POSE for it"
        )
    config = copy.deepcopy(load_composite_controller_config(controller="BASIC", robot=robot))
    part = load_part_controller_config(default_controller=controller)
    # single-arm robots: robosuite's arm is "right"; the other parts of BASIC (left, torso, head, base, legs)
    # would only be dropped again with a warning each
    gripper = config["body_parts"]["right"].get("gripper")
    config["body_parts"] = {"right": dict(part, **({"gripper": gripper} if gripper else {}))}
    return config
