"""Loops and measurements for the VR tests: robosuite's teleoperation loop, in real time or in step with a
scripted client (``veragmil_suite.devices.vr.client``)."""

from __future__ import annotations

import time
from collections.abc import Callable

from veragmil_suite.devices.vr.client import HAND, IDENTITY, Client, controller, pose_message  # noqa: F401


def make_lift_env():
    """robosuite's Lift with XArm7 at 20 Hz, rendering offscreen for the stream: a cheap arm to teleoperate."""
    import robosuite

    env = robosuite.make(
        "Lift",
        robots="XArm7",
        has_renderer=False,
        has_offscreen_renderer=True,
        use_camera_obs=False,
        control_freq=20,
        ignore_done=True,
    )
    env.reset()
    return env


def env_action(env, device, action_dict: dict):
    """The env.step() vector from an input2action() dict, as robosuite's collect_human_demonstrations does."""
    robot = env.robots[device.active_robot]
    arm_actions = {}
    for arm in robot.arms:
        kind = robot.part_controllers[arm].input_type
        arm_actions[arm] = action_dict[f"{arm}_delta" if kind == "delta" else f"{arm}_abs"]
        if robot.gripper[arm].dof > 0:
            arm_actions[f"{arm}_gripper"] = action_dict[f"{arm}_gripper"]
    return robot.create_action_vector(arm_actions)


def eef_pose(env, device):
    """World position and rotation matrix of the site the arm controller drives."""
    arm_controller = env.robots[device.active_robot].part_controllers[device.active_arm]
    site = env.sim.model.site_name2id(arm_controller.ref_name)
    return env.sim.data.site_xpos[site].copy(), env.sim.data.site_xmat[site].reshape(3, 3).copy()


def lockstep(env, device, client, script: Callable[[float], dict | None], duration: float, rate: float = 90.0,
             extra: Callable[[], None] | None = None):  # fmt: skip
    """Replay script(t) (kwargs of ``pose_message``, t in simulated seconds) in step with the simulation: before
    each control step, the messages due by then are sent and handled. Independent of the machine's load: every
    step sees exactly the hand poses of its time. ``extra()`` runs after each step. Returns the per-step log."""
    period = env.control_timestep
    log = []
    sent = 0
    k = 0
    target = device.messages_handled
    t_base = client.last_t_ms + 1000.0 / rate  # the page's clock never goes back
    while k * period <= duration:
        t_step = k * period
        while sent / rate <= t_step:
            kwargs = script(sent / rate)
            if kwargs is not None:
                client.send_pose(t_ms=t_base + 1000.0 * sent / rate, **kwargs)
                target += 1
            sent += 1
        deadline = time.monotonic() + 5.0
        while device.messages_handled < target and time.monotonic() < deadline:
            time.sleep(0.001)
        action = device.input2action()
        if action is None:
            log.append(dict(t=t_step, engaged=device.engaged, p=None, r=None, action=None))
            break
        env.step(env_action(env, device, action))
        p, r = eef_pose(env, device)
        log.append(dict(t=t_step, engaged=device.engaged, p=p, r=r, action=action))
        if extra is not None:
            extra()
        k += 1
    return log


def run_loop(env, device, until: Callable[[], bool], max_seconds: float = 30.0, realtime: bool = True,
             extra: Callable[[], None] | None = None):  # fmt: skip
    """robosuite's teleoperation loop at the env's control rate (real time): records, per step, the wall time,
    whether the clutch is engaged, the end-effector pose and the action; stops when input2action() returns None,
    until() is true or max_seconds passed. ``extra()`` runs after each step."""
    period = env.control_timestep
    log = []
    start = time.monotonic()
    k = 0
    while time.monotonic() - start < max_seconds and not until():
        action = device.input2action()
        if action is None:
            break
        env.step(env_action(env, device, action))
        p, r = eef_pose(env, device)
        log.append(dict(t=time.monotonic(), engaged=device.engaged, p=p, r=r, action=action))
        if extra is not None:
            extra()
        k += 1
        if realtime:
            delay = start + k * period - time.monotonic()
            if delay > 0:
                time.sleep(delay)
    return log
