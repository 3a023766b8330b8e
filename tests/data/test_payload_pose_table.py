"""A table of static poses, one averaged row each with a time column (issue 27, item 6).

The "recorded poses" format of ROS gravity-compensation packages: 100 poses, one row per pose,
rows seconds apart. Before the fix ``payload`` (which reads motion from the orientation over the
time column) saw every row "move" (a 30° step over 5 s is faster than a still threshold) and
refused with "no static hold ... give --keep-moving". Truth comes from the simulation: a mass
with a known centre of mass under gravity rotated into the sensor frame by scipy, plus a bias
and Gaussian noise of known size.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
from scipy.spatial.transform import Rotation

FTCAL = str(Path(sys.executable).with_name("ftcal"))
SRC = str(Path(__file__).resolve().parents[2] / "src")
MASS, COM = 1.2, np.array([0.01, -0.02, 0.09])
FORCE_BIAS, TORQUE_BIAS = np.array([3.0, -2.0, 5.0]), np.array([0.1, -0.05, 0.02])
NOISE_F, NOISE_T = 0.05, 0.003


def pose_table(path: Path, n: int = 100, seed: int = 27) -> Path:
    rng = np.random.default_rng(seed)
    rotations = Rotation.random(n, random_state=seed)  # sensor -> world, world gravity along -z
    g_sensor = rotations.inv().apply(np.array([0.0, 0.0, -9.81]))
    force = MASS * g_sensor + FORCE_BIAS + rng.normal(0.0, NOISE_F, (n, 3))
    torque = np.cross(COM, MASS * g_sensor) + TORQUE_BIAS + rng.normal(0.0, NOISE_T, (n, 3))
    q = rotations.as_quat()  # x, y, z, w
    table = pd.DataFrame(np.c_[force, torque, q], columns=["u1", "u2", "u3", "u4", "u5", "u6",
                                                            "qx", "qy", "qz", "qw"])
    table.insert(0, "time", 1.7e9 + 5.0 * np.arange(n) + rng.uniform(0, 0.5, n))  # a pose every ~5 s
    table.to_csv(path, index=False)
    return path


def run(*args, cwd):
    return subprocess.run([FTCAL, *map(str, args)], capture_output=True, text=True, cwd=cwd,
                          env={**os.environ, "PYTHONPATH": SRC}, timeout=300)


def test_one_row_per_pose_is_recognised_and_payload_recovers_the_truth(tmp_path):
    table = pose_table(tmp_path / "poses.csv")
    done = run("payload", table, "--orientation", "qx,qy,qz,qw", "--time", "time", "-o", "p.json", cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    said = done.stdout + done.stderr
    assert "a table of static poses" in said and "100 hold(s) in 100 rows" in said
    assert "--keep-moving" not in done.stderr
    result = json.loads((tmp_path / "p.json").read_text())
    se = result["stderr"]
    # Within 4 standard errors of the simulation's truth, and those errors of the size the noise
    # gives: sigma_F / (g sqrt(n / 3)) for the mass with random gravity directions (~0.009 kg).
    assert abs(result["mass"] - MASS) < 4 * se["mass"]
    assert 0.3 < se["mass"] / (NOISE_F / (9.81 * np.sqrt(100 / 3))) < 3
    np.testing.assert_array_less(np.abs(np.array(result["com"]) - COM), 4 * np.array(se["com"]))
    np.testing.assert_array_less(np.abs(np.array(result["force_bias"]) - FORCE_BIAS), 4 * np.array(se["force_bias"]))


def test_a_recording_sampled_fast_is_not_a_pose_table(tmp_path):
    """The same poses joined by 100 Hz moves stay a recording whose moves are found and excluded."""
    rng = np.random.default_rng(5)
    rotations = Rotation.random(4, random_state=5)
    rows, t = [], 0.0
    for k in range(4):
        for _ in range(100):  # 1 s still
            rows.append((t, rotations[k]))
            t += 0.01
        if k < 3:
            for s in np.linspace(0, 1, 100)[1:-1]:  # 1 s slerp to the next pose
                rows.append((t, Rotation.from_rotvec(s * (rotations[k + 1] * rotations[k].inv()).as_rotvec())
                             * rotations[k]))
                t += 0.01
    time = np.array([r[0] for r in rows])
    rot = Rotation.concatenate([r[1] for r in rows])
    g_sensor = rot.inv().apply([0.0, 0.0, -9.81])
    wrench = np.c_[MASS * g_sensor, np.cross(COM, MASS * g_sensor)] + rng.normal(0, 0.01, (len(rows), 6))
    frame = pd.DataFrame(np.c_[time, wrench, rot.as_quat()],
                         columns=["time", "u1", "u2", "u3", "u4", "u5", "u6", "qx", "qy", "qz", "qw"])
    frame.to_csv(tmp_path / "moves.csv", index=False)
    done = run("payload", "moves.csv", "--orientation", "qx,qy,qz,qw", "-o", "p.json", cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    said = done.stdout + done.stderr
    assert "a table of static poses" not in said and "4 hold(s)" in said and "excluded" in said
