"""End to end in a real browser: Debian's Chromium (headless) opens our page from our server, Meta's WebXR emulator
(iwer) plays the headset, the emulated right controller moves with squeeze held, and the simulated arm moves the
same way; camera frames reach the page and are drawn in the immersive session.

Needs ``chromium`` (apt) and ``tests/browser/node_modules`` (``tests/browser/setup.sh``); skipped, saying which,
only when those are absent.
"""

import json
import shutil
import socket
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from helpers.vr import make_lift_env, run_loop

from veragmil_suite.data.schema import open_dataset
from veragmil_suite.devices import VRDevice, VRServerOptions

BROWSER_DIR = Path(__file__).resolve().parent / "browser"
CHROMIUM = Path("/usr/bin/chromium")


def _missing() -> str | None:
    if not CHROMIUM.exists():
        return "Debian chromium is not installed (tests/browser/setup.sh installs it)"
    if shutil.which("node") is None:
        return "node is not installed (tests/browser/setup.sh installs it)"
    for package in ("playwright-core", "iwer"):
        if not (BROWSER_DIR / "node_modules" / package / "package.json").exists():
            return f"tests/browser/node_modules/{package} is absent (run tests/browser/setup.sh)"
    return None


# real time: make test runs these alone, after the rest (see conftest.py)
pytestmark = [pytest.mark.realtime, pytest.mark.skipif(_missing() is not None, reason=_missing() or "")]

# hand moves in the XR frame (x right, y up, z toward the operator) and where they must take the end-effector:
# agentview looks back at the robot (along -x), so the image's right is +y and up is +z
MOVES = [([0.10, 0.0, 0.0], [0.0, 1.0, 0.0]), ([0.0, 0.08, 0.0], [0.0, 0.0, 1.0])]


def test_emulated_quest_in_chromium_drives_the_arm_and_sees_the_camera():
    env = make_lift_env()
    # the 200 ms staleness rule is tested in test_vr_device.py; a browser sharing two loaded cores with the
    # simulator may skip frames, and this test is about the path through the browser. iwer marks every
    # controller pose as emulatedPosition, which a real Quest does only for a controller it has lost
    device = VRDevice(
        env,
        server=VRServerOptions(port=0),
        camera_name="agentview",
        stale_timeout=0.5,
        allow_emulated_position=True,
        verbose=False,
    )
    browser = subprocess.Popen(
        ["node", "e2e_vr.mjs", device.url, json.dumps([move for move, _ in MOVES])],
        cwd=BROWSER_DIR,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        device.start_control()
        log = run_loop(env, device, until=lambda: browser.poll() is not None, max_seconds=120)
        out, err = browser.communicate(timeout=30)
    finally:
        if browser.poll() is None:
            browser.kill()
        device.close()
        env.close()
    assert browser.returncode == 0, f"browser script failed:\n{err[-3000:]}"
    result = json.loads(out.strip().splitlines()[-1])
    assert result["errors"] == []

    stats = result["stats"]
    assert result["framesBeforeXR"] >= 3  # the camera stream reached the page before VR
    assert stats["framesDrawn"] > 10 and stats["framesDecoded"] > 30  # and was drawn on the panel in VR
    assert stats["posesSent"] > 100 and stats["lastFrame"]["panels"] == 2
    # the page reads each frame's timing block and times its own part (decode, then the next XR frame)
    assert stats["lastFrame"]["timing"]["step"] > 0 and stats["lastFrame"]["timing"]["poseSeq"] > 0
    latency = stats["latency"]
    assert latency["decoded"] > 30 and latency["drawn"] > 10
    assert 0 < latency["receivedToDecodedMs"] < 1000 and 0 <= latency["decodedToDrawnMs"] < 1000

    # one engaged stretch per move; the end-effector displacement of each, once it settled (before the next)
    engaged = np.array([e["engaged"] for e in log])
    starts = np.flatnonzero(engaged[1:] & ~engaged[:-1]) + 1
    assert len(starts) == len(MOVES)
    ends = list(starts[1:] - 1) + [len(log) - 1]
    for (move, direction), i0, i1 in zip(MOVES, starts, ends):
        moved = log[i1]["p"] - log[i0]["p"]
        size = np.linalg.norm(move)
        assert np.dot(moved, direction) / np.linalg.norm(moved) > 0.95  # the same way
        assert np.linalg.norm(moved) == pytest.approx(size, rel=0.2)  # about as far (scale 1)


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_a_vr_collection_in_chromium_discards_keeps_and_saves_scoop_granular_demos(tmp_path):
    """veragmil-collect --device vr as an operator meets it: the page shows the collection's state, an episode
    starts at the first squeeze, B discards, A keeps, and the page is told what was saved."""
    out = tmp_path / "vr.hdf5"
    port = _free_port()
    collect = subprocess.Popen(
        [str(Path(sys.executable).with_name("veragmil-collect")), "--device", "vr", "--vr-port", str(port),
         "--vr-allow-emulated", "--food", "pasta", "--n-grains", "12", "--camera-size", "64", "--episodes", "1",
         "--operator", "browser", "--output", str(out),
         "--horizon", "2000"],  # 100 s: a page slowed by a loaded host ends its episode by A or B, not the horizon
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )  # fmt: skip
    # the page shows an attempt's number before its scene is reset, and asks for the squeeze once it is ready
    ready = "squeeze the grip to start"
    steps = [
        {"waitFor": "kept 0/1 | discarded 0"},
        {"waitFor": ready},
        {"move": [0.0, 0.05, 0.0], "press": "b-button", "waitFor": "discarded 1"},
        {"waitFor": ready},
        {"move": [0.05, 0.0, 0.0], "press": "a-button", "waitFor": f"finished: 1 demo saved to {out}"},
    ]
    browser = None
    try:
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline and collect.poll() is None:
            try:
                socket.create_connection(("127.0.0.1", port), timeout=0.5).close()
                break
            except OSError:
                time.sleep(0.2)
        browser = subprocess.run(
            ["node", "e2e_vr.mjs", f"http://localhost:{port}/", json.dumps(steps)],
            cwd=BROWSER_DIR, capture_output=True, text=True, timeout=240,
        )  # fmt: skip
        if browser.returncode != 0:
            collect.kill()  # it waits for a page that has gone; the browser's own error is the one to read
        stdout, stderr = collect.communicate(timeout=60)
    finally:
        if collect.poll() is None:
            collect.kill()
            print("collect:", collect.communicate()[0][-3000:])
            if browser is not None:
                print("browser:", browser.stdout[-3000:], browser.stderr[-3000:])
    # the collection's own output ends with the VR server's counters (reconnections, pages dropped as silent)
    collected = f"collect:\n{stdout[-3000:]}\n{stderr[-3000:]}"
    assert browser.returncode == 0, f"browser script failed:\n{browser.stderr[-3000:]}\n{collected}"
    assert collect.returncode == 0, collected
    assert "vr server: connections " in stdout, collected
    result = json.loads(browser.stdout.strip().splitlines()[-1])
    assert result["errors"] == []
    assert result["stats"]["finished"] and result["stats"]["finalText"] == f"1 demo saved to {out}", collected
    with open_dataset(out) as f:
        data = f["data"]
        assert list(data.keys()) == ["demo_0"]
        demo = data["demo_0"]
        assert demo.attrs["device"] == "vr" and demo.attrs["operator"] == "browser"
        assert demo.attrs["end_reason"] == "operator"
        assert np.abs(demo["actions"][()]).max() > 0.05  # the hand moved the spoon
        attempts = json.loads(data.attrs["attempts"])
        assert [a["kept"] for a in attempts] == [False, True]
