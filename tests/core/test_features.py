"""Monomial basis and ARX regressor layout against the paper, sklearn and hand-built matrices."""

from math import comb

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from sklearn.preprocessing import PolynomialFeatures

from ftcal.core.features import MonomialBasis, RegressorLayout, n_coefficients, n_monomials
from ftcal.runtime.errors import FtcalError


# --------------------------------------------------------------------------- counts
@pytest.mark.parametrize("degree, expected", [(1, 48), (2, 216), (3, 720), (4, 1980), (5, 4752)])
def test_coefficient_counts_match_paper_table_ii(degree, expected):
    assert n_coefficients(7, degree, 6) == expected
    # The basis and layout count the same thing, per output.
    layout = RegressorLayout(MonomialBasis(7, degree), n_outputs=6)
    assert 6 * layout.n_features == expected
    assert 6 * MonomialBasis(7, degree).n_terms == expected


def test_quadratic_and_cubic_counts_of_the_papers_worked_example():
    # Section II: nu = 6 gives 21 quadratic terms (not 36) and 56 cubic ones (not 216).
    assert n_monomials(6, 2) == 21
    assert n_monomials(6, 3) == 56
    degrees = MonomialBasis(6, 3).exponents.sum(axis=1)
    assert np.count_nonzero(degrees == 2) == 21
    assert np.count_nonzero(degrees == 3) == 56


def test_quadratic_pairs_are_the_papers_list():
    # Section II lists (1,1),(1,2),...,(1,6),(2,2),...,(6,6) for nu = 6.
    pairs = [(l, m) for l in range(6) for m in range(l, 6)]
    expected = np.zeros((len(pairs), 6), dtype=int)
    for row, (l, m) in enumerate(pairs):
        expected[row, l] += 1
        expected[row, m] += 1
    exps = MonomialBasis(6, 2).exponents
    np.testing.assert_array_equal(exps[6:27], expected)


@pytest.mark.parametrize("nu, ny, na, nb, degree", [
    (7, 6, 1, 0, 1), (7, 6, 2, 1, 2), (2, 3, 3, 2, 3), (1, 1, 0, 4, 2), (4, 2, 1, 3, 4),
])
def test_arx_count_follows_the_design_formula(nu, ny, na, nb, degree):
    per_output = ny * na + 1 + sum((nb + 1) * comb(nu + p - 1, p) for p in range(1, degree + 1))
    assert n_coefficients(nu, degree, ny, na, nb) == ny * per_output
    layout = RegressorLayout(MonomialBasis(nu, degree), ny, na, nb)
    assert layout.n_features == per_output
    assert len(layout.column_names([f"u{i}" for i in range(nu)], [f"y{i}" for i in range(ny)])) == per_output


@settings(max_examples=60, deadline=None)
@given(nu=st.integers(1, 9), degree=st.integers(1, 6), ny=st.integers(1, 6),
       na=st.integers(0, 4), nb=st.integers(0, 4))
def test_counts_follow_the_formula(nu, degree, ny, na, nb):
    per_output = ny * na + 1 + sum((nb + 1) * comb(nu + p - 1, p) for p in range(1, degree + 1))
    assert n_coefficients(nu, degree, ny, na, nb) == ny * per_output
    assert RegressorLayout(MonomialBasis(nu, degree), ny, na, nb).n_features == per_output


# ----------------------------------------------------------------- column order
@pytest.mark.parametrize("nu, degree", [(1, 1), (1, 5), (2, 3), (3, 4), (6, 2), (7, 3), (8, 2)])
def test_exponents_equal_sklearn_powers_with_offset_last(nu, degree):
    powers = PolynomialFeatures(degree).fit(np.zeros((1, nu))).powers_
    expected = np.roll(powers, -1, axis=0)
    np.testing.assert_array_equal(MonomialBasis(nu, degree).exponents, expected)


def test_monomial_matrix_built_by_hand_nu2_degree3():
    u = np.array([[2.0, 3.0], [-1.0, 0.5], [0.0, -2.0], [1.5, 1.5]])
    a, b = u[:, 0], u[:, 1]
    expected = np.column_stack([a, b, a * a, a * b, b * b, a**3, a * a * b, a * b * b, b**3, np.ones(4)])
    np.testing.assert_allclose(MonomialBasis(2, 3).evaluate(u), expected, rtol=1e-15)
    assert MonomialBasis(2, 3).term_names(["a", "b"]) == [
        "a", "b", "a^2", "a·b", "b^2", "a^3", "a^2·b", "a·b^2", "b^3", "1"]


@pytest.mark.parametrize("nu, degree", [(1, 4), (3, 3), (7, 2), (8, 3)])
def test_evaluate_matches_sklearn_features(rng, ref_features, nu, degree):
    u = rng.uniform(-2, 2, size=(37, nu))
    np.testing.assert_allclose(MonomialBasis(nu, degree).evaluate(u), ref_features(u, degree),
                               rtol=1e-13, atol=1e-13)


def test_evaluate_accepts_non_contiguous_input(rng, ref_features):
    u = rng.uniform(-1, 1, size=(40, 6))[::2, ::2]  # strided view, 3 columns
    np.testing.assert_allclose(MonomialBasis(3, 3).evaluate(u), ref_features(u, 3), rtol=1e-13)


def test_term_names_are_readable():
    names = MonomialBasis(3, 3).term_names(["u1", "u2", "T"])
    assert names[:3] == ["u1", "u2", "T"]
    assert "u1·T" in names and "u2^2·T" in names and "T^3" in names
    assert names[-1] == "1"
    assert len(set(names)) == len(names)
    assert MonomialBasis(2, 2).term_names() == ["x0", "x1", "x0^2", "x0·x1", "x1^2", "1"]


