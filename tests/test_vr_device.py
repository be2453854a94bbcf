"""VRDevice in robosuite's teleoperation loop, driven by a scripted WebSocket client (no headset, no browser).

Most tests replay the hand in step with the simulation (``helpers.vr.lockstep``), so the result does not depend on
how loaded the machine is; the staleness and streaming tests run in real time, as they must.
"""

import io
import time

import numpy as np
import pytest
from helpers.recording import make_env, tiny_env_kwargs
from helpers.vr import HAND, Client, controller, eef_pose, env_action, lockstep, make_lift_env, run_loop
from PIL import Image

from veragmil_suite.devices import VRDevice, VRServerOptions
from veragmil_suite.devices.vr import frames as F

# real time (staleness, heartbeats, timeouts): make test runs these alone, after the rest (see conftest.py)
pytestmark = pytest.mark.realtime

ANY_PORT = VRServerOptions(port=0)


@pytest.fixture(scope="module")
def rig():
    env = make_lift_env()
    device = VRDevice(env, server=ANY_PORT, camera_name="agentview", verbose=False)
    yield env, device
    device.close()
    env.close()


@pytest.fixture
def session(rig):
    """A fresh episode and a connected client; lockstep tests do not test staleness, so it is relaxed."""
    env, device = rig
    env.reset()
    device.stale_timeout = 5.0
    device.on_episode_command = None
    client = Client(device.url).connect()
    device.start_control()
    yield env, device, client
    client.close()


def squeeze_after(t0, script):
    """Hand released until t0 (the clutch starts latched), then squeezed, posed by script(t - t0)."""

    def run(t):
        if t < t0:
            return dict(right=controller(squeeze=0.0))
        p, q = script(t - t0)
        return dict(right=controller(p=np.add(HAND, p), q=q, squeeze=1.0))

    return run


def rotation_error_deg(a, b):
    return float(np.degrees(np.linalg.norm(F.mat_to_rotvec(a @ b.T))))


# 6 cm circle in the operator's frontal plane, 3 cm in and out, at 0.25 Hz (9.4 cm/s), the hand pitching +-20 deg
RADIUS, FREQ, HOLD, PITCH = 0.06, 0.25, 0.5, np.radians(20)


def circle(t):
    s = min(max(t - HOLD, 0.0), 1.0 / FREQ)
    w = 2 * np.pi * FREQ * s
    dp = np.array([RADIUS * np.sin(w), RADIUS * (1 - np.cos(w)), -0.5 * RADIUS * np.sin(w)])
    a = PITCH * np.sin(w)
    return dp, np.array([np.sin(a / 2), 0.0, 0.0, np.cos(a / 2)])


