"""Solvers against numpy.linalg.lstsq, scikit-learn Ridge/Lasso and OSQP."""

import warnings

import numpy as np
import pytest
from sklearn.linear_model import Lasso as SklearnLasso
from sklearn.linear_model import Ridge as SklearnRidge

from ftcal.core.dataset import Dataset
from ftcal.core.model import CalibrationModel
from ftcal.core.solvers.base import ScaledProblem, Spectrum
from ftcal.core.solvers.lasso import Lasso
from ftcal.core.solvers.least_squares import LeastSquares, Ridge
from ftcal.core.solvers.osqp_qp import OsqpLasso, OsqpLeastSquares
from ftcal.core.statistics import dense_statistics
from ftcal.runtime.errors import FtcalError, IllPosedFitWarning


def _problem(rng, n=200, p=12, ny=2, noise=0.3):
    """A regressor with columns of very different scales (last one the offset)."""
    a = rng.standard_normal((n, p)) * np.geomspace(0.01, 100, p)
    a[:, -1] = 1.0
    x = rng.standard_normal((p, ny))
    x[::3] = 0.0
    b = a @ x + noise * rng.standard_normal((n, ny))
    return a, b


def _scaled(a):
    return a / np.abs(a).max(axis=0)


def _lasso_objective(a, b, coef, lam):
    return 0.5 * ((a @ coef - b) ** 2).sum(axis=0) + lam * np.abs(coef).sum(axis=0)


# ----------------------------------------------------------------- least squares
def test_least_squares_equals_lstsq_on_statistics(rng):
    a, b = _problem(rng)
    problem = ScaledProblem.from_statistics(dense_statistics(a, b))
    np.testing.assert_array_equal(problem.column_scale, np.abs(a).max(axis=0))
    result = LeastSquares().fit(problem)
    expected = np.linalg.lstsq(a, b, rcond=None)[0]
    np.testing.assert_allclose(result.coef / problem.column_scale[:, None], expected, rtol=1e-8, atol=1e-12)
    assert result.rank == a.shape[1]


def test_spectrum_rank_and_condition_match_numpy(rng):
    a, _ = _problem(rng, p=8)
    spectrum = Spectrum.of(a.T @ a)
    # Jacobi equilibration of AᵀA is unit-norm columns of A.
    expected = np.linalg.cond(a / np.linalg.norm(a, axis=0))
    assert spectrum.condition_number == pytest.approx(expected, rel=1e-6)
    assert spectrum.rank == 8
    dup = np.c_[a, 3.0 * a[:, 1]]
    spectrum = Spectrum.of(dup.T @ dup)
    assert spectrum.rank == np.linalg.matrix_rank(dup) == 8
    # Exactly collinear: the smallest eigenvalue is rounding noise, so the condition number is
    # at least above the level at which the model warns.
    assert spectrum.condition_number > 1e7


@pytest.mark.parametrize("p", [40, 520])  # under and over SPECTRUM_MAX: eigen-decomposition, then Cholesky
def test_conditioning_solves_and_measures_like_numpy_on_both_sides_of_its_size_switch(rng, p):
    from ftcal.core.solvers.base import SPECTRUM_MAX, Conditioning

    assert (p > SPECTRUM_MAX) == (p == 520)
    a = rng.standard_normal((3 * p, p)) * np.geomspace(0.1, 10, p)
    b = rng.standard_normal((3 * p, 2))
    conditioning = Conditioning.of(a.T @ a)
    assert (conditioning.cholesky is not None) == (p > SPECTRUM_MAX)
    np.testing.assert_allclose(conditioning.solve(a.T @ b), np.linalg.lstsq(a, b, rcond=None)[0], rtol=1e-9)
    assert conditioning.rank == p
    exact = np.linalg.cond(a / np.linalg.norm(a, axis=0))
    if p > SPECTRUM_MAX:
        # sqrt of LAPACK's estimate of κ1(G): κ1 >= κ2 for a symmetric G, norms within sqrt(p) of each
        # other, and the estimate falls short of κ1 by a small factor at most.
        assert exact / 2 <= conditioning.condition_number <= exact * np.sqrt(p)
    else:
        assert conditioning.condition_number == pytest.approx(exact, rel=1e-8)


