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
``text`` says what was saved, then close code ``CLOSE_FINISHED``: the page shows it and stops reconnecting)
and binary camera frames: ``FRAME_HEADER`` (little-endian: magic ``b"VF"``,
version, panels (1 RGB, 2 RGB|depth side by side), frame id, simulated time, width, height) then a JPEG.

Unknown fields are ignored (a newer page still works); anything else unexpected raises ``ProtocolError`` with a
``reason`` the server counts under.
"""

from __future__ import annotations

import json
import math
import struct
from dataclasses import dataclass

import numpy as np

SCHEMA_VERSION = 1
MAX_MESSAGE_BYTES = 8192  # a pose message is about 600 bytes
MAX_TOKEN_CHARS = 128
MAX_POSITION_M = 100.0  # farther than any room: a corrupted number
MAX_SEQ = 2**53  # JavaScript's exact-integer limit

FRAME_MAGIC = b"VF"
FRAME_HEADER = struct.Struct("<2sBBIdHH")
PANELS_RGB = 1
PANELS_RGB_DEPTH = 2


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


def server_message(kind: str, **fields) -> str:
    """A JSON text message from the server."""
    return json.dumps({"v": SCHEMA_VERSION, "type": kind, **fields}, separators=(",", ":"))


def pack_frame(jpeg: bytes, frame_id: int, sim_time: float, width: int, height: int, panels: int) -> bytes:
    """A binary camera frame: header, then the JPEG bytes."""
    header = FRAME_HEADER.pack(FRAME_MAGIC, SCHEMA_VERSION, panels, frame_id & 0xFFFFFFFF, sim_time, width, height)
    return header + jpeg


def unpack_frame(data: bytes) -> tuple[dict, bytes]:
    """Header fields and JPEG bytes of a binary camera frame (the page does the same in JavaScript)."""
    if len(data) < FRAME_HEADER.size:
        raise ValueError("frame shorter than its header")
    magic, version, panels, frame_id, sim_time, width, height = FRAME_HEADER.unpack_from(data)
    if magic != FRAME_MAGIC:
        raise ValueError("not a camera frame")
    header = dict(version=version, panels=panels, frame_id=frame_id, sim_time=sim_time, width=width, height=height)
    return header, data[FRAME_HEADER.size :]
