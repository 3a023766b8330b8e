"""``ftcal payload`` in one pass (issue 32): the convention check's holds come from the tables as the fit
reads them, rotations per hold without SciPy, and the jackknife's t quantile without ``scipy.special``.

Every number checked comes from outside the code under test: hold means of noise-free readings are the
readings themselves, rotations are SciPy's, t quantiles are ``scipy.stats.t``'s and the printed tables'.
"""

import json
import os
import subprocess
import sys
import warnings

import numpy as np
import pandas as pd
import pytest
from scipy import stats
from scipy.spatial.transform import Rotation, Slerp

from ftcal.check.conventions import HoldCollector, read_holds
from ftcal.cli import main
from ftcal.core.jackknife import t_cdf, t_quantile, t_scale
from ftcal.data.holds import rotation_matrices
from ftcal.payload.kinematics import OrientationSource
from ftcal.payload.tables import read_payload_tables
from ftcal.runtime.errors import FtcalWarning

G = 9.81
MASS, COM = 0.8, np.array([0.02, 0.01, 0.05])
BIAS = np.array([1.0, -2.0, 0.5, 0.05, -0.02, 0.01])
RATE, HOLD_ROWS, MOVE_ROWS = 100.0, 300, 60
WRENCH = ("Fx", "Fy", "Fz", "Tx", "Ty", "Tz")


def noise_free_table(path, seed: int, n_holds: int = 5, start_time: float = 0.0):
    """A table of still poses joined by slerp moves, readings without noise; returns the poses' rotations."""
    poses = Rotation.random(n_holds, random_state=seed)
    quats = []
    for k in range(n_holds):
        if k:
            move = Slerp([0.0, 1.0], Rotation.concatenate([poses[k - 1], poses[k]]))
            quats.append(move(np.linspace(0.0, 1.0, MOVE_ROWS + 2)[1:-1]).as_quat())
        quats.append(np.repeat(poses[k].as_quat()[None], HOLD_ROWS, axis=0))
    q = np.concatenate(quats)
    gravity = Rotation.from_quat(q).inv().apply([0.0, 0.0, -G])
    wrench = np.c_[MASS * gravity, np.cross(COM, MASS * gravity)] + BIAS
    frame = pd.DataFrame(wrench, columns=list(WRENCH))
    frame[["qx", "qy", "qz", "qw"]] = q
    frame["time"] = start_time + np.arange(len(q)) / RATE
    frame.to_parquet(path)
    return poses


def test_rotation_matrices_are_scipys():
    q = np.random.default_rng(3).normal(size=(500, 4)) * 2.5  # any norm: both normalise
    np.testing.assert_allclose(rotation_matrices(q), Rotation.from_quat(q).as_matrix(), rtol=0, atol=1e-14)


@pytest.mark.parametrize("dof", [1, 2, 3, 4, 5, 8, 19, 20, 99, 499, 501, 5000, 10 ** 6])
def test_t_distribution_matches_scipy(dof):
    # The sum has dof/2 terms: its rounding grows with dof (quantiles that far out use an expansion).
    for t in (-7.5, -1.3, 0.0, 0.4, 2.0, 30.0):
        assert t_cdf(t, dof) == pytest.approx(stats.t.cdf(t, dof), abs=1e-13 if dof <= 5000 else 1e-11)
    for p in (0.6, 0.9, 0.975, 0.999):
        assert t_quantile(p, dof) == pytest.approx(stats.t.ppf(p, dof), rel=1e-11)


def test_t_scale_from_printed_tables():
    # t_{19, 0.975} = 2.093 and t_{4, 0.975} = 2.776 (printed tables), z_{0.975} = 1.960
    assert t_scale(19) == pytest.approx(2.093 / 1.960, abs=1e-3)
    assert t_scale(4) == pytest.approx(2.776 / 1.960, abs=1e-3)


