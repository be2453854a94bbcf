"""The VR server's TCP connections: which are let in, what each must do by when, and their TLS.

A connection counts against the cap (``max_connections``) from the moment it is accepted, its TLS handshake
included: an unfinished handshake holds a socket and a 256 KiB buffer as surely as an idle connection does. The
operator's authenticated WebSocket has a slot of its own, outside the cap. At the cap a new connection takes the
place of the oldest one that is not handling a request (in its TLS handshake, before its first request, idle
between requests), else of the oldest one handling one, so no number of other connections can keep the operator's
page out; once it has authenticated, a client that reopens whatever is closed finds room again without pushing
anyone out. A client that floods connections to push the page's out before it authenticates is held to a rate per
address (a token bucket: ``max_connections`` at once, then ``connect_rate`` a second); beyond it, its connections
are closed as soon as they are accepted. Every connection has ``request_timeout`` seconds to finish its TLS
handshake and send the headers of its first request.

TLS is started on a connection only once it has been let in (``loop.start_tls``), so a handshake costs nothing
before it is counted. Every refusal, eviction and timeout goes to the server's counters, never to a traceback.
"""

from __future__ import annotations

import asyncio
import math
import ssl
import time
from collections.abc import Callable

MAX_TRACKED_ADDRESSES = 1024  # rate buckets kept at most; full ones (addresses quiet for a while) are dropped first


class ConnectionPool:
    """The open connections of one server, oldest first; used only from the server's event loop.

    Args:
        max_connections (int): connections open at once, at most, besides the operator's WebSocket
        request_timeout (float): seconds a connection has to finish its TLS handshake and its first request's headers
        connect_rate (float): new connections a second allowed to one address once its burst of
            ``max_connections`` is spent; ``math.inf``: no limit
        ssl_context (ssl.SSLContext or None): serve TLS with it
        note (callable): ``note(counter)`` for each connection refused, evicted, timed out or failing TLS
    """

    def __init__(
        self,
        max_connections: int,
        request_timeout: float,
        connect_rate: float,
        ssl_context: ssl.SSLContext | None,
        note: Callable[[str], None],
    ):
        self.max_connections = max_connections
        self.request_timeout = request_timeout
        self.connect_rate = connect_rate
        self.ssl_context = ssl_context
        self.note = note
        self._open: dict[ConnectionGuard, None] = {}  # in the order they were let in
        self._by_transport: dict[asyncio.BaseTransport, ConnectionGuard] = {}
        self._buckets: dict[str, tuple[float, float]] = {}  # address -> (tokens, when counted)

    def __len__(self) -> int:
        return len(self._open)

    def protocol_factory(self, inner_factory: Callable[[], asyncio.Protocol]) -> Callable[[], asyncio.Protocol]:
        """A factory for ``loop.create_server``: aiohttp's protocol for each connection, behind a guard."""
        return lambda: ConnectionGuard(self, inner_factory())

    def guard(self, transport: asyncio.BaseTransport | None) -> ConnectionGuard | None:
        """The guard of the connection whose aiohttp protocol was given ``transport`` (``request.transport``)."""
        return self._by_transport.get(transport) if transport is not None else None

    def close_all(self) -> None:
        for guard in list(self._open):
            guard.close()

    def admit(self, guard: ConnectionGuard, address: str) -> bool:
        """Let ``guard`` in, evicting another connection at the cap; False (counted) when it must be closed."""
        if not self._within_rate(address):
            self.note("refused_rate")
            return False
        if sum(not g.operator for g in self._open) >= self.max_connections:
            victim = self._victim()
            if victim is None:
                self.note("refused_busy")
                return False
            self.note("evicted")
            victim.close()
        self._open[guard] = None
        return True

    def _victim(self) -> ConnectionGuard | None:
        idle = next((g for g in self._open if g.requests == 0 and not g.operator), None)
        return idle if idle is not None else next((g for g in self._open if not g.operator), None)

    def _within_rate(self, address: str) -> bool:
        if math.isinf(self.connect_rate):
            return True
        now = time.monotonic()
        burst = float(self.max_connections)
        tokens, then = self._buckets.get(address, (burst, now))
        tokens = min(burst, tokens + (now - then) * self.connect_rate)
        allowed = tokens >= 1.0
        self._buckets[address] = (tokens - 1.0 if allowed else tokens, now)
        if len(self._buckets) > MAX_TRACKED_ADDRESSES:
            self._forget_full_buckets(now, burst)
        return allowed

    def _forget_full_buckets(self, now: float, burst: float) -> None:
        full = [a for a, (tokens, then) in self._buckets.items() if tokens + (now - then) * self.connect_rate >= burst]
        for address in full:
            del self._buckets[address]
        while len(self._buckets) > MAX_TRACKED_ADDRESSES:  # every one busy: the longest known go first
            del self._buckets[next(iter(self._buckets))]

    def _connected(self, guard: ConnectionGuard, transport: asyncio.BaseTransport) -> None:
        self._by_transport[transport] = guard

    def _release(self, guard: ConnectionGuard) -> None:
        self._open.pop(guard, None)
        if guard.transport is not None:
            self._by_transport.pop(guard.transport, None)