# ------------------------------------------------------------------------- ridge
@pytest.mark.parametrize("lam", [1e-3, 0.5, 10.0, 500.0])
def test_ridge_equals_sklearn_on_scaled_regressor(rng, lam):
    a, b = _problem(rng)
    result = Ridge(lam).fit(ScaledProblem.from_statistics(dense_statistics(a, b)))
    expected = SklearnRidge(alpha=lam, fit_intercept=False).fit(_scaled(a), b).coef_.T
    np.testing.assert_allclose(result.coef, expected, rtol=1e-8, atol=1e-10)


@pytest.mark.parametrize("lam", [0.0, -1.0, np.nan, "1"])
def test_ridge_rejects_bad_lambda(rng, lam):
    a, b = _problem(rng, n=20, p=3)
    with pytest.raises(FtcalError, match="'lam' parameter of Ridge"):
        Ridge(lam).fit(ScaledProblem.from_statistics(dense_statistics(a, b)))


# ------------------------------------------------------------------------- LASSO
@pytest.mark.parametrize("lam", [0.05, 1.0, 20.0, 200.0])
def test_lasso_equals_sklearn_on_scaled_regressor(rng, lam):
    a, b = _problem(rng)
    n = a.shape[0]
    a_s = _scaled(a)
    result = Lasso(lam).fit(ScaledProblem.from_statistics(dense_statistics(a, b)))
    reference = SklearnLasso(alpha=lam / n, fit_intercept=False, tol=1e-14, max_iter=200_000).fit(a_s, b)
    expected = reference.coef_.T
    ours, theirs = _lasso_objective(a_s, b, result.coef, lam), _lasso_objective(a_s, b, expected, lam)
    assert np.all(ours <= theirs * (1 + 1e-12))
    np.testing.assert_allclose(ours, theirs, rtol=1e-10)
    np.testing.assert_allclose(result.coef, expected, rtol=1e-6, atol=1e-8)
    # Exact zeros, in the same places as coordinate descent's.
    np.testing.assert_array_equal(result.coef == 0.0, np.abs(expected) == 0.0)
    assert result.info["converged"] and result.info["lambda"] == lam
    assert result.info["n_nonzero"] == np.count_nonzero(result.coef, axis=0).tolist()


def test_lasso_sparsity_grows_with_lambda(rng):
    a, b = _problem(rng, p=16, ny=1)
    problem = ScaledProblem.from_statistics(dense_statistics(a, b))
    lam_max = float(np.abs(_scaled(a).T @ b).max())
    counts = [np.count_nonzero(Lasso(f * lam_max).fit(problem).coef) for f in (1e-4, 1e-2, 0.1, 0.5, 0.9)]
    assert counts == sorted(counts, reverse=True)
    assert counts[0] > counts[-1] >= 1
    assert counts[0] >= 12  # 11 true nonzeros + offset need not all survive, but most do


def test_lasso_all_zero_at_and_above_lambda_max(rng):
    a, b = _problem(rng)
    problem = ScaledProblem.from_statistics(dense_statistics(a, b))
    lam_max = np.abs(_scaled(a).T @ b).max(axis=0)  # ‖Aᵀb‖∞ per output, computed independently
    for lam in (lam_max.max(), 2 * lam_max.max()):
        assert not np.any(Lasso(lam).fit(problem).coef)
    # Just under one output's λ_max: that output gets exactly one nonzero, the other stays zero.
    small, large = np.argmin(lam_max), np.argmax(lam_max)
    coef = Lasso(lam_max[small] * 0.999).fit(problem).coef
    assert np.count_nonzero(coef[:, small]) == 1
    assert np.count_nonzero(coef[:, large]) >= 1


