"""The calibration model: a monomial basis (optionally ARX), an input normalization and coefficients.

The model evaluates in the normalized basis it stores (inputs mapped by
``(u − offset) / scale``); converting to raw-input monomials (the paper's XML)
is done only on export, by :mod:`ftcal.core.conversion`, which measures what that
loses.

Which basis a fit is solved in: least squares does not depend on the basis, so
it is always solved in the best-conditioned one (``center``) and its
coefficients mapped exactly into the stored basis. A penalty does depend on the
basis: ridge and LASSO are solved in the stored basis, by default the paper's
(raw monomials scaled by their max-abs, ``maxabs``).
"""

from __future__ import annotations

import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from ..runtime.checks import check_choice, check_finite_matrix, check_int
from ..runtime.errors import FtcalError, IllPosedFitWarning, NotFittedError, OutOfRangeWarning
from ..runtime.progress import progress_bar
from ..runtime.threads import map_ranges, single_threaded_blas
from . import metrics
from .dataset import Dataset
from .estimator import EstimatorParams
from .excitation import Spread, span_distance, span_limit
from .features import FeatureCombination, MonomialBasis, RegressorLayout, n_coefficients, substitution_matrix
from .kernels import compiled, step_table
from .limits import (ARX_WARMUP, FREE_RUN_STARTS, MAX_DEGREE, MAX_GRAM_BYTES, MAX_LAG, NORMALIZATIONS,
                     PREDICTION_MODES)
from .normalization import Normalization, normalization_from_range, variables_normalization, variables_range
from .ranges import RangeSums, describe, outside_by_channel
from .solvers.base import ScaledProblem, Solver, SolverResult
from .solvers.least_squares import LeastSquares
from .statistics import SufficientStatistics, layout_statistics, sum_statistics

PREDICT_CHUNK = 4096
# The OSQP comparison path builds the dense regressor; refuse beyond this many cells.
DENSE_LIMIT_CELLS = 200_000_000
CONDITION_WARNING = 1e7
# Least squares is solved in this basis whatever the stored one (it is the best conditioned).
SOLVE_BASIS = "center"


@dataclass(frozen=True)
class FitFrame:
    """What a fit takes from the data and the model's parameters, before any solver runs.

    Attributes
    ----------
    layout : RegressorLayout
    normalization : str
        The stored basis, one of :data:`ftcal.core.limits.NORMALIZATIONS`.
    input_normalization, output_normalization : Normalization
        The stored basis's normalizations.
    solve_input_normalization, solve_output_normalization : Normalization
        The basis the solver works in (differs from the stored one only for least squares).
    input_names, output_names : tuple of str
    input_range, output_range : ndarray of shape (n, 2)
        Training min and max per column.
    n_rows : int
        Regressor rows (samples minus ARX warm-up rows per segment).
    """

    layout: RegressorLayout
    normalization: str
    input_normalization: Normalization
    output_normalization: Normalization
    solve_input_normalization: Normalization
    solve_output_normalization: Normalization
    input_names: tuple[str, ...]
    output_names: tuple[str, ...]
    input_range: np.ndarray
    output_range: np.ndarray
    n_rows: int

    @property
    def solves_in_stored_basis(self) -> bool:
        return self.solve_input_normalization is self.input_normalization



def check_gram_size(layout: RegressorLayout) -> None:
    """Refuse, before anything is allocated, a fit whose Gram matrix exceeds :data:`MAX_GRAM_BYTES`.

    Raises
    ------
    FtcalError
        Naming the coefficient count, the memory the Gram matrix needs and what to lower.
    """
    p = layout.n_features
    need = 8 * p * p
    if need > MAX_GRAM_BYTES:
        arx = "" if layout.is_static else f", na={layout.na}, nb={layout.nb}"
        lower = "--degree" if layout.is_static else "--degree, --na or --nb"
        raise FtcalError(f"degree {layout.basis.degree}{arx} over {layout.basis.n_inputs} inputs has {p:,} "
                         f"coefficients per output ({p * layout.n_outputs:,} in all); its Gram matrix alone needs "
                         f"{need / 1e9:.1f} GB, above the limit of {MAX_GRAM_BYTES / 1e9:.0f} GB: lower {lower}.")

