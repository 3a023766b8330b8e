"""Least squares and ridge from the normal equations of the scaled problem."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ...runtime.checks import check_float
from .base import Conditioning, ScaledProblem, SolverResult


class LeastSquares:
    """x* = argmin ½‖Ax − b‖², minimum-norm when A is rank deficient (like ``lstsq``).

    Examples
    --------
    >>> import numpy as np
    >>> from ftcal.core.statistics import dense_statistics
    >>> a = np.array([[0.0, 1.0], [1.0, 1.0], [2.0, 1.0]])
    >>> b = np.array([[1.0], [3.0], [5.0]])  # b = 2a + 1
    >>> problem = ScaledProblem.from_statistics(dense_statistics(a, b))
    >>> result = LeastSquares().fit(problem)
    >>> np.round(result.coef[:, 0] / problem.column_scale, 12).tolist()
    [2.0, 1.0]
    """

    name = "lstsq"
    penalty = "none"

    def fit(self, problem: ScaledProblem) -> SolverResult:
        """Solve G x = c (minimum norm when G is singular).

        Parameters
        ----------
        problem : ScaledProblem

        Returns
        -------
        SolverResult
            ``coef`` of shape (p, n_outputs) for the scaled columns.
        """
        conditioning = Conditioning.of(problem.gram)
        coef = conditioning.solve(problem.cross)
        return SolverResult(coef, conditioning.rank, conditioning.condition_number)


class Ridge:
    """x* = argmin ½‖Ax − b‖² + ½λ‖x‖² on max-abs scaled columns (offset included).

    This is ftcal's one ridge scale: the same λ as
    ``sklearn.linear_model.Ridge(alpha=λ, fit_intercept=False)`` on the scaled
    regressor with its constant column (sklearn minimizes ‖Ax − b‖² + λ‖x‖²,
    twice this objective). A QP written as ½‖Ax − b‖² + λ'‖x‖² (the paper's
    MATLAB form) has λ = 2λ'.

    Parameters
    ----------
    lam : float > 0
        Ridge weight λ.

    Examples
    --------
    >>> import numpy as np
    >>> from ftcal.core.statistics import dense_statistics
    >>> a, b = np.ones((4, 1)), np.full((4, 1), 2.0)  # least squares: x = 2
    >>> Ridge(4.0).fit(ScaledProblem.from_statistics(dense_statistics(a, b))).coef.round(12).tolist()  # 8 / (4 + 4)
    [[1.0]]
    """

    name = "ridge"
    penalty = "ridge"

    def __init__(self, lam: float):
        self.lam = lam

    def fit(self, problem: ScaledProblem) -> SolverResult:
        """Solve (G + λI) x = c by Cholesky.

        Parameters
        ----------
        problem : ScaledProblem

        Returns
        -------
        SolverResult
            ``coef`` of shape (p, n_outputs); ``info["lambda"]`` is λ.
        """
        lam = check_float(self.lam, "lam", "Ridge", 0.0, low_inclusive=False)
        conditioning = Conditioning.of(problem.gram)
        system = problem.gram + lam * np.eye(problem.n_features)
        import scipy.linalg

        factor = scipy.linalg.cho_factor(system, lower=True, check_finite=False)
        coef = scipy.linalg.cho_solve(factor, problem.cross, check_finite=False)
        return SolverResult(coef, conditioning.rank, conditioning.condition_number, {"lambda": lam})

    def fit_path(self, problem: ScaledProblem, lams: Sequence[float], *,
                 eigen: tuple[np.ndarray, np.ndarray] | None = None) -> list[SolverResult]:
        """Solutions for each λ in ``lams`` from one eigen-decomposition of G.

        Parameters
        ----------
        problem : ScaledProblem
        lams : sequence of float > 0
        eigen : (values, vectors), optional
            ``numpy.linalg.eigh(problem.gram)``, when the caller has it.

        Returns
        -------
        list of SolverResult, one per λ (``info["lambda"]`` set)
        """
        lams = [check_float(lam, "lam", "Ridge", 0.0, low_inclusive=False) for lam in lams]
        values, vectors = eigen if eigen is not None else np.linalg.eigh(problem.gram)
        projected = vectors.T @ problem.cross
        top = max(values[-1], 0.0)
        rank = int(np.sum(values > top * np.finfo(float).eps * max(values.size, 10) * 10))
        condition = float(np.sqrt(top / values[0])) if values[0] > 0 else float("inf")
        return [SolverResult(vectors @ (projected / (values + lam)[:, None]), rank, condition, {"lambda": lam})
                for lam in lams]
