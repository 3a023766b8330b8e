"""What the data can determine (ftcal.core.excitation): the span of the reference wrenches, the span of
the training inputs (out-of-range beyond the box), the payload regressor. Truth from physics: one rigid tool
with its centre of mass on the sensor's z axis gives T = c × F, so Tz = 0, Tx = -h Fy and Ty = h Fx."""

import json
import warnings

import numpy as np
import pandas as pd
import pytest
from scipy.spatial.transform import Rotation

from ftcal.cli import main
from ftcal.core.dataset import Dataset
from ftcal.core.excitation import Spread, output_excitation, regressor_excitation, span_distance
from ftcal.core.model import CalibrationModel
from ftcal.files.model_files import load_model
from ftcal.files.model_files import save_model
from ftcal.runtime.errors import FtcalError, FtcalWarning, OutOfRangeWarning

OUTPUTS = ["Fx", "Fy", "Fz", "Tx", "Ty", "Tz"]
INPUTS = ["u1", "u2", "u3", "u4", "u5", "u6"]


def tool_wrenches(n, mass, com, seed):
    gravity = Rotation.random(n, random_state=seed).inv().apply([0.0, 0.0, -9.81])
    return np.c_[mass * gravity, np.cross(com, mass * gravity)]


def calibration_table(wrench, seed=0):
    """Raw gauges r = M⁻¹ w + noise: an affine sensor the fit should invert."""
    rng = np.random.default_rng(seed)
    mixing = np.eye(6) + 0.1 * np.random.default_rng(42).standard_normal((6, 6))
    raw = np.linalg.solve(mixing, wrench.T).T + rng.normal(0.0, 0.01, wrench.shape)
    return pd.DataFrame(np.c_[raw, wrench], columns=INPUTS + OUTPUTS), mixing


def test_one_rigid_tool_spans_three_directions_and_the_warning_names_them():
    excitation = output_excitation(Spread.of(tool_wrenches(800, 1.2, [0.0, 0.0, 0.1], 1)), OUTPUTS)
    assert excitation.n_excited == 3
    assert sorted(excitation.missing) == sorted(["force along x and torque about y (only in a fixed ratio)",
                                                 "force along y and torque about x (only in a fixed ratio)",
                                                 "torque about z"])
    text = excitation.warning()
    assert text.startswith("reference wrenches span 3 of 6 directions; ")
    assert "torque about z never excited" in text and "add loads or poses that twist the sensor" in text
    assert "other lever arms" in text


def test_several_tools_and_loads_excite_every_direction():
    parts = [tool_wrenches(300, m, c, seed) for seed, (m, c) in enumerate(
        [(1.2, [0.0, 0.0, 0.1]), (2.0, [0.08, -0.05, 0.02]), (0.7, [-0.06, 0.09, -0.04])])]
    excitation = output_excitation(Spread.of(np.vstack(parts)), OUTPUTS)
    assert excitation.n_excited == 6 and excitation.warning() is None


def test_spread_merges_exactly_and_constant_outputs_are_refused():
    x = np.random.default_rng(0).normal(3.0, 2.0, (1000, 4))
    merged = Spread.of(x[:123]) + Spread.of(x[123:700]) + Spread.of(x[700:])
    np.testing.assert_allclose(merged.mean, x.mean(axis=0), rtol=1e-12)
    np.testing.assert_allclose(merged.covariance, np.cov(x.T, bias=True), rtol=1e-10)
    with pytest.raises(FtcalError, match="reference outputs Fx,Fy,Fz,Tx,Ty,Tz are constant: nothing to fit"):
        output_excitation(Spread.of(np.ones((10, 6))), OUTPUTS)


def test_span_distance_is_the_mahalanobis_distance():
    rng = np.random.default_rng(1)
    x = rng.normal(size=(5000, 3)) @ np.array([[2.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 0.5, 0.1]])
    spread = Spread.of(x)
    probe = rng.normal(size=(5, 3))
    centred = probe - x.mean(axis=0)
    expected = np.einsum("ij,jk,ik->i", centred, np.linalg.inv(np.cov(x.T, bias=True)), centred)
    np.testing.assert_allclose(span_distance(spread, probe), expected, rtol=1e-8)


