"""The fit, evaluate and predict steps (ftcal.fit, ftcal.evaluate, ftcal.predict) against their commands.

References: the ``ftcal`` command run as a subprocess on the same generated files (every number of
its model file and of its ``--json`` must equal the Python step's), and numpy on the dense
regressor for the training error computed from the sufficient statistics.
"""

import json
import os
import re
import subprocess
import sys
import warnings

import numpy as np
import pandas as pd
import pytest
from conftest import sensor_like_data

import ftcal
from ftcal.core.dataset import DEFAULT_OUTPUTS
from ftcal.core.metrics import statistics_training_error
from ftcal.runtime.errors import OutOfRangeWarning

INPUTS = ("u1", "u2", "u3", "u4", "u5", "u6", "T")
FTCAL = os.path.join(os.path.dirname(sys.executable), "ftcal")
# Fields of a model file that name the moment or the program that wrote it, not the fit.
NOT_THE_FIT = {"time_utc", "sha256", "digest"}


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    """Four small tables (four groups), sensor-like inputs, outputs with noise."""
    folder = tmp_path_factory.mktemp("workflow")
    rng = np.random.default_rng(11)
    paths = []
    for index, n in enumerate((500, 700, 600, 800)):
        u, y = sensor_like_data(rng, n)
        y = y + rng.normal(0.0, 0.2, y.shape)
        path = folder / f"part{index}.parquet"
        pd.DataFrame(np.c_[u, y], columns=[*INPUTS, *DEFAULT_OUTPUTS]).to_parquet(path, index=False)
        paths.append(str(path))
    return paths


def command(*argv, cwd=None):
    env = dict(os.environ, FTCAL_PROGRESS="0")
    done = subprocess.run([FTCAL, *argv], capture_output=True, text=True, env=env, timeout=600, cwd=cwd)
    assert done.returncode == 0, done.stderr
    return done


def numbers_equal(a, b, path="") -> None:
    """Every number, string and list of two JSON documents equal (floats exactly), the time stamps aside."""
    if isinstance(a, dict):
        assert set(a) - NOT_THE_FIT == set(b) - NOT_THE_FIT, path
        for key in set(a) - NOT_THE_FIT:
            numbers_equal(a[key], b[key], f"{path}.{key}")
    elif isinstance(a, list):
        assert len(a) == len(b), path
        for index, (x, y) in enumerate(zip(a, b)):
            numbers_equal(x, y, f"{path}[{index}]")
    else:
        assert a == b, f"{path}: {a!r} != {b!r}"


def model_document(path):
    with open(path, encoding="utf-8") as handle:
        return json.load(handle)


def test_fit_from_python_writes_the_file_and_prints_the_text_of_the_command(files, tmp_path):
    target = tmp_path / "model.json"
    result = ftcal.fit(files, degree=2, output=target)
    python_doc = model_document(target)
    done = command("fit", *files, "--degree", "2", "-o", str(target))
    numbers_equal(python_doc, model_document(target))
    assert done.stdout == result.summary() + "\n"
    assert done.stderr.strip().splitlines()[-len(result.notes):] == result.notes
    assert result.output == str(target) and result.lines[-1] == f"wrote {target}"


def test_a_dataframe_and_a_dataset_fit_the_model_the_files_fit(files):
    by_files = ftcal.fit(files[:1], degree=2).model
    frame = pd.read_parquet(files[0])
    by_frame = ftcal.fit(frame, degree=2).model
    by_dataset = ftcal.fit(ftcal.load_dataset(files[0]), degree=2).model
    # The same normal equations; the in-memory path sums them in its own order.
    np.testing.assert_array_equal(by_frame.coef_, by_files.coef_)
    np.testing.assert_allclose(by_dataset.coef_, by_files.coef_, rtol=1e-9, atol=1e-9 * np.abs(by_files.coef_).max())


