"""Normalized ↔ raw-input coefficients: hand expansions, properties, precision loss."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ftcal.core.conversion import affine_part, from_raw, precision_loss, to_raw
from ftcal.core.dataset import Dataset
from ftcal.core.features import MonomialBasis, RegressorLayout
from ftcal.core.model import model_from_fitted
from ftcal.core.normalization import Normalization
from ftcal.runtime.errors import FtcalError, PrecisionLossWarning


def make_model(coef, degree, in_offset, in_scale, *, na=0, nb=0, out_offset=None, out_scale=None,
               input_range=None, output_range=None):
    coef = np.asarray(coef, dtype=float)
    if coef.ndim == 1:
        coef = coef[:, None]
    nu, ny = len(in_offset), coef.shape[1]
    in_offset, in_scale = np.asarray(in_offset, float), np.asarray(in_scale, float)
    out_offset = np.zeros(ny) if out_offset is None else np.asarray(out_offset, float)
    out_scale = np.ones(ny) if out_scale is None else np.asarray(out_scale, float)
    return model_from_fitted(
        degree=degree, na=na, nb=nb, normalization="center", coef=coef,
        input_normalization=Normalization(in_offset, in_scale),
        output_normalization=Normalization(out_offset, out_scale),
        input_names=[f"u{i + 1}" for i in range(nu)], output_names=[f"y{i + 1}" for i in range(ny)],
        input_range=np.c_[in_offset - in_scale, in_offset + in_scale] if input_range is None else input_range,
        output_range=np.tile([-1.0, 1.0], (ny, 1)) if output_range is None else output_range)


def raw_polynomial(layout, raw, u):
    """Evaluate raw monomials one sample and one term at a time (static layouts)."""
    exps, _ = layout.exponent_rows()
    return np.array([[sum(raw[c, o] * np.prod([ui ** int(e) for ui, e in zip(point, exps[c])])
                          for c in range(len(exps))) for o in range(raw.shape[1])] for point in u])


def test_one_input_degree_two_by_hand():
    # a·x + b·x² + c with x = (u − 3)/2:
    #   u: a/2 − 6b/4,  u²: b/4,  1: c − 3a/2 + 9b/4.
    a, b, c = 1.5, -0.5, 4.0
    raw = to_raw(make_model([a, b, c], 2, [3.0], [2.0]))
    np.testing.assert_allclose(raw[:, 0], [0.75 + 0.75, -0.125, 4.0 - 2.25 - 1.125], rtol=1e-15)


def test_cross_term_by_hand():
    # x1·x2 = (u1 u2 − o2 u1 − o1 u2 + o1 o2) / (s1 s2), o = (1, −2), s = (2, 4): s1 s2 = 8.
    # Columns: u1, u2, u1², u1·u2, u2², 1.
    raw = to_raw(make_model([0, 0, 0, 1.0, 0, 0], 2, [1.0, -2.0], [2.0, 4.0]))
    np.testing.assert_allclose(raw[:, 0], [2 / 8, -1 / 8, 0, 1 / 8, 0, -2 / 8], rtol=1e-15)


def test_arx_columns_by_hand():
    # Columns y(k−1), u(k), u(k−1), 1 with x = (u − 2)/4 and ỹ = (y − 10)/5:
    #   y(k−1): p/5,  u: a0/4,  u(k−1): a1/4,  1: c − 10p/5 − 2a0/4 − 2a1/4.
    p, a0, a1, c = 0.5, 2.0, -1.0, 3.0
    model = make_model([p, a0, a1, c], 1, [2.0], [4.0], na=1, nb=1, out_offset=[10.0], out_scale=[5.0])
    np.testing.assert_allclose(to_raw(model)[:, 0], [0.1, 0.5, -0.25, 3.0 - 1.0 - 1.0 + 0.5], rtol=1e-15)


def test_from_raw_identity_keeps_coefficients_and_never_warns_out_of_range():
    raw = np.array([[2.0], [-1.0], [0.5]])
    model = from_raw(raw, degree=2, input_names=["u"], output_names=["y"])
    np.testing.assert_array_equal(model.coef_, raw)
    # 2u − u² + 0.5 at u = 3 and at a far point: 6 − 9 + 0.5 and 2e6 − 1e12 + 0.5.
    np.testing.assert_allclose(model.predict(np.array([[3.0], [1e6]]))[:, 0], [-2.5, 2e6 - 1e12 + 0.5])


@st.composite
def random_models(draw):
    nu = draw(st.integers(1, 3))
    ny = draw(st.integers(1, 2))
    degree = draw(st.integers(1, 3))
    na, nb = draw(st.sampled_from([(0, 0), (0, 0), (1, 0), (1, 1), (0, 2)]))
    seed = draw(st.integers(0, 2 ** 32 - 1))
    rng = np.random.default_rng(seed)
    layout = RegressorLayout(MonomialBasis(nu, degree), ny, na, nb)
    return make_model(rng.normal(size=(layout.n_features, ny)), degree,
                      rng.uniform(-5, 5, nu), rng.uniform(0.5, 5, nu), na=na, nb=nb,
                      out_offset=rng.uniform(-5, 5, ny), out_scale=rng.uniform(0.5, 5, ny)), rng


@settings(max_examples=40, deadline=None)
@given(random_models())
def test_raw_form_predicts_like_the_model(case):
    model, rng = case
    layout = model.layout_
    raw = to_raw(model)
    lo, hi = model.input_range_[:, 0], model.input_range_[:, 1]
    u = rng.uniform(lo, hi, (12, lo.size))
    if layout.is_static:
        expected = model.predict(u)
        np.testing.assert_allclose(raw_polynomial(layout, raw, u), expected, rtol=1e-9, atol=1e-9)
    else:
        # One step ahead by hand: row k from u(k−j) and y(k−j), straight from the raw columns.
        y = rng.uniform(-3, 3, (12, model.coef_.shape[1]))
        exps, lags = layout.exponent_rows()
        native = model.predict(Dataset.from_arrays(u, y, input_names=model.input_names_,
                                                   output_names=model.output_names_), mode="one-step")
        ny = y.shape[1]
        for k in range(layout.max_lag, 12):
            features = [y[k - 1 - c // ny, c % ny] if lags[c] < 0 else np.prod(u[k - lags[c]] ** exps[c])
                        for c in range(layout.n_features)]
            np.testing.assert_allclose(np.asarray(features) @ raw, native[k], rtol=1e-9, atol=1e-9)


@settings(max_examples=40, deadline=None)
@given(random_models())
def test_raw_to_normalized_round_trip(case):
    model, _ = case
    back = from_raw(to_raw(model), degree=model.degree, na=model.na, nb=model.nb,
                    input_names=model.input_names_, output_names=model.output_names_,
                    input_normalization=model.input_normalization_,
                    output_normalization=model.output_normalization_)
    np.testing.assert_allclose(back.coef_, model.coef_, rtol=1e-9, atol=1e-9 * np.abs(model.coef_).max())


@settings(max_examples=30, deadline=None)
@given(st.integers(2, 3), st.integers(1, 3), st.integers(0, 2 ** 32 - 1))
def test_permuting_inputs_permutes_exponents(nu, degree, seed):
    rng = np.random.default_rng(seed)
    perm = rng.permutation(nu)
    basis = MonomialBasis(nu, degree)
    exps = [tuple(e) for e in basis.exponents.tolist()]
    coef = rng.normal(size=(basis.n_terms, 1))
    offset, scale = rng.uniform(-3, 3, nu), rng.uniform(0.5, 3, nu)
    # The permuted model's input i is the original input perm[i]; so its monomial e' is the
    # original monomial with e[perm[i]] = e'[i].
    column = {e: c for c, e in enumerate(exps)}
    permuted_coef = np.array([coef[column[_unpermute(e, perm)]] for e in exps])
    raw = to_raw(make_model(coef, degree, offset, scale))
    raw_permuted = to_raw(make_model(permuted_coef, degree, offset[perm], scale[perm]))
    for c, e in enumerate(exps):
        np.testing.assert_allclose(raw_permuted[c], raw[column[_unpermute(e, perm)]], rtol=1e-12, atol=1e-12)


def _unpermute(e, perm):
    original = [0] * len(e)
    for i, p in enumerate(perm):
        original[p] = e[i]
    return tuple(original)


def test_precision_loss_small_for_a_well_scaled_model():
    model = make_model([1.0, 2.0, -1.0, 0.5, 0.25, 3.0], 2, [10.0, -4.0], [2.0, 1.0])
    assert precision_loss(model, to_raw(model)) < 1e-12


def test_precision_loss_warns_when_raw_monomials_cancel():
    # x⁵ with x = (u − 1e5)/1: raw terms near 1e25 must cancel to values of size 1.
    coef = np.zeros(6)
    coef[4] = 1.0
    model = make_model(coef, 5, [1e5], [1.0])
    with pytest.warns(PrecisionLossWarning, match="y1"):
        loss = precision_loss(model, to_raw(model))
    assert loss > 1e-3


def test_precision_loss_uses_one_step_prediction_for_arx():
    model = make_model([0.5, 2.0, -1.0, 3.0], 1, [2.0], [4.0], na=1, nb=1,
                       out_offset=[10.0], out_scale=[5.0], output_range=np.array([[5.0, 15.0]]))
    assert precision_loss(model, to_raw(model)) < 1e-12
    wrong = to_raw(model)
    wrong[0] *= 1.1  # a past-output coefficient that the static part alone would not reveal
    with pytest.warns(PrecisionLossWarning):
        precision_loss(model, wrong)


def test_affine_part_names_the_offending_term():
    # u1, u2, u1², u1·u2, u2², 1: a nonzero quadratic term is refused by name.
    model = make_model([1.0, 2.0, 0.0, 0.5, 0.0, 1.0], 2, [0.0, 0.0], [1.0, 1.0])
    with pytest.raises(FtcalError, match=r"'u1·u2'"):
        affine_part(model, 2, "The export")
    affine = make_model([1.0, 2.0, 0.0, 0.0, 0.0, 1.0], 2, [1.0, 3.0], [2.0, 4.0])
    matrix, offset = affine_part(affine, 2, "The export")
    # x1 + 2 x2 + 1 = u1/2 + u2/2 + (1 − 1/2 − 6/4).
    np.testing.assert_allclose(matrix, [[0.5, 0.5]])
    np.testing.assert_allclose(offset, [-1.0])


def test_precision_loss_includes_the_box_corners():
    # An error δ on the u1·u2·u3 coefficient changes predictions by δ·|u1 u2 u3|, which
    # reaches δ only at the corners of the [−1, 1]³ training box.
    model = make_model(np.zeros(20), 3, [0.0, 0.0, 0.0], [1.0, 1.0, 1.0])
    exps, _ = model.layout_.exponent_rows()
    column = [c for c, e in enumerate(exps.tolist()) if e == [1, 1, 1]][0]
    wrong = to_raw(model)
    wrong[column] = 1e-9
    assert precision_loss(model, wrong) == pytest.approx(1e-9, rel=1e-6)
