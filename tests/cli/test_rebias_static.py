"""``payload --rebias`` re-tares from the still samples only, like the identification (issue 28).

A recording of holds joined by moves; during a move the tool's acceleration adds an inertial
force the static model lacks (here 4 N along x at the peak, by construction). Truth: the bias
BIAS, mass MASS and centre of mass COM below, from hand statics in the sensor frame.
"""

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
from scipy.spatial.transform import Rotation, Slerp

FTCAL = str(Path(sys.executable).with_name("ftcal"))
G, MASS = 9.81, 1.3
COM = np.array([0.012, -0.025, 0.071])
BIAS = np.array([3.0, -2.0, 5.0, 0.1, -0.2, 0.05])
NOISE = np.array([0.05, 0.05, 0.05, 0.002, 0.002, 0.002])
RATE_HZ, HOLD_S, MOVE_S = 50.0, 4.0, 2.0


def holds_and_moves(seed=0, n_poses=12):
    rng = np.random.default_rng(seed)
    rots = Rotation.random(n_poses, random_state=seed + 1)
    hold, move = int(HOLD_S * RATE_HZ), int(MOVE_S * RATE_HZ)
    parts, inertial = [], []
    for k in range(n_poses):
        parts.append(Rotation.from_quat(np.repeat(rots[k].as_quat()[None], hold, axis=0)))
        inertial.append(np.zeros(hold))
        if k + 1 < n_poses:
            s = np.linspace(0, 1, move + 2)[1:-1]
            parts.append(Slerp([0, 1], rots[[k, k + 1]])(s))
            inertial.append(4.0 * np.sin(np.pi * s))  # N, along x, while the tool accelerates and brakes
    rot = Rotation.concatenate(parts)
    g = rot.inv().apply([0.0, 0.0, -G])
    extra = np.zeros((len(g), 6))
    extra[:, 0] = np.concatenate(inertial)
    wrench = np.c_[MASS * g, np.cross(COM, MASS * g)] + BIAS + extra + rng.normal(size=(len(g), 6)) * NOISE
    frame = pd.DataFrame(np.c_[np.arange(len(g)) / RATE_HZ, rot.as_quat(), wrench],
                         columns=["time", "qx", "qy", "qz", "qw", "u1", "u2", "u3", "u4", "u5", "u6"])
    return frame


def ftcal(*args):
    return subprocess.run([FTCAL, *map(str, args)], capture_output=True, text=True, timeout=300)


def test_rebias_on_the_identifications_own_recording_finds_no_drift(tmp_path):
    data = tmp_path / "run.csv"
    holds_and_moves().to_csv(data, index=False)
    done = ftcal("payload", data, "--orientation", "qx,qy,qz,qw", "--bias-drift", "none", "-o", tmp_path / "p.json")
    assert done.returncode == 0, done.stderr
    first = json.loads((tmp_path / "p.json").read_text())
    done = ftcal("payload", "--rebias", tmp_path / "p.json", data, "--orientation", "qx,qy,qz,qw",
                 "-o", tmp_path / "q.json")
    assert done.returncode == 0, done.stderr
    assert "within what the identification's uncertainty explains" in done.stdout, done.stdout
    assert "static samples:" in done.stdout
    second = json.loads((tmp_path / "q.json").read_text())
    # The same still samples and the same mass/COM: the same bias (to rounding), and close to the truth.
    np.testing.assert_allclose(second["force_bias"], first["force_bias"], atol=1e-6)
    np.testing.assert_allclose(second["force_bias"], BIAS[:3], atol=0.05)


def test_rebias_refuses_options_it_would_ignore(tmp_path):
    data = tmp_path / "run.csv"
    holds_and_moves(seed=3, n_poses=8).to_csv(data, index=False)
    assert ftcal("payload", data, "--orientation", "qx,qy,qz,qw", "-o", tmp_path / "p.json").returncode == 0
    for extra, option in ((["--dynamic"], "--dynamic"), (["--bias-drift", "linear"], "--bias-drift"),
                          (["--group-by", "time"], "--group-by"), (["--frame", "tool"], "--frame"),
                          (["--temperature", "u1"], "--temperature")):
        done = ftcal("payload", "--rebias", tmp_path / "p.json", data, "--orientation", "qx,qy,qz,qw",
                     "-o", tmp_path / "q.json", *extra)
        lines = done.stderr.strip().splitlines()
        assert done.returncode == 2 and len(lines) == 1 and option in lines[0], done.stderr
        assert not (tmp_path / "q.json").exists()
