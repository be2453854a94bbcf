"""VRDevice: teleoperation from a Meta Quest (or any WebXR headset) through its browser, as a robosuite Device.

The device starts a server (``vr_server``) that serves the WebXR page and receives the headset's and controllers'
poses over a WebSocket, and a camera stream (``vr_stream``) that sends the simulator's view back to the headset.
Each control step, ``get_controller_state()`` turns the newest filtered hand pose into an end-effector target
(``vr_clutch``) and returns the delta from where the arm's OSC controller will start, in the form robosuite's
``Device.input2action()`` expects; ``_postprocess_device_outputs`` scales it by the controller's own output
limits. A robosuite teleoperation loop therefore drives the arm unchanged:

    device = VRDevice(env, camera_name="overhead")
    device.start_control()
    while True:
        action_dict = device.input2action()
        if action_dict is None:                  # keep / discard / reset pressed in VR
            command = device.episode_command     # "keep", "discard" or "reset"
            break
        env.step(robot.create_action_vector({"right": action_dict["right_delta"], ...}))

Episode hooks for collection scripts: ``episode_command`` (what ended the episode, None while it runs),
``request_episode_end(command)`` (the same from a keyboard or a script), ``on_episode_command`` (a callback), and
``recording`` / ``status_message`` (shown on the operator's status line). Nothing here ends an episode by itself
when the headset disconnects: the robot holds still and the operator reconnects.

``input2action(mirror_actions=True)`` is not for VR: the map already follows the camera (recenter instead).
"""

from __future__ import annotations

import collections
import threading
import time
from collections.abc import Callable

import numpy as np
from robosuite.controllers.parts.arm.osc import OperationalSpaceController
from robosuite.devices import Device

from veragmil_suite.devices.session import SessionDevice
from veragmil_suite.devices.vr.clutch import Clutch, Pose
from veragmil_suite.devices.vr.controls import DEFAULT_BINDINGS, ButtonEvents
from veragmil_suite.devices.vr.device_status import DeviceStatusMixin
from veragmil_suite.devices.vr.filters import PoseFilter
from veragmil_suite.devices.vr.frames import camera_heading, mat_to_quat, mat_to_rotvec, quat_to_mat
from veragmil_suite.devices.vr.protocol import PoseMessage
from veragmil_suite.devices.vr.server import VRServer
from veragmil_suite.devices.vr.server_options import VRServerOptions
from veragmil_suite.devices.vr.stream import CameraStream, VRStreamOptions

EPISODE_COMMANDS = ("keep", "discard", "reset")
SCALE_STEP = 1.25
SCALE_LIMITS = (0.05, 5.0)