def test_replayed_trajectory_is_followed(session):
    """The stated error: the commanded pose follows the hand 50 ms behind within 3 mm / 1 deg RMS; the arm (robosuite
    OSC, ~0.16 s lag) within 3 cm / 8 deg RMS while the hand moves at 9.4 cm/s, and within 5 mm / 1.5 deg of where
    the hand says one second after it stops. Malformed and out-of-order messages in the stream change nothing."""
    env, device, client = session
    counts0 = device.server.stats()
    targets = []
    junk = iter(['{"v":1,"type":"pose"', "[]", b"\x00", '{"v":1,"type":"pose","seq":0,"t":0,"visible":true}'] * 5)

    def extra():
        targets.append(device.target_pose)
        item = next(junk, None)
        if item is not None:
            client.send(item)

    script = squeeze_after(0.2, circle)
    log = lockstep(env, device, client, script, duration=0.2 + HOLD + 1 / FREQ + 1.0, extra=extra)
    start = next(i for i, entry in enumerate(log) if entry["engaged"])
    assert all(entry["engaged"] for entry in log[start:])
    p0, r0 = log[start]["p"], log[start]["r"]
    M = device.clutch.map

    def expected(t):
        dp, q = circle(t - 0.2)
        return p0 + M @ dp, F.map_rotation(M, F.quat_to_mat(q)) @ r0

    moving = [i for i, e in enumerate(log) if 0.2 + HOLD < e["t"] < 0.2 + HOLD + 1 / FREQ]
    cmd_p, cmd_r, arm_p, arm_r = [], [], [], []
    for i in moving:
        p_hand_50ms, r_hand_50ms = expected(log[i]["t"] - 0.05)
        cmd_p.append(np.linalg.norm(targets[i].p - p_hand_50ms))
        cmd_r.append(rotation_error_deg(F.quat_to_mat(targets[i].q), r_hand_50ms))
        p_hand, r_hand = expected(log[i]["t"])
        arm_p.append(np.linalg.norm(log[i]["p"] - p_hand))
        arm_r.append(rotation_error_deg(log[i]["r"], r_hand))
    rms = lambda x: float(np.sqrt(np.mean(np.square(x))))  # noqa: E731
    assert rms(cmd_p) < 0.003 and rms(cmd_r) < 1.0
    assert rms(arm_p) < 0.03 and max(arm_p) < 0.045 and rms(arm_r) < 8.0
    p_end, r_end = expected(log[-1]["t"])
    assert np.linalg.norm(log[-1]["p"] - p_end) < 0.005
    assert rotation_error_deg(log[-1]["r"], r_end) < 1.5
    counts = device.server.stats()
    assert counts["malformed"] - counts0["malformed"] == 15 and counts["out_of_order"] - counts0["out_of_order"] == 5


def test_engaging_never_moves_the_arm_and_release_holds(session):
    env, device, client = session
    twisted = F.rotvec_to_quat(np.array([0.4, -0.9, 0.3]))  # an awkward grip, far from any home pose

    def script(t):
        if t < 0.2:
            return dict(right=controller(p=np.add(HAND, [0.2, -0.1, 0.1]), q=twisted, squeeze=0.0))
        if t < 1.2:  # squeezed, still
            return dict(right=controller(p=np.add(HAND, [0.2, -0.1, 0.1]), q=twisted, squeeze=1.0))
        if t < 2.7:  # 5 cm up while squeezed, then hold
            dy = 0.05 * min(t - 1.2, 0.5) / 0.5
            return dict(right=controller(p=np.add(HAND, [0.2, -0.1 + dy, 0.1]), q=twisted, squeeze=1.0))
        return dict(right=controller(p=HAND, squeeze=0.0))  # released; the hand wanders back

    p_start, r_start = eef_pose(env, device)
    targets = []

    def at_lift():
        if len(targets) < 54:  # the target at 2.65 s, with the hand still up
            targets.append(device.target_pose)

    log = lockstep(env, device, client, script, duration=4.0, extra=at_lift)
    still = [e for e in log if 0.25 <= e["t"] < 1.2]
    assert all(e["engaged"] for e in still)
    assert max(np.linalg.norm(e["p"] - p_start) for e in still) < 0.002
    assert max(rotation_error_deg(e["r"], r_start) for e in still) < 0.5
    lifted = [e for e in log if 2.6 <= e["t"] < 2.7][-1]["p"]
    np.testing.assert_allclose(targets[-1].p - p_start, [0, 0, 0.05], atol=1e-5)  # hand up 5 cm: target up 5 cm
    assert np.linalg.norm(lifted - targets[-1].p) < 0.01  # the arm there, but for OSC's steady-state error
    held = [e for e in log if e["t"] >= 2.8]
    assert not any(e["engaged"] for e in held)
    assert max(np.linalg.norm(e["p"] - lifted) for e in held) < 0.005


