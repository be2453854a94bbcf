"""The operator's view: the environment's camera, rendered by a separate process and sent as JPEG frames.

A thread of this process samples the simulation's positions (``qpos`` and mocap poses) up to ``fps`` times a
second, hands them to the renderer process (``vr_render``: its own OpenGL context, MuJoCo and GIL) and publishes
the JPEG it returns. The renderer runs at a lower priority (nice 10): short of CPU, the stream drops frames before
the simulation drops real time. The teleoperation loop never waits for a frame and a frame never waits for a step;
a frame may mix two consecutive physics substeps (a few milliseconds apart), which no operator can see. The model
goes to the renderer once per model (``mj_saveModel`` to a temporary file, ~10 ms): robosuite's hard reset builds
a new one each episode, and the renderer keeps its OpenGL context when the meshes and textures are unchanged.

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

import numpy as np

from veragmil_suite.devices.vr_protocol import PANELS_RGB, PANELS_RGB_DEPTH, pack_frame
from veragmil_suite.devices.vr_render import ENCODERS, receive, send
from veragmil_suite.rendering import use_headless_rendering

LOG = logging.getLogger(__name__)

WORKER = Path(__file__).resolve().parent / "vr_render.py"
RESTART_DELAY_S = 2.0
# a still scene (the simulation paused: before the first squeeze, between episodes) is sent again this often (s),
# without rendering it again, so that a page that connects or drops a frame still shows it
STILL_FRAME_REPEAT_S = 0.5
RENDER_NICENESS = 10  # the renderer yields the CPU to the simulation: the environment must keep real time


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
        encoder (str): JPEG encoder, "pillow" (measured 2-3x faster on these frames, scripts/bench_vr.py) or
            "opencv"
    """

    width: int = 320
    height: int = 240
    fps: float = 30.0
    depth: bool = True
    depth_range: tuple[float, float] | None = None
    jpeg_quality: int = 80
    encoder: str = "pillow"


class CameraStream:
    """Renders one camera of a robosuite env at up to ``options.fps`` and hands each frame to ``on_frame``.

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
        self._thread: threading.Thread | None = None

    # ------------------------------------------------------------------ lifecycle
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
        if self._thread is not None:
            self._thread.join(10.0)
            self._thread = None
        self._kill()
        self._model_file.unlink(missing_ok=True)

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

    # ------------------------------------------------------------------ renderer process
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
        import mujoco

        mujoco.mj_saveModel(model, str(self._model_file), None)
        _, info = self._request(("model", str(self._model_file)), timeout)
        self.context_builds = info["context_builds"]
        self.models_sent += 1
        self._model = model

    # ------------------------------------------------------------------ sampling thread
    def _run(self) -> None:
        period = 1.0 / self.fps
        next_t = time.monotonic()
        last_sim_time = None
        while not self._stop.is_set():
            delay = next_t - time.monotonic()
            if delay > 0 and self._stop.wait(delay):
                break
            next_t = max(next_t + period, time.monotonic())
            if not self.active():
                last_sim_time = None
                continue
            try:
                if self._proc is None or self._proc.poll() is not None:
                    self._kill()
                    self._spawn()
                    self.restarts += 1
                last_sim_time = self._frame(last_sim_time)
            except Exception as e:  # a frame lost is better than a stream lost: restart the renderer, go on
                self.errors += 1
                self.error = f"{e.__class__.__name__}: {e}"
                if self.errors <= 3:
                    LOG.exception("VR camera frame failed")
                self._kill()
                if self._stop.wait(RESTART_DELAY_S):
                    break

    def _frame(self, last_sim_time: float | None) -> float | None:
        sim = getattr(self.env, "sim", None)
        if sim is None:
            return last_sim_time
        model, data = sim.model._model, sim.data._data
        if float(data.time) == last_sim_time and model is self._model:
            # nothing moved since the last frame: no new render, but the same frame again now and then
            if self._last_frame is not None and time.monotonic() - self._last_frame[1] >= STILL_FRAME_REPEAT_S:
                self._send(self._last_frame[0])
            return last_sim_time
        if model is not self._model:
            self._send_model(model)
        sim_time = float(data.time)
        request = dict(
            qpos=np.array(data.qpos),
            mocap_pos=np.array(data.mocap_pos),
            mocap_quat=np.array(data.mocap_quat),
            depth=self.depth,
            keep_depth=self.keep_depth,
        )
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
        self._send(pack_frame(result["jpeg"], self.frames, sim_time, result["width"], result["height"], panels))
        return sim_time

    def _send(self, frame: bytes) -> None:
        self._last_frame = (frame, time.monotonic())
        if self.on_frame is not None:
            self.on_frame(frame)
