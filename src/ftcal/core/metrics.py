"""Calibration metrics: plain functions of (y_true, y_pred), arrays of shape (n_samples, n_outputs).

Definitions follow the paper: BestFit = 1 − sqrt(MSE / mean((y − ȳ)²)) per axis,
and the "force-norm RMSE" (the paper's "RMSE of force norm") is the RMSE of
‖f‖ − ‖f̂‖ (a scalar per sample), which ignores direction errors; the "RMSE of the
force error norm" (``*_error_norm_rmse``, sqrt(mean ‖f − f̂‖²)) counts them too.
Every metric is printed under the name and unit of :data:`METRIC_NAMES` and
:func:`metric_unit`, defined once for users in docs/metrics.md.

There is one evaluation path: :class:`ErrorSums` holds additive, centred sums of
consecutive rows from which every metric of :func:`summarize` follows. A streamed
file (:mod:`ftcal.data.streaming`) adds them chunk by chunk; :func:`summarize`, the
in-memory evaluation, is the same sums over one chunk, the whole array.
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from .metrics_text import norm_rmse_text  # noqa: F401  (its home: numpy-free, for ftcal info)

POSE_CELL_CAP = 100_000  # beyond this many distinct poses no polynomial ftcal fits is near saturation

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
    """All metrics as a JSON-ready dict (the keys of ``ftcal evaluate --json``): :class:`ErrorSums` of one chunk.

    Parameters
    ----------
    y_true, y_pred : ndarray of shape (n_samples, n_outputs), n_samples >= 1
    output_names : sequence of str

    Returns
    -------
    dict
        :data:`EVALUATION_KEYS` except ``n_out_of_range`` (the model adds it).

    Examples
    --------
    >>> import numpy as np
    >>> summarize(np.array([[0.0], [0.0]]), np.array([[3.0], [-3.0]]), ["a"])["rmse"]
    [3.0]
    """
    return ErrorSums.of(y_true, y_pred, output_names).to_dict(output_names)


@dataclass
class ErrorSums:
    """Additive sums of consecutive rows from which every metric of :func:`summarize` follows.

    ``a + b`` (``b``'s rows after ``a``'s) gives the sums of the concatenation, so
    chunks and files add up in any tree that keeps their order. The first and second
    moments of the outputs and of the residual r = y − ŷ, and the residual's lag-1
    product, are kept *centred*: about a centre c near the mean, with the remainder
    Σ(x − c) carried along. A merge moves both parts to a common centre with exact
    identities (Chan, Golub & LeVeque's pairwise update, written for any centre), so
    no step subtracts two large raw sums: a residual whose mean is large next to its
    spread keeps as many digits as the direct computation on the whole array.
    Shapes: (n_outputs,) per output; the norm sums are (2,), forces then torques.

    Attributes
    ----------
    n : int
        Rows.
    y_centre, y_dev_sum, y_dev_sq : ndarray
        Centre c of the outputs, Σ (y − c) and Σ (y − c)².
    r_centre, r_dev_sum, r_dev_sq, r_dev_lag : ndarray
        Centre c of the residual, Σ (r − c), Σ (r − c)² and Σ_t (r_t − c)(r_(t+1) − c).
    r_first, r_last : ndarray
        The first and last residual row (to join the lag-1 product across blocks).
    sse : ndarray
        Σ r² (a sum of squares: no cancellation).
    max_abs : ndarray
        max |r|.
    norm_sq : ndarray of shape (2,)
        Σ (‖v‖ − ‖v̂‖)² for the force and torque triples, NaN where the outputs have none.
    error_norm_sq : ndarray of shape (2,)
        Σ ‖v − v̂‖², NaN alike.
    n_out_of_range : int or None
        Rows with inputs outside the training range, when counted (a streamed evaluation counts them;
        :func:`summarize` does not, and its callers add the model's count).
    training_segments : frozenset
        Indices of the model's training fingerprints found in the rows (a streamed evaluation).
    pose_cells : frozenset
        Occupied cells of the pose grid, when counted, at most :data:`POSE_CELL_CAP` (``fit``'s
        saturation warning).
    ranges : RangeSums or None
        Which inputs left the training range, how far, and the error there.

    Examples
    --------
    >>> import numpy as np
    >>> y, p = np.array([[1.0], [2.0], [4.0]]), np.zeros((3, 1))
    >>> split = (ErrorSums.of(y[:1], p[:1], ["a"]) + ErrorSums.of(y[1:], p[1:], ["a"])).to_dict(["a"])
    >>> split["max_abs_error"], round(split["rmse"][0] ** 2 * 3, 9)  # Σ r² = 1 + 4 + 16
    ([4.0], 21.0)

    By hand, r − r̄ = (−4, −1, 5)/3, so acf(1) = ((4 − 5)/9) / (42/9) = −1/42:

    >>> round(split["residual_autocorrelation_lag1"][0] * 42, 9)
    -1.0
    """

    n: int
    y_centre: np.ndarray
    y_dev_sum: np.ndarray
    y_dev_sq: np.ndarray
    r_centre: np.ndarray
    r_dev_sum: np.ndarray
    r_dev_sq: np.ndarray
    r_dev_lag: np.ndarray
    r_first: np.ndarray
    r_last: np.ndarray
    sse: np.ndarray
    max_abs: np.ndarray
    norm_sq: np.ndarray
    error_norm_sq: np.ndarray
    n_out_of_range: int | None = None
    training_segments: frozenset = frozenset()
    pose_cells: frozenset = frozenset()
    ranges: object = None  # a RangeSums or None (ftcal.core.ranges imports this module, not the other way)

    @classmethod
    def of(cls, y: np.ndarray, prediction: np.ndarray, output_names: Sequence[str],
           n_out_of_range: int | None = None, ranges=None) -> "ErrorSums":
        """Sums of one block of rows, centred at the block's means.

        Parameters
        ----------
        y, prediction : ndarray of shape (m, n_outputs), m >= 1
        output_names : sequence of str
            To find the force and torque triples (:func:`force_torque_columns`).
        n_out_of_range : rows of the block with inputs outside the training range, if counted
        ranges : the block's :class:`~ftcal.core.ranges.RangeSums`, optional

        Returns
        -------
        ErrorSums
        """
        y, prediction = np.asarray(y, dtype=float), np.asarray(prediction, dtype=float)
        if y.ndim != 2 or y.shape != prediction.shape or len(y) == 0:
            raise ValueError(f"ErrorSums needs y and prediction of one shape (m >= 1, n_outputs); "
                             f"got {y.shape} and {prediction.shape}.")
        r = y - prediction
        norm_sq, error_norm_sq = np.full(2, np.nan), np.full(2, np.nan)
        for k, columns in enumerate(force_torque_columns(output_names)):
            if columns is not None:
                norms = np.linalg.norm(y[:, columns], axis=1) - np.linalg.norm(prediction[:, columns], axis=1)
                norm_sq[k] = norms @ norms
                error_norm_sq[k] = np.sum(r[:, columns] ** 2)
        y_centre, r_centre = y.mean(axis=0), r.mean(axis=0)
        y_dev, r_dev = y - y_centre, r - r_centre
        return cls(len(y), y_centre, y_dev.sum(axis=0), np.einsum("ij,ij->j", y_dev, y_dev),
                   r_centre, r_dev.sum(axis=0), np.einsum("ij,ij->j", r_dev, r_dev),
                   np.einsum("ij,ij->j", r_dev[1:], r_dev[:-1]), r[0].copy(), r[-1].copy(),
                   np.einsum("ij,ij->j", r, r), np.abs(r).max(axis=0), norm_sq, error_norm_sq,
                   n_out_of_range, ranges=ranges)

    def __add__(self, other: "ErrorSums") -> "ErrorSums":
        n = self.n + other.n
        y_centre = _common_centre(self.n, self.y_centre, self.y_dev_sum, other.n, other.y_centre, other.y_dev_sum)
        r_centre = _common_centre(self.n, self.r_centre, self.r_dev_sum, other.n, other.r_centre, other.r_dev_sum)
        y_a, y_b = (_recentred(s.n, s.y_centre, s.y_dev_sum, s.y_dev_sq, y_centre) for s in (self, other))
        r_a, r_b = (_recentred(s.n, s.r_centre, s.r_dev_sum, s.r_dev_sq, r_centre) for s in (self, other))
        # the one lag pair across the join: a's last row, b's first row
        join = (self.r_last - r_centre) * (other.r_first - r_centre)
        counted = (None if self.n_out_of_range is None and other.n_out_of_range is None
                   else (self.n_out_of_range or 0) + (other.n_out_of_range or 0))
        return ErrorSums(n=n, y_centre=y_centre, y_dev_sum=y_a[0] + y_b[0], y_dev_sq=y_a[1] + y_b[1],
                         r_centre=r_centre, r_dev_sum=r_a[0] + r_b[0], r_dev_sq=r_a[1] + r_b[1],
                         r_dev_lag=self._lag_about(r_centre) + other._lag_about(r_centre) + join,
                         r_first=self.r_first, r_last=other.r_last, sse=self.sse + other.sse,
                         max_abs=np.maximum(self.max_abs, other.max_abs), norm_sq=self.norm_sq + other.norm_sq,
                         error_norm_sq=self.error_norm_sq + other.error_norm_sq, n_out_of_range=counted,
                         training_segments=self.training_segments | other.training_segments,
                         pose_cells=capped_union(self.pose_cells, other.pose_cells),
                         ranges=None if self.ranges is None or other.ranges is None else self.ranges + other.ranges)

    def _lag_about(self, centre: np.ndarray) -> np.ndarray:
        """Σ_t (r_t − centre)(r_(t+1) − centre) over this block's n − 1 pairs (exact identity, any centre).

        With d = centre − c: Σ_(t<n) (r_t − c) = S − (r_last − c) and Σ_(t>1) (r_t − c) = S − (r_first − c),
        where S = Σ (r − c); the pairs' sum is then L − d (2S − (r_first − c) − (r_last − c)) + (n − 1) d².
        """
        shift = centre - self.r_centre
        ends = (self.r_first - self.r_centre) + (self.r_last - self.r_centre)
        return self.r_dev_lag - shift * (2 * self.r_dev_sum - ends) + (self.n - 1) * shift * shift

    def to_dict(self, output_names: Sequence[str]) -> dict:
        """The metrics of :func:`summarize` (a JSON-ready dict; NaN metrics become None or NaN as there),
        and ``n_out_of_range`` when the sums counted it.

        Parameters
        ----------
        output_names : sequence of str

        Returns
        -------
        dict
        """
        n = self.n
        with np.errstate(all="ignore"):  # undefined metrics become NaN (None in JSON) or are refused
            y_m2 = _recentred(n, self.y_centre, self.y_dev_sum, self.y_dev_sq, self.y_centre + self.y_dev_sum / n)[1]
            r_mean = self.r_centre + self.r_dev_sum / n
            r_m2 = _recentred(n, self.r_centre, self.r_dev_sum, self.r_dev_sq, r_mean)[1]
            lag = self._lag_about(r_mean)
            best = np.where(y_m2 > 0, 1.0 - np.sqrt(self.sse / y_m2), np.nan)
            acf = np.where(r_m2 > 0, lag / r_m2, 0.0) if n > 1 else np.zeros_like(r_m2)

        def root_mean(value: float):
            return None if np.isnan(value) else float(np.sqrt(value / n))

        # Near 1: the residual is slow, unmodelled dynamics or drift (try ARX, --na/--nb).
        return {"n_samples": int(n), "outputs": list(output_names), "rmse": np.sqrt(self.sse / n).tolist(),
                "best_fit": _json_list(best), "max_abs_error": self.max_abs.tolist(),
                "residual_autocorrelation_lag1": acf.tolist(),
                "force_norm_rmse": root_mean(self.norm_sq[0]), "torque_norm_rmse": root_mean(self.norm_sq[1]),
                "force_error_norm_rmse": root_mean(self.error_norm_sq[0]),
                "torque_error_norm_rmse": root_mean(self.error_norm_sq[1]),
                **({} if self.n_out_of_range is None else {"n_out_of_range": int(self.n_out_of_range)})}


    def summary(self, output_names: Sequence[str]) -> dict:
        """Deprecated: :meth:`to_dict` (``summary()`` renders text across ftcal; the numbers are ``to_dict``)."""
        _renamed("ErrorSums.summary", "ErrorSums.to_dict")
        return self.to_dict(output_names)


def _renamed(old: str, new: str) -> None:
    """The DeprecationWarning of a renamed method (as :func:`ftcal.runtime.deprecation.deprecated_alias` words it)."""
    import warnings

    from ..runtime.deprecation import REMOVED_IN

    warnings.warn(f"{old} is deprecated and will be removed in ftcal {REMOVED_IN}; use {new}.", DeprecationWarning,
                  stacklevel=3)


def capped_union(a: frozenset, b: frozenset) -> frozenset:
    """Pose cells of two blocks, stopped growing at :data:`POSE_CELL_CAP`."""
    return a | b if len(a) < POSE_CELL_CAP else a


def _common_centre(n_a: int, centre_a: np.ndarray, dev_sum_a: np.ndarray, n_b: int, centre_b: np.ndarray,
                   dev_sum_b: np.ndarray) -> np.ndarray:
    """The mean of two blocks' rows, a's centre plus a small correction (no large raw sums)."""
    return centre_a + (n_b * (centre_b - centre_a) + dev_sum_a + dev_sum_b) / (n_a + n_b)


def _recentred(n: int, centre: np.ndarray, dev_sum: np.ndarray, dev_sq: np.ndarray,
               new_centre: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(Σ (x − new), Σ (x − new)²) from the sums about ``centre``: S − n d and Q − 2 d S + n d², d = new − centre.

    Near the mean d and S are small, so neither subtracts large numbers (Chan's update when S = 0).
    """
    shift = new_centre - centre
    return dev_sum - n * shift, dev_sq - 2 * shift * dev_sum + n * shift * shift


def _json_list(values: np.ndarray) -> list:
    """Floats for JSON, with None where a value is undefined (NaN)."""
    return [float(v) if np.isfinite(v) else None for v in values]


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
