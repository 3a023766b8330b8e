"""Monomial feature bases and the ARX regressor layout.

Column order follows the paper (and its XML files): for degree p = 1..np the
degree-p monomials in lexicographic combinations-with-replacement order over the
inputs, then the offset as the LAST column. With ARX orders (na, nb): first the
past outputs y_l(k-j) for j = 1..na, l = 1..ny; then for each p and each lag
j = 0..nb the degree-p monomials at lag j; then the offset.

Evaluation is fast because every monomial of degree p >= 2 is one earlier
monomial (its "parent", dropping the last factor) times one input: a degree-5
basis over 7 inputs costs one multiply per column, not five.
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from functools import cached_property
from itertools import combinations_with_replacement
from math import comb

import numpy as np

from ..runtime.checks import check_int
from .limits import MAX_DEGREE, MAX_LAG


def n_monomials(n_inputs: int, degree: int) -> int:
    """Number of monomials of exactly ``degree`` in ``n_inputs`` variables: C(nu+p-1, p)."""
    return comb(n_inputs + degree - 1, degree)


def n_coefficients(n_inputs: int, degree: int, n_outputs: int = 1, na: int = 0, nb: int = 0) -> int:
    """Coefficients of a model: ny * (ny*na + 1 + sum_p (nb+1) * C(nu+p-1, p)).

    Examples
    --------
    The paper's counts for ny = 6 outputs and nu = 7 inputs, degrees 1 to 5:

    >>> [n_coefficients(7, d, 6) for d in range(1, 6)]
    [48, 216, 720, 1980, 4752]
    """
    for name, value, low in (("n_inputs", n_inputs, 1), ("degree", degree, 0), ("n_outputs", n_outputs, 1),
                             ("na", na, 0), ("nb", nb, 0)):
        check_int(value, name, "n_coefficients", low)
    per_output = n_outputs * na + 1 + sum((nb + 1) * n_monomials(n_inputs, p)
                                          for p in range(1, degree + 1))
    return n_outputs * per_output


def combinations_by_degree(n_inputs: int, degree: int) -> list[tuple[int, ...]]:
    """Index tuples of the monomials of degree 1..degree, in the paper's order."""
    return [c for p in range(1, degree + 1)
            for c in combinations_with_replacement(range(n_inputs), p)]


class MonomialEvaluator:
    """Evaluate all monomials of degree 1..``degree`` in graded lexicographic order.

    In lexicographic combinations-with-replacement order, the degree-p
    monomials whose first factor is input i are u_i times the degree-(p-1)
    monomials over inputs >= i, and those form a contiguous tail of the
    degree-(p-1) block. So each (p, i) pair is one broadcast multiply between
    contiguous slices: no gathers and no temporaries.

    ``first_row`` is where the degree-1 block starts in the output.
    """

    def __init__(self, n_inputs: int, degree: int, first_row: int = 0):
        self.n_inputs = n_inputs
        self.degree = degree
        self.first_row = first_row
        # starts[p]: row of the first degree-p monomial.
        starts = {1: first_row}
        for p in range(2, degree + 1):
            starts[p] = starts[p - 1] + n_monomials(n_inputs, p - 1)
        self.n_rows = starts[degree] + n_monomials(n_inputs, degree) if n_inputs else first_row
        self.top_start = starts[degree]
        steps = []
        for p in range(2, degree + 1):
            dst = starts[p]
            for i in range(n_inputs):
                # Degree-(p-1) monomials over inputs i..nu-1: the last C(nu-i+p-2, p-1).
                count = n_monomials(n_inputs - i, p - 1)
                src_stop = starts[p - 1] + n_monomials(n_inputs, p - 1)
                steps.append((i, slice(src_stop - count, src_stop), slice(dst, dst + count)))
                dst += count
        self._steps = steps
        n_top = n_inputs if degree >= 2 else 0
        self.top_steps = steps[len(steps) - n_top:] if n_top else []

    def evaluate_transposed(self, u_t: np.ndarray, out: np.ndarray) -> np.ndarray:
        """Fill rows ``first_row..`` of ``out`` (rows, m) from ``u_t`` (n_inputs, m).

        Terms-by-samples layout keeps every operand a contiguous block.
        """
        return self._evaluate(u_t, out, self._steps)

    def evaluate_below_top(self, u_t: np.ndarray, out: np.ndarray) -> np.ndarray:
        """Like :meth:`evaluate_transposed` but without the highest degree's rows."""
        return self._evaluate(u_t, out, self._steps[:len(self._steps) - len(self.top_steps)])

    def _evaluate(self, u_t, out, steps):
        if self.n_inputs == 0:
            return out
        out[self.first_row:self.first_row + self.n_inputs] = u_t
        for i, src, dst in steps:
            np.multiply(out[src], u_t[i], out=out[dst])
        return out


