"""The operator's view: the environment's camera, rendered by a separate process and sent as JPEG frames.

A thread of this process copies the simulation's positions (``qpos`` and mocap poses) as soon as a control step
has finished, hands them to the renderer process (``render``: its own OpenGL context, MuJoCo and GIL) and
publishes the JPEG it returns, so a frame shows each step as early as it can: what the operator sees lags the
hand by the wait for the next control step, the step, the render and the transfer, never by a frame clock as
well. It checks a running step for completion every millisecond (``POLL_S``), from the moment the device
computes the step's action (``note_action``) or sees a step begun; between steps it sleeps, looking for a scene
moved without a step (a reset) every frame period. Frames come at most ``fps`` a second (a faster control rate
has steps skipped: each frame shows the newest one). An environment
without robosuite's step clock (``timestep``, ``cur_time``), or ``VRStreamOptions(sync_to_steps=False)``, is
sampled on an ``fps`` clock instead, and such a frame may show a step half done.

The renderer runs at a lower priority (nice 10): short of CPU, the stream drops frames before the simulation drops
real time. The teleoperation loop never waits for a frame. The model goes to the renderer once per model
(``mj_saveModel`` to a temporary file, ~10 ms): robosuite's hard reset builds a new one each episode, and the
renderer keeps its OpenGL context when the meshes and textures are unchanged.

Each frame carries a timing block (``vr_protocol.pack_frame``): the control step it shows, the pose message that
step's action came from, and when each stage happened, for ``benchmarks/bench_vr.py`` to attribute the latency.

Depth comes from the same render pass, in metres, colour-mapped (turbo, near red to far blue) and shown beside
the RGB image in the same JPEG: one decode and one texture on the headset.
"""

from __future__ import annotations

import json
import logging
import os
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import mujoco
import numpy as np

from veragmil_suite.devices.vr.protocol import PANELS_RGB, PANELS_RGB_DEPTH, pack_frame
from veragmil_suite.devices.vr.render import ENCODERS, receive, send
from veragmil_suite.utils.rendering import use_headless_rendering

LOG = logging.getLogger(__name__)

WORKER = Path(__file__).resolve().parent / "render.py"
RESTART_DELAY_S = 2.0
# a still scene (the simulation paused: before the first squeeze, between episodes) is sent again this often (s),
# without rendering it again, so that a page that connects or drops a frame still shows it
STILL_FRAME_REPEAT_S = 0.5
RENDER_NICENESS = 10  # the renderer yields the CPU to the simulation: the environment must keep real time
POLL_S = 0.001  # how often a running control step is checked for completion (s): the most a frame waits for it
# after the device computes an action, how long (s) the stream watches for its step to begin; a step seen begun is
# watched to its end whatever this is. Covers the loop's own work between input2action() and env.step()
EXPECT_STEP_S = 0.03


@dataclass(frozen=True)
class VRStreamOptions:
    """What a ``CameraStream`` sends to the headset: image size, frame rate, depth panel and JPEG encoding.

    Args:
        width, height (int): size of the RGB panel in pixels (the depth panel, when shown, doubles the width)
        fps (float): most frames per second
        depth (bool): show the colour-mapped depth panel beside the RGB one (the operator can toggle it)
        depth_range (tuple or None): metres from red (near) to blue (far) on the depth panel; None: what the camera
            sees in the first frame of each model (robust percentiles), so colours keep their meaning through an
            episode
        jpeg_quality (int): JPEG quality, 1-100
        encoder (str): JPEG encoder, "pillow" (measured 2-3x faster on these frames, benchmarks/bench_vr.py) or
            "opencv"
        sync_to_steps (bool): render each frame as soon as a control step finishes (the newest step, at most fps
            frames a second); False: sample the simulation on an fps clock, which adds up to a frame period of
            latency (benchmarks/bench_vr.py compares both)
    """

    width: int = 320
    height: int = 240
    fps: float = 30.0
    depth: bool = True
    depth_range: tuple[float, float] | None = None
    jpeg_quality: int = 80
    encoder: str = "pillow"
    sync_to_steps: bool = True


