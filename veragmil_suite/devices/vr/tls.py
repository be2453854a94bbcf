"""A self-signed TLS certificate for serving the VR page over Wi-Fi.

WebXR needs a secure context: localhost (USB, ``adb reverse``) is one, a LAN address is one only over HTTPS. The
certificate is made once with the ``openssl`` command-line tool (Debian package ``openssl``) and kept, so the
headset's browser, told once to proceed past the warning, keeps trusting it; it is remade when it no longer
names every address the server is reached at or is within a month of expiring.
"""

from __future__ import annotations

import hashlib
import ipaddress
import os
import shutil
import socket
import ssl
import subprocess
import tempfile
from pathlib import Path

DEFAULT_CERT_DIR = Path(os.environ.get("VERAGMIL_CACHE_DIR", Path.home() / ".cache" / "veragmil_suite")) / "vr_tls"
CERT_DAYS = 825  # the longest validity browsers accept for a TLS server certificate
RENEW_BEFORE_S = 30 * 24 * 3600


def lan_addresses() -> list[str]:
    """This machine's IPv4 address on the default route (what a headset on the same Wi-Fi connects to)."""
    addrs = []
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        try:
            s.connect(("10.255.255.255", 1))  # UDP connect sends nothing; it only picks the outgoing interface
            addrs.append(s.getsockname()[0])
        except OSError:
            pass
    return [a for a in addrs if not ipaddress.ip_address(a).is_loopback]


def _san(names: list[str]) -> str:
    parts = []
    for n in names:
        try:
            ipaddress.ip_address(n)
            parts.append(f"IP:{n}")
        except ValueError:
            parts.append(f"DNS:{n}")
    return ",".join(parts)


def _cert_names(cert_path: Path) -> set[str] | None:
    """Names in the certificate's subjectAltName, or None when it is unreadable or expires within a month."""
    try:
        out = subprocess.run(
            [
                "openssl",
                "x509",
                "-in",
                str(cert_path),
                "-noout",
                "-checkend",
                str(RENEW_BEFORE_S),
                "-ext",
                "subjectAltName",
            ],
            capture_output=True,
            text=True,
            check=False,
        )
    except OSError:
        return None
    if out.returncode != 0:
        return None
    names = set()
    for line in out.stdout.splitlines():
        for item in line.split(","):
            item = item.strip()
            if item.startswith("IP Address:"):
                names.add(str(ipaddress.ip_address(item.split(":", 1)[1].strip())))
            elif item.startswith("DNS:"):
                names.add(item[4:].strip())
    return names


def ensure_certificate(names: list[str], cert_dir: str | Path | None = None) -> tuple[Path, Path]:
    """Paths (cert, key) of a self-signed certificate naming every entry of ``names``; made when needed."""
    if shutil.which("openssl") is None:
        raise RuntimeError("HTTPS needs the openssl command (Debian: apt-get install openssl), or pass cert/key files")
    cert_dir = Path(cert_dir) if cert_dir is not None else DEFAULT_CERT_DIR
    cert_dir.mkdir(parents=True, exist_ok=True)
    cert, key = cert_dir / "cert.pem", cert_dir / "key.pem"
    wanted = {str(ipaddress.ip_address(n)) if _is_ip(n) else n for n in names}
    if cert.exists() and key.exists():
        have = _cert_names(cert)
        if have is not None and wanted <= have and _pair_loads(cert, key):
            return cert, key
    with tempfile.TemporaryDirectory(dir=cert_dir) as tmp:
        tmp_cert, tmp_key = Path(tmp) / "cert.pem", Path(tmp) / "key.pem"
        subprocess.run(
            [
                "openssl", "req", "-x509", "-newkey", "ec", "-pkeyopt", "ec_paramgen_curve:prime256v1",
                "-nodes", "-sha256", "-days", str(CERT_DAYS), "-subj", "/CN=veragmil_suite VR teleoperation",
                "-keyout", str(tmp_key), "-out", str(tmp_cert),
                "-addext", f"subjectAltName={_san(sorted(wanted))}",
                "-addext", "extendedKeyUsage=serverAuth",
            ],
            check=True,
            capture_output=True,
        )  # fmt: skip
        os.chmod(tmp_key, 0o600)
        os.replace(tmp_key, key)
        os.replace(tmp_cert, cert)
    return cert, key


def _pair_loads(cert: Path, key: Path) -> bool:
    """Whether ``key`` is the private key of ``cert`` (the two are replaced one after the other: a kill between
    leaves a new key beside the old certificate)."""
    try:
        ssl.create_default_context(ssl.Purpose.CLIENT_AUTH).load_cert_chain(cert, key)
    except (ssl.SSLError, OSError):
        return False
    return True


def _is_ip(name: str) -> bool:
    try:
        ipaddress.ip_address(name)
        return True
    except ValueError:
        return False


def fingerprint(cert_path: str | Path) -> str:
    """SHA-256 fingerprint of a PEM certificate, as browsers show it (colon-separated hex)."""
    der = ssl.PEM_cert_to_DER_cert(Path(cert_path).read_text())
    digest = hashlib.sha256(der).hexdigest().upper()
    return ":".join(digest[i : i + 2] for i in range(0, len(digest), 2))


def server_context(cert: str | Path, key: str | Path) -> ssl.SSLContext:
    """TLS server context for aiohttp from a certificate and key file."""
    ctx = ssl.create_default_context(ssl.Purpose.CLIENT_AUTH)
    ctx.load_cert_chain(str(cert), str(key))
    return ctx