def test_stale_messages_hold_the_arm_and_release_the_clutch(session):
    """No message for 200 ms: release (latched until the squeeze is let go) and hold still; in real time."""
    env, device, client = session
    device.stale_timeout = 0.2

    def script(t):
        if t < 0.3:
            return dict(right=controller(squeeze=0.0))
        if t < 1.3:  # squeezed, drifting right at 2 cm/s
            return dict(right=controller(p=np.add(HAND, [0.02 * (t - 0.3), 0, 0]), squeeze=1.0))
        if t < 2.0:
            return None  # the headset went to sleep / Wi-Fi dropped
        if t < 2.5:  # back, squeeze still held: must not re-engage
            return dict(right=controller(p=np.add(HAND, [0.05, 0, 0]), squeeze=1.0))
        if t < 2.7:
            return dict(right=controller(p=np.add(HAND, [0.05, 0, 0]), squeeze=0.0))
        return dict(right=controller(p=np.add(HAND, [0.05, 0, 0]), squeeze=1.0))

    samples = []
    t_start = time.monotonic()
    done = client.play(script, duration=3.2)
    log = run_loop(env, device, until=done.done, extra=lambda: samples.append(device.pose_age))
    ts = np.array([e["t"] - t_start for e in log])
    engaged = np.array([e["engaged"] for e in log])
    ages = np.array([np.inf if a is None else a for a in samples])
    assert engaged[(ts > 0.6) & (ts < 1.2)].any()
    # the rule, step by step: never engaged on a message older than the timeout
    assert not engaged[ages > 0.2 + 1e-3].any()
    gap = (ts > 1.3 + 0.25) & (ts < 2.0)
    assert gap.any() and not engaged[gap].any()
    release = np.flatnonzero(~engaged & (ts > 1.3))[0]
    held = [log[i]["p"] for i in np.flatnonzero(gap)]
    assert max(np.linalg.norm(p - log[release]["p"]) for p in held) < 0.004
    assert not engaged[(ts > 2.05) & (ts < 2.45)].any()  # latched while the squeeze was never let go
    assert engaged[ts > 2.9].any()  # a fresh squeeze engages again
    assert device.episode_command is None and device.clutch.forced_releases >= 1


def test_reconnect_without_restart(session):
    env, device, client = session
    connections0 = device.server.stats()["connections"]
    p0, _ = eef_pose(env, device)
    right = squeeze_after(0.2, lambda t: (np.array([0.04 * min(t, 1.0), 0, 0]), np.array([0, 0, 0, 1.0])))
    lockstep(env, device, client, right, duration=1.8)
    client.close()  # the Wi-Fi drops
    deadline = time.monotonic() + 5
    while device.server.connected and time.monotonic() < deadline:
        time.sleep(0.01)
    assert not device.server.connected
    p1, _ = eef_pose(env, device)
    gap = run_loop(env, device, until=lambda: False, max_seconds=0.5)  # the loop goes on, the arm holds
    assert all(e["action"] is not None and not e["engaged"] for e in gap)
    assert np.linalg.norm(gap[-1]["p"] - p1) < 0.004
    again = Client(device.url).connect()  # the page reloads and reconnects: a new connection, seq from 0
    try:
        up = squeeze_after(0.2, lambda t: (np.array([0, 0.04 * min(t, 1.0), 0]), np.array([0, 0, 0, 1.0])))
        log = lockstep(env, device, again, up, duration=1.8)
        assert log[-1]["engaged"]
    finally:
        again.close()
    M = device.clutch.map
    moved = log[-1]["p"] - p0
    np.testing.assert_allclose(moved, M @ [0.04, 0.04, 0.0], atol=0.008)
    assert device.server.stats()["connections"] == connections0 + 1
    assert device.episode_command is None


def test_the_page_is_told_the_collection_state_and_when_it_is_over():
    env = make_lift_env()
    device = VRDevice(env, server=ANY_PORT, camera_name="agentview", verbose=False)
    client = Client(device.url).connect()
    try:
        device.progress = "episode 3 | kept 2/5 | discarded 0 | vr.hdf5"
        device.start_control()
        deadline = time.monotonic() + 5
        while not any("kept 2/5" in s["text"] for s in client.statuses) and time.monotonic() < deadline:
            device.input2action()
            time.sleep(0.05)
        assert any(s["progress"] == device.progress for s in client.statuses)
        device.close(farewell="2 demos saved to vr.hdf5")
        assert client.wait_closed() is not None and client.finished  # like the page, it closed and stays closed
        assert client.statuses[-1] == {"v": 1, "type": "status", "text": "2 demos saved to vr.hdf5", "final": True}
    finally:
        client.close()
        device.close()
        env.close()


