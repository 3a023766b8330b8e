"""Calibration metrics: plain functions of (y_true, y_pred), arrays of shape (n_samples, n_outputs).

Definitions follow the paper: BestFit = 1 − sqrt(MSE / mean((y − ȳ)²)) per axis,
and the "force-norm RMSE" (the paper's "RMSE of force norm") is the RMSE of
‖f‖ − ‖f̂‖ (a scalar per sample), which ignores direction errors; the "RMSE of the
force error norm" (``*_error_norm_rmse``, sqrt(mean ‖f − f̂‖²)) counts them too.
Every metric is printed under the name and unit of :data:`METRIC_NAMES` and
:func:`metric_unit`, defined once for users in docs/metrics.md.
"""

from __future__ import annotations

import re
from collections.abc import Sequence

import numpy as np

FORCE_UNIT, TORQUE_UNIT = "N", "N·m"

# The one name of each metric (keys of `ftcal evaluate --json`), as the CLI, the report and docs/metrics.md print it.
METRIC_NAMES = {
    "rmse": "RMSE",
    "best_fit": "BestFit",
    "max_abs_error": "max |error|",
    "force_norm_rmse": "force-norm RMSE",
    "torque_norm_rmse": "torque-norm RMSE",
    "force_error_norm_rmse": "RMSE of the force error norm",
    "torque_error_norm_rmse": "RMSE of the torque error norm",
    "residual_autocorrelation_lag1": "resid. acf(1)",
}
# One line per metric for the foot of printed tables; docs/metrics.md has the full definitions.
METRIC_NOTES = (
    "force-norm RMSE = RMSE of ‖f‖ − ‖f̂‖ (the paper's; ignores direction errors); "
    "RMSE of the force error norm = sqrt(mean ‖f − f̂‖²) (counts them; torques alike)",
    "resid. acf(1) = lag-1 autocorrelation of the residual (near 0: white noise; near 1: slow drift or "
    "unmodelled dynamics, try --na/--nb or more temperature data); see docs/metrics.md",
)

_FORCE = re.compile(r"(^|[_\W])(F|f)_?[xyz]$")
_TORQUE = re.compile(r"(^|[_\W])(T|M|tau)_?[xyz]$")


def rmse(y_true: np.ndarray, y_pred: np.ndarray) -> np.ndarray:
    """Root mean square error per output.

    Parameters
    ----------
    y_true, y_pred : ndarray of shape (n_samples, n_outputs)

    Returns
    -------
    ndarray of shape (n_outputs,), in the outputs' units

    Examples
    --------
    >>> import numpy as np
    >>> rmse(np.array([[0.0], [0.0]]), np.array([[3.0], [-3.0]])).tolist()
    [3.0]
    """
    return np.sqrt(np.mean((y_true - y_pred) ** 2, axis=0))


def best_fit(y_true: np.ndarray, y_pred: np.ndarray) -> np.ndarray:
    """1 − sqrt(MSE / variance of y) per output; 1 is perfect, 0 is the mean predictor.

    Parameters
    ----------
    y_true, y_pred : ndarray of shape (n_samples, n_outputs)

    Returns
    -------
    ndarray of shape (n_outputs,), NaN where y_true is constant

    Examples
    --------
    >>> import numpy as np
    >>> y = np.array([[1.0], [-1.0]])
    >>> best_fit(y, np.zeros((2, 1))).tolist(), best_fit(y, y).tolist()
    ([0.0], [1.0])
    """
    mse = np.mean((y_true - y_pred) ** 2, axis=0)
    variance = np.var(y_true, axis=0)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(variance > 0, 1.0 - np.sqrt(mse / variance), np.nan)


def max_abs_error(y_true: np.ndarray, y_pred: np.ndarray) -> np.ndarray:
    """Largest absolute error per output.

    Parameters
    ----------
    y_true, y_pred : ndarray of shape (n_samples, n_outputs)

    Returns
    -------
    ndarray of shape (n_outputs,)
    """
    return np.max(np.abs(y_true - y_pred), axis=0)


