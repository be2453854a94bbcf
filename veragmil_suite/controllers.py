"""Controller configurations for the scooping task: robosuite's own composite controllers, with our defaults."""

from __future__ import annotations

import copy

import numpy as np
from robosuite.controllers import load_composite_controller_config, load_part_controller_config
from robosuite.controllers.parts.arm.ik import SUPPORTED_IK_ROBOTS

ARM_CONTROLLERS = ("OSC_POSE", "IK_POSE")

# OSC_POSE stiffness. XArm7's joints have 1 N m of dry friction (frictionloss): at robosuite's kp=150 the pull of a
# small pose error does not overcome it, and the spoon stops 1-8 mm short of a held target (0.07 mm with the
# friction removed). kp=2000 holds every direction within 0.7 mm (scripts/bench_controller.py).
OSC_KP = 2000.0
# robosuite's own OSC_POSE stiffness, to which its action scale (output_max) is tuned, at its default control rate
ROBOSUITE_OSC_KP = 150.0
ROBOSUITE_CONTROL_FREQ_HZ = 20.0


def osc_speed_per_offset(kp, kd, control_period_s: float):
    """Speed (m/s or rad/s) at which OSC_POSE moves per unit of a delta action's offset (m or rad).

    OSC anchors each step's goal at the pose reached and holds it for one control period, so the offset shrinks by
    half a period's travel on average and the spoon settles where kp * (offset - speed * period / 2) = kd * speed.
    Measured at kp=2000: 14.1 /s against 14.3 predicted; below ~1 mm offsets joint friction slows it further.
    """
    kp, kd = np.asarray(kp, dtype=float), np.asarray(kd, dtype=float)
    return kp / (kd + kp * control_period_s / 2.0)


# robosuite 1.5's IK_POSE is differential IK on MuJoCo's site Jacobian: nothing in it is robot-specific but its
# 7-entry null-space gains, so it drives every 7-DoF arm; robosuite's list of IK robots predates that (pybullet URDFs)
IK_ROBOTS = ("XArm7", "Panda", "Sawyer", "IIWA", "Kinova3", "Jaco")


def load_scoop_controller_config(controller: str = "OSC_POSE", robot: str = "XArm7") -> dict:
    """robosuite's BASIC composite controller for ``robot`` with ``controller`` driving the arm.

    OSC_POSE (default) takes delta end-effector poses; IK_POSE is robosuite's inverse-kinematics controller, as
    the paper used, for 7-DoF arms: its actions are the spoon's target displacement in metres and rotation in
    radians, about world axes, clipped to 0.02 m and 0.05 rad (env.action_spec). Either gives 6-D actions: the
    spoon has no gripper DoF.
    """
    if controller not in ARM_CONTROLLERS:
        raise ValueError(f"Unknown arm controller {controller!r}; accepted: {', '.join(ARM_CONTROLLERS)}")
    if controller == "IK_POSE" and robot not in IK_ROBOTS:
        raise ValueError(
            f"robosuite's IK_POSE controller needs a 7-DoF arm ({', '.join(IK_ROBOTS)}), not {robot!r}; "
            "use OSC_POSE for it"
        )
    config = copy.deepcopy(load_composite_controller_config(controller="BASIC", robot=robot))
    part = load_part_controller_config(default_controller=controller)
    if controller == "OSC_POSE":
        # stiffer, and the output range shrunk so that an action still means the speed it means with robosuite's
        # defaults (devices keep their feel, and a policy's actions their size); the damping ratio is robosuite's,
        # which sets kd = 2 sqrt(kp) * damping_ratio
        period = 1.0 / ROBOSUITE_CONTROL_FREQ_HZ
        ratio = float(part["damping_ratio"])
        gain = osc_speed_per_offset(OSC_KP, 2.0 * np.sqrt(OSC_KP) * ratio, period)
        stock_gain = osc_speed_per_offset(part["kp"], 2.0 * np.sqrt(part["kp"]) * ratio, period)
        part["kp"] = OSC_KP
        part["output_max"] = [float(v * stock_gain / gain) for v in part["output_max"]]
        part["output_min"] = [float(v * stock_gain / gain) for v in part["output_min"]]
    if controller == "IK_POSE":
        SUPPORTED_IK_ROBOTS.add(robot)  # robosuite asserts membership when it builds the controller
        # IK_POSE hands absolute joint targets to its JointPositionController base, whose input_type defaults to
        # "delta": the targets were added to the current joint angles and the arm ran away (robosuite issue #640)
        part["input_type"] = "absolute"
        # its default kp=100 reaches a tenth of each step's joint target, and the small corrections stick in XArm7's
        # joint friction (frictionloss 1 N m), bending +z commands 37% sideways; robosuite's own WHOLE_BODY_IK joint
        # gain keeps every axis within 5% on XArm7 and Panda
        part["kp"] = 1000
    # single-arm robots: robosuite's arm is "right"; the other parts of BASIC (left, torso, head, base, legs)
    # would only be dropped again with a warning each
    gripper = config["body_parts"]["right"].get("gripper")
    config["body_parts"] = {"right": dict(part, **({"gripper": gripper} if gripper else {}))}
    return config