def test_spoon_lands_on_the_held_target_in_scoop_granular():
    """ScoopGranular's default controller puts the spoon within 1 mm of where a still hand holds it (robosuite's
    kp=150 OSC stopped 1-8 mm short, held by XArm7's joint friction)."""
    env = make_env(tiny_env_kwargs(food="barley", depth=False))
    device = VRDevice(env, server=ANY_PORT, verbose=False)
    env.reset()
    device.stale_timeout = 5.0
    client = Client(device.url).connect()
    try:
        device.start_control()
        # 10 cm to the operator's right and 5 cm up (clear of the pile) over a second, then the hand holds still
        move = squeeze_after(0.2, lambda t: (np.array([0.10, 0.05, 0.0]) * min(t, 1.0), np.array([0, 0, 0, 1.0])))
        log = lockstep(env, device, client, move, duration=4.0)
        assert log[-1]["engaged"]
        start = next(e["p"] for e in log if e["engaged"])
        assert np.linalg.norm(log[-1]["p"] - start) > 0.1  # it went the whole way...
        assert np.linalg.norm(log[-1]["p"] - device.target_pose.p) < 0.001  # ...and landed on the target
    finally:
        client.close()
        device.close()
        env.close()


@pytest.mark.parametrize(
    "hand,button,command",
    [("right", "a", "keep"), ("right", "b", "discard"), ("left", "a", "reset")],
)
def test_episode_buttons_end_the_episode(session, hand, button, command):
    env, device, client = session
    heard = []
    device.on_episode_command = heard.append

    def script(t):
        pressed = 0.3 < t < 0.5 or t > 1.0  # a brush of the thumb first, then a long press
        c = controller(**{button: pressed})
        return {hand: c, "right" if hand == "left" else "left": controller()}

    log = lockstep(env, device, client, script, duration=3.0)
    assert log[-1]["action"] is None and 1.5 <= log[-1]["t"] <= 1.6  # 0.5 s after the long press began
    assert device.episode_command == command and heard == [command]
    device.start_control()
    assert device.episode_command is None and device.input2action() is not None


def test_camera_frames_and_status_reach_the_page(session):
    env, device, client = session
    device.stale_timeout = 0.2
    run_loop(env, device, until=lambda: len(client.frames) >= 12, max_seconds=10)
    frames = [h for _, h in client.frames]  # the first is the newest frame when the page connected
    assert len(frames) >= 12
    assert [f["frame_id"] for f in frames] == sorted(f["frame_id"] for f in frames)
    assert 0 <= env.sim.data.time - frames[-1]["sim_time"] < 0.5  # what the page shows is the current scene
    # every episode (hard reset) builds a new model; the OpenGL context made for the first one is kept
    assert device.stream.models_sent >= 2 and device.stream.stats()["context_builds"] == 1
    assert frames[-1]["panels"] == 2 and (frames[-1]["width"], frames[-1]["height"]) == (640, 240)
    status = client.statuses[-1]
    assert status["connected"] and "CONNECTED" in status["text"] and status["depth"] is True

    def toggle(t):  # left trigger: depth panel off
        return dict(left=controller(trigger=1.0 if t < 0.2 else 0.0), right=controller())

    client.frames.clear()
    done = client.play(toggle, duration=0.4)
    run_loop(env, device, until=lambda: done.done() and len(client.frames) >= 3, max_seconds=10)
    assert client.frames[-1][1]["panels"] == 1 and client.frames[-1][1]["width"] == 320
    device.stream.depth = True