class CalibrationModel(EstimatorParams):
    """Polynomial (optionally ARX) map from raw sensor inputs to the wrench.

    Parameters
    ----------
    degree : int in [1, 10], default 1
        Polynomial degree np; the convenient way to choose a
        :class:`~ftcal.core.features.MonomialBasis` over the data's inputs.
    basis : MonomialBasis, optional
        The feature basis itself (its ``n_inputs`` must match the data);
        when given, ``degree`` must be left at its default or agree with it.
    solver : Solver, default :class:`~ftcal.core.solvers.least_squares.LeastSquares`
        Any object following the :class:`~ftcal.core.solvers.base.Solver` protocol.
    na, nb : int in [0, 50]
        ARX orders: past outputs y(k−1..k−na) and input lags 0..nb.
    normalization : {"center", "maxabs"}, optional
        The basis the coefficients are stored (and a penalty defined) in. By
        default the paper's ``"maxabs"`` for ridge and LASSO (so λ means what
        it means in the paper) and ``"center"`` for least squares.
    prior : CalibrationModel, optional
        A fitted model over the same inputs and outputs to shrink toward: the
        penalty is applied to θ − θ_prior instead of θ (needs a penalized solver).

    Attributes
    ----------
    layout_ : RegressorLayout
    coef_ : ndarray of shape (n_features, n_outputs), for normalized features
    normalization_ : str, the stored basis
    input_normalization_, output_normalization_ : Normalization
    input_names_, output_names_ : tuple of str
    input_range_, output_range_ : ndarray of shape (n, 2), training min and max
    input_spread_ : Spread or None, mean and covariance of the training inputs (None: files
        written before ftcal recorded it; then only the range is checked)
    n_samples_fit_ : int, regressor rows used by the fit
    rank_, condition_number_ : of the scaled regressor, in the basis solved in
    solver_info_ : dict, ``name`` and ``lambda`` (None when unpenalized) plus solver details
    training_metrics_ : dict (see :func:`ftcal.core.metrics.summarize`)

    Examples
    --------
    >>> import numpy as np
    >>> u = np.linspace(-1.0, 1.0, 21)[:, None]
    >>> model = CalibrationModel(2).fit(u, 3.0 * u ** 2 - 1.0)
    >>> np.round(model.predict(np.array([[0.5]])), 12).tolist()
    [[-0.25]]
    """

    # The model family protocol (ftcal.core.families.ModelFamily).
    family = "polynomial"
    exports = frozenset({"json", "paper-xml", "icub-firmware", "wbd", "c", "c-runtime", "onnx"})
    streams = True

    def __init__(self, degree: int = 1, *, basis: MonomialBasis | None = None, solver: Solver | None = None,
                 na: int = 0, nb: int = 0, normalization: str | None = None,
                 prior: "CalibrationModel | None" = None):
        self.degree = degree
        self.basis = basis
        self.solver = solver
        self.na = na
        self.nb = nb
        self.normalization = normalization
        self.prior = prior

    # ------------------------------------------------------------------ fit
    def fit(self, data: Dataset | np.ndarray, outputs: np.ndarray | None = None) -> "CalibrationModel":
        """Fit on a :class:`Dataset` (or an inputs array plus ``outputs``).

        Parameters
        ----------
        data : Dataset, or ndarray of shape (n_samples, n_inputs)
        outputs : ndarray of shape (n_samples, n_outputs), optional
            Reference outputs (N, N·m) when ``data`` is an array.

        Returns
        -------
        CalibrationModel
            ``self``, fitted.

        Raises
        ------
        FtcalError
            On invalid parameters, data without outputs, or no regressor rows.
        """
        data = _as_dataset(data, outputs)
        frame = self.frame(data)
        stats = self.statistics(data, frame.layout, frame.solve_input_normalization,
                                frame.solve_output_normalization)

        def dense():
            return self._dense_regressor(data, frame)

        self.fit_statistics(frame, stats, dense)
        self.input_spread_ = Spread.of(data.inputs)
        self.training_metrics_ = self.score(data, warn_out_of_range=False)
        return self

    def fit_statistics(self, frame: FitFrame, stats: SufficientStatistics,
                       dense: Callable[[], tuple[np.ndarray, np.ndarray]] | None = None) -> "CalibrationModel":
        """Solve from summed statistics (streamed or distributed fits): everything :meth:`fit` does but score.

        Parameters
        ----------
        frame : FitFrame
            From :meth:`frame` or :meth:`frame_from_ranges`.
        stats : SufficientStatistics
            Of ``frame.layout`` in ``frame``'s solve basis, over all regressor rows.
        dense : callable, optional
            Gives the dense regressor, for solvers that need it (OSQP); without
            it such solvers raise FtcalError.

        Returns
        -------
        CalibrationModel
            ``self``, fitted, with empty ``training_metrics_`` (the caller scores).
        """
        problem = ScaledProblem.from_statistics(stats, dense)
        prior = self._prior_coef(frame, problem)
        result = self._solver().fit(problem if prior is None else problem.shifted(prior))
        if prior is not None:
            result.coef = result.coef + prior
        self.adopt(frame, problem, result)
        self._warn_if_rank_deficient(frame.layout)
        return self

    def _solver(self) -> Solver:
        solver = self.solver if self.solver is not None else LeastSquares()
        if not isinstance(solver, Solver):
            raise FtcalError(f"The 'solver' parameter of CalibrationModel must follow the Solver protocol "
                             f"(name, penalty, fit(problem)). Got {solver!r} instead.")
        check_choice(solver.penalty, "solver.penalty", "CalibrationModel", ("none", "ridge", "lasso"))
        return solver

    def frame(self, data: Dataset) -> FitFrame:
        """Validate the parameters against ``data`` and derive everything a solver does not decide.

        Parameters
        ----------
        data : Dataset
            With reference outputs.

        Returns
        -------
        FitFrame
        """
        if data.outputs is None:
            raise FtcalError("Fitting needs reference outputs (the expected wrench); the data has none.")
        u, y = data.inputs, data.outputs
        return self.frame_from_ranges(np.c_[u.min(axis=0), u.max(axis=0)], np.c_[y.min(axis=0), y.max(axis=0)],
                                      data.input_names, data.output_names,
                                      [b - a for a, b in data.segment_bounds()])

    def frame_from_ranges(self, input_range: np.ndarray, output_range: np.ndarray, input_names: Sequence[str],
                          output_names: Sequence[str], segment_lengths: Sequence[int]) -> FitFrame:
        """:meth:`frame` from the data's ranges and segment lengths alone (streamed fits).

        Parameters
        ----------
        input_range, output_range : ndarray of shape (n_inputs, 2), (n_outputs, 2)
            Min and max of each column over all the training samples.
        input_names, output_names : sequence of str
        segment_lengths : sequence of int
            Samples per segment (ARX lags stay inside a segment).

        Returns
        -------
        FitFrame

        Raises
        ------
        FtcalError
            On invalid parameters, or no regressor rows.
        """
        input_range = np.asarray(input_range, dtype=np.float64)
        output_range = np.asarray(output_range, dtype=np.float64)
        basis = self._basis(input_range.shape[0])
        na = check_int(self.na, "na", "CalibrationModel", 0, MAX_LAG)
        nb = check_int(self.nb, "nb", "CalibrationModel", 0, MAX_LAG)
        penalized = self._solver().penalty != "none"
        mode = self.normalization
        if mode is None:
            mode = "maxabs" if penalized else "center"
        mode = check_choice(mode, "normalization", "CalibrationModel", NORMALIZATIONS)
        layout = RegressorLayout(basis, output_range.shape[0], na, nb)
        check_gram_size(layout)
        (u_min, u_max), (y_min, y_max) = input_range.T, output_range.T
        # Past outputs follow the input basis: the paper's are raw values scaled by max-abs.
        in_norm = normalization_from_range(u_min, u_max, mode)
        out_norm = normalization_from_range(y_min, y_max, mode)
        solve_in, solve_out = in_norm, out_norm
        if not penalized and mode != SOLVE_BASIS:
            solve_in = normalization_from_range(u_min, u_max, SOLVE_BASIS)
            solve_out = normalization_from_range(y_min, y_max, SOLVE_BASIS)
        n_rows = sum(max(n - layout.max_lag, 0) for n in segment_lengths)
        _warn_if_ill_posed(input_names, u_max - u_min, layout, n_rows)
        if n_rows == 0:
            raise FtcalError(f"No regressor rows: every segment is shorter than the ARX lag "
                             f"max(na, nb) = {layout.max_lag}.")
        return FitFrame(layout, mode, in_norm, out_norm, solve_in, solve_out, tuple(input_names),
                        tuple(output_names), input_range.copy(), output_range.copy(), int(n_rows))

    def _basis(self, n_inputs: int) -> MonomialBasis:
        if self.basis is None:
            return MonomialBasis(n_inputs, check_int(self.degree, "degree", "CalibrationModel", 1, MAX_DEGREE))
        if not isinstance(self.basis, MonomialBasis):
            raise FtcalError(f"The 'basis' parameter of CalibrationModel must be a MonomialBasis. "
                             f"Got {self.basis!r} instead.")
        if self.basis.n_inputs != n_inputs:
            raise FtcalError(f"The basis has {self.basis.n_inputs} inputs; the data has {n_inputs}.")
        if self.degree not in (1, self.basis.degree):
            raise FtcalError(f"degree={self.degree!r} contradicts the basis of degree {self.basis.degree}; "
                             "pass one of them.")
        return self.basis

    def adopt(self, frame: FitFrame, problem: ScaledProblem, result: SolverResult) -> "CalibrationModel":
        """Become the model ``result`` solves ``problem`` with, in ``frame`` (cross-validation uses this).

        Parameters
        ----------
        frame : FitFrame
            From :meth:`frame` of a model with this model's parameters.
        problem : ScaledProblem
            Solved in ``frame``'s solve basis.
        result : SolverResult

        Returns
        -------
        CalibrationModel
            ``self``, fitted, without ``training_metrics_`` (empty).
        """
        coef = result.coef / problem.column_scale[:, None]
        if not frame.solves_in_stored_basis:
            coef = change_basis(frame.layout, coef, frame.solve_input_normalization,
                                frame.solve_output_normalization, frame.input_normalization,
                                frame.output_normalization)
        lam = result.info.get("lambda")
        self._set_fitted(
            layout=frame.layout, coef=coef, normalization=frame.normalization,
            input_normalization=frame.input_normalization, output_normalization=frame.output_normalization,
            input_names=frame.input_names, output_names=frame.output_names, input_range=frame.input_range,
            output_range=frame.output_range, n_samples_fit=frame.n_rows, rank=result.rank,
            condition_number=result.condition_number,
            solver_info={"name": self._solver().name, **result.info,
                         "lambda": None if lam is None else float(lam)},
            training_metrics={})
        return self

    def _set_fitted(self, *, layout: RegressorLayout, coef: np.ndarray, normalization: str,
                    input_normalization: Normalization, output_normalization: Normalization,
                    input_names: Sequence[str], output_names: Sequence[str], input_range: np.ndarray,
                    output_range: np.ndarray, n_samples_fit: int, rank: int, condition_number: float,
                    solver_info: dict, training_metrics: dict, input_spread: Spread | None = None) -> None:
        """The one place the fitted state is written."""
        coef = np.asarray(coef, dtype=np.float64)
        if coef.shape != (layout.n_features, len(output_names)):
            raise FtcalError(f"Coefficient table has shape {coef.shape}; degree {layout.basis.degree}, "
                             f"na={layout.na}, nb={layout.nb} with {len(input_names)} inputs and "
                             f"{len(output_names)} outputs needs {(layout.n_features, len(output_names))}.")
        self.layout_ = layout
        # C order, as loaded files have: BLAS sums in a layout-dependent order.
        self.coef_ = np.ascontiguousarray(coef)
        self.normalization_ = normalization
        self.input_normalization_ = input_normalization
        self.output_normalization_ = output_normalization
        self.input_names_ = tuple(input_names)
        self.output_names_ = tuple(output_names)
        self.input_range_ = np.asarray(input_range, dtype=np.float64)
        self.output_range_ = np.asarray(output_range, dtype=np.float64)
        self.n_samples_fit_ = int(n_samples_fit)
        self.rank_ = int(rank)
        self.condition_number_ = float(condition_number)
        self.solver_info_ = dict(solver_info)
        self.training_metrics_ = dict(training_metrics)
        self.input_spread_ = input_spread

    def _prior_coef(self, frame: FitFrame, problem: ScaledProblem) -> np.ndarray | None:
        """The prior's coefficients for ``problem``'s scaled columns, or None without a prior."""
        if self.prior is None:
            return None
        prior = self.prior
        if not isinstance(prior, CalibrationModel):
            raise FtcalError(f"The 'prior' parameter of CalibrationModel must be a fitted CalibrationModel. "
                             f"Got {prior!r} instead.")
        prior._check_fitted()
        if self._solver().penalty == "none":
            raise FtcalError("A prior changes only penalized fits; use it with --ridge or --lasso.")
        if prior.input_names_ != frame.input_names or prior.output_names_ != frame.output_names:
            raise FtcalError(f"The prior maps {','.join(prior.input_names_)} -> {','.join(prior.output_names_)}; "
                             f"the data has {','.join(frame.input_names)} -> {','.join(frame.output_names)}.")
        layout = frame.layout
        if (prior.layout_.na, prior.layout_.nb) != (layout.na, layout.nb) or prior.layout_.basis.degree > layout.basis.degree:
            raise FtcalError(f"The prior (degree {prior.layout_.basis.degree}, na={prior.layout_.na}, "
                             f"nb={prior.layout_.nb}) does not fit inside this model (degree {layout.basis.degree}, "
                             f"na={layout.na}, nb={layout.nb}).")
        coef = np.zeros((layout.n_features, len(frame.output_names)))
        own = RegressorLayout(layout.basis, layout.n_outputs, layout.na, layout.nb)
        coef[prior.layout_.index_in(own)] = prior.coef_
        coef = change_basis(layout, coef, prior.input_normalization_, prior.output_normalization_,
                            frame.solve_input_normalization, frame.solve_output_normalization)
        return coef * problem.column_scale[:, None]

    @staticmethod
    def statistics(data: Dataset, layout: RegressorLayout, in_norm: Normalization,
                   out_norm: Normalization) -> SufficientStatistics:
        """Sufficient statistics of ``data`` for ``layout``, segment by segment.

        Parameters
        ----------
        data : Dataset
        layout : RegressorLayout
        in_norm, out_norm : Normalization
            The basis of the inputs and of the past outputs (ARX).

        Returns
        -------
        SufficientStatistics
        """
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

    @staticmethod
    def _dense_regressor(data: Dataset, frame: FitFrame) -> tuple[np.ndarray, np.ndarray]:
        layout = frame.layout
        if frame.n_rows * layout.n_features > DENSE_LIMIT_CELLS:
            raise FtcalError(
                f"The OSQP solver needs the dense {frame.n_rows} × {layout.n_features} regressor "
                f"({frame.n_rows * layout.n_features * 8 / 1e9:.1f} GB); use --solver lstsq, which never builds it.")
        u_norm = frame.solve_input_normalization.apply(data.inputs)
        y_norm = frame.solve_output_normalization.apply(data.outputs)
        blocks, targets = [], []
        for a, b in data.segment_bounds():
            blocks.append(layout.evaluate_segment(u_norm[a:b], y_norm[a:b]))
            targets.append(data.outputs[a + layout.max_lag:b])
        return np.concatenate(blocks), np.concatenate(targets)

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
        """Boolean mask of samples outside the training data: any input outside its range, or outside the span.

        See :meth:`out_of_span`.
        """
        self._check_fitted()
        return np.any(outside_by_channel(inputs, self.input_range_), axis=1) | self.out_of_span(inputs)

    def out_of_span(self, inputs: np.ndarray) -> np.ndarray:
        """Boolean mask of samples outside the span of the training inputs, even inside their range.

        Their squared Mahalanobis distance from the training inputs
        (:func:`ftcal.core.excitation.span_distance`) exceeds
        :func:`ftcal.core.excitation.span_limit`: a combination of inputs the
        training data never had, such as a push along a direction that one rigid
        tool turned through poses never applies. All False without
        ``input_spread_`` (model files from before ftcal recorded it).
        """
        self._check_fitted()
        inputs = np.asarray(inputs, dtype=np.float64)
        if self.input_spread_ is None:
            return np.zeros(inputs.shape[0], dtype=bool)
        return span_distance(self.input_spread_, inputs) > span_limit(inputs.shape[1])

    def predict(self, data: Dataset | np.ndarray, *, mode: str = "free-run", start: str = "zeros",
                warn_out_of_range: bool = True) -> np.ndarray:
        """Predicted outputs.

        Parameters
        ----------
        data : Dataset, or ndarray of shape (n_samples, n_inputs)
            Raw inputs (and, for one-step ARX prediction, measured outputs).
        mode : {"free-run", "one-step"}
            Matters only for ARX models: ``"free-run"`` feeds back past
            predictions (deployment on the robot), ``"one-step"`` uses the
            measured past outputs in ``data`` (the paper's evaluation).
        start : {"zeros", "measured"}
            Free-run history at each segment start. ``"zeros"`` (the paper's
            code): past outputs are zero, so the first max(na, nb) rows are 0
            and the recursion starts at row max(na, nb). ``"measured"``
            (ftcal's): every row is predicted, with the first measured output
            (or, without outputs, the steady state for the first input) as
            history. Models with na = 0 have no feedback: free-run is one-step.
        warn_out_of_range : bool
            Warn (:class:`~ftcal.runtime.errors.OutOfRangeWarning`) about inputs outside the training
            range: which inputs, how far (in training spans), how many samples.

        Returns
        -------
        ndarray of shape (n_samples, n_outputs)
            Rows before max(na, nb) within a segment see their first input
            sample repeated as input history.

        Raises
        ------
        FtcalError
            On non-finite inputs, missing columns, or one-step without outputs.
        """
        self._check_fitted()
        check_choice(mode, "mode", "CalibrationModel.predict", PREDICTION_MODES)
        check_choice(start, "start", "CalibrationModel.predict", FREE_RUN_STARTS)
        data = _as_dataset(data, None, self.input_names_)
        u = check_finite_matrix(data.select_inputs(self.input_names_), "inputs",
                                len(self.input_names_), self.input_names_)
        if warn_out_of_range:
            self._warn_out_of_range(RangeSums.of(u, self.input_range_, outside_span=self.out_of_span(u)),
                                    stacklevel=3)
        if self.layout_.is_static:
            return self._predict_static(u)
        u_norm = self.input_normalization_.apply(u)
        if mode == "one-step" and data.outputs is None:
            raise FtcalError("One-step-ahead prediction needs the measured outputs in the data.")
        measured = None if data.outputs is None else _outputs_in_order(data, self.output_names_)
        # One BLAS thread: results must not depend on thread scheduling (bit-identical reruns).
        with single_threaded_blas():
            return np.concatenate([self._predict_arx_segment(u_norm[a:b], None if measured is None else measured[a:b],
                                                             mode, start)
                                   for a, b in data.segment_bounds()])

    def _warn_out_of_range(self, ranges: RangeSums, stacklevel: int) -> None:
        """One warning for one cause: inputs outside the training range, and those outside its span."""
        message = describe(ranges.summary(self.input_names_))
        if message:
            warnings.warn(message, OutOfRangeWarning, stacklevel=stacklevel)

    def _predict_static(self, u: np.ndarray) -> np.ndarray:
        basis = self.layout_.basis
        coef_t = np.ascontiguousarray(self.coef_.T)
        out = np.empty((u.shape[0], coef_t.shape[0]))
        offset, inv_scale = self.input_normalization_.offset, 1.0 / self.input_normalization_.scale
        kernels = compiled()
        if kernels is not None:
            u, steps = np.ascontiguousarray(u, dtype=np.float64), step_table(basis.n_inputs, basis.degree)
            map_ranges(lambda begin, end: kernels.predict(u[begin:end], offset, inv_scale, coef_t, steps,
                                                          out[begin:end]), u.shape[0], PREDICT_CHUNK)
            return out
        offset, inv_scale = offset[:, None], inv_scale[:, None]  # per input, across a chunk's samples

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

    def _predict_arx_segment(self, u_norm: np.ndarray, y_measured: np.ndarray | None, mode: str,
                             start: str) -> np.ndarray:
        layout, lag = self.layout_, self.layout_.max_lag
        ny = len(self.output_names_)
        padded_u = np.concatenate([np.repeat(u_norm[:1], lag, axis=0), u_norm])
        if layout.na == 0:
            return self._arx_product(padded_u, np.zeros((padded_u.shape[0], ny)))
        if mode == "one-step":
            y_norm = self.output_normalization_.apply(y_measured)
            padded_y = np.concatenate([np.repeat(y_norm[:1], lag, axis=0), y_norm])
            return self._arx_product(padded_u, padded_y)
        # Free run: the input part once for all samples, then the output recursion.
        exogenous = self._arx_product(padded_u, np.zeros((padded_u.shape[0], ny)))
        feedback = [self.coef_[(j - 1) * ny:j * ny] for j in range(1, layout.na + 1)]
        scale = self.output_normalization_.scale
        offset = self.output_normalization_.offset
        result = np.empty_like(exogenous)
        first = 0
        if start == "zeros":
            # The paper's predictor: zero outputs before row max(na, nb), recursion from there.
            first = min(lag, exogenous.shape[0])
            result[:first] = 0.0
            history = [self.output_normalization_.apply(np.zeros(ny))] * layout.na
        elif y_measured is not None:
            history = [self.output_normalization_.apply(y_measured[0])] * layout.na
        else:
            history = [self.output_normalization_.apply(self._steady_state(exogenous[0], feedback))] * layout.na
        for k in range(first, exogenous.shape[0]):
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

    def score(self, data: Dataset, *, mode: str = "one-step", start: str = "zeros", warmup: str = "drop",
              warn_out_of_range: bool = True) -> dict:
        """Metrics of :func:`ftcal.core.metrics.summarize` plus ``n_out_of_range``.

        Parameters
        ----------
        data : Dataset
            With reference outputs.
        mode, start : str
            ARX prediction (see :meth:`predict`); the default is the paper's
            evaluation, one-step-ahead.
        warmup : {"drop", "keep"}
            ``"drop"`` (the paper's code) leaves the first max(na, nb) rows of
            each segment out of the metrics; no effect on static models.
        warn_out_of_range : bool
            Warn once about inputs outside the training range, with the force- and
            torque-norm errors on those samples next to those inside.

        Returns
        -------
        dict
            For ARX models also the other mode's metrics, under ``"free_run"``
            or ``"one_step"``.
        """
        self._check_fitted()
        check_choice(warmup, "warmup", "CalibrationModel.score", ARX_WARMUP)
        if data.outputs is None:
            raise FtcalError("Evaluating needs reference outputs in the data.")
        y = _outputs_in_order(data, self.output_names_)
        rows = np.ones(data.n_samples, dtype=bool)
        if warmup == "drop" and self.layout_.max_lag:
            for a, b in data.segment_bounds():
                rows[a:a + self.layout_.max_lag] = False
        if not rows.any():
            raise FtcalError(f"Nothing to evaluate: every segment is shorter than the ARX warm-up "
                             f"max(na, nb) = {self.layout_.max_lag} rows.")
        prediction = self.predict(data, mode=mode, start=start, warn_out_of_range=False)
        summary = metrics.summarize(y[rows], prediction[rows], self.output_names_)
        inputs = data.select_inputs(self.input_names_)
        summary["n_out_of_range"] = int(self.out_of_range(inputs).sum())
        if warn_out_of_range and summary["n_out_of_range"]:
            self._warn_out_of_range(RangeSums.of(inputs, self.input_range_, y, prediction, self.output_names_,
                                                 scored=rows, outside_span=self.out_of_span(inputs)),
                                    stacklevel=3)
        if not self.layout_.is_static and data.outputs is not None:
            other = "free-run" if mode == "one-step" else "one-step"
            second = self.predict(data, mode=other, start=start, warn_out_of_range=False)
            summary[other.replace("-", "_")] = metrics.summarize(y[rows], second[rows], self.output_names_)
        return summary

    @property
    def is_static(self) -> bool:
        """True without ARX lags (``na = nb = 0``): each prediction depends on its own sample only."""
        return self.na == 0 and self.nb == 0

    def label(self) -> str:
        """``np4``, ``np2 na=1 nb=1``, ``np4 lasso λ=50`` (the labels of cross-validation tables)."""
        d = self.describe()
        name = f"np{d['degree']}" + (f" na={d['na']} nb={d['nb']}" if d["na"] or d["nb"] else "")
        solver, lam = str(self.solver_info_.get("name") or ""), self.solver_info_.get("lambda")
        if lam is not None and ("lasso" in solver or "ridge" in solver):
            name += f" {'lasso' if 'lasso' in solver else 'ridge'} λ={float(lam):g}"
        return name

    def to_document(self) -> dict:
        """The polynomial's model-file fields: ``model``, ``terms``, ``coefficients`` and fit diagnostics.

        Raises
        ------
        FtcalError
            Non-finite coefficients.
        """
        self._check_fitted()
        if not np.all(np.isfinite(self.coef_)):
            raise FtcalError("The model has non-finite coefficients (NaN or inf); refusing to save it.")
        layout = self.layout_
        exponents, lags = layout.exponent_rows()
        return {"model": {"degree": layout.basis.degree, "na": layout.na, "nb": layout.nb,
                          "normalization": self.normalization_},
                "terms": {"exponents": exponents.tolist(), "lags": lags.tolist(),
                          "names": layout.column_names(self.input_names_, self.output_names_)},
                "coefficients": self.coef_.tolist(),
                "fit": {"rank": self.rank_, "condition_number": self.condition_number_}}

    @classmethod
    def from_document(cls, doc: dict, source: str) -> "CalibrationModel":
        """The model of a schema-valid model-file document (checks the schema cannot express).

        Raises
        ------
        FtcalError
            Term or coefficient counts that do not match the degree, lags and outputs, terms out of
            the paper's column order; the message names ``source`` and the field.
        """
        spec, inputs, outputs = doc["model"], doc["inputs"], doc["outputs"]
        nu, ny = len(inputs), len(outputs)
        model_class = (f"degree {spec['degree']}, na={spec['na']}, nb={spec['nb']} with {nu} inputs "
                       f"and {ny} outputs")
        # Count by formula before building the basis, which enumerates every term.
        n_terms = n_coefficients(nu, spec["degree"], ny, spec["na"], spec["nb"]) // ny
        coef = doc["coefficients"]
        for field, entries in (("terms.exponents", doc["terms"]["exponents"]), ("terms.lags", doc["terms"]["lags"]),
                               ("terms.names", doc["terms"]["names"]), ("coefficients", coef)):
            if len(entries) != n_terms:
                raise FtcalError(f"{source}: {field} has {len(entries)} entries; {model_class} has {n_terms} terms.")
        layout = RegressorLayout(MonomialBasis(nu, spec["degree"]), ny, spec["na"], spec["nb"])
        _check_terms(doc["terms"], layout, model_class, source)
        bad_row = next((i for i, row in enumerate(coef) if len(row) != ny), None)
        if bad_row is not None:
            raise FtcalError(f"{source}: coefficients[{bad_row}] has {len(coef[bad_row])} values; the model has "
                             f"{ny} outputs.")
        fit = doc["fit"]
        return model_from_fitted(
            degree=spec["degree"], na=spec["na"], nb=spec["nb"], normalization=spec["normalization"],
            coef=np.array(coef, dtype=np.float64),
            input_normalization=variables_normalization(inputs), output_normalization=variables_normalization(outputs),
            input_names=[v["name"] for v in inputs], output_names=[v["name"] for v in outputs],
            input_range=variables_range(inputs), output_range=variables_range(outputs),
            n_samples_fit=fit["n_samples"], rank=fit["rank"],
            condition_number=float("nan") if fit["condition_number"] is None else float(fit["condition_number"]),
            solver_info=fit["solver"], training_metrics=fit["metrics"], input_spread=_spread(fit, nu, source))

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


