"""The core's contracts: the Solver protocol, an injected basis, clone/templates, limits declared once, doctests."""

from __future__ import annotations

import doctest
import importlib
import json
from importlib import resources

import numpy as np
import pytest

from ftcal.core import limits
from ftcal.core.dataset import Dataset
from ftcal.core.features import MonomialBasis
from ftcal.core.model import CalibrationModel
from ftcal.core.select import Candidate, cross_validate, fit_best, grouped_folds
from ftcal.core.solvers import (
    Lasso,
    LeastSquares,
    OsqpLasso,
    OsqpLeastSquares,
    Ridge,
    ScaledProblem,
    Solver,
    SolverResult,
)
from ftcal.runtime.errors import FtcalError


class NumpyLstsq:
    """A solver written against the protocol alone: numpy's QR/SVD lstsq on the dense scaled regressor."""

    name = "numpy-lstsq"
    penalty = "none"

    def fit(self, problem: ScaledProblem) -> SolverResult:
        a, b = problem.scaled_regressor()
        coef, _, rank, _ = np.linalg.lstsq(a, b, rcond=None)
        return SolverResult(coef, int(rank), float(np.linalg.cond(a)))


def test_every_solver_follows_the_protocol():
    for solver in (LeastSquares(), Ridge(1.0), Lasso(1.0), OsqpLeastSquares(), OsqpLasso(1.0), NumpyLstsq()):
        assert isinstance(solver, Solver)
        assert solver.penalty in limits.PENALTIES
    assert not isinstance(object(), Solver)


def test_a_new_solver_is_one_class(rng, ref_features):
    u = rng.uniform(-1, 1, (300, 3))
    y = ref_features(u, 2) @ rng.normal(size=(10, 2)) + 0.01 * rng.normal(size=(300, 2))
    model = CalibrationModel(2, solver=NumpyLstsq()).fit(u, y)
    expected = ref_features(u, 2) @ np.linalg.lstsq(ref_features(u, 2), y, rcond=None)[0]
    np.testing.assert_allclose(model.predict(u), expected, atol=1e-9)
    assert model.solver_info_["name"] == "numpy-lstsq" and model.solver_info_["lambda"] is None


def test_an_object_without_the_protocol_is_refused(rng):
    u = rng.uniform(-1, 1, (50, 2))
    with pytest.raises(FtcalError, match="Solver protocol"):
        CalibrationModel(1, solver="lasso").fit(u, u)


def test_injected_basis_equals_the_degree_shortcut(rng):
    u = rng.uniform(-1, 1, (200, 3))
    y = np.c_[u[:, 0] * u[:, 1], u[:, 2] ** 2]
    by_degree = CalibrationModel(2).fit(u, y)
    by_basis = CalibrationModel(basis=MonomialBasis(3, 2)).fit(u, y)
    np.testing.assert_array_equal(by_basis.coef_, by_degree.coef_)
    with pytest.raises(FtcalError, match="basis has 2 inputs"):
        CalibrationModel(basis=MonomialBasis(2, 2)).fit(u, y)
    with pytest.raises(FtcalError, match="contradicts"):
        CalibrationModel(3, basis=MonomialBasis(3, 2)).fit(u, y)


def test_clone_copies_parameters_not_fitted_state(rng):
    u = rng.uniform(-1, 1, (100, 2))
    model = CalibrationModel(2, na=0, normalization="maxabs").fit(u, u)
    copy = model.clone(degree=3)
    assert copy.get_params() == {**model.get_params(), "degree": 3}
    assert not hasattr(copy, "coef_")
    with pytest.raises(FtcalError, match="no parameter"):
        model.clone(order=2)


def test_cross_validation_uses_the_template(rng):
    # Every candidate inherits the template's ARX order: a fold model has past-output columns.
    n_groups, per = 4, 150
    u = rng.uniform(-1, 1, (n_groups * per, 2))
    y = np.c_[u[:, 0] + 0.5 * u[:, 1], u[:, 1]] + 0.01 * rng.normal(size=(n_groups * per, 2))
    groups = np.repeat(np.arange(n_groups), per)
    data = Dataset.from_arrays(u, y, groups=groups, segments=groups)
    template = CalibrationModel(na=1, nb=1)
    result = cross_validate(data, [Candidate(1, "none", None)], template=template, n_folds=2)
    best = fit_best(data, result, template=template)
    assert (best.layout_.na, best.layout_.nb) == (1, 1)
    # The CV score of the one candidate is the fold mean of its validation scores, each a real number.
    assert len(result.scores[0].fold_scores) == len(grouped_folds(groups, 2))


