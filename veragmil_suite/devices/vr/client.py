"""A scripted stand-in for the VR page: speaks schema v1 over the WebSocket from its own thread and event loop.

For tests, the benchmark (benchmarks/bench_vr.py), and checking a server without a headset::

    python -m veragmil_suite.devices.vr.client http://localhost:8765/ --seconds 5

connects, squeezes, traces a 5 cm circle with the right hand and prints what came back.
"""

from __future__ import annotations

import argparse
import asyncio
import json
import math
import sys
import threading
import time
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING, Any

import aiohttp

from veragmil_suite.devices.vr.protocol import unpack_frame
from veragmil_suite.devices.vr.server_options import CLOSE_FINISHED
from veragmil_suite.utils import cli

if TYPE_CHECKING:
    from concurrent.futures import Future

HAND = (0.2, 1.1, -0.3)  # a right hand held in front of a standing operator (XR frame)
IDENTITY = (0.0, 0.0, 0.0, 1.0)


def controller(
    p: Sequence[float] = HAND,
    q: Sequence[float] = IDENTITY,
    squeeze: float = 0.0,
    trigger: float = 0.0,
    stick: Sequence[float] = (0.0, 0.0),
    stick_press: bool = False,
    a: bool = False,
    b: bool = False,
    emulated: bool = False,
) -> dict:
    return {
        "p": list(p),
        "q": list(q),
        "emulated": emulated,
        "trigger": trigger,
        "squeeze": squeeze,
        "stick": list(stick),
        "stick_press": stick_press,
        "a": a,
        "b": b,
    }


def pose_message(seq: int, t_ms: float, right: dict | None = None, left: dict | None = None,
                 head_q: Sequence[float] = IDENTITY, visible: bool = True) -> str:  # fmt: skip
    return json.dumps(
        {
            "v": 1,
            "type": "pose",
            "seq": seq,
            "t": t_ms,
            "visible": visible,
            "head": {"p": [0.0, 1.6, 0.0], "q": list(head_q)},
            "right": right,
            "left": left,
        }
    )


def ws_url(http_url: str) -> str:
    return http_url.replace("http", "ws", 1) + "ws"


