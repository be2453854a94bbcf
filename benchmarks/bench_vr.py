"""Benchmark of the VR teleoperation path: pose-to-action latency, messages/s handled, frames/s streamed,
hand-to-frame latency and where it goes.

    python benchmarks/bench_vr.py              # about five minutes
    python benchmarks/bench_vr.py --seconds 4 --trials 40  # shorter runs, noisier figures

1. Rendering and JPEG encoding of the streamed camera (ScoopGranular's overhead camera, 320x240 RGB + depth):
   MuJoCo's default quality against the stream's settings (no multisampling, shadows or reflections, coarse
   primitives), and OpenCV against Pillow on the 640x240 RGB|depth image.
2. Messages/s: a client process sends pose messages as fast as it can; how many the server validates and the device
   filters per second, and the device's time per message.
3. Pose-to-action latency, in robosuite's loop at 20 Hz with the page's 90 Hz: the age of the newest pose when an
   action is computed, and the time from a hand step leaving the client to the first action that moves for it.
4. Frames/s streamed while the environment runs in real time (a client at 90 Hz connected, the loop paced to the
   control rate): frames received per second, control steps per second achieved, renderer times.
5. Hand-to-frame latency: ScoopGranular (rice) at 20 Hz in real time; a client process (the page's part) holds the
   grip and moves the hand 2 cm every 0.6-0.9 s, and times each move from its first pose message leaving the
   client to the first camera frame it receives showing a control step whose action came from that message or a
   later one (each frame's timing block says which, ``vr_protocol.pack_frame``). The timing block splits the time
   into stages: pose sent -> control step begins (the socket, then the wait for the next step), the control step,
   the state to the renderer process, render, depth colour map and JPEG, back to the stream, the server's event
   loop, the socket to the client; and the client's JPEG decode after that. Both frame schedules, in turn for 4 s
   each with the same client (a changing load affects both alike): frames rendered right after each control step
   (the default) and on a 30 fps clock (``sync_to_steps=False``). A clocked frame may show a step half done: the
   first such frame counts as showing the move (its action has begun), and a second line gives the first frame of
   that step finished. A headset adds its own decode and display: up to one 90 Hz display frame (11 ms).

    python benchmarks/bench_vr.py --sections 5 --trials 200   # hand-to-frame only, about 200 moves per schedule
    python benchmarks/bench_vr.py --sections 5 --physics calibrated   # on the calibrated grains
"""

from __future__ import annotations

import argparse
import asyncio
import io
import json
import multiprocessing
import os
import random
import sys
import time

# OSMesa whatever the display (veragmil_suite.utils.rendering's forced choice), set before robosuite is imported
os.environ["MUJOCO_GL"] = os.environ["PYOPENGL_PLATFORM"] = "osmesa"
os.environ.setdefault("PYNPUT_BACKEND", "dummy")

import numpy as np  # noqa: E402
import robosuite  # noqa: E402

import veragmil_suite  # noqa: E402, F401  (registers ScoopGranular)
from veragmil_suite.devices import VRDevice, VRServerOptions, VRStreamOptions  # noqa: E402
from veragmil_suite.devices.vr.client import HAND, Client, controller, pose_message, ws_url  # noqa: E402
from veragmil_suite.devices.vr.protocol import unpack_frame  # noqa: E402
from veragmil_suite.devices.vr.render import Renderer, depth_colormap, encode_jpeg  # noqa: E402
from veragmil_suite.utils import cli  # noqa: E402
from veragmil_suite.utils.timing import per_call  # noqa: E402

SECTIONS = (1, 2, 3, 4, 5)  # the numbered parts of this module's docstring


def make(env_name: str, control_freq: int = 20, physics: str | None = None):
    """The benchmarked environment; ``physics`` (ScoopGranular's, veragmil_suite.models.foods.PHYSICS) None: its
    default."""
    kwargs = dict(robots="XArm7", has_renderer=False, has_offscreen_renderer=False, use_camera_obs=False)
    if env_name == "ScoopGranular":
        kwargs.update(food="rice", pile_variants=1)
        if physics is not None:
            kwargs.update(physics=physics)
    env = robosuite.make(env_name, control_freq=control_freq, ignore_done=True, **kwargs)
    env.reset()
    return env