def norm_rmse(true_vectors: np.ndarray, pred_vectors: np.ndarray) -> float:
    """RMSE of ‖v‖ − ‖v̂‖ over samples (the paper's "RMSE of force norm").

    Parameters
    ----------
    true_vectors, pred_vectors : ndarray of shape (n_samples, 3)

    Returns
    -------
    float

    Examples
    --------
    >>> import numpy as np
    >>> norm_rmse(np.array([[3.0, 4.0, 0.0]]), np.array([[0.0, 0.0, 5.0]]))  # same norm, other direction
    0.0
    """
    diff = np.linalg.norm(true_vectors, axis=1) - np.linalg.norm(pred_vectors, axis=1)
    return float(np.sqrt(np.mean(diff ** 2)))


def error_norm_rmse(true_vectors: np.ndarray, pred_vectors: np.ndarray) -> float:
    """RMSE of ‖v − v̂‖ over samples (direction errors included).

    Parameters
    ----------
    true_vectors, pred_vectors : ndarray of shape (n_samples, 3)

    Returns
    -------
    float

    Examples
    --------
    >>> import numpy as np
    >>> error_norm_rmse(np.array([[3.0, 4.0, 0.0]]), np.array([[0.0, 0.0, 0.0]]))
    5.0
    """
    return float(np.sqrt(np.mean(np.sum((true_vectors - pred_vectors) ** 2, axis=1))))


def residual_autocorrelation(y_true: np.ndarray, y_pred: np.ndarray, max_lag: int = 20) -> np.ndarray:
    """Normalized autocorrelation of residuals per output at lags 0..max_lag, shape (max_lag+1, n_outputs).

    Values well above 2/sqrt(N) at small lags mean unmodelled dynamics (try ARX).

    Parameters
    ----------
    y_true, y_pred : ndarray of shape (n_samples, n_outputs)
    max_lag : int

    Returns
    -------
    ndarray of shape (max_lag + 1, n_outputs); row 0 is 1 (0 for a zero residual)
    """
    r = y_true - y_pred
    r = r - r.mean(axis=0)
    denom = np.sum(r * r, axis=0)
    lags = min(max_lag, r.shape[0] - 1)
    acf = np.array([np.sum(r[k:] * r[:r.shape[0] - k], axis=0) for k in range(lags + 1)])
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(denom > 0, acf / denom, 0.0)


def force_torque_columns(output_names: Sequence[str]) -> tuple[list[int] | None, list[int] | None]:
    """Indices of the three force and three torque outputs, by name (``Fx``, ``r_arm_ft_Ty``...).

    Six outputs with other names are taken as (Fx, Fy, Fz, Tx, Ty, Tz) in order.

    Parameters
    ----------
    output_names : sequence of str

    Returns
    -------
    (forces, torques) : list of 3 int, or None when not found

    Examples
    --------
    >>> force_torque_columns(["Tx", "Ty", "Tz", "Fx", "Fy", "Fz"])
    ([3, 4, 5], [0, 1, 2])
    """
    forces = [i for i, n in enumerate(output_names) if _FORCE.search(n)]
    torques = [i for i, n in enumerate(output_names) if _TORQUE.search(n)]
    found_forces = forces if len(forces) == 3 else None
    found_torques = torques if len(torques) == 3 else None
    if len(output_names) == 6:
        # Unnamed halves of a six-axis wrench follow the (F, T) order, unless named otherwise.
        if found_forces is None and found_torques != [0, 1, 2]:
            found_forces = [0, 1, 2] if found_torques is None else [i for i in range(6) if i not in found_torques]
        if found_torques is None and found_forces is not None:
            found_torques = [i for i in range(6) if i not in found_forces]
    return found_forces, found_torques


def wrench_blocks(output_names: Sequence[str]) -> dict[str, list[int]]:
    """The force and torque triples among the outputs by block name, those not found left out.

    Examples
    --------
    >>> wrench_blocks(["Fx", "Fy", "Fz", "Tx", "Ty", "Tz"])
    {'force': [0, 1, 2], 'torque': [3, 4, 5]}
    """
    forces, torques = force_torque_columns(output_names)
    return {name: columns for name, columns in (("force", forces), ("torque", torques)) if columns}