class Client:
    """A page without a browser: connects, says hello, answers pings, collects frames and status messages.

    ``play(script, duration, rate)`` sends ``pose_message(**script(t))`` at ``rate`` Hz for ``duration`` seconds
    from the client's thread, timestamped like XR frames, while the test's thread steps the environment.
    Like the page, it closes the connection on a final status (``finished``); ``close_on_final=False`` plays a
    page that does not.
    """

    def __init__(
        self, http_url: str, token: str | None = None, headers: dict | None = None, close_on_final: bool = True
    ):
        self.url = ws_url(http_url)
        self.token = token
        self.headers = headers or {}
        self.frames: list[tuple[float, dict]] = []
        self.statuses: list[dict] = []
        self.welcome: dict | None = None
        self.last_jpeg: bytes | None = None
        self.close_code: int | None = None
        self.close_on_final = close_on_final
        self.finished = False
        self.seq = 0
        self.t0 = time.monotonic()
        self.last_t_ms = 0.0
        self._loop = asyncio.new_event_loop()
        self._thread = threading.Thread(target=self._loop.run_forever, daemon=True)
        self._thread.start()
        self._ws = None
        self._session = None
        self._closed = threading.Event()

    def _run(self, coro, timeout=30.0):
        return asyncio.run_coroutine_threadsafe(coro, self._loop).result(timeout)

    def connect(self, hello: str | None = None, wait_welcome: bool = True) -> Client:
        self._run(self._connect(hello, wait_welcome))
        return self

    async def _connect(self, hello, wait_welcome):
        self._session = aiohttp.ClientSession()
        try:
            self._ws = await self._session.ws_connect(self.url, headers=self.headers, max_msg_size=0)
        except Exception:
            await self._session.close()
            self._session = None
            raise
        self._closed.clear()
        self._loop.create_task(self._receive(self._ws))
        await self._ws.send_str(hello or json.dumps({"v": 1, "type": "hello", "token": self.token, "client": "test"}))
        if wait_welcome:
            for _ in range(500):
                if self.welcome is not None or self._closed.is_set():
                    break
                await asyncio.sleep(0.01)

    async def _receive(self, ws):
        async for msg in ws:
            if msg.type == aiohttp.WSMsgType.BINARY:
                header, jpeg = unpack_frame(msg.data)
                self.frames.append((time.monotonic(), header))
                self.last_jpeg = jpeg
            elif msg.type == aiohttp.WSMsgType.TEXT:
                data = json.loads(msg.data)
                if data["type"] == "welcome":
                    self.welcome = data
                elif data["type"] == "status":
                    self.statuses.append(data)
                    if data.get("final") and self.close_on_final:
                        self.finished = True
                        await ws.close(code=CLOSE_FINISHED, message=b"finished")
                elif data["type"] == "ping":
                    await ws.send_str(json.dumps({"v": 1, "type": "pong", "id": data["id"]}))
        self.close_code = ws.close_code
        self._closed.set()

    def wait_closed(self, timeout: float = 5.0) -> int | None:
        self._closed.wait(timeout)
        return self.close_code

    def send(self, data: str | bytes) -> None:
        async def _send():
            if isinstance(data, bytes):
                await self._ws.send_bytes(data)
            else:
                await self._ws.send_str(data)

        self._run(_send())

    def send_pose(self, t_ms: float | None = None, **kwargs: Any) -> None:
        """One pose message with the next seq, timestamped t_ms (default: now); kwargs of ``pose_message``."""
        t_ms = 1000.0 * (time.monotonic() - self.t0) if t_ms is None else t_ms
        self.send(pose_message(self.seq, t_ms, **kwargs))
        self.seq += 1
        self.last_t_ms = t_ms

    def play(self, script: Callable[[float], dict | None], duration: float, rate: float = 90.0) -> Future[int]:
        """Send ``pose_message(**script(t))`` (None: send nothing) at rate Hz; returns a Future."""

        async def _play():
            start = time.monotonic()
            k = 0
            while True:
                t = k / rate
                if t > duration:
                    return k
                delay = start + t - time.monotonic()
                if delay > 0:
                    await asyncio.sleep(delay)
                kwargs = script(t)
                if kwargs is not None and not self._ws.closed:
                    self.last_t_ms = max(self.last_t_ms + 1e-3, 1000.0 * (time.monotonic() - self.t0))
                    await self._ws.send_str(pose_message(self.seq, self.last_t_ms, **kwargs))
                    self.seq += 1
                k += 1

        return asyncio.run_coroutine_threadsafe(_play(), self._loop)

    def close(self) -> None:
        async def _close():
            if self._ws is not None:
                await self._ws.close()
            if self._session is not None:
                await self._session.close()

        if self._loop.is_running():
            self._run(_close())
            self._loop.call_soon_threadsafe(self._loop.stop)
            self._thread.join(5)
        if not self._loop.is_running() and not self._loop.is_closed():
            self._loop.close()  # else the garbage collector closes it, by then perhaps after its own sockets


def build_parser() -> cli.Parser:
    parser = cli.Parser(
        "python -m veragmil_suite.devices.vr.client",
        description="Drive a VR server like the headset's page would, without a headset.",
    )
    parser.add_argument("url", type=cli.url, help="the page's address, e.g. http://localhost:8765/")
    parser.add_argument("--token", type=cli.text, help="pairing token (servers bound beyond localhost)")
    parser.add_argument("--seconds", type=cli.positive, default=5.0, help="how long the hand draws its circle")
    parser.add_argument("--radius", type=cli.positive, default=0.05, help="circle radius, metres")
    return parser


@cli.command(build_parser)
def main(args: argparse.Namespace) -> int:
    """Connects, draws a circle with the right hand holding the grip, and says what the server streamed."""
    try:
        client = Client(args.url, token=args.token).connect()
    except (aiohttp.ClientError, OSError) as error:
        raise cli.UsageError(f"{args.url}: no VR server answers there ({cli.one_line(error)})") from None
    if client.welcome is None:
        client.close()
        raise cli.UsageError(
            f"{args.url}: the server sent no welcome (close code {client.close_code}); a wrong --token?"
        )
    print("welcome:", json.dumps(client.welcome["config"]))

    def circle(t: float) -> dict:
        w = 2 * math.pi * 0.25 * max(t - 0.5, 0.0)
        p = (HAND[0] + args.radius * math.sin(w), HAND[1] + args.radius * (1 - math.cos(w)), HAND[2])
        return dict(right=controller(p=p, squeeze=0.0 if t < 0.3 else 1.0))

    client.play(circle, args.seconds).result(args.seconds + 10)
    time.sleep(0.3)
    fps = len([f for f in client.frames if f[0] > client.t0 + 1.0]) / max(args.seconds - 1.0, 1e-9)
    print(f"frames: {len(client.frames)} ({fps:.1f}/s after the first second)")
    if client.statuses:
        print("status:", client.statuses[-1]["text"])
    client.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