def test_collected_holds_are_the_hand_means_and_those_of_a_second_read(tmp_path):
    paths = [tmp_path / "a.parquet", tmp_path / "b.parquet"]
    poses = noise_free_table(paths[0], seed=1)
    poses = Rotation.concatenate([poses, noise_free_table(paths[1], seed=2, start_time=1000.0)])
    source = OrientationSource(("qx", "qy", "qz", "qw"), G)
    collector = HoldCollector(source, wrench=WRENCH, time="time")
    recording = read_payload_tables(paths, source, wrench=WRENCH, time="time", select=collector)
    assert recording.n_samples == sum(len(pd.read_parquet(p)) for p in paths)  # no rows chosen by the collector
    held = collector.averages()
    assert held.n_holds == len(poses)
    # Noise-free readings: each hold's mean is the reading of its pose, its rotation the pose's.
    gravity = poses.inv().apply([0.0, 0.0, -G])
    np.testing.assert_allclose(held.wrench, np.c_[MASS * gravity, np.cross(COM, MASS * gravity)] + BIAS, atol=1e-9)
    np.testing.assert_allclose(held.gravity, gravity, atol=1e-9)
    np.testing.assert_allclose(held.rotation, poses.as_matrix(), atol=1e-9)
    # The same holds as reading the files again (the check's own route, ftcal check's).
    again = read_holds(paths, source, wrench=WRENCH, time="time")
    for name in ("wrench", "gravity", "rotation", "noise"):
        np.testing.assert_allclose(getattr(held, name), getattr(again, name), rtol=0, atol=1e-12)
    for name in ("start", "stop"):
        np.testing.assert_array_equal(getattr(held, name), getattr(again, name))


def test_collector_keeps_the_fits_selection_and_the_first_error(tmp_path):
    path = tmp_path / "a.parquet"
    noise_free_table(path, seed=4)
    source = OrientationSource(("qx", "qy", "qz", "qw"), G)
    first_rows = lambda frame, kinematics, where: np.arange(len(frame)) < 100  # noqa: E731
    collector = HoldCollector(source, first_rows, wrench=WRENCH, time="stamp")  # no column 'stamp'
    recording = read_payload_tables([path], source, wrench=WRENCH, select=collector)
    assert recording.n_samples == 100
    with pytest.raises(Exception, match="stamp"):
        collector.averages()


def test_payload_reads_each_table_once(tmp_path, monkeypatch):
    import ftcal.data.tables as tables

    paths = [tmp_path / "a.parquet", tmp_path / "b.parquet"]
    noise_free_table(paths[0], seed=5)
    noise_free_table(paths[1], seed=6, start_time=1000.0)
    reads = []
    real = tables.read_table
    monkeypatch.setattr(tables, "read_table", lambda path, *a, **k: reads.append(str(path)) or real(path, *a, **k))
    with warnings.catch_warnings():
        warnings.simplefilter("error", FtcalWarning)  # good data: no convention warning
        assert main(["payload", *map(str, paths), "--inputs", ",".join(WRENCH), "--orientation", "qx,qy,qz,qw",
                     "--bias-drift", "none", "-o", str(tmp_path / "p.json")]) == 0
    assert sorted(reads) == sorted(map(str, paths))
    payload = json.loads((tmp_path / "p.json").read_text())
    assert json.dumps(payload).count("mass") and abs(_mass(payload) - MASS) < 1e-9


def _mass(payload):
    stack = [payload]
    while stack:
        item = stack.pop()
        if isinstance(item, dict):
            if isinstance(item.get("mass"), (int, float)):
                return item["mass"]
            stack.extend(item.values())
    raise AssertionError("no mass in the payload file")


def test_payload_imports_no_scipy(tmp_path):
    path = tmp_path / "a.parquet"
    noise_free_table(path, seed=7)
    code = ("import sys\nfrom ftcal.cli import main\n"
            f"assert main(['payload', {str(path)!r}, '--inputs', {','.join(WRENCH)!r}, '--orientation', "
            f"'qx,qy,qz,qw', '--time', 'time', '-o', {str(tmp_path / 'p.json')!r}]) == 0\n"
            "print(sorted(m for m in sys.modules if m == 'scipy' or m.startswith('scipy.')))")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          env=dict(os.environ, FTCAL_PROGRESS="0"))
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.strip().splitlines()[-1] == "[]"