def test_each_control_step_gets_a_frame_that_names_the_pose_it_followed(session):
    """Frames are rendered right after a control step finishes (never halfway), and their timing block names the
    step and the pose message whose action drove it, with the stages in order."""
    env, device, client = session
    used = {}  # control step -> seq of the newest pose message before it
    handled = device.messages_handled
    for _ in range(12):
        client.send_pose(right=controller())
        handled += 1
        deadline = time.monotonic() + 5.0
        while device.messages_handled < handled and time.monotonic() < deadline:
            time.sleep(0.001)
        action = device.input2action()
        used[env.timestep + 1] = client.seq - 1
        env.step(env_action(env, device, action))
        deadline = time.monotonic() + 5.0  # a teleoperation loop would sleep here; this one waits for the frame
        while time.monotonic() < deadline and not any(
            h.get("timing", {}).get("step") == env.timestep for _, h in client.frames
        ):
            time.sleep(0.001)
    frames = {h["frame_id"]: h["timing"] for _, h in client.frames if "timing" in h}  # a still frame is sent again
    timed = [t for t in frames.values() if t["step"] in used]
    assert [t["step"] for t in timed] == sorted(used)  # one frame per step, in order
    for t in timed:
        assert not t["mid_step"] and t["pose_seq"] == used[t["step"]]
        stages = [t[k] for k in ("action", "captured", "render_start", "rendered", "encoded", "published", "sent")]
        assert stages == sorted(stages) and t["pose_received"] <= t["action"]


def test_a_scene_moved_without_a_step_is_rendered_again(session):
    """A reset places the robot and objects without a control step or a tick of the simulated clock; the page must
    not keep showing the scene from before."""
    env, device, client = session
    run_loop(env, device, until=lambda: len(client.frames) >= 2, max_seconds=10)
    time.sleep(0.2)
    last = client.frames[-1][1]["frame_id"]
    env.sim.data.qpos[env.robots[0]._ref_joint_pos_indexes[0]] += 0.3
    env.sim.forward()
    deadline = time.monotonic() + 5.0
    while time.monotonic() < deadline and client.frames[-1][1]["frame_id"] == last:
        time.sleep(0.01)
    assert client.frames[-1][1]["frame_id"] > last
    assert client.frames[-1][1]["timing"]["step"] == env.timestep  # no step was taken


def test_streamed_jpeg_shows_the_scene_and_its_depth(session):
    env, device, client = session
    device.stream.keep_depth = True
    try:
        run_loop(env, device, until=lambda: len(client.frames) >= 3, max_seconds=10)
    finally:
        device.stream.keep_depth = False
    image = np.asarray(Image.open(io.BytesIO(client.last_jpeg)))
    assert image.shape == (240, 640, 3)
    assert image[:, :320].std() > 10 and image[:, 320:].std() > 10  # a scene, and a depth map with near and far
    depth = device.stream.last_depth_m
    assert depth.shape == (240, 320)
    # metres along the camera axis: most pixels see the table top, whose depth follows from the camera's pose
    cam = env.sim.model.camera_name2id("agentview")
    rot, pos = env.sim.data.cam_xmat[cam].reshape(3, 3), env.sim.data.cam_xpos[cam]
    half = np.tan(np.radians(env.sim.model.cam_fovy[cam]) / 2)
    cols, rows = np.meshgrid(np.arange(320), np.arange(240))
    rays = np.stack(
        [((cols + 0.5) / 320 * 2 - 1) * half * 320 / 240, (1 - (rows + 0.5) / 240 * 2) * half, -np.ones(cols.shape)], -1
    )
    rays = rays @ rot.T  # unit depth along the camera axis, in the world
    table_depth = (env.table_offset[2] - pos[2]) / rays[..., 2]
    on_table = np.abs(depth - table_depth) < 0.005
    assert on_table.mean() > 0.5