@settings(max_examples=40, deadline=None)
@given(nu=st.integers(1, 6), degree=st.integers(1, 4), data=st.data())
def test_permuting_inputs_permutes_exponent_rows(nu, degree, data):
    perm = data.draw(st.permutations(range(nu)))
    exps = MonomialBasis(nu, degree).exponents
    permuted = {tuple(row) for row in exps[:, perm]}
    assert permuted == {tuple(row) for row in exps}
    assert len(permuted) == len(exps)  # no duplicated monomial


@pytest.mark.parametrize("args", [(0, 2), (3, 0), (3, 11), (2.0, 2), (True, 2), (3, "2")])
def test_invalid_basis_parameters_raise(args):
    with pytest.raises(FtcalError, match="parameter of MonomialBasis"):
        MonomialBasis(*args)


def test_index_in_maps_lower_degree_terms(rng):
    low, high = MonomialBasis(4, 2), MonomialBasis(4, 4)
    idx = low.index_in(high)
    np.testing.assert_array_equal(high.exponents[idx], low.exponents)
    u = rng.uniform(-1, 1, size=(10, 4))
    np.testing.assert_allclose(high.evaluate(u)[:, idx], low.evaluate(u), rtol=1e-15)


# ------------------------------------------------------------------- ARX layout
def test_arx_column_names_in_design_order():
    layout = RegressorLayout(MonomialBasis(2, 2), n_outputs=2, na=2, nb=1)
    assert layout.column_names(["u", "v"], ["Fx", "Fy"]) == [
        "Fx(k-1)", "Fy(k-1)", "Fx(k-2)", "Fy(k-2)",
        "u", "v", "u(k-1)", "v(k-1)",
        "u^2", "u·v", "v^2", "u(k-1)^2", "u(k-1)·v(k-1)", "v(k-1)^2",
        "1",
    ]


def test_arx_exponent_rows_by_hand():
    layout = RegressorLayout(MonomialBasis(2, 2), n_outputs=2, na=2, nb=1)
    exps, lags = layout.exponent_rows()
    expected_exps = np.array([[0, 0]] * 4 + [[1, 0], [0, 1]] * 2 + [[2, 0], [1, 1], [0, 2]] * 2 + [[0, 0]])
    np.testing.assert_array_equal(exps, expected_exps)
    np.testing.assert_array_equal(lags, [-1] * 4 + [0, 0, 1, 1] + [0, 0, 0, 1, 1, 1] + [0])


def _hand_arx_rows(u, y, na, nb):
    """Rows k = max(na, nb)..n-1 for degree 2 over two inputs, the paper's column order (docs/formats.md §1)."""
    rows = []
    for k in range(max(na, nb), len(u)):
        row = [y[k - j, l] for j in range(1, na + 1) for l in range(y.shape[1])]
        row += [u[k - j, i] for j in range(nb + 1) for i in range(2)]
        for j in range(nb + 1):
            a, b = u[k - j]
            row += [a * a, a * b, b * b]
        rows.append(row + [1.0])
    return np.array(rows)


@pytest.mark.parametrize("na, nb", [(2, 1), (1, 3), (0, 2), (3, 0)])
def test_arx_segment_regressor_built_by_hand(rng, na, nb):
    u = rng.uniform(-1, 1, size=(9, 2))
    y = rng.uniform(-1, 1, size=(9, 2))
    layout = RegressorLayout(MonomialBasis(2, 2), n_outputs=2, na=na, nb=nb)
    got = layout.evaluate_segment(u, y if na else None)
    np.testing.assert_allclose(got, _hand_arx_rows(u, y, na, nb), rtol=1e-15)


def test_arx_segment_shorter_than_lag_has_no_rows(rng):
    layout = RegressorLayout(MonomialBasis(2, 1), n_outputs=1, na=3, nb=0)
    got = layout.evaluate_segment(rng.uniform(size=(3, 2)), rng.uniform(size=(3, 1)))
    assert got.shape == (0, layout.n_features)


@pytest.mark.parametrize("kwargs", [{"n_outputs": 0}, {"na": -1}, {"nb": 51}])
def test_invalid_layout_parameters_raise(kwargs):
    args = {"n_outputs": 1, **kwargs}
    with pytest.raises(FtcalError, match="parameter of RegressorLayout"):
        RegressorLayout(MonomialBasis(2, 1), **args)


@pytest.mark.parametrize("n_inputs,degree", [(1, 1), (1, 3), (7, 1), (7, 2), (7, 4), (3, 5)])
def test_combine_transposed_equals_coefficients_times_explicit_features(n_inputs, degree):
    # Reference: sklearn's PolynomialFeatures columns (offset moved last) times the coefficients.
    from sklearn.preprocessing import PolynomialFeatures

    rng = np.random.default_rng(degree)
    basis = MonomialBasis(n_inputs, degree)
    u = rng.uniform(-1.0, 1.0, (300, n_inputs))
    coef_t = rng.normal(size=(4, basis.n_terms))
    explicit = PolynomialFeatures(degree).fit_transform(u)
    explicit = np.column_stack([explicit[:, 1:], explicit[:, 0]])
    work = np.empty((basis.n_terms, 512))  # wider than the chunk, as in prediction
    got = basis.combine_transposed(np.ascontiguousarray(u.T), coef_t, work)
    np.testing.assert_allclose(got, coef_t @ explicit.T, rtol=1e-12, atol=1e-12)
