"""The VR page <-> server message schema, version 1: parsing with strict validation, and the frame header.

Everything the page sends is JSON text, one object per WebSocket message, at most ``MAX_MESSAGE_BYTES``:

``hello`` (first message of every connection)::

    {"v": 1, "type": "hello", "token": "K7QM-2XPA" | null, "client": "<user agent>"}

``pose`` (one per XR frame, up to the ``send_hz`` the server asks for)::

    {"v": 1, "type": "pose", "seq": 1042, "t": 123456.7, "visible": true,
     "head":  {"p": [x, y, z], "q": [x, y, z, w]} | null,
     "right": CONTROLLER | null, "left": CONTROLLER | null}

    CONTROLLER = {"p": [x, y, z] | null, "q": [x, y, z, w] | null, "emulated": false,
                  "trigger": 0..1, "squeeze": 0..1, "stick": [x, y], "stick_press": bool, "a": bool, "b": bool}

  Poses are grip poses in the XR reference space (metres; x right, y up, z toward the user). ``seq`` is a
  per-connection counter that must increase; ``t`` is the XR frame time (ms, the page's clock) and must not
  decrease. ``stick`` is [right, forward] in [-1, 1] (the page flips the gamepad's y). ``a``/``b`` are A/B on
  the right controller and X/Y on the left. A null pose means the controller is not tracked; ``emulated`` is
  WebXR's ``emulatedPosition`` (the position is estimated, not tracked: controller out of the cameras' view, or
  an emulator). ``visible`` false means the headset hides the page (asleep, system menu).

``pong``: ``{"v": 1, "type": "pong", "id": <id of the server's ping>}``.

The server sends JSON text (``welcome`` with the configuration, ``status`` about 10 times a second, ``ping`` once
a second, ``error`` before closing; when the collection is over, a last ``status`` with ``"final": true`` whose
``text`` says what was saved: the page shows it, closes the connection with ``CLOSE_FINISHED`` and stops
reconnecting; a page that does not close it within ``FAREWELL_TIMEOUT_S`` is closed with that code)
and binary camera frames: ``FRAME_HEADER`` (little-endian: magic ``b"VF"``,
frame version, panels (1 RGB, 2 RGB|depth side by side), frame id, simulated time, width, height) then a JPEG.
Frame version 1 has nothing more. Version 2 (``FRAME_VERSION_TIMED``, what ``vr_stream`` sends) inserts, between
that header and the JPEG, a u16 byte count and a timing block (``FRAME_TIMING``: the control step shown, the pose
message its action came from, and when each stage of the frame's way happened, ``time.monotonic()`` seconds of
this machine) so a client on the same machine can attribute its latency; a parser skips the block by its count,
so fields appended later do not break it.

Unknown fields are ignored (a newer page still works); anything else unexpected raises ``ProtocolError`` with a
``reason`` the server counts under.
"""

from __future__ import annotations

import json
import math
import struct
from dataclasses import dataclass
from typing import Any

import numpy as np

SCHEMA_VERSION = 1
MAX_MESSAGE_BYTES = 8192  # a pose message is about 600 bytes
MAX_TOKEN_CHARS = 128
MAX_POSITION_M = 100.0  # farther than any room: a corrupted number
MAX_SEQ = 2**53  # JavaScript's exact-integer limit

FRAME_MAGIC = b"VF"
FRAME_HEADER = struct.Struct("<2sBBIdHH")
FRAME_VERSION = 1  # header, JPEG
FRAME_VERSION_TIMED = 2  # header, u16 block length, timing block, JPEG
PANELS_RGB = 1
PANELS_RGB_DEPTH = 2
# the timing block: step (u32, control steps begun when the state was captured; NO_STEP: unknown), flags (u32,
# FLAG_MID_STEP: captured while that step was still running), pose_seq (i64, seq of the newest pose message the
# step's action was computed from; -1: none), then the TIMES (f64, time.monotonic() seconds; NaN: unknown)
FRAME_TIMING = struct.Struct("<IIq8d")
_BLOCK_LEN = struct.Struct("<H")
NO_STEP = 0xFFFFFFFF
FLAG_MID_STEP = 1
TIMES = (
    "pose_received",  # the server received that pose message
    "action",  # the action was computed from it (input2action, just before the control step)
    "captured",  # the stream copied the simulation's state
    "render_start",  # the renderer process received the request
    "rendered",  # the renderer read the image back
    "encoded",  # depth colour map and JPEG done
    "published",  # the frame was handed to the server
    "sent",  # the server's event loop wrote it to the socket (stamped by ``stamp_sent``)
)
_SENT_OFFSET = FRAME_HEADER.size + _BLOCK_LEN.size + FRAME_TIMING.size - 8


