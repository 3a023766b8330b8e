"""Sufficient statistics of least-squares problems, accumulated chunk by chunk.

Fitting never builds the N × p regressor: it sums AᵀA, AᵀB, BᵀB, column sums
and column max-abs over chunks of samples, so memory is O(p²) whatever N is,
and statistics from several files, segments or validation groups just add up.

For static polynomial models AᵀA is not computed as a matrix product at all.
Each entry is a sum of a product of two monomials, i.e. a *moment*
Σ_n u_n^(e_i + e_j) of degree <= 2·degree. There are far fewer moments than
Gram entries (19,448 against 313,236 for degree 5 over 7 inputs), and each is
the product of two basis terms in exactly one way that :class:`MomentPlan`
groups into a few small matrix products. The compiled kernel (see
:mod:`ftcal.core.kernels`) computes them tile by tile in cache; without it numpy
computes the same sums chunk by chunk, about three times slower. ARX models (lagged
columns) use plain chunked AᵀA.

There is one statistics path: :class:`StatisticsAccumulator` takes raw samples,
normalizes them and adds them up, chunk by chunk. A streamed file
(:mod:`ftcal.data.streaming`) feeds it one chunk at a time; a dataset in memory
(:func:`dataset_statistics`, :meth:`ftcal.core.model.CalibrationModel.statistics`)
is the same accumulator fed one chunk, the whole dataset.
"""

from __future__ import annotations

import threading
from collections.abc import Iterable
from dataclasses import dataclass, replace
from functools import cache, cached_property

import numpy as np

from ..runtime.threads import map_ranges
from .excitation import Spread
from .features import MonomialBasis, RegressorLayout
from .kernels import compiled, step_table
from .normalization import Normalization

CHUNK_SAMPLES = 1024  # numpy kernel: terms × samples chunks of this width; more calls cost more than cache misses
# input_spread refuses inputs whose squared normalized mean exceeds this many variances: the moments' rounding
# (about 1e-16 of the mean square) would then exceed 1e-10 of the variance.
SPREAD_MAX_CANCELLATION = 1e6


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
def moment_plan(n_inputs: int, degree: int) -> "MomentPlan":
    """The :class:`MomentPlan` of ``MonomialBasis(n_inputs, degree)``, built once per process.

    Its tables cost milliseconds, which a file streamed in many chunks would
    otherwise pay per chunk.
    """
    return MomentPlan(MonomialBasis(n_inputs, degree))


