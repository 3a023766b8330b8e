"""Grouped cross-validation: folds made of whole groups, scores against numpy, the selection rule."""

from __future__ import annotations

import warnings
from itertools import combinations_with_replacement

import numpy as np
import pytest

from ftcal.core.dataset import Dataset
from ftcal.core.model import CalibrationModel
from ftcal.core.select import (
    PAPER_LAMBDAS,
    Candidate,
    cross_validate,
    default_candidates,
    fit_best,
    fit_candidates,
    grouped_folds,
    select_model,
)
from ftcal.core.solvers import Lasso, Ridge
from ftcal.runtime.errors import FtcalError

OUTPUTS = ("Fx", "Fy", "Fz", "Tx", "Ty", "Tz")


def raw_monomials(u: np.ndarray, degree: int) -> np.ndarray:
    cols = [np.prod(u[:, list(c)], axis=1) for p in range(1, degree + 1)
            for c in combinations_with_replacement(range(u.shape[1]), p)]
    return np.column_stack(cols + [np.ones(len(u))])


def force_error_norm_rmse(y, p):
    return float(np.sqrt(np.mean(np.sum((y[:, :3] - p[:, :3]) ** 2, axis=1))))


def grouped_data(rng, n_groups=5, per_group=400, nonlinear=True, noise=0.05):
    u = rng.uniform(-1, 1, (n_groups * per_group, 3)) + np.array([2.0, -1.0, 0.5])
    y = np.column_stack([3 * u[:, 0] + u[:, 1], u[:, 1] - u[:, 2], 2 * u[:, 2] + 1,
                         u[:, 0] - u[:, 2], u[:, 1] + 0.5, u[:, 0]])
    if nonlinear:
        y[:, 0] += 0.8 * u[:, 0] * u[:, 1]
        y[:, 2] += 0.5 * u[:, 2] ** 2
    y += noise * rng.standard_normal(y.shape)
    groups = np.repeat([f"g{i}" for i in range(n_groups)], per_group)
    return Dataset.from_arrays(u, y, input_names=("a", "b", "c"), output_names=OUTPUTS,
                               segments=np.repeat(np.arange(n_groups), per_group), groups=groups)


def test_folds_hold_whole_groups_and_cover_every_sample_once():
    groups = np.array(["a"] * 50 + ["b"] * 10 + ["c"] * 30 + ["d"] * 30 + ["e"] * 5)
    folds = grouped_folds(groups, n_folds=3)
    assert len(folds) == 3
    np.testing.assert_array_equal(np.sum(folds, axis=0), np.ones(len(groups)))
    for mask in folds:
        for label in np.unique(groups):
            in_fold = mask[groups == label]
            assert in_fold.all() or not in_fold.any()
    # Greedy balancing: no fold exceeds the lightest by more than the largest group.
    sizes = [int(m.sum()) for m in folds]
    assert max(sizes) - min(sizes) <= 50


def test_one_group_cannot_be_cross_validated():
    with pytest.raises(FtcalError, match="at least 2 groups"):
        grouped_folds(np.array(["only"] * 10))


def test_least_squares_fold_scores_equal_numpy_lstsq(rng):
    data = grouped_data(rng)
    result = cross_validate(data, [Candidate(2, "none", None)], n_folds=5, objective="force")
    folds = grouped_folds(data.groups, 5)
    expected, expected_train = [], []
    for mask in folds:
        coef = np.linalg.lstsq(raw_monomials(data.inputs[~mask], 2), data.outputs[~mask], rcond=None)[0]
        expected.append(force_error_norm_rmse(data.outputs[mask], raw_monomials(data.inputs[mask], 2) @ coef))
        expected_train.append(force_error_norm_rmse(data.outputs[~mask], raw_monomials(data.inputs[~mask], 2) @ coef))
    # Scores come from statistics (θᵀGθ − 2θᵀc + ‖y‖²), never from predictions: check against numpy.
    scores = result.score_of(Candidate(2, "none", None))
    np.testing.assert_allclose(scores.fold_scores, expected, rtol=1e-6)
    np.testing.assert_allclose(scores.fold_train_scores, expected_train, rtol=1e-6)


