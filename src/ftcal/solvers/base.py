"""What every solver returns, and the column scaling they share.

Solvers work on :class:`~ftcal.statistics.SufficientStatistics` whose columns
are scaled by their max |value| (the paper's feature normalization), so that a
LASSO or ridge weight means the same whatever the raw units are. The
coefficients they return multiply those *scaled* columns; the model folds the
scale back in.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.linalg
import scipy.linalg.lapack

from .._threads import single_threaded_blas
from ..statistics import SufficientStatistics


@dataclass
class SolverResult:
    """Coefficients (p, ny) for the max-abs scaled columns, and diagnostics."""

    coef: np.ndarray
    rank: int
    condition_number: float
    info: dict = field(default_factory=dict)


@dataclass(frozen=True)
class ScaledProblem:
    """The normal equations of the column-scaled problem: G x = c."""

    gram: np.ndarray
    cross: np.ndarray
    target_sq: np.ndarray
    column_scale: np.ndarray  # the max |A_ij| each column was divided by
    n_samples: int

    @classmethod
    def from_statistics(cls, stats: SufficientStatistics) -> "ScaledProblem":
        scale = np.where(stats.column_maxabs > 0, stats.column_maxabs, 1.0)
        inv = 1.0 / scale
        return cls(stats.gram * inv[:, None] * inv[None, :], stats.cross * inv[:, None],
                   stats.target_sq, scale, stats.n_samples)

    @property
    def n_features(self) -> int:
        return self.gram.shape[0]


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
        smallest = max(self.values[0], 0.0)
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


@dataclass(frozen=True)
class Conditioning:
    """Rank and condition of a Gram matrix, cheaply when it is well posed.

    A Cholesky factorization of the equilibrated Gram plus LAPACK's condition
    estimate costs a few percent of an eigen-decomposition; only when that
    shows (near) rank deficiency is the full :class:`Spectrum` computed.
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
        with single_threaded_blas():
            return cls._of(gram)

    @classmethod
    def _of(cls, gram: np.ndarray) -> "Conditioning":
        p = gram.shape[0]
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
        factor, jacobi = self.cholesky
        z = scipy.linalg.cho_solve((factor, True), rhs * jacobi[:, None], check_finite=False)
        return z * jacobi[:, None]