class MomentPlan:
    """Which products of basis terms give every moment of a static monomial basis of degree q.

    Moments of degree <= q are the column sums of the terms. A moment of degree
    q + 1 .. 2q, its factors sorted x_i1 <= ... <= x_iD, is (its last q factors:
    a degree-q term whose first factor is some input k) times (the others: a
    term over inputs <= k), in exactly one way. So for each k one product
    L_k R_kᵀ gives those moments: L_k are the degree-q terms starting with k,
    consecutive rows of the basis, and R_k the first ``count_k`` of
    :attr:`columns`, the non-constant terms ordered by their last factor. Both
    kernels (compiled and numpy) use these tables and this moment layout.

    Attributes
    ----------
    steps : ndarray of int64, shape (n_steps, 4)
        The basis evaluation: row ``destination + r`` = row ``source + r`` times input ``i``.
    blocks : ndarray of int64, shape (n_blocks, 4)
        Per k: first row of L_k, its rows, count_k, offset of its moments (row-major).
    columns : ndarray of int64
        Basis rows of the block columns, in order.
    n_moments : int
        Column sums (one per term, the offset's counts samples) then the blocks.
    """

    def __init__(self, basis: MonomialBasis):
        self.basis = basis
        combos, q = basis.combinations, basis.degree
        self.steps = step_table(basis.n_inputs, basis.degree)
        terms = np.array([row for row, combo in enumerate(combos) if combo])
        last = np.array([combos[row][-1] for row in terms])
        order = np.argsort(last, kind="stable")
        self.columns = terms[order].astype(np.int64)
        count = np.searchsorted(last[order], np.arange(basis.n_inputs), side="right")
        blocks, offset = [], basis.n_terms
        for k in range(basis.n_inputs):
            rows = [row for row, combo in enumerate(combos) if len(combo) == q and combo[0] == k]
            blocks.append((rows[0], len(rows), count[k], offset))
            offset += len(rows) * count[k]
        self.blocks = np.array(blocks, dtype=np.int64)
        self.n_moments = offset
        self._local = threading.local()  # each thread's numpy workspace

    @cached_property
    def gram_index(self) -> np.ndarray:
        """Position in the moment vector of each Gram entry, shape (p, p)."""
        exps = self.basis.exponents
        p, base = len(exps), 2 * self.basis.degree + 1  # exponents of moments are <= 2q: no carry
        pairs = [(np.arange(p), None)] + [(np.repeat(np.arange(first, first + rows), cols),
                                          np.tile(self.columns[:cols], rows)) for first, rows, cols, _ in self.blocks]
        if float(base) ** self.basis.n_inputs < 2.0 ** 62:
            # Codes are linear in the exponents, so a moment's code is the sum of its two terms' codes.
            code = exps @ base ** np.arange(self.basis.n_inputs)
            moment_codes = np.concatenate([code[i] if j is None else code[i] + code[j] for i, j in pairs])
            entry_codes = code[:, None] + code[None, :]
        else:  # too many inputs for one int64 code: rank the exponent vectors themselves
            vectors = [exps[i] if j is None else exps[i] + exps[j] for i, j in pairs]
            entries = (exps[:, None, :] + exps[None, :, :]).reshape(p * p, -1)
            _, ranks = np.unique(np.concatenate(vectors + [entries]), axis=0, return_inverse=True)
            ranks = ranks.ravel()
            moment_codes, entry_codes = ranks[:self.n_moments], ranks[self.n_moments:].reshape(p, p)
        order = np.argsort(moment_codes)
        return order[np.searchsorted(moment_codes[order], entry_codes)]

    def new_moments(self) -> np.ndarray:
        return np.zeros(self.n_moments)

    def gram(self, moments: np.ndarray) -> np.ndarray:
        return moments[self.gram_index]

    def accumulate_compiled(self, kernels, u_norm: np.ndarray, y: np.ndarray, moments: np.ndarray,
                            cross: np.ndarray, maxabs: np.ndarray) -> None:
        """Add the statistics of samples ``u_norm`` (m, n_inputs), ``y`` (m, n_outputs) with ``kernels``."""
        kernels.accumulate(np.ascontiguousarray(u_norm, dtype=np.float64), np.ascontiguousarray(y, dtype=np.float64),
                             self.basis.n_terms, self.steps, self.blocks, self.columns, moments, cross, maxabs)

    def accumulate_numpy(self, a_t: np.ndarray, moments: np.ndarray) -> None:
        """Add the moments of the basis terms ``a_t`` (n_terms, m) of a chunk into ``moments``."""
        m = a_t.shape[1]
        workspace = getattr(self._local, "workspace", None)
        if workspace is None or workspace.shape[1] < m:
            workspace = self._local.workspace = np.empty((len(self.columns), m))
        right = np.take(a_t, self.columns, axis=0, out=workspace[:, :m])
        moments[:self.basis.n_terms] += a_t.sum(axis=1)
        for first, rows, cols, offset in self.blocks.tolist():
            block = moments[offset:offset + rows * cols].reshape(rows, cols)
            block += a_t[first:first + rows] @ right[:cols].T


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
        self._plan = moment_plan(basis.n_inputs, basis.degree)
        self._moments = self._plan.new_moments()
        self._stats = SufficientStatistics.zeros(basis.n_terms, n_outputs)

    def add(self, u_norm: np.ndarray, y: np.ndarray, chunk: int = CHUNK_SAMPLES, advance=None) -> None:
        """Add normalized inputs (m, n_inputs) and their targets (m, n_outputs).

        ``chunk``: samples per cache-sized step; ``advance``: called with each step's sample count.
        """
        basis, plan, kernels = self.basis, self._plan, compiled()

        def compiled_work(begin: int, end: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
            moments, cross, maxabs = plan.new_moments(), np.zeros((basis.n_terms, y.shape[1])), np.zeros(basis.n_terms)
            plan.accumulate_compiled(kernels, u_norm[begin:end], y[begin:end], moments, cross, maxabs)
            if advance is not None:
                advance(end - begin)
            return moments, cross, maxabs

        def work(begin: int, end: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
            moments = plan.new_moments()
            cross, maxabs = np.zeros((basis.n_terms, y.shape[1])), np.zeros(basis.n_terms)
            features = np.empty((basis.n_terms, chunk))
            for start in range(begin, end, chunk):
                stop = min(start + chunk, end)
                u_t = np.ascontiguousarray(u_norm[start:stop].T)
                a_t = basis.evaluate_transposed(u_t, features[:, :stop - start])
                plan.accumulate_numpy(a_t, moments)
                cross += a_t @ y[start:stop]
                # max and -min instead of abs(): no chunk-sized temporary.
                np.maximum(maxabs, a_t.max(axis=1), out=maxabs)
                np.maximum(maxabs, -a_t.min(axis=1), out=maxabs)
                if advance is not None:
                    advance(stop - start)
            return moments, cross, maxabs

        stats = self._stats
        kernel = compiled_work if kernels is not None else work
        for moments, cross, maxabs in map_ranges(kernel, u_norm.shape[0], chunk):
            self._moments += moments
            stats.cross += cross
            np.maximum(stats.column_maxabs, maxabs, out=stats.column_maxabs)
        stats.target_sq += np.einsum("ij,ij->j", y, y)
        stats.target_sum += y.sum(axis=0)
        stats.n_samples += u_norm.shape[0]

    def statistics(self) -> SufficientStatistics:
        """The statistics of every sample added so far."""
        return replace(self._stats, gram=self._plan.gram(self._moments), cross=self._stats.cross.copy(),
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


class StatisticsAccumulator:
    """Sufficient statistics of any layout from raw samples, added chunk by chunk: the one statistics path.

    Each chunk is normalized (``in_norm`` for the inputs, ``out_norm`` for the past outputs of
    ARX layouts) and added. Static layouts take the rows split anywhere (the moment path,
    :class:`StaticAccumulator`); ARX layouts take whole segments, so lags never cross a
    segment boundary, and keep one entry per segment in row order (:meth:`parts`): summed left
    to right, the entries of consecutive files add in the order of the rows.

    Parameters
    ----------
    layout : RegressorLayout
    in_norm : Normalization
        Maps raw inputs to the normalized inputs of the basis.
    out_norm : Normalization, optional
        Maps raw outputs to the normalized past outputs (needed by ARX layouts only).

    Examples
    --------
    >>> import numpy as np
    >>> u = np.random.default_rng(0).uniform(-1, 1, (100, 2))
    >>> y = u[:, :1] ** 2
    >>> layout, identity = RegressorLayout(MonomialBasis(2, 2), 1), Normalization.identity(2)
    >>> whole = StatisticsAccumulator(layout, identity)
    >>> whole.add(u, y)
    >>> chunked = StatisticsAccumulator(layout, identity)
    >>> for start in range(0, 100, 30):
    ...     chunked.add(u[start:start + 30], y[start:start + 30])
    >>> bool(np.allclose(whole.statistics().gram, chunked.statistics().gram, rtol=1e-13, atol=0))
    True
    """

    def __init__(self, layout: RegressorLayout, in_norm: Normalization, out_norm: Normalization | None = None):
        self.layout = layout
        self.in_norm = in_norm
        self.out_norm = out_norm
        self._static = StaticAccumulator(layout.basis, layout.n_outputs) if layout.is_static else None
        self._segments: list[SufficientStatistics] = []

    def add(self, u: np.ndarray, y: np.ndarray, segments: Iterable[tuple[int, int]] | None = None,
            advance=None) -> None:
        """Add raw inputs ``u`` (m, n_inputs) and targets ``y`` (m, n_outputs).

        Parameters
        ----------
        u, y : ndarray
        segments : iterable of (begin, end), optional
            The segments of the chunk (row ranges, whole segments); ARX layouts only, by default
            the chunk is one segment. Static layouts ignore it: their rows add up in any split.
        advance : callable, optional
            Called with sample counts as they are done (a progress bar).
        """
        u_norm = self.in_norm.apply(u)
        if self._static is not None:
            self._static.add(u_norm, y, advance=advance)
            return
        if self.out_norm is None:
            raise ValueError("An ARX layout needs out_norm, the normalization of its past outputs.")
        y_norm = self.out_norm.apply(y)
        for begin, end in ([(0, u.shape[0])] if segments is None else segments):
            self._segments.append(layout_statistics(self.layout, u_norm[begin:end], y[begin:end],
                                                    y_norm[begin:end], advance=advance))

    def parts(self) -> list[SufficientStatistics]:
        """The statistics added so far: one entry for static layouts, one per segment (row order) for ARX."""
        if self._static is not None:
            return [self._static.statistics()]
        return list(self._segments)

    def statistics(self) -> SufficientStatistics:
        """The statistics of every sample added so far (the :meth:`parts` summed left to right)."""
        parts = self.parts()
        if not parts:
            return SufficientStatistics.zeros(self.layout.n_features, self.layout.n_outputs)
        return sum_statistics(parts)


def dataset_statistics(data, layout: RegressorLayout, in_norm: Normalization, out_norm: Normalization,
                       advance=None) -> SufficientStatistics:
    """Statistics of a dataset in memory: the :class:`StatisticsAccumulator` over one chunk, the whole dataset.

    Parameters
    ----------
    data : Dataset
        With ``inputs``, ``outputs`` and ``segment_bounds()`` (ARX lags stay inside segments).
    layout : RegressorLayout
    in_norm, out_norm : Normalization
        The basis of the inputs and of the past outputs (ARX).
    advance : callable, optional
        Called with sample counts as they are done.

    Returns
    -------
    SufficientStatistics
    """
    accumulator = StatisticsAccumulator(layout, in_norm, out_norm)
    accumulator.add(data.inputs, data.outputs, None if layout.is_static else data.segment_bounds(), advance)
    return accumulator.statistics()


def input_spread(stats: SufficientStatistics, basis: MonomialBasis, normalization: Normalization) -> Spread | None:
    """The :class:`~ftcal.core.excitation.Spread` of the raw inputs, from a static model's statistics.

    The input means and centred cross-products are moments of degree ≤ 2, which the Gram of
    any static basis holds: Σ u_k (offset row × degree-1 column), Σ u_k u_l (degree-1 block),
    N (offset × offset). They are in the normalized basis ``u_norm = (u − offset) / scale``
    the statistics were taken in, where Σ (u − ū)(u − ū)ᵀ = S Σ (u_n − ū_n)(u_n − ū_n)ᵀ S.
    Subtracting N ū_n ū_nᵀ from Σ u_n u_nᵀ cancels digits as ū_n² exceeds the variance: a
    centred basis (inputs spanning [-1, 1]) keeps that within N (one sample at a range end, the
    rest at the other); a basis that does not centre may not, so beyond
    :data:`SPREAD_MAX_CANCELLATION` this returns None and the caller computes the spread
    from the data.

    Parameters
    ----------
    stats : SufficientStatistics of ``basis`` (static: the offset is the last column)
    basis : MonomialBasis, its first ``n_inputs`` columns the inputs themselves
    normalization : Normalization the statistics' inputs were normalized with

    Returns
    -------
    Spread of shape n_inputs, or None (cancellation, or no samples)

    Examples
    --------
    >>> import numpy as np
    >>> from ftcal.core.normalization import normalization_from_range
    >>> u = np.random.default_rng(0).uniform(3.0, 5.0, (200, 2))
    >>> norm = normalization_from_range(u.min(axis=0), u.max(axis=0))
    >>> stats = static_statistics(MonomialBasis(2, 2), norm.apply(u), u[:, :1])
    >>> spread = input_spread(stats, MonomialBasis(2, 2), norm)
    >>> bool(np.allclose(spread.m2, Spread.of(u).m2, rtol=1e-12, atol=0))
    True
    """
    k, n = basis.n_inputs, stats.n_samples
    if n == 0:
        return None
    sums = stats.gram[-1, :k]
    centred = stats.gram[:k, :k] - np.outer(sums, sums) / n
    centred = (centred + centred.T) / 2.0  # the moments are symmetric; their difference may round apart
    mean, squares = sums / n, np.diag(centred)
    if np.any(mean * mean * n > SPREAD_MAX_CANCELLATION * np.maximum(squares, 0.0)) or np.any(squares < 0):
        return None
    scale = normalization.scale
    return Spread(n, normalization.offset + scale * mean, centred * np.outer(scale, scale))