class ConnectionGuard(asyncio.Protocol):
    """One TCP connection, in front of aiohttp's protocol for it (``inner``): let in or closed at once, timed until
    its first request, and over HTTPS handed to ``inner`` only once its TLS handshake is done."""

    def __init__(self, pool: ConnectionPool, inner: asyncio.Protocol):
        self._pool, self._inner = pool, inner
        self._tcp: asyncio.Transport | None = None
        self.transport: asyncio.BaseTransport | None = None  # inner's: the TCP transport, or TLS over it
        self._timer: asyncio.TimerHandle | None = None
        self._handshake: asyncio.Task | None = None  # held: the event loop keeps only a weak reference to tasks
        self._early: list[bytes] = []  # decrypted before inner had its transport
        self._early_eof = False
        self._closed = False
        self.requests = 0  # requests being handled (a WebSocket's lasts as long as it is open)
        self.operator = False  # the authenticated operator's WebSocket: outside the cap, never evicted

    def request_started(self) -> None:
        """The headers of a request are in: the connection has kept its deadline."""
        self.requests += 1
        self._cancel_timer()

    def request_finished(self) -> None:
        self.requests -= 1

    def close(self) -> None:
        """Close at once (evicted, timed out, server stopping)."""
        self._release()
        if self._tcp is not None:
            self._tcp.abort()

    def connection_made(self, transport: asyncio.Transport) -> None:
        pool = self._pool
        peer = transport.get_extra_info("peername")
        if not pool.admit(self, str(peer[0]) if peer else "?"):
            self._closed = True
            transport.abort()
            return
        self._tcp = transport
        loop = asyncio.get_running_loop()
        self._timer = loop.call_later(pool.request_timeout, self._expire)
        if pool.ssl_context is None:
            self._connect_inner(transport)
        else:
            self._handshake = loop.create_task(self._start_tls(loop, transport))

    async def _start_tls(self, loop: asyncio.AbstractEventLoop, tcp: asyncio.Transport) -> None:
        if self._closed:  # evicted before this task ran: a handshake begun now would outlive the socket
            return
        try:
            # asyncio's own handshake timeout is a backstop: the guard's timer (request_timeout) closes it first
            tls = await loop.start_tls(
                tcp,
                self,
                self._pool.ssl_context,
                server_side=True,
                ssl_handshake_timeout=2 * self._pool.request_timeout,
            )
        except OSError:  # ssl.SSLError, the peer reset, asyncio's handshake timeout
            tls = None
        except asyncio.CancelledError:  # the server stopping
            self._release()
            raise
        if self._closed:  # evicted or timed out during the handshake, or gone right after it
            return
        if tls is None:  # failed, or the peer closed mid-handshake
            self._pool.note("tls_failed")
            self._release()
            return
        self._connect_inner(tls)

    def _connect_inner(self, transport: asyncio.BaseTransport) -> None:
        self.transport = transport
        self._pool._connected(self, transport)
        self._inner.connection_made(transport)
        for data in self._early:
            self._inner.data_received(data)
        self._early = []
        if self._early_eof:
            self._inner.eof_received()

    def data_received(self, data: bytes) -> None:
        if self.transport is None:  # TLS: data decrypted in the same read as the handshake's end
            self._early.append(data)
        else:
            self._inner.data_received(data)

    def eof_received(self) -> bool | None:
        if self.transport is None:
            self._early_eof = True
            return None
        return self._inner.eof_received()

    def pause_writing(self) -> None:
        if self.transport is not None:
            self._inner.pause_writing()

    def resume_writing(self) -> None:
        if self.transport is not None:
            self._inner.resume_writing()

    def connection_lost(self, exc: Exception | None) -> None:
        self._release()
        if self.transport is not None:
            self._inner.connection_lost(exc)

    def _expire(self) -> None:
        self._timer = None
        if not self._closed:
            self._pool.note("idle_closed")
            self.close()

    def _cancel_timer(self) -> None:
        if self._timer is not None:
            self._timer.cancel()
            self._timer = None

    def _release(self) -> None:
        self._cancel_timer()
        if not self._closed:
            self._closed = True
            self._pool._release(self)
