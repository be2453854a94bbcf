"""The camera renderer of the VR stream, run as its own process (``python render.py '<json config>'``).

Why a process and not a thread: MuJoCo keeps its OpenGL function table in process-wide globals and reloads it
whenever any rendering context is made, and robosuite makes one at every hard reset (every episode) on the main
thread. A thread rendering at that moment read a reversed depth buffer, or worse. A process of its own has its
own table, its own GIL, and software rendering (osmesa) cannot slow the teleoperation loop down.

The process imports only MuJoCo, numpy and an image codec (not robosuite, not this package), so this file runs
directly as a script; its parent (``vr_stream``) chooses its OpenGL platform in its environment
(``veragmil_suite.utils.rendering``: OSMesa unless MUJOCO_GL says otherwise). Messages are pickled objects framed by a
4-byte little-endian length, on stdin (requests) and stdout (replies), between this process and its parent only:

    ("model", path)     load the model saved at path (``mj_saveModel``); reply ("model_ok", info)
    ("frame", request)  render qpos / mocap poses; reply ("frame", result: the JPEG, its size, and when rendering
                        started and ended and encoding ended, in time.monotonic() seconds)
    ("stop",)           exit
"""

from __future__ import annotations

import copy
import io
import json
import os
import pickle
import struct
import sys
import time
from typing import IO, Any

import cv2
import mujoco
import numpy as np
from PIL import Image

ENCODERS = ("pillow", "opencv")
_LEN = struct.Struct("<I")


def encode_jpeg(rgb: np.ndarray, quality: int = 80, encoder: str = "pillow") -> bytes:
    """JPEG bytes of an (H, W, 3) uint8 RGB image."""
    if encoder == "opencv":
        ok, buf = cv2.imencode(".jpg", np.ascontiguousarray(rgb[:, :, ::-1]), [cv2.IMWRITE_JPEG_QUALITY, int(quality)])
        if not ok:
            raise RuntimeError("OpenCV could not encode the frame")
        return buf.tobytes()
    if encoder == "pillow":
        out = io.BytesIO()
        Image.fromarray(np.ascontiguousarray(rgb)).save(out, format="JPEG", quality=int(quality))
        return out.getvalue()
    raise ValueError(f"encoder must be one of {ENCODERS}")


_DEPTH_LUT: np.ndarray | None = None


def depth_colormap(depth_m: np.ndarray, near: float, far: float, out: np.ndarray | None = None) -> np.ndarray:
    """(H, W) metres -> (H, W, 3) uint8: turbo from red (near) to blue (far) in 256 equal bins; from far on,
    black. Written into ``out`` when given (the depth half of the streamed image: no copy to join them)."""
    idx = ((depth_m - near) * (256.0 / (far - near))).clip(0, 256).astype(np.intp)
    return np.take(_depth_lut(), idx, axis=0, out=out, mode="clip")


def _depth_lut() -> np.ndarray:
    global _DEPTH_LUT
    if _DEPTH_LUT is None:
        from matplotlib import colormaps  # heavy: matplotlib, only for the depth colormap

        lut = (colormaps["turbo"](np.linspace(1.0, 0.0, 256))[:, :3] * 255).astype(np.uint8)
        _DEPTH_LUT = np.concatenate([lut, np.zeros((1, 3), np.uint8)])  # entry 256: beyond far
    return _DEPTH_LUT


def auto_depth_range(depth_m: np.ndarray, far_clip: float) -> tuple[float, float]:
    """The depths a view spans (1st to 99th percentile of what is nearer than the far clip, 5% margin): the
    colour scale of the depth panel, fixed per model so colours mean the same distance all episode long."""
    seen = depth_m[depth_m < 0.99 * far_clip]
    if seen.size == 0:
        return 0.0, far_clip
    lo, hi = np.percentile(seen, [1.0, 99.0])
    margin = max(0.05 * (hi - lo), 0.01)
    return float(max(lo - margin, 0.0)), float(hi + margin)