def step_progress(env: Any) -> tuple[int, bool] | None:
    """(control steps begun, whether the last one has finished) of a robosuite environment, from its step clock:
    ``step()`` counts ``timestep`` up before its physics and ``cur_time`` up after it. None for an environment
    without that clock."""
    steps, cur_time, dt = (getattr(env, name, None) for name in ("timestep", "cur_time", "control_timestep"))
    if steps is None or cur_time is None or not dt:
        return None
    return int(steps), round(cur_time / dt) == steps


def frame_decision(
    now: float,
    scene: tuple,
    complete: bool,
    shown: tuple | None,
    last_capture: float,
    min_interval: float,
    expecting: bool,
    idle_wait: float,
) -> tuple[bool, float]:
    """The stream's scheduling rule: (render now, seconds to wait before deciding again).

    A frame is due as soon as the scene (model, simulated time, steps, positions) differs from the one last
    ``shown`` and no control step is half done (``complete``), but no sooner than ``min_interval`` after the last
    capture. While a step runs or one is ``expecting`` to begin, the scene is checked again after ``POLL_S``;
    otherwise after ``idle_wait`` (the stream wakes earlier when the device computes an action).
    """
    if complete and scene != shown:
        wait = last_capture + min_interval - now
        return (True, 0.0) if wait <= 0 else (False, wait)
    if not complete or expecting:
        return False, POLL_S
    return False, idle_wait


def _positions_hash(state) -> int:
    """What the camera sees moves only with these (an MjData, or a copy of its arrays in a dict)."""
    get = state.get if isinstance(state, dict) else lambda name: getattr(state, name)
    return hash((get("qpos").tobytes(), get("mocap_pos").tobytes(), get("mocap_quat").tobytes()))


