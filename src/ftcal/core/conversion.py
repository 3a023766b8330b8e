"""Exact algebra between the normalized basis a model is fitted in and raw-input monomials.

A fitted :class:`~ftcal.core.model.CalibrationModel` multiplies monomials of
normalized inputs ``x_i = (u_i − o_i) / s_i``. The paper's XML (and every
affine export) wants coefficients of monomials of the raw inputs ``u_i``. The
binomial expansion

    Π_i x_i^e_i = Π_i s_i^−e_i Σ_{k_i=0}^{e_i} C(e_i, k_i) u_i^k_i (−o_i)^(e_i−k_i)

maps each normalized column onto raw columns of the same lag and lower or equal
degree, which all exist in the basis; constants go to the offset column. Past
outputs (ARX) are affine in the same way. The raw table keeps the model's
column order, which is the paper's XML row order.

Raw monomials of large, off-center inputs (ADC counts near 5000) cancel
catastrophically at high degree, so :func:`precision_loss` measures what the
raw form loses against the model's own prediction.
"""

from __future__ import annotations

import itertools
import warnings
from collections.abc import Sequence

import numpy as np

from ..runtime.errors import FtcalError, PrecisionLossWarning
from .dataset import Dataset
from .features import RegressorLayout, substitution_matrix
from .model import CalibrationModel, model_from_fitted
from .normalization import Normalization

PRECISION_TOLERANCE = 1e-6
MAX_ALL_CORNERS_INPUTS = 10
_RAW_CHUNK = 256


def to_raw(model: CalibrationModel) -> np.ndarray:
    """Coefficients of raw-input monomials, shape (n_features, n_outputs), in the model's column order.

    Entries that overflow float64 (tiny input scales at a high degree) come out as ±inf or
    NaN, silently: writers use :func:`to_raw_finite`, which refuses them.
    """
    model._check_fitted()
    inn, out = model.input_normalization_, model.output_normalization_
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        t = substitution_matrix(model.layout_, inn.offset, inn.scale, out.offset, out.scale)
        return np.asarray(t @ model.coef_)


def to_raw_finite(model: CalibrationModel, target: str) -> np.ndarray:
    """:func:`to_raw`, or :class:`FtcalError` when a raw coefficient overflows (``target`` names the export)."""
    raw = to_raw(model)
    bad = ~np.isfinite(raw)
    if bad.any():
        row = int(np.argwhere(bad)[0][0])
        name = model.layout_.column_names(model.input_names_, model.output_names_)[row]
        raise FtcalError(f"{target}: the raw-input coefficient of {name!r} overflows float64 "
                         f"({int(bad.sum())} coefficient(s) not finite; the inputs' training range is too "
                         "narrow for this degree in raw units); keep the model in the JSON format.")
    return raw


def from_raw(raw_coef: np.ndarray, *, degree: int, input_names: Sequence[str],
             output_names: Sequence[str], na: int = 0, nb: int = 0,
             input_normalization: Normalization | None = None,
             output_normalization: Normalization | None = None,
             input_range: np.ndarray | None = None,
             output_range: np.ndarray | None = None) -> CalibrationModel:
    """A fitted model from raw-input coefficients (the inverse of :func:`to_raw`).

    Without normalizations the model evaluates raw monomials directly (identity
    normalization). With them, the coefficients are re-expressed in that
    normalized basis. Unknown training ranges are (−inf, inf): predictions
    never warn about being out of range.
    """
    nu, ny = len(input_names), len(output_names)
    inn = input_normalization or Normalization.identity(nu)
    out = output_normalization or Normalization.identity(ny)
    # ``normalization`` is only the mode a refit would use; the default is as good as any.
    model = model_from_fitted(
        degree=degree, na=na, nb=nb, normalization="center", coef=raw_coef,
        input_normalization=inn, output_normalization=out,
        input_names=input_names, output_names=output_names,
        input_range=_unbounded(nu) if input_range is None else input_range,
        output_range=_unbounded(ny) if output_range is None else output_range)
    if input_normalization is not None or output_normalization is not None:
        # u = (x − (−o/s)) / (1/s): the same substitution, with inverted parameters.
        t = substitution_matrix(model.layout_, -inn.offset / inn.scale, 1.0 / inn.scale,
                                -out.offset / out.scale, 1.0 / out.scale)
        model.coef_ = np.asarray(t @ model.coef_)
    return model


def _unbounded(n: int) -> np.ndarray:
    return np.tile([-np.inf, np.inf], (n, 1))


def predict_raw(layout: RegressorLayout, raw_coef: np.ndarray, u: np.ndarray,
                y: np.ndarray | None = None) -> np.ndarray:
    """Evaluate raw-input monomials with plain numpy powers (no shared code with the model).

    Parameters
    ----------
    u : ndarray of shape (n_samples, n_inputs), raw inputs
    y : ndarray of shape (n_samples, n_outputs), past outputs (ARX only)

    Returns
    -------
    ndarray of shape (n_samples − max_lag, n_outputs): rows k = max_lag .. n−1.
    """
    exps, lags = layout.exponent_rows()
    start, n = layout.max_lag, u.shape[0]
    result = np.zeros((max(n - start, 0), raw_coef.shape[1]))
    for lag in range(layout.nb + 1):
        cols = lags == lag
        shifted = u[start - lag:n - lag]
        for a in range(0, shifted.shape[0], _RAW_CHUNK):
            # powers[:, i, e] = u_i^e; a monomial is the product of one power per input.
            powers = shifted[a:a + _RAW_CHUNK, :, None] ** np.arange(layout.basis.degree + 1)
            monomials = np.ones((powers.shape[0], int(cols.sum())))
            for i, e in enumerate(exps[cols].T):
                monomials *= powers[:, i, e]
            result[a:a + _RAW_CHUNK] += monomials @ raw_coef[cols]
    ny = layout.n_outputs
    for j in range(1, layout.na + 1):
        result += y[start - j:n - j] @ raw_coef[(j - 1) * ny:j * ny]
    return result