def _spread(fit: dict, n_inputs: int, source: str) -> Spread | None:
    """The training inputs' mean and covariance (optional: files from before ftcal recorded them)."""
    doc = fit.get("input_spread")
    if doc is None:
        return None
    mean, cov = doc["mean"], doc["covariance"]
    if len(mean) != n_inputs or len(cov) != n_inputs or any(len(row) != n_inputs for row in cov):
        raise FtcalError(f"{source}: fit.input_spread has {len(mean)} means and a {len(cov)}-row covariance; "
                         f"the model has {n_inputs} inputs.")
    if any(v is None for v in (*mean, *(x for row in cov for x in row))):
        raise FtcalError(f"{source}: fit.input_spread holds non-finite values.")
    return Spread.from_json(doc)


def _check_terms(terms: dict, layout: RegressorLayout, model_class: str, source: str) -> None:
    expected_exps, expected_lags = layout.exponent_rows()
    for row, (got, want) in enumerate(zip(terms["exponents"], expected_exps.tolist())):
        if got != want:
            raise FtcalError(f"{source}: terms.exponents[{row}] is {got}; {model_class} has {want} there "
                             "(the paper's column order).")
    for row, (got, want) in enumerate(zip(terms["lags"], expected_lags.tolist())):
        if got != want:
            raise FtcalError(f"{source}: terms.lags[{row}] is {got}; {model_class} has {want} there.")