def env_action(env, device, action: dict) -> np.ndarray:
    robot = env.robots[0]
    parts = {arm: action[f"{arm}_delta"] for arm in robot.arms}
    parts.update({f"{a}_gripper": action[f"{a}_gripper"] for a in robot.arms if robot.gripper[a].dof > 0})
    return robot.create_action_vector(parts)


def timed(fn, n: int) -> float:
    """Milliseconds per call of ``fn`` (after one untimed call)."""
    return 1000 * per_call(fn, n).wall_s


def bench_render() -> None:
    """Section 1: the streamed camera rendered and JPEG-encoded, ms per frame."""
    env = make("ScoopGranular")
    model, data = env.sim.model._model, env.sim.data._data
    print("1. streamed camera: ScoopGranular 'overhead', 320x240, RGB + depth, osmesa (software)")
    for fast in (False, True):
        r = Renderer("overhead", 320, 240, fast=fast)
        r.load(model)
        ms = timed(lambda r=r: r.render(data.qpos, data.mocap_pos, data.mocap_quat), 20)
        label = "stream settings (offsamples 0, no shadows/reflections)" if fast else "MuJoCo's default quality"
        print(f"   render {label:55s} {ms:6.1f} ms  ({1000 / ms:5.1f} fps)")
    rgb, depth = r.render(data.qpos, data.mocap_pos, data.mocap_quat)
    image = np.concatenate([rgb, depth_colormap(depth, 0.2, 2.5)], axis=1)
    for encoder in ("opencv", "pillow"):
        ms = timed(lambda e=encoder: encode_jpeg(image, 80, e), 100)
        size = len(encode_jpeg(image, 80, encoder))
        print(f"   JPEG q80 640x240 with {encoder:7s} {ms:6.2f} ms, {size / 1024:5.1f} KiB")
    env.close()


def _flood(url: str, n: int, out) -> None:
    """Child process: send n pose messages as fast as the socket takes them."""
    import aiohttp  # in the child process that uses it

    async def run():
        msgs = [pose_message(i, float(i), right=controller(squeeze=0.0)) for i in range(n)]
        async with aiohttp.ClientSession() as s:
            async with s.ws_connect(ws_url(url)) as ws:
                await ws.send_str(json.dumps({"v": 1, "type": "hello", "token": None, "client": "bench"}))
                await ws.receive()  # welcome
                t0 = time.perf_counter()
                for m in msgs:
                    await ws.send_str(m)
                out.put(time.perf_counter() - t0)
                await asyncio.sleep(1.0)

    asyncio.run(run())


def bench_messages(n: int) -> None:
    """Section 2: pose messages the device handles per second, sent as fast as the socket takes them."""
    env = make("Lift")
    device = VRDevice(env, server=VRServerOptions(port=0), verbose=False)
    try:
        ctx = multiprocessing.get_context("spawn")
        out = ctx.Queue()
        handled0 = device.messages_handled
        proc = ctx.Process(target=_flood, args=(device.url, n, out))
        t0 = time.perf_counter()
        proc.start()
        t_first = None
        while device.messages_handled - handled0 < n and time.perf_counter() - t0 < 120:
            if t_first is None and device.messages_handled > handled0:
                t_first = time.perf_counter()
            time.sleep(0.001)
        t_last = time.perf_counter()
        first = device.server.stats()
        send_s = out.get(timeout=30)
        proc.join(10)
        handled = device.messages_handled - handled0
        rate = handled / max(t_last - (t_first or t0), 1e-9)  # from the first message handled to the last
        stats = device.stats()
        print("2. messages: a client process sending pose messages as fast as it can")
        print(f"   {handled} handled of {n} sent (client sending for {send_s:.2f} s): {rate:,.0f} messages/s handled")
        print(f"   device time per message (filters, buttons): {stats['handle_us']:.0f} us; dropped: "
              f"{first['malformed'] + first['oversized'] + first['out_of_order']}")  # fmt: skip
    finally:
        device.close()
        env.close()


