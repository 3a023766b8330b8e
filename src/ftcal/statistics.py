"""Sufficient statistics of least-squares problems, accumulated chunk by chunk.

Fitting never builds the N × p regressor: it sums AᵀA, AᵀB, BᵀB, column sums
and column max-abs over chunks of samples, so memory is O(p²) whatever N is,
and statistics from several files, segments or validation groups just add up.

For static polynomial models AᵀA is not computed as a matrix product at all.
Each entry is a sum of a product of two monomials, i.e. a *moment*
Σ_n u_n^(e_i + e_j) of degree <= 2·degree. There are far fewer moments than
Gram entries (19,448 against 313,236 for degree 5 over 7 inputs), and they are
computed with small matrix products: split the inputs into a left and a right
group; every moment is (left monomial of degree d) × (right monomial of degree
<= 2·degree - d), so for each d one product L_dᵀ R_{<=2·degree-d} gives all of
them exactly once. ARX models (lagged columns) use plain chunked AᵀA.
"""

from __future__ import annotations

from collections.abc import Iterable
import threading
from dataclasses import dataclass, replace
from functools import cache, cached_property
from itertools import combinations_with_replacement

import numpy as np

from ._threads import map_ranges
from .features import MonomialBasis, MonomialEvaluator, RegressorLayout

CHUNK_SAMPLES = 1024  # terms × samples chunks of this width stay in cache


@dataclass
class SufficientStatistics:
    """Everything a least-squares / ridge / LASSO fit needs, for one regressor layout.

    Attributes
    ----------
    gram : ndarray of shape (p, p)      AᵀA
    cross : ndarray of shape (p, ny)    AᵀB
    target_sq : ndarray of shape (ny,)  column sums of B²
    target_sum : ndarray of shape (ny,) column sums of B
    column_maxabs : ndarray of shape (p,) max |A_ij| per column
    n_samples : int                     rows of A

    Statistics of disjoint row blocks add up:

    >>> import numpy as np
    >>> a, y = np.arange(12.0).reshape(6, 2), np.ones((6, 1))
    >>> total = dense_statistics(a[:2], y[:2]) + dense_statistics(a[2:], y[2:])
    >>> np.array_equal(total.gram, a.T @ a), total.n_samples
    (True, 6)
    """

    gram: np.ndarray
    cross: np.ndarray
    target_sq: np.ndarray
    target_sum: np.ndarray
    column_maxabs: np.ndarray
    n_samples: int = 0

    @classmethod
    def zeros(cls, n_features: int, n_outputs: int) -> "SufficientStatistics":
        return cls(np.zeros((n_features, n_features)), np.zeros((n_features, n_outputs)),
                   np.zeros(n_outputs), np.zeros(n_outputs), np.zeros(n_features), 0)

    def __add__(self, other: "SufficientStatistics") -> "SufficientStatistics":
        return SufficientStatistics(self.gram + other.gram, self.cross + other.cross,
                                    self.target_sq + other.target_sq,
                                    self.target_sum + other.target_sum,
                                    np.maximum(self.column_maxabs, other.column_maxabs),
                                    self.n_samples + other.n_samples)

    @property
    def n_features(self) -> int:
        return self.gram.shape[0]

    def restrict(self, columns: np.ndarray) -> "SufficientStatistics":
        """Statistics of the sub-regressor made of ``columns`` (e.g. a lower degree)."""
        return replace(self, gram=self.gram[np.ix_(columns, columns)], cross=self.cross[columns],
                       column_maxabs=self.column_maxabs[columns])


def sum_statistics(parts: Iterable[SufficientStatistics]) -> SufficientStatistics:
    """The statistics of all ``parts`` together (at least one).

    Parameters
    ----------
    parts : iterable of SufficientStatistics, same layout

    Returns
    -------
    SufficientStatistics
    """
    parts = list(parts)
    total = parts[0]
    for part in parts[1:]:
        total = total + part
    return total


@cache
def moment_gram(n_inputs: int, degree: int) -> "MomentGram":
    """The :class:`MomentGram` of ``MonomialBasis(n_inputs, degree)``, built once per process.

    Its index tables cost milliseconds, which a file streamed in many chunks
    would otherwise pay per chunk; its workspace is per thread.
    """
    return MomentGram(MonomialBasis(n_inputs, degree))


