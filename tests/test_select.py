"""Grouped cross-validation: folds made of whole groups, scores against numpy, the selection rule."""

from __future__ import annotations

import warnings
from itertools import combinations_with_replacement

import numpy as np
import pytest

from ftcal.dataset import Dataset
from ftcal.errors import FtcalError
from ftcal.model import CalibrationModel
from ftcal.select import Candidate, cross_validate, default_candidates, fit_candidates, grouped_folds
from ftcal.solvers import Lasso

OUTPUTS = ("Fx", "Fy", "Fz", "Tx", "Ty", "Tz")


def raw_monomials(u: np.ndarray, degree: int) -> np.ndarray:
    cols = [np.prod(u[:, list(c)], axis=1) for p in range(1, degree + 1)
            for c in combinations_with_replacement(range(u.shape[1]), p)]
    return np.column_stack(cols + [np.ones(len(u))])


def force_norm_rmse(y, p):
    diff = np.linalg.norm(y[:, :3], axis=1) - np.linalg.norm(p[:, :3], axis=1)
    return float(np.sqrt(np.mean(diff ** 2)))


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
    result = cross_validate(data, [Candidate(2, "none", None)], n_folds=5)
    folds = grouped_folds(data.groups, 5)
    expected = []
    for mask in folds:
        coef = np.linalg.lstsq(raw_monomials(data.inputs[~mask], 2), data.outputs[~mask], rcond=None)[0]
        expected.append(force_norm_rmse(data.outputs[mask], raw_monomials(data.inputs[mask], 2) @ coef))
    np.testing.assert_allclose(result.scores[0].fold_scores, expected, rtol=1e-6)


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
