"""`ftcal payload` says what its standard errors leave out (the sensor's gain), and identifies on a calibration.

A tool of known mass and centre of mass at rest in 24 orientations (quaternion columns), white noise of
known size; the sensor reads its wrench (1 + e) times too large. The mass shift measured between the runs
with and without the gain error is compared with the sensitivity the printout gives.
"""

from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from scipy.spatial.transform import Rotation

import ftcal

FTCAL = str(Path(sys.executable).with_name("ftcal"))
RAW = ["u1", "u2", "u3", "u4", "u5", "u6"]
OUT = ["Fx", "Fy", "Fz", "Tx", "Ty", "Tz"]
MASS, COM = 1.2, np.array([0.01, -0.015, 0.06])
BIAS = np.array([1.5, -0.8, 2.0, 0.05, -0.03, 0.02])


def poses(seed: int = 4, n: int = 24, per_pose: int = 20) -> tuple[np.ndarray, np.ndarray]:
    """(wrench the tool applies plus the bias, quaternions), ``per_pose`` noisy samples per orientation."""
    rng = np.random.default_rng(seed)
    rotations = Rotation.random(n, random_state=seed)
    g = np.repeat(rotations.inv().apply([0.0, 0.0, -9.81]), per_pose, axis=0)
    force = MASS * g
    wrench = np.column_stack([force, np.cross(COM, force)]) + BIAS
    wrench += rng.normal(0.0, [0.05, 0.05, 0.05, 0.003, 0.003, 0.003], wrench.shape)
    return wrench, np.repeat(rotations.as_quat(), per_pose, axis=0)


def table(wrench, quaternions, columns=RAW) -> pd.DataFrame:
    frame = pd.DataFrame(wrench, columns=columns)
    frame[["qx", "qy", "qz", "qw"]] = quaternions
    frame["pose"] = np.repeat(np.arange(len(wrench) // 20), 20)
    return frame


def payload(tmp_path, frame, name, *extra):
    frame.to_parquet(tmp_path / f"{name}.parquet")
    done = subprocess.run([FTCAL, "payload", f"{name}.parquet", "--orientation", "qx,qy,qz,qw", "--keep-moving",
                           "--group-by", "pose", "-o", f"{name}.json", *extra], cwd=tmp_path, capture_output=True,
                          text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    return done.stdout, json.loads((tmp_path / f"{name}.json").read_text())


@pytest.mark.parametrize("torques_too", [True, False])
def test_the_printed_gain_sensitivity_is_the_shift_a_gain_error_makes(tmp_path, torques_too):
    wrench, q = poses()
    e = 0.03
    gain = np.r_[np.full(3, 1 + e), np.full(3, 1 + e if torques_too else 1.0)]
    right, right_file = payload(tmp_path, table(wrench, q), "right")
    wrong, wrong_file = payload(tmp_path, table(wrench * gain, q), "wrong")
    measured = wrong_file["mass"] - right_file["mass"]
    line = next(l for l in right.splitlines() if l.startswith("gain: "))
    assert "assume the sensor's gain is right" in line
    per_unit = float(re.search(r"e·m = ([0-9.]+) kg × e", line).group(1))
    # The shift of a 3 % gain error, measured in simulation, is what the printout predicts: e x m
    assert measured == pytest.approx(e * per_unit, rel=0.02)
    # ... and many times the standard error the printout gives, which cannot see it
    se = right_file["stderr"]["mass"]
    assert measured > 10 * se
    assert "gain is right" in right_file["fit"]["standard_errors"]  # the file says it too
    if torques_too:  # a gain shared by forces and torques leaves the centre of mass where it was
        np.testing.assert_allclose(wrong_file["com"], right_file["com"], atol=1e-4)
    del wrong


def test_calibration_identifies_on_the_calibrated_wrench_in_one_command(tmp_path):
    rng = np.random.default_rng(9)
    mixing = np.eye(6) + 0.05 * rng.standard_normal((6, 6))  # raw channels: a cross-talking sensor
    # the calibration: fitted on a workbench set with known wrenches
    y = rng.normal(0.0, 15.0, (3000, 6))
    bench = pd.DataFrame(np.column_stack([y @ mixing.T + rng.normal(0, 0.01, y.shape), y]), columns=RAW + OUT)
    ftcal.save_model(ftcal.fit(bench, inputs=RAW, outputs=OUT).model, tmp_path / "cal.json")
    wrench, q = poses(seed=5)
    raw = table(wrench @ mixing.T, q)
    one, one_file = payload(tmp_path, raw, "raw", "--calibration", "cal.json")
    assert "wrench: cal.json applied to u1,u2,u3,u4,u5,u6" in one
    # the true tool, within 3 standard errors
    assert abs(one_file["mass"] - MASS) < 3 * one_file["stderr"]["mass"]
    np.testing.assert_allclose(one_file["force_bias"], BIAS[:3], atol=3 * max(one_file["stderr"]["force_bias"]))
    # without the calibration the raw channels give another tool
    _, uncalibrated = payload(tmp_path, raw, "uncal")
    assert abs(uncalibrated["mass"] - MASS) > 10 * one_file["stderr"]["mass"]
    bad = subprocess.run([FTCAL, "payload", "raw.parquet", "--orientation", "qx,qy,qz,qw", "--calibration", "cal.json",
                          "--inputs", "u1,u2,u3,u4,u5,u6", "-o", "x.json"], cwd=tmp_path, capture_output=True,
                         text=True, timeout=120)
    assert bad.returncode == 2 and len(bad.stderr.strip().splitlines()) == 1 and "--calibration" in bad.stderr