class MomentGram:
    """AᵀA of a static monomial basis from its moments, chunk by chunk (see :func:`moment_gram`)."""

    def __init__(self, basis: MonomialBasis):
        self.basis = basis
        nu, top = basis.n_inputs, 2 * basis.degree
        self.n_left = (nu + 1) // 2
        n_right = nu - self.n_left
        self._left = _GradedMonomials(self.n_left, top)
        self._right = _GradedMonomials(n_right, top)
        # Block d: left monomials of degree d times right monomials of degree <= top - d.
        self._blocks = []
        offset = 0
        for d in range(top + 1):
            rows = self._left.degree_slice(d)
            cols = self._right.up_to(top - d)
            size = (rows.stop - rows.start) * cols
            self._blocks.append((rows, cols, offset))
            offset += size
        self.n_moments = offset
        self._local = threading.local()  # each thread's (left, right) workspace

    @cached_property
    def gram_index(self) -> np.ndarray:
        """Position in the moment vector of each Gram entry, shape (p, p)."""
        exps = self.basis.exponents
        left, right = exps[:, :self.n_left], exps[:, self.n_left:]
        # Table codes are linear in the exponents (no carry below base top + 1), so the code of
        # each entry's moment, e_i + e_j, is the sum of the two terms' codes.
        left_code, right_code = self._left.code(left), self._right.code(right)
        row = self._left.at_code(left_code[:, None] + left_code[None, :])
        col = self._right.at_code(right_code[:, None] + right_code[None, :])
        degree = left.sum(axis=1)
        d = degree[:, None] + degree[None, :]
        starts = np.array([start for rows, _, start in self._blocks])
        widths = np.array([cols for _, cols, _ in self._blocks])
        firsts = np.array([rows.start for rows, _, _ in self._blocks])
        return starts[d] + (row - firsts[d]) * widths[d] + col

    def new_moments(self) -> np.ndarray:
        return np.zeros(self.n_moments)

    def accumulate(self, u_t: np.ndarray, moments: np.ndarray) -> None:
        """Add the moments of the normalized chunk ``u_t`` (nu, m) into ``moments``."""
        m = u_t.shape[1]
        workspace = getattr(self._local, "workspace", None)
        if workspace is None or workspace[0].shape[1] < m:
            workspace = self._local.workspace = (np.empty((self._left.n_terms, m)),
                                                 np.empty((self._right.n_terms, m)))
        left = self._left.evaluate(u_t[:self.n_left], workspace[0][:, :m])
        right = self._right.evaluate(u_t[self.n_left:], workspace[1][:, :m])
        for rows, cols, start in self._blocks:
            size = (rows.stop - rows.start) * cols
            block = moments[start:start + size].reshape(rows.stop - rows.start, cols)
            block += left[rows] @ right[:cols].T

    def gram(self, moments: np.ndarray) -> np.ndarray:
        return moments[self.gram_index]


