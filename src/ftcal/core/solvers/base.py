"""The solver contract, what every solver returns, and the column scaling they share.

Solvers work on a :class:`ScaledProblem`: the normal equations of the regressor
whose columns are scaled by their max |value| (the paper's feature
normalization), so that a LASSO or ridge weight means the same whatever the raw
units are. The coefficients they return multiply those *scaled* columns; the
model folds the scale back in. A solver that needs the samples themselves (the
paper's OSQP programs) asks the problem for its dense regressor.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Protocol, runtime_checkable

import numpy as np

from ...runtime.errors import FtcalError
from ...runtime.threads import single_threaded_blas
from ..precision import settle
from ..statistics import SufficientStatistics


@dataclass
class SolverResult:
    """Coefficients for the max-abs scaled columns, and diagnostics.

    Attributes
    ----------
    coef : ndarray of shape (n_features, n_outputs)
    rank : int
        Numerical rank of the scaled regressor.
    condition_number : float
        Of the equilibrated regressor (NaN when the solver does not compute it).
    info : dict
        Solver details for the model file: ``"lambda"`` for penalized solvers,
        iteration counts, nonzero counts.
    """

    coef: np.ndarray
    rank: int
    condition_number: float
    info: dict = field(default_factory=dict)


@dataclass(frozen=True)
class ScaledProblem:
    """The normal equations G x = c of the column-scaled problem.

    Attributes
    ----------
    gram : ndarray of shape (p, p)
        AᵀA of the scaled regressor A (each column divided by ``column_scale``).
    cross : ndarray of shape (p, n_outputs)
        AᵀB.
    target_sq : ndarray of shape (n_outputs,)
        Column sums of B².
    column_scale : ndarray of shape (p,)
        The max |A_ij| each raw column was divided by (1 for all-zero columns).
    n_samples : int
        Rows of A.
    dense : callable, optional
        Returns the unscaled regressor rows (n_samples, p) and targets
        (n_samples, n_outputs), for solvers that need the samples themselves.

    Examples
    --------
    >>> import numpy as np
    >>> from ftcal.core.statistics import dense_statistics
    >>> a = np.array([[1.0, 1.0], [2.0, 1.0], [4.0, 1.0]])
    >>> problem = ScaledProblem.from_statistics(dense_statistics(a, np.ones((3, 1))))
    >>> problem.column_scale.tolist()
    [4.0, 1.0]
    """

    gram: np.ndarray
    cross: np.ndarray
    target_sq: np.ndarray
    column_scale: np.ndarray
    n_samples: int
    dense: Callable[[], tuple[np.ndarray, np.ndarray]] | None = None

    @classmethod
    def from_statistics(cls, stats: SufficientStatistics,
                        dense: Callable[[], tuple[np.ndarray, np.ndarray]] | None = None) -> "ScaledProblem":
        """The scaled problem of ``stats``; ``dense`` optionally gives the samples (see the class)."""
        scale = np.where(stats.column_maxabs > 0, stats.column_maxabs, 1.0)
        inv = 1.0 / scale
        return cls(stats.gram * inv[:, None] * inv[None, :], stats.cross * inv[:, None],
                   stats.target_sq, scale, stats.n_samples, dense)

    @property
    def n_features(self) -> int:
        return self.gram.shape[0]

    def scaled_regressor(self) -> tuple[np.ndarray, np.ndarray]:
        """The dense scaled regressor (n_samples, p) and targets (n_samples, n_outputs).

        Raises
        ------
        FtcalError
            When the problem was built from statistics alone.
        """
        if self.dense is None:
            raise FtcalError("This solver needs the samples, but the problem was built from "
                             "statistics alone; use a streaming solver (lstsq, ridge, lasso).")
        a, targets = self.dense()
        return a / self.column_scale, targets

    def shifted(self, prior: np.ndarray) -> "ScaledProblem":
        """The problem in δ = x − ``prior`` (p, n_outputs): c becomes c − G·prior.

        A penalty on δ shrinks toward ``prior`` instead of toward zero.
        """
        residual_sq = self.target_sq - 2 * np.einsum("ij,ij->j", prior, self.cross) \
            + np.einsum("ij,ij->j", prior, self.gram @ prior)
        dense = None
        if self.dense is not None:
            source, scale = self.dense, self.column_scale

            def dense():
                a, targets = source()
                return a, targets - (a / scale) @ prior
        return ScaledProblem(self.gram, self.cross - self.gram @ prior, residual_sq, self.column_scale,
                             self.n_samples, dense)


@runtime_checkable
class Solver(Protocol):
    """What the model asks of a solver: one name, one penalty kind, one method.

    Attributes
    ----------
    name : str
        Recorded in model files (``"lstsq"``, ``"ridge"``, ``"lasso"``, ``"osqp"``...).
    penalty : str
        One of :data:`ftcal.core.limits.PENALTIES`. Least squares does not depend on
        the basis, so the model solves ``"none"`` problems in its best-conditioned
        basis; a penalty is defined on the columns of the model's own basis.
    """

    name: str
    penalty: str

    def fit(self, problem: ScaledProblem) -> SolverResult:
        """Coefficients for ``problem``'s scaled columns; penalized solvers put their λ in ``info["lambda"]``."""
        ...


