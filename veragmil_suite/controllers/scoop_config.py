"""Controller configurations for the scooping task: robosuite's own composite controllers, with our defaults."""

from __future__ import annotations

import copy
import json
from typing import TYPE_CHECKING, Any

import numpy as np
from robosuite.controllers import load_composite_controller_config, load_part_controller_config
from robosuite.controllers.composite.composite_controller import CompositeController, register_composite_controller
from robosuite.controllers.parts.arm.ik import SUPPORTED_IK_ROBOTS

from veragmil_suite.models.humanoid import SPOON_ARM, check_robot, humanoid_layout

if TYPE_CHECKING:
    from robosuite.controllers.parts.arm.osc import OperationalSpaceController

ARM_CONTROLLERS = ("OSC_POSE", "IK_POSE")

# OSC_POSE stiffness. XArm7's joints have 1 N m of dry friction (frictionloss): at robosuite's kp=150 the pull of a
# small pose error does not overcome it, and the spoon stops 1-8 mm short of a held target (0.07 mm with the
# friction removed). kp=2000 holds every direction within 0.7 mm (benchmarks/bench_controller.py).
OSC_KP = 2000.0
# robosuite's own OSC_POSE stiffness, to which its action scale (output_max) is tuned, at its default control rate
ROBOSUITE_OSC_KP = 150.0
ROBOSUITE_CONTROL_FREQ_HZ = 20.0


def osc_speed_per_offset(kp: float | np.ndarray, kd: float | np.ndarray, control_period_s: float) -> float | np.ndarray:
    """Speed (m/s or rad/s) at which OSC_POSE moves per unit of a delta action's offset (m or rad).

    OSC anchors each step's goal at the pose reached and holds it for one control period, so the offset shrinks by
    half a period's travel on average and the spoon settles where kp * (offset - speed * period / 2) = kd * speed.
    Measured at kp=2000: 14.1 /s against 14.3 predicted; below ~1 mm offsets joint friction slows it further.
    """
    kp, kd = np.asarray(kp, dtype=float), np.asarray(kd, dtype=float)
    return kp / (kd + kp * control_period_s / 2.0)


# A five-joint arm (the G1's) cannot hold all six pose coordinates: OSC_POSE leaves the rotation about the world's
# vertical (the spoon's heading) free, which the task does not need, and holds position and tilt
FREE_HEADING_KP = 0.0


def leave_heading_free(controller: OperationalSpaceController) -> None:
    """
    Makes an OSC_POSE controller ignore the rotation about the world's vertical when its stiffness there is zero.

    With the Jacobian's heading row left in, OSC still asked the five-joint arm for zero heading acceleration, a
    sixth demand it cannot meet beside position and tilt: its least-squares compromise stalled the spoon short of the
    post-scoop pose. Without the row, position and tilt are five coordinates for five joints, met exactly (with the
    coupled operational-space inertia, uncouple_pos_ori false, set by load_scoop_controller_config).
    """
    if np.asarray(controller.kp, dtype=float)[5] != FREE_HEADING_KP or getattr(controller, "heading_free", False):
        return
    update = controller.update

    def update_without_heading(force: bool = False) -> None:
        update(force)
        controller.J_ori[2] = 0.0
        controller.J_full[5] = 0.0

    controller.update = update_without_heading
    controller.heading_free = True


# Stiffness of the parts that hold a fixed joint pose (robosuite's JOINT_POSITION kp, in 1/s^2: its torques are the
# mass matrix times kp times the error): the G1's other arm and torso stay within a milliradian while the spoon arm
# moves (robosuite's own torso default)
HELD_PART_KP = 1000.0


@register_composite_controller
class SpoonArmController(CompositeController):
    """
    robosuite's BASIC composite controller with only the spoon arm in the action: every other part (a humanoid's
    other arm, its torso) holds the joint pose given in the config's ``held_qpos``, by part name. The action is
    then the spoon arm's alone (6-D for OSC_POSE), as on a single-arm robot, and a reset or a replayed state cannot
    move what the other parts hold.
    """

    name = "SPOON_ARM"

    @property
    def held_qpos(self) -> dict[str, np.ndarray]:
        held = (self.composite_controller_specific_config or {}).get("held_qpos", {})
        return {part: np.asarray(q, dtype=float) for part, q in held.items() if part in self.part_controllers}

    def setup_action_split_idx(self) -> None:
        start = 0
        held = self.held_qpos
        for part_name, controller in self.part_controllers.items():
            if part_name in self.grippers:
                width = self.grippers[part_name].dof
            else:
                width = 0 if part_name in held else controller.control_dim
            self._action_split_indexes[part_name] = (start, start + width)
            start += width

    def set_goal(self, all_action: np.ndarray) -> None:
        held = self.held_qpos
        for part_name, controller in self.part_controllers.items():
            if part_name in held:
                continue
            start, end = self._action_split_indexes[part_name]
            action = all_action[start:end]
            if part_name in self.grippers:
                action = self.grippers[part_name].format_action(action)
            controller.set_goal(action)

    def reset(self) -> None:
        super().reset()
        for part_name, qpos in self.held_qpos.items():
            controller = self.part_controllers[part_name]
            controller.goal_qpos = qpos.copy()
            if controller.interpolator is not None:
                controller.interpolator.set_goal(controller.goal_qpos)

    @property
    def action_limits(self) -> tuple[np.ndarray, np.ndarray]:
        low, high = [], []
        held = self.held_qpos
        for part_name, controller in self.part_controllers.items():
            if part_name in held:
                continue
            if part_name in self.grippers:
                dof = self.grippers[part_name].dof
                part_low, part_high = [-1.0] * dof, [1.0] * dof
            else:
                part_low, part_high = controller.control_limits
            low, high = np.concatenate([low, part_low]), np.concatenate([high, part_high])
        return low, high


