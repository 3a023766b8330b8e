"""Distinct poses in the data, and the warning when a fit has nearly as many coefficients as poses."""

from __future__ import annotations

import warnings

import numpy as np

from ...runtime.errors import ParameterWarning
from ..limits import POSE_BINS, SATURATION_RATIO


class SaturationWarning(ParameterWarning):
    """A least-squares fit has nearly as many coefficients per output as distinct poses."""


def pose_cells(u: np.ndarray, input_range: np.ndarray, bins: int = POSE_BINS) -> set[bytes]:
    """The cells of a grid over the inputs' ranges (``bins`` per input) that samples ``u`` occupy.

    Their number counts distinct poses: a static load case (one pose and its noise) fills
    one cell, or a few at a cell border; a sweep fills one cell per 1/``bins`` of the range.

    Parameters
    ----------
    u : ndarray of shape (n_samples, n_inputs), raw inputs
    input_range : ndarray of shape (n_inputs, 2), min and max of each input over all the data
    bins : int

    Returns
    -------
    set, one entry per occupied cell (an int, or bytes when the grid has 2⁶³ cells or more;
    the sets of several chunks of the same inputs unite)

    Examples
    --------
    >>> u = np.array([[0.0, 0.0], [0.01, 0.0], [1.0, 1.0]])
    >>> len(pose_cells(u, np.array([[0.0, 1.0], [0.0, 1.0]])))
    2
    """
    low, span = input_range[:, 0], np.maximum(input_range[:, 1] - input_range[:, 0], np.finfo(float).tiny)
    cells = np.asarray(u, dtype=np.float64) - low  # (u - low) / span * bins, in place
    cells /= span
    cells *= bins
    np.floor(cells, out=cells)
    np.clip(cells, 0, bins - 1, out=cells)
    if float(bins) ** cells.shape[1] < 2.0**53:
        # One float64 per cell, exact below 2⁵³: a BLAS product, and the distinct codes found by sorting
        # before they become Python ints (a static load case is thousands of samples in a few cells).
        codes = np.unique(cells @ (float(bins) ** np.arange(cells.shape[1])))
        return set(codes.astype(np.int64).tolist())
    cells = cells.astype(np.int64)
    if float(bins) ** cells.shape[1] < 2.0**63:  # one integer per cell: far faster to make unique than bytes
        return set((cells @ (bins ** np.arange(cells.shape[1], dtype=np.int64))).tolist())
    rows = np.ascontiguousarray(cells.astype(np.uint8)).view(np.dtype((np.void, cells.shape[1])))
    return {bytes(r) for r in np.unique(rows.ravel())}


def warn_if_saturated(n_coefficients: int, n_poses: int, n_groups: int, what: str = "The fit") -> bool:
    """Warn (:class:`SaturationWarning`) when coefficients per output exceed
    :data:`~ftcal.core.limits.SATURATION_RATIO` times the distinct poses; True when it warned.

    Samples do not count: many samples of one pose determine one point of the map.
    """
    if n_coefficients <= SATURATION_RATIO * n_poses:
        return False
    warnings.warn(SaturationWarning(
        ("degree", "ridge", "lasso"),
        f"{what} is near saturation: {n_coefficients} coefficients per output for {n_poses} distinct poses "
        f"({n_groups} groups); it can fit the poses' noise and validate worse than affine. Lower the degree, "
        "use {ridge}/{lasso} (or {degree} auto), or record more poses."), stacklevel=2)
    return True