def bench_latency(seconds: float) -> None:
    """Section 3: a pose message's way from the client to the device's action, ms."""
    env = make("Lift")
    device = VRDevice(env, server=VRServerOptions(port=0), verbose=False)
    client = Client(device.url).connect()
    try:
        device.start_control()
        state = {"dx": 0.0, "sent": None}

        def script(t):
            return dict(right=controller(p=(HAND[0] + state["dx"], HAND[1], HAND[2]), squeeze=0.0 if t < 0.3 else 1.0))

        future = client.play(script, duration=seconds, rate=90.0)
        ages, delays = [], []
        period = env.control_timestep
        start = time.monotonic()
        k = 0
        next_step_at = start + 1.0
        while not future.done():
            action = device.input2action()
            now = time.monotonic()
            if device.pose_age is not None and now - start > 0.5:
                ages.append(1000 * device.pose_age)
            if state["sent"] is not None and np.abs(action["right_delta"][:3]).max() > 0.05:
                delays.append(1000 * (now - state["sent"]))
                state["sent"] = None
            if state["sent"] is None and now > next_step_at and device.engaged:
                state["dx"] = 0.02 if state["dx"] == 0 else 0.0  # a 2 cm hand step, back and forth
                state["sent"] = time.monotonic()
                next_step_at = now + 0.8
            env.step(env_action(env, device, action))
            k += 1
            delay = start + k * period - time.monotonic()
            if delay > 0:
                time.sleep(delay)
        print("3. pose-to-action latency: 20 Hz control loop, page at 90 Hz")
        p95 = np.percentile(ages, 95)
        print(f"   age of the newest pose at each action: mean {np.mean(ages):.1f} ms, p95 {p95:.1f} ms")
        print(f"   hand step -> first action moving for it: mean {np.mean(delays):.1f} ms, max {np.max(delays):.1f} ms "
              f"({len(delays)} steps; includes waiting for the next 50 ms control step)")  # fmt: skip
    finally:
        client.close()
        device.close()
        env.close()


def bench_env_alone(env_name: str, control_freq: int, steps: int) -> float:
    """ms per env.step with a zero action and nothing else running in this process: the baseline."""
    env = make(env_name, control_freq)
    zero = np.zeros(env.action_dim)
    ms = timed(lambda: env.step(zero), steps)
    env.close()
    return ms


def bench_stream(env_name: str, control_freq: int, seconds: float, depth: bool = True) -> None:
    """Section 4: frames per second streamed beside the control loop, and what streaming costs the env's step."""
    alone = bench_env_alone(env_name, control_freq, 40)
    env = make(env_name, control_freq)
    camera = "overhead" if env_name == "ScoopGranular" else "agentview"
    device = VRDevice(
        env, server=VRServerOptions(port=0), stream=VRStreamOptions(depth=depth), camera_name=camera, verbose=False
    )
    client = Client(device.url).connect()
    try:
        device.start_control()
        future = client.play(lambda t: dict(right=controller(squeeze=0.0)), duration=seconds, rate=90.0)
        period = env.control_timestep
        start = time.monotonic()
        sim0 = env.sim.data.time
        k = 0
        busy = 0.0
        while not future.done():
            t0 = time.monotonic()
            env.step(env_action(env, device, device.input2action()))
            busy += time.monotonic() - t0
            k += 1
            delay = start + k * period - time.monotonic()
            if delay > 0:
                time.sleep(delay)  # paced to the control rate; when behind, it runs flat out (not real time)
        wall = time.monotonic() - start
        frames = [t for t, _ in client.frames if t > client.t0 + 1.0]
        fps = len(frames) / max(frames[-1] - frames[0], 1e-9) if len(frames) > 1 else 0.0
        rtf = (env.sim.data.time - sim0) / wall
        s = device.stream.stats()
        panels = "RGB+depth" if depth else "RGB"
        step_ms = 1000 * busy / max(k, 1)
        print(f"   {env_name:13s} {control_freq:2d} Hz {panels:9s}: {fps:5.1f} frames/s streamed, real-time factor "
              f"{rtf:4.2f}, step {step_ms:5.1f} ms (env alone {alone:5.1f}); renderer {s['render_ms']:5.1f} ms "
              f"render + {s['encode_ms']:4.1f} ms encode")  # fmt: skip
    finally:
        client.close()
        device.close()
        env.close()


