"""Message schema v1: what is accepted, what is dropped under which reason, the frame header and its timing block
(in Python and in the page's parser); button events."""

import base64
import json
import math
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from veragmil_suite.devices.vr.controls import DEFAULT_BINDINGS, Binding, ButtonEvents
from veragmil_suite.devices.vr.protocol import (
    MAX_MESSAGE_BYTES,
    PANELS_RGB_DEPTH,
    TIMES,
    ControllerState,
    HelloMessage,
    PongMessage,
    PoseMessage,
    ProtocolError,
    pack_frame,
    parse_client_message,
    stamp_sent,
    unpack_frame,
)


def controller(**overrides):
    c = {
        "p": [0.2, 1.1, -0.3],
        "q": [0, 0, 0, 1],
        "emulated": False,
        "trigger": 0.0,
        "squeeze": 1.0,
        "stick": [0.0, 0.0],
        "stick_press": False,
        "a": False,
        "b": False,
    }
    c.update(overrides)
    return c


def pose(**overrides):
    m = {
        "v": 1,
        "type": "pose",
        "seq": 7,
        "t": 1234.5,
        "visible": True,
        "head": {"p": [0, 1.6, 0], "q": [0, 0, 0, 1]},
        "right": controller(),
        "left": None,
    }
    m.update(overrides)
    return json.dumps(m)


def reason(text):
    with pytest.raises(ProtocolError) as e:
        parse_client_message(text)
    return e.value.reason


def test_a_pose_message_parses_into_typed_fields():
    msg = parse_client_message(pose(extra_field_from_a_newer_page=1))
    assert isinstance(msg, PoseMessage) and msg.seq == 7 and msg.t == 1234.5 and msg.visible
    assert msg.left is None
    np.testing.assert_allclose(msg.right.pose.p, [0.2, 1.1, -0.3])
    assert msg.right.squeeze == 1.0 and not msg.right.a
    np.testing.assert_allclose(msg.head.q, [0, 0, 0, 1])


def test_quaternions_are_normalised_and_untracked_controllers_have_no_pose():
    msg = parse_client_message(pose(right=controller(q=[0, 0, 0, 1.2])))
    assert np.linalg.norm(msg.right.pose.q) == pytest.approx(1.0) and not msg.right.emulated
    assert parse_client_message(pose(right=controller(emulated=True))).right.emulated
    assert parse_client_message(pose(right=controller(p=None, q=None))).right.pose is None


def test_hello_and_pong():
    assert parse_client_message('{"v":1,"type":"hello","token":"AB-CD","client":"x"}') == HelloMessage("AB-CD", "x")
    assert parse_client_message('{"v":1,"type":"hello","token":null}') == HelloMessage(None, "")
    assert parse_client_message('{"v":1,"type":"pong","id":3}') == PongMessage(3)


@pytest.mark.parametrize(
    "text",
    [
        "not json",
        "[1, 2]",
        '{"v":1,"type":"teleport"}',
        pose(seq=-1),
        pose(seq=True),
        pose(seq=1.5),
        pose(t="soon"),
        pose(visible=1),
        pose(head={"p": [0, 1], "q": [0, 0, 0, 1]}),
        pose(head={"p": [0, 1, 1e6], "q": [0, 0, 0, 1]}),
        pose(head={"p": [0, 1, 0], "q": [0, 0, 0, 0.1]}),
        pose(right=controller(trigger=1.5)),
        pose(right=controller(squeeze=True)),
        pose(right=controller(stick=[0, 2])),
        pose(right=controller(a="yes")),
        pose(right=controller(emulated=1)),
        pose(right=[1, 2, 3]),
        pose(t=float("nan")),
        pose().replace("1234.5", "Infinity"),
        '{"v":1,"type":"hello","token":5}',
        '{"v":1,"type":"pong","id":"x"}',
    ],
)
def test_malformed_messages_are_rejected(text):
    assert reason(text) == "malformed"


def test_binary_oversized_and_other_versions_have_their_own_reasons():
    assert reason(b"\x00\x01") == "malformed"
    assert reason(pose(padding="x" * MAX_MESSAGE_BYTES)) == "oversized"
    assert reason(pose(v=2)) == "version"
    assert reason(pose(v=True)) == "version"
    assert reason('{"type":"pose"}') == "version"


def test_frame_header_round_trip():
    data = pack_frame(b"\xff\xd8jpeg", frame_id=42, sim_time=3.25, width=640, height=240, panels=PANELS_RGB_DEPTH)
    header, jpeg = unpack_frame(data)
    assert jpeg == b"\xff\xd8jpeg"
    assert header == dict(version=1, panels=2, frame_id=42, sim_time=3.25, width=640, height=240)
    assert len(data) - len(jpeg) == 20  # the page reads a 20-byte header
    with pytest.raises(ValueError):
        unpack_frame(b"XX" + data[2:])
    assert stamp_sent(data, 1.0) == data  # no timing block to stamp


TIMING = dict(step=17, mid_step=False, pose_seq=1042, **{name: 100.0 + i / 1000 for i, name in enumerate(TIMES)})


