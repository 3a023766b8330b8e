"""The calibration model: a monomial basis (optionally ARX), an input normalization and coefficients.

The model evaluates in the normalized basis it was fitted in (inputs mapped by
``(u − offset) / scale``), which keeps high degrees well conditioned; converting
to raw-input monomials (the paper's XML) is done only on export, by
:mod:`ftcal.conversion`, which measures what that loses.
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence

import numpy as np

from . import metrics
from ._threads import map_ranges, single_threaded_blas
from ._checks import check_choice, check_finite_matrix, check_int
from .dataset import Dataset
from .errors import FtcalError, IllPosedFitWarning, NotFittedError, OutOfRangeWarning
from .features import FeatureCombination, MonomialBasis, RegressorLayout
from .normalization import MODES, Normalization, normalization_from_range
from .progress import progress_bar
from .solvers.base import ScaledProblem
from .solvers.least_squares import LeastSquares
from .statistics import SufficientStatistics, layout_statistics, sum_statistics

PREDICT_CHUNK = 4096
PREDICTION_MODES = ("free-run", "one-step")
# The OSQP comparison path builds the dense regressor; refuse beyond this many cells.
DENSE_LIMIT_CELLS = 200_000_000
CONDITION_WARNING = 1e7
RANGE_TOLERANCE = 1e-9


class CalibrationModel:
    """Polynomial (optionally ARX) map from raw sensor inputs to the wrench.

    Parameters
    ----------
    degree : int in [1, 10]
        Polynomial degree np.
    solver : solver object, default :class:`~ftcal.solvers.least_squares.LeastSquares`
        Anything with ``fit(ScaledProblem) -> SolverResult`` (least squares,
        ridge, LASSO) or ``fit_dense(A, B) -> SolverResult`` (the OSQP QPs).
    na, nb : int
        ARX orders: past outputs y(k−1..k−na) and input lags 0..nb.
    normalization : {"center", "maxabs"}
        How inputs are normalized before building monomials.

    Fitted attributes
    -----------------
    layout_ : RegressorLayout
    coef_ : ndarray of shape (n_features, n_outputs), for normalized features
    input_normalization_, output_normalization_ : Normalization
    input_names_, output_names_ : tuple of str
    input_range_, output_range_ : ndarray of shape (n, 2), training min and max
    n_samples_fit_ : int, regressor rows used by the fit
    rank_, condition_number_ : of the scaled regressor
    solver_info_ : dict
    training_metrics_ : dict (see :func:`ftcal.metrics.summarize`)
    """

    def __init__(self, degree: int = 1, *, solver=None, na: int = 0, nb: int = 0,
                 normalization: str = "center"):
        self.degree = degree
        self.solver = solver
        self.na = na
        self.nb = nb
        self.normalization = normalization

    # ------------------------------------------------------------------ fit
    def fit(self, data: Dataset, outputs: np.ndarray | None = None) -> "CalibrationModel":
        """Fit on a :class:`Dataset` (or an inputs array plus ``outputs``)."""
        data = _as_dataset(data, outputs)
        if data.outputs is None:
            raise FtcalError("Fitting needs reference outputs (the expected wrench); the data has none.")
        degree = check_int(self.degree, "degree", "CalibrationModel", 1, 10)
        na = check_int(self.na, "na", "CalibrationModel", 0, 50)
        nb = check_int(self.nb, "nb", "CalibrationModel", 0, 50)
        mode = check_choice(self.normalization, "normalization", "CalibrationModel", MODES)
        solver = self.solver if self.solver is not None else LeastSquares()

        u, y = data.inputs, data.outputs
        layout = RegressorLayout(MonomialBasis(u.shape[1], degree), y.shape[1], na, nb)
        in_norm = normalization_from_range(u.min(axis=0), u.max(axis=0), mode)
        out_norm = normalization_from_range(y.min(axis=0), y.max(axis=0), "center")
        n_rows = sum(max(b - a - layout.max_lag, 0) for a, b in data.segment_bounds())
        self._warn_if_ill_posed(data, layout, n_rows)
        if n_rows == 0:
            raise FtcalError(f"No regressor rows: every segment is shorter than the ARX lag "
                             f"max(na, nb) = {layout.max_lag}.")

        if hasattr(solver, "fit_dense"):
            a, targets = self._dense_regressor(data, layout, in_norm, out_norm)
            column_scale = np.abs(a).max(axis=0)
            column_scale[column_scale == 0] = 1.0
            result = solver.fit_dense(a / column_scale, targets)
        else:
            stats = self.statistics(data, layout, in_norm, out_norm)
            problem = ScaledProblem.from_statistics(stats)
            result = solver.fit(problem)
            column_scale = problem.column_scale

        self.layout_ = layout
        # C order, as loaded files have: BLAS sums in a layout-dependent order.
        self.coef_ = np.ascontiguousarray(result.coef / column_scale[:, None])
        self.input_normalization_ = in_norm
        self.output_normalization_ = out_norm
        self.input_names_ = tuple(data.input_names)
        self.output_names_ = tuple(data.output_names)
        self.input_range_ = np.c_[u.min(axis=0), u.max(axis=0)]
        self.output_range_ = np.c_[y.min(axis=0), y.max(axis=0)]
        self.n_samples_fit_ = int(n_rows)
        self.rank_ = int(result.rank)
        self.condition_number_ = float(result.condition_number)
        self.solver_info_ = {"name": solver.name, "lambda": float(getattr(solver, "lam", 0.0)) or None,
                             **{k: v for k, v in result.info.items() if k != "lambda"}}
        self._warn_if_rank_deficient(layout)
        self.training_metrics_ = self.score(data, warn_out_of_range=False)
        return self

    @staticmethod
    def statistics(data: Dataset, layout: RegressorLayout, in_norm: Normalization,
                   out_norm: Normalization) -> SufficientStatistics:
        """Sufficient statistics of ``data`` for ``layout``, segment by segment."""
        u_norm = in_norm.apply(data.inputs)
        y = data.outputs
        if layout.is_static:
            # Segments do not matter without lags: one pass over everything.
            with progress_bar("accumulating statistics", data.n_samples) as advance:
                return layout_statistics(layout, u_norm, y, None, advance=advance)
        y_norm = out_norm.apply(y)
        parts = []
        with progress_bar("accumulating statistics", data.n_samples) as advance:
            for a, b in data.segment_bounds():
                parts.append(layout_statistics(layout, u_norm[a:b], y[a:b], y_norm[a:b], advance=advance))
        return sum_statistics(parts)

    def _dense_regressor(self, data, layout, in_norm, out_norm):
        n_rows = sum(max(b - a - layout.max_lag, 0) for a, b in data.segment_bounds())
        if n_rows * layout.n_features > DENSE_LIMIT_CELLS:
            raise FtcalError(
                f"The OSQP solver needs the dense {n_rows} × {layout.n_features} regressor "
                f"({n_rows * layout.n_features * 8 / 1e9:.1f} GB); use --solver lstsq, which never builds it.")
        u_norm = in_norm.apply(data.inputs)
        y_norm = out_norm.apply(data.outputs)
        blocks, targets = [], []
        for a, b in data.segment_bounds():
            blocks.append(layout.evaluate_segment(u_norm[a:b], y_norm[a:b]))
            targets.append(data.outputs[a + layout.max_lag:b])
        return np.concatenate(blocks), np.concatenate(targets)

    def _warn_if_ill_posed(self, data: Dataset, layout: RegressorLayout, n_rows: int) -> None:
        p = layout.n_features
        if n_rows < p:
            warnings.warn(
                f"The fit is under-determined: {n_rows} samples for {p} coefficients per output. "
                "Lower the degree, add recordings, or use --lasso/--ridge.",
                IllPosedFitWarning, stacklevel=3)
        span = data.inputs.max(axis=0) - data.inputs.min(axis=0)
        for name, width in zip(data.input_names, span):
            if width == 0:
                warnings.warn(
                    f"Input {name!r} is constant in the training data, so its terms duplicate the "
                    "offset; drop it with --inputs or record data where it varies.",
                    IllPosedFitWarning, stacklevel=3)

    def _warn_if_rank_deficient(self, layout: RegressorLayout) -> None:
        if self.solver_info_.get("lambda"):
            return  # ridge and LASSO penalties make collinear problems well posed
        p = layout.n_features
        if self.rank_ < p:
            warnings.warn(
                f"The regressor has rank {self.rank_} < {p} columns (collinear or constant inputs, "
                "or too high a degree for this data); the minimum-norm solution was used. "
                "Lower the degree, add varied data, or use --ridge/--lasso.",
                IllPosedFitWarning, stacklevel=3)
        elif self.condition_number_ > CONDITION_WARNING:
            warnings.warn(
                f"The regressor is ill-conditioned (condition number {self.condition_number_:.2g}); "
                "coefficients are poorly determined. Lower the degree or use --ridge/--lasso.",
                IllPosedFitWarning, stacklevel=3)

    # -------------------------------------------------------------- predict
    def _check_fitted(self) -> None:
        if not hasattr(self, "coef_"):
            raise NotFittedError("This CalibrationModel is not fitted yet; call fit() or load a model file.")

    @property
    def n_coefficients(self) -> int:
        self._check_fitted()
        return int(self.coef_.size)

    def out_of_range(self, inputs: np.ndarray) -> np.ndarray:
        """Boolean mask of samples with any input outside the training range."""
        self._check_fitted()
        low, high = self.input_range_[:, 0], self.input_range_[:, 1]
        slack = RANGE_TOLERANCE * np.maximum(high - low, 1.0)
        return np.any((inputs < low - slack) | (inputs > high + slack), axis=1)

    def predict(self, data: Dataset | np.ndarray, *, mode: str = "free-run",
                warn_out_of_range: bool = True) -> np.ndarray:
        """Predicted outputs, shape (n_samples, n_outputs).

        ``mode`` matters only for ARX models: ``"free-run"`` feeds back past
        predictions (deployment on the robot), ``"one-step"`` uses the measured
        past outputs in ``data`` (one-step-ahead). The first max(na, nb) samples
        of each segment see their first sample repeated as history.
        """
        self._check_fitted()
        check_choice(mode, "mode", "CalibrationModel.predict", PREDICTION_MODES)
        data = _as_dataset(data, None, self.input_names_)
        u = check_finite_matrix(data.select_inputs(self.input_names_), "inputs",
                                len(self.input_names_), self.input_names_)
        if warn_out_of_range:
            n_out = int(self.out_of_range(u).sum())
            if n_out:
                warnings.warn(
                    f"{n_out} of {len(u)} samples have inputs outside the training range; "
                    "predictions there are extrapolations.", OutOfRangeWarning, stacklevel=2)
        if self.layout_.is_static:
            return self._predict_static(u)
        u_norm = self.input_normalization_.apply(u)
        if mode == "one-step" and data.outputs is None:
            raise FtcalError("One-step-ahead prediction needs the measured outputs in the data.")
        measured = None if data.outputs is None else _outputs_in_order(data, self.output_names_)
        # One BLAS thread: results must not depend on thread scheduling (bit-identical reruns).
        with single_threaded_blas():
            return np.concatenate([self._predict_arx_segment(u_norm[a:b], None if measured is None else measured[a:b],
                                                             mode)
                                   for a, b in data.segment_bounds()])

    def _predict_static(self, u: np.ndarray) -> np.ndarray:
        basis = self.layout_.basis
        coef_t = np.ascontiguousarray(self.coef_.T)
        out = np.empty((u.shape[0], coef_t.shape[0]))
        offset = self.input_normalization_.offset[:, None]
        inv_scale = (1.0 / self.input_normalization_.scale)[:, None]

        def work(begin: int, end: int) -> None:
            combine = FeatureCombination(basis, coef_t, PREDICT_CHUNK)
            for start in range(begin, end, PREDICT_CHUNK):
                stop = min(start + PREDICT_CHUNK, end)
                # Normalize per chunk, in cache, instead of a full pass over u.
                # A contiguous copy (never a view: it is modified in place) with contiguous rows.
                u_t = np.array(u[start:stop].T, order="C")
                u_t -= offset
                u_t *= inv_scale
                out[start:stop] = combine(u_t).T

        map_ranges(work, u.shape[0], PREDICT_CHUNK)
        return out

    def _predict_arx_segment(self, u_norm: np.ndarray, y_measured: np.ndarray | None, mode: str) -> np.ndarray:
        layout, lag = self.layout_, self.layout_.max_lag
        ny = len(self.output_names_)
        padded_u = np.concatenate([np.repeat(u_norm[:1], lag, axis=0), u_norm])
        if mode == "one-step":
            y_norm = self.output_normalization_.apply(y_measured)
            padded_y = np.concatenate([np.repeat(y_norm[:1], lag, axis=0), y_norm])
            return self._arx_product(padded_u, padded_y)
        # Free run: the input part once for all samples, then the output recursion.
        exogenous = self._arx_product(padded_u, np.zeros((padded_u.shape[0], ny)))
        feedback = [self.coef_[(j - 1) * ny:j * ny] for j in range(1, layout.na + 1)]
        scale = self.output_normalization_.scale
        offset = self.output_normalization_.offset
        if y_measured is not None:
            history = [self.output_normalization_.apply(y_measured[0])] * layout.na
        else:
            history = [self.output_normalization_.apply(self._steady_state(exogenous[0], feedback))] * layout.na
        result = np.empty_like(exogenous)
        for k in range(exogenous.shape[0]):
            value = exogenous[k].copy()
            for j, block in enumerate(feedback):
                value += history[-1 - j] @ block
            result[k] = value
            history.append((value - offset) / scale)
            history.pop(0)
        return result

    def _arx_product(self, padded_u: np.ndarray, padded_y: np.ndarray) -> np.ndarray:
        """Regressor rows times coefficients, ``PREDICT_CHUNK`` rows at a time (never the whole N × p)."""
        lag = self.layout_.max_lag
        n = padded_u.shape[0] - lag
        out = np.empty((n, self.coef_.shape[1]))
        for start in range(0, n, PREDICT_CHUNK):
            stop = min(start + PREDICT_CHUNK, n)
            rows = self.layout_.evaluate_segment(padded_u[start:stop + lag], padded_y[start:stop + lag])
            out[start:stop] = rows @ self.coef_
        return out

    def _steady_state(self, exogenous: np.ndarray, feedback: list[np.ndarray]) -> np.ndarray:
        """Output y with y = g + Σ_j ((y − o)/s) S_j, i.e. the fixed point for constant input."""
        ny = exogenous.size
        inv_scale = np.diag(1.0 / self.output_normalization_.scale)
        s_total = sum(feedback) if feedback else np.zeros((ny, ny))
        system = np.eye(ny) - (inv_scale @ s_total).T
        rhs = exogenous - (self.output_normalization_.offset / self.output_normalization_.scale) @ s_total
        try:
            return np.linalg.solve(system, rhs)
        except np.linalg.LinAlgError:
            return exogenous

    def score(self, data: Dataset, *, mode: str = "free-run", warn_out_of_range: bool = True) -> dict:
        """Metrics of :func:`ftcal.metrics.summarize` plus ``n_out_of_range``."""
        self._check_fitted()
        if data.outputs is None:
            raise FtcalError("Evaluating needs reference outputs in the data.")
        y = _outputs_in_order(data, self.output_names_)
        prediction = self.predict(data, mode=mode, warn_out_of_range=warn_out_of_range)
        summary = metrics.summarize(y, prediction, self.output_names_)
        summary["n_out_of_range"] = int(self.out_of_range(data.select_inputs(self.input_names_)).sum())
        if not self.layout_.is_static and mode == "free-run":
            one_step = self.predict(data, mode="one-step", warn_out_of_range=False)
            summary["one_step"] = metrics.summarize(y, one_step, self.output_names_)
        return summary

    def describe(self) -> dict:
        """Counts for reports: model class, coefficients, nonzeros."""
        self._check_fitted()
        return {
            "degree": self.layout_.basis.degree, "na": self.layout_.na, "nb": self.layout_.nb,
            "n_inputs": len(self.input_names_), "n_outputs": len(self.output_names_),
            "n_coefficients": int(self.coef_.size),
            "n_nonzero": int(np.count_nonzero(self.coef_)),
        }


def _as_dataset(data, outputs=None, input_names: Sequence[str] | None = None) -> Dataset:
    if isinstance(data, Dataset):
        return data
    u = np.asarray(data, dtype=np.float64)
    if u.ndim == 1:
        u = u[:, None]
    names = tuple(input_names) if input_names is not None and len(input_names) == u.shape[1] else None
    return Dataset.from_arrays(u, outputs, input_names=names)


def _outputs_in_order(data: Dataset, names: Sequence[str]) -> np.ndarray:
    index = {n: i for i, n in enumerate(data.output_names)}
    missing = [n for n in names if n not in index]
    if missing:
        raise FtcalError(f"The data has no output column(s) {', '.join(map(repr, missing))} "
                         "that the model predicts.")
    return data.outputs[:, [index[n] for n in names]]


def model_from_fitted(*, degree: int, na: int, nb: int, normalization: str, coef: np.ndarray,
                      input_normalization: Normalization, output_normalization: Normalization,
                      input_names: Sequence[str], output_names: Sequence[str],
                      input_range: np.ndarray, output_range: np.ndarray, n_samples_fit: int = 0,
                      rank: int | None = None, condition_number: float = float("nan"),
                      solver_info: dict | None = None, training_metrics: dict | None = None,
                      solver=None) -> CalibrationModel:
    """Rebuild a fitted model from stored parts (model files use this)."""
    model = CalibrationModel(degree, solver=solver, na=na, nb=nb, normalization=normalization)
    layout = RegressorLayout(MonomialBasis(len(input_names), degree), len(output_names), na, nb)
    coef = np.asarray(coef, dtype=np.float64)
    if coef.shape != (layout.n_features, len(output_names)):
        raise FtcalError(f"Coefficient table has shape {coef.shape}; degree {degree}, na={na}, nb={nb} "
                         f"with {len(input_names)} inputs and {len(output_names)} outputs needs "
                         f"{(layout.n_features, len(output_names))}.")
    model.layout_ = layout
    model.coef_ = np.ascontiguousarray(coef)
    model.input_normalization_ = input_normalization
    model.output_normalization_ = output_normalization
    model.input_names_ = tuple(input_names)
    model.output_names_ = tuple(output_names)
    model.input_range_ = np.asarray(input_range, dtype=np.float64)
    model.output_range_ = np.asarray(output_range, dtype=np.float64)
    model.n_samples_fit_ = int(n_samples_fit)
    model.rank_ = int(rank if rank is not None else layout.n_features)
    model.condition_number_ = float(condition_number)
    model.solver_info_ = dict(solver_info or {})
    model.training_metrics_ = dict(training_metrics or {})
    return model