def test_schema_bounds_are_the_declared_limits():
    schema = json.loads(resources.files("ftcal").joinpath("schemas/model-1.json").read_text())
    spec = schema["properties"]["model"]["properties"]
    assert spec["degree"]["maximum"] == limits.MAX_DEGREE
    assert spec["na"]["maximum"] == spec["nb"]["maximum"] == limits.MAX_LAG
    assert tuple(spec["normalization"]["enum"]) == limits.NORMALIZATIONS


def test_library_and_cli_read_the_declared_limits(rng):
    from ftcal.cli import build_parser

    u = rng.uniform(-1, 1, (30, 2))
    with pytest.raises(FtcalError, match=rf"\[1, {limits.MAX_DEGREE}\]"):
        CalibrationModel(limits.MAX_DEGREE + 1).fit(u, u)
    with pytest.raises(FtcalError, match=rf"\[0, {limits.MAX_LAG}\]"):
        CalibrationModel(1, na=limits.MAX_LAG + 1).fit(u, u)
    fit = build_parser()._subparsers._group_actions[0].choices["fit"]
    choices = {a.dest: a.choices for a in fit._actions if a.choices}
    assert tuple(choices["normalization"]) == limits.NORMALIZATIONS
    assert tuple(choices["solver"]) == limits.SOLVERS


def test_limits_module_imports_nothing_heavy():
    import subprocess
    import sys

    code = "import sys, ftcal.core.limits; print('numpy' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"


DOCTEST_MODULES = ["ftcal.core.features", "ftcal.core.statistics", "ftcal.core.solvers.base", "ftcal.core.solvers.least_squares",
                   "ftcal.core.solvers.lasso", "ftcal.core.model.state", "ftcal.core.model.basis", "ftcal.core.metrics", "ftcal.core.select.candidates",
                   "ftcal.core.select.folds", "ftcal.core.select.poses", "ftcal.core.dataset",
                   "ftcal.core.normalization", "ftcal.core.directions", "ftcal.core.estimator",
                   "ftcal.core.precision"]


@pytest.mark.parametrize("name", DOCTEST_MODULES)
def test_docstring_examples_run(name):
    module = importlib.import_module(name)
    result = doctest.testmod(module, optionflags=doctest.NORMALIZE_WHITESPACE)
    assert result.attempted > 0, f"{name} has no examples"
    assert result.failed == 0


@pytest.mark.parametrize("family", ["polynomial", "mlp"])
def test_both_families_follow_sklearns_parameter_contract(family):
    # scikit-learn's own clone and its parameter checks (get_params/set_params round trip, no
    # validation in __init__) on each family, through one shared implementation.
    from sklearn.base import clone
    from sklearn.utils.estimator_checks import check_get_params_invariance, check_set_params

    from ftcal.core.mlp import MLPModel

    model = CalibrationModel(2, na=1) if family == "polynomial" else MLPModel(hidden=(8,), seed=3)
    copy = clone(model)
    assert copy is not model and copy.get_params(deep=False) == model.get_params(deep=False)
    check_get_params_invariance(type(model).__name__, model)
    check_set_params(type(model).__name__, model)
    with pytest.raises(FtcalError, match="has no parameter 'degreee'"):
        model.set_params(degreee=3)


def test_docs_api_lists_exactly_the_public_names():
    import re
    from pathlib import Path

    import ftcal

    page = (Path(__file__).parents[2] / "docs/api.md").read_text(encoding="utf-8")
    listed = set(re.findall(r"^\| `(\w+)` \|", page, flags=re.MULTILINE))
    assert listed == set(ftcal.__all__)
    assert set(ftcal.__all__) <= set(dir(ftcal))


def test_every_public_name_has_an_example_that_runs():
    import ftcal

    finder, runner = doctest.DocTestFinder(recurse=False), doctest.DocTestRunner(optionflags=doctest.NORMALIZE_WHITESPACE)
    for name in ftcal.__all__:
        obj = getattr(ftcal, name)
        assert "Examples\n" in (obj.__doc__ or ""), f"ftcal.{name} has no Examples section"
        module = importlib.import_module(obj.__module__)  # examples run in their own module, as doctest does
        tests = [t for t in finder.find(obj, name, globs=dict(vars(module))) if t.examples]
        assert tests, f"ftcal.{name} has no runnable example"
        for test in tests:
            runner.run(test)
    assert runner.failures == 0
