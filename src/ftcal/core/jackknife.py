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

from collections.abc import Sequence

import numpy as np


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
    from scipy.special import ndtri, stdtrit  # scipy.stats would cost a second of imports

    return float(stdtrit(dof, 0.975) / ndtri(0.975))


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