def test_true_degree_wins_and_ties_go_to_fewer_coefficients(rng):
    nonlinear = grouped_data(rng, nonlinear=True)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        assert cross_validate(nonlinear, default_candidates((1, 2, 3), penalty=None)).best.degree == 2
    # On affine data degrees 2 and 3 only fit noise: within 1% of degree 1, which has fewer terms.
    affine = grouped_data(rng, nonlinear=False, per_group=2000)
    result = cross_validate(affine, default_candidates((1, 2, 3), penalty=None))
    scores = {s.candidate.degree: s.score for s in result.scores}
    assert max(scores.values()) <= min(scores.values()) * 1.01
    assert result.best.degree == 1


def test_fit_candidates_equals_separate_fits(rng):
    data = grouped_data(rng)
    candidates = [Candidate(1, "none", None), Candidate(3, "none", None),
                  Candidate(3, "lasso", 0.5), Candidate(3, "lasso", 5.0)]
    models = fit_candidates(data, candidates)
    for candidate in candidates:
        solver = Lasso(candidate.lam) if candidate.penalty == "lasso" else None
        alone = CalibrationModel(candidate.degree, solver=solver).fit(data)
        np.testing.assert_allclose(models[candidate].predict(data), alone.predict(data), rtol=1e-9, atol=1e-9)


# ------------------------------------------------------------ model selection on a known sensor
def load_case_sensor(rng, n_groups, per_group, nonlinear, noise=0.02):
    """A strain-gauge-like sensor held at ``n_groups`` static loads (each load a group, slightly varying).

    Readings are an affine map of the load (plus, when ``nonlinear``, a quadratic cross-talk the
    inverse needs degree 2 for); the outputs are the loads. Noise is on the readings.
    """
    loads = rng.uniform(-1, 1, (n_groups, 1, 3)) + 0.05 * rng.standard_normal((n_groups, per_group, 3))
    y = loads.reshape(-1, 3) * np.array([50.0, 50.0, 80.0])
    x = y / 50.0
    readings = np.c_[x @ np.array([[1.0, 0.2, 0.0], [0.1, 1.0, 0.3], [0.0, -0.2, 1.0]]).T,
                     x[:, 0] - x[:, 1]] * 100.0 + 2000.0
    if nonlinear:
        readings[:, 0] += 15.0 * x[:, 0] * x[:, 1]
        readings[:, 2] += 12.0 * x[:, 2] ** 2
    readings += noise * 100.0 * rng.standard_normal(readings.shape)
    groups = np.repeat([f"load{g}" for g in range(n_groups)], per_group)
    return Dataset.from_arrays(readings, np.c_[y, 0.01 * y], input_names=("s1", "s2", "s3", "s4"),
                               output_names=OUTPUTS, segments=np.repeat(np.arange(n_groups), per_group),
                               groups=groups)


def held_out_error(model, data):
    p = model.predict(data, warn_out_of_range=False)
    return force_error_norm_rmse(data.outputs, p)


def test_lambda_max_is_where_lasso_zeroes_every_non_offset_coefficient(rng):
    from sklearn.linear_model import Lasso as SklearnLasso

    from ftcal.core.select import lasso_lambda_max
    from ftcal.core.solvers.base import ScaledProblem
    from ftcal.core.statistics import dense_statistics

    a = np.c_[rng.uniform(-1, 3, (200, 4)), np.ones(200)]
    b = a[:, :2] @ [[1.0], [-2.0]] + 5.0 + 0.1 * rng.standard_normal((200, 1))
    problem = ScaledProblem.from_statistics(dense_statistics(a, b))
    top = lasso_lambda_max(problem)
    a_s = a / problem.column_scale
    for factor, zero in ((1.001, True), (0.99, False)):
        # scikit-learn, α = λ/N, offset penalized like every column (the paper's problem)
        coef = SklearnLasso(alpha=factor * top / 200, fit_intercept=False, tol=1e-12,
                            max_iter=100_000).fit(a_s, b[:, 0]).coef_
        assert (np.abs(coef[:-1]).max() < 1e-9) == zero, factor
        assert coef[-1] != 0


