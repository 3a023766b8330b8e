"""The cost of ``--degree auto``: what the estimate counts, the budget kept during the search, the
progress it reports, and the LASSO path on ill-conditioned monomials (no timings asserted)."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from sklearn.linear_model import Lasso as SklearnLasso
from sklearn.preprocessing import PolynomialFeatures

from ftcal.core.dataset import Dataset
from ftcal.core.select import CostEstimate, SearchBudget, estimate_cost, select_model
from ftcal.core.solvers.base import ScaledProblem
from ftcal.core.solvers.lasso import Lasso
from ftcal.core.statistics import dense_statistics


def _cases(rng, n_groups=12, per_group=40):
    u = np.repeat(rng.uniform(-1, 1, (n_groups, 3)), per_group, axis=0) + 0.05 * rng.standard_normal(
        (n_groups * per_group, 3))
    y = np.c_[u @ [1.0, 2.0, 3.0] + 0.3 * u[:, 0] ** 2, u[:, 1] - 0.2 * u[:, 2] * u[:, 0]]
    y = y + 0.01 * rng.standard_normal(y.shape)
    return Dataset.from_arrays(u, y, groups=np.repeat(np.arange(n_groups), per_group))


def _quiet(function, *args, **kwargs):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return function(*args, **kwargs)


def _estimate(seconds, final=0.0):
    n = len(seconds)
    return CostEstimate(tuple(range(1, n + 1)), ((0, 0),) * n, tuple(seconds), (0.0,) * n, 3, 5, 0.0,
                        (final,) * n)


def test_a_budget_already_spent_drops_every_later_degree_and_says_which(rng):
    data = _cases(rng)
    budget = SearchBudget(10.0, _estimate([1.0, 1.0, 1.0]), clock=lambda: 100.0)
    result = _quiet(select_model, data, degrees=(1, 2, 3), penalties=("ridge",), budget=budget, stop_early=False)
    assert {s.candidate.degree for s in result.scores} == {1}
    assert any(note.startswith("degrees 2, 3 not tried") and "--budget 10 s" in note for note in result.notes)
    assert "degrees 2, 3 not tried" in result.summary()


def test_a_budget_with_room_keeps_every_degree(rng):
    data = _cases(rng)
    budget = SearchBudget(10.0, _estimate([1.0, 1.0, 1.0]), clock=lambda: 0.0)
    result = _quiet(select_model, data, degrees=(1, 2, 3), penalties=("ridge",), budget=budget, stop_early=False)
    assert {s.candidate.degree for s in result.scores} == {1, 2, 3}
    assert not any("not tried" in note for note in result.notes)


def test_the_budget_scales_its_prediction_by_the_pace_of_the_degrees_done():
    # Degree 1 predicted 1 s, took 3 s: degree 2 (predicted 1 s) is expected to take 3 s.
    now = [0.0]
    budget = SearchBudget(6.0, _estimate([1.0, 1.0], final=0.5), clock=lambda: now[0])
    budget.start(1)
    now[0] = 3.0
    budget.finish(1)
    assert budget.pace == pytest.approx(3.0)
    # 3 s used + 3 s predicted + 0.5 s final fit > 6 s, though 3 + 1 + 0.5 would fit.
    assert "would take about 3.5 s more" in budget.overrun(2)
    # A degree done faster than predicted never lowers the prediction below the estimate.
    quick = SearchBudget(6.0, _estimate([1.0, 1.0]), clock=lambda: now[0])
    quick.start(1)
    quick.finish(1)
    assert quick.pace == 1.0


def test_progress_counts_every_candidate_on_every_fold(rng):
    data = _cases(rng)
    done = []
    result = _quiet(select_model, data, degrees=(1, 2), penalties=("lasso", "ridge"), n_folds=4,
                    advance=done.append)
    assert sum(done) == len(result.scores) * result.n_folds == len(result.scores) * 4


def test_the_estimate_counts_folds_times_candidates():
    five = estimate_cost(10_000, 6, 6, (1, 2, 3), 5)
    ten = estimate_cost(10_000, 6, 6, (1, 2, 3), 10)
    # Every solve is per fold: twice the folds, twice the solve units, degree by degree.
    assert [b for _, b in ten.units] == [2 * b for _, b in five.units]
    # 1 least squares + 10 LASSO λ + 13 ridge λ per degree (the default grids).
    assert five.candidates == 24
    # Fewer λ, fewer units; the CPU already spent is part of the total.
    fewer = estimate_cost(10_000, 6, 6, (1, 2, 3), 5, n_lambdas=2, spent_seconds=1.5)
    assert sum(b for _, b in fewer.units) < sum(b for _, b in five.units)
    assert fewer.total_seconds == pytest.approx(1.5 + fewer.search_seconds + fewer.final_seconds[-1])


def test_the_estimate_counts_the_pair_fits_of_nested_cross_validation():
    # Few load cases a fold (12 in 5 folds): every candidate is also fitted on the complement of each pair of
    # folds, C(5, 2) = 10 training sets beside the 5 of the folds; 20 load cases (4 a fold) have none.
    flat = estimate_cost(360, 6, 6, (1, 2, 3), 5, n_groups=20)
    nested = estimate_cost(360, 6, 6, (1, 2, 3), 5, n_groups=12)
    assert flat.units == estimate_cost(360, 6, 6, (1, 2, 3), 5).units
    assert [b for _, b in nested.units] == [3 * b for _, b in flat.units]  # (5 + 10) / 5
    assert [a for a, _ in nested.units] == [a for a, _ in flat.units]  # no statistics pass more
    assert nested.final_seconds == pytest.approx(flat.final_seconds)  # one refit, whatever the folds


def test_the_search_counts_the_pair_fits_it_makes(rng):
    # The work the search counts against the estimate (the budget's pace): with nested cross-validation
    # the solve units are those of 15 training sets a candidate, as the estimate plans.
    data = _cases(rng, n_groups=12, per_group=30)
    result = _quiet(select_model, data, degrees=(1, 2), penalties=(), stop_early=False)
    plain = _quiet(select_model, _cases(np.random.default_rng(1), n_groups=20, per_group=18), degrees=(1, 2),
                   penalties=(), stop_early=False)
    assert result.search.nested and not plain.search.nested
    # Least squares only: every candidate costs the same on each training set (no path events), so the
    # counted solve units are in the ratio of the training sets, 15 : 5.
    assert result.search.work["solve"] == 3 * plain.search.work["solve"]
    assert all(len(s.inner_mse) == 5 * 4 for s in result.scores)  # (outer k, inner j), j != k


def test_lasso_path_on_ill_conditioned_monomials_is_exact_in_tens_of_events_per_lambda(rng):
    # Raw ADC-like counts in a narrow band: degree-3 monomials nearly collinear after max-abs scaling.
    x = rng.uniform(-1, 1, (400, 3))
    u = 1000.0 + 40.0 * x
    a = PolynomialFeatures(3, include_bias=False).fit_transform(u)
    a = np.c_[a, np.ones(len(u))]
    b = np.c_[x @ [1.0, -2.0, 0.5] + 0.3 * x[:, 0] * x[:, 1], x[:, 2] ** 2] + 0.01 * rng.standard_normal((400, 2))
    a_s = a / np.abs(a).max(axis=0)
    assert np.linalg.cond(a_s / np.linalg.norm(a_s, axis=0)) > 1e6
    problem = ScaledProblem.from_statistics(dense_statistics(a, b))
    lam_max = np.abs(a_s.T @ b).max()
    lams = list(lam_max * np.logspace(-1, -5, 9))
    results = Lasso(1.0).fit_path(problem, lams)
    for lam, result in zip(lams, results):
        coef = result.coef
        # Optimality checked with numpy on the dense regressor: |Aᵀr| ≤ λ off the support, = λ·sign on it.
        gradient = a_s.T @ (b - a_s @ coef)
        zero = coef == 0
        assert np.all(np.abs(gradient[zero]) <= lam * (1 + 1e-6))
        np.testing.assert_allclose(gradient[~zero], lam * np.sign(coef[~zero]), rtol=1e-6, atol=1e-9 * lam)
        assert result.info["admm_outputs"] == []
        reference = SklearnLasso(alpha=lam / len(a), fit_intercept=False, tol=1e-10, max_iter=20_000)
        reference = _quiet(reference.fit, a_s, b)
        ours = 0.5 * ((a_s @ coef - b) ** 2).sum(0) + lam * np.abs(coef).sum(0)
        theirs = 0.5 * ((a_s @ reference.coef_.T - b) ** 2).sum(0) + lam * np.abs(reference.coef_.T).sum(0)
        assert np.all(ours <= theirs * (1 + 1e-9))
    # Tens of path events per λ and output, not thousands of iterations.
    assert sum(r.info["events"] for r in results) / (len(lams) * b.shape[1]) <= 30


def test_the_budget_counts_only_this_commands_cpu_when_main_runs_inside_another_program(tmp_path, capsys):
    # A notebook or a test suite that has already used more CPU than --budget still gets its search: the
    # budget starts at main(), not at the process's start. Burn 2 s of CPU first, then ask for a 1.5 s budget
    # on a table whose degree-1/2 search costs a fraction of a second.
    import time

    import numpy as np
    import pandas as pd

    from ftcal.cli import main

    rng = np.random.default_rng(0)
    u = rng.normal(size=(600, 3))
    # 20 load cases of 30 rows: 4 a fold, no nested cross-validation (whose pair fits triple the solves).
    frame = pd.DataFrame(u, columns=["u1", "u2", "u3"]).assign(
        Fx=u @ [1.0, 2.0, 3.0] + 0.01 * rng.normal(size=600), group=np.repeat(np.arange(20), 30))
    frame.to_csv(tmp_path / "t.csv", index=False)
    start = time.process_time()
    while time.process_time() - start < 2.0:
        pass
    code = main(["fit", str(tmp_path / "t.csv"), "--inputs", "u1,u2,u3", "--outputs", "Fx", "--degree", "auto",
                 "--max-degree", "2", "--group-by", "group", "--budget", "1.5", "-o", str(tmp_path / "m.json")])
    out = capsys.readouterr().out
    assert code == 0 and "not tried" not in out and "dropped" not in out, out
