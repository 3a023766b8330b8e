"""Sufficient statistics of the payload regressor, per wrench axis, chunk by chunk.

The stacked regressor has six rows per sample; keeping the statistics of
each axis apart (they simply add up to the stacked ones) gives the residual
RMS of every axis and a per-axis noise weighting without a second pass over
the data. Static poses need only the moments of ``[g, 1, wrench]`` (one
10 × 10 product per chunk); the dynamic regressor is built chunk by chunk.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..core.statistics import SufficientStatistics, dense_statistics, sum_statistics
from ..runtime.threads import map_ranges
from .kinematics import Kinematics
from .regressor import dynamic_regressor, static_regressor

CHUNK_SAMPLES = 16_384  # a (chunk, 6, 16) regressor block stays a few MB


@dataclass
class AxisStatistics:
    """One :class:`~ftcal.core.statistics.SufficientStatistics` (p columns, 1 target) per wrench axis."""

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
    if not dynamic:
        return _static_statistics(wrench, kinematics.gravity, chunk)
    n = wrench.shape[0]
    p = 16

    def work(begin: int, end: int) -> AxisStatistics:
        parts = [SufficientStatistics.zeros(p, 1) for _ in range(6)]
        for start in range(begin, end, chunk):
            stop = min(start + chunk, end)
            rows = kinematics.rows(start, stop)
            y = dynamic_regressor(rows.proper(), rows.angular_velocity, rows.angular_acceleration)
            for axis in range(6):
                parts[axis] = parts[axis] + dense_statistics(np.ascontiguousarray(y[:, axis, :]),
                                                             wrench[start:stop, axis:axis + 1])
        return AxisStatistics(tuple(parts))

    pieces = map_ranges(work, n, chunk)
    if not pieces:
        return AxisStatistics(tuple(SufficientStatistics.zeros(p, 1) for _ in range(6)))
    return AxisStatistics(tuple(sum_statistics([piece.axes[a] for piece in pieces]) for a in range(6)))


def _static_maps() -> np.ndarray:
    """L of shape (6, 10, 4): the static regressor row of axis i is ``L[i] @ [g, 1]`` (affine in g)."""
    constant = static_regressor(np.zeros(3))[0]
    slopes = [static_regressor(e)[0] - constant for e in np.eye(3)]
    return np.stack([np.column_stack([slopes[0][i], slopes[1][i], slopes[2][i], constant[i]]) for i in range(6)])


def _static_statistics(wrench: np.ndarray, gravity: np.ndarray, chunk: int) -> AxisStatistics:
    """Static statistics from the moments of z = [g, 1, wrench] alone: one 10 × 10 product per chunk.

    Every static regressor row is ``L_i [g, 1]``, so AᵀA of axis i is
    ``L_i (Σ z zᵀ) L_iᵀ`` and Aᵀb is ``L_i Σ z w_i``; exact, and far cheaper
    than forming the N × 6 × 10 regressor.
    """
    n = wrench.shape[0]

    def work(begin: int, end: int) -> tuple[np.ndarray, np.ndarray]:
        moments = np.zeros((10, 10))
        z = np.empty((min(chunk, end - begin), 10))
        maxabs = np.zeros(4)
        for start in range(begin, end, chunk):
            stop = min(start + chunk, end)
            block = z[:stop - start]
            block[:, :3] = gravity[start:stop]
            block[:, 3] = 1.0
            block[:, 4:] = wrench[start:stop]
            moments += block.T @ block
            np.maximum(maxabs, np.abs(block[:, :4]).max(axis=0), out=maxabs)
        return moments, maxabs

    parts = map_ranges(work, n, chunk)
    moments = sum((m for m, _ in parts), np.zeros((10, 10)))
    maxabs = np.max([a for _, a in parts], axis=0) if parts else np.zeros(4)
    zz, zw, ww = moments[:4, :4], moments[:4, 4:], np.diag(moments[4:, 4:])
    axes = []
    for i, lmap in enumerate(_static_maps()):
        axes.append(SufficientStatistics(lmap @ zz @ lmap.T, (lmap @ zw[:, i])[:, None], ww[i:i + 1].copy(),
                                         np.array([moments[3, 4 + i]]), np.abs(lmap) @ maxabs, n))
    return AxisStatistics(tuple(axes))
