"""Causal still/static test for live samples (the on-line counterpart of :mod:`ftcal.data.holds`).

The offline holds look half a window before *and after* each sample; live there is no after.
A sample is *still* when the sensor turned less than ``min_rate`` (rad/s) on average since the
newest sample at least ``window`` s older; it is *static* once it has been still for ``min_hold``
s (the arm has settled). The motion signal is the orientation quaternion when given (every
rotation), else the gravity direction (rotations about gravity are invisible to it, and do not
change the tool's gravity wrench), else joint positions (the fastest joint). Defaults are the
offline ones (:data:`~ftcal.data.holds.HOLD_WINDOW_S`, :data:`~ftcal.data.holds.MIN_ANGULAR_RATE`,
:data:`~ftcal.data.holds.MIN_HOLD_S`). Until ``window`` s of history exist a sample is moving.
"""

from __future__ import annotations

import math
from collections import deque

import numpy as np


def _angles(kind: str, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Angle (rad) between rows of ``x`` and ``y``: quaternions, directions, or the largest joint travel."""
    if kind == "quaternion":
        sign = np.where(np.einsum("ij,ij->i", x, y) < 0.0, -1.0, 1.0)[:, None]
        return 2.0 * np.arctan2(np.linalg.norm(x - sign * y, axis=1), np.linalg.norm(x + sign * y, axis=1))
    if kind == "direction":
        return np.arctan2(np.linalg.norm(np.cross(x, y), axis=1), np.einsum("ij,ij->i", x, y))
    return np.abs(x - y).max(axis=1)


def _angle_one(kind: str, x: tuple, y: tuple) -> float:
    """:func:`_angles` for one pair of plain-float tuples (the per-sample path: no numpy)."""
    if kind == "quaternion":
        (x0, x1, x2, x3), (y0, y1, y2, y3) = x, y
        if x0 * y0 + x1 * y1 + x2 * y2 + x3 * y3 < 0.0:
            y0, y1, y2, y3 = -y0, -y1, -y2, -y3
        minus = math.sqrt((x0 - y0) ** 2 + (x1 - y1) ** 2 + (x2 - y2) ** 2 + (x3 - y3) ** 2)
        plus = math.sqrt((x0 + y0) ** 2 + (x1 + y1) ** 2 + (x2 + y2) ** 2 + (x3 + y3) ** 2)
        return 2.0 * math.atan2(minus, plus)
    if kind == "direction":
        (x0, x1, x2), (y0, y1, y2) = x, y
        cross = math.sqrt((x1 * y2 - x2 * y1) ** 2 + (x2 * y0 - x0 * y2) ** 2 + (x0 * y1 - x1 * y0) ** 2)
        return math.atan2(cross, x0 * y0 + x1 * y1 + x2 * y2)
    return max(abs(a - b) for a, b in zip(x, y))


class MotionDetector:
    """Marks live samples still and static from a motion signal, carrying its history across blocks.

    Parameters
    ----------
    window : s, the span the rate is measured over
    min_rate : rad/s, below it a sample is still
    min_hold : s, still this long makes a sample static
    """

    def __init__(self, window: float, min_rate: float, min_hold: float) -> None:
        self.window, self.min_rate, self.min_hold = window, min_rate, min_hold
        self.kind: str | None = None
        # The history is held as arrays (blocks) or as a deque of (time, signal tuple) (single samples),
        # converted only when the caller switches between the two.
        self._time = np.empty(0)
        self._signal: np.ndarray | None = None
        self._recent: deque | None = None
        self.last_moving = -math.inf  # time of the newest sample that was not still

    def reset(self) -> None:
        """Forget the history (a new signal kind, or a gap in the stream)."""
        self._time, self._signal, self._recent, self.last_moving = np.empty(0), None, None, -math.inf

    def _as_arrays(self) -> None:
        if self._recent is not None:
            recent, self._recent = self._recent, None
            self._time = np.array([r[0] for r in recent], dtype=float)
            self._signal = np.array([r[1] for r in recent], dtype=float) if recent else None

    def _as_deque(self) -> deque:
        if self._recent is None:
            signals = [] if self._signal is None else [tuple(row) for row in self._signal.tolist()]
            self._recent = deque(zip(self._time.tolist(), signals))
            self._time, self._signal = np.empty(0), None
        return self._recent

    def static_one(self, time: float, kind: str, signal: tuple) -> tuple[bool, bool]:
        """:meth:`static` for one sample in plain floats: (static, moving).

        Parameters
        ----------
        time : s, after the previous sample
        kind : {"quaternion", "direction", "joints"}
        signal : tuple of floats (a unit quaternion, a direction of any length, or joint positions)
        """
        if kind == "direction":
            norm = math.sqrt(signal[0] * signal[0] + signal[1] * signal[1] + signal[2] * signal[2])
            signal = (signal[0] / norm, signal[1] / norm, signal[2] / norm)
        recent = self._as_deque()
        if kind != self.kind or (recent and len(recent[0][1]) != len(signal)):
            self.reset()
            self.kind = kind
            recent = self._as_deque()
        recent.append((time, signal))
        cutoff = time - self.window
        while len(recent) > 1 and recent[1][0] <= cutoff:  # keep the newest sample at least a window older
            recent.popleft()
        then, old = recent[0]
        if then <= cutoff and len(recent) > 1:
            still = _angle_one(kind, signal, old) / (time - then) < self.min_rate
            moving = not still
        else:
            still = moving = False
        if not still:
            self.last_moving = time
        return still and time - self.last_moving >= self.min_hold, moving

    def static(self, time: np.ndarray, kind: str, signal: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Static and moving masks of a block of samples, each of shape (n,).

        A sample is moving when its rate is known and at least ``min_rate``; without ``window`` s
        of history it is neither static nor moving.

        Parameters
        ----------
        time : ndarray of shape (n,), s, increasing
        kind : {"quaternion", "direction", "joints"}
        signal : ndarray of shape (n, k), the motion signal (directions need not be unit length)
        """
        if kind == "direction":
            signal = signal / np.linalg.norm(signal, axis=1, keepdims=True)
        self._as_arrays()
        if kind != self.kind or (self._signal is not None and self._signal.shape[1] != signal.shape[1]):
            self.reset()
            self.kind = kind
        times = np.concatenate([self._time, time])
        signals = signal if self._signal is None else np.vstack([self._signal, signal])
        first = times.size - time.size
        ref = np.searchsorted(times, time - self.window, side="right") - 1
        have = ref >= 0
        rate = np.full(time.size, np.inf)
        if have.any():
            k = np.flatnonzero(have)
            span = time[k] - times[ref[k]]
            rate[k] = _angles(kind, signals[first + k], signals[ref[k]]) / span
        still = rate < self.min_rate
        moving_time = np.where(still, -np.inf, time)
        last = np.maximum(np.maximum.accumulate(moving_time), self.last_moving)
        self.last_moving = float(last[-1])
        keep = max(int(np.searchsorted(times, times[-1] - self.window, side="right")) - 1, 0)
        self._time, self._signal = times[keep:], signals[keep:]
        return still & (time - last >= self.min_hold), np.isfinite(rate) & ~still
