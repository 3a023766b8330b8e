"""LASSO on sufficient statistics: ADMM in p variables, finished by an exact active-set solve.

Objective (the paper's, per output): ½‖Ax − b‖² + λ‖x‖₁ on max-abs scaled
columns, offset included. ``sklearn.linear_model.Lasso(alpha=λ/N,
fit_intercept=False)`` on the same scaled regressor solves the same problem.

ADMM splits x = z: the x-step solves (G + ρI) x = c + ρ(z − w), which costs
two small matrix products once G = VΛVᵀ is known, for any ρ; the z-step
soft-thresholds, giving exact zeros. ADMM alone converges slowly to high
accuracy, so every few iterations we guess the active set and signs from z,
solve the reduced system G_SS x_S = c_S − λ·sign, and accept it if it satisfies
the LASSO optimality conditions — then the answer is exact, not approximate.
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence

import numpy as np

from ...runtime.checks import check_float
from ...runtime.errors import FtcalWarning
from ...runtime.threads import single_threaded_blas
from .base import Conditioning, ScaledProblem, SolverResult

KKT_RTOL = 1e-7
POLISH_EVERY = 20
RHO_EVERY = 10
RELAXATION = 1.6
MAX_ITER = 20000
MAX_ACTIVE_SET_STEPS = 30


class Lasso:
    """LASSO with exact zeros: x* = argmin ½‖Ax − b‖² + λ‖x‖₁; ``fit_path`` warm-starts over several λ.

    Parameters
    ----------
    lam : float > 0
        LASSO weight λ (on max-abs scaled columns: the paper's scale).
    max_iter : int
        ADMM iterations before giving up (with a warning).

    Examples
    --------
    >>> import numpy as np
    >>> from ftcal.core.statistics import dense_statistics
    >>> a = np.array([[1.0, 0.0], [0.0, 1.0]])
    >>> b = np.array([[3.0], [0.5]])
    >>> problem = ScaledProblem.from_statistics(dense_statistics(a, b))
    >>> Lasso(1.0).fit(problem).coef[:, 0].tolist()  # soft threshold: 3 - 1, and 0.5 -> 0
    [2.0, 0.0]
    """

    name = "lasso"
    penalty = "lasso"

    def __init__(self, lam: float, max_iter: int = MAX_ITER):
        self.lam = lam
        self.max_iter = max_iter

    def fit(self, problem: ScaledProblem) -> SolverResult:
        """The solution at ``lam``; ``info`` has ``"lambda"``, ``"n_nonzero"``, ``"iterations"``.

        Parameters
        ----------
        problem : ScaledProblem

        Returns
        -------
        SolverResult
        """
        return self.fit_path(problem, [self.lam])[0]

    def fit_path(self, problem: ScaledProblem, lams: Sequence[float], *,
                 eigen: tuple[np.ndarray, np.ndarray] | None = None) -> list[SolverResult]:
        """Solutions for each λ in ``lams`` (returned in the given order), warm-started from large to small λ.

        Parameters
        ----------
        problem : ScaledProblem
        lams : sequence of float > 0
        eigen : (values, vectors), optional
            ``numpy.linalg.eigh(problem.gram)`` when the caller has it (cross-validation
            shares it with ridge); rank and condition number then come from these values.

        Returns
        -------
        list of SolverResult, one per λ
        """
        lams = [check_float(lam, "lam", "Lasso", 0.0, low_inclusive=False) for lam in lams]
        with single_threaded_blas():
            return self._fit_path(problem, lams, eigen)

    def _fit_path(self, problem: ScaledProblem, lams: list[float], eigen) -> list[SolverResult]:
        if eigen is None:
            values, vectors = np.linalg.eigh(problem.gram)
            equilibrated = Conditioning.of(problem.gram)
            rank, condition = equilibrated.rank, equilibrated.condition_number
        else:
            values, vectors = eigen
            rank, condition = _rank_and_condition(values)
        state = _AdmmState.cold(problem, values)
        results: dict[int, SolverResult] = {}
        for index in sorted(range(len(lams)), key=lambda i: -lams[i]):
            state.rescale_dual(lams[index])
            coef, info = _solve_one_lambda(problem, values, vectors, lams[index], state, self.max_iter)
            if not info["converged"]:
                warnings.warn(
                    f"LASSO at lambda={lams[index]:g} stopped after {self.max_iter} iterations "
                    f"without meeting the optimality tolerance for output(s) {info['unconverged']}; "
                    "coefficients are approximate. Try a larger lambda or a lower degree.",
                    FtcalWarning, stacklevel=2)
            info["lambda"] = lams[index]
            info["n_nonzero"] = np.count_nonzero(coef, axis=0).tolist()
            results[index] = SolverResult(coef, rank, condition, info)
        return [results[i] for i in range(len(lams))]


def _rank_and_condition(values: np.ndarray) -> tuple[int, float]:
    """Rank and condition number of A from the eigenvalues of AᵀA (ascending)."""
    top = max(values[-1], 0.0)
    keep = values > top * np.finfo(float).eps * max(values.size, 10) * 10
    smallest = values[0]
    return int(keep.sum()), float(np.sqrt(top / smallest)) if smallest > 0 else float("inf")


class _AdmmState:
    """Warm-start state across λ: z (coefficients), w (scaled dual), ρ per output."""

    def __init__(self, z: np.ndarray, w: np.ndarray, rho: np.ndarray, lam: float | None):
        self.z, self.w, self.rho, self.lam = z, w, rho, lam

    @classmethod
    def cold(cls, problem: ScaledProblem, values: np.ndarray) -> "_AdmmState":
        p, ny = problem.cross.shape
        positive = values[values > values[-1] * 1e-12]
        # Geometric mean of the spectrum's ends: a standard good ADMM step for QPs.
        rho0 = float(np.sqrt(positive[0] * positive[-1])) if positive.size else 1.0
        return cls(np.zeros((p, ny)), np.zeros((p, ny)), np.full(ny, rho0), None)

    def rescale_dual(self, lam: float) -> None:
        # w = y/ρ with y a subgradient of λ‖z‖₁; keep it consistent with the new λ.
        if self.lam is not None:
            self.w *= lam / self.lam
        self.lam = lam


def _solve_one_lambda(problem, values, vectors, lam, state, max_iter):
    gram, cross = problem.gram, problem.cross
    p, ny = cross.shape
    coef = np.zeros((p, ny))
    done = np.zeros(ny, dtype=bool)
    # λ >= ‖c‖∞ makes x = 0 optimal exactly.
    zero = np.abs(cross).max(axis=0) <= lam
    done |= zero
    z, w, rho = state.z, state.w, state.rho
    c_vt = vectors.T @ cross
    # Polish only when the sign pattern has settled and differs from the last failure.
    tried = [None] * ny
    previous_signs = np.sign(z)
    iterations = 0
    while not done.all() and iterations < max_iter:
        todo = np.flatnonzero(~done)
        for step in range(POLISH_EVERY):
            rhs = c_vt[:, todo] + rho[todo] * (vectors.T @ (z[:, todo] - w[:, todo]))
            x = vectors @ (rhs / (values[:, None] + rho[todo]))
            z_old = z[:, todo]
            # Over-relaxation (α = 1.6) speeds ADMM up on QPs at no cost.
            x_hat = RELAXATION * x + (1.0 - RELAXATION) * z_old
            v = x_hat + w[:, todo]
            z_new = np.sign(v) * np.maximum(np.abs(v) - lam / rho[todo], 0.0)
            w[:, todo] = v - z_new
            z[:, todo] = z_new
            iterations += 1
            if step % RHO_EVERY == RHO_EVERY - 1:
                # Residual balancing keeps primal and dual progress comparable.
                primal = np.linalg.norm(x - z_new, axis=0)
                dual = rho[todo] * np.linalg.norm(z_new - z_old, axis=0)
                factor = np.where(primal > 10 * dual, 2.0, np.where(dual > 10 * primal, 0.5, 1.0))
                rho[todo] *= factor
                w[:, todo] /= factor
        signs = np.sign(z)
        for i in todo:
            pattern = signs[:, i]
            settled = np.array_equal(pattern, previous_signs[:, i])
            if not settled or (tried[i] is not None and np.array_equal(pattern, tried[i])):
                continue
            polished = _polish(gram, cross[:, i], z[:, i], lam)
            if polished is None:
                tried[i] = pattern.copy()
                continue
            coef[:, i] = polished
            done[i] = True
            # Exact primal/dual pair as the warm start for the next λ.
            z[:, i] = polished
            w[:, i] = (cross[:, i] - gram @ polished) / rho[i]
        previous_signs = signs
    for i in np.flatnonzero(~done):
        coef[:, i] = z[:, i]
    coef[:, zero] = 0.0
    z[:, zero] = 0.0
    w[:, zero] = (cross[:, zero] / rho[zero]) if zero.any() else 0.0
    info = {"iterations": iterations, "converged": bool(done.all()),
            "unconverged": np.flatnonzero(~done).tolist()}
    return coef, info


def _polish(gram: np.ndarray, c: np.ndarray, z: np.ndarray, lam: float) -> np.ndarray | None:
    """Exact LASSO solution from the support and signs of ``z``, or None.

    Starting from z's support, a few active-set corrections (drop coefficients
    whose sign flips, add the most violated inactive ones) fix a support that
    ADMM has nearly, but not exactly, found. The answer is returned only when
    it satisfies the optimality conditions, so it is exact, never approximate.
    """
    support = np.flatnonzero(z)
    signs = np.sign(z[support])
    tolerance = lam * (1.0 + KKT_RTOL)
    for _ in range(MAX_ACTIVE_SET_STEPS):
        x = np.zeros_like(z)
        if support.size:
            x_s = _reduced_solve(gram, c, support, signs, lam)
            if x_s is None:
                return None
            flipped = x_s * signs <= 0
            if flipped.any():
                support, signs = support[~flipped], signs[~flipped]
                continue
            x[support] = x_s
        gradient = c - gram @ x
        violation = np.abs(gradient) - tolerance
        violation[support] = -np.inf
        if not np.any(violation > 0):
            return x
        # Add the worst offenders (a few at a time keeps the number of steps small).
        worst = np.argsort(-violation)[:max(1, int(np.sum(violation > 0)) // 4)]
        worst = worst[violation[worst] > 0]
        support = np.concatenate([support, worst])
        signs = np.concatenate([signs, np.sign(gradient[worst])])
    return None


def _reduced_solve(gram, c, support, signs, lam):
    """Solve G_SS x_S = c_S − λ·signs; None if the system is inconsistent."""
    block = gram[np.ix_(support, support)]
    rhs = c[support] - lam * signs
    try:
        import scipy.linalg

        factor = scipy.linalg.cho_factor(block, check_finite=False)
        return scipy.linalg.cho_solve(factor, rhs, check_finite=False)
    except np.linalg.LinAlgError:
        # Duplicate columns in the support: the optimum is not unique; take
        # the minimum-norm one if the reduced system is consistent.
        x_s = np.linalg.lstsq(block, rhs, rcond=None)[0]
        if np.linalg.norm(block @ x_s - rhs) > KKT_RTOL * max(np.linalg.norm(rhs), lam):
            return None
        return x_s