def test_lasso_path_equals_separate_fits(rng):
    a, b = _problem(rng)
    problem = ScaledProblem.from_statistics(dense_statistics(a, b))
    lams = [10.0, 0.5, 200.0, 1.0, 50.0, 10.0]  # unsorted, with a repeat
    path = Lasso(1.0).fit_path(problem, lams)
    assert [r.info["lambda"] for r in path] == lams
    for lam, result in zip(lams, path):
        alone = Lasso(lam).fit(problem)
        np.testing.assert_allclose(result.coef, alone.coef, rtol=1e-9, atol=1e-12)
        np.testing.assert_array_equal(result.coef == 0, alone.coef == 0)


def test_lasso_with_duplicate_columns_converges(rng):
    # Exact duplicates happen in practice: with the paper's max-abs input scaling a constant
    # temperature input becomes a copy of the offset column.
    a = rng.standard_normal((100, 5))
    a = np.c_[a, a[:, 0], np.ones(100)]
    b = (a[:, :3] @ [1.0, 2.0, 3.0] + 0.1 * rng.standard_normal(100))[:, None]
    lam = 0.5
    problem = ScaledProblem.from_statistics(dense_statistics(a, b))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        result = Lasso(lam, max_iter=2000).fit(problem)
    reference = SklearnLasso(alpha=lam / 100, fit_intercept=False, tol=1e-12, max_iter=100_000).fit(_scaled(a), b)
    np.testing.assert_allclose(_lasso_objective(_scaled(a), b, result.coef, lam),
                               _lasso_objective(_scaled(a), b, reference.coef_.reshape(-1, 1), lam), rtol=1e-9)
    assert result.info["converged"]


@pytest.mark.parametrize("lam", [0.0, -2.0, np.inf, None])
def test_lasso_rejects_bad_lambda(rng, lam):
    a, b = _problem(rng, n=20, p=3)
    with pytest.raises(FtcalError, match="'lam' parameter of Lasso"):
        Lasso(lam).fit(ScaledProblem.from_statistics(dense_statistics(a, b)))


# -------------------------------------------------------------------------- OSQP
# osqp >= 1.0 warns (PendingDeprecationWarning) on every solve() without raise_error; that is
# tested on its own below, and ignored where the numbers are the point.
OSQP_PENDING = "ignore:The default value of raise_error:PendingDeprecationWarning"


def test_osqp_solvers_emit_no_warnings(rng):
    a, b = _problem(rng, n=30, p=4, ny=1)
    a_s = _scaled(a)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        OsqpLeastSquares().fit_dense(a_s, b)
        OsqpLasso(1.0).fit_dense(a_s, b)


@pytest.mark.filterwarnings(OSQP_PENDING)
def test_osqp_least_squares_close_to_lstsq(rng):
    a, b = _problem(rng, n=120, p=8)
    a_s = _scaled(a)
    expected = np.linalg.lstsq(a_s, b, rcond=None)[0]
    best = 0.5 * ((a_s @ expected - b) ** 2).sum(axis=0)
    loose = OsqpLeastSquares().fit_dense(a_s, b).coef  # the paper's eps = 1e-4
    assert np.all(0.5 * ((a_s @ loose - b) ** 2).sum(axis=0) <= best * (1 + 1e-4))
    tight = OsqpLeastSquares(eps=1e-10).fit_dense(a_s, b).coef
    np.testing.assert_allclose(tight, expected, rtol=1e-5, atol=1e-7)


