"""Affine input normalization, u_norm = (u - offset) / scale.

Two modes:

``"center"`` (default)
    offset = mid-range, scale = half-range, so every input spans [-1, 1].
    Centering is what keeps degree-4/5 monomials well conditioned when raw
    channels carry large offsets (ADC counts around 5000, temperatures ~35 °C).
``"maxabs"``
    offset = 0, scale = max |u|: the paper's normalization. After the solvers'
    column max-abs scaling the features are exactly the paper's normalized
    regressor columns.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..runtime.checks import check_choice
from .limits import NORMALIZATIONS


@dataclass(frozen=True)
class Normalization:
    """Per-column offset and scale; ``apply`` maps raw values to normalized ones.

    Attributes
    ----------
    offset, scale : ndarray of shape (n_columns,)

    Examples
    --------
    >>> import numpy as np
    >>> Normalization(np.array([10.0]), np.array([2.0])).apply(np.array([[12.0]])).tolist()
    [[1.0]]
    """

    offset: np.ndarray
    scale: np.ndarray

    def apply(self, values: np.ndarray) -> np.ndarray:
        return (values - self.offset) / self.scale

    @classmethod
    def identity(cls, n_columns: int) -> "Normalization":
        return cls(np.zeros(n_columns), np.ones(n_columns))


def normalization_from_range(low: np.ndarray, high: np.ndarray, mode: str = "center") -> Normalization:
    """Normalization for columns spanning [low, high]; a constant column gets scale 1.

    Parameters
    ----------
    low, high : ndarray of shape (n_columns,)
    mode : {"center", "maxabs"}

    Returns
    -------
    Normalization

    Examples
    --------
    >>> import numpy as np
    >>> n = normalization_from_range(np.array([4.0]), np.array([8.0]), "center")
    >>> n.offset.tolist(), n.scale.tolist()
    ([6.0], [2.0])
    >>> normalization_from_range(np.array([4.0]), np.array([8.0]), "maxabs").scale.tolist()
    [8.0]
    """
    check_choice(mode, "normalization", "CalibrationModel", NORMALIZATIONS)
    low = np.asarray(low, dtype=np.float64)
    high = np.asarray(high, dtype=np.float64)
    if mode == "center":
        offset = (high + low) / 2.0
        scale = (high - low) / 2.0
    else:
        offset = np.zeros_like(low)
        scale = np.maximum(np.abs(low), np.abs(high))
    # A constant column would divide by zero; scale 1 keeps it finite and the
    # ill-posedness is reported by the fit's rank check instead.
    scale = np.where(scale > 0, scale, 1.0)
    return Normalization(offset, scale)


def variables_normalization(variables: list[dict]) -> Normalization:
    """The normalization of a model file's ``inputs`` or ``outputs`` entries (``offset``, ``scale``)."""
    return Normalization(np.array([v["offset"] for v in variables], dtype=np.float64),
                         np.array([v["scale"] for v in variables], dtype=np.float64))


def variables_range(variables: list[dict]) -> np.ndarray:
    """Training [min, max] of a model file's ``inputs`` or ``outputs`` entries, shape (n, 2).

    ``null`` means unknown: an unbounded side, so predictions never warn there.
    """
    return np.array([[-np.inf if lo is None else lo, np.inf if hi is None else hi]
                     for lo, hi in (v["range"] for v in variables)], dtype=np.float64).reshape(-1, 2)
