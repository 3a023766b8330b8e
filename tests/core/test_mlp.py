"""The MLP family: training, reproducibility, model files, ONNX (onnxruntime) and C (compiled) to 1e-9."""

from __future__ import annotations

import json
import shutil
import subprocess
import warnings

import numpy as np
import pandas as pd
import pytest

from ftcal.cli import main
from ftcal.core.dataset import Dataset
from ftcal.core.mlp import EarlyStoppingWarning, MLPModel, _glorot, _objective
from ftcal.core.model import CalibrationModel
from ftcal.files.model_files import load_model
from ftcal.files.model_files import load_model, save_model
from ftcal.runtime.errors import FtcalError

CC = shutil.which("cc")
needs_cc = pytest.mark.skipif(CC is None, reason="no system C compiler `cc` on PATH")
INPUTS = ("u1", "u2", "u3")
OUTPUTS = ("Fx", "Fy", "Fz", "Tx", "Ty", "Tz")


def truth(u: np.ndarray) -> np.ndarray:
    """A smooth nonlinear wrench of three raw inputs (offsets and units far from [-1, 1])."""
    x = (u - np.array([5000.0, -200.0, 30.0])) / np.array([800.0, 50.0, 8.0])
    return np.c_[40.0 * np.sin(2.0 * x[:, 0]) * np.cos(x[:, 1]), 30.0 * x[:, 0] * x[:, 1],
                 25.0 * np.tanh(2.0 * x[:, 1]) + 5.0 * x[:, 2], 2.0 * x[:, 0] ** 2, 1.5 * np.sin(3.0 * x[:, 2]),
                 x[:, 0] - x[:, 1] * x[:, 2]]