def test_fit_on_one_rigid_tool_warns_and_flags_a_push_it_never_saw(tmp_path, capsys):
    frame, mixing = calibration_table(tool_wrenches(2000, 1.2, [0.0, 0.0, 0.1], 1))
    frame.to_csv(tmp_path / "rigid.csv", index=False)
    model_path = tmp_path / "rigid.json"
    with warnings.catch_warnings():
        warnings.simplefilter("always", FtcalWarning)
        assert main(["fit", str(tmp_path / "rigid.csv"), "--inputs", ",".join(INPUTS), "-o", str(model_path)]) == 0
    captured = capsys.readouterr()
    assert "excitation: reference wrenches span 3 of 6 directions" in captured.out
    warned = [line for line in captured.err.splitlines() if line.startswith("warning: reference wrenches span")]
    assert len(warned) == 1 and "torque about z never excited" in warned[0] and "twist the sensor" in warned[0]
    # A pure 10 N push along x: its raw gauges stay inside the training box, but not inside its span.
    push = np.linalg.solve(mixing, np.array([10.0, 0, 0, 0, 0, 0]))[None, :]
    model = load_model(model_path)
    inside_box = np.all((push >= model.input_range_[:, 0]) & (push <= model.input_range_[:, 1]))
    assert inside_box
    assert model.out_of_span(push).all() and model.out_of_range(push).all()
    # the training samples themselves are inside
    assert not model.out_of_range(frame[INPUTS].to_numpy()).any()
    with pytest.warns(OutOfRangeWarning, match=r"1 of 1 sample\(s\) inside the training range lies outside the "
                                               "span of the training inputs"):
        model.predict(push)
    pd.DataFrame(push, columns=INPUTS).to_csv(tmp_path / "push.csv", index=False)
    with warnings.catch_warnings():
        warnings.simplefilter("always", FtcalWarning)
        assert main(["predict", str(model_path), str(tmp_path / "push.csv"), "-o", str(tmp_path / "p.csv")]) == 0
    assert "1 of 1 sample(s) inside the training range lies outside the span of the training inputs" in \
        capsys.readouterr().err


def test_model_files_keep_the_span_and_old_files_check_the_range_only(tmp_path):
    frame, mixing = calibration_table(tool_wrenches(500, 1.2, [0.0, 0.0, 0.1], 2))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", FtcalWarning)
        model = CalibrationModel(1).fit(Dataset.from_arrays(frame[INPUTS].to_numpy(), frame[OUTPUTS].to_numpy(),
                                                            input_names=tuple(INPUTS)))
    save_model(model, tmp_path / "m.json")
    loaded = load_model(tmp_path / "m.json")
    np.testing.assert_allclose(loaded.input_spread_.mean, frame[INPUTS].to_numpy().mean(axis=0), rtol=1e-12)
    push = np.linalg.solve(mixing, np.array([10.0, 0, 0, 0, 0, 0]))[None, :]
    assert loaded.out_of_span(push).all()
    # a file written before the span was recorded: valid, and only the box is checked
    doc = json.loads((tmp_path / "m.json").read_text())
    del doc["fit"]["input_spread"]
    from ftcal.files.model_json import digest

    doc.pop("sha256")
    doc["sha256"] = digest(doc)
    (tmp_path / "old.json").write_text(json.dumps(doc))
    old = load_model(tmp_path / "old.json")
    assert old.input_spread_ is None and not old.out_of_span(push).any()
    assert not old.out_of_range(push).any()


def test_payload_regressor_excitation():
    # Gram of a regressor whose third column copies the first: one direction of three is not determined.
    a = np.random.default_rng(0).normal(size=(100, 3)) * [1.0, 50.0, 1.0]
    a[:, 2] = 2.0 * a[:, 0]
    singular, n = regressor_excitation(a.T @ a)
    assert n == 2 and singular[0] == 1.0 and singular[2] < 1e-6
    # scaling a column (other units) changes nothing
    b = a * [1.0, 1e-3, 1.0]
    np.testing.assert_allclose(regressor_excitation(b.T @ b)[0], singular, atol=1e-6)


def test_fit_refuses_outputs_that_never_vary(tmp_path, capsys):
    frame, _ = calibration_table(np.tile([[1.0, 2.0, 3.0, 0.1, 0.2, 0.3]], (50, 1)))
    frame.to_csv(tmp_path / "flat.csv", index=False)
    assert main(["fit", str(tmp_path / "flat.csv"), "--inputs", ",".join(INPUTS), "-o", str(tmp_path / "m.json")]) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 and "are constant: nothing to fit a calibration to" in lines[0]
    assert not (tmp_path / "m.json").exists()