@pytest.mark.filterwarnings(OSQP_PENDING)
def test_osqp_lasso_objective_matches_ours(rng):
    a, b = _problem(rng, n=60, p=8)
    a_s = _scaled(a)
    problem = ScaledProblem.from_statistics(dense_statistics(a_s, b))
    np.testing.assert_array_equal(problem.column_scale, 1.0)
    for lam in (0.1, 2.0, 10.0):
        ours = Lasso(lam).fit(problem).coef
        theirs = OsqpLasso(lam).fit_dense(a_s, b).coef
        f_ours, f_theirs = _lasso_objective(a_s, b, ours, lam), _lasso_objective(a_s, b, theirs, lam)
        assert np.all(f_ours <= f_theirs * (1 + 1e-12))
        np.testing.assert_allclose(f_theirs, f_ours, rtol=1e-3)  # OSQP stops at eps = 1e-4
        tight = OsqpLasso(lam, eps=1e-10).fit_dense(a_s, b).coef
        np.testing.assert_allclose(tight, ours, atol=1e-6)


# ------------------------------------------------- least squares through the model
def _standardized_lstsq(ref_features, u, y, u_val, degree):
    """lstsq on monomials of z-scored inputs: same polynomial space, different basis from ftcal's."""
    mean, std = u.mean(axis=0), u.std(axis=0)
    coef = np.linalg.lstsq(ref_features((u - mean) / std, degree), y, rcond=None)[0]
    return ref_features((u_val - mean) / std, degree) @ coef


def _rmse(y, p):
    return np.sqrt(np.mean((y - p) ** 2, axis=0))


@pytest.mark.parametrize("degree", [1, 2, 3, 4, pytest.param(5, marks=pytest.mark.slow)])
def test_least_squares_predictions_match_lstsq_on_raw_sensor_inputs(rng, ref_features, make_sensor_data, degree):
    u, y = make_sensor_data(rng, 1800)
    u_val, y_val = make_sensor_data(rng, 400)
    inside = ~np.any((u_val < u.min(axis=0)) | (u_val > u.max(axis=0)), axis=1)
    u_val, y_val = u_val[inside], y_val[inside]
    model = CalibrationModel(degree).fit(Dataset.from_arrays(u, y))
    ours = model.predict(u_val)
    reference = _standardized_lstsq(ref_features, u, y, u_val, degree)
    np.testing.assert_allclose(_rmse(y_val, ours), _rmse(y_val, reference), rtol=1e-3)
    assert np.max(np.abs(ours - reference)) <= 1e-3 * np.max(_rmse(y_val, reference))
    assert model.rank_ == model.layout_.n_features


def test_degree5_small_input_set_matches_lstsq(rng, ref_features, make_sensor_data):
    # Degree 5 on 3 channels + temperature keeps the fast suite covering np = 5.
    u, y = make_sensor_data(rng, 1500, n_channels=3)
    u_val, y_val = make_sensor_data(rng, 300, n_channels=3)
    model = CalibrationModel(5).fit(Dataset.from_arrays(u, y))
    ours = model.predict(u_val, warn_out_of_range=False)
    reference = _standardized_lstsq(ref_features, u, y, u_val, 5)
    np.testing.assert_allclose(_rmse(y_val, ours), _rmse(y_val, reference), rtol=1e-3)
    np.testing.assert_allclose(model.predict(u), _standardized_lstsq(ref_features, u, y, u, 5),
                               atol=1e-6 * np.abs(y).max())


@pytest.mark.parametrize("degree", [1, 2, 3])
def test_recovers_known_polynomial_from_noise_free_data(rng, ref_features, degree):
    # Inputs reach exactly ±1 in every column, so the "center" normalization is the identity
    # and coef_ must equal the true coefficients in the paper's column order.
    u = rng.uniform(-1, 1, size=(400, 3))
    u[:3] = [[-1, -1, -1], [1, 1, 1], [-1, 1, -1]]
    features = ref_features(u, degree)
    true = rng.uniform(-2, 2, size=(features.shape[1], 2))
    model = CalibrationModel(degree).fit(Dataset.from_arrays(u, features @ true))
    np.testing.assert_allclose(model.input_normalization_.offset, 0.0, atol=1e-15)
    np.testing.assert_allclose(model.input_normalization_.scale, 1.0, rtol=1e-15)
    np.testing.assert_allclose(model.coef_, true, rtol=1e-8, atol=1e-9)
    u_new = rng.uniform(-1, 1, size=(50, 3))
    np.testing.assert_allclose(model.predict(u_new), ref_features(u_new, degree) @ true, rtol=1e-8, atol=1e-9)