def test_recenter_and_scale_buttons(session):
    """The operator turns 90 degrees left, presses Y (recenter) and flicks the stick up (scale x1.25): a hand
    stroke along the new facing drives the end-effector along the camera's forward, 1.25 times as far."""
    env, device, client = session
    turned = np.array([0.0, np.sin(np.pi / 4), 0.0, np.cos(np.pi / 4)])  # head yawed +90 deg about XR up
    forward = F.quat_to_mat(turned) @ [0, 0, -1]  # now XR -x

    def script(t):
        left = controller(b=0.3 < t < 0.4)  # Y: recenter
        right = controller(stick=(0.0, 1.0 if 0.5 < t < 0.6 else 0.0))  # flick up: scale up
        if t > 0.8:
            right = controller(p=np.add(HAND, forward * 0.04 * min(t - 1.0, 1.0) if t > 1.0 else 0), squeeze=1.0)
        return dict(left=left, right=right, head_q=turned)

    p_start, _ = eef_pose(env, device)
    log = lockstep(env, device, client, script, duration=2.5)
    assert log[-1]["engaged"] and device.clutch.pos_scale == pytest.approx(1.25)
    camera_forward = np.array([np.cos(device.clutch.camera_yaw), np.sin(device.clutch.camera_yaw), 0.0])
    np.testing.assert_allclose(device.target_pose.p - p_start, 1.25 * 0.04 * camera_forward, atol=1e-4)
    assert camera_forward[0] < -0.99  # agentview looks back at the robot: forward is -x
    assert client.statuses[-1]["recenter"] >= 1 and client.statuses[-1]["scale"] == pytest.approx(1.25)


def test_vr_drives_the_spoon_in_scoop_granular():
    """Our task: XArm7 with the spoon (6-D actions, no gripper), the overhead camera streamed by default."""
    from helpers.env import make_env

    env = make_env("rice", robot="XArm7", initialization_noise=None)
    env.reset()
    device = VRDevice(env, server=ANY_PORT, stale_timeout=5.0, verbose=False)
    client = Client(device.url).connect()
    try:
        assert device.camera_name == "overhead" and env.action_dim == 6
        device.start_control()
        stroke = squeeze_after(0.2, lambda t: (np.array([0.03, 0.04, 0.0]) * min(t, 1.0), np.array([0, 0, 0, 1.0])))
        log = lockstep(env, device, client, stroke, duration=2.5)
        moved = log[-1]["p"] - log[0]["p"]
        np.testing.assert_allclose(moved, device.clutch.map @ [0.03, 0.04, 0.0], atol=0.01)
        assert moved[2] == pytest.approx(0.04, abs=0.01)  # hand up, spoon up
        assert client.frames and client.frames[-1][1]["panels"] == 2
    finally:
        client.close()
        device.close()
        env.close()


def test_a_crashed_renderer_is_restarted_and_the_loop_never_waits(session):
    env, device, client = session
    device.stale_timeout = 0.2
    run_loop(env, device, until=lambda: len(client.frames) >= 3, max_seconds=10)
    restarts = device.stream.restarts
    device.stream._proc.kill()  # the rendering process dies (out of memory, a driver crash)
    n = len(client.frames)
    log = run_loop(env, device, until=lambda: len(client.frames) >= n + 3, max_seconds=20)
    assert len(client.frames) >= n + 3 and device.stream.restarts == restarts + 1
    steps = np.diff([e["t"] for e in log])
    assert steps.max() < 0.5  # the teleoperation loop went on while the renderer came back


def test_hidden_page_and_estimated_positions_release_the_clutch(session):
    """A headset that hides the page (asleep, system menu) or a controller whose position is only estimated
    (WebXR's emulatedPosition) releases the clutch, latched, while messages keep coming."""
    env, device, client = session

    def script(t):
        if t < 0.2:
            return dict(right=controller())
        if 1.0 < t < 1.5:
            return dict(right=controller(squeeze=1.0), visible=False)
        if 2.0 < t < 2.5:
            return dict(right=controller(squeeze=1.0, emulated=True))
        if 1.5 <= t <= 1.6 or 2.5 <= t <= 2.6:
            return dict(right=controller(squeeze=0.0))  # let go, to engage again
        return dict(right=controller(squeeze=1.0))

    log = lockstep(env, device, client, script, duration=3.0)
    engaged = {round(e["t"], 2): e["engaged"] for e in log}
    assert engaged[0.9] and engaged[1.9] and engaged[2.9]
    assert not any(v for t, v in engaged.items() if 1.05 <= t <= 1.5 or 2.05 <= t <= 2.5)
    assert device.clutch.forced_releases == 2
