"""Directions the product reports or stores, made the same on every machine.

An eigenvector or a null-space basis vector has no sign of its own, and two
components of equal size have no order of their own: LAPACK builds (OpenBLAS
core types, thread counts) pick differently. Everything ftcal prints or writes
about a direction goes through these rules:

- **sign**: the first component whose magnitude is at least :data:`CANONICAL_TIE`
  of the largest is positive (so ``(−0.71, 0, 0.71)`` reads ``(0.71, 0, −0.71)``);
- **order by size**: magnitudes that agree to :data:`CANONICAL_TIE` (relative) are
  a tie, broken by the index, never by rounding;
- **precision**: components are stated to :data:`ftcal.core.precision.DIRECTION` of the
  largest (:func:`ftcal.core.precision.settle`), so one that is 0 in exact arithmetic is 0.
"""

from __future__ import annotations

import numpy as np

from .precision import DIRECTION, settle

CANONICAL_TIE = 1e-6
"""Relative difference under which two magnitudes are taken as equal (rounding differs between
BLAS kernels by ~1e-15 relative; a real difference a user should see is far above 1e-6)."""


def canonical_sign(vector: np.ndarray) -> np.ndarray:
    """``vector`` with the sign that makes its first sizeable component positive, to :data:`DIRECTION`.

    Parameters
    ----------
    vector : ndarray of shape (n,)

    Returns
    -------
    ndarray of shape (n,)
        ``vector`` or ``-vector``, settled to :data:`DIRECTION` of its largest component; a zero
        vector is returned as zeros.

    Examples
    --------
    >>> canonical_sign(np.array([-0.5, 1e-17, 0.5])).tolist()
    [0.5, 0.0, -0.5]
    """
    v = np.asarray(vector, dtype=np.float64)
    size = np.abs(v)
    if not size.any():
        return v + 0.0
    first = int(np.flatnonzero(size >= size.max() * CANONICAL_TIE)[0])
    return settle(-v if v[first] < 0 else v, DIRECTION)


def order_by_size(values: np.ndarray) -> np.ndarray:
    """Indices of ``values`` by decreasing magnitude, ties (to :data:`CANONICAL_TIE`) in index order.

    Parameters
    ----------
    values : ndarray of shape (n,)

    Returns
    -------
    ndarray of shape (n,), int

    Examples
    --------
    >>> order_by_size(np.array([0.7071067811865476, 0.1, -0.7071067811865475])).tolist()
    [0, 2, 1]
    """
    size = np.abs(np.asarray(values, dtype=np.float64))
    order = np.argsort(-size, kind="stable")
    if size.size < 2:
        return order
    # Runs of neighbours (in size order) closer than CANONICAL_TIE · max are one tie: index order inside.
    tie = np.abs(np.diff(size[order])) <= CANONICAL_TIE * size.max()
    run = np.concatenate(([0], np.cumsum(~tie)))
    return order[np.lexsort((order, run))]
