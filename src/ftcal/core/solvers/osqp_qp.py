"""The paper's quadratic programs, solved with OSQP, for comparison.

These follow the paper's recipe on the dense max-abs scaled regressor A, one
output at a time:

least squares   min ½ xᵀ(AᵀA)x − (Aᵀb)ᵀx
LASSO           min ½‖r‖² + λ·1ᵀt   s.t.  Ax − r = b,  −t <= x <= t

The LASSO program has one variable per sample (r), which is what makes the
paper's code take minutes per output; ftcal's own :class:`~ftcal.core.solvers.lasso.Lasso`
solves the same problem in p variables. OSQP stops at a tolerance
(``eps``, 1e-4 as in the recipe), so its coefficients have no exact zeros.
"""

from __future__ import annotations

import numpy as np

from ...runtime.errors import FtcalError, ParameterError
from .base import ScaledProblem, SolverResult

DEFAULT_EPS = 1e-4


def _solve_qp(P, q, A, lower, upper, eps: float, max_iter: int):
    import osqp
    import scipy.sparse as sp

    problem = osqp.OSQP()
    problem.setup(P=sp.csc_matrix(P), q=q, A=sp.csc_matrix(A), l=lower, u=upper,
                  eps_abs=eps, eps_rel=eps, max_iter=max_iter, verbose=False, polishing=False)
    result = problem.solve(raise_error=False)  # we check the status ourselves
    status = str(result.info.status)
    if "solved" not in status.lower():
        raise ParameterError('solver', f"OSQP did not solve the problem (status: {status}); "
                         "use {solver} lstsq, or a lower degree.")
    return result.x, int(result.info.iter)


class OsqpLeastSquares:
    """The paper's least-squares QP, per output, on the dense scaled regressor."""

    name = "osqp"
    penalty = "none"

    def __init__(self, eps: float = DEFAULT_EPS, max_iter: int = 100000):
        self.eps = eps
        self.max_iter = max_iter

    def fit(self, problem: ScaledProblem) -> SolverResult:
        """Solve on ``problem``'s dense scaled regressor (see :meth:`fit_dense`)."""
        return self.fit_dense(*problem.scaled_regressor())

    def fit_dense(self, a_scaled: np.ndarray, targets: np.ndarray) -> SolverResult:
        """``a_scaled`` (n, p) max-abs scaled regressor, ``targets`` (n, ny)."""
        import scipy.sparse as sp  # imported here: the least-squares path never needs it

        p = a_scaled.shape[1]
        hessian = sp.triu(sp.csc_matrix(a_scaled.T @ a_scaled), format="csc")
        no_constraints = sp.csc_matrix((0, p))
        coef = np.empty((p, targets.shape[1]))
        iterations = []
        for i in range(targets.shape[1]):
            x, its = _solve_qp(hessian, -(a_scaled.T @ targets[:, i]), no_constraints,
                               np.empty(0), np.empty(0), self.eps, self.max_iter)
            coef[:, i] = x
            iterations.append(its)
        return SolverResult(coef, p, float("nan"), {"iterations": iterations})


class OsqpLasso:
    """The paper's LASSO QP with one residual variable per sample."""

    name = "osqp-lasso"
    penalty = "lasso"

    def __init__(self, lam: float, eps: float = DEFAULT_EPS, max_iter: int = 100000):
        self.lam = lam
        self.eps = eps
        self.max_iter = max_iter

    def fit(self, problem: ScaledProblem) -> SolverResult:
        """Solve on ``problem``'s dense scaled regressor (see :meth:`fit_dense`)."""
        return self.fit_dense(*problem.scaled_regressor())

    def fit_dense(self, a_scaled: np.ndarray, targets: np.ndarray) -> SolverResult:
        """``a_scaled`` (n, p) max-abs scaled regressor, ``targets`` (n, ny)."""
        import scipy.sparse as sp  # imported here: the least-squares path never needs it

        n, p = a_scaled.shape
        eye_p, eye_n = sp.identity(p, format="csc"), sp.identity(n, format="csc")
        # Variables v = [x (p), t (p), r (n)].
        hessian = sp.block_diag([sp.csc_matrix((2 * p, 2 * p)), eye_n], format="csc")
        linear = np.r_[np.zeros(p), np.full(p, self.lam), np.zeros(n)]
        constraints = sp.vstack([
            sp.hstack([sp.csc_matrix(a_scaled), sp.csc_matrix((n, p)), -eye_n]),
            sp.hstack([eye_p, -eye_p, sp.csc_matrix((p, n))]),
            sp.hstack([-eye_p, -eye_p, sp.csc_matrix((p, n))]),
        ], format="csc")
        coef = np.empty((p, targets.shape[1]))
        iterations = []
        for i in range(targets.shape[1]):
            lower = np.r_[targets[:, i], np.full(2 * p, -np.inf)]
            upper = np.r_[targets[:, i], np.zeros(2 * p)]
            v, its = _solve_qp(hessian, linear, constraints, lower, upper, self.eps, self.max_iter)
            coef[:, i] = v[:p]
            iterations.append(its)
        return SolverResult(coef, p, float("nan"), {"iterations": iterations, "lambda": self.lam})