def test_auto_selection_finds_the_nonlinearity_and_beats_affine_on_new_load_cases(rng):
    train = load_case_sensor(rng, 30, 40, nonlinear=True)
    fresh = load_case_sensor(np.random.default_rng(99), 20, 40, nonlinear=True)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = select_model(train, degrees=(1, 2, 3))
    assert result.best.degree >= 2
    best = fit_best(train, result)
    affine = CalibrationModel(1).fit(train)
    assert held_out_error(best, fresh) < 0.7 * held_out_error(affine, fresh)
    assert "margin over np1" in result.verdict() and "within the fold noise" not in result.verdict()
    # Ridge and LASSO candidates were tried on grids from the data.
    tried = {s.candidate.penalty for s in result.scores}
    assert tried == {"none", "lasso", "ridge"}


def test_auto_selection_never_loses_to_affine_by_more_than_the_fold_noise(rng):
    # Affine truth: anything nonlinear only fits noise.
    for seed in range(3):
        gen = np.random.default_rng(seed)
        train = load_case_sensor(gen, 12, 60, nonlinear=False, noise=0.05)
        fresh = load_case_sensor(gen, 12, 60, nonlinear=False, noise=0.05)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            result = select_model(train, degrees=(1, 2, 3))
            best = fit_best(train, result)
        affine = CalibrationModel(1).fit(train)
        noise = result.comparison().spread
        # When the search keeps the affine model, the two errors differ by rounding only (its coefficients
        # come from summed fold statistics): a relative 1e-9 is no loss, and no exact tie is asserted.
        reference = held_out_error(affine, fresh)
        assert held_out_error(best, fresh) <= reference + noise + 1e-9 * reference


def test_lasso_grid_spans_three_decades_below_lambda_max(rng):
    from ftcal.core.select import lasso_lambda_max
    from ftcal.core.solvers.base import ScaledProblem

    data = load_case_sensor(rng, 10, 50, nonlinear=True)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = select_model(data, degrees=(2,), penalties=("lasso",))
    lams = sorted(s.candidate.lam for s in result.scores if s.candidate.penalty == "lasso")
    frame = CalibrationModel(2, solver=Lasso(1.0)).frame(data)
    stats = CalibrationModel.statistics(data, frame.layout, frame.input_normalization, frame.output_normalization)
    top = lasso_lambda_max(ScaledProblem.from_statistics(stats))
    np.testing.assert_allclose(lams[-10:], top * 10.0 ** (-0.3 * np.arange(10, 0, -1)), rtol=1e-9)


def test_ridge_grid_grows_past_its_heavy_edge_when_the_best_sits_there(rng):
    # Zero-mean noise for outputs: the heaviest penalty (predict ~0) is best, so the grid grows upwards.
    from ftcal.core.solvers.base import ScaledProblem

    data = load_case_sensor(rng, 8, 40, nonlinear=False)
    data = Dataset.from_arrays(data.inputs, rng.standard_normal(data.outputs.shape), input_names=data.input_names,
                               output_names=OUTPUTS, groups=data.groups)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = select_model(data, degrees=(2,), penalties=("ridge",))
    frame = CalibrationModel(2, solver=Ridge(1.0)).frame(data)
    stats = CalibrationModel.statistics(data, frame.layout, frame.input_normalization, frame.output_normalization)
    problem = ScaledProblem.from_statistics(stats)
    default_top = np.trace(problem.gram) / problem.n_features
    lams = [s.candidate.lam for s in result.scores if s.candidate.penalty == "ridge"]
    assert max(lams) > 5 * default_top


def test_fixed_lambdas_and_penalties(rng):
    data = load_case_sensor(rng, 6, 30, nonlinear=True)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = select_model(data, degrees=(1, 2), penalties=("ridge",), lambdas=PAPER_LAMBDAS,
                              stop_early=False)
    labels = {s.candidate for s in result.scores}
    expected = {Candidate(d, "none", None) for d in (1, 2)} | {Candidate(d, "ridge", lam) for d in (1, 2)
                                                                for lam in PAPER_LAMBDAS}
    assert labels == expected


def test_degrees_past_a_worse_one_are_not_tried(rng):
    data = load_case_sensor(rng, 8, 40, nonlinear=False, noise=0.2)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = select_model(data, degrees=(1, 2, 3, 4), penalties=())
    tried = sorted({s.candidate.degree for s in result.scores})
    scores = {s.candidate.degree: s.score for s in result.scores}
    # Stopped right after the first degree that validated worse than every lower one.
    last = tried[-1]
    assert last < 4 and result.skipped_degrees == tuple(range(last + 1, 5))
    assert scores[last] > min(scores[d] for d in tried if d < last)