MOVE_M = 0.02  # the hand's step, along the operator's right
MOVE_EVERY_S = (0.6, 0.9)  # drawn at random, so that moves fall at every phase of the control period
SWITCH_S = 4.0  # each frame schedule in turn for this long
# (name, from, to): the stages of a move's way, in the times a frame's timing block carries ("client_sent": the
# move's first message left the client; "received": the frame reached the client)
STAGES = (
    ("pose sent -> control step begins", "client_sent", "action"),
    ("control step", "action", "captured"),
    ("state to the renderer", "captured", "render_start"),
    ("render", "render_start", "rendered"),
    ("depth map + JPEG encode", "rendered", "encoded"),
    ("JPEG back to the stream", "encoded", "published"),
    ("server event loop", "published", "sent"),
    ("socket -> client", "sent", "received"),
)


def _hand_client(url: str, trials: int, seed: int, out) -> None:
    """Child process, the page's part: sends the right hand at 90 Hz with the grip held, moves it MOVE_M back or
    forth every MOVE_EVERY_S, and stamps each move's first message; stamps every frame on arrival and decodes it as
    the page would. Puts (moves [(seq, t_sent)], frames [(t_received, timing, decode_ms)]) on out."""
    import aiohttp  # in the child process that uses it
    from PIL import Image  # in the child process that uses it

    rng = random.Random(seed)

    async def run():
        moves, frames = [], []
        async with aiohttp.ClientSession() as session:
            async with session.ws_connect(ws_url(url), max_msg_size=0) as ws:
                await ws.send_str(json.dumps({"v": 1, "type": "hello", "token": None, "client": "bench"}))

                async def receive():
                    async for msg in ws:
                        t = time.monotonic()
                        if msg.type == aiohttp.WSMsgType.BINARY:
                            header, jpeg = unpack_frame(msg.data)
                            t0 = time.perf_counter()
                            Image.open(io.BytesIO(jpeg)).load()
                            frames.append((t, header.get("timing"), 1000 * (time.perf_counter() - t0)))
                        elif msg.type == aiohttp.WSMsgType.TEXT:
                            data = json.loads(msg.data)
                            if data["type"] == "ping":
                                await ws.send_str(json.dumps({"v": 1, "type": "pong", "id": data["id"]}))

                receiver = asyncio.create_task(receive())
                start = time.monotonic()
                next_move = start + 1.5  # engaged by then
                dx, seq = 0.0, 0
                while len(moves) < trials:
                    delay = start + seq / 90.0 - time.monotonic()
                    if delay > 0:
                        await asyncio.sleep(delay)
                    now = time.monotonic()
                    moved = now >= next_move
                    if moved:
                        dx = MOVE_M - dx
                        next_move = now + rng.uniform(*MOVE_EVERY_S)
                    hand = controller(p=(HAND[0] + dx, HAND[1], HAND[2]), squeeze=0.0 if now - start < 0.3 else 1.0)
                    msg = pose_message(seq, 1000.0 * (now - start), right=hand)
                    sent = time.monotonic()
                    await ws.send_str(msg)
                    if moved:
                        moves.append((seq, sent))
                    seq += 1
                await asyncio.sleep(1.0)  # the last move's frames
                receiver.cancel()
        out.put((moves, frames))

    asyncio.run(run())


