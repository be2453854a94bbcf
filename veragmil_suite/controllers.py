"""Controller configurations for the scooping task: robosuite's own composite controllers, with our defaults."""

from __future__ import annotations

import copy

from robosuite.controllers import load_composite_controller_config, load_part_controller_config

ARM_CONTROLLERS = ("OSC_POSE", "IK_POSE")


def load_scoop_controller_config(controller: str = "OSC_POSE", robot: str = "XArm7") -> dict:
    """robosuite's BASIC composite controller for ``robot`` with ``controller`` driving the arm.

    OSC_POSE (default) takes delta end-effector poses; IK_POSE is robosuite's inverse-kinematics controller, as
    the paper used. Either gives 6-D actions: the spoon has no gripper DoF.
    """
    if controller not in ARM_CONTROLLERS:
        raise ValueError(f"Unknown arm controller {controller!r}; accepted: {', '.join(ARM_CONTROLLERS)}")
    config = copy.deepcopy(load_composite_controller_config(controller="BASIC", robot=robot))
    part = load_part_controller_config(default_controller=controller)
    for arm, arm_config in config["body_parts"].items():
        if arm in ("right", "left"):
            gripper = arm_config.get("gripper")
            config["body_parts"][arm] = dict(part, **({"gripper": gripper} if gripper else {}))
    return config