def block_error_norm_rmse(mse: np.ndarray, columns: Sequence[int]) -> np.ndarray:
    """√Σ MSE over ``columns`` of the last axis: a block's error-norm RMSE from its outputs' mean squared errors.

    Examples
    --------
    >>> block_error_norm_rmse(np.array([[9.0, 16.0, 1.0]]), [0, 1]).tolist()
    [5.0]
    """
    return np.sqrt(np.asarray(mse)[..., list(columns)].sum(axis=-1))


def output_units(output_names: Sequence[str]) -> list[str]:
    """N for the force outputs, N·m for the torque outputs, "" for others (found by :func:`force_torque_columns`).

    Examples
    --------
    >>> output_units(["Fx", "Fy", "Fz", "Tx", "Ty", "Tz"])
    ['N', 'N', 'N', 'N·m', 'N·m', 'N·m']
    """
    units = [""] * len(output_names)
    for name, columns in wrench_blocks(output_names).items():
        for i in columns:
            units[i] = FORCE_UNIT if name == "force" else TORQUE_UNIT
    return units


def metric_unit(key: str) -> str:
    """The unit of a scalar metric of :data:`METRIC_NAMES` ("%" for BestFit, "" for a per-output unit or none).

    Examples
    --------
    >>> metric_unit("force_norm_rmse"), metric_unit("torque_error_norm_rmse"), metric_unit("best_fit")
    ('N', 'N·m', '%')
    """
    if key.startswith("force_"):
        return FORCE_UNIT
    if key.startswith("torque_"):
        return TORQUE_UNIT
    return "%" if key == "best_fit" else ""


def format_metric(key: str, value: float, digits: int = 5) -> str:
    """``"force-norm RMSE: 2.0921 N"``: a scalar metric with its one name and its unit."""
    unit = metric_unit(key)
    return f"{METRIC_NAMES[key]}: {value:.{digits}g}" + (f" {unit}" if unit else "")


# The keys of `ftcal evaluate --json` (and of the train/validation entries of the demo's summary.json).
EVALUATION_KEYS = ("rmse", "best_fit", "max_abs_error", "force_norm_rmse", "torque_norm_rmse",
                   "force_error_norm_rmse", "torque_error_norm_rmse", "residual_autocorrelation_lag1",
                   "n_samples", "n_out_of_range", "outputs")


def summarize(y_true: np.ndarray, y_pred: np.ndarray, output_names: Sequence[str]) -> dict:
    """All metrics as a JSON-ready dict (the keys of ``ftcal evaluate --json``).

    Parameters
    ----------
    y_true, y_pred : ndarray of shape (n_samples, n_outputs)
    output_names : sequence of str

    Returns
    -------
    dict
        :data:`EVALUATION_KEYS` except ``n_out_of_range`` (the model adds it).
    """
    summary: dict = {
        "n_samples": int(y_true.shape[0]),
        "outputs": list(output_names),
        "rmse": rmse(y_true, y_pred).tolist(),
        "best_fit": _json_list(best_fit(y_true, y_pred)),
        "max_abs_error": max_abs_error(y_true, y_pred).tolist(),
        # Near 1: the residual is slow, unmodelled dynamics or drift (try ARX, --na/--nb).
        "residual_autocorrelation_lag1": (residual_autocorrelation(y_true, y_pred, 1)[-1].tolist()
                                          if y_true.shape[0] > 1 else [0.0] * y_true.shape[1]),
        "force_norm_rmse": None, "torque_norm_rmse": None,
        "force_error_norm_rmse": None, "torque_error_norm_rmse": None,
    }
    for name, columns in wrench_blocks(output_names).items():
        summary[f"{name}_norm_rmse"] = norm_rmse(y_true[:, columns], y_pred[:, columns])
        summary[f"{name}_error_norm_rmse"] = error_norm_rmse(y_true[:, columns], y_pred[:, columns])
    return summary


def _json_list(values: np.ndarray) -> list:
    """Floats for JSON, with None where a value is undefined (NaN)."""
    return [float(v) if np.isfinite(v) else None for v in values]


