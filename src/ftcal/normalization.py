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

from ._checks import check_choice

MODES = ("center", "maxabs")


@dataclass(frozen=True)
class Normalization:
    """Per-column offset and scale; ``apply`` maps raw values to normalized ones."""

    offset: np.ndarray
    scale: np.ndarray

    def apply(self, values: np.ndarray) -> np.ndarray:
        return (values - self.offset) / self.scale

    @classmethod
    def identity(cls, n_columns: int) -> "Normalization":
        return cls(np.zeros(n_columns), np.ones(n_columns))


def normalization_from_range(low: np.ndarray, high: np.ndarray, mode: str = "center") -> Normalization:
    """Normalization for columns spanning [low, high]; a constant column gets scale 1."""
    check_choice(mode, "normalization", "CalibrationModel", MODES)
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
