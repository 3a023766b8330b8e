"""Help texts, option warnings, lazy imports, the table loader and training-segment fingerprints."""

import hashlib
import json
import subprocess
import sys
import warnings
from pathlib import Path

import cli_data as cd
import numpy as np
import pandas as pd

from ftcal import Dataset, load_dataset
from ftcal.cli import main
from ftcal.core.fingerprint import find_training_segments, segment_fingerprints
from ftcal.runtime.errors import FtcalWarning

FTCAL = str(Path(sys.executable).with_name("ftcal"))


def help_text(*command: str) -> str:
    done = subprocess.run([FTCAL, *command, "--help"], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    return " ".join(done.stdout.split())  # argparse wraps lines


def test_help_names_the_environment_and_the_units():
    top = help_text()
    assert "FTCAL_PROGRESS" in top and "FTCAL_THREADS" in top and "XDG_CACHE_HOME" in top
    dataset = help_text("dataset")
    assert "gravity in base-frame axes, m/s²" in dataset
    assert "frame length in samples" in dataset
    assert "--cache-dir" in dataset and "--cache-dir" in help_text("expected")
    fit = help_text("fit")
    assert "1 to 10 (the paper fits 1 to 5)" in fit


def test_lasso_without_degree_warns_that_it_fits_degree_one(tmp_path, capfd):
    data = tmp_path / "d.csv"
    cd.training_frame(np.random.default_rng(3), 300).to_csv(data, index=False)
    out = tmp_path / "m.json"
    with warnings.catch_warnings():
        warnings.simplefilter("always", FtcalWarning)
        assert main(["fit", str(data), "--lasso", "1", "-o", str(out)]) == 0
    assert "warning: --lasso without --degree fits degree 1" in capfd.readouterr().err
    assert json.loads(out.read_text())["model"]["degree"] == 1
    with warnings.catch_warnings():
        warnings.simplefilter("error", FtcalWarning)  # with --degree: no warning
        assert main(["fit", str(data), "--degree", "2", "--lasso", "1", "-o", str(out)]) == 0


def test_light_commands_import_no_heavy_library(tmp_path):
    data = tmp_path / "d.csv"
    # without load cases: on grouped tables an explicit degree is also cross-validated against affine (issue 44),
    # with the selection's machinery, which uses SciPy; the solve itself must not
    cd.training_frame(np.random.default_rng(4), 300).drop(columns="load").to_csv(data, index=False)
    script = f"""
import sys
from ftcal.cli import build_parser, main
build_parser()
assert "numpy" not in sys.modules, "ftcal --help imports numpy"
assert main(["fit", {str(data)!r}, "--degree", "2", "-o", {str(tmp_path / "m.json")!r}]) == 0
# SciPy too: a least-squares fit with fewer than 500 terms solves with numpy alone.
heavy = [m for m in ("pandas", "jsonschema", "matplotlib", "idyntree", "scipy", "importlib.metadata")
         if m in sys.modules]
assert not heavy, heavy
"""
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr


def test_load_dataset_reads_like_pandas(tmp_path):
    frame = cd.training_frame(np.random.default_rng(5), 200)
    path = tmp_path / "t.csv"
    frame.to_csv(path, index=False)
    data = load_dataset(str(path), segment_by="rec", group_by="load")
    by_pandas = pd.read_csv(path)
    np.testing.assert_array_equal(data.inputs, by_pandas[list(cd.INPUTS)].to_numpy())
    np.testing.assert_array_equal(data.outputs, by_pandas[list(cd.OUTPUTS)].to_numpy())
    assert list(data.groups) == list(by_pandas["load"])
    assert len(data.segment_bounds()) == by_pandas["rec"].nunique()
    no_t = tmp_path / "no_t.csv"
    frame.drop(columns="T").to_csv(no_t, index=False)
    assert load_dataset([str(no_t)]).input_names == cd.INPUTS[:6]


def test_fingerprints_follow_the_documented_format():
    rng = np.random.default_rng(6)
    u, y = rng.normal(size=(50, 7)), rng.normal(size=(50, 6))
    data = Dataset.from_arrays(u, y, segments=np.repeat([0, 1], 25))
    prints = segment_fingerprints(data)
    assert [p["rows"] for p in prints] == [25, 25]
    # docs/formats.md §7: sha256 of the float64 values, inputs then outputs, row-major, little-endian
    by_hand = hashlib.sha256(np.hstack([u[25:], y[25:]]).astype("<f8").tobytes()).hexdigest()
    assert prints[1]["sha256"] == by_hand
    # found again inside other data, after unrelated rows, as one segment
    other = Dataset.from_arrays(np.vstack([rng.normal(size=(7, 7)), u[25:]]),
                                np.vstack([rng.normal(size=(7, 6)), y[25:]]))
    assert find_training_segments(other, prints) == [1]
    changed = Dataset.from_arrays(u[25:] + np.r_[np.zeros((24, 7)), np.full((1, 7), 1e-9)], y[25:])
    assert find_training_segments(changed, prints) == []