def test_ridge_prior_shrinks_toward_the_prior_exactly(rng):
    """½‖Aθ − y‖² + ½λ‖θ − θp‖² on the paper's regressor: θ = (AᵀA + λI)⁻¹(Aᵀy + λθp), by numpy."""
    data = load_case_sensor(rng, 6, 50, nonlinear=True)
    prior = CalibrationModel(1).fit(load_case_sensor(np.random.default_rng(5), 6, 50, nonlinear=False))
    lam = 30.0
    model = CalibrationModel(1, solver=Ridge(lam), prior=prior).fit(data)
    u = data.inputs
    a = np.c_[u, np.ones(len(u))]
    scale = np.abs(a).max(axis=0)
    a_s = a / scale
    prior_on_u = prior.predict(u, warn_out_of_range=False)
    theta_prior = np.linalg.lstsq(a, prior_on_u, rcond=None)[0] * scale[:, None]
    theta = np.linalg.solve(a_s.T @ a_s + lam * np.eye(5), a_s.T @ data.outputs + lam * theta_prior)
    np.testing.assert_allclose(model.predict(u), a_s @ theta, rtol=0, atol=1e-8 * np.abs(data.outputs).max())
    # A huge L1 weight leaves exactly the prior (θ − θp = 0).
    stuck = CalibrationModel(1, solver=Lasso(1e12), prior=prior).fit(data)
    np.testing.assert_allclose(stuck.predict(u), prior_on_u, rtol=0, atol=1e-8 * np.abs(data.outputs).max())


def test_cli_selection_options_and_prior(tmp_path, capsys, rng):
    import pandas as pd

    from ftcal.cli import main
    from ftcal.files.model_files import load_model

    data = load_case_sensor(rng, 6, 40, nonlinear=True)
    table = pd.DataFrame(data.inputs, columns=data.input_names)
    table[list(OUTPUTS)] = data.outputs
    table["case"] = data.groups
    path = tmp_path / "cases.csv"
    table.to_csv(path, index=False)
    common = ["fit", str(path), "--inputs", "s1,s2,s3,s4", "--group-by", "case"]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        assert main([*common, "--degree", "auto", "--penalties", "ridge", "--lambdas", "paper", "--verbose",
                     "-o", str(tmp_path / "auto.json")]) == 0
    out = capsys.readouterr().out
    assert "np2 ridge λ=200" in out and "lasso" not in out.split("selected")[0]
    # A heavy ridge toward a prior stays at the prior; without a penalty --prior is refused.
    with warnings.catch_warnings():
        warnings.simplefilter("always")
        assert main([*common, "-o", str(tmp_path / "prior.json")]) == 0
        # the torques are 0.01 × the forces: 3 of the 6 output directions, which fit says
        assert "warning: reference wrenches span 3 of 6 directions" in capsys.readouterr().err
        assert main([*common, "--degree", "1", "--ridge", "1e9", "--prior", str(tmp_path / "prior.json"),
                     "-o", str(tmp_path / "shrunk.json")]) == 0
    prior, shrunk = load_model(tmp_path / "prior.json"), load_model(tmp_path / "shrunk.json")
    np.testing.assert_allclose(shrunk.predict(data.inputs), prior.predict(data.inputs), rtol=0, atol=1e-4)
    # The model file names its prior, with the digest of the prior file's bytes (hashlib).
    import hashlib

    from ftcal.files.model_files import load_model_file

    recorded = load_model_file(tmp_path / "shrunk.json").prior
    assert recorded == {"source": str(tmp_path / "prior.json"),
                        "file_sha256": hashlib.sha256((tmp_path / "prior.json").read_bytes()).hexdigest()}
    assert load_model_file(tmp_path / "prior.json").prior is None
    capsys.readouterr()
    assert main(["info", str(tmp_path / "shrunk.json")]) == 0
    assert f"shrunk toward the prior {tmp_path / 'prior.json'}" in capsys.readouterr().out
    capsys.readouterr()
    assert main([*common, "--prior", str(tmp_path / "prior.json"), "-o", str(tmp_path / "x.json")]) == 2
    assert "--prior" in capsys.readouterr().err