def test_degree_auto_from_python_gives_the_commands_selection(files, tmp_path):
    options = dict(degree="auto", max_degree=2, folds=2, penalties=("ridge",), lambdas=(1e-3, 1e-1))
    python_path, cli_path = tmp_path / "python.json", tmp_path / "cli.json"
    result = ftcal.fit(files, output=python_path, **options)
    done = command("fit", *files, "--degree", "auto", "--max-degree", "2", "--folds", "2", "--penalties", "ridge",
                   "--lambdas", "0.001,0.1", "-o", str(cli_path))
    python_doc, cli_doc = model_document(python_path), model_document(cli_path)
    # The cost estimate counts the CPU seconds already spent (it differs run to run); everything fitted is equal.
    for doc in (python_doc, cli_doc):
        doc["fit"]["solver"]["cross_validation"].pop("notes", None)
        doc.pop("sources", None)
    numbers_equal(python_doc, cli_doc)
    assert result.selection is not None
    printed = done.stdout.splitlines()
    assert printed[-1] == f"wrote {cli_path}" and result.lines[-1] == f"wrote {python_path}"
    # The estimate counts the CPU seconds spent so far; every other line is the same.
    lines = result.summary().splitlines()
    assert [line for line in printed[:-1] if not line.startswith("estimated work:")] == \
        [line for line in lines[:-1] if not line.startswith("estimated work:")]


def test_evaluate_from_python_gives_every_number_of_the_commands_json(files, tmp_path):
    model = tmp_path / "model.json"
    ftcal.fit(files[:2], degree=2, output=model)
    done = command("evaluate", str(model), *files[2:], "--json")
    result = ftcal.evaluate(str(model), files[2:])
    numbers_equal(json.loads(result.to_json()), json.loads(done.stdout))
    text = command("evaluate", str(model), *files[2:])
    assert text.stdout == result.summary() + "\n"
    # a model object and a DataFrame: the same numbers
    frame = pd.concat([pd.read_parquet(p) for p in files[2:]], ignore_index=True)
    again = ftcal.evaluate(ftcal.load_model(model), frame)
    np.testing.assert_allclose(again.metrics["rmse"], result.metrics["rmse"], rtol=1e-12)


def test_predict_from_python_writes_the_commands_file(files, tmp_path):
    model = tmp_path / "model.json"
    fitted = ftcal.fit(files[:2], degree=2, output=model).model
    command("predict", str(model), *files[2:], "-o", str(tmp_path / "cli.csv"))
    with warnings.catch_warnings():  # held-out files: a few samples beyond the training range (warned once)
        warnings.simplefilter("ignore", OutOfRangeWarning)
        result = ftcal.predict(str(model), files[2:], output=tmp_path / "python.csv")
        in_memory = ftcal.predict(fitted, files[2:])
    assert (tmp_path / "cli.csv").read_bytes() == (tmp_path / "python.csv").read_bytes()
    assert result.n_rows == 600 + 800 and result.to_dict()["n_rows"] == 1400
    written = pd.read_csv(tmp_path / "cli.csv")
    np.testing.assert_allclose(in_memory.predictions.to_numpy(), written.to_numpy(), rtol=1e-12, atol=1e-9)


def test_results_explain_themselves_and_the_steps_are_public(files):
    result = ftcal.fit(files[:1], degree=1)
    # The repr says what was fitted (the summary's model line), and how much more print() shows.
    assert repr(result).startswith("<FitResult: model: degree 1") and "print()" in repr(result)
    evaluation = ftcal.evaluate(result.model, files[:1])
    rmse = evaluation.metrics["rmse"][0]
    assert repr(evaluation).startswith(f"<EvaluationResult: {evaluation.metrics['n_samples']} samples; RMSE Fx {rmse:.4g} N")
    assert str(result) == result.summary()
    document = json.loads(result.to_json())
    assert document["n_samples"] == 500 and document["family"] == "polynomial"
    assert document["training_metrics"]["outputs"] == list(DEFAULT_OUTPUTS)
    assert "<pre>" in result._repr_html_()
    for name in ("fit", "evaluate", "predict", "FitResult", "EvaluationResult", "PredictionResult"):
        assert name in ftcal.__all__ and name in dir(ftcal)
    assert ftcal.fit.__module__ == "ftcal.workflow.fitting"


def test_bad_input_is_one_ftcal_error(files, tmp_path):
    with pytest.raises(ftcal.FtcalError, match="^folds goes with degree auto"):
        ftcal.fit(files, degree=2, folds=3)
    with pytest.raises(ftcal.FtcalError, match="must end in .json"):
        ftcal.fit(files, output=tmp_path / "model.txt")
    with pytest.raises(ftcal.FtcalError, match="expected a file name"):
        ftcal.fit(42)


