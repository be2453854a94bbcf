"""Who produces a recording's actions, behind one interface: the scripted expert, or a person on a device (robosuite's
keyboard, SpaceMouse, DualSense or viewer, or our VR headset) through robosuite's own input-to-action path.
"""

from __future__ import annotations

import time
from typing import TYPE_CHECKING

import numpy as np

from veragmil_suite.devices.expert import ScriptedScooper
from veragmil_suite.devices.session import RobosuiteDevice, SessionDevice
from veragmil_suite.utils.cli.handler import UsageError

if TYPE_CHECKING:
    import argparse

    from robosuite.devices import Device

    from veragmil_suite.environments.scoop import ScoopGranular


class ScriptedOperator:
    """The scripted expert as an operator: never asks, never needs a display."""

    source = "scripted"

    def __init__(self, env, profile: str, seed: int):
        self.expert = ScriptedScooper(env, profile, seed=seed)
        self.name = f"scripted-{self.expert.profile.name}"
        self.command = None
        self.label = None

    def begin(self, seed: int | None = None) -> None:
        self.expert.reset(seed=seed)
        self.command = None

    def action(self, obs: dict) -> np.ndarray | None:
        """The action to execute; ``label`` is the one to record (they differ under injected noise)."""
        if self.expert.done:
            return None
        self.label = self.expert.act(obs)
        return self.expert.executed(self.label)

    def close(self) -> None:
        pass


class TeleopOperator:
    """A person on a teleoperation device (a SessionDevice, or one of robosuite's devices, which it wraps) as an
    operator."""

    source = "human"

    def __init__(self, env, device, name: str, arm: str = "right", goal_update_mode: str = "target"):
        self.env = env
        self.device = device if isinstance(device, SessionDevice) else RobosuiteDevice(device)
        self.name = name
        self.arm = arm
        self.goal_update_mode = goal_update_mode
        self.command = None
        self.label = None  # the action executed is the one recorded

    def begin(self, seed: int | None = None) -> None:
        self.command = None
        self.ended = False
        self.device.start_control()
        if self.device.clutched:
            # the episode starts at the operator's first squeeze; until then the robot stands still and nothing is
            # recorded or counted against the horizon
            self.device.show_status("squeeze the grip to start")
            while not self.device.engaged:
                if self.device.input2action() is None:  # keep, discard or reset before starting: an empty episode
                    self.command = self.device.episode_command or "reset"
                    self.ended = True
                    return
                time.sleep(self.env.control_timestep)
            self.device.show_status("")
        self.device.set_recording(True)

    def action(self, obs: dict) -> np.ndarray | None:
        if self.ended:
            return None
        # robosuite's devices take goal_update_mode; "target" is their default, which any device gives
        mode = {} if self.goal_update_mode == "target" else {"goal_update_mode": self.goal_update_mode}
        action_dict = self.device.input2action(**mode)
        if action_dict is None:
            self.command = self.device.episode_command or "reset"
            return None
        robot = self.env.robots[0]
        controller = robot.part_controllers[self.arm]
        key = f"{self.arm}_delta" if getattr(controller, "input_type", "delta") == "delta" else f"{self.arm}_abs"
        return robot.create_action_vector({self.arm: action_dict[key]})

    def wait_for_verdict(self) -> str | None:
        """After an episode ended by itself, the operator's keep or discard, on a device that asks for one (VR)."""
        if not self.device.asks_verdict:
            return None
        self.device.show_status("press keep or discard")
        self.device.start_control()
        while self.device.input2action() is not None:
            time.sleep(0.02)
        return self.device.episode_command

    def end(self) -> None:
        self.device.set_recording(False)

    def show_progress(self, text: str) -> None:
        """The collection's state on the device's status line, where it has one (VR)."""
        self.device.show_progress(text)

    def close(self, farewell: str | None = None) -> None:
        self.device.close_session(farewell)

    def connection_line(self) -> str | None:
        """The device's non-zero connection counters (VR: the server's, vr.server_options.COUNTERS), so that a
        session whose page reconnected or was dropped as silent says so after the fact."""
        counters = self.device.connection_counters()
        if counters is None:
            return None
        counts = [f"{name} {n}" for name, n in counters.items() if n]
        return "vr server: " + (", ".join(counts) or "no page connected")


def make_device(args: argparse.Namespace, env: ScoopGranular) -> Device:
    """The teleoperation device for ``--device``, built as robosuite's collect_human_demonstrations.py builds it
    (robosuite's own classes) or our VRDevice; UsageError when its hardware cannot be opened."""
    sensitivity = dict(pos_sensitivity=args.pos_sensitivity, rot_sensitivity=args.rot_sensitivity)
    if args.device == "keyboard":
        from robosuite.devices import Keyboard  # robosuite.devices imports pynput and hid: only when making a device

        return Keyboard(env=env, **sensitivity)
    if args.device in ("spacemouse", "dualsense"):
        name = {"spacemouse": "SpaceMouse", "dualsense": "DualSense"}[args.device]
        try:
            import robosuite.devices  # robosuite.devices imports pynput and hid: only when making a device

            device_class = getattr(robosuite.devices, name)  # absent when hidapi is missing
            extra = {"reverse_xy": args.reverse_xy} if args.device == "dualsense" else {}
            return device_class(env=env, **sensitivity, **extra)
        except (OSError, ImportError, AttributeError) as e:
            raise UsageError(f"--device {args.device}: no {name} found through hidapi ({e})") from None
    if args.device == "mjgui":
        from robosuite.devices.mjgui import MJGUI  # robosuite.devices imports pynput and hid: only when making a device

        return MJGUI(env=env, active_end_effector=args.arm)
    from veragmil_suite.devices import VRDevice, VRServerOptions  # the VR server imports aiohttp: only with --device vr

    return VRDevice(
        env,
        server=VRServerOptions(host=args.vr_host, port=args.vr_port),
        **sensitivity,
        allow_emulated_position=args.vr_allow_emulated,
        verbose=not args.quiet,
    )


def make_operator(args: argparse.Namespace, env: ScoopGranular) -> ScriptedOperator | TeleopOperator:
    """The operator for ``--device``: the scripted expert, or a person on a device (make_device)."""
    if args.device == "scripted":
        return ScriptedOperator(env, args.profile, args.seed)
    device = make_device(args, env)
    return TeleopOperator(env, device, args.operator or "", arm=args.arm, goal_update_mode=args.goal_update_mode)
