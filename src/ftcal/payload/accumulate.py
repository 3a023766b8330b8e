"""Sufficient statistics of the payload regressor, per wrench axis, chunk by chunk.

The stacked regressor has six rows per sample; keeping the statistics of
each axis apart (they simply add up to the stacked ones) gives the residual
RMS of every axis and a per-axis noise weighting without a second pass over
the data. Static poses need only the moments of ``[g, 1, wrench]`` (one
10 × 10 product per chunk); the dynamic regressor is built chunk by chunk.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

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

    def take(self, columns: np.ndarray) -> "AxisStatistics":
        """The statistics of some of the regressor columns (the others held at zero)."""
        c = np.asarray(columns, dtype=np.int64)
        return AxisStatistics(tuple(SufficientStatistics(s.gram[np.ix_(c, c)], s.cross[c], s.target_sq, s.target_sum,
                                                         s.column_maxabs[c], s.n_samples) for s in self.axes))

    def residual_sum_of_squares(self, theta: np.ndarray) -> np.ndarray:
        """‖A θ − b‖² of each axis, shape (6,), from the statistics alone."""
        rss = [s.target_sq[0] - 2.0 * theta @ s.cross[:, 0] + theta @ s.gram @ theta for s in self.axes]
        return np.maximum(np.array(rss), 0.0)  # rounding can push an exact fit below zero


def payload_statistics(wrench: np.ndarray, kinematics: Kinematics, dynamic: bool = False,
                       chunk: int = CHUNK_SAMPLES, extra: np.ndarray | None = None) -> AxisStatistics:
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
    extra : ndarray of shape (n_samples, k) or None
        Static model only: k covariates (e.g. time, temperature) the bias is
        affine in; θ gains 6 coefficients per covariate, ordered covariate
        by covariate, axis by axis (``Fx..Tz``).

    Returns
    -------
    AxisStatistics
    """
    if not dynamic:
        return _static_statistics(wrench, kinematics.gravity, chunk, extra)
    if extra is not None:
        raise ValueError("covariates of the bias are supported by the static model only")
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


@lru_cache(maxsize=1)
def _static_maps() -> np.ndarray:
    """L of shape (6, 10, 4): the static regressor row of axis i is ``L[i] @ [g, 1]`` (affine in g); read-only."""
    constant = static_regressor(np.zeros(3))[0]
    slopes = [static_regressor(e)[0] - constant for e in np.eye(3)]
    maps = np.stack([np.column_stack([slopes[0][i], slopes[1][i], slopes[2][i], constant[i]]) for i in range(6)])
    maps.flags.writeable = False
    return maps


def _static_statistics(wrench: np.ndarray, gravity: np.ndarray, chunk: int,
                       extra: np.ndarray | None = None) -> AxisStatistics:
    """Static statistics from the moments of z = [g, 1, extra, wrench] alone: one small product per chunk.

    Every static regressor row is ``L_i [g, 1]`` (plus the axis' own covariate
    columns), so AᵀA of axis i is ``L_i (Σ z zᵀ) L_iᵀ`` and Aᵀb is ``L_i Σ z w_i``;
    exact, and far cheaper than forming the N × 6 × p regressor.
    """
    n = wrench.shape[0]
    k = 0 if extra is None else extra.shape[1]
    d = 4 + k  # regressor inputs: g, 1, covariates

    def work(begin: int, end: int) -> tuple[np.ndarray, np.ndarray]:
        moments = np.zeros((d + 6, d + 6))
        z = np.empty((min(chunk, end - begin), d + 6))
        maxabs = np.zeros(d)
        for start in range(begin, end, chunk):
            stop = min(start + chunk, end)
            block = z[:stop - start]
            block[:, :3] = gravity[start:stop]
            block[:, 3] = 1.0
            if k:
                block[:, 4:d] = extra[start:stop]
            block[:, d:] = wrench[start:stop]
            moments += block.T @ block
            np.maximum(maxabs, np.abs(block[:, :d]).max(axis=0), out=maxabs)
        return moments, maxabs

    parts = map_ranges(work, n, chunk)
    moments = sum((m for m, _ in parts), np.zeros((d + 6, d + 6)))
    maxabs = np.max([a for _, a in parts], axis=0) if parts else np.zeros(d)
    return static_axis_statistics(moments, maxabs, n)


def static_axis_statistics(moments: np.ndarray, maxabs: np.ndarray, n: int) -> AxisStatistics:
    """Per-axis statistics of the static model from the moments ``Σ z zᵀ`` of z = [g, 1, extra, wrench].

    Parameters
    ----------
    moments : ndarray of shape (d + 6, d + 6), d = 4 + number of covariates
    maxabs : ndarray of shape (d,), max |z| of the regressor inputs (column scaling)
    n : number of samples summed

    Returns
    -------
    AxisStatistics with 10 + 6 k parameters
    """
    d = moments.shape[0] - 6
    k = d - 4
    zz, zw, ww = moments[:d, :d], moments[:d, d:], np.diag(moments[d:, d:])
    axes = []
    for i, lmap4 in enumerate(_static_maps()):
        lmap = np.zeros((10 + 6 * k, d))
        lmap[:10, :4] = lmap4
        for j in range(k):
            lmap[10 + 6 * j + i, 4 + j] = 1.0  # axis i's bias moves with covariate j
        axes.append(SufficientStatistics(lmap @ zz @ lmap.T, (lmap @ zw[:, i])[:, None], ww[i:i + 1].copy(),
                                         np.array([moments[3, d + i]]), np.abs(lmap) @ maxabs, n))
    return AxisStatistics(tuple(axes))