class VRDevice(SessionDevice, DeviceStatusMixin, Device):
    """A robosuite Device driven by a WebXR headset's controller (see the module docstring).

    Args:
        env (RobotEnv): the environment whose arm is driven (OSC_POSE arm controller)
        server (VRServerOptions or None): address (``port=0``: any free one, see ``url``), pairing token, TLS
            and timeouts of the page's server; None: its defaults (127.0.0.1:8765, for USB with ``adb reverse``)
        stream (VRStreamOptions or None): size, frame rate, depth panel and JPEG encoding of the camera stream;
            None: its defaults (320x240 at 30 frames/s, with depth)
        camera_name (str or None): camera streamed to the headset, whose heading the hand's motions follow; None
            picks "overhead", then "agentview"
        pos_sensitivity (float): end-effector metres per hand metre
        rot_sensitivity (float): end-effector radians per hand radian
        precision_factor (float): translation scale multiplier in precision mode
        mode (str): "relative" (clutch re-anchors at every squeeze) or "absolute" (anchors kept)
        hand (str): "right" or "left", the controller that drives the arm
        command_hz (float): most pose messages per second the page sends (the paper: 100)
        stale_timeout (float): seconds without a message after which the arm holds and the clutch releases
        max_linear_speed, max_angular_speed (float): velocity clamp on the commanded pose (m/s, rad/s)
        squeeze_threshold (float): squeeze value that engages
        allow_emulated_position (bool): drive with controller positions the runtime only estimates (WebXR's
            emulatedPosition: the controller left the cameras' view; emulators mark every pose so); off by
            default, such poses release the clutch
        filter_params (dict): keyword arguments of ``vr_filters.PoseFilter``
        on_episode_command (callable): called with "keep", "discard" or "reset" when the operator ends an episode
        verbose (bool): print the controls and the address to open
    """

    def __init__(
        self,
        env,
        server: VRServerOptions | None = None,
        stream: VRStreamOptions | None = None,
        camera_name: str | None = None,
        pos_sensitivity: float = 1.0,
        rot_sensitivity: float = 1.0,
        precision_factor: float = 0.25,
        mode: str = "relative",
        hand: str = "right",
        command_hz: float = 100.0,
        stale_timeout: float = 0.2,
        max_linear_speed: float = 0.5,
        max_angular_speed: float = 3.0,
        squeeze_threshold: float = 0.5,
        allow_emulated_position: bool = False,
        filter_params: dict | None = None,
        on_episode_command: Callable[[str], None] | None = None,
        verbose: bool = True,
    ):
        super().__init__(env)
        if hand not in ("right", "left"):
            raise ValueError("hand must be 'right' or 'left'")
        for robot in env.robots:
            for arm in robot.arms:
                if not isinstance(robot.part_controllers[arm], OperationalSpaceController):
                    raise ValueError(
                        f"VRDevice drives OSC_POSE arm controllers; {arm} arm of {robot.name} has "
                        f"{robot.part_controllers[arm].name}"
                    )
        self.hand = hand
        self.pos_sensitivity = pos_sensitivity
        self.rot_sensitivity = rot_sensitivity
        self.stale_timeout = stale_timeout
        self.squeeze_threshold = squeeze_threshold
        self.allow_emulated_position = allow_emulated_position
        self.on_episode_command = on_episode_command
        self.camera_name = camera_name or self._default_camera(env)
        self.recording = False
        self.status_message = ""
        self.progress = ""  # the collection's state, set by the recorder: episode, kept and discarded counts, file
        self.episode_command: str | None = None
        self.episodes = 0
        self.pose_age: float | None = None  # age of the newest pose at the last control step (s)

        self._clutch = Clutch(
            pos_scale=pos_sensitivity,
            rot_scale=rot_sensitivity,
            precision_factor=precision_factor,
            mode=mode,
            max_linear_speed=max_linear_speed,
            max_angular_speed=max_angular_speed,
        )
        self._filter = PoseFilter(**(filter_params or {}))
        self._buttons = ButtonEvents(DEFAULT_BINDINGS, main_hand=hand)
        self._lock = threading.Lock()
        self._events: collections.deque[str] = collections.deque(maxlen=64)
        self._ctrl: Pose | None = None
        self._squeeze = 0.0
        self._trigger = 0.0
        self._head_q: np.ndarray | None = None
        self._visible = False
        self._recv_time: float | None = None
        self._seq: int | None = None  # seq of the newest pose message (this connection)
        self._connected = False
        self._handle_s = 0.0  # seconds spent handling pose messages (server thread)
        self._handled = 0
        self._pose_ages: collections.deque[float] = collections.deque(maxlen=2000)
        self._last_status = 0.0
        self._recenters = 0
        self._stale = True
        self._reset_state = 0
        self._enabled = False

        stream = VRStreamOptions() if stream is None else stream
        self.server = VRServer(
            server,
            on_pose=self._on_pose,
            on_connect=self._on_connect,
            on_disconnect=self._on_disconnect,
            config=dict(
                send_hz=command_hz,
                hand=hand,
                camera=self.camera_name,
                stream=dict(width=stream.width, height=stream.height, fps=stream.fps),
            ),
        )
        self.stream = CameraStream(
            env,
            self.camera_name,
            stream,
            on_frame=self.server.publish_frame,
            active=lambda: self.server.connected,
        )
        self._reset_internal_state()
        self.server.start()
        self.stream.start()
        if verbose:
            self._display_controls()
            self._display_address()

    @staticmethod
    def _display_controls():
        """Method to pretty print controls."""

        def print_command(char: str, info: str) -> None:
            char += " " * (30 - len(char))
            print(f"{char}\t{info}")

        print("")
        print_command("Control (right hand drives)", "Command")
        print_command("right squeeze (hold)", "engage: the hand drives the end-effector")
        print_command("right trigger", "gripper (no effect on a spoon)")
        print_command("right A (hold 0.5 s)", "keep the episode")
        print_command("right B (hold 0.5 s)", "discard the episode")
        print_command("right stick press", "toggle precision (finer translation)")
        print_command("right stick up/down", "translation scale up/down")
        print_command("left X (hold 0.5 s)", "reset the environment")
        print_command("left Y", "recenter: your forward becomes the camera's")
        print_command("left stick press", "toggle relative/absolute mode")
        print_command("left trigger", "show/hide the depth panel")
        print("")

    def _display_address(self) -> None:
        port = self.server.port
        if self.server.lan_urls():
            print(f"VR page on this machine: {self.server.url}")
        else:
            print(f"VR page: {self.server.url}  (Quest over USB: adb reverse tcp:{port} tcp:{port})")
        for url in self.server.lan_urls():
            print(f"VR page on this network: {url}")
        if self.server.token:
            print(f"Pairing token: {self.server.token}")
        if self.server.fingerprint:
            print(f"Certificate SHA-256: {self.server.fingerprint}")
        print("")

    def _reset_internal_state(self):
        """Resets internal state of the device, except for the reset signal."""
        super()._reset_internal_state()
        self._clutch.reset()
        self._target: Pose | None = None

    def start_control(self) -> None:
        """Begin an episode: hold the arm where it is until the operator squeezes again."""
        self._reset_internal_state()
        self._reset_state = 0
        self._enabled = True
        self.episode_command = None
        self._clutch.set_camera_yaw(self._camera_yaw())
        self._publish_status(force=True)

    def get_controller_state(self) -> dict:
        """The newest command: dpos (metres) and raw_drotation (radians, robosuite's device convention) from
        the arm controller's reference pose to the clutch's target, grasp, and reset."""
        now = time.monotonic()
        robot = self.env.robots[self.active_robot]
        controller = robot.part_controllers[self.active_arm]
        with self._lock:
            ctrl, squeeze, trigger = self._ctrl, self._squeeze, self._trigger
            head_q, visible, recv_time, connected = self._head_q, self._visible, self._recv_time, self._connected
            seq = self._seq
            discontinuities = self._filter.discontinuities
            events = list(self._events)
            self._events.clear()
        for event in events:
            self._apply_event(event, head_q)
        self.pose_age = None if recv_time is None else now - recv_time
        # the socket's own state, read now: the disconnect callback reaches this thread a moment after the close
        connected = connected and self.server.connected
        fresh = connected and visible and self.pose_age is not None and self.pose_age <= self.stale_timeout
        self._stale = not fresh
        if fresh:
            with self._lock:  # status() may read the ages from the server thread
                self._pose_ages.append(now - recv_time)
        ee = self._ee_pose(controller)
        self._target = self._clutch.update(
            squeeze=self._enabled and squeeze >= self.squeeze_threshold,
            available=fresh,
            ctrl=ctrl,
            ee=ee,
            dt=float(self.env.control_timestep),
            discontinuities=discontinuities,
        )
        if fresh:
            self.grasp_states[self.active_robot][self.active_arm_index] = trigger >= 0.5
        dpos, drot, rot_frame = self._delta_to_target(controller, self._target)
        self._publish_status()
        # the frames showing the coming step carry the pose it follows, for latency measurements
        self.stream.note_action(seq if fresh else None, recv_time if fresh else None, now)
        return dict(
            dpos=dpos,
            rotation=rot_frame,
            # input2action reorders raw_drotation as [1, 0, 2] and negates z (robosuite's SpaceMouse axes)
            raw_drotation=np.array([drot[1], drot[0], -drot[2]]),
            grasp=int(self.grasp),
            reset=self._reset_state,
            base_mode=int(self.base_mode),
        )

    def _postprocess_device_outputs(self, dpos, drotation):
        """Metres and radians to the controller's normalised action: the inverse of its scale_action."""
        controller = self.env.robots[self.active_robot].part_controllers[self.active_arm]
        delta = np.concatenate([dpos, drotation])
        in_lo, in_hi = np.asarray(controller.input_min, float), np.asarray(controller.input_max, float)
        out_lo, out_hi = np.asarray(controller.output_min, float), np.asarray(controller.output_max, float)
        norm = (delta - (out_hi + out_lo) / 2) * ((in_hi - in_lo) / (out_hi - out_lo)) + (in_hi + in_lo) / 2
        # past the controller's per-step limit, shrink translation and rotation as vectors: clipping each axis
        # alone would turn the motion off its direction
        for part in (slice(0, 3), slice(3, 6)):
            peak = float(np.max(np.abs(norm[part])))
            if peak > 1.0:
                norm[part] /= peak
        norm = np.clip(norm, np.maximum(in_lo, -1.0), np.minimum(in_hi, 1.0))
        return norm[:3], norm[3:]

    # the recording session's hooks (SessionDevice): a clutch, a status line, a verdict button, a server
    clutched = True

    def show_status(self, text: str) -> None:
        self.status_message = text

    def set_recording(self, on: bool) -> None:
        self.recording = on

    def show_progress(self, text: str) -> None:
        self.progress = text

    @property
    def asks_verdict(self) -> bool:
        return True

    def connection_counters(self) -> dict[str, int]:
        return self.stats()["server"]

    def close_session(self, farewell: str | None = None) -> None:
        self.close(farewell=farewell)

    def request_episode_end(self, command: str) -> None:
        """End the episode as the VR buttons do: ``input2action()`` returns None from the next call on."""
        if command not in EPISODE_COMMANDS:
            raise ValueError(f"command must be one of {EPISODE_COMMANDS}")
        if self.episode_command is not None:
            return
        self.episode_command = command
        self.episodes += 1
        self._reset_state = 1
        self._enabled = False
        self._publish_status(force=True)
        if self.on_episode_command is not None:
            self.on_episode_command(command)

    @property
    def engaged(self) -> bool:
        """Whether the operator's hand drives the arm right now."""
        return self._clutch.engaged

    @property
    def target_pose(self) -> Pose | None:
        """The commanded end-effector pose (world frame) of the last control step."""
        return None if self._target is None else self._target.copy()

    @property
    def messages_handled(self) -> int:
        """Pose messages handed to the device so far (all connections)."""
        return self._handled

    @property
    def clutch(self) -> Clutch:
        return self._clutch

    @property
    def url(self) -> str:
        return self.server.url

    def stats(self) -> dict:
        """Server counters, stream timings, pose-handling time and pose age at action."""
        with self._lock:
            ages = np.array(self._pose_ages) * 1000.0 if self._pose_ages else np.zeros(1)
        return dict(
            server=self.server.stats(),
            stream=self.stream.stats(),
            handled=self._handled,
            handle_us=1e6 * self._handle_s / max(self._handled, 1),
            pose_age_ms_mean=float(ages.mean()),
            pose_age_ms_p95=float(np.percentile(ages, 95)),
            engage_count=self._clutch.engage_count,
            forced_releases=self._clutch.forced_releases,
            discontinuities=self._filter.discontinuities,
        )

    def close(self, farewell: str | None = None) -> None:
        """Stop streaming and serving (the port is free again). ``farewell`` (for example "12 demos saved to
        FILE") is shown on the page as the session's last word, and the page stops reconnecting."""
        self.stream.stop()
        self.server.stop(farewell)

    def __enter__(self) -> VRDevice:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def _on_connect(self, connection: int) -> None:
        with self._lock:
            self._filter.reset()
            self._buttons.reset()
            self._ctrl = None
            self._recv_time = None
            self._seq = None
            self._connected = True
        self._publish_status(force=True)

    def _on_disconnect(self, connection: int) -> None:
        with self._lock:
            self._connected = False

    def _on_pose(self, msg: PoseMessage, recv_time: float) -> None:
        t0 = time.perf_counter()
        t = msg.t / 1000.0
        ctrl = msg.right if self.hand == "right" else msg.left
        with self._lock:
            tracked = ctrl is not None and ctrl.pose is not None and (self.allow_emulated_position or not ctrl.emulated)
            if tracked and msg.visible:
                p, q, _ = self._filter(ctrl.pose.p, ctrl.pose.q, t)
                self._ctrl = Pose(p, q)
            else:
                self._filter.reset()  # tracking lost: start afresh when it is back (the clutch re-anchors)
                self._ctrl = None
            self._squeeze = ctrl.squeeze if ctrl is not None else 0.0
            self._trigger = ctrl.trigger if ctrl is not None else 0.0
            self._head_q = None if msg.head is None else msg.head.q
            self._visible = msg.visible
            self._recv_time = recv_time
            self._seq = msg.seq
            self._events.extend(self._buttons.update({"left": msg.left, "right": msg.right}, t))
            self._handled += 1
            self._handle_s += time.perf_counter() - t0

    @staticmethod
    def _default_camera(env) -> str:
        names = [env.sim.model.camera_id2name(i) for i in range(env.sim.model.ncam)]
        for name in ("overhead", "agentview"):
            if name in names:
                return name
        if not names:
            raise ValueError("the environment has no camera to stream")
        return names[0]

    def _camera_yaw(self) -> float:
        cam_id = self.env.sim.model.camera_name2id(self.camera_name)
        return camera_heading(self.env.sim.data.cam_xmat[cam_id])

    def _ee_pose(self, controller) -> Pose:
        site = self.env.sim.model.site_name2id(controller.ref_name)
        return Pose(
            np.array(self.env.sim.data.site_xpos[site]),
            mat_to_quat(np.array(self.env.sim.data.site_xmat[site]).reshape(3, 3)),
        )

    def _delta_to_target(self, controller, target: Pose) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Translation and rotation vector from the controller's reference pose to target, in the controller's
        input frame (its robot base, or the world), and the target's rotation in that frame."""
        if controller.input_ref_frame == "base":
            frame_p, frame_r = np.asarray(controller.origin_pos, float), np.asarray(controller.origin_ori, float)
        else:
            frame_p, frame_r = np.zeros(3), np.eye(3)
        goal_p = frame_r.T @ (target.p - frame_p)
        goal_r = frame_r.T @ quat_to_mat(target.q)
        mode = getattr(controller, "_goal_update_mode", "achieved")
        if mode == "desired" and controller.goal_pos is not None and controller.goal_ori is not None:
            ref_p, ref_r = np.asarray(controller.goal_pos, float), np.asarray(controller.goal_ori, float)
        else:
            ee = self._ee_pose(controller)
            ref_p, ref_r = frame_r.T @ (ee.p - frame_p), frame_r.T @ quat_to_mat(ee.q)
        return goal_p - ref_p, mat_to_rotvec(goal_r @ ref_r.T), goal_r

    def _apply_event(self, event: str, head_q: np.ndarray | None) -> None:
        if event in EPISODE_COMMANDS:
            if self._enabled:
                self.request_episode_end(event)
        elif event == "recenter":
            if head_q is not None:
                self._clutch.recenter(head_q)
                self._recenters += 1
        elif event == "precision":
            self._clutch.toggle_precision()
        elif event == "mode":
            self._clutch.toggle_mode()
        elif event in ("scale_up", "scale_down"):
            factor = SCALE_STEP if event == "scale_up" else 1.0 / SCALE_STEP
            self._clutch.set_pos_scale(float(np.clip(self._clutch.pos_scale * factor, *SCALE_LIMITS)))
        elif event == "depth":
            self.stream.depth = not self.stream.depth
        self._publish_status(force=True)