@dataclass(frozen=True)
class Spectrum:
    """Eigen-decomposition of a symmetric Gram matrix after Jacobi equilibration.

    Equilibrating (unit diagonal) first makes the eigenvalues a fair measure of
    collinearity rather than of column magnitudes.
    """

    values: np.ndarray
    vectors: np.ndarray
    jacobi: np.ndarray  # 1 / sqrt(diag G)

    @classmethod
    def of(cls, gram: np.ndarray) -> "Spectrum":
        diag = np.diag(gram).copy()
        jacobi = 1.0 / np.sqrt(np.where(diag > 0, diag, 1.0))
        values, vectors = np.linalg.eigh(gram * jacobi[:, None] * jacobi[None, :])
        return cls(values, vectors, jacobi)

    def rank_threshold(self) -> float:
        # The Gram entries carry relative rounding ~eps·p, so eigenvalues below
        # that fraction of the largest are indistinguishable from zero.
        return self.values[-1] * np.finfo(float).eps * max(self.values.size, 10) * 10

    @property
    def rank(self) -> int:
        return int(np.sum(self.values > self.rank_threshold()))

    @property
    def condition_number(self) -> float:
        """Condition number of the equilibrated regressor A (square root of the Gram's)."""
        # The eigenvalues are known to the rank threshold: the smallest stated to it (core.precision's rule),
        # so a rank-deficient Gram's condition is inf on every machine, not its rounding noise.
        top = self.values[-1]
        smallest = settle(self.values[0], self.rank_threshold() / top, top) if top > 0 else 0.0
        return float(np.sqrt(self.values[-1] / smallest)) if smallest > 0 else float("inf")

    def solve(self, rhs: np.ndarray) -> np.ndarray:
        """Minimum-norm solution of G x = rhs (in the equilibrated metric).

        Eigenvalues under the rank threshold are dropped, like ``lstsq``'s ``rcond``.
        """
        keep = self.values > self.rank_threshold()
        inverse = np.where(keep, 1.0 / np.where(keep, self.values, 1.0), 0.0)
        z = self.vectors.T @ (rhs * self.jacobi[:, None])
        return self.jacobi[:, None] * (self.vectors @ (inverse[:, None] * z))


# Gram matrices up to this size are factorized single-threaded (milliseconds either way).
SMALL_GRAM = 1000
# Up to this size the whole spectrum (numpy's eigh, under 30 ms) is cheaper than importing
# SciPy for a Cholesky factorization (~0.15 s), and it gives the exact condition number.
SPECTRUM_MAX = 500


@dataclass(frozen=True)
class Conditioning:
    """Rank and condition of a Gram matrix, cheaply when it is well posed.

    Small Grams (p <= ``SPECTRUM_MAX``) are eigen-decomposed outright. For larger
    ones a Cholesky factorization of the equilibrated Gram plus LAPACK's
    condition estimate costs a few percent of an eigen-decomposition; only when
    that shows (near) rank deficiency is the full :class:`Spectrum` computed.
    """

    rank: int
    condition_number: float
    cholesky: tuple | None  # (factor, jacobi) when the Gram is safely positive definite
    spectrum: Spectrum | None

    @classmethod
    def of(cls, gram: np.ndarray) -> "Conditioning":
        if gram.shape[0] > SMALL_GRAM:
            return cls._of(gram)
        # Small: one thread is as fast, and waking BLAS's thread pool costs ~0.3 s on a first call.
        with single_threaded_blas(scipy=gram.shape[0] > SPECTRUM_MAX):  # SciPy's Cholesky above SPECTRUM_MAX
            return cls._of(gram)

    @classmethod
    def _of(cls, gram: np.ndarray) -> "Conditioning":
        p = gram.shape[0]
        if p > SPECTRUM_MAX:
            import scipy.linalg.lapack

            diag = np.diag(gram).copy()
            jacobi = 1.0 / np.sqrt(np.where(diag > 0, diag, 1.0))
            equilibrated = gram * jacobi[:, None] * jacobi[None, :]
            factor, info = scipy.linalg.lapack.dpotrf(equilibrated, lower=1, clean=1)
            if info == 0:
                anorm = np.abs(equilibrated).sum(axis=0).max()
                rcond, info = scipy.linalg.lapack.dpocon(factor, anorm, uplo="L")
                # Same threshold as Spectrum.rank_threshold, on the reciprocal condition.
                if info == 0 and rcond > np.finfo(float).eps * max(p, 10) * 10:
                    return cls(p, float(np.sqrt(1.0 / rcond)), (factor, jacobi), None)
        spectrum = Spectrum.of(gram)
        return cls(spectrum.rank, spectrum.condition_number, None, spectrum)

    def solve(self, rhs: np.ndarray) -> np.ndarray:
        """(Minimum-norm) solution of G x = rhs."""
        if self.cholesky is None:
            return self.spectrum.solve(rhs)
        import scipy.linalg

        factor, jacobi = self.cholesky
        z = scipy.linalg.cho_solve((factor, True), rhs * jacobi[:, None], check_finite=False)
        return z * jacobi[:, None]