def send(stream: IO[bytes], obj: Any) -> None:
    data = pickle.dumps(obj, protocol=pickle.HIGHEST_PROTOCOL)
    stream.write(_LEN.pack(len(data)))
    stream.write(data)
    stream.flush()


def receive(stream: IO[bytes]) -> Any:
    """The next message, or None at end of stream."""
    head = stream.read(_LEN.size)
    if len(head) < _LEN.size:
        return None
    (n,) = _LEN.unpack(head)
    data = stream.read(n)
    if len(data) < n:
        return None
    return pickle.loads(data)


class Renderer:
    """Offscreen RGB + depth of one camera, with the cheapest settings that still look right: no multisampling,
    no shadows, no reflections, coarse primitives. The OpenGL context (a second to make: every texture is
    uploaded) is kept across models that carry the same meshes and textures."""

    def __init__(self, camera: str, width: int, height: int, fast: bool = True):
        self.camera, self.width, self.height = camera, width, height
        self.fast = fast  # False: the model's own quality (for comparison in benchmarks/bench_vr.py)
        self.model = None
        self._assets = None
        self._gl = None
        self.context_builds = 0
        self.rgb = np.zeros((height, width, 3), dtype=np.uint8)
        self.zbuf = np.zeros((height, width), dtype=np.float32)

    def _same_assets(self, m) -> bool:
        a = self._assets
        if a is None:
            return False
        sizes = ("nmesh", "nmeshvert", "nmeshface", "ntex", "ntexdata", "nhfield", "nhfielddata", "nskin", "nmat")
        if any(getattr(a, s) != getattr(m, s) for s in sizes):
            return False
        arrays = ("mesh_vert", "mesh_face", "tex_data", "hfield_data", "mat_texid")
        return all(np.array_equal(getattr(a, name), getattr(m, name)) for name in arrays)

    def load(self, m: mujoco.MjModel) -> None:
        from mujoco.gl_context import GLContext  # loads the GL backend MUJOCO_GL names: only when rendering

        if self._gl is None or not self._same_assets(m):
            if self._gl is not None:
                self._ctx.free()
                self._gl.free()
            fast = copy.deepcopy(m)
            if self.fast:
                fast.vis.quality.offsamples = 0
                fast.vis.quality.numslices = min(int(fast.vis.quality.numslices), 12)
                fast.vis.quality.numstacks = min(int(fast.vis.quality.numstacks), 8)
            fast.vis.global_.offwidth = self.width
            fast.vis.global_.offheight = self.height
            self._gl = GLContext(self.width, self.height)
            self._gl.make_current()
            self._ctx = mujoco.MjrContext(fast, mujoco.mjtFontScale.mjFONTSCALE_100)
            mujoco.mjr_setBuffer(mujoco.mjtFramebuffer.mjFB_OFFSCREEN, self._ctx)
            self._ctx.readDepthMap = mujoco.mjtDepthMap.mjDEPTH_ZERONEAR
            self._assets = fast
            self.context_builds += 1
        self.scene = mujoco.MjvScene(m, maxgeom=10000)
        if self.fast:
            for flag in (mujoco.mjtRndFlag.mjRND_SHADOW, mujoco.mjtRndFlag.mjRND_REFLECTION):
                self.scene.flags[flag] = 0
        self.cam = mujoco.MjvCamera()
        self.cam.type = mujoco.mjtCamera.mjCAMERA_FIXED
        self.cam.fixedcamid = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_CAMERA, self.camera)
        if self.cam.fixedcamid < 0:
            raise ValueError(f"no camera {self.camera!r} in the model")
        self.opt = mujoco.MjvOption()
        self.data = mujoco.MjData(m)
        self.rect = mujoco.MjrRect(0, 0, self.width, self.height)
        extent = float(m.stat.extent)
        self.near, self.far = float(m.vis.map.znear) * extent, float(m.vis.map.zfar) * extent
        self.model = m

    def render(self, qpos: np.ndarray, mocap_pos: np.ndarray, mocap_quat: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(rgb, depth in metres) of the model at these positions, upright."""
        m, d = self.model, self.data
        d.qpos[:] = qpos
        d.mocap_pos[:] = mocap_pos
        d.mocap_quat[:] = mocap_quat
        mujoco.mj_kinematics(m, d)
        mujoco.mj_comPos(m, d)  # cameras that track a subtree need its centre of mass
        mujoco.mj_camlight(m, d)
        mujoco.mjv_updateScene(m, d, self.opt, None, self.cam, mujoco.mjtCatBit.mjCAT_ALL, self.scene)
        mujoco.mjr_render(self.rect, self.scene, self._ctx)
        mujoco.mjr_readPixels(self.rgb, self.zbuf, self.rect, self._ctx)
        # OpenGL rows run bottom-up; the depth buffer is 0..1 between the clip planes, not linear
        z = self.zbuf[::-1]
        return self.rgb[::-1], self.near / (1.0 - z * (1.0 - self.near / self.far))


def serve(config: dict, requests: IO[bytes], replies: IO[bytes]) -> None:
    """Answer the parent's requests until it says stop or goes away."""
    renderer = Renderer(config["camera"], config["width"], config["height"])
    side_by_side = np.empty((config["height"], 2 * config["width"], 3), np.uint8)  # RGB | depth, one JPEG
    depth_range = config["depth_range"]  # None: from the first frame of each model
    # imports and tables made now, not in the first frame (matplotlib alone takes a good part of a second)
    try:
        _depth_lut()
        encode_jpeg(side_by_side[:8, :8], config["quality"], config["encoder"])
    except Exception:  # the first frame that needs them reports the error to the parent
        pass
    while True:
        msg = receive(requests)
        if msg is None or msg[0] == "stop":
            return
        try:
            if msg[0] == "model":
                t0 = time.perf_counter()
                renderer.load(mujoco.MjModel.from_binary_path(msg[1]))
                depth_range = config["depth_range"]
                info = dict(context_builds=renderer.context_builds, load_ms=1000 * (time.perf_counter() - t0))
                send(replies, ("model_ok", info))
            elif msg[0] == "frame":
                req = msg[1]
                # monotonic: the same clock in every process of this machine, so the stages line up end to end
                t0 = time.monotonic()
                rgb, depth_m = renderer.render(req["qpos"], req["mocap_pos"], req["mocap_quat"])
                t1 = time.monotonic()
                if depth_range is None:
                    depth_range = auto_depth_range(depth_m, renderer.far)
                if req["depth"]:
                    image = side_by_side
                    image[:, : renderer.width] = rgb
                    depth_colormap(depth_m, *depth_range, out=image[:, renderer.width :])
                else:
                    image = rgb
                jpeg = encode_jpeg(image, config["quality"], config["encoder"])
                t2 = time.monotonic()
                result = dict(
                    jpeg=jpeg,
                    width=image.shape[1],
                    height=image.shape[0],
                    render_ms=1000 * (t1 - t0),
                    encode_ms=1000 * (t2 - t1),
                    render_start=t0,
                    rendered=t1,
                    encoded=t2,
                    depth_m=depth_m.copy() if req.get("keep_depth") else None,
                    depth_range=depth_range,
                )
                send(replies, ("frame", result))
            else:
                send(replies, ("error", f"unknown request {msg[0]!r}"))
        except Exception as e:  # reported to the parent, which decides; the process stays up
            send(replies, ("error", f"{e.__class__.__name__}: {e}"))


def main() -> None:
    config = json.loads(sys.argv[1])
    requests, replies = sys.stdin.buffer, sys.stdout.buffer
    sys.stdout = sys.stderr  # a stray print must not corrupt the reply stream
    if hasattr(os, "nice"):
        os.nice(int(config.get("nice", 0)))  # short of CPU, drop frames rather than control steps
    serve(config, requests, replies)


if __name__ == "__main__":
    main()
