"""The calibration model's parameters and fitted state: fit from data or from summed statistics.

Which basis a fit is solved in: least squares does not depend on the basis, so
it is always solved in the best-conditioned one (``center``) and its
coefficients mapped exactly into the stored basis. A penalty does depend on the
basis: ridge and LASSO are solved in the stored basis, by default the paper's
(raw monomials scaled by their max-abs, ``maxabs``).
"""

from __future__ import annotations

import warnings
from collections.abc import Callable, Sequence

import numpy as np

from ...runtime.checks import check_choice, check_int
from ...runtime.errors import FtcalError, ParameterError, IllPosedFitWarning, IllPosedParameterWarning, NotFittedError
from ...runtime.progress import progress_bar
from ..dataset import Dataset
from ..estimator import EstimatorParams
from ..excitation import Spread
from ..features import MonomialBasis, RegressorLayout
from ..limits import MAX_DEGREE, MAX_LAG, NORMALIZATIONS
from ..normalization import Normalization, normalization_from_range
from ..solvers.base import ScaledProblem, Solver, SolverResult
from ..solvers.least_squares import LeastSquares
from ..statistics import SufficientStatistics, dataset_statistics
from .basis import change_basis
from .document import DocumentMixin
from .frame import SOLVE_BASIS, FitFrame, as_dataset, check_gram_size, dense_regressor, warn_if_ill_posed
from .prediction import PredictionMixin

CONDITION_WARNING = 1e7


class CalibrationModel(PredictionMixin, DocumentMixin, EstimatorParams):
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
    exports = frozenset({"json", "paper-xml", "icub-firmware", "wbd", "c", "c-runtime", "cpp-runtime", "onnx"})
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
    def fit(self, data: Dataset | np.ndarray, y: np.ndarray | None = None) -> "CalibrationModel":
        """Fit on a :class:`Dataset` (or an inputs array plus its outputs ``y``).

        Parameters
        ----------
        data : Dataset, or ndarray of shape (n_samples, n_inputs)
        y : ndarray of shape (n_samples, n_outputs), optional
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
        data = as_dataset(data, y)
        frame = self.frame(data)
        stats = self.statistics(data, frame.layout, frame.solve_input_normalization,
                                frame.solve_output_normalization)

        def dense():
            return dense_regressor(data, frame)

        self.fit_statistics(frame, stats, dense)
        self.input_spread_ = Spread.of(data.inputs)
        self.training_metrics_ = self.metrics(data, warn_out_of_range=False)
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
            raise FtcalError("Fitting needs reference outputs (the expected wrench); the data has none: the model "
                             "requires y to be passed, but the target y is None.")
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
        warn_if_ill_posed(input_names, u_max - u_min, layout, n_rows)
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
            raise ParameterError(('ridge', 'lasso'), "A prior changes only penalized fits; use it with {ridge} or {lasso}.")
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
        """Sufficient statistics of ``data`` for ``layout`` (:func:`~ftcal.core.statistics.dataset_statistics`:
        the streaming accumulator over one chunk; ARX lags stay inside segments).

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
        # The one statistics path: the streaming accumulator fed one chunk, the whole dataset.
        with progress_bar("accumulating statistics", data.n_samples) as advance:
            return dataset_statistics(data, layout, in_norm, out_norm, advance)

    def _warn_if_rank_deficient(self, layout: RegressorLayout) -> None:
        if self.solver_info_.get("lambda"):
            return  # ridge and LASSO penalties make collinear problems well posed
        p = layout.n_features
        if self.rank_ < p:
            warnings.warn(IllPosedParameterWarning(
                ("ridge", "lasso"), f"The regressor has rank {self.rank_} < {p} columns (collinear or constant "
                "inputs, or too high a degree for this data); the minimum-norm solution was used. "
                "Lower the degree, add varied data, or use {ridge}/{lasso}."), stacklevel=3)
        elif self.condition_number_ > CONDITION_WARNING:
            warnings.warn(IllPosedParameterWarning(
                ("ridge", "lasso"), f"The regressor is ill-conditioned (condition number "
                f"{self.condition_number_:.2g}); coefficients are poorly determined. Lower the degree or use "
                "{ridge}/{lasso}."), stacklevel=3)

    def _check_fitted(self) -> None:
        if not hasattr(self, "coef_"):
            raise NotFittedError("This CalibrationModel is not fitted yet; call fit() or load a model file.")

    @property
    def n_coefficients(self) -> int:
        self._check_fitted()
        return int(self.coef_.size)

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

    def describe(self) -> dict:
        """Counts for reports: model class, coefficients, nonzeros."""
        self._check_fitted()
        return {
            "degree": self.layout_.basis.degree, "na": self.layout_.na, "nb": self.layout_.nb,
            "n_inputs": len(self.input_names_), "n_outputs": len(self.output_names_),
            "n_coefficients": int(self.coef_.size),
            "n_nonzero": int(np.count_nonzero(self.coef_)),
        }


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
    return CalibrationModel._from_fitted(
        degree=degree, na=na, nb=nb, normalization=normalization, coef=coef,
        input_normalization=input_normalization, output_normalization=output_normalization,
        input_names=input_names, output_names=output_names, input_range=input_range, output_range=output_range,
        n_samples_fit=n_samples_fit, rank=rank, condition_number=condition_number, solver_info=solver_info,
        training_metrics=training_metrics, solver=solver, input_spread=input_spread)