def test_timed_frame_round_trip_and_sent_stamp():
    data = pack_frame(b"\xff\xd8jpeg", 42, 3.25, 640, 240, PANELS_RGB_DEPTH, dict(TIMING, sent=None))
    header, jpeg = unpack_frame(data)
    assert jpeg == b"\xff\xd8jpeg" and header["version"] == 2 and header["frame_id"] == 42
    assert math.isnan(header["timing"].pop("sent"))  # stamped by the server as it sends
    assert header["timing"] == {k: v for k, v in TIMING.items() if k != "sent"}
    header, jpeg = unpack_frame(stamp_sent(data, 123.5))
    assert header["timing"]["sent"] == 123.5 and jpeg == b"\xff\xd8jpeg"
    # unknown values: no step clock, no pose behind the step, a stage not timed
    header, _ = unpack_frame(pack_frame(b"j", 1, 0.0, 320, 240, 1, dict(captured=5.0)))
    timing = header["timing"]
    assert timing["step"] is None and timing["pose_seq"] == -1 and timing["captured"] == 5.0
    assert math.isnan(timing["action"]) and timing["mid_step"] is False


def test_timing_block_is_skipped_by_its_length():
    data = pack_frame(b"\xff\xd8jpeg", 42, 3.25, 640, 240, PANELS_RGB_DEPTH, TIMING)
    n = int.from_bytes(data[20:22], "little")
    longer = data[:20] + (n + 8).to_bytes(2, "little") + data[22 : 22 + n] + b"newfield" + data[22 + n :]
    header, jpeg = unpack_frame(longer)  # a field appended by a later version
    assert jpeg == b"\xff\xd8jpeg" and header["timing"]["pose_seq"] == 1042
    for broken in (data[:21], data[:30], data[:20] + (4).to_bytes(2, "little") + data[22:]):
        with pytest.raises(ValueError):
            unpack_frame(broken)


@pytest.mark.skipif(shutil.which("node") is None, reason="node is not installed")
def test_the_page_parses_both_frame_versions():
    """web/link.js's parseFrame (run by node) reads what pack_frame writes, timing block or not."""
    web = Path(__file__).resolve().parents[1] / "veragmil_suite" / "devices" / "vr" / "web"
    frames = [
        pack_frame(b"\xff\xd8jpeg", 42, 3.25, 640, 240, PANELS_RGB_DEPTH),
        stamp_sent(pack_frame(b"\xff\xd8jpeg", 43, 3.5, 640, 240, PANELS_RGB_DEPTH, TIMING), 200.0),
    ]
    script = """
import { parseFrame } from "./link.js";
const out = JSON.parse(process.argv[1]).map((b64) => {
  const bytes = Buffer.from(b64, "base64");
  const f = parseFrame(bytes.buffer.slice(bytes.byteOffset, bytes.byteOffset + bytes.length));
  return { ...f, jpeg: Buffer.from(f.jpeg).toString("latin1") };
});
console.log(JSON.stringify(out));
"""
    arg = json.dumps([base64.b64encode(f).decode() for f in frames])
    run = subprocess.run(["node", "--input-type=module", "-e", script, arg], cwd=web, capture_output=True, text=True)
    assert run.returncode == 0, run.stderr
    old, timed = json.loads(run.stdout)
    assert old == dict(version=1, panels=2, frameId=42, simTime=3.25, width=640, height=240, jpeg="\xff\xd8jpeg")
    assert timed["frameId"] == 43 and timed["jpeg"] == "\xff\xd8jpeg"
    camel = {"".join(w.title() if i else w for i, w in enumerate(k.split("_"))): v for k, v in TIMING.items()}
    assert timed["timing"] == dict(camel, sent=200.0)


# ---------------------------------------------------------------- buttons


def state(**kw):
    base = dict(
        pose=None, emulated=False, trigger=0.0, squeeze=0.0, stick=(0.0, 0.0), stick_press=False, a=False, b=False
    )
    base.update(kw)
    return ControllerState(**base)


def test_press_fires_once_on_the_edge():
    ev = ButtonEvents()
    assert ev.update({"left": state(b=True), "right": state()}, 0.0) == ["recenter"]
    assert ev.update({"left": state(b=True), "right": state()}, 0.1) == []
    assert ev.update({"left": state(), "right": state()}, 0.2) == []
    assert ev.update({"left": state(b=True), "right": state()}, 0.3) == ["recenter"]


def test_episode_buttons_need_a_long_press():
    ev = ButtonEvents()
    assert ev.update({"right": state(a=True)}, 0.0) == []
    assert ev.update({"right": state(a=True)}, 0.3) == []
    assert ev.update({"right": state()}, 0.4) == []  # let go too soon: nothing
    fired = [e for t in np.arange(1.0, 2.0, 0.05) for e in ev.update({"right": state(a=True)}, t)]
    assert fired == ["keep"]  # once, after half a second


def test_analog_controls_have_hysteresis_and_the_stick_flicks():
    ev = ButtonEvents()
    levels = [0.8, 0.5, 0.8, 0.2, 0.8]  # dips to 0.5 are not releases; 0.2 is
    fired = [ev.update({"left": state(trigger=v)}, i * 0.1) for i, v in enumerate(levels)]
    assert fired == [["depth"], [], [], [], ["depth"]]
    assert ev.update({"right": state(stick=(0.0, 0.9))}, 1.0) == ["scale_up"]
    assert ev.update({"right": state(stick=(0.0, -0.9))}, 1.1) == ["scale_down"]


def test_left_handed_operator_swaps_the_hands_and_absent_controllers_release():
    ev = ButtonEvents(DEFAULT_BINDINGS, main_hand="left")
    assert ev.update({"left": state(stick_press=True)}, 0.0) == ["precision"]
    assert ev.update({"right": state(stick_press=True)}, 0.1) == ["mode"]
    ev.update({}, 0.2)
    assert ev.update({"left": state(stick_press=True)}, 0.3) == ["precision"]
    with pytest.raises(ValueError):
        Binding("main", "a", "fly")
