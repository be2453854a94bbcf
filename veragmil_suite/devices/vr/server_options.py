"""The VR server's options and the limits it holds any client to: connections, rates, timeouts, message sizes, the
access token, close codes, and what it counts.
"""

from __future__ import annotations

import ipaddress
import re
import secrets
from dataclasses import dataclass
from pathlib import Path

WEB_DIR = Path(__file__).resolve().parent / "web"
MAX_WS_FRAME_BYTES = 64 * 1024  # larger WebSocket messages are not even buffered: the connection is closed
TOKEN_ALPHABET = "ABCDEFGHJKLMNPQRSTUVWXYZ23456789"  # no 0/O, 1/I: typed on a headset keyboard
AUTH_MAX_FAILURES = 5
AUTH_WINDOW_S = 60.0
PING_INTERVAL_S = 1.0
# open TCP connections at most, TLS handshakes included (the page needs one WebSocket and a few HTTP fetches): at it
# a new connection replaces an older one, so idle sockets cannot use up the process's file descriptors
MAX_CONNECTIONS = 32
# seconds a new connection has to finish its TLS handshake and send its first request's headers, and an HTTP
# keep-alive may idle
REQUEST_TIMEOUT_S = 10.0
# new connections a second from one address, after a burst of MAX_CONNECTIONS, on a server open to the network (a
# page makes a handful on loading, one a second while reconnecting); over it they are closed on accept
CONNECT_RATE = 5.0
# seconds between two log lines that sum up refused, evicted and timed-out connections and malformed requests
SUMMARY_INTERVAL_S = 10.0
# seconds a WebSocket client may stay silent (it answers the server's pings every PING_INTERVAL_S) before the
# connection is taken for half-open (Wi-Fi gone without a FIN) and dropped, so that a reconnection finds a free slot
HEARTBEAT_TIMEOUT_S = 5.0
# seconds past its 0.1 s wait after which the send loop takes its own event loop to have been stalled (the GIL held
# by the simulation, a starved CPU): the client's messages of that time lie unread, so its silence is not counted
LOOP_STALL_S = 1.0
# seconds the server waits, after the final status, for the page to close the connection itself; a server that
# closes first while poses stream in closes a socket with unread data, which resets the connection, and the browser
# then reports an abnormal closure (and reconnects) instead of the finish. Past it the server closes (CLOSE_FINISHED)
FAREWELL_TIMEOUT_S = 3.0
HOST_RE = re.compile(r"[A-Za-z0-9.\-\[\]:]+")  # a Host header fit to be echoed into the page's CSP

# close codes in the application range (4000-4999)
CLOSE_SUPERSEDED = 4000
CLOSE_FINISHED = 4100  # the program is done with the headset (the collection is over): no reconnecting
CLOSE_UNAUTHORIZED = 4401
CLOSE_HELLO_TIMEOUT = 4408
CLOSE_LOCKED_OUT = 4429

COUNTERS = (
    "connections",  # WebSocket connections accepted (authenticated)
    "received",  # text messages received from authenticated clients
    "accepted",  # pose messages handed to the device
    "malformed",  # not JSON, not the schema, binary, unknown type
    "oversized",  # longer than MAX_MESSAGE_BYTES (or than MAX_WS_FRAME_BYTES: connection closed)
    "version",  # a schema version this server does not speak
    "out_of_order",  # seq not increasing or t decreasing
    "handler_errors",  # the device's pose handler raised (logged)
    "auth_failed",  # wrong or missing pairing token
    "locked_out",  # connections refused after repeated wrong tokens
    "unauthenticated",  # first message not a hello, or none within the hello timeout
    "forbidden_origin",  # WebSocket opened from another site's page
    "forbidden_host",  # a localhost server asked under another name (DNS rebinding)
    "superseded",  # connections closed because a newer one authenticated
    "refused_busy",  # TCP connections closed at once: the cap reached and no connection to evict
    "refused_rate",  # TCP connections closed at once: their address over its connection rate
    "evicted",  # TCP connections closed to make room for a newer one at the cap
    "idle_closed",  # TCP connections without a TLS handshake and a request's headers within the request timeout
    "tls_failed",  # TLS handshakes that failed or were abandoned by the client
    "malformed_http",  # requests that were not HTTP or not valid HTTP (answered 400, connection closed)
    "accept_failed",  # accepts that failed for want of file descriptors or memory
    "heartbeat_timeouts",  # WebSocket clients silent for the heartbeat timeout (half-open), dropped
    "farewell_timeouts",  # pages that did not close the connection within FAREWELL_TIMEOUT_S of the final status
    "frames_published",
    "frames_sent",
    "frames_skipped",
    "status_sent",
)
# what the periodic summary reports; a line at WARNING when any but the last two happened (a browser's untrusted
# certificate and its unused spare connections are routine), at INFO otherwise
SUMMARIZED = ("refused_busy", "refused_rate", "evicted", "malformed_http", "accept_failed", "tls_failed", "idle_closed")


