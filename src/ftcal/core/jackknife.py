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

import numpy as np


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