def sensor(n=1600, groups=8, seed=0, noise=0.0) -> Dataset:
    rng = np.random.default_rng(seed)
    u = np.array([5000.0, -200.0, 30.0]) + rng.uniform(-1.0, 1.0, (n, 3)) * np.array([800.0, 50.0, 8.0])
    y = truth(u) + noise * rng.standard_normal((n, 6))
    return Dataset.from_arrays(u, y, input_names=INPUTS, output_names=OUTPUTS,
                               groups=(np.arange(n) * groups // n).astype(str))


@pytest.fixture(scope="module")
def fitted(tmp_path_factory):
    """A small network fitted once, saved: (model, path, held-out inputs)."""
    data = sensor()
    model = MLPModel((8, 6), max_iter=60, n_folds=4, seed=3).fit(data)
    path = tmp_path_factory.mktemp("mlp") / "mlp.json"
    save_model(model, path)
    u = sensor(300, seed=9).inputs
    return model, path, u


def test_gradient_matches_central_differences():
    rng = np.random.default_rng(1)
    x, t, sizes = rng.normal(size=(30, 3)), rng.normal(size=(30, 2)), (3, 5, 4, 2)
    params = _glorot(sizes, 0) + 0.1 * rng.normal(size=_glorot(sizes, 0).size)
    for activation in ("tanh", "relu"):
        _, grad = _objective(params, x, t, sizes, activation, 0.03)
        step = 1e-6
        numeric = [(_objective(params + e, x, t, sizes, activation, 0.03)[0]
                    - _objective(params - e, x, t, sizes, activation, 0.03)[0]) / (2 * step)
                   for e in np.eye(params.size) * step]
        np.testing.assert_allclose(grad, numeric, rtol=1e-5, atol=1e-8)


def test_same_seed_same_weights_other_seed_other_weights():
    data = sensor(400)
    first, again, other = (MLPModel((5,), max_iter=30, n_folds=2, seed=s).fit(data) for s in (7, 7, 8))
    assert all(np.array_equal(a, b) for a, b in zip(first.weights_, again.weights_))
    assert not np.array_equal(first.weights_[0], other.weights_[0])


def test_mlp_beats_affine_on_held_out_groups_of_a_nonlinear_sensor():
    data = sensor(2400, groups=8, noise=0.2)
    held_out = np.isin(data.groups, ["6", "7"])
    train, test = data.subset(~held_out), data.subset(held_out)
    exact = truth(test.inputs)  # the noise-free truth, independent of both fits
    mlp = MLPModel((16,), max_iter=300, n_folds=3, seed=0).fit(train)
    affine = CalibrationModel(1).fit(train)

    def rmse(model):
        return float(np.sqrt(np.mean((model.predict(test, warn_out_of_range=False) - exact) ** 2)))

    assert rmse(mlp) < 0.25 * rmse(affine)
    # Early stopping chose a checkpoint on the grouped folds and scored it fold by fold.
    assert mlp.cv_["n_folds"] == 3 and mlp.cv_["iterations"] in mlp.cv_["checkpoints"]
    assert len(mlp.cv_["fold_scores"]) == 3


def test_one_group_trains_all_iterations_with_a_warning():
    data = Dataset.from_arrays(sensor(200).inputs, sensor(200).outputs, input_names=INPUTS, output_names=OUTPUTS)
    with pytest.warns(EarlyStoppingWarning, match="at least two groups"):
        model = MLPModel((3,), max_iter=7).fit(data)
    assert model.cv_ is None and model.n_iter_ <= 7


def test_json_round_trip_predicts_bit_identically(fitted):
    model, path, u = fitted
    doc = json.loads(path.read_text())
    assert doc["family"] == "mlp" and [len(layer["biases"]) for layer in doc["parameters"]["layers"]] == [8, 6, 6]
    loaded = load_model(path)
    assert isinstance(loaded, MLPModel) and loaded.exports == {"json", "c", "onnx"}
    assert np.array_equal(loaded.predict(u, warn_out_of_range=False), model.predict(u, warn_out_of_range=False))
    assert loaded.training_metrics_["rmse"] == pytest.approx(model.training_metrics_["rmse"], rel=1e-15)


def test_onnx_matches_predict_in_onnxruntime(fitted, tmp_path):
    ort = pytest.importorskip("onnxruntime")
    model, path, u = fitted
    assert main(["convert", str(path), "--to", "onnx", "-o", str(tmp_path / "m.onnx")]) == 0
    session = ort.InferenceSession(str(tmp_path / "m.onnx"), providers=["CPUExecutionProvider"])
    got = session.run(None, {"u": u})[0]
    expected = model.predict(u, warn_out_of_range=False)
    assert got.dtype == np.float64
    np.testing.assert_allclose(got, expected, rtol=1e-9, atol=1e-9 * np.abs(expected).max())


DRIVER = r"""
#include <stdio.h>
#include "mlp_net.h"
int main(void)
{
    double u[MLP_NET_N_INPUTS], y[MLP_NET_N_OUTPUTS];
    int i;
    for (;;) {
        for (i = 0; i < MLP_NET_N_INPUTS; ++i)
            if (scanf("%lf", &u[i]) != 1) return 0;
        mlp_net_predict(u, y);
        for (i = 0; i < MLP_NET_N_OUTPUTS; ++i) printf("%.17g ", y[i]);
        printf("%d\n", mlp_net_in_range(u));
    }
}
"""


@needs_cc
@pytest.mark.parametrize("activation", ["tanh", "relu"])
def test_c_compiles_strictly_and_matches_predict(tmp_path, activation):
    train = sensor(400)
    model = MLPModel((7, 5), activation=activation, max_iter=40, n_folds=2, seed=1).fit(train)
    path = tmp_path / "m.json"
    save_model(model, path)
    assert main(["convert", str(path), "--to", "c", "--name", "mlp_net", "-o", str(tmp_path / "c")]) == 0
    (tmp_path / "c" / "main.c").write_text(DRIVER)
    exe = tmp_path / "c" / "run"
    subprocess.run([CC, "-std=c99", "-O2", "-Wall", "-Wextra", "-Werror", "-pedantic", "main.c", "mlp_net.c",
                    "-lm", "-o", str(exe)], cwd=tmp_path / "c", check=True)
    u = np.r_[sensor(200, seed=5).inputs, [[9000.0, 0.0, 30.0]]]  # the last row is outside the training box
    text = "\n".join(" ".join(format(v, ".17g") for v in row) for row in u)
    out = np.loadtxt(subprocess.run([str(exe)], input=text, capture_output=True, text=True, check=True)
                     .stdout.splitlines())
    expected = model.predict(u, warn_out_of_range=False)
    np.testing.assert_allclose(out[:, :-1], expected, rtol=1e-9, atol=1e-9 * np.abs(expected).max())
    inside = np.all((u >= train.inputs.min(axis=0)) & (u <= train.inputs.max(axis=0)), axis=1)
    assert out[:, -1].tolist() == inside.astype(float).tolist() and not inside[-1]


def test_cli_fit_predict_evaluate_and_refusals(tmp_path, capsys):
    data = sensor(800, groups=4)
    frame = pd.DataFrame(np.c_[data.inputs, data.outputs], columns=INPUTS + OUTPUTS)
    frame["case"] = data.groups
    table = tmp_path / "train.csv"
    frame.to_csv(table, index=False, float_format="%.17g")
    out = tmp_path / "mlp.json"
    argv = ["fit", str(table), "--inputs", ",".join(INPUTS), "--group-by", "case", "--family", "mlp",
            "--hidden", "6", "--max-iter", "30", "--folds", "2", "-o", str(out)]
    assert main(argv) == 0
    printed = capsys.readouterr().out
    assert "np1" in printed and "mlp 6 tanh" in printed and "2 grouped folds" in printed
    model = load_model(out)
    assert main(["predict", str(out), str(table), "-o", str(tmp_path / "p.csv")]) == 0
    predicted = pd.read_csv(tmp_path / "p.csv")[list(OUTPUTS)].to_numpy()
    np.testing.assert_allclose(predicted, model.predict(data.inputs), rtol=1e-12, atol=1e-12)
    capsys.readouterr()
    held = sensor(300, seed=4)
    pd.DataFrame(np.c_[held.inputs, held.outputs], columns=INPUTS + OUTPUTS).to_csv(
        tmp_path / "held.csv", index=False, float_format="%.17g")
    assert main(["evaluate", str(out), str(tmp_path / "held.csv"), "--json"]) == 0
    result = json.loads(capsys.readouterr().out)
    error = held.outputs[:, :3] - model.predict(held.inputs, warn_out_of_range=False)[:, :3]
    by_hand = np.sqrt(np.mean(np.sum(error ** 2, axis=1)))
    assert result["force_error_norm_rmse"] == pytest.approx(by_hand, rel=1e-9)
    refusals = [(["--hidden", "0"], "--hidden 0: expected 1 to 4 comma-separated layer sizes"),
                (["--hidden", "32,x"], "--hidden 32,x: expected"),
                (["--weight-decay", "-1"], "--weight-decay -1: must be a finite number >= 0"),
                (["--max-iter", "0"], "--max-iter 0: must be a whole number"),
                (["--degree", "3"], "--family mlp does not take --degree")]
    for extra, fragment in refusals:
        assert main(argv[:-2] + extra + ["-o", str(tmp_path / "bad.json")]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and fragment in err[0], err
    assert main(["fit", str(table), "--hidden", "8", "-o", str(tmp_path / "bad.json")]) == 2
    assert capsys.readouterr().err.strip() == "ftcal fit: error: --hidden go with --family mlp."
    assert main(["convert", str(out), "--to", "paper-xml", "-o", str(tmp_path / "m.xml")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == ["ftcal convert: error: --to paper-xml: the mlp family cannot be exported there; "
                   "it exports c, json, onnx."]
    assert not (tmp_path / "bad.json").exists() and not (tmp_path / "m.xml").exists()


def test_library_refuses_bad_options():
    data = sensor(100)
    for options, fragment in (({"hidden": (0,)}, "'hidden' parameter of MLPModel must be an int in [1, 256]"),
                              ({"hidden": ()}, "non-empty sequence"),
                              ({"weight_decay": -1.0}, "'weight_decay' parameter of MLPModel must be a finite number >= 0"),
                              ({"activation": "sigmoid"}, "'activation' parameter of MLPModel must be one of")):
        with pytest.raises(FtcalError, match=fragment.replace("[", r"\[").replace("]", r"\]")):
            MLPModel(**{"max_iter": 5, **options}).fit(data)


@pytest.mark.slow
def test_report_compares_the_mlp_with_polynomials(fitted, tmp_path):
    model, path, _ = fitted
    data = sensor(400, seed=11)
    frame = pd.DataFrame(np.c_[data.inputs, data.outputs], columns=INPUTS + OUTPUTS)
    frame.to_csv(tmp_path / "validation.csv", index=False, float_format="%.17g")
    affine = tmp_path / "np1.json"
    with warnings.catch_warnings():
        save_model(CalibrationModel(1).fit(sensor()), affine)
    assert main(["report", str(path), str(affine), str(tmp_path / "validation.csv"), "-o",
                 str(tmp_path / "r.html")]) == 0
    html = (tmp_path / "r.html").read_text()
    # Runs are named by file; the MLP is its own family in the tables and figures.
    assert "mlp-lbfgs" in html
    assert "the MLP models" in html and "np1" in html


def test_cli_comparison_uses_the_mlps_own_folds():
    """The affine row printed beside the MLP is scored on the very folds early stopping used."""
    from ftcal.core.metrics import error_norm_rmse
    from ftcal.core.select import Candidate, cross_validate, grouped_folds

    data = sensor(600, groups=6, noise=0.5)
    affine = Candidate(1, "none", None)
    scores = cross_validate(data, [affine], n_folds=3, objective="force").score_of(affine)
    by_hand = []
    for held in grouped_folds(data.groups, 3):
        model = CalibrationModel(1).fit(data.subset(~held))
        prediction = model.predict(data.subset(held), warn_out_of_range=False)
        by_hand.append(error_norm_rmse(data.outputs[held, :3], prediction[:, :3]))
    np.testing.assert_allclose(scores.fold_scores, by_hand, rtol=1e-8)
