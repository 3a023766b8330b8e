"""`ftcal check --accept` tells a failure that is an offset alone from one a re-tare does not fix.

The test recordings are those of tests/data/test_evaluate_baseline.py (a tool at rest in several orientations,
known gain error, per-recording offsets, known noise), written one recording per file: a re-tare at the
file's first static hold removes its offset exactly, up to the noise of the hold's mean.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import ftcal
from test_evaluate_baseline import OUT, RAW, SIGMA, held_out, training_model

FTCAL = str(Path(sys.executable).with_name("ftcal"))


def write_recordings(folder: Path, offsets) -> list[str]:
    frame, _, _ = held_out(offsets=offsets)
    names = []
    for r, part in frame.groupby("segment"):
        names.append(f"rec{r}.parquet")
        part.drop(columns=["segment", "load"]).to_parquet(folder / names[-1])
    return names


def accept(folder: Path, names, model: str):
    # thresholds 6 sigma: the noise passes, a 1 N offset does not
    return subprocess.run([FTCAL, "check", "--accept", model, *names, "--max-force-error", str(6 * SIGMA),
                           "--max-torque-error", str(6 * SIGMA)], cwd=folder, capture_output=True, text=True,
                          timeout=300)


def test_an_offset_alone_is_named_with_what_the_re_tare_gives(tmp_path):
    offsets = np.tile([1.0, -1.5, 0.8, 0.2, -0.3, 0.25], (6, 1))
    names = write_recordings(tmp_path, offsets)
    ftcal.save_model(training_model(), tmp_path / "model.json")
    done = accept(tmp_path, names, "model.json")
    assert done.returncode == 1, done.stdout + done.stderr
    line = next(l for l in done.stdout.splitlines() if l.startswith("the failure is an offset alone"))
    # the offset removed is the raw offset seen through the model, (I + G)^-1 b, up to the hold's noise
    from test_evaluate_baseline import gain_error

    expected = np.linalg.inv(np.eye(6) + gain_error()) @ offsets[0]
    removed = line.split("offset removed: ")[1].split(")")[0].split()
    shown = np.array([float(v) for v in removed[1::2]])
    np.testing.assert_allclose(shown, expected, atol=0.02)
    rms = np.array([float(v) for v in line.split("RMS ")[1].split()[1::2]])
    assert np.all(rms < 1.6 * SIGMA)
    assert done.stdout.strip().splitlines()[-1].startswith("FAIL")  # the verdict itself is unchanged


def test_a_gain_error_is_not_called_an_offset(tmp_path):
    offsets = np.zeros((6, 6))
    names = write_recordings(tmp_path, offsets)
    frame, _, _ = held_out(offsets=offsets)
    # the vendor's matrix with its 4 % cross-talk: an identity model on the raw channels
    identity = ftcal.fit(frame.assign(**{o: frame[r] for o, r in zip(OUT, RAW)}), inputs=RAW, outputs=OUT).model
    ftcal.save_model(identity, tmp_path / "identity.json")
    done = accept(tmp_path, names, "identity.json")
    assert done.returncode == 1
    assert any(l.startswith("not an offset alone") for l in done.stdout.splitlines()), done.stdout
