"""Benchmark of the VR teleoperation path: pose-to-action latency, messages/s handled, frames/s streamed.

    python scripts/bench_vr.py              # about a minute and a half
    python scripts/bench_vr.py --seconds 4  # shorter runs, noisier figures

1. Rendering and JPEG encoding of the streamed camera (ScoopGranular's overhead camera, 320x240 RGB + depth):
   MuJoCo's default quality against the stream's settings (no multisampling, shadows or reflections, coarse
   primitives), and OpenCV against Pillow on the 640x240 RGB|depth image.
2. Messages/s: a client process sends pose messages as fast as it can; how many the server validates and the device
   filters per second, and the device's time per message.
3. Pose-to-action latency, in robosuite's loop at 20 Hz with the page's 90 Hz: the age of the newest pose when an
   action is computed, and the time from a hand step leaving the client to the first action that moves for it.
4. Frames/s streamed while the environment runs in real time (a client at 90 Hz connected, the loop paced to the
   control rate): frames received per second, control steps per second achieved, renderer times.
"""

from __future__ import annotations

import argparse
import asyncio
import json
import multiprocessing
import os
import runpy
import time
from pathlib import Path

# OSMesa whatever the display, set before robosuite is imported: veragmil_suite.rendering is run from its file, as
# importing it through the package would import robosuite first
runpy.run_path(str(Path(__file__).resolve().parents[1] / "veragmil_suite" / "rendering.py"))["use_headless_rendering"]()
os.environ.setdefault("PYNPUT_BACKEND", "dummy")

import numpy as np  # noqa: E402
import robosuite  # noqa: E402

import veragmil_suite  # noqa: E402, F401  (registers ScoopGranular)
from veragmil_suite.devices import VRDevice, VRServerOptions, VRStreamOptions  # noqa: E402
from veragmil_suite.devices.vr_client import HAND, Client, controller, pose_message, ws_url  # noqa: E402
from veragmil_suite.devices.vr_render import Renderer, depth_colormap, encode_jpeg  # noqa: E402


def make(env_name: str, control_freq: int = 20):
    kwargs = dict(robots="XArm7", has_renderer=False, has_offscreen_renderer=False, use_camera_obs=False)
    if env_name == "ScoopGranular":
        kwargs.update(food="rice", pile_variants=1)
    env = robosuite.make(env_name, control_freq=control_freq, ignore_done=True, **kwargs)
    env.reset()
    return env


def env_action(env, device, action: dict) -> np.ndarray:
    robot = env.robots[0]
    parts = {arm: action[f"{arm}_delta"] for arm in robot.arms}
    parts.update({f"{a}_gripper": action[f"{a}_gripper"] for a in robot.arms if robot.gripper[a].dof > 0})
    return robot.create_action_vector(parts)


def timed(fn, n: int) -> float:
    fn()
    t0 = time.perf_counter()
    for _ in range(n):
        fn()
    return 1000 * (time.perf_counter() - t0) / n


# ------------------------------------------------------------------------------------------------ 1. render, encode
def bench_render() -> None:
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


# ------------------------------------------------------------------------------------------------ 2. messages/s
def _flood(url: str, n: int, out) -> None:
    """Child process: send n pose messages as fast as the socket takes them."""
    import aiohttp

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


# ------------------------------------------------------------------------------------------------ 3. latency
def bench_latency(seconds: float) -> None:
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


# ------------------------------------------------------------------------------------------------ 4. frames/s
def bench_env_alone(env_name: str, control_freq: int, steps: int) -> float:
    """ms per env.step with a zero action and nothing else running in this process: the baseline."""
    env = make(env_name, control_freq)
    zero = np.zeros(env.action_dim)
    ms = timed(lambda: env.step(zero), steps)
    env.close()
    return ms


def bench_stream(env_name: str, control_freq: int, seconds: float, depth: bool = True) -> None:
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


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--seconds", type=float, default=8.0, help="length of each real-time run")
    p.add_argument("--messages", type=int, default=20000, help="messages in the throughput run")
    args = p.parse_args()
    print(f"{os.cpu_count()} CPUs, MUJOCO_GL={os.environ['MUJOCO_GL']}, load average {os.getloadavg()[0]:.2f}")
    bench_render()
    bench_messages(args.messages)
    bench_latency(args.seconds)
    print("4. frames/s streamed while the environment keeps real time (client at 90 Hz connected)")
    bench_stream("Lift", 20, args.seconds)
    bench_stream("ScoopGranular", 20, args.seconds)
    bench_stream("ScoopGranular", 20, args.seconds, depth=False)
    bench_stream("ScoopGranular", 60, args.seconds)
    print(f"load average at the end {os.getloadavg()[0]:.2f} (other processes share the CPUs: figures are theirs too)")


if __name__ == "__main__":
    main()