def _warn_if_ill_posed(input_names: Sequence[str], span: np.ndarray, layout: RegressorLayout,
                       n_rows: int) -> None:
    p = layout.n_features
    if n_rows < p:
        warnings.warn(
            f"The fit is under-determined: {n_rows} samples for {p} coefficients per output. "
            "Lower the degree, add recordings, or use --lasso/--ridge.",
            IllPosedFitWarning, stacklevel=5)
    for name, width in zip(input_names, span):
        if width == 0:
            warnings.warn(
                f"Input {name!r} is constant in the training data, so its terms duplicate the "
                "offset; drop it with --inputs or record data where it varies.",
                IllPosedFitWarning, stacklevel=5)


def change_basis(layout: RegressorLayout, coef: np.ndarray, from_inputs: Normalization,
                 from_outputs: Normalization, to_inputs: Normalization, to_outputs: Normalization) -> np.ndarray:
    """The same polynomial's coefficients in another normalized basis (exact algebra).

    Parameters
    ----------
    layout : RegressorLayout
    coef : ndarray of shape (n_features, n_outputs)
        Coefficients of ``layout``'s columns evaluated at ``from_*``-normalized values.
    from_inputs, from_outputs, to_inputs, to_outputs : Normalization

    Returns
    -------
    ndarray of shape (n_features, n_outputs)
        Coefficients for ``to_*``-normalized values.

    Examples
    --------
    >>> import numpy as np
    >>> layout = RegressorLayout(MonomialBasis(1, 2), 1)
    >>> center = Normalization(np.array([3.0]), np.array([2.0]))   # z = (u - 3) / 2
    >>> raw = Normalization.identity(1)
    >>> change_basis(layout, np.array([[0.0], [1.0], [0.0]]), center, raw, raw, raw).ravel().tolist()  # z² = (u² - 6u + 9) / 4
    [-1.5, 0.25, 2.25]
    """
    # z = (v − o_to)/s_to and x = (v − o_from)/s_from give x = (z − (o_from − o_to)/s_to) / (s_from/s_to).
    t = substitution_matrix(layout, (from_inputs.offset - to_inputs.offset) / to_inputs.scale,
                            from_inputs.scale / to_inputs.scale,
                            (from_outputs.offset - to_outputs.offset) / to_outputs.scale,
                            from_outputs.scale / to_outputs.scale)
    return np.asarray(t @ coef)


