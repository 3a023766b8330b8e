"""One name per idea (issue 29, item 4): the sensor columns a step reads are `--inputs` / ``inputs=``
everywhere; ``--wrench`` / ``wrench=``, the old spelling, still works, with one notice.

Expected values are physical: a 1.5 kg tool hanging at a known centre of mass, seen in 10 still
poses with no bias, weighs 1.5 kg, and compensating it leaves a zero contact wrench.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from scipy.spatial.transform import Rotation

import ftcal
from ftcal.files.payload_json import load_payload
from ftcal.runtime.errors import FtcalError

FTCAL = str(Path(sys.executable).with_name("ftcal"))
MASS, COM = 1.5, np.array([0.01, -0.02, 0.06])
COLUMNS = ["Fx", "Fy", "Fz", "Tx", "Ty", "Tz"]  # not the default u1..u6: the step must be told
GRAVITY = ("gx", "gy", "gz")


@pytest.fixture
def poses(tmp_path):
    """10 still poses of 60 samples each, the wrench of the tool alone, gravity in the sensor frame."""
    rows = []
    for k, rotation in enumerate(Rotation.random(10, random_state=7)):
        gravity = rotation.inv().apply([0.0, 0.0, -9.81])
        force = MASS * gravity
        rows += [[0.01 * (60 * k + i), *force, *np.cross(COM, force), *gravity] for i in range(60)]
    path = tmp_path / "poses.csv"
    pd.DataFrame(rows, columns=["time", *COLUMNS, *GRAVITY]).to_csv(path, index=False)
    return path


def test_payload_compensate_and_check_take_inputs_and_the_old_wrench_keyword(poses, tmp_path):
    new = ftcal.identify_payload(str(poses), inputs=COLUMNS, gravity_columns=GRAVITY)
    assert new.mass == pytest.approx(MASS, rel=1e-9)
    with pytest.warns(FutureWarning, match="wrench= is now inputs="):
        old = ftcal.identify_payload(str(poses), wrench=COLUMNS, gravity_columns=GRAVITY)
    assert old.mass == new.mass
    with pytest.raises(FtcalError, match="inputs: given twice"):
        ftcal.identify_payload(str(poses), inputs=COLUMNS, wrench=COLUMNS, gravity_columns=GRAVITY)

    new.save(tmp_path / "tool.json")
    contact = ftcal.compensate(tmp_path / "tool.json", str(poses), inputs=COLUMNS, gravity_columns=GRAVITY)
    assert np.abs(contact.contact).max() < 1e-6  # N and N·m: nothing but the tool's weight
    with pytest.warns(FutureWarning, match="wrench= is now inputs="):
        again = ftcal.compensate(tmp_path / "tool.json", str(poses), wrench=COLUMNS, gravity_columns=GRAVITY)
    np.testing.assert_array_equal(again.contact, contact.contact)

    checked = ftcal.check_sensor(str(poses), inputs=COLUMNS, gravity_columns=GRAVITY)
    assert checked.report.mass == pytest.approx(MASS, rel=1e-6)
    with pytest.warns(FutureWarning, match="wrench= is now inputs="):
        old_check = ftcal.check_sensor(str(poses), wrench=COLUMNS, gravity_columns=GRAVITY)
    assert old_check.report.mass == checked.report.mass


def run(*args, cwd):
    return subprocess.run([FTCAL, *args], cwd=cwd, capture_output=True, text=True, timeout=300)


def test_the_commands_read_wrench_as_inputs_with_one_notice(poses, tmp_path):
    columns = ",".join(COLUMNS)
    gravity = ["--gravity-columns", ",".join(GRAVITY)]
    new = run("payload", str(poses), "--inputs", columns, *gravity, "-o", "new.json", cwd=tmp_path)
    assert new.returncode == 0, new.stderr
    assert "notice" not in new.stderr
    old = run("payload", str(poses), "--wrench", columns, *gravity, "-o", "old.json", cwd=tmp_path)
    assert old.returncode == 0, old.stderr
    notices = [line for line in old.stderr.splitlines() if line.startswith("notice:")]
    assert notices == ["notice: --wrench is now --inputs (the old spelling still works)"], old.stderr
    assert old.stdout == new.stdout  # the same payload, printed the same way
    assert load_payload(tmp_path / "old.json").mass == pytest.approx(MASS, rel=1e-9)

    for command in (["compensate", "new.json", str(poses), *gravity, "-o", "contact.csv"],
                    ["check", str(poses), *gravity]):
        done = run(*command, "--wrench", columns, cwd=tmp_path)
        assert done.returncode == 0, done.stderr
        assert sum(line.startswith("notice: --wrench is now --inputs") for line in done.stderr.splitlines()) == 1
    contact = pd.read_csv(tmp_path / "contact.csv")
    assert np.abs(contact[COLUMNS].to_numpy()).max() < 1e-6

    both = run("payload", str(poses), "--inputs", columns, "--wrench", columns, *gravity, "-o", "both.json",
               cwd=tmp_path)
    assert both.returncode == 2 and len(both.stderr.strip().splitlines()) == 1, both.stderr
    assert "given twice" in both.stderr and not (tmp_path / "both.json").exists()


def arx_tables(folder):
    """Three recordings of a first-order sensor (y_k = 0.5 y_{k-1} + 2 u_k), numbered 0, 1, 2 in the
    'segment' column as ftcal dataset numbers them, in one file; the third also alone in another file."""
    rng = np.random.default_rng(3)
    parts = []
    for segment, n in enumerate((120, 150, 130)):
        u = rng.uniform(-1.0, 1.0, n)
        y = np.zeros(n)
        y[0] = 2.0 * u[0]
        for k in range(1, n):
            y[k] = 0.5 * y[k - 1] + 2.0 * u[k]
        parts.append(pd.DataFrame({"u1": u, "Fx": y, "segment": segment}))
    whole, third = folder / "three.parquet", folder / "third.parquet"
    pd.concat(parts, ignore_index=True).to_parquet(whole)
    parts[2].to_parquet(third)
    return str(whole), str(third)


def test_fit_evaluate_and_predict_use_the_segment_column_by_default(tmp_path):
    whole, third = arx_tables(tmp_path)
    keywords = dict(inputs=["u1"], outputs=["Fx"], degree=1, na=1, nb=0)
    fitted = ftcal.fit(whole, output=tmp_path / "arx.json", **keywords)
    named = ftcal.fit(whole, segment_by="segment", **keywords)
    assert any(note.startswith("segments: the tables' 'segment' column") for note in fitted.notes)
    assert not any(note.startswith("segments:") for note in named.notes)
    # One warm-up row per recording (na = 1 never reaches across a recording's start).
    assert fitted.model.training_metrics_["n_samples"] == 400 - 3 == named.model.training_metrics_["n_samples"]
    np.testing.assert_array_equal(fitted.model.coef_, named.model.coef_)

    # The model file's training fingerprints are per recording: the same segments are found in the data.
    with pytest.warns(ftcal.FtcalWarning, match="contains 3 of the 3 training segments"):
        scores = ftcal.evaluate(tmp_path / "arx.json", whole)
    assert scores.metrics["n_samples"] == 400 - 3  # the same segments as the fit: one warm-up row each
    assert scores.summary().splitlines()[0].startswith("segments: the tables' 'segment' column")
    # ... and the third file holds one of the three.
    with pytest.warns(ftcal.FtcalWarning, match="contains 1 of the 3 training segments"):
        ftcal.evaluate(tmp_path / "arx.json", third)
    predicted = ftcal.predict(tmp_path / "arx.json", whole)
    assert any(note.startswith("segments: the tables' 'segment' column") for note in predicted.notes)