def hand_to_frame_trials(moves: list, frames: list) -> list[dict]:
    """Per move, the times of its way (keys of STAGES, "decode_ms", and "finished": when the client received the
    first frame of that control step once finished, or of a later step): the first frame received whose control
    step's action came from the move's first message or a later one. Moves no frame showed are left out."""
    rows = []
    i = 0
    for seq, sent in moves:
        while i < len(frames) and (frames[i][1] is None or frames[i][1]["pose_seq"] < seq):
            i += 1
        if i == len(frames):
            break
        received, timing, decode_ms = frames[i]
        later = (t for t, f, _ in frames[i:] if f is not None and (f["step"] > timing["step"] or not f["mid_step"]))
        finished = next(later, float("nan"))
        rows.append(dict(timing, client_sent=sent, received=received, decode_ms=decode_ms, finished=finished))
    return rows


def _summary(values) -> str:
    v = np.asarray(values, dtype=float)
    v = v[np.isfinite(v)]
    if v.size == 0:
        return "      (no data)"
    return f"{np.median(v):6.1f} {np.percentile(v, 90):6.1f} {v.max():6.1f}"


def bench_hand_to_frame(trials: int, env_name: str = "ScoopGranular", physics: str | None = None) -> None:
    """Section 5: hand to frame. Both frame schedules in turn, SWITCH_S each, with one client throughout: a machine
    whose load changes affects both alike. A move counts for the schedule in force from just before it to its
    frame."""
    env = make(env_name, physics=physics)
    camera = "overhead" if env_name == "ScoopGranular" else "agentview"
    device = VRDevice(env, server=VRServerOptions(port=0), camera_name=camera, verbose=False)
    schedules = {True: "after each control step", False: "on a 30 fps clock"}
    stats = {sync: dict(steps=0, busy=0.0, sim=0.0, wall=0.0) for sync in schedules}
    switches = []  # (time, sync)
    ctx = multiprocessing.get_context("spawn")
    out = ctx.Queue()
    moves = int(2.5 * trials) + 4  # about 1 in 5 moves straddles a switch and counts for neither schedule
    proc = ctx.Process(target=_hand_client, args=(device.url, moves, 0, out))
    period = env.control_timestep
    try:
        proc.start()
        device.start_control()
        start = time.monotonic()
        k, got, sync = 0, None, None
        while got is None and time.monotonic() - start < 120 + 2 * moves:
            t0 = time.monotonic()
            if not switches or t0 - switches[-1][0] >= SWITCH_S:
                sync = not switches or not sync
                device.stream.sync_to_steps = sync
                switches.append((t0, sync))
            sim0 = env.sim.data.time
            env.step(env_action(env, device, device.input2action()))
            t1 = time.monotonic()
            k += 1
            delay = start + k * period - t1
            if delay > 0:
                time.sleep(delay)
            st = stats[sync]
            st["steps"] += 1
            st["busy"] += t1 - t0
            st["sim"] += env.sim.data.time - sim0
            st["wall"] += time.monotonic() - t0
            if not out.empty():
                got = out.get()
        proc.join(10)
        if got is None:
            raise RuntimeError("the hand-to-frame client did not finish")
    finally:
        if proc.is_alive():
            proc.kill()
        device.close()
        env.close()
    moves, frames = got
    times = np.array([t for t, _ in switches])

    def schedule(t0: float, t1: float):
        """The schedule in force from t0 to t1, None when it changed in between (or just before: the stream sees
        a change at its next decision)."""
        i, j = np.searchsorted(times, [t0 - 0.05, t1], side="right") - 1
        return switches[i][1] if i == j and i >= 0 else None

    task = "ScoopGranular (rice)" if env_name == "ScoopGranular" else env_name
    print(f"5. hand-to-frame: {task}, 20 Hz control in real time, 320x240 RGB+depth; a client process moves the")
    print(f"   hand 2 cm, the frame schedule changes every {SWITCH_S:.0f} s; ms, median / p90 / max over the moves")
    rows = hand_to_frame_trials(moves, frames)
    for sync, name in schedules.items():
        mine = [r for r in rows if schedule(r["client_sent"], np.nan_to_num(r["finished"], nan=np.inf)) is sync]
        seen = [t for t, _, _ in frames if schedule(t - 0.2, t) is sync]  # frames of the schedule, once settled
        ends = [*times[1:], frames[-1][0] if frames else times[-1]]
        spans = sum(max(end - t - 0.25, 0.0) for (t, s_), end in zip(switches, ends) if s_ is sync)
        mid = np.mean([r["mid_step"] for r in mine]) if mine else 0.0
        st = stats[sync]
        print(f"   frames {name}: {len(mine)} moves, {len(seen) / max(spans, 1e-9):4.1f} frames/s received, "
              f"real-time factor {st['sim'] / max(st['wall'], 1e-9):4.2f}, control step "
              f"{1000 * st['busy'] / max(st['steps'], 1):5.1f} ms, {100 * mid:3.0f}% of frames show a step "
              "half done")  # fmt: skip
        total = [1000 * (r["received"] - r["client_sent"]) for r in mine]
        print(f"      {'hand -> frame received':36s} {_summary(total)}")
        if mid > 0:
            finished = [1000 * (r["finished"] - r["client_sent"]) for r in mine]
            print(f"      {'  (its step finished in a frame)':36s} {_summary(finished)}")
        for label, a, b in STAGES:
            print(f"        {label:34s} {_summary([1000 * (r[b] - r[a]) for r in mine])}")
        print(f"      {'client JPEG decode':36s} {_summary([r['decode_ms'] for r in mine])}")
        decoded = [1000 * (r["received"] - r["client_sent"]) + r["decode_ms"] for r in mine]
        print(f"      {'hand -> frame decoded':36s} {_summary(decoded)}")


