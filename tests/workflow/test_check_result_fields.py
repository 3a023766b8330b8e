"""``CheckResult`` holds the check's report and numbers and renders its text from them (issue #43).

Truth: a tool of known mass held still in known orientations (conventions), and an affine sensor tested
against the model fitted to it (acceptance); the numbers the text states are checked against that truth
or a hand computation, and a result whose numbers changed renders the changed numbers.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pandas as pd
from scipy.spatial.transform import Rotation

from ftcal.check.accept import Thresholds
from ftcal.core.dataset import Dataset
from ftcal.core.model import CalibrationModel
from ftcal.files.model_files import save_model
from ftcal.workflow.checking import check_sensor

MASS, COM = 1.2, np.array([0.0, 0.0, 0.04])
AXES = ["Fx", "Fy", "Fz", "Tx", "Ty", "Tz"]
U = [f"u{i}" for i in range(1, 7)]


def test_the_conventions_text_follows_its_holds_and_report(tmp_path):
    rows, rng = [], np.random.default_rng(0)
    for k, rotation in enumerate(Rotation.random(8, random_state=3)):
        gravity = rotation.inv().apply([0.0, 0.0, -9.81])
        force = MASS * gravity
        wrench = np.r_[force, np.cross(COM, force)]
        rows += [[0.01 * (100 * k + i), *(wrench + 0.01 * rng.normal(size=6)), *gravity] for i in range(100)]
    path = tmp_path / "holds.csv"
    pd.DataFrame(rows, columns=["time", *U, "gx", "gy", "gz"]).to_csv(path, index=False)
    result = check_sensor(str(path), gravity_columns=("gx", "gy", "gz"))
    assert result.passed and result.run.n_holds == 8
    first = result.lines[0]
    assert first.startswith("8 static holds") and f"tool mass {result.report.mass:.4g} ±" in first
    assert abs(result.report.mass - MASS) < 0.01
    fewer = replace(result, run=replace(result.run, n_holds=5), report=replace(result.report, mass=2 * MASS))
    assert fewer.lines[0].startswith("5 static holds") and f"tool mass {2 * MASS:.4g} ±" in fewer.lines[0]
    assert result.lines[-1] == fewer.lines[-1] == \
        "no finding: sign, axes, frame, zeroing and torque reference look as declared"


def test_the_acceptance_text_follows_its_thresholds_and_errors(tmp_path):
    rng = np.random.default_rng(1)
    gains = np.eye(6) * 40.0 + 4.0 * rng.standard_normal((6, 6))
    w = rng.uniform(-1.0, 1.0, (3000, 6)) * [60, 60, 60, 4, 4, 4]
    raw = w @ gains.T + rng.normal(size=w.shape)
    model = CalibrationModel(degree=1).fit(Dataset.from_arrays(raw, w, input_names=U, output_names=AXES))
    save_model(model, tmp_path / "affine.json")
    loads = np.repeat([[0, 0, 0, 0, 0, 0], [40, -10, 30, 1, 2, -1], [-50, 20, -5, -3, 1, 2]], 200, axis=0)
    test_raw = loads @ gains.T + rng.normal(size=loads.shape)
    frame = pd.DataFrame(np.c_[test_raw, loads], columns=U + AXES).assign(pose=np.repeat(["a", "b", "c"], 200))
    frame.to_csv(tmp_path / "test.csv", index=False)
    result = check_sensor(str(tmp_path / "test.csv"), accept=str(tmp_path / "affine.json"), group_by="pose")
    # The RMS error per axis, by hand: the model's prediction against the loads.
    error = model.predict(test_raw) - loads
    rmse = np.sqrt(np.mean(error ** 2, axis=0))
    np.testing.assert_allclose(result.report.rmse, rmse, rtol=1e-9)
    fx = next(line for line in result.lines if line.startswith("Fx "))
    assert f"{rmse[0]:>12.4g}" in fx and result.lines[-1] == "PASS"
    assert f"on {len(frame)} samples in 3 pose(s)" in result.lines[0]
    # Thresholds below the errors: every axis over, and the text says so with the new threshold.
    strict = Thresholds(float(rmse[:3].min()) / 2, float(rmse[3:].min()) / 2, "given")
    tight = replace(result, report=replace(result.report, thresholds=strict))
    assert f"thresholds {strict.force:.4g} N, {strict.torque:.4g} N·m" in tight.lines[0]
    assert sum(line.endswith("  over") for line in tight.lines) == 6
    assert replace(result, run=replace(result.run, recorded=("h.sqlite", "SN1", 3))).lines[-1] == \
        "recorded in h.sqlite for sensor SN1 (3 calibration(s))"