def precision_loss(model: CalibrationModel, raw_coef: np.ndarray, *, n_points: int = 2000,
                   seed: int = 0, tolerance: float = PRECISION_TOLERANCE, warn: bool = True) -> float:
    """Largest |native − raw| prediction difference over the training box, in output units.

    Points are the box corners plus ``n_points`` uniform samples; for ARX models
    the past outputs are drawn from the training output range and both forms are
    compared one step ahead. Warns with :class:`PrecisionLossWarning` when the
    difference on any output exceeds ``tolerance`` times that output's range.
    """
    model._check_fitted()
    rng = np.random.default_rng(seed)
    u = sample_training_box(model, n_points, rng)
    layout = model.layout_
    if layout.is_static:
        native = model.predict(u, warn_out_of_range=False)
        raw = predict_raw(layout, raw_coef, u)
    else:
        out = model.output_normalization_
        y_low, y_high = _box(model.output_range_, out.offset - out.scale, out.offset + out.scale)
        y = rng.uniform(y_low, y_high, (u.shape[0], y_low.size))
        data = Dataset.from_arrays(u, y, input_names=model.input_names_, output_names=model.output_names_)
        native = model.predict(data, mode="one-step", warn_out_of_range=False)[layout.max_lag:]
        raw = predict_raw(layout, raw_coef, u, y)
    diff = np.max(np.abs(native - raw), axis=0)
    span = model.output_range_[:, 1] - model.output_range_[:, 0]
    # Without a finite training range, judge against the size of the predictions.
    span = np.where(np.isfinite(span) & (span > 0), span, np.maximum(np.max(np.abs(native), axis=0), 1.0))
    relative = diff / span
    worst = int(np.argmax(relative))
    if warn and relative[worst] > tolerance:
        warnings.warn(
            f"Raw-input coefficients lose precision: their predictions differ from the model's by up to "
            f"{diff[worst]:.3g} on {model.output_names_[worst]!r} ({relative[worst]:.2g} of its training "
            f"range) inside the training range. The native JSON model file keeps full precision.",
            PrecisionLossWarning, stacklevel=2)
    return float(diff.max())


def sample_training_box(model: CalibrationModel, n_points: int, rng: np.random.Generator) -> np.ndarray:
    """Inputs spanning the training box: its corners plus ``n_points`` uniform samples.

    Returns
    -------
    ndarray of shape (n_corners + n_points, n_inputs); where a training range is
    unknown, the normalization's ±1 box stands in for it.
    """
    inn = model.input_normalization_
    low, high = _box(model.input_range_, inn.offset - inn.scale, inn.offset + inn.scale)
    return np.vstack([_corners(low, high, rng), rng.uniform(low, high, (n_points, low.size))])


def _box(stored: np.ndarray, low_fallback: np.ndarray, high_fallback: np.ndarray):
    """Training box, falling back (where unknown) to the normalization's ±1 box."""
    finite = np.isfinite(stored).all(axis=1)
    return np.where(finite, stored[:, 0], low_fallback), np.where(finite, stored[:, 1], high_fallback)


def _corners(low: np.ndarray, high: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """All 2^nu box corners, or 2^MAX_ALL_CORNERS_INPUTS random ones for many inputs."""
    nu = low.size
    if nu <= MAX_ALL_CORNERS_INPUTS:
        pick = np.array(list(itertools.product((False, True), repeat=nu)))
    else:
        pick = rng.integers(0, 2, (2 ** MAX_ALL_CORNERS_INPUTS, nu)).astype(bool)
    return np.where(pick, high, low)


def affine_part(model: CalibrationModel, n_linear: int, target: str,
                advice: str = "Export a degree-1 model without other terms, or use the JSON or paper-xml format."
                ) -> tuple[np.ndarray, np.ndarray]:
    """Matrix (n_outputs, n_linear) and offset (n_outputs,) of a model affine in its first inputs.

    Raises :class:`FtcalError` naming the first other term (higher degree, lag,
    past output, or a later input such as temperature) with a nonzero raw
    coefficient; ``target`` names the export in that message and ``advice``
    ends it.
    """
    model._check_fitted()
    layout = model.layout_
    n_linear = min(n_linear, len(model.input_names_))
    raw = to_raw_finite(model, target)
    exps, lags = layout.exponent_rows()
    linear = [int(np.flatnonzero((lags == 0) & (exps.sum(axis=1) == 1) & (exps[:, i] == 1))[0])
              for i in range(n_linear)]
    names = layout.column_names(model.input_names_, model.output_names_)
    allowed = set(linear) | {layout.n_features - 1}
    for c in range(layout.n_features):
        if c not in allowed and np.any(raw[c] != 0):
            kept = ", ".join(model.input_names_[:n_linear])
            raise FtcalError(
                f"{target} holds only an affine map of the inputs {kept}; this model's term "
                f"{names[c]!r} has nonzero coefficients (largest |value| {np.max(np.abs(raw[c])):.3g}). "
                + advice)
    return raw[linear].T.copy(), raw[-1].copy()