def norm_rmse_text(metrics: dict, spec: str = ".4f", units: bool = True) -> str:
    """``force-norm RMSE … N, torque-norm RMSE … N·m`` from training metrics; either may be absent
    (force-only or torque-only outputs); '' when both are.

    Examples
    --------
    >>> norm_rmse_text({"force_norm_rmse": 1.5, "torque_norm_rmse": None})
    'force-norm RMSE 1.5000 N'
    """
    parts = [f"{what}-norm RMSE {metrics[key]:{spec}}" + (f" {unit}" if units else "")
             for what, key, unit in (("force", "force_norm_rmse", "N"), ("torque", "torque_norm_rmse", "N·m"))
             if metrics.get(key) is not None]
    return ", ".join(parts)


def statistics_training_error(gram: np.ndarray, cross: np.ndarray, target_sq: np.ndarray,
                              target_sum: np.ndarray, n_samples: int, coef: np.ndarray,
                              output_scale: np.ndarray, output_names: Sequence[str]) -> dict:
    """Training RMSE, BestFit and error-norm RMSEs of a linear-in-coefficients fit, from its summed statistics.

    With regressor A (n × p), targets B (n × ny) and coefficients Θ (p × ny), each output's sum of
    squared residuals is ``‖b − Aθ‖² = bᵀb − 2θᵀ(Aᵀb) + θᵀ(AᵀA)θ`` and its spread
    ``Σ(b − b̄)² = bᵀb − (Σb)²/n``: no second pass over the samples. The statistics may be in a
    normalized output basis ``b = (y − offset) / output_scale``; both sums scale by ``output_scale²``.
    What needs the samples themselves (max |error|, residual autocorrelation, the norm of each
    predicted force) is not here: those stay with a pass over the data (``ftcal evaluate``).

    Parameters
    ----------
    gram : ndarray of shape (p, p)      AᵀA
    cross : ndarray of shape (p, ny)    AᵀB
    target_sq, target_sum : ndarray of shape (ny,)   Σ b², Σ b per output
    n_samples : int                     rows of A
    coef : ndarray of shape (p, ny)     Θ, in the basis of the statistics
    output_scale : ndarray of shape (ny,)  y = offset + output_scale · b
    output_names : sequence of str      to find the force and torque triples

    Returns
    -------
    dict
        ``n_samples``, ``outputs``, ``rmse``, ``best_fit`` (None where an output is constant),
        ``force_error_norm_rmse``, ``torque_error_norm_rmse`` (None without that triple).

    Examples
    --------
    >>> import numpy as np
    >>> a = np.c_[np.arange(4.0), np.ones(4)]
    >>> y = np.array([[0.0], [1.0], [2.0], [4.0]])
    >>> theta = np.linalg.lstsq(a, y, rcond=None)[0]
    >>> out = statistics_training_error(a.T @ a, a.T @ y, (y ** 2).sum(0), y.sum(0), 4, theta,
    ...                                 np.ones(1), ["Fx"])
    >>> bool(np.isclose(out["rmse"][0], np.sqrt(np.mean((y - a @ theta) ** 2))))
    True
    """
    coef = np.asarray(coef, dtype=np.float64)
    scale_sq = np.asarray(output_scale, dtype=np.float64) ** 2
    # θᵀ(Gθ − 2c) + bᵀb per output; clipped at 0 (rounding can leave a tiny negative on an exact fit)
    sse = np.maximum(np.einsum("ij,ij->j", coef, gram @ coef - 2.0 * cross) + target_sq, 0.0) * scale_sq
    spread = np.maximum(target_sq - target_sum ** 2 / n_samples, 0.0) * scale_sq
    with np.errstate(divide="ignore", invalid="ignore"):
        fit = np.where(spread > 0, 1.0 - np.sqrt(sse / spread), np.nan)
    out: dict = {"n_samples": int(n_samples), "outputs": list(output_names),
                 "rmse": np.sqrt(sse / n_samples).tolist(), "best_fit": _json_list(fit),
                 "force_error_norm_rmse": None, "torque_error_norm_rmse": None}
    for name, columns in wrench_blocks(output_names).items():
        out[f"{name}_error_norm_rmse"] = float(np.sqrt(sse[columns].sum() / n_samples))
    return out