def test_recovers_polynomial_in_raw_units(rng, ref_features, make_sensor_data):
    # y is an exact cubic of the raw ADC counts and temperature.
    u, _ = make_sensor_data(rng, 600, n_channels=2)
    z = (u - [5000.0, 5000.0, 35.0]) / [800.0, 800.0, 10.0]
    true = rng.uniform(-5, 5, size=(20, 1))
    model = CalibrationModel(3).fit(Dataset.from_arrays(u, ref_features(z, 3) @ true))
    u_new = u[:50] + rng.uniform(-1, 1, size=(50, 3))
    np.testing.assert_allclose(model.predict(u_new, warn_out_of_range=False), ref_features(
        (u_new - [5000.0, 5000.0, 35.0]) / [800.0, 800.0, 10.0], 3) @ true, rtol=1e-7, atol=1e-7)


# ------------------------------------------------------------------ ill-posed fits
def _rank_deficient_cases(rng):
    base = rng.uniform(-1, 1, size=(300, 3)) * [200.0, 50.0, 5.0] + [5000.0, 4000.0, 35.0]
    duplicate = np.c_[base, base[:, 0]]
    collinear = np.c_[base, 2.0 * base[:, 0] - base[:, 1] + 7.0]
    constant = np.c_[base, np.full(300, 36.5)]
    return {"duplicate": duplicate, "collinear": collinear, "constant": constant}


@pytest.mark.parametrize("case", ["duplicate", "collinear", "constant"])
@pytest.mark.parametrize("degree", [1, 2])
def test_rank_deficient_fit_warns_and_predicts_like_lstsq(rng, case, degree, ref_features):
    u = _rank_deficient_cases(rng)[case]
    y = np.c_[np.sin(u[:, 0] / 100.0), u[:, 1] * u[:, 2] / 1e4]
    with pytest.warns(IllPosedFitWarning) as record:
        model = CalibrationModel(degree).fit(Dataset.from_arrays(u, y))
    assert any("rank" in str(w.message) for w in record)
    assert model.rank_ < model.layout_.n_features
    # Raw-input monomials scaled by hand; lstsq's minimum-norm solution on them.
    z = (u - u.mean(axis=0)) / np.where(u.std(axis=0) > 0, u.std(axis=0), 1.0)
    a = ref_features(z, degree)
    expected = a @ np.linalg.lstsq(a, y, rcond=None)[0]
    np.testing.assert_allclose(model.predict(u), expected, atol=1e-8 * np.abs(y).max())


def test_constant_input_warns_by_name(rng):
    u = np.c_[rng.uniform(-1, 1, size=(100, 2)), np.full(100, 35.0)]
    y = u[:, :1] * 2.0
    with pytest.warns(IllPosedFitWarning) as record:
        CalibrationModel(1).fit(Dataset.from_arrays(u, y, input_names=["a", "b", "T"]))
    assert any("'T'" in str(w.message) and "constant" in str(w.message) for w in record)


def test_fewer_samples_than_coefficients_warns(rng, ref_features):
    u = rng.uniform(-1, 1, size=(15, 3))  # degree 3 over 3 inputs: 20 coefficients
    y = rng.normal(size=(15, 1))
    with pytest.warns(IllPosedFitWarning) as record:
        model = CalibrationModel(3).fit(Dataset.from_arrays(u, y))
    assert any("under-determined: 15 samples for 20 coefficients" in str(w.message) for w in record)
    # With more coefficients than samples the least-squares fit interpolates the data.
    np.testing.assert_allclose(model.predict(u), y, atol=1e-6)


# ----------------------------------------------- regularized fits through the model
def _signed_counts(make_sensor_data, rng, n):
    """Sensor data with ADC counts centred on zero (signed channels), so max-abs scaling is sane."""
    u, y = make_sensor_data(rng, n, n_channels=2)
    return u - [5000.0, 5000.0, 0.0], y


