"""Least squares and ridge from the normal equations of the scaled problem."""

from __future__ import annotations

import numpy as np
import scipy.linalg

from .._checks import check_float
from .base import Conditioning, ScaledProblem, SolverResult


class LeastSquares:
    """x* = argmin ½‖Ax − b‖², minimum-norm when A is rank deficient (like ``lstsq``)."""

    name = "lstsq"
    lam = 0.0

    def fit(self, problem: ScaledProblem) -> SolverResult:
        conditioning = Conditioning.of(problem.gram)
        coef = conditioning.solve(problem.cross)
        return SolverResult(coef, conditioning.rank, conditioning.condition_number)


class Ridge:
    """x* = argmin ½‖Ax − b‖² + ½λ‖x‖² on max-abs scaled columns (offset included).

    Matches ``sklearn.linear_model.Ridge(alpha=λ, fit_intercept=False)`` on the
    scaled regressor with its constant column.
    """

    name = "ridge"

    def __init__(self, lam: float):
        self.lam = lam

    def fit(self, problem: ScaledProblem) -> SolverResult:
        lam = check_float(self.lam, "lam", "Ridge", 0.0, low_inclusive=False)
        conditioning = Conditioning.of(problem.gram)
        system = problem.gram + lam * np.eye(problem.n_features)
        factor = scipy.linalg.cho_factor(system, lower=True, check_finite=False)
        coef = scipy.linalg.cho_solve(factor, problem.cross, check_finite=False)
        return SolverResult(coef, conditioning.rank, conditioning.condition_number)
