"""Filters for tracked VR poses: One-Euro on position, adaptive slerp on orientation, jump rejection, and the
velocity clamp on the commanded pose.

Hand tracking jitters by a millimetre or so at 72-120 Hz, and the operator's hand shakes; a fixed low-pass filter
that removes the jitter also lags deliberate motion. The One-Euro filter (Casiez, Roussel, Vogel, CHI 2012) is a
low-pass filter whose cutoff rises with speed: still hands are smoothed hard, fast motion passes with little lag.
Orientation gets the same treatment on the sphere of unit quaternions (slerp toward each sample by the One-Euro
smoothing factor, its cutoff raised by the angular speed). Tracking glitches (a controller lost and found again
metres away) are not motion: they are rejected as jumps, and the clutch re-anchors instead of moving the robot.
"""

from __future__ import annotations

import abc
import math

import numpy as np

from veragmil_suite.devices.vr.frames import quat_angle, quat_conj, quat_mul, quat_normalize, quat_slerp, quat_to_rotvec


def smoothing_factor(dt: float, cutoff_hz: float) -> float:
    """Weight of a new sample in an exponential low-pass filter with this cutoff, sampled dt seconds apart."""
    tau = 1.0 / (2.0 * math.pi * cutoff_hz)
    return dt / (dt + tau)


class _AdaptiveCutoffFilter(abc.ABC):
    """The One-Euro parameters, shared by the vector and the orientation filter."""

    def __init__(self, min_cutoff: float = 1.0, beta: float = 0.0, d_cutoff: float = 1.0, max_gap: float = 0.5):
        if min_cutoff <= 0 or d_cutoff <= 0 or beta < 0:
            raise ValueError("cutoffs must be positive and beta non-negative")
        self.min_cutoff = min_cutoff
        self.beta = beta
        self.d_cutoff = d_cutoff
        self.max_gap = max_gap
        self.reset()

    @abc.abstractmethod
    def reset(self) -> None:
        """Forget the signal: the next sample passes unfiltered."""


class OneEuroFilter(_AdaptiveCutoffFilter):
    """One-Euro filter on a vector signal; the cutoff follows the norm of the (filtered) velocity.

    Args:
        min_cutoff (float): cutoff (Hz) of a still signal; lower removes more jitter
        beta (float): cutoff gained per unit of speed (Hz per unit/s); higher lags less when moving fast
        d_cutoff (float): cutoff (Hz) of the velocity estimate itself
        max_gap (float): a pause longer than this (s) restarts the filter at the next sample rather than
            blending across it
    """

    def reset(self) -> None:
        """Forget the signal: the next sample passes unfiltered."""
        self._x: np.ndarray | None = None
        self._dx: np.ndarray | None = None
        self._t: float | None = None

    @property
    def value(self) -> np.ndarray | None:
        return None if self._x is None else self._x.copy()

    def __call__(self, x: np.ndarray, t: float) -> np.ndarray:
        """Filter the sample x taken at time t (seconds); samples not after the previous one change nothing."""
        x = np.asarray(x, dtype=float)
        if self._x is None or self._t is None or t - self._t > self.max_gap:
            self._x, self._dx, self._t = x.copy(), np.zeros_like(x), t
            return self._x.copy()
        dt = t - self._t
        if dt <= 0.0:
            return self._x.copy()
        a_d = smoothing_factor(dt, self.d_cutoff)
        self._dx = self._dx + a_d * ((x - self._x) / dt - self._dx)
        cutoff = self.min_cutoff + self.beta * float(np.linalg.norm(self._dx))
        self._x = self._x + smoothing_factor(dt, cutoff) * (x - self._x)
        self._t = t
        return self._x.copy()