def _paper_scaled_regressor(ref_features, u, degree):
    """The paper's regressor: monomials of u / max|u|, then columns divided by their max |value|."""
    a = ref_features(u / np.abs(u).max(axis=0), degree)
    return a / np.abs(a).max(axis=0)


def test_model_lasso_equals_sklearn_on_paper_regressor(rng, ref_features, make_sensor_data):
    u, y = _signed_counts(make_sensor_data, rng, 400)
    lam = 5.0
    model = CalibrationModel(2, solver=Lasso(lam), normalization="maxabs").fit(Dataset.from_arrays(u, y))
    a_s = _paper_scaled_regressor(ref_features, u, 2)
    column_scale = np.abs(ref_features(u / np.abs(u).max(axis=0), 2)).max(axis=0)
    reference = SklearnLasso(alpha=lam / len(u), fit_intercept=False, tol=1e-14, max_iter=500_000).fit(a_s, y)
    ours = model.coef_ * column_scale[:, None]
    f_ours, f_theirs = _lasso_objective(a_s, y, ours, lam), _lasso_objective(a_s, y, reference.coef_.T, lam)
    np.testing.assert_allclose(f_ours, f_theirs, rtol=1e-7)
    assert np.all(f_ours <= f_theirs * (1 + 1e-9))
    assert model.solver_info_["lambda"] == lam
    assert model.describe()["n_nonzero"] < model.coef_.size


def test_model_ridge_equals_sklearn_on_paper_regressor(rng, ref_features, make_sensor_data):
    u, y = _signed_counts(make_sensor_data, rng, 300)
    model = CalibrationModel(2, solver=Ridge(0.3), normalization="maxabs").fit(Dataset.from_arrays(u, y))
    a_s = _paper_scaled_regressor(ref_features, u, 2)
    column_scale = np.abs(ref_features(u / np.abs(u).max(axis=0), 2)).max(axis=0)
    expected = SklearnRidge(alpha=0.3, fit_intercept=False).fit(a_s, y).coef_.T
    np.testing.assert_allclose(model.coef_ * column_scale[:, None], expected, rtol=1e-6, atol=1e-8)


@pytest.mark.filterwarnings(OSQP_PENDING)
def test_model_osqp_least_squares_close_to_lstsq(rng, ref_features, make_sensor_data):
    u, y = make_sensor_data(rng, 300, n_channels=2)
    model = CalibrationModel(2, solver=OsqpLeastSquares(eps=1e-9)).fit(Dataset.from_arrays(u, y))
    expected = _standardized_lstsq(ref_features, u, y, u, 2)
    np.testing.assert_allclose(model.predict(u), expected, atol=1e-5 * np.abs(y).max())
    assert model.solver_info_["name"] == "osqp"


def test_lasso_polish_repairs_a_nearly_right_support(rng):
    # Start the active-set polish from sklearn's solution with one active coefficient
    # dropped and one inactive one added: it must still land on sklearn's optimum.
    from ftcal.core.solvers.lasso import _polish

    a, b = _problem(rng, n=300, p=12, ny=1)
    a_s = _scaled(a)
    lam = 2.0
    reference = SklearnLasso(alpha=lam / len(a), fit_intercept=False, tol=1e-12, max_iter=1_000_000).fit(a_s, b[:, 0])
    active = np.flatnonzero(reference.coef_)
    inactive = np.flatnonzero(reference.coef_ == 0)
    assert active.size >= 2 and inactive.size >= 1
    guess = reference.coef_.copy()
    guess[active[0]] = 0.0
    guess[inactive[0]] = 1.0
    polished = _polish(a_s.T @ a_s, a_s.T @ b[:, 0], guess, lam)
    assert polished is not None
    np.testing.assert_allclose(polished, reference.coef_, rtol=1e-6, atol=1e-8)
    assert np.array_equal(np.flatnonzero(polished), active)