class CameraStream:
    """Renders one camera of a robosuite env after each control step (at most ``options.fps`` frames a second)
    and hands each frame to ``on_frame``.

    Args:
        env: the robosuite environment (its ``sim`` is read, never written)
        camera_name (str): the camera to stream ("overhead" in ScoopGranular, "agentview" in robosuite's tasks)
        options (VRStreamOptions or None): size, frame rate, depth panel and encoding; None: the defaults
        on_frame (callable): ``on_frame(frame: bytes)`` with a ``vr_protocol`` binary frame, from the stream thread
        active (callable): frames are made only while this returns True (someone is watching)
        keep_depth (bool): keep the last depth map in metres (``last_depth_m``), for inspection
    """

    def __init__(
        self,
        env,
        camera_name: str,
        options: VRStreamOptions | None = None,
        on_frame: Callable[[bytes], None] | None = None,
        active: Callable[[], bool] | None = None,
        keep_depth: bool = False,
    ):
        options = VRStreamOptions() if options is None else options
        if options.encoder not in ENCODERS:
            raise ValueError(f"encoder must be one of {ENCODERS}")
        if env.sim.model.camera_name2id(camera_name) < 0:
            raise ValueError(f"no camera {camera_name!r} in the environment")
        self.env = env
        self.camera_name = camera_name
        self.width, self.height = int(options.width), int(options.height)
        self.fps = float(options.fps)
        self.depth = bool(options.depth)  # what is shown now: the operator toggles it
        depth_range = options.depth_range
        self.depth_range = None if depth_range is None else (float(depth_range[0]), float(depth_range[1]))
        self.jpeg_quality = int(options.jpeg_quality)
        self.encoder = options.encoder
        self.sync_to_steps = bool(options.sync_to_steps)
        self.on_frame = on_frame
        self.active = active or (lambda: True)
        self.keep_depth = keep_depth
        self.last_depth_m: np.ndarray | None = None
        self.shown_depth_range: tuple[float, float] | None = None  # metres from red to blue on the depth panel
        self.frames = 0
        self._last_frame: tuple[bytes, float] | None = None  # the last frame sent and when
        self.errors = 0
        self.restarts = 0
        self.models_sent = 0
        self.context_builds = 0
        self.error: str | None = None
        self._render_ms = 0.0
        self._encode_ms = 0.0
        self._frame_ms = 0.0
        self._proc: subprocess.Popen | None = None
        self._model = None
        self._model_file = Path(tempfile.gettempdir()) / f"veragmil_vr_{os.getpid()}_{id(self)}.mjb"
        self._stop = threading.Event()
        self._wake = threading.Event()  # an action was computed (a step is about to run), or stop
        self._actions: dict[int, tuple[int | None, float | None, float]] = {}  # step -> its action's origin
        self._actions_lock = threading.Lock()
        self._thread: threading.Thread | None = None

    def start(self, timeout: float = 120.0) -> CameraStream:
        """Start the renderer process and the sampling thread; returns once the renderer has the model (a few
        seconds: the renderer uploads every texture into its OpenGL context)."""
        if self._thread is None:
            self._stop.clear()
            self._spawn()
            self._send_model(self.env.sim.model._model, timeout)
            self._thread = threading.Thread(target=self._run, name="vr-camera", daemon=True)
            self._thread.start()
        return self

    def stop(self) -> None:
        self._stop.set()
        self._wake.set()
        if self._thread is not None:
            self._thread.join(10.0)
            self._thread = None
        self._kill()
        self._model_file.unlink(missing_ok=True)

    def note_action(self, pose_seq: int | None, pose_received: float | None, action_time: float) -> None:
        """The device computed the action of the next control step from pose message ``pose_seq`` (received at
        ``pose_received``) at ``action_time`` (``time.monotonic()``): the frames of that step say so, and the
        stream watches for the step to finish."""
        progress = step_progress(self.env)
        if progress is not None:
            with self._actions_lock:
                self._actions[progress[0] + 1] = (pose_seq, pose_received, action_time)
                for step in [s for s in self._actions if s < progress[0] - 8]:
                    del self._actions[step]
        self._wake.set()

    def stats(self) -> dict:
        n = max(self.frames, 1)
        return dict(
            frames=self.frames,
            errors=self.errors,
            restarts=self.restarts,
            models_sent=self.models_sent,
            context_builds=self.context_builds,
            render_ms=self._render_ms / n,
            encode_ms=self._encode_ms / n,
            frame_ms=self._frame_ms / n,
        )

    def _spawn(self) -> None:
        config = dict(
            camera=self.camera_name,
            width=self.width,
            height=self.height,
            quality=self.jpeg_quality,
            encoder=self.encoder,
            depth_range=self.depth_range,
            nice=RENDER_NICENESS,
        )
        environ = dict(os.environ)
        use_headless_rendering(environ=environ)  # the renderer imports MuJoCo alone, without this package
        self._proc = subprocess.Popen(
            [sys.executable, str(WORKER), json.dumps(config)],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            env=environ,
        )
        self._model = None

    def _kill(self) -> None:
        proc, self._proc = self._proc, None
        if proc is None:
            return
        try:
            send(proc.stdin, ("stop",))
            proc.stdin.close()
            proc.wait(5.0)
        except (OSError, subprocess.TimeoutExpired, ValueError):
            proc.kill()
            proc.wait(5.0)
        finally:
            if proc.stdout is not None:
                proc.stdout.close()

    def _request(self, msg, timeout: float | None = None):
        """Send a request, wait for the reply; raises on a dead renderer or an error reply."""
        proc = self._proc
        if proc is None:
            raise RuntimeError("no renderer process")
        send(proc.stdin, msg)
        timer = threading.Timer(timeout, proc.kill) if timeout else None
        if timer is not None:
            timer.start()
        try:
            reply = receive(proc.stdout)
        finally:
            if timer is not None:
                timer.cancel()
        if reply is None:
            raise RuntimeError(f"the renderer process exited (code {proc.poll()})")
        if reply[0] == "error":
            raise RuntimeError(f"renderer: {reply[1]}")
        return reply

    def _send_model(self, model, timeout: float = 60.0) -> None:
        mujoco.mj_saveModel(model, str(self._model_file), None)
        _, info = self._request(("model", str(self._model_file)), timeout)
        self.context_builds = info["context_builds"]
        self.models_sent += 1
        self._model = model

    def _run(self) -> None:
        period = 1.0 / self.fps
        shown = None  # the scene of the last frame rendered
        last_capture = -float("inf")
        expect_until = 0.0
        while not self._stop.is_set():
            now = time.monotonic()
            if self._wake.is_set():
                self._wake.clear()
                if self.sync_to_steps:
                    expect_until = now + EXPECT_STEP_S
            if not self.active():
                shown = None  # whoever connects next gets a fresh frame
                self._wake.wait(period)
                continue
            wait = period
            try:
                if self._proc is None or self._proc.poll() is not None:
                    self._kill()
                    self._spawn()
                    self.restarts += 1
                observed = self._scene()
                if observed is None:  # no simulation (a hard reset is building the next one)
                    self._wake.wait(period)
                    continue
                sim, scene, complete = observed
                render, wait = frame_decision(
                    now, scene, complete, shown, last_capture, period, now < expect_until, period
                )
                if render:
                    captured = self._frame(sim)
                    if captured is not None:
                        shown, last_capture, expect_until = captured, now, 0.0
                        continue
                    wait = POLL_S  # a step began while the state was copied: copy it again once it is over
                elif scene == shown and self._last_frame is not None:
                    if now - self._last_frame[1] >= STILL_FRAME_REPEAT_S:
                        self._send(self._last_frame[0])  # nothing moved: the same frame again, not rendered again
            except Exception as e:  # a frame lost is better than a stream lost: restart the renderer, go on
                self.errors += 1
                self.error = f"{e.__class__.__name__}: {e}"
                if self.errors <= 3:
                    LOG.exception("VR camera frame failed")
                self._kill()
                if self._stop.wait(RESTART_DELAY_S):
                    break
                continue
            if wait > POLL_S:
                self._wake.wait(wait)  # an action computed meanwhile wakes the stream at once
            else:
                self._stop.wait(wait)

    def _scene(self) -> tuple[tuple, tuple, bool] | None:
        """((model, data), the scene's identity, whether it can be shown: with ``sync_to_steps``, no control step
        may be half done); None without a simulation. The identity is the model, the simulated time, the control
        steps begun and a hash of the positions: a reset moves everything without a step or a tick of the clock."""
        env = self.env
        sim = getattr(env, "sim", None)
        try:
            model, data = sim.model._model, sim.data._data
        except AttributeError:  # no simulation, or one a hard reset freed
            return None
        progress = step_progress(env)
        scene = (id(model), float(data.time), None if progress is None else progress[0], _positions_hash(data))
        return (model, data), scene, progress is None or progress[1] or not self.sync_to_steps

    def _frame(self, sim: tuple) -> tuple | None:
        """Render and publish the state of sim (model, data), and return its scene (as ``_scene``: the simulation
        may have moved on since that was read); None when a control step began while the state was being copied
        (with ``sync_to_steps``), and nothing was rendered."""
        env = self.env
        model, data = sim
        if model is not self._model:
            self._send_model(model)
        before = step_progress(env)
        captured = time.monotonic()
        request = dict(
            qpos=np.array(data.qpos),
            mocap_pos=np.array(data.mocap_pos),
            mocap_quat=np.array(data.mocap_quat),
            depth=self.depth,
            keep_depth=self.keep_depth,
        )
        sim_time = float(data.time)
        after = step_progress(env)
        if self.sync_to_steps and before is not None and (after != before or not before[1]):
            return None  # timestep counts up before any physics: unchanged, the copy is of one finished step
        scene = (id(model), sim_time, None if before is None else before[0], _positions_hash(request))
        timing = dict(captured=captured)
        if before is not None:
            with self._actions_lock:
                pose_seq, pose_received, action_time = self._actions.get(before[0], (None, None, None))
            timing.update(
                step=before[0], mid_step=not before[1], pose_seq=pose_seq, pose_received=pose_received,
                action=action_time,
            )  # fmt: skip
        t0 = time.perf_counter()
        _, result = self._request(("frame", request), timeout=30.0)
        self._frame_ms += 1000 * (time.perf_counter() - t0)
        self._render_ms += result["render_ms"]
        self._encode_ms += result["encode_ms"]
        panels = PANELS_RGB_DEPTH if request["depth"] else PANELS_RGB
        self.frames += 1
        if result["depth_m"] is not None:
            self.last_depth_m = result["depth_m"]
        self.shown_depth_range = result["depth_range"]
        timing.update(render_start=result["render_start"], rendered=result["rendered"], encoded=result["encoded"])
        timing["published"] = time.monotonic()
        frame = pack_frame(result["jpeg"], self.frames, sim_time, result["width"], result["height"], panels, timing)
        self._send(frame)
        return scene

    def _send(self, frame: bytes) -> None:
        self._last_frame = (frame, time.monotonic())
        if self.on_frame is not None:
            self.on_frame(frame)
