"""Grouped (block) jackknife standard errors with t intervals.

An estimate's spread when each of G contiguous blocks of a recording is left
out in turn measures its uncertainty without assuming independent samples:
residuals correlated within a block (slow noise, drift, a systematic pose
order) move the leave-one-block-out estimates together, so the spread grows
with them. The covariance ``(G − 1)/G · Σ_b (θ₋b − θ̄)(θ₋b − θ̄)ᵀ`` is the CR3
cluster-robust estimate; it is scaled by ``(t_{G−1, 0.975} / z_{0.975})²`` so
that ±1.96 standard errors is a 95 % interval with G − 1 degrees of freedom.

Callers refit from summed statistics (total minus the block's), never from the
samples again. ``ftcal payload`` and ``ftcal fit --estimate-payload`` cut a
recording into :data:`~ftcal.core.limits.ROBUST_CLUSTERS` blocks.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from .precision import SOLUTION


T_EXPANSION_DOF = 500  # above this many degrees of freedom, t quantiles from their expansion in 1/ν


def block_edges(n_samples: int, n_blocks: int) -> np.ndarray:
    """Row edges of ``min(n_blocks, n_samples)`` contiguous blocks of equal size (up to one row).

    Parameters
    ----------
    n_samples, n_blocks : int

    Returns
    -------
    ndarray of int64, shape (blocks + 1,), from 0 to ``n_samples``

    Examples
    --------
    >>> block_edges(10, 4).tolist()
    [0, 2, 5, 7, 10]
    """
    return np.linspace(0, n_samples, min(n_blocks, n_samples) + 1).astype(np.int64)


def t_scale(dof: int) -> float:
    """``t_{dof, 0.975} / z_{0.975}``: widens ±1.96 standard errors to a 95 % interval with ``dof`` degrees.

    Examples
    --------
    >>> round(t_scale(19), 4)  # t_{19, 0.975} = 2.0930 (tables), z = 1.9600
    1.0679
    """
    from statistics import NormalDist

    return t_quantile(0.975, dof) / NormalDist().inv_cdf(0.975)


def t_cdf(t: float, dof: int) -> float:
    """P(T ≤ ``t``) for Student's t with ``dof`` (integer ≥ 1) degrees of freedom, in closed form.

    With θ = atan(t/√ν), P(|T| ≤ t) is a finite sum in cos θ (Abramowitz & Stegun 26.7.3-4): for ν odd
    (2/π)(θ + sin θ (cos θ + (2/3) cos³θ + … + (2·4⋯(ν−3))/(1·3⋯(ν−2)) cos^(ν−2) θ)), for ν even
    sin θ (1 + (1/2) cos²θ + … + (1·3⋯(ν−3))/(2·4⋯(ν−2)) cos^(ν−2) θ): a few lines of the standard
    library where ``scipy.special`` costs most of a second of imports (``ftcal payload`` needs one quantile).

    Examples
    --------
    >>> round(t_cdf(12.706204736174705, 1), 12)   # t_{1, 0.975} (tables: 12.706)
    0.975
    """
    theta = math.atan2(t, math.sqrt(dof))
    c2, sin = math.cos(theta) ** 2, math.sin(theta)
    if dof % 2:
        term, total = math.cos(theta), 0.0
        for k in range(1, (dof - 1) // 2 + 1):  # terms cos^(2k-1) θ with coefficients 2·4⋯(2k−2)/(1·3⋯(2k−1))
            total += term
            term *= c2 * (2 * k) / (2 * k + 1)
        two_sided = (2.0 / math.pi) * (theta + sin * total) if dof > 1 else 2.0 * theta / math.pi
    else:
        term, total = 1.0, 0.0
        for k in range(1, dof // 2 + 1):  # terms cos^(2k-2) θ with coefficients 1·3⋯(2k−3)/(2·4⋯(2k−2))
            total += term
            term *= c2 * (2 * k - 1) / (2 * k)
        two_sided = sin * total
    return 0.5 + 0.5 * two_sided  # two_sided carries the sign of t


def t_quantile(probability: float, dof: int) -> float:
    """The ``probability`` quantile (0.5 < p < 1) of Student's t, by bisection on :func:`t_cdf`.

    Examples
    --------
    >>> round(t_quantile(0.975, 19), 4)   # tables: 2.0930
    2.093
    """
    if dof > T_EXPANSION_DOF:
        # The sum has ν/2 terms; this far out the Cornish-Fisher expansion in 1/ν (A&S 26.7.5) is exact
        # to ~1e-14 and costs nothing.
        from statistics import NormalDist

        z = NormalDist().inv_cdf(probability)
        return (z + (z ** 3 + z) / (4 * dof) + (5 * z ** 5 + 16 * z ** 3 + 3 * z) / (96 * dof ** 2)
                + (3 * z ** 7 + 19 * z ** 5 + 17 * z ** 3 - 15 * z) / (384 * dof ** 3)
                + (79 * z ** 9 + 776 * z ** 7 + 1482 * z ** 5 - 1920 * z ** 3 - 945 * z) / (92160 * dof ** 4))
    low, high = 0.0, 1.0
    while t_cdf(high, dof) < probability:
        high *= 2.0
    for _ in range(200):
        middle = 0.5 * (low + high)
        if t_cdf(middle, dof) < probability:
            low = middle
        else:
            high = middle
        if high - low <= 1e-14 * high:
            break
    return 0.5 * (low + high)


def jackknife_covariance(refits: Sequence[np.ndarray]) -> np.ndarray | None:
    """Grouped-jackknife covariance from the leave-one-block-out estimates, t-scaled (see the module).

    Parameters
    ----------
    refits : sequence of ndarray of shape (p,), one per block left out

    Returns
    -------
    ndarray of shape (p, p), or None with fewer than two refits
    """
    g = len(refits)
    if g < 2:
        return None
    spread = np.asarray(refits, dtype=np.float64) - np.mean(refits, axis=0)
    covariance = t_scale(g - 1) ** 2 * (g - 1) / g * (spread.T @ spread)
    return 0.5 * (covariance + covariance.T)


# Coarser partitions tried beside the finest: residuals correlated over more than one block (a drift that
# follows the pose order, a slow wander) move neighbouring blocks together, and only merged blocks see it.
COARSER_BLOCKS = (10, 5)
# The coarsest partition's standard error above this multiple of the finest one's (the t scales of 4 and 19
# degrees of freedom alone make it 1.33; a smooth drift reaches about 3.2; short AR(1) noise crossed it in 1
# of 200 recordings of tests/data/test_payload_coverage.py): the errors are correlated
# over a fifth of the recording or more, so the recording holds only a few independent pieces of evidence and
# its standard error is itself uncertain (a warning says so).
UNDETERMINED_ERROR = 3.0


def merged_partitions(n_blocks: int, coarser: Sequence[int] = COARSER_BLOCKS) -> list[np.ndarray]:
    """Edges (in units of the ``n_blocks`` fine blocks) of the coarser partitions into contiguous runs.

    Only partitions with at least 3 and fewer than ``n_blocks`` runs are returned (a 2-run jackknife has
    one degree of freedom).

    Examples
    --------
    >>> [e.tolist() for e in merged_partitions(20)]
    [[0, 2, 4, 6, 8, 10, 12, 14, 16, 18, 20], [0, 4, 8, 12, 16, 20]]
    """
    return [block_edges(n_blocks, g) for g in coarser if 3 <= g < n_blocks]


@dataclass(frozen=True)
class Widened:
    """A covariance whose standard errors are the largest over several block partitions.

    Attributes
    ----------
    covariance : (p, p) the finest partition's correlations, each standard error raised to the widest
    blocks : number of blocks of each partition tried, finest first
    ratio : (p,) the coarsest partition's standard error over the finest one's (1 without coarser ones)
    """

    covariance: np.ndarray
    blocks: tuple[int, ...]
    ratio: np.ndarray

    @property
    def undetermined(self) -> bool:
        """The error grows with the blocks' length beyond :data:`UNDETERMINED_ERROR`: not determined by the data."""
        return bool(np.any(self.ratio > UNDETERMINED_ERROR))


