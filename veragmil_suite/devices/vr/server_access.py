"""Who the VR server answers: its HTTP pages and headers, the hosts and origins it accepts, and the operator's
pairing token, with a lockout after repeated wrong tokens."""

from __future__ import annotations

import asyncio
import collections
import hmac
import time
from urllib.parse import urlsplit

from aiohttp import WSMsgType, web

from veragmil_suite.devices.vr.protocol import (
    HelloMessage,
    ProtocolError,
    parse_client_message,
    server_message,
)
from veragmil_suite.devices.vr.server_options import (
    AUTH_MAX_FAILURES,
    AUTH_WINDOW_S,
    CLOSE_HELLO_TIMEOUT,
    CLOSE_LOCKED_OUT,
    CLOSE_UNAUTHORIZED,
    HOST_RE,
    canonical_token,
    is_local_name,
)


class ServerAccessMixin:
    """VRServer's HTTP side and access checks (see the module docstring)."""

    async def _headers(self, request: web.Request, response: web.StreamResponse) -> None:
        response.headers["Cache-Control"] = "no-store"
        response.headers["X-Content-Type-Options"] = "nosniff"
        host = request.host if HOST_RE.fullmatch(request.host or "") else ""
        sockets = f" ws://{host} wss://{host}" if host else ""
        response.headers["Content-Security-Policy"] = (
            f"default-src 'self'; img-src 'self' blob: data:; connect-src 'self'{sockets}; frame-ancestors 'none'"
        )

    @web.middleware
    async def _request_phase(self, request: web.Request, handler) -> web.StreamResponse:
        """Tell the connection's guard that a request is in (its deadline kept) and while it is being handled."""
        guard = self._pool.guard(request.transport)
        if guard is None:
            return await handler(request)
        guard.request_started()
        try:
            return await handler(request)
        finally:
            guard.request_finished()

    @web.middleware
    async def _host_guard(self, request: web.Request, handler) -> web.StreamResponse:
        if not self.requires_token and not is_local_name(request.host):
            self.count("forbidden_host")
            return web.Response(status=403, text="this server answers to localhost only")
        return await handler(request)

    async def _no_icon(self, request: web.Request) -> web.StreamResponse:
        return web.Response(status=204)  # browsers ask; an error would only clutter the page's console

    async def _index(self, request: web.Request) -> web.StreamResponse:
        return web.FileResponse(self.web_dir / "index.html")

    def _origin_ok(self, request: web.Request) -> bool:
        origin = request.headers.get("Origin")
        if origin is None:  # not a browser (scripts, tests): browsers always send Origin on WebSocket requests
            return True
        parts = urlsplit(origin)
        return parts.scheme in ("http", "https") and parts.netloc == request.host

    def _locked_out(self, peer: str) -> bool:
        q = self._failures.get(peer)
        now = time.monotonic()
        while q and now - q[0] > AUTH_WINDOW_S:
            q.popleft()
        return bool(q) and len(q) >= AUTH_MAX_FAILURES

    def _token_ok(self, token: str | None) -> bool:
        if not self.requires_token:
            return True
        if token is None:
            return False
        return hmac.compare_digest(canonical_token(token).encode(), canonical_token(self.token).encode())

    async def _authenticate(self, ws: web.WebSocketResponse, peer: str) -> bool:
        try:
            msg = await asyncio.wait_for(ws.receive(), self.hello_timeout)
        except asyncio.TimeoutError:
            self.count("unauthenticated")
            await ws.close(code=CLOSE_HELLO_TIMEOUT, message=b"no hello")
            return False
        hello = None
        if msg.type == WSMsgType.TEXT:
            try:
                hello = parse_client_message(msg.data)
            except ProtocolError as e:
                self.count(e.reason)
        if not isinstance(hello, HelloMessage):
            self.count("unauthenticated")
            if not ws.closed:
                await ws.close(code=CLOSE_UNAUTHORIZED, message=b"the first message must be a hello")
            return False
        if self._locked_out(peer):
            self.count("locked_out")
            await ws.send_str(server_message("error", reason="too many wrong tokens: wait a minute"))
            await ws.close(code=CLOSE_LOCKED_OUT, message=b"locked out")
            return False
        if not self._token_ok(hello.token):
            self.count("auth_failed")
            self._failures.setdefault(peer, collections.deque()).append(time.monotonic())
            await asyncio.sleep(self.auth_failure_delay)  # a wrong guess costs time
            await ws.send_str(server_message("error", reason="wrong or missing pairing token"))
            await ws.close(code=CLOSE_UNAUTHORIZED, message=b"wrong token")
            return False
        return True