# robosuite 1.5's IK_POSE is differential IK on MuJoCo's site Jacobian: nothing in it is robot-specific but its
# 7-entry null-space gains, so it drives every 7-DoF arm; robosuite's list of IK robots predates that (pybullet URDFs)
IK_ROBOTS = ("XArm7", "Panda", "Sawyer", "IIWA", "Kinova3", "Jaco")


def load_scoop_controller_config(controller: str = "OSC_POSE", robot: str = "XArm7") -> dict:
    """robosuite's BASIC composite controller for ``robot`` with ``controller`` driving the arm.

    OSC_POSE (default) takes delta end-effector poses; IK_POSE is robosuite's inverse-kinematics controller, as
    the paper used, for 7-DoF arms: its actions are the spoon's target displacement in metres and rotation in
    radians, about world axes, clipped to 0.02 m and 0.05 rad (env.action_spec). Either gives 6-D actions: the
    spoon has no gripper DoF.

    A humanoid (veragmil_suite.models.humanoid: the G1) gets our SPOON_ARM composite instead: OSC_POSE on its right
    (spoon) arm, the same 6-D action, with its heading component (index 5) unused since the five-joint arm leaves the
    heading free, while the left arm and the torso hold the layout's pose under JOINT_POSITION control.
    """
    if controller not in ARM_CONTROLLERS:
        raise ValueError(f"Unknown arm controller {controller!r}; accepted: {', '.join(ARM_CONTROLLERS)}")
    check_robot(robot)
    layout = humanoid_layout(robot)
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
    config["body_parts"] = {SPOON_ARM: dict(part, **({"gripper": gripper} if gripper else {}))}
    if layout is not None:
        config["type"] = SpoonArmController.name
        config["body_parts"][SPOON_ARM]["kp"] = [OSC_KP] * 5 + [FREE_HEADING_KP]
        config["body_parts"][SPOON_ARM]["uncouple_pos_ori"] = False
        for held_part in layout.held_qpos:
            held = load_part_controller_config(default_controller="JOINT_POSITION")
            held.update(kp=HELD_PART_KP, input_type="absolute", interpolation=None)
            config["body_parts"][held_part] = held
        config["composite_controller_specific_configs"] = {
            "held_qpos": {part: [float(v) for v in q] for part, q in layout.held_qpos.items()}
        }
    return config


class UntunedControllerWarning(UserWarning):
    """ScoopGranular was made with a controller config other than the ones its data, expert and devices were tuned
    for (load_scoop_controller_config): the same action moves the spoon differently."""


def untuned_controller_difference(config: Any, robot: str) -> str:
    """
    What makes ``config`` (a composite controller config, or a robosuite <= 1.4 arm part config) differ from the
    closest of load_scoop_controller_config's configs for ``robot``, in one sentence; "" when it is one of them.
    """
    tuned = {name: load_scoop_controller_config(name, robot) for name in _tuned_controllers(robot)}
    config = _plain(config)
    if not isinstance(config, dict):
        return f"controller_configs {config!r} is not a controller config dict"
    if "body_parts" in config:
        composite, part = config.get("type"), config["body_parts"].get(SPOON_ARM, {})
    else:  # robosuite <= 1.4: the arm's part alone, which robosuite puts in its BASIC composite
        composite, part = "BASIC", config
    name = part.get("type") if part.get("type") in tuned else ARM_CONTROLLERS[0]
    reference = _plain(tuned[name])
    differences = []
    if composite != reference["type"]:
        differences.append(f"composite type {composite} (tuned: {reference['type']})")
    reference_part = reference["body_parts"][SPOON_ARM]
    for key in sorted(set(part) & set(reference_part)):
        if not _same(part[key], reference_part[key]):
            differences.append(f"{SPOON_ARM} arm {key} {_short(part[key])} (tuned: {_short(reference_part[key])})")
    missing = sorted(set(reference_part) - set(part))
    if missing:
        differences.append(f"{SPOON_ARM} arm without {', '.join(missing)}")
    if not differences:
        return ""
    return (
        f"controller_configs differ from the controller ScoopGranular's demonstrations, expert and devices were tuned "
        f"for on {robot} (veragmil_suite.controllers.scoop_config.load_scoop_controller_config({name!r}, "
        f"robot={robot!r})): "
        f"{'; '.join(differences)}. The same action moves the spoon differently than in the recorded data"
    )


def _tuned_controllers(robot: str) -> tuple[str, ...]:
    return tuple(name for name in ARM_CONTROLLERS if name != "IK_POSE" or robot in IK_ROBOTS)


def _plain(value):
    """``value`` as JSON gives it back (datasets store configs as JSON: tuples become lists)."""
    try:
        return json.loads(json.dumps(value))
    except (TypeError, ValueError):
        return value


def _same(a, b) -> bool:
    if a == b:
        return True
    try:
        a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    except (TypeError, ValueError):
        return False
    return a.shape == b.shape and np.allclose(a, b, rtol=1e-9, atol=0)


def _short(value) -> str:
    if isinstance(value, list) and all(isinstance(v, (int, float)) for v in value):
        return "[" + ", ".join(f"{v:.4g}" for v in value) + "]"
    return f"{value:.4g}" if isinstance(value, float) else repr(value)