class MonomialBasis:
    """All monomials of degree 1..``degree`` in ``n_inputs`` variables, plus an offset.

    Parameters
    ----------
    n_inputs : int >= 1
    degree : int in [1, 10]

    Examples
    --------
    >>> basis = MonomialBasis(2, 2)
    >>> basis.term_names(["a", "b"])
    ['a', 'b', 'a^2', 'a·b', 'b^2', '1']
    """

    def __init__(self, n_inputs: int, degree: int):
        self.n_inputs = check_int(n_inputs, "n_inputs", "MonomialBasis", 1)
        self.degree = check_int(degree, "degree", "MonomialBasis", 1, MAX_DEGREE)

    @cached_property
    def combinations(self) -> list[tuple[int, ...]]:
        """Index tuples of every term, offset (empty tuple) last."""
        return combinations_by_degree(self.n_inputs, self.degree) + [()]

    @property
    def n_terms(self) -> int:
        return len(self.combinations)

    @cached_property
    def exponents(self) -> np.ndarray:
        """Exponent table, shape (n_terms, n_inputs); the last row (offset) is zeros."""
        table = np.zeros((self.n_terms, self.n_inputs), dtype=np.int64)
        for row, combo in enumerate(self.combinations):
            for j in combo:
                table[row, j] += 1
        return table

    @cached_property
    def term_degrees(self) -> np.ndarray:
        return self.exponents.sum(axis=1)

    @cached_property
    def _evaluator(self) -> MonomialEvaluator:
        return MonomialEvaluator(self.n_inputs, self.degree)

    def evaluate(self, u: np.ndarray) -> np.ndarray:
        """Features of ``u`` (n_samples, n_inputs) as (n_samples, n_terms)."""
        u = np.asarray(u, dtype=np.float64)
        return self.evaluate_transposed(np.ascontiguousarray(u.T)).T

    def evaluate_transposed(self, u_t: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
        """Features as (n_terms, m) from ``u_t`` (n_inputs, m) — the fast layout."""
        if out is None:
            out = np.empty((self.n_terms, u_t.shape[1]))
        out[-1] = 1.0
        return self._evaluator.evaluate_transposed(u_t, out)

    def term_names(self, input_names: Sequence[str] | None = None) -> list[str]:
        """Readable names such as ``'u1·T'`` or ``'s0^2·s3'``; the offset is ``'1'``."""
        names = list(input_names) if input_names is not None else [f"x{j}" for j in range(self.n_inputs)]
        return [monomial_name(row, names) for row in self.exponents]

    def combine_transposed(self, u_t: np.ndarray, coef_t: np.ndarray, work: np.ndarray | None = None) -> np.ndarray:
        """``coef_t`` (k, n_terms) times the features of ``u_t`` (n_inputs, m): shape (k, m).

        See :class:`FeatureCombination`, which also reuses its buffers across chunks.
        """
        return FeatureCombination(self, coef_t, u_t.shape[1])(u_t).copy()

    def index_in(self, larger: "MonomialBasis") -> np.ndarray:
        """Positions of this basis's terms inside a basis of higher degree."""
        if larger.n_inputs != self.n_inputs or larger.degree < self.degree:
            raise ValueError("index_in needs a basis over the same inputs of at least this degree")
        position = {c: i for i, c in enumerate(larger.combinations)}
        return np.array([position[c] for c in self.combinations], dtype=np.intp)


class FeatureCombination:
    """Evaluate ``coef_t @ features(u)`` chunk by chunk, without forming the top degree.

    The highest degree's features are never formed: its terms with first
    factor u_i are u_i times a contiguous block of the degree below, so their
    share is u_i ⊙ (coefficient block @ that block). That skips most of the
    feature work (210 of 330 rows at degree 4 over 7 inputs). Coefficient
    blocks and scratch buffers are prepared once, for chunks up to ``width``.
    """

    def __init__(self, basis: "MonomialBasis", coef_t: np.ndarray, width: int):
        self._basis = basis
        self._evaluator = basis._evaluator
        k = coef_t.shape[0]
        self._below = self._evaluator.top_start if self._evaluator.top_steps else basis.n_terms - 1
        self._coef_below = np.ascontiguousarray(coef_t[:, :self._below])
        self._offset = np.ascontiguousarray(coef_t[:, -1:])
        self._top = [(i, src, np.ascontiguousarray(coef_t[:, dst])) for i, src, dst in self._evaluator.top_steps]
        self._features = np.empty((basis.n_terms, width))
        self._scratch = np.empty((k, width))
        self._result = np.empty((k, width))

    def __call__(self, u_t: np.ndarray) -> np.ndarray:
        """(k, m) for ``u_t`` (n_inputs, m <= width); a view into a reused buffer."""
        m = u_t.shape[1]
        features = self._features[:, :m]
        if self._top:
            self._evaluator.evaluate_below_top(u_t, features)
        else:
            self._evaluator.evaluate_transposed(u_t, features)
        result, scratch = self._result[:, :m], self._scratch[:, :m]
        np.matmul(self._coef_below, features[:self._below], out=result)
        result += self._offset
        for i, src, block in self._top:
            np.matmul(block, features[src], out=scratch)
            np.multiply(scratch, u_t[i], out=scratch)
            np.add(result, scratch, out=result)
        return result


def monomial_name(exponents: Sequence[int], names: Sequence[str]) -> str:
    """``[2, 0, 1] , ['a','b','c'] -> 'a^2·c'``; all zeros -> ``'1'``."""
    parts = [n if e == 1 else f"{n}^{e}" for n, e in zip(names, exponents) if e]
    return "·".join(parts) if parts else "1"


class RegressorLayout:
    """Columns of the (possibly ARX) regressor for one output, in the paper's order.

    Parameters
    ----------
    basis : MonomialBasis over the inputs
    n_outputs : int, number of outputs ny (used by the past-output columns)
    na : past outputs y(k-1) .. y(k-na)
    nb : input lags; monomials are evaluated at lags 0..nb

    Examples
    --------
    The paper's degree-4 model over 6 channels and temperature: 1980 coefficients over 6 outputs.

    >>> RegressorLayout(MonomialBasis(7, 4), n_outputs=6).n_features
    330
    """

    def __init__(self, basis: MonomialBasis, n_outputs: int, na: int = 0, nb: int = 0):
        self.basis = basis
        self.n_outputs = check_int(n_outputs, "n_outputs", "RegressorLayout", 1)
        self.na = check_int(na, "na", "RegressorLayout", 0, MAX_LAG)
        self.nb = check_int(nb, "nb", "RegressorLayout", 0, MAX_LAG)

    @property
    def is_static(self) -> bool:
        return self.na == 0 and self.nb == 0

    @property
    def max_lag(self) -> int:
        return max(self.na, self.nb)

    @property
    def n_past_outputs(self) -> int:
        return self.n_outputs * self.na

    @property
    def n_features(self) -> int:
        return self.n_past_outputs + (self.nb + 1) * (self.basis.n_terms - 1) + 1

    @cached_property
    def _lag_blocks(self) -> list[tuple[int, np.ndarray, np.ndarray]]:
        """(lag j, target columns, basis term indices) per (degree, lag) block."""
        degrees = self.basis.term_degrees[:-1]
        blocks = []
        column = self.n_past_outputs
        for p in range(1, self.basis.degree + 1):
            terms = np.flatnonzero(degrees == p)
            for j in range(self.nb + 1):
                blocks.append((j, np.arange(column, column + len(terms)), terms))
                column += len(terms)
        return blocks

    def column_names(self, input_names: Sequence[str], output_names: Sequence[str]) -> list[str]:
        """Readable names: ``'Fx(k-1)'``, ``'u1·T'`` (lag 0) or ``'u1(k-2)·T(k-2)'``, ``'1'``."""
        names = [f"{output_names[l]}(k-{j})" for j in range(1, self.na + 1)
                 for l in range(self.n_outputs)]
        names += [""] * (self.n_features - len(names))
        exps = self.basis.exponents
        for j, cols, terms in self._lag_blocks:
            lagged = list(input_names) if j == 0 else [f"{n}(k-{j})" for n in input_names]
            for c, t in zip(cols, terms):
                names[c] = monomial_name(exps[t], lagged)
        names[-1] = "1"
        return names

    def exponent_rows(self) -> tuple[np.ndarray, np.ndarray]:
        """Per column: input exponents (n_features, nu) and lag (n_features,); -1 lag marks past outputs."""
        exps = np.zeros((self.n_features, self.basis.n_inputs), dtype=np.int64)
        lags = np.full(self.n_features, -1, dtype=np.int64)
        for j, cols, terms in self._lag_blocks:
            exps[cols] = self.basis.exponents[terms]
            lags[cols] = j
        lags[-1] = 0
        return exps, lags

    def index_in(self, larger: "RegressorLayout") -> np.ndarray:
        """Columns of ``larger`` (same inputs, outputs and lags, at least this degree) holding each of ours.

        Examples
        --------
        >>> RegressorLayout(MonomialBasis(2, 1), 1).index_in(RegressorLayout(MonomialBasis(2, 2), 1)).tolist()
        [0, 1, 5]
        """
        if (larger.n_outputs, larger.na, larger.nb) != (self.n_outputs, self.na, self.nb):
            raise ValueError("index_in needs a layout with the same outputs and lags")
        exps_s, lags_s = self.exponent_rows()
        exps_l, lags_l = larger.exponent_rows()
        index = {(int(lag), tuple(e)): c for c, (e, lag) in enumerate(zip(exps_l.tolist(), lags_l)) if lag >= 0}
        rows = [index[(int(lag), tuple(e))] if lag >= 0 else c
                for c, (e, lag) in enumerate(zip(exps_s.tolist(), lags_s))]
        rows[-1] = larger.n_features - 1
        return np.array(rows, dtype=np.intp)

    def evaluate_segment(self, u_norm: np.ndarray, y_past_norm: np.ndarray | None) -> np.ndarray:
        """Regressor rows k = max_lag .. n-1 of one segment, shape (n - max_lag, n_features).

        ``u_norm`` (n, nu) are normalized inputs; ``y_past_norm`` (n, ny) the
        normalized outputs whose past values enter the regressor (None if na = 0).
        Rows whose lags would reach before the segment start are dropped, so lags
        never cross segment boundaries.
        """
        n = u_norm.shape[0]
        start = self.max_lag
        m = max(n - start, 0)
        out = np.empty((self.n_features, m))
        if m == 0:
            return out.T
        monomials = self.basis.evaluate_transposed(np.ascontiguousarray(u_norm.T))
        for j, cols, terms in self._lag_blocks:
            out[cols] = monomials[terms, start - j:n - j]
        for j in range(1, self.na + 1):
            block = slice((j - 1) * self.n_outputs, j * self.n_outputs)
            out[block] = y_past_norm[start - j:n - j].T
        out[-1] = 1.0
        return out.T


class Substitution:
    """A sparse square matrix as (row, column, value) triples, applied with ``@`` by numpy alone.

    ``T @ x`` adds ``value * x[column]`` into ``row`` in the triples' order: one sequential sum
    per entry, the same on every CPU, and no SciPy import for the light commands (``ftcal info``).
    """

    def __init__(self, rows, cols, values, n: int):
        self.rows, self.cols = np.asarray(rows, dtype=np.intp), np.asarray(cols, dtype=np.intp)
        self.values, self.shape = np.asarray(values, dtype=float), (n, n)

    def __matmul__(self, x):
        x = np.asarray(x, dtype=float)
        out = np.zeros((self.shape[0],) + x.shape[1:])
        terms = self.values.reshape((-1,) + (1,) * (x.ndim - 1)) * x[self.cols]
        np.add.at(out, self.rows, terms)
        return out

    def toarray(self) -> np.ndarray:
        return self @ np.eye(self.shape[1])


def substitution_matrix(layout: RegressorLayout, in_offset: np.ndarray, in_scale: np.ndarray,
                        out_offset: np.ndarray, out_scale: np.ndarray) -> Substitution:
    """Sparse T (n_features, n_features) with ``coef_v = T @ coef_z`` for ``z = (v − offset) / scale``.

    ``coef_z`` multiplies the layout's columns evaluated at ``z`` (inputs with
    ``in_*``, past outputs with ``out_*``); ``coef_v`` gives the same
    polynomial in ``v``.
    """
    exps, lags = layout.exponent_rows()
    n = layout.n_features
    offset_col = n - 1
    column_of = {(int(lag), tuple(e)): c for c, (e, lag) in enumerate(zip(exps.tolist(), lags))
                 if lag >= 0 and c != offset_col}
    rows, cols, values = [offset_col], [offset_col], [1.0]
    ny = layout.n_outputs
    for c in range(layout.n_past_outputs):
        l = c % ny
        rows += [c, offset_col]
        cols += [c, c]
        values += [1.0 / out_scale[l], -out_offset[l] / out_scale[l]]
    for c in range(layout.n_past_outputs, offset_col):
        e = exps[c]
        used = np.flatnonzero(e)
        for ks in itertools.product(*(range(e[i] + 1) for i in used)):
            factor = 1.0
            k = np.zeros_like(e)
            for i, ki in zip(used, ks):
                factor *= comb(int(e[i]), ki) * (-in_offset[i]) ** int(e[i] - ki) / in_scale[i] ** int(e[i])
                k[i] = ki
            rows.append(column_of[(int(lags[c]), tuple(k.tolist()))] if any(ks) else offset_col)
            cols.append(c)
            values.append(factor)
    return Substitution(rows, cols, values, n)  # duplicate (row, col) pairs add up
