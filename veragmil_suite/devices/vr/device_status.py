"""What the headset's page shows of the session: the operator's status panel, published when it changes."""

from __future__ import annotations

import time

import numpy as np


class DeviceStatusMixin:
    """What the headset's page shows of the session: the operator's status panel, published when it changes."""

    def status(self) -> dict:
        """What the operator's status line shows."""
        with self._lock:
            ages = list(self._pose_ages)[-20:]
        latency = 1000.0 * float(np.mean(ages)) if ages else None
        rtt = self.server.rtt_ms
        c = self._clutch
        parts = [
            "CONNECTED" if self.server.connected else "waiting for the headset",
            *(["controller not tracked"] if self.server.connected and self._ctrl is None else []),
            "ENGAGED" if c.engaged else ("released (stale)" if self._stale and self.server.connected else "released"),
            "REC" if self.recording else "not recording",
            f"scale {c.scale:.2f}" + (" precision" if c.precision else ""),
            c.mode,
        ]
        if latency is not None:
            parts.append(f"pose {latency:.0f} ms")
        if rtt is not None:
            parts.append(f"rtt {rtt:.0f} ms")
        shown = self.stream.shown_depth_range
        if self.stream.depth and shown is not None:
            parts.append(f"depth {shown[0]:.2f}-{shown[1]:.2f} m")
        if self.progress:
            parts.append(self.progress)
        if self.episode_command is not None:
            parts.append(f"episode: {self.episode_command}")
        if self.status_message:
            parts.append(self.status_message)
        return dict(
            connected=self.server.connected,
            engaged=c.engaged,
            stale=self._stale,
            recording=self.recording,
            scale=c.scale,
            precision=c.precision,
            mode=c.mode,
            latency_ms=latency,
            rtt_ms=rtt,
            depth=self.stream.depth,
            depth_range_m=None if self.stream.shown_depth_range is None else list(self.stream.shown_depth_range),
            recenter=self._recenters,
            episode=self.episodes,
            episode_command=self.episode_command,
            progress=self.progress,
            text=" | ".join(parts),
        )

    def _publish_status(self, force: bool = False) -> None:
        now = time.monotonic()
        if force or now - self._last_status >= 0.1:
            self._last_status = now
            self.server.publish_status(self.status())