def build_parser() -> cli.Parser:
    parser = cli.Parser("bench_vr.py", description=__doc__)
    parser.add_argument("--seconds", type=cli.positive, default=8.0, help="length of each real-time run")
    parser.add_argument("--messages", type=cli.count, default=20000, help="messages in the throughput run")
    parser.add_argument(
        "--trials", type=cli.count, default=100, help="hand moves per frame schedule in the hand-to-frame run"
    )
    parser.add_argument(
        "--sections",
        type=cli.ListOf(cli.Integer(1, len(SECTIONS), accepted=f"a section in [1, {len(SECTIONS)}]")),
        default=list(SECTIONS),
        help="which sections to run, e.g. 5 or 1,3",
    )
    parser.add_argument(
        "--env",
        type=cli.Choice("environment", ("ScoopGranular", "Lift")),
        default="ScoopGranular",
        help="hand-to-frame: the task (Lift: a cheaper simulation)",
    )
    parser.add_argument(
        "--physics", type=cli.physics, help="hand-to-frame: ScoopGranular's physics (default: the task's)"
    )
    return parser


@cli.command(build_parser)
def main(args: argparse.Namespace) -> int:
    """The sections asked for, in order."""
    sections = set(args.sections)
    print(f"{os.cpu_count()} CPUs, MUJOCO_GL={os.environ['MUJOCO_GL']}, load average {os.getloadavg()[0]:.2f}")
    if 1 in sections:
        bench_render()
    if 2 in sections:
        bench_messages(args.messages)
    if 3 in sections:
        bench_latency(args.seconds)
    if 4 in sections:
        print("4. frames/s streamed while the environment keeps real time (client at 90 Hz connected)")
        bench_stream("Lift", 20, args.seconds)
        bench_stream("ScoopGranular", 20, args.seconds)
        bench_stream("ScoopGranular", 20, args.seconds, depth=False)
        bench_stream("ScoopGranular", 60, args.seconds)
    if 5 in sections:
        bench_hand_to_frame(args.trials, args.env, args.physics)
    print(f"load average at the end {os.getloadavg()[0]:.2f} (other processes share the CPUs: figures are theirs too)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