class SlerpFilter(_AdaptiveCutoffFilter):
    """One-Euro filter for orientations: slerp toward each sample, cutoff raised by the angular speed.

    Args as ``OneEuroFilter``, with beta in Hz per rad/s.
    """

    def reset(self) -> None:
        """Forget the signal: the next sample passes unfiltered."""
        self._q: np.ndarray | None = None
        self._omega = np.zeros(3)
        self._t: float | None = None

    @property
    def value(self) -> np.ndarray | None:
        return None if self._q is None else self._q.copy()

    def __call__(self, q: np.ndarray, t: float) -> np.ndarray:
        """Filter the unit quaternion q (x, y, z, w) sampled at time t (seconds)."""
        q = quat_normalize(q)
        if self._q is None or self._t is None or t - self._t > self.max_gap:
            self._q, self._omega, self._t = q, np.zeros(3), t
            return self._q.copy()
        dt = t - self._t
        if dt <= 0.0:
            return self._q.copy()
        # angular velocity as a vector, smoothed before its norm is taken: the norm of raw differences would
        # read jitter as speed and open the filter on a still hand
        omega = quat_to_rotvec(quat_mul(q, quat_conj(self._q))) / dt
        self._omega = self._omega + smoothing_factor(dt, self.d_cutoff) * (omega - self._omega)
        cutoff = self.min_cutoff + self.beta * float(np.linalg.norm(self._omega))
        self._q = quat_slerp(self._q, q, smoothing_factor(dt, cutoff))
        self._t = t
        return self._q.copy()


class PoseFilter:
    """The whole pose pipeline for one tracked device: jump rejection, then One-Euro position and slerp orientation.

    The defaults, measured at 90 Hz (tests/test_vr_filters.py): a still hand's 1 mm jitter drops to under a
    quarter, a hand moving at 0.5 m/s is followed 8 mm (15 ms) behind; orientation jitter drops to a fifth, a
    2 rad/s turn is followed 0.03 rad behind.

    A jump (the raw position moving more than ``max_pos_jump`` metres or the orientation more than
    ``max_rot_jump`` radians between two consecutive samples, faster than a hand can move at 72 Hz) restarts both
    filters at the new pose and increments ``discontinuities``, which the clutch reads to re-anchor.
    """

    def __init__(
        self,
        pos_min_cutoff: float = 1.0,
        pos_beta: float = 8.0,
        rot_min_cutoff: float = 1.0,
        rot_beta: float = 2.0,
        d_cutoff: float = 1.0,
        max_pos_jump: float = 0.08,
        max_rot_jump: float = 0.8,
    ):
        self.position = OneEuroFilter(pos_min_cutoff, pos_beta, d_cutoff)
        self.orientation = SlerpFilter(rot_min_cutoff, rot_beta, d_cutoff)
        self.max_pos_jump = max_pos_jump
        self.max_rot_jump = max_rot_jump
        self.discontinuities = 0
        self._last_raw: tuple[np.ndarray, np.ndarray] | None = None

    def reset(self) -> None:
        """Forget the signal (tracking lost, client reconnected); not counted as a discontinuity."""
        self.position.reset()
        self.orientation.reset()
        self._last_raw = None

    def is_jump(self, p: np.ndarray, q: np.ndarray) -> bool:
        """Whether the raw pose (p, q) is too far from the previous raw sample to be motion."""
        if self._last_raw is None:
            return False
        p0, q0 = self._last_raw
        return bool(np.linalg.norm(p - p0) > self.max_pos_jump or quat_angle(q0, q) > self.max_rot_jump)

    def __call__(self, p: np.ndarray, q: np.ndarray, t: float) -> tuple[np.ndarray, np.ndarray, bool]:
        """Filtered (position, quaternion) and whether this sample was a jump."""
        p = np.asarray(p, dtype=float)
        q = quat_normalize(q)
        jumped = self.is_jump(p, q)
        if jumped:
            self.position.reset()
            self.orientation.reset()
            self.discontinuities += 1
        self._last_raw = (p.copy(), q.copy())
        return self.position(p, t), self.orientation(q, t), jumped


def clamp_translation(current: np.ndarray, target: np.ndarray, max_step: float) -> np.ndarray:
    """Move from current toward target by at most max_step (metres), along the straight line."""
    d = np.asarray(target, dtype=float) - current
    n = float(np.linalg.norm(d))
    return np.asarray(target, dtype=float).copy() if n <= max_step else current + d * (max_step / n)


def clamp_rotation(current: np.ndarray, target: np.ndarray, max_angle: float) -> np.ndarray:
    """Turn from quaternion current toward target by at most max_angle (radians), along the shorter arc."""
    angle = quat_angle(current, target)
    return quat_normalize(target) if angle <= max_angle else quat_slerp(current, target, max_angle / angle)