def model_from_fitted(*, degree: int, na: int, nb: int, normalization: str, coef: np.ndarray,
                      input_normalization: Normalization, output_normalization: Normalization,
                      input_names: Sequence[str], output_names: Sequence[str],
                      input_range: np.ndarray, output_range: np.ndarray, n_samples_fit: int = 0,
                      rank: int | None = None, condition_number: float = float("nan"),
                      solver_info: dict | None = None, training_metrics: dict | None = None,
                      solver: Solver | None = None, input_spread: Spread | None = None) -> CalibrationModel:
    """Rebuild a fitted model from stored parts (model files use this).

    Parameters
    ----------
    degree, na, nb : int
    normalization : str
        The stored basis (one of :data:`ftcal.core.limits.NORMALIZATIONS`).
    coef : ndarray of shape (n_features, n_outputs)
    input_normalization, output_normalization : Normalization
    input_names, output_names : sequence of str
    input_range, output_range : ndarray of shape (n, 2)
    n_samples_fit, rank, condition_number, solver_info, training_metrics, solver
        Fit diagnostics, as a fitted model carries them.
    input_spread : Spread or None
        Mean and covariance of the training inputs (the span check of :meth:`CalibrationModel.out_of_range`).

    Returns
    -------
    CalibrationModel

    Raises
    ------
    FtcalError
        When ``coef`` does not have the layout's shape.
    """
    model = CalibrationModel(degree, solver=solver, na=na, nb=nb, normalization=normalization)
    layout = RegressorLayout(MonomialBasis(len(input_names), degree), len(output_names), na, nb)
    model._set_fitted(
        layout=layout, coef=coef, normalization=normalization, input_normalization=input_normalization,
        output_normalization=output_normalization, input_names=input_names, output_names=output_names,
        input_range=input_range, output_range=output_range, n_samples_fit=n_samples_fit,
        rank=layout.n_features if rank is None else rank, condition_number=condition_number,
        solver_info=solver_info or {}, training_metrics=training_metrics or {}, input_spread=input_spread)
    return model