class ProtocolError(ValueError):
    """A client message that is dropped; ``reason`` is the counter it goes under."""

    def __init__(self, reason: str, detail: str):
        super().__init__(f"{reason}: {detail}")
        self.reason = reason
        self.detail = detail


@dataclass(frozen=True)
class TrackedPose:
    p: np.ndarray  # (3,) metres, XR frame
    q: np.ndarray  # (4,) unit quaternion (x, y, z, w)


@dataclass(frozen=True)
class ControllerState:
    pose: TrackedPose | None  # None when not tracked
    emulated: bool  # the runtime estimates the position rather than tracking it
    trigger: float
    squeeze: float
    stick: tuple[float, float]
    stick_press: bool
    a: bool
    b: bool


@dataclass(frozen=True)
class HelloMessage:
    token: str | None
    client: str


@dataclass(frozen=True)
class PoseMessage:
    seq: int
    t: float  # milliseconds, page clock
    visible: bool
    head: TrackedPose | None
    left: ControllerState | None
    right: ControllerState | None


@dataclass(frozen=True)
class PongMessage:
    id: int


def _malformed(detail: str) -> ProtocolError:
    return ProtocolError("malformed", detail)


def _reject_constant(name: str):
    raise _malformed(f"non-finite number {name}")  # json accepts NaN and Infinity unless told not to


def _number(obj: dict, key: str, lo: float, hi: float) -> float:
    v = obj.get(key)
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or not lo <= v <= hi:
        raise _malformed(f"{key} must be a number in [{lo}, {hi}]")
    return float(v)


def _bool(obj: dict, key: str) -> bool:
    v = obj.get(key)
    if not isinstance(v, bool):
        raise _malformed(f"{key} must be true or false")
    return v


def _vector(v, n: int, key: str, bound: float) -> np.ndarray:
    if not isinstance(v, list) or len(v) != n:
        raise _malformed(f"{key} must be a list of {n} numbers")
    for x in v:
        if isinstance(x, bool) or not isinstance(x, (int, float)) or not math.isfinite(x) or abs(x) > bound:
            raise _malformed(f"{key} must hold finite numbers within +-{bound}")
    return np.array(v, dtype=float)


def _pose(v, key: str) -> TrackedPose | None:
    if v is None:
        return None
    if not isinstance(v, dict):
        raise _malformed(f"{key} must be an object or null")
    p = _vector(v.get("p"), 3, f"{key}.p", MAX_POSITION_M)
    q = _vector(v.get("q"), 4, f"{key}.q", 2.0)
    n = float(np.linalg.norm(q))
    if not 0.5 < n < 1.5:  # WebXR sends unit quaternions; far from unit is corruption, not rounding
        raise _malformed(f"{key}.q is not a unit quaternion (norm {n:.3f})")
    return TrackedPose(p, q / n)


def _controller(v, key: str) -> ControllerState | None:
    if v is None:
        return None
    if not isinstance(v, dict):
        raise _malformed(f"{key} must be an object or null")
    pose = _pose(v, key) if v.get("p") is not None else None
    stick = _vector(v.get("stick"), 2, f"{key}.stick", 1.01)
    return ControllerState(
        pose=pose,
        emulated=_bool(v, "emulated") if "emulated" in v else False,
        trigger=_number(v, "trigger", 0.0, 1.0),
        squeeze=_number(v, "squeeze", 0.0, 1.0),
        stick=(float(stick[0]), float(stick[1])),
        stick_press=_bool(v, "stick_press"),
        a=_bool(v, "a"),
        b=_bool(v, "b"),
    )