@pytest.mark.parametrize("offset", [0.0, 20.0])
def test_training_error_from_the_statistics_equals_the_residuals(offset):
    # Dense regressor by hand (monomials up to degree 2 of 3 inputs, and a constant); least squares by
    # numpy; then a perturbed coefficient set (as a penalized fit would give): the formula holds for any.
    rng = np.random.default_rng(3)
    u = rng.uniform(-1.0, 1.0, (4000, 3))
    columns = [u[:, i] for i in range(3)] + [u[:, i] * u[:, j] for i in range(3) for j in range(i, 3)]
    a = np.column_stack(columns + [np.ones(len(u))])
    y = np.column_stack([np.sin(2 * u[:, 0]) + u[:, 1] ** 3, u[:, 2] * np.exp(u[:, 0]), 3 * u[:, 1]])
    y = y + offset + rng.normal(0.0, 0.05, y.shape)
    theta = np.linalg.lstsq(a, y, rcond=None)[0]
    names = ["Fx", "Fy", "Fz"]
    for coef in (theta, theta + rng.normal(0.0, 1e-2, theta.shape)):
        out = statistics_training_error(a.T @ a, a.T @ y, np.sum(y * y, axis=0), y.sum(axis=0), len(y), coef,
                                        np.ones(3), names)
        residual = y - a @ coef
        rmse = np.sqrt(np.mean(residual ** 2, axis=0))
        best = 1.0 - np.sqrt(np.mean(residual ** 2, axis=0) / np.var(y, axis=0))
        np.testing.assert_allclose(out["rmse"], rmse, rtol=1e-9)
        np.testing.assert_allclose(out["best_fit"], best, rtol=1e-9)
        assert out["force_error_norm_rmse"] == pytest.approx(np.sqrt(np.mean(np.sum(residual ** 2, axis=1))),
                                                             rel=1e-9)
        assert out["torque_error_norm_rmse"] is None


def test_a_streamed_static_fit_takes_its_training_error_from_the_statistics(files, tmp_path):
    # Against the residuals of the fitted model on the files read whole (numpy): RMSE and BestFit to 1e-9.
    result = ftcal.fit(files, degree=3)
    model = result.model
    data = ftcal.load_dataset(files)
    residual = data.outputs - model.predict(data.inputs)
    metrics = model.training_metrics_
    np.testing.assert_allclose(metrics["rmse"], np.sqrt(np.mean(residual ** 2, axis=0)), rtol=1e-9)
    best = 1.0 - np.sqrt(np.mean(residual ** 2, axis=0) / np.var(data.outputs, axis=0))
    np.testing.assert_allclose(metrics["best_fit"], best, rtol=1e-9)
    assert "max_abs_error" not in metrics  # needs the samples: ftcal evaluate
    assert any("from the fit's statistics" in line for line in result.lines)


def test_targets_far_from_zero_are_scored_in_a_pass(files, tmp_path):
    # yᵀy / ‖r‖² ~ 1e12 here: the statistics would cancel ~12 digits (STATISTICS_ERROR_DIGITS allows 7),
    # so the fit scores the samples instead, and its RMSE still equals numpy's on the residuals.
    frame = pd.read_parquet(files[0])
    frame[list(DEFAULT_OUTPUTS)] += 1e5
    path = tmp_path / "offset.parquet"
    frame.to_parquet(path, index=False)
    model = ftcal.fit(path, degree=2).model
    assert "max_abs_error" in model.training_metrics_
    residual = frame[list(DEFAULT_OUTPUTS)].to_numpy() - model.predict(frame[list(INPUTS)].to_numpy())
    np.testing.assert_allclose(model.training_metrics_["rmse"], np.sqrt(np.mean(residual ** 2, axis=0)), rtol=1e-9)


def test_report_from_python_writes_the_commands_page(files, tmp_path):
    from ftcal.workflow import report

    model = tmp_path / "model.json"
    ftcal.fit(files[:2], degree=1, output=model)
    done = command("report", str(model), *files[2:], "--train", files[0], "-o", str(tmp_path / "cli.html"))
    with warnings.catch_warnings():  # held-out files: a few samples beyond the training range
        warnings.simplefilter("ignore", OutOfRangeWarning)
        result = report([model], files[2:], tmp_path / "python.html", train=[files[0]])
    # Every table and number of the page; the figures (matplotlib names SVG elements at random) and the
    # minute the page was made aside.
    pages = [re.sub(r"<svg.*?</svg>", "<svg/>", (tmp_path / name).read_text(encoding="utf-8"), flags=re.S)
             for name in ("cli.html", "python.html")]
    pages = [re.sub(r"\d{4}-\d\d-\d\d \d\d:\d\d UTC", "(time)", page) for page in pages]
    assert pages[0] == pages[1] and "<table" in pages[0]
    assert result.n_models == 1 and result.n_validation_samples == 600 + 800
    assert done.stdout.replace("cli.html", "python.html") == result.summary() + "\n"
