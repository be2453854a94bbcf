"""The VR server: one port serving the WebXR page and a WebSocket, in a background thread (aiohttp).

One operator drives the robot at a time: the newest authenticated connection wins and the previous one is closed
(a page reload reconnects before the old socket has timed out). Every message is validated
(``vr_protocol.parse_client_message``); malformed, oversized, out-of-order and unauthenticated messages are
dropped and counted in ``stats()``, never raised: the teleoperation loop must outlive anything a client sends.

Security: the server binds to 127.0.0.1 by default (USB with ``adb reverse``). Binding any other address needs a
pairing token (generated when not given, shown in the terminal, entered on the page or passed as ``?token=``),
and turns HTTPS on by default. Repeated wrong tokens lock the address out for a minute, so the 40-bit token
cannot be guessed online. Browsers may only open the WebSocket from the page's own origin, so another web site
open in the operator's browser cannot drive the robot through localhost; and a server bound to localhost answers
only requests addressed to localhost, so no site can reach it by pointing its own name at 127.0.0.1 (DNS
rebinding).

Connections are admitted by ``vr_connections``: at most ``max_connections`` open, TLS handshakes included, and a
slot of its own for the operator's authenticated WebSocket; at the cap a new connection replaces the oldest one not
in a request (else the oldest other one), so the operator always gets in; each address is held to a connection
rate when the server is open to the network; and refusals, evictions, timeouts and malformed HTTP requests are
counted and summed up in one log line every ``SUMMARY_INTERVAL_S`` at most, never logged one traceback each.

Camera frames are sent newest-first: the server keeps only the latest frame, and a connection still busy sending
the previous one skips to whatever is newest when it is done (``frames_skipped``).
"""

from __future__ import annotations

import asyncio
import collections
import logging
import math
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from aiohttp import WSCloseCode, WSMsgType, web
from aiohttp.http_exceptions import HttpProcessingError

from veragmil_suite.devices.vr import tls as vr_tls
from veragmil_suite.devices.vr.connections import ConnectionPool
from veragmil_suite.devices.vr.protocol import (
    MAX_MESSAGE_BYTES,
    PongMessage,
    PoseMessage,
    ProtocolError,
    parse_client_message,
    server_message,
    stamp_sent,
)
from veragmil_suite.devices.vr.server_access import ServerAccessMixin
from veragmil_suite.devices.vr.server_options import (
    CLOSE_FINISHED,
    CLOSE_SUPERSEDED,
    CONNECT_RATE,
    COUNTERS,
    FAREWELL_TIMEOUT_S,
    LOOP_STALL_S,
    MAX_WS_FRAME_BYTES,
    PING_INTERVAL_S,
    SUMMARIZED,
    SUMMARY_INTERVAL_S,
    VRServerOptions,
    is_loopback,
    new_token,
)

LOG = logging.getLogger(__name__)


class _RequestLog(logging.LoggerAdapter):
    """aiohttp's server log, with malformed requests counted instead of logged: a traceback each would let any
    client fill the terminal before its token is ever checked."""

    def __init__(self, note: Callable[[str], None]):
        super().__init__(logging.getLogger("aiohttp.server"), {})
        self._note = note

    def log(self, level: int, msg: object, *args: object, exc_info: Any = None, **kwargs: Any) -> None:
        if isinstance(exc_info, HttpProcessingError):
            self._note("malformed_http")
        else:
            super().log(level, msg, *args, exc_info=exc_info, **kwargs)