def widest_covariance(partitions: Sequence[Sequence[np.ndarray]]) -> Widened | None:
    """Grouped-jackknife covariances over several partitions, each standard error the largest (t-scaled).

    A jackknife over G blocks is honest when the errors of different blocks are uncorrelated; errors
    correlated over longer stretches make it too small, and a coarser partition (fewer, longer blocks)
    catches them at the price of fewer degrees of freedom, which its t scale pays. The correlations are the
    finest partition's (the best determined), each variance raised to the largest partition's.

    Parameters
    ----------
    partitions : per partition, finest first, the leave-one-block-out estimates (each of shape (p,))

    Returns
    -------
    Widened, or None when the finest partition has fewer than two refits
    """
    finest = jackknife_covariance(partitions[0]) if partitions else None
    if finest is None:
        return None
    se = np.sqrt(np.maximum(np.diag(finest), 0.0))
    widest, blocks, last = se.copy(), [len(partitions[0])], se.copy()
    for refits in partitions[1:]:
        covariance = jackknife_covariance(refits)
        if covariance is None or len(refits) < 3:
            continue
        last = np.sqrt(np.maximum(np.diag(covariance), 0.0))
        widest = np.maximum(widest, last)
        blocks.append(len(refits))
    # An error below the solution's precision of its estimate is rounding (a noiseless fit): not widened, ratio 1,
    # so what is printed does not depend on the CPU's rounding.
    scale = np.abs(np.asarray(partitions[0], dtype=np.float64)).max(axis=0)
    positive = se > SOLUTION * scale
    factor = np.where(positive, widest / np.where(positive, se, 1.0), 1.0)
    ratio = np.where(positive, last / np.where(positive, se, 1.0), 1.0)
    return Widened(finest * factor[:, None] * factor[None, :], tuple(blocks), ratio)