class _GradedMonomials:
    """All monomials of degree 0..top in a few variables, ordered by degree (1 first)."""

    def __init__(self, n_vars: int, top: int):
        self.n_vars = n_vars
        self.top = top
        combos = [()] + [c for p in range(1, top + 1 if n_vars else 1)
                         for c in combinations_with_replacement(range(n_vars), p)]
        self._evaluator = MonomialEvaluator(n_vars, top, first_row=1)
        degrees = np.array([len(c) for c in combos])
        self._first = np.searchsorted(degrees, np.arange(top + 2))
        self.n_terms = len(combos)
        # Dense lookup from exponent vectors (mixed radix, base top+1) to rows.
        exps = np.zeros((len(combos), max(n_vars, 1)), dtype=np.intp)
        for i, c in enumerate(combos):
            for j in c:
                exps[i, j] += 1
        self._radix = (top + 1) ** np.arange(max(n_vars, 1), dtype=np.intp)
        self._table = np.full((top + 1) ** max(n_vars, 1), -1, dtype=np.intp)
        self._table[exps @ self._radix] = np.arange(len(combos))

    def degree_slice(self, d: int) -> slice:
        return slice(int(self._first[d]), int(self._first[d + 1]))

    def up_to(self, d: int) -> int:
        """How many monomials have degree <= d (they come first)."""
        return int(self._first[d + 1])

    def code(self, exponents: np.ndarray) -> np.ndarray:
        """Table code of each exponent vector (last axis); codes of sums are sums of codes."""
        if self.n_vars == 0:
            return np.zeros(exponents.shape[:-1], dtype=np.intp)
        return exponents @ self._radix

    def at_code(self, codes: np.ndarray) -> np.ndarray:
        """Row among these monomials of each table code."""
        return self._table[codes]

    def evaluate(self, u_t: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
        if out is None:
            out = np.empty((self.n_terms, u_t.shape[1]))
        out[0] = 1.0
        return self._evaluator.evaluate_transposed(u_t, out)


class StaticAccumulator:
    """Sufficient statistics of a static polynomial model, added chunk by chunk.

    Chunks add their moments, cross products and column maxima; the Gram is
    assembled from the moments once, in :meth:`statistics`. Sample ranges of a
    chunk are processed by parallel worker threads.

    Parameters
    ----------
    basis : MonomialBasis
    n_outputs : int, targets per sample
    """

    def __init__(self, basis: MonomialBasis, n_outputs: int):
        self.basis = basis
        self._engine = moment_gram(basis.n_inputs, basis.degree)
        self._moments = self._engine.new_moments()
        self._stats = SufficientStatistics.zeros(basis.n_terms, n_outputs)

    def add(self, u_norm: np.ndarray, y: np.ndarray, chunk: int = CHUNK_SAMPLES, advance=None) -> None:
        """Add normalized inputs (m, n_inputs) and their targets (m, n_outputs).

        ``chunk``: samples per cache-sized step; ``advance``: called with each step's sample count.
        """
        basis, engine = self.basis, self._engine

        def work(begin: int, end: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
            moments = engine.new_moments()
            cross, maxabs = np.zeros((basis.n_terms, y.shape[1])), np.zeros(basis.n_terms)
            features = np.empty((basis.n_terms, chunk))
            for start in range(begin, end, chunk):
                stop = min(start + chunk, end)
                u_t = np.ascontiguousarray(u_norm[start:stop].T)
                a_t = basis.evaluate_transposed(u_t, features[:, :stop - start])
                engine.accumulate(u_t, moments)
                cross += a_t @ y[start:stop]
                # max and -min instead of abs(): no chunk-sized temporary.
                np.maximum(maxabs, a_t.max(axis=1), out=maxabs)
                np.maximum(maxabs, -a_t.min(axis=1), out=maxabs)
                if advance is not None:
                    advance(stop - start)
            return moments, cross, maxabs

        stats = self._stats
        for moments, cross, maxabs in map_ranges(work, u_norm.shape[0], chunk):
            self._moments += moments
            stats.cross += cross
            np.maximum(stats.column_maxabs, maxabs, out=stats.column_maxabs)
        stats.target_sq += np.einsum("ij,ij->j", y, y)
        stats.target_sum += y.sum(axis=0)
        stats.n_samples += u_norm.shape[0]

    def statistics(self) -> SufficientStatistics:
        """The statistics of every sample added so far."""
        return replace(self._stats, gram=self._engine.gram(self._moments), cross=self._stats.cross.copy(),
                       target_sq=self._stats.target_sq.copy(), target_sum=self._stats.target_sum.copy(),
                       column_maxabs=self._stats.column_maxabs.copy())


def static_statistics(basis: MonomialBasis, u_norm: np.ndarray, y: np.ndarray,
                      chunk: int = CHUNK_SAMPLES, advance=None) -> SufficientStatistics:
    """Statistics of a static polynomial model over normalized inputs (N, nu) and targets (N, ny).

    Sample ranges are processed by parallel worker threads and their
    statistics summed.

    Parameters
    ----------
    basis : MonomialBasis
    u_norm : ndarray of shape (n_samples, n_inputs), normalized inputs
    y : ndarray of shape (n_samples, n_outputs), targets
    chunk : int, samples per chunk
    advance : callable, optional, called with each chunk's sample count

    Returns
    -------
    SufficientStatistics

    Examples
    --------
    >>> import numpy as np
    >>> u = np.random.default_rng(0).uniform(-1, 1, (50, 2))
    >>> stats = static_statistics(MonomialBasis(2, 3), u, u[:, :1])
    >>> a = MonomialBasis(2, 3).evaluate(u)
    >>> bool(np.allclose(stats.gram, a.T @ a))
    True
    """
    accumulator = StaticAccumulator(basis, y.shape[1])
    accumulator.add(u_norm, y, chunk, advance)
    return accumulator.statistics()


def dense_statistics(a: np.ndarray, y: np.ndarray) -> SufficientStatistics:
    """Statistics of an explicit regressor block.

    Parameters
    ----------
    a : ndarray of shape (m, p)
    y : ndarray of shape (m, n_outputs)

    Returns
    -------
    SufficientStatistics
    """
    return SufficientStatistics(a.T @ a, a.T @ y, np.einsum("ij,ij->j", y, y), y.sum(axis=0),
                                np.abs(a).max(axis=0) if len(a) else np.zeros(a.shape[1]),
                                a.shape[0])


def layout_statistics(layout: RegressorLayout, u_norm: np.ndarray, y: np.ndarray,
                      y_past_norm: np.ndarray | None, chunk: int = 8 * CHUNK_SAMPLES,
                      advance=None) -> SufficientStatistics:
    """Statistics of one segment for any layout (ARX included); lags stay inside the segment.

    Static layouts take the moment path; ARX layouts build regressor rows chunk
    by chunk (each chunk carries ``max_lag`` samples of history).

    Parameters
    ----------
    layout : RegressorLayout
    u_norm : ndarray of shape (n, n_inputs), normalized inputs of one segment
    y : ndarray of shape (n, n_outputs), targets
    y_past_norm : ndarray of shape (n, n_outputs) or None
        Normalized outputs entering the past-output columns (ARX).
    chunk : int
    advance : callable, optional

    Returns
    -------
    SufficientStatistics
        Of rows k = max_lag .. n − 1.
    """
    if layout.is_static:
        return static_statistics(layout.basis, u_norm, y, advance=advance)
    n, lag = u_norm.shape[0], layout.max_lag
    stats = SufficientStatistics.zeros(layout.n_features, y.shape[1])
    for start in range(lag, n, chunk):
        stop = min(start + chunk, n)
        a = layout.evaluate_segment(u_norm[start - lag:stop],
                                    None if y_past_norm is None else y_past_norm[start - lag:stop])
        stats = stats + dense_statistics(a, y[start:stop])
        if advance is not None:
            advance(stop - start)
    return stats
