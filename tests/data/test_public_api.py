"""The declared public API: one name per idea (old names warn for one release and give the new name's
result), and both model families pass scikit-learn's own estimator checks where they apply, through one
shared implementation (core.estimator.EstimatorParams)."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from sklearn.metrics import r2_score
from sklearn.utils.estimator_checks import parametrize_with_checks

import ftcal
from ftcal.core.estimator import EstimatorParams
from ftcal.core.mlp import MLPModel
from ftcal.core.model import CalibrationModel
from ftcal.files import model_files, model_json
from ftcal.runtime.errors import FtcalError

# The checks that cannot apply, and why (scikit-learn reports any other failure as a test failure).
NOT_APPLICABLE = {
    "check_estimators_unfitted": "ftcal raises its own NotFittedError (an FtcalError, so a ValueError, one line "
                                 "for the CLI); scikit-learn's check wants sklearn.exceptions.NotFittedError, and "
                                 "scikit-learn is not a run-time dependency",
    "check_regressors_train": "predictions are always (n_samples, n_outputs): a wrench has six outputs, and the "
                              "model files, exports and metrics keep one-output models 2-D too",
    "check_fit1d": "a 1-D input array is one input channel (n_samples,), by design",
    "check_fit2d_predict1d": "a 1-D input array is one input channel (n_samples,), by design",
}


def expected_failures(estimator):
    return NOT_APPLICABLE


# ftcal's models do not inherit sklearn.base.BaseEstimator (scikit-learn is not a run-time dependency);
# scikit-learn warns about it, and the checks below are what that warning asks to verify.
NOT_A_BASE_ESTIMATOR = "Estimator .* does not inherit from `sklearn.base.BaseEstimator`"
with warnings.catch_warnings():
    warnings.filterwarnings("ignore", message=NOT_A_BASE_ESTIMATOR, category=UserWarning)
    SKLEARN_CHECKS = parametrize_with_checks(
        [CalibrationModel(2), MLPModel(hidden=(4,), seed=0, max_iter=30, early_stopping=False)],
        expected_failed_checks=expected_failures)


# scikit-learn's random data are outside the training range now and then, or ill-posed for a degree-2
# basis: ftcal says so with an FtcalWarning, which is right, not a failure of the contract.
@pytest.mark.filterwarnings("ignore::ftcal.runtime.errors.FtcalWarning")
@pytest.mark.filterwarnings(f"ignore:{NOT_A_BASE_ESTIMATOR}:UserWarning")
@SKLEARN_CHECKS
def test_sklearn_estimator_checks(estimator, check):
    check(estimator)


def test_both_families_share_one_implementation_of_the_contract():
    for name in ("get_params", "set_params", "clone", "score", "n_features_in_", "__sklearn_tags__", "__repr__"):
        assert getattr(CalibrationModel, name) is getattr(MLPModel, name) is getattr(EstimatorParams, name)


@pytest.mark.parametrize("model", [CalibrationModel(2), MLPModel(hidden=(6,), seed=1, max_iter=60, early_stopping=False)])
def test_score_is_sklearns_r2_and_metrics_is_the_papers_dict(model):
    rng = np.random.default_rng(4)
    u = rng.uniform(-1.0, 1.0, (300, 2))
    y = np.c_[u[:, 0] ** 2 + u[:, 1], u[:, 0] - u[:, 1]] + 0.05 * rng.normal(size=(300, 2))
    model.fit(u, y)
    test = rng.uniform(-0.9, 0.9, (100, 2))
    truth = np.c_[test[:, 0] ** 2 + test[:, 1], test[:, 0] - test[:, 1]]
    prediction = model.predict(test)
    assert model.score(test, truth) == pytest.approx(r2_score(truth, prediction), abs=1e-12)
    weights = rng.uniform(0.5, 2.0, 100)
    assert model.score(test, truth, weights) == pytest.approx(r2_score(truth, prediction, sample_weight=weights),
                                                              abs=1e-12)
    data = ftcal.Dataset.from_arrays(test, truth)
    assert model.score(data) == pytest.approx(r2_score(truth, prediction), abs=1e-12)
    metrics = model.metrics(data, warn_out_of_range=False)
    rmse = np.sqrt(np.mean((truth - prediction) ** 2, axis=0))
    np.testing.assert_allclose(metrics["rmse"], rmse, rtol=1e-9)
    with pytest.raises(FtcalError, match="needs reference outputs"):
        model.score(test)


def test_a_model_reads_as_its_constructor_call():
    from ftcal.core.solvers import Lasso

    assert repr(CalibrationModel()) == "CalibrationModel()"
    assert repr(CalibrationModel(3, na=2, normalization="maxabs")) == "CalibrationModel(degree=3, na=2, normalization='maxabs')"
    assert repr(MLPModel(hidden=(8,), seed=3)) == "MLPModel(hidden=(8,), seed=3)"
    assert repr(CalibrationModel(2, solver=Lasso(1.0))).startswith("CalibrationModel(degree=2, solver=")


def test_bad_arrays_are_refused_in_one_line():
    import scipy.sparse

    u = np.linspace(-1.0, 1.0, 20)[:, None]
    with pytest.raises(FtcalError, match="sparse input is not supported"):
        CalibrationModel(1).fit(scipy.sparse.csr_matrix(np.c_[u, u]), np.c_[u, u])
    with pytest.raises(FtcalError, match="Complex data not supported"):
        MLPModel(hidden=(2,)).fit(u + 1j, u)
    model = CalibrationModel(1).fit(np.c_[u, 2 * u ** 2], u)
    with pytest.raises(FtcalError, match="X has 3 features, but CalibrationModel is expecting 2 features as "
                                         "input: one column per input u1, u2"):
        model.predict(np.c_[u, u, u])
    assert model.n_features_in_ == 2 and not hasattr(CalibrationModel(1), "n_features_in_")


def model_on_a_line():
    u = np.array([[0.0], [1.0], [2.0]])
    return CalibrationModel(1).fit(u, 2.0 * u + 1.0)


# old name -> (the new callable, how to call both); the new names are the public ones
@pytest.mark.parametrize("old, new, new_name", [
    (model_files.read_model, model_files.load_model, "ftcal.load_model"),
    (model_json.load_model, model_files.load_model, "ftcal.load_model"),
    (model_files.read_model_file, model_files.load_model_file, "ftcal.files.model_files.load_model_file"),
    (model_json.load_model_file, model_files.load_model_file, "ftcal.files.model_files.load_model_file"),
])
def test_old_reader_names_warn_and_read_the_same(old, new, new_name, tmp_path):
    path = tmp_path / "m.json"
    ftcal.save_model(model_on_a_line(), path)
    with pytest.warns(DeprecationWarning) as caught:
        result = old(path)
    assert len(caught) == 1 and str(caught[0].message).endswith(f"use {new_name}.")
    assert old.deprecated_for == new_name and old.__wrapped__ is new if callable(getattr(old, "__wrapped__", None)) \
        else old.deprecated_for == new_name
    expected = new(path)
    model, reference = (result, expected) if not hasattr(result, "model") else (result.model, expected.model)
    np.testing.assert_array_equal(model.predict(np.array([[1.5]])), reference.predict(np.array([[1.5]])))
    assert float(model.predict(np.array([[1.5]]))[0, 0]) == pytest.approx(4.0, abs=1e-12)  # 2·1.5 + 1


@pytest.mark.parametrize("old", [model_files.write_model, model_json.save_model])
def test_old_writer_names_warn_and_write_the_same_file(old, tmp_path):
    model = model_on_a_line()
    ftcal.save_model(model, tmp_path / "new.json")
    with pytest.warns(DeprecationWarning, match="use ftcal.save_model"):
        if old is model_files.write_model:
            old(model, tmp_path / "old.json", "json")
        else:
            old(model, tmp_path / "old.json")
    new, legacy = (model_json.read_model_json(tmp_path / name) for name in ("new.json", "old.json"))
    assert model_json.digest(model_json.model_document(new.model)) == model_json.digest(
        model_json.model_document(legacy.model))


def test_the_public_names_are_the_new_ones():
    assert ftcal.load_model is model_files.load_model and ftcal.save_model is model_files.save_model
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # the public names never warn
        path = None
        import tempfile
        from pathlib import Path

        path = Path(tempfile.mkdtemp()) / "m.xml"
        ftcal.save_model(model_on_a_line(), path, "paper-xml")
        assert float(ftcal.load_model(path).predict(np.array([[0.5]]))[0, 0]) == pytest.approx(2.0, rel=1e-9)


def test_read_dataset_is_load_dataset_under_its_old_name(tmp_path):
    import pandas as pd

    from ftcal.data.tables import read_dataset

    u = np.linspace(0.0, 1.0, 5)
    pd.DataFrame({"u1": u, "Fx": 3.0 * u, "run": ["a", "a", "b", "b", "b"]}).to_csv(tmp_path / "t.csv", index=False)
    new = ftcal.load_dataset(tmp_path / "t.csv", inputs=["u1"], outputs=["Fx"], group_by="run")
    with pytest.warns(DeprecationWarning, match="ftcal.data.tables.read_dataset is deprecated .* use ftcal.load_dataset"):
        old = read_dataset([tmp_path / "t.csv"], ["u1"], ["Fx"], group_by="run")
    np.testing.assert_array_equal(old.inputs, u[:, None])
    np.testing.assert_array_equal(old.outputs, 3.0 * u[:, None])
    assert list(old.groups) == list(new.groups) == ["a", "a", "b", "b", "b"]
    # without the output columns, for prediction
    pd.DataFrame({"u1": u}).to_csv(tmp_path / "inputs.csv", index=False)
    assert ftcal.load_dataset(tmp_path / "inputs.csv", inputs=["u1"], require_outputs=False).outputs is None