class VRServer(ServerAccessMixin):
    """aiohttp server for the VR page, running its own event loop in a daemon thread.

    Args:
        options (VRServerOptions or None): address, security and timeouts; None: the defaults
        on_pose (callable): ``on_pose(msg: PoseMessage, recv_time: float)`` called in the server thread
        on_connect, on_disconnect (callable): called in the server thread with the connection number
        config (dict): sent to the page in the welcome message
    """

    def __init__(
        self,
        options: VRServerOptions | None = None,
        on_pose: Callable[[PoseMessage, float], None] | None = None,
        on_connect: Callable[[int], None] | None = None,
        on_disconnect: Callable[[int], None] | None = None,
        config: dict | None = None,
    ):
        options = VRServerOptions() if options is None else options
        self.host = options.host
        self.requested_port = options.port
        self.requires_token = options.token is not None or not is_loopback(options.host)
        self.token = (options.token or new_token()) if self.requires_token else None
        self.tls = (not is_loopback(options.host)) if options.tls is None else options.tls
        self.cert, self.key, self.cert_dir = options.cert, options.key, options.cert_dir
        self.on_pose = on_pose
        self.on_connect = on_connect
        self.on_disconnect = on_disconnect
        self.config = dict(config or {})
        self.status_interval = 1.0 / options.status_hz
        self.hello_timeout = options.hello_timeout
        self.auth_failure_delay = options.auth_failure_delay
        self.web_dir = Path(options.web_dir)
        self.max_connections = int(options.max_connections)
        self.request_timeout = float(options.request_timeout)
        self.heartbeat_timeout = float(options.heartbeat_timeout)
        default_rate = CONNECT_RATE if self.requires_token else math.inf
        self.connect_rate = default_rate if options.connect_rate is None else float(options.connect_rate)
        self._pool: ConnectionPool | None = None
        self._summarized = collections.Counter()  # SUMMARIZED counts since the last summary (the server thread's)
        self._summary: asyncio.TimerHandle | None = None
        self._tcp_server: asyncio.AbstractServer | None = None
        self.port: int | None = None
        self.fingerprint: str | None = None

        self._counts = collections.Counter({k: 0 for k in COUNTERS})
        self._counts_lock = threading.Lock()
        self._frame: tuple[int, bytes] | None = None
        self._status: tuple[int, str] | None = None
        self._publish_lock = threading.Lock()
        self._failures: dict[str, collections.deque] = {}
        self._client: web.WebSocketResponse | None = None
        self._client_gone: asyncio.Event | None = None  # set when the client's handler has returned
        self._client_id = 0
        self._rtt_ms: float | None = None
        self._pings: dict[int, float] = {}
        self._ping_id = 0  # across connections: a late pong of an old connection matches nothing
        self._last_message_time: float | None = None
        self._loop: asyncio.AbstractEventLoop | None = None
        self._wake: asyncio.Event | None = None
        self._thread: threading.Thread | None = None
        self._ready = threading.Event()
        self._error: BaseException | None = None
        self._runner: web.AppRunner | None = None

    def start(self, timeout: float = 15.0) -> VRServer:
        """Start listening (returns once the port is bound; raises what binding raised)."""
        if self._thread is not None:
            return self
        ssl_context = None
        if self.tls:
            if self.cert is None or self.key is None:
                names = ["localhost", "127.0.0.1"] + ([] if is_loopback(self.host) else vr_tls.lan_addresses())
                if not is_loopback(self.host) and self.host not in ("0.0.0.0", "::"):
                    names.append(self.host)
                cert, key = vr_tls.ensure_certificate(names, self.cert_dir)
                self.cert, self.key = str(cert), str(key)
            ssl_context = vr_tls.server_context(self.cert, self.key)
            self.fingerprint = vr_tls.fingerprint(self.cert)
        self._thread = threading.Thread(target=self._run, args=(ssl_context,), name="vr-server", daemon=True)
        self._thread.start()
        if not self._ready.wait(timeout):
            raise TimeoutError("the VR server did not start")
        if self._error is not None:
            self._thread = None
            raise self._error
        return self

    def stop(self, farewell: str | None = None) -> None:
        """Close the connection and the port; safe to call twice. With ``farewell``, the page is told that the
        session is over (a final status with that text), closes the connection itself and does not reconnect."""
        loop, thread = self._loop, self._thread
        if loop is None or thread is None:
            return
        try:
            # the page's answer to a farewell, then at most aiohttp's 10 s close handshake
            asyncio.run_coroutine_threadsafe(self._shutdown(farewell), loop).result(FAREWELL_TIMEOUT_S + 10.0)
        except Exception:
            LOG.exception("VR server shutdown")
        loop.call_soon_threadsafe(loop.stop)
        thread.join(10.0)
        self._thread = None
        self._loop = None

    def _run(self, ssl_context) -> None:
        loop = asyncio.new_event_loop()
        asyncio.set_event_loop(loop)
        loop.set_exception_handler(self._loop_exception)
        self._loop = loop
        try:
            loop.run_until_complete(self._startup(ssl_context))
        except BaseException as e:  # bind errors and the like: reported to start()'s caller
            self._error = e
            self._ready.set()
            loop.close()
            return
        self._ready.set()
        try:
            loop.run_forever()
        finally:
            pending = asyncio.all_tasks(loop)
            for task in pending:
                task.cancel()
            loop.run_until_complete(asyncio.gather(*pending, return_exceptions=True))
            loop.close()

    async def _startup(self, ssl_context) -> None:
        self._wake = asyncio.Event()
        app = web.Application(client_max_size=MAX_MESSAGE_BYTES, middlewares=[self._request_phase, self._host_guard])
        app.router.add_get("/", self._index)
        app.router.add_get("/ws", self._websocket)
        app.router.add_get("/favicon.ico", self._no_icon)
        app.router.add_static("/static/", self.web_dir, show_index=False, follow_symlinks=False)
        app.on_response_prepare.append(self._headers)
        self._runner = web.AppRunner(
            app,
            access_log=None,
            handle_signals=False,
            keepalive_timeout=self.request_timeout,
            logger=_RequestLog(self._note),
        )
        await self._runner.setup()
        # TLS is the pool's to start, once a connection is let in
        self._pool = ConnectionPool(
            self.max_connections, self.request_timeout, self.connect_rate, ssl_context, self._note
        )
        self._tcp_server = await asyncio.get_running_loop().create_server(
            self._pool.protocol_factory(self._runner.server),  # aiohttp's per-connection protocol, behind a guard
            self.host,
            self.requested_port,
            reuse_address=True,
            # asyncio accepts up to `backlog` sockets a wakeup, and a socket evicted for them closes a wakeup later: a
            # flood holds at most the cap and about three backlogs of files (asyncio's default, 100: over 300). Twice
            # the cap: a smaller queue makes clients wait out SYN retries (1 s each) under the same flood
            backlog=2 * self.max_connections,
        )
        self.port = self._tcp_server.sockets[0].getsockname()[1]

    async def _shutdown(self, farewell: str | None = None) -> None:
        client, gone = self._client, self._client_gone
        if client is not None and not client.closed:
            if farewell is None:
                await client.close(code=WSCloseCode.GOING_AWAY, message=b"server stopping")
            else:
                try:
                    await client.send_str(server_message("status", text=farewell, final=True))
                    # the page answers the final status by closing (see FAREWELL_TIMEOUT_S)
                    await asyncio.wait_for(gone.wait(), FAREWELL_TIMEOUT_S)
                except ConnectionError:
                    pass  # the page is gone already; it reconnects to nothing and says so
                except asyncio.TimeoutError:
                    self.count("farewell_timeouts")
                if not client.closed:
                    await client.close(code=CLOSE_FINISHED, message=b"finished")
        if self._tcp_server is not None:
            self._tcp_server.close()
        if self._runner is not None:
            await self._runner.cleanup()
        if self._pool is not None:
            self._pool.close_all()
        self._log_summary()

    @property
    def url(self) -> str:
        """The page's address for a browser on this machine (over USB: on the headset too)."""
        local = is_loopback(self.host) or self.host in ("0.0.0.0", "::")
        return f"{'https' if self.tls else 'http'}://{'localhost' if local else self.host}:{self.port}/"

    def lan_urls(self) -> list[str]:
        """The page's addresses for a headset on the same network (empty when bound to loopback)."""
        if is_loopback(self.host):
            return []
        hosts = vr_tls.lan_addresses() if self.host in ("0.0.0.0", "::") else [self.host]
        return [f"{'https' if self.tls else 'http'}://{h}:{self.port}/" for h in hosts]

    @property
    def connected(self) -> bool:
        return self._client is not None and not self._client.closed

    @property
    def rtt_ms(self) -> float | None:
        """WebSocket round trip measured by the last ping."""
        return self._rtt_ms

    def stats(self) -> dict:
        """A copy of every counter (see ``COUNTERS``)."""
        with self._counts_lock:
            return dict(self._counts)

    def count(self, key: str, n: int = 1) -> None:
        with self._counts_lock:
            self._counts[key] += n

    @property
    def open_connections(self) -> int:
        """TCP connections let in and not yet closed, TLS handshakes included."""
        return len(self._pool) if self._pool is not None else 0

    def publish_frame(self, data: bytes) -> None:
        """Offer a binary camera frame (``vr_protocol.pack_frame``); replaces any frame not yet sent."""
        with self._publish_lock:
            fid = self._frame[0] + 1 if self._frame else 1
            self._frame = (fid, data)
        self.count("frames_published")
        self._wakeup()

    def publish_status(self, status: dict) -> None:
        """Offer a status for the page (sent at most ``status_hz`` times a second, newest only)."""
        text = server_message("status", **status)
        with self._publish_lock:
            sid = self._status[0] + 1 if self._status else 1
            self._status = (sid, text)
        self._wakeup()

    def _wakeup(self) -> None:
        loop, wake = self._loop, self._wake
        if loop is not None and wake is not None and self.connected:
            try:
                loop.call_soon_threadsafe(wake.set)
            except RuntimeError:  # the loop closed between the check and the call: nothing to wake
                pass

    def _note(self, key: str) -> None:
        """Count a refused, evicted or timed-out connection or a malformed request (server thread); a log line sums
        them up SUMMARY_INTERVAL_S after the first."""
        self.count(key)
        self._summarized[key] += 1
        if self._summary is None:
            self._summary = asyncio.get_running_loop().call_later(SUMMARY_INTERVAL_S, self._log_summary)

    def _log_summary(self) -> None:
        if self._summary is not None:
            self._summary.cancel()
            self._summary = None
        counts, self._summarized = self._summarized, collections.Counter()
        if counts:
            level = logging.WARNING if any(counts[k] for k in SUMMARIZED[:-2]) else logging.INFO
            text = ", ".join(f"{k} {counts[k]}" for k in SUMMARIZED if counts[k])
            LOG.log(level, "VR server, connections refused or closed early: %s (%s open at most)", text,
                    self.max_connections)  # fmt: skip

    def _loop_exception(self, loop: asyncio.AbstractEventLoop, context: dict) -> None:
        # out of file descriptors, asyncio pauses accepting for a second and reports each time: counted instead
        if context.get("message") == "socket.accept() out of system resource":
            self._note("accept_failed")
        else:
            loop.default_exception_handler(context)

    async def _websocket(self, request: web.Request) -> web.StreamResponse:
        if not self._origin_ok(request):
            self.count("forbidden_origin")
            return web.Response(status=403, text="cross-origin WebSocket refused")
        ws = web.WebSocketResponse(max_msg_size=MAX_WS_FRAME_BYTES, compress=False, autoping=True)
        await ws.prepare(request)
        peer = request.remote or "?"
        if not await self._authenticate(ws, peer):
            return ws
        guard = self._pool.guard(request.transport)
        if guard is not None:
            guard.operator = True  # a slot of its own, never evicted
        previous, self._client = self._client, ws
        gone = self._client_gone = asyncio.Event()
        self._client_id += 1
        cid = self._client_id
        self.count("connections")
        if previous is not None and not previous.closed:
            self.count("superseded")
            await previous.close(code=CLOSE_SUPERSEDED, message=b"superseded by a newer connection")
        await ws.send_str(server_message("welcome", connection=cid, config=self.config))
        if self.on_connect is not None:
            self._call(self.on_connect, cid)
        order = {"seq": -1, "t": float("-inf"), "heard": time.monotonic()}
        sender = asyncio.create_task(self._send_loop(ws, order, request.transport))
        try:
            async for msg in ws:
                order["heard"] = time.monotonic()
                if msg.type == WSMsgType.TEXT:
                    self._handle_text(msg.data, order)
                elif msg.type == WSMsgType.BINARY:
                    self.count("received")
                    self.count("malformed")
                elif msg.type == WSMsgType.ERROR:
                    code = getattr(ws.exception(), "code", None)
                    self.count("oversized" if code == WSCloseCode.MESSAGE_TOO_BIG else "malformed")
        finally:
            gone.set()
            sender.cancel()
            if guard is not None:
                guard.operator = False
            if self._client is ws:
                self._client = None
                if self.on_disconnect is not None:
                    self._call(self.on_disconnect, cid)
        return ws

    def _handle_text(self, data: str, order: dict) -> None:
        self.count("received")
        try:
            msg = parse_client_message(data)
        except ProtocolError as e:
            self.count(e.reason)
            return
        if isinstance(msg, PoseMessage):
            if msg.seq <= order["seq"] or msg.t < order["t"]:
                self.count("out_of_order")
                return
            order["seq"], order["t"] = msg.seq, msg.t
            self.count("accepted")
            self._last_message_time = time.monotonic()
            if self.on_pose is not None:
                self._call(self.on_pose, msg, self._last_message_time)
        elif isinstance(msg, PongMessage):
            sent = self._pings.pop(msg.id, None)
            if sent is not None:
                self._rtt_ms = (time.monotonic() - sent) * 1000.0
        else:  # a second hello
            self.count("malformed")

    def _call(self, fn, *args) -> None:
        try:
            fn(*args)
        except Exception:
            self.count("handler_errors")
            LOG.exception("VR handler raised; the message was dropped")

    async def _send_loop(self, ws: web.WebSocketResponse, order: dict, transport) -> None:
        """Send the newest frame and status whenever there is one, and a ping every second; drop a client silent
        for the heartbeat timeout (``order["heard"]``: when it last sent anything, or when this loop last came back from
        a stall, whose messages were not read)."""
        with self._publish_lock:
            published_before = self._frame[0] if self._frame else 0
        last_frame = 0  # the newest frame goes out at once
        last_status, last_status_time = 0, 0.0
        next_ping = time.monotonic()
        try:
            while not ws.closed:
                waited_from = time.monotonic()
                try:
                    await asyncio.wait_for(self._wake.wait(), timeout=0.1)
                except asyncio.TimeoutError:
                    pass
                woke = time.monotonic()
                if woke - waited_from > LOOP_STALL_S:
                    order["heard"] = max(order["heard"], woke)
                self._wake.clear()
                with self._publish_lock:
                    frame, status = self._frame, self._status
                if frame is not None and frame[0] != last_frame:
                    # frames published while this connection was busy and never sent (not those from before it)
                    skipped = frame[0] - max(last_frame, published_before) - 1
                    if skipped > 0:
                        self.count("frames_skipped", skipped)
                    last_frame = frame[0]
                    await ws.send_bytes(stamp_sent(frame[1], time.monotonic()))
                    self.count("frames_sent")
                now = time.monotonic()
                if now - order["heard"] > self.heartbeat_timeout:
                    self.count("heartbeat_timeouts")
                    if transport is not None:
                        transport.abort()  # half-open: no close handshake would ever be answered
                    return
                if status is not None and status[0] != last_status and now - last_status_time >= self.status_interval:
                    last_status, last_status_time = status[0], now
                    await ws.send_str(status[1])
                    self.count("status_sent")
                if now >= next_ping:
                    self._ping_id += 1
                    self._pings = {self._ping_id: now}
                    next_ping = now + PING_INTERVAL_S
                    await ws.send_str(server_message("ping", id=self._ping_id))
        except (ConnectionError, RuntimeError, asyncio.CancelledError):
            return  # the connection went away; the receive side cleans up