def parse_client_message(data: str | bytes) -> HelloMessage | PoseMessage | PongMessage:
    """Parse and validate one message from the page; raises ``ProtocolError`` (reason: oversized, malformed,
    version) for anything not in the schema."""
    if isinstance(data, bytes):
        raise ProtocolError("malformed", "binary message (the schema is JSON text)")
    if len(data) > MAX_MESSAGE_BYTES:
        raise ProtocolError("oversized", f"{len(data)} characters > {MAX_MESSAGE_BYTES}")
    try:
        obj = json.loads(data, parse_constant=_reject_constant)
    except ProtocolError:
        raise
    except (ValueError, RecursionError) as e:
        raise _malformed(f"not JSON ({e.__class__.__name__})") from None
    if not isinstance(obj, dict):
        raise _malformed("not a JSON object")
    if obj.get("v") != SCHEMA_VERSION or isinstance(obj.get("v"), bool):
        raise ProtocolError("version", f"schema version {obj.get('v')!r}, this server speaks {SCHEMA_VERSION}")
    kind = obj.get("type")
    if kind == "pose":
        seq = obj.get("seq")
        if isinstance(seq, bool) or not isinstance(seq, int) or not 0 <= seq < MAX_SEQ:
            raise _malformed("seq must be a non-negative integer")
        return PoseMessage(
            seq=seq,
            t=_number(obj, "t", 0.0, 1e15),
            visible=_bool(obj, "visible"),
            head=_pose(obj.get("head"), "head"),
            left=_controller(obj.get("left"), "left"),
            right=_controller(obj.get("right"), "right"),
        )
    if kind == "hello":
        token = obj.get("token")
        if token is not None and (not isinstance(token, str) or len(token) > MAX_TOKEN_CHARS):
            raise _malformed("token must be a short string or null")
        client = obj.get("client", "")
        if not isinstance(client, str):
            raise _malformed("client must be a string")
        return HelloMessage(token=token, client=client[:200])
    if kind == "pong":
        pid = obj.get("id")
        if isinstance(pid, bool) or not isinstance(pid, int):
            raise _malformed("pong id must be an integer")
        return PongMessage(id=pid)
    raise _malformed(f"unknown message type {kind!r}")


def server_message(kind: str, **fields: Any) -> str:
    """A JSON text message from the server."""
    return json.dumps({"v": SCHEMA_VERSION, "type": kind, **fields}, separators=(",", ":"))


def pack_frame(
    jpeg: bytes,
    frame_id: int,
    sim_time: float,
    width: int,
    height: int,
    panels: int,
    timing: dict | None = None,
) -> bytes:
    """A binary camera frame: header, then the JPEG bytes; with ``timing`` (keys ``step``, ``mid_step``,
    ``pose_seq`` and the ``TIMES``, any missing one unknown), a version-2 frame carrying it."""
    version = FRAME_VERSION if timing is None else FRAME_VERSION_TIMED
    header = FRAME_HEADER.pack(FRAME_MAGIC, version, panels, frame_id & 0xFFFFFFFF, sim_time, width, height)
    if timing is None:
        return header + jpeg
    step = timing.get("step")
    block = FRAME_TIMING.pack(
        NO_STEP if step is None else int(step) & 0xFFFFFFFF,
        FLAG_MID_STEP if timing.get("mid_step") else 0,
        -1 if timing.get("pose_seq") is None else int(timing["pose_seq"]),
        *(math.nan if timing.get(k) is None else float(timing[k]) for k in TIMES),
    )
    return header + _BLOCK_LEN.pack(len(block)) + block + jpeg


def stamp_sent(frame: bytes, t: float) -> bytes:
    """The frame with its ``sent`` time set to t (a version-1 frame, which has no timing, is returned as is)."""
    if len(frame) < _SENT_OFFSET + 8 or frame[2] != FRAME_VERSION_TIMED:
        return frame
    out = bytearray(frame)
    struct.pack_into("<d", out, _SENT_OFFSET, t)
    return bytes(out)


def unpack_frame(data: bytes) -> tuple[dict, bytes]:
    """Header fields and JPEG bytes of a binary camera frame (the page does the same in JavaScript); a version-2
    frame's header has a ``timing`` dict too (``step`` None and ``pose_seq`` -1 when unknown, times NaN)."""
    if len(data) < FRAME_HEADER.size:
        raise ValueError("frame shorter than its header")
    magic, version, panels, frame_id, sim_time, width, height = FRAME_HEADER.unpack_from(data)
    if magic != FRAME_MAGIC:
        raise ValueError("not a camera frame")
    header = dict(version=version, panels=panels, frame_id=frame_id, sim_time=sim_time, width=width, height=height)
    start = FRAME_HEADER.size
    if version >= FRAME_VERSION_TIMED:
        if len(data) < start + _BLOCK_LEN.size:
            raise ValueError("frame shorter than its timing block")
        (n,) = _BLOCK_LEN.unpack_from(data, start)
        start += _BLOCK_LEN.size
        if n < FRAME_TIMING.size or len(data) < start + n:
            raise ValueError("frame shorter than its timing block")
        step, flags, pose_seq, *times = FRAME_TIMING.unpack_from(data, start)
        header["timing"] = dict(
            step=None if step == NO_STEP else step, mid_step=bool(flags & FLAG_MID_STEP), pose_seq=pose_seq,
            **dict(zip(TIMES, times)),
        )  # fmt: skip
        start += n
    return header, data[start:]
