"""Sufficient statistics of the payload regressor, per wrench axis, chunk by chunk.

The stacked regressor has six rows per sample; keeping the statistics of
each axis apart (they simply add up to the stacked ones) gives the residual
RMS of every axis and a per-axis noise weighting without a second pass over
the data.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .._threads import map_ranges
from ..statistics import SufficientStatistics, dense_statistics, sum_statistics
from .kinematics import Kinematics
from .regressor import dynamic_regressor, static_regressor

CHUNK_SAMPLES = 16_384  # a (chunk, 6, 16) regressor block stays a few MB


@dataclass
class AxisStatistics:
    """One :class:`~ftcal.statistics.SufficientStatistics` (p columns, 1 target) per wrench axis."""

    axes: tuple[SufficientStatistics, ...]

    def __add__(self, other: "AxisStatistics") -> "AxisStatistics":
        return AxisStatistics(tuple(a + b for a, b in zip(self.axes, other.axes)))

    @property
    def n_samples(self) -> int:
        return self.axes[0].n_samples

    @property
    def n_parameters(self) -> int:
        return self.axes[0].n_features

    def gram(self, weights: np.ndarray | None = None) -> np.ndarray:
        """Σ_axis w_axis · AᵀA, shape (p, p)."""
        w = np.ones(6) if weights is None else weights
        return sum(wi * s.gram for wi, s in zip(w, self.axes))

    def cross(self, weights: np.ndarray | None = None) -> np.ndarray:
        """Σ_axis w_axis · Aᵀb, shape (p,)."""
        w = np.ones(6) if weights is None else weights
        return sum(wi * s.cross[:, 0] for wi, s in zip(w, self.axes))

    def residual_sum_of_squares(self, theta: np.ndarray) -> np.ndarray:
        """‖A θ − b‖² of each axis, shape (6,), from the statistics alone."""
        rss = [s.target_sq[0] - 2.0 * theta @ s.cross[:, 0] + theta @ s.gram @ theta for s in self.axes]
        return np.maximum(np.array(rss), 0.0)  # rounding can push an exact fit below zero


def payload_statistics(wrench: np.ndarray, kinematics: Kinematics, dynamic: bool = False,
                       chunk: int = CHUNK_SAMPLES) -> AxisStatistics:
    """Statistics of ``wrench ≈ Y θ`` for the static (10) or dynamic (16) parameter set.

    Parameters
    ----------
    wrench : ndarray of shape (n_samples, 6)
        The wrench read by the sensor, N and N·m (ftcal sign convention).
    kinematics : Kinematics
        With ``n_samples`` rows; ``dynamic`` uses its ω, α and proper acceleration.
    dynamic : bool
        Fit the 10 inertial parameters plus 6 biases instead of mass, first
        moment and 6 biases.

    Returns
    -------
    AxisStatistics
    """
    n = wrench.shape[0]
    p = 16 if dynamic else 10

    def work(begin: int, end: int) -> AxisStatistics:
        parts = [SufficientStatistics.zeros(p, 1) for _ in range(6)]
        for start in range(begin, end, chunk):
            stop = min(start + chunk, end)
            rows = kinematics.rows(start, stop)
            if dynamic:
                y = dynamic_regressor(rows.proper(), rows.angular_velocity, rows.angular_acceleration)
            else:
                y = static_regressor(rows.gravity)
            for axis in range(6):
                parts[axis] = parts[axis] + dense_statistics(np.ascontiguousarray(y[:, axis, :]),
                                                             wrench[start:stop, axis:axis + 1])
        return AxisStatistics(tuple(parts))

    pieces = map_ranges(work, n, chunk)
    if not pieces:
        return AxisStatistics(tuple(SufficientStatistics.zeros(p, 1) for _ in range(6)))
    return AxisStatistics(tuple(sum_statistics([piece.axes[a] for piece in pieces]) for a in range(6)))