def is_loopback(host: str) -> bool:
    """Whether binding to host keeps the server unreachable from the network."""
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


def new_token() -> str:
    """A pairing token: 8 characters from a 32-letter alphabet (40 bits), shown as XXXX-XXXX."""
    raw = "".join(secrets.choice(TOKEN_ALPHABET) for _ in range(8))
    return f"{raw[:4]}-{raw[4:]}"


def is_local_name(host_header: str) -> bool:
    """Whether a Host header names this machine's loopback (localhost, 127.x, [::1]), port aside."""
    host = host_header.rsplit(":", 1)[0] if not host_header.endswith("]") else host_header
    host = host.strip("[]")
    return host == "localhost" or is_loopback(host)


def canonical_token(token: str) -> str:
    return "".join(c for c in token.upper() if c.isalnum())


@dataclass(frozen=True)
class VRServerOptions:
    """How a ``VRServer`` listens and guards its connections; the defaults suit a Quest over USB (``adb reverse``).

    Args:
        host (str): address to bind; 127.0.0.1 (USB) unless a Wi-Fi headset connects (e.g. "0.0.0.0")
        port (int): TCP port; 0 picks a free one (``VRServer.port`` after ``start()``)
        token (str or None): pairing token; required, and generated when None, when host is not loopback
        tls (bool or None): serve HTTPS; None: exactly when host is not loopback
        cert, key (str or None): certificate and key files (PEM); with HTTPS and either one None, a self-signed
            pair is made
        cert_dir (str or None): folder where the self-signed pair is kept; None: ``vr_tls.DEFAULT_CERT_DIR``
        status_hz (float): most status messages per second sent to the page (Hz)
        hello_timeout (float): seconds a new WebSocket connection has to say hello
        auth_failure_delay (float): seconds a wrong pairing token waits for its answer
        web_dir (str or Path): folder of the page's files (``WEB_DIR``)
        max_connections (int): open TCP connections at most, TLS handshakes included, besides the operator's
            authenticated WebSocket (``MAX_CONNECTIONS``)
        request_timeout (float): seconds a connection has to finish its TLS handshake and send its first request's
            headers; also the HTTP keep-alive (``REQUEST_TIMEOUT_S``)
        connect_rate (float or None): new connections a second from one address after a burst of max_connections;
            None: ``CONNECT_RATE`` when a token is required (the server is open to the network), no limit otherwise
            (on loopback every client is 127.0.0.1, the headset over USB included: a shared limit would let a local
            flood hold the operator to its pace); ``math.inf``: no limit
        heartbeat_timeout (float): seconds of silence after which a WebSocket client is taken for gone
            (``HEARTBEAT_TIMEOUT_S``)
    """

    host: str = "127.0.0.1"
    port: int = 8765
    token: str | None = None
    tls: bool | None = None
    cert: str | None = None
    key: str | None = None
    cert_dir: str | None = None
    status_hz: float = 10.0
    hello_timeout: float = 5.0
    auth_failure_delay: float = 0.5
    web_dir: str | Path = WEB_DIR
    max_connections: int = MAX_CONNECTIONS
    request_timeout: float = REQUEST_TIMEOUT_S
    connect_rate: float | None = None
    heartbeat_timeout: float = HEARTBEAT_TIMEOUT_S
