"""Metamorphic tests: changes that only move rounding leave ftcal's text and files as they were.

A stranger's CPU (another OpenBLAS kernel, AVX-512 or not) changes every floating-point result in its
last bits; so do these changes, which need no other machine:

- every number of the input table multiplied by 1 + 1e-12·N(0, 1) (far below any sensor's resolution);
- the rows of each group (load case, pose) in another order (static models: the order carries nothing);
- the tables read in chunks of 37 rows instead of 65,536 (the streaming readers' ``chunk_rows``);
- two BLAS threads and two worker threads instead of one.

The printed text (stdout and stderr) must be identical, character for character; so must the written
files' structure, strings and every number ftcal states to a precision (``core.precision``: the
payload's undetermined directions). The files' other numbers (fitted coefficients, estimates) are
written at full precision, because predictions from a model file reproduce the fit to 1e-12, and must
agree to 1e-8 relative: what a 1e-12 perturbation can move, amplified by the fits' conditioning.
The truth is the unchanged run; nothing here is pasted from a run.
"""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from scipy.spatial.transform import Rotation

# Runs one ftcal command with the tables read in chunks of argv[1] rows (0: the default) and writes
# how many chunks were read to argv[2], so the test knows the chunking really changed.
RUNNER = """
import sys
from ftcal.data import table_chunks
rows, count = int(sys.argv[1]), sys.argv[2]
read, chunks = table_chunks._read_table_chunks, [0]
def counted(path, inputs, outputs, labels, require_outputs, chunk_rows):
    for chunk in read(path, inputs, outputs, labels, require_outputs, rows or chunk_rows):
        chunks[0] += 1
        yield chunk
table_chunks._read_table_chunks = counted
from ftcal.cli import main
code = main(sys.argv[3:])
open(count, "w").write(str(chunks[0]))
sys.exit(code)
"""
CHUNK_ROWS = 37
# Fields that identify the data or the run, not results: the digest, the creation time and sources, and
# the training segments' fingerprints (evaluate's training-data check: other bytes, another print).
IDENTITY = ("sha256", "created", "training_segments")
# The selection's work estimate states seconds measured on this run: a clock, not a result.
SECONDS = re.compile(r"\d+(\.\d+)? s\b")
ONE_THREAD = {"OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1", "FTCAL_THREADS": "1"}
TWO_THREADS = {"OPENBLAS_NUM_THREADS": "2", "OMP_NUM_THREADS": "2", "FTCAL_THREADS": "2"}
CHANNELS = ["u1", "u2", "u3", "u4", "u5", "u6"]
OUTPUTS = ["Fx", "Fy", "Fz", "Tx", "Ty", "Tz"]


def calibration_table(n_groups: int, per_group: int, seed: int) -> pd.DataFrame:
    """ADC counts of six mixed channels and a temperature, loads with a mild nonlinearity, per load case."""
    rng = np.random.default_rng(seed)
    loads = (rng.uniform(-1, 1, (n_groups, 1, 6)) + 0.15 * rng.standard_normal((n_groups, per_group, 6))).reshape(-1, 6)
    temperature = np.repeat(rng.uniform(25, 44, n_groups), per_group) + 0.1 * rng.standard_normal(loads.shape[0])
    mixing = np.eye(6) + 0.2 * np.random.default_rng(123).standard_normal((6, 6))
    counts = 5000.0 + 800.0 * loads @ mixing.T + 3.0 * (temperature[:, None] - 35.0)
    wrench = loads * [100, 100, 100, 10, 10, 10] + 5.0 * np.tanh(2.0 * loads[:, :1])
    wrench += 0.01 * (temperature[:, None] - 35.0) ** 2 + rng.normal(size=wrench.shape) * [0.3, 0.3, 0.3, 0.01, 0.01, 0.01]
    frame = pd.DataFrame(np.c_[counts, temperature, wrench], columns=[*CHANNELS, "T", *OUTPUTS])
    frame["load"] = np.repeat([f"L{g}" for g in range(n_groups)], per_group)
    return frame


def payload_table(case: str) -> pd.DataFrame:
    """A tool held in still poses. ``undetermined``: tool down and on its side only (one null direction);
    ``noiseless``: exact readings of a 2 kg tool on the sensor's z axis, no bias (most estimates exactly 0)."""
    rng = np.random.default_rng(5)
    mass, com, bias = 1.3, np.array([0.012, -0.025, 0.071]), np.array([3.0, -2.0, 5.0, 0.1, -0.2, 0.05])
    noise = np.array([0.3, 0.3, 0.3, 0.01, 0.01, 0.01])
    if case == "undetermined":
        turns = Rotation.from_euler("y", np.tile([0.0, 90.0], 5)[:, None], degrees=True)
    else:
        turns = Rotation.random(10, random_state=3)
    if case == "noiseless":
        mass, com, bias, noise = 2.0, np.array([0.0, 0.0, 0.05]), np.zeros(6), np.zeros(6)
    rotations = Rotation.from_quat(np.repeat(turns.as_quat(), 30, axis=0))
    gravity = rotations.inv().apply([0.0, 0.0, -9.81])
    wrench = np.c_[mass * gravity, np.cross(com, mass * gravity)] + bias
    wrench += rng.normal(size=wrench.shape) * noise
    frame = pd.DataFrame(np.c_[rotations.as_quat(), wrench], columns=["qx", "qy", "qz", "qw", *CHANNELS])
    frame["pose"] = np.repeat(np.arange(10), 30)
    return frame


def perturbed(frame: pd.DataFrame) -> pd.DataFrame:
    out = frame.copy()
    numbers = out.select_dtypes("float").columns  # measurements, not the groups' integer labels
    noise = np.random.default_rng(11).standard_normal((len(out), len(numbers)))
    out[numbers] = out[numbers].to_numpy() * (1.0 + 1e-12 * noise)
    return out


def reordered(frame: pd.DataFrame, group: str) -> pd.DataFrame:
    """The same rows, each group's in a random order (groups keep their place)."""
    rng = np.random.default_rng(13)
    order = np.concatenate([rng.permutation(rows) for rows in frame.groupby(group, sort=False).indices.values()])
    return frame.iloc[order].reset_index(drop=True)


def run(tmp: Path, name: str, argv: list[str], *, env: dict = ONE_THREAD, chunk_rows: int = 0):
    """Run ``ftcal argv`` ({dir} in an argument is this run's folder); (text, files written, chunks read).

    The text names this run's folder DIR and the table's folder DATA."""
    folder = tmp / name
    folder.mkdir()
    argv = [a.replace("{dir}", str(folder)) for a in argv]
    count = folder / "chunks.txt"
    environment = {k: v for k, v in os.environ.items() if not k.startswith(("OPENBLAS_", "OMP_", "FTCAL_"))}
    done = subprocess.run([sys.executable, "-c", RUNNER, str(chunk_rows), str(count), *argv],
                          env=dict(environment, **env), capture_output=True, text=True, timeout=300)
    assert done.returncode in (0, 1), done.stderr
    text = f"exit {done.returncode}\n{done.stdout}\n{done.stderr}".replace(str(folder), "DIR")
    text = re.sub(r"^(estimated work: .*)$", lambda line: SECONDS.sub("S s", line[1]), text, flags=re.M)
    for table in argv:
        if table.endswith(".csv"):
            text = text.replace(str(Path(table).parent), "DATA")
    files = {p.name: json.loads(p.read_text()) for p in sorted(folder.glob("*.json"))}
    return text, files, int(count.read_text())


def _split(document, ignore=()):
    """(shape with the exactly stated numbers, list of the full-precision numbers, in document order)."""
    numbers = []

    def walk(node, exact):
        if isinstance(node, dict):
            return {k: walk(v, exact or k == "undetermined") for k, v in node.items()
                    if k not in IDENTITY and k not in ignore}
        if isinstance(node, list):
            return [walk(v, exact) for v in node]
        if isinstance(node, float) and not exact:
            numbers.append(node)
            return "<number>"
        if isinstance(node, str) and node.startswith("estimated work: "):  # the selection's notes, kept in the file
            return SECONDS.sub("S s", node)
        return node

    return walk(document, False), np.array(numbers)


def assert_same(baseline, other, what: str, ignore=()) -> None:
    text_a, files_a, _ = baseline
    text_b, files_b, _ = other
    assert text_b == text_a, f"{what}: the text changed"
    assert sorted(files_b) == sorted(files_a)
    for name in files_a:
        shape_a, numbers_a = _split(files_a[name], ignore)
        shape_b, numbers_b = _split(files_b[name], ignore)
        assert shape_b == shape_a, f"{what}: {name} changed beyond its full-precision numbers"
        np.testing.assert_allclose(numbers_b, numbers_a, rtol=1e-8, atol=1e-8 * np.abs(numbers_a).max(initial=0),
                                   err_msg=f"{what}: {name}")


def _tables(tmp: Path, name: str, frame: pd.DataFrame, group: str | None) -> dict[str, Path]:
    """The table as it is, perturbed, and reordered within its groups, as CSV files."""
    variants = {"as is": frame, "perturbed by 1e-12": perturbed(frame)}
    if group is not None:
        variants["reordered within groups"] = reordered(frame, group)
    paths = {}
    for i, (what, table) in enumerate(variants.items()):
        (tmp / f"{name}-table{i}").mkdir()
        paths[what] = tmp / f"{name}-table{i}" / f"{name}.csv"  # one name: the text names the table
        table.to_csv(paths[what], index=False, float_format="%.17g")
    return paths


def check_metamorphic(tmp: Path, name: str, frame: pd.DataFrame, argv, *, group: str | None,
                      chunked: bool = True, ignore=()) -> None:
    """``argv(table)`` run on the variants of ``frame``: each text and file as the unchanged run's (the
    files' fields in ``ignore`` left out)."""
    tables = _tables(tmp, name, frame, group)
    baseline = run(tmp, f"{name}-base", argv(tables["as is"]))
    for i, (what, path) in enumerate(tables.items()):
        if what != "as is":
            # the training residuals' lag-1 autocorrelation is a property of the row order
            assert_same(baseline, run(tmp, f"{name}-{i}", argv(path)), f"{name}, {what}",
                        ignore=(*ignore, "residual_autocorrelation_lag1") if what.startswith("reordered") else ignore)
    assert_same(baseline, run(tmp, f"{name}-threads", argv(tables["as is"]), env=TWO_THREADS),
                f"{name}, two BLAS and worker threads", ignore)
    if chunked:
        chunks = run(tmp, f"{name}-chunks", argv(tables["as is"]), chunk_rows=CHUNK_ROWS)
        assert chunks[2] > baseline[2], "the smaller chunks were not used"
        assert_same(baseline, chunks, f"{name}, chunks of {CHUNK_ROWS} rows", ignore)


@pytest.mark.parametrize("case", ["undetermined", "determined", "noiseless"])
def test_payload_text_and_file_hold_under_rounding_changes(tmp_path, case):
    frame = payload_table(case)
    argv = lambda table: ["payload", str(table), "--orientation", "qx,qy,qz,qw", "--group-by", "pose",  # noqa: E731
                          "-o", "{dir}/payload.json"]
    # Not reordered: the standard errors come from a jackknife over contiguous blocks of the recording, so
    # row order is its time order (serial correlation, drift). payload reads each table whole: no chunks.
    check_metamorphic(tmp_path, "payload", frame, argv, group=None, chunked=False)
    if case == "noiseless":  # what is 0 in exact arithmetic prints 0 (was ±1e-16 here, other noise elsewhere)
        text = run(tmp_path, "payload-truth", argv(tmp_path / "payload-table0" / "payload.csv"))[0]
        for name in ("com x", "com y", *(f"{kind} bias {a}" for kind in ("force", "torque") for a in "xyz")):
            assert re.search(rf"^  {name}\s+0 ± 0 ", text, re.M), name
        assert re.search(r"^  mass\s+2 ± 0 kg", text, re.M) and re.search(r"^  com z\s+0.05 ± 0 m", text, re.M)
        assert "residual RMS: Fx 0  Fy 0  Fz 0  Tx 0  Ty 0  Tz 0" in text


def test_fit_of_a_fixed_degree_holds_under_rounding_changes(tmp_path):
    argv = lambda table: ["fit", str(table), "--degree", "2", "--group-by", "load", "-o", "{dir}/model.json"]  # noqa: E731
    check_metamorphic(tmp_path, "fit", calibration_table(8, 50, 1), argv, group="load")


def test_an_exact_fit_states_its_training_error_as_0(tmp_path):
    # References computed from the readings (an exact linear function): the training RMSE is 0 in exact
    # arithmetic; it printed 1.3e-13 N here and 9e-10 N with the inputs perturbed by 1e-12.
    frame = calibration_table(8, 40, 3)
    mixing = np.random.default_rng(1).normal(size=(7, 6)) * 0.05
    frame[OUTPUTS] = (frame[[*CHANNELS, "T"]].to_numpy() - np.r_[[5000.0] * 6, 0.0]) @ mixing
    argv = lambda table: ["fit", str(table), "--degree", "1", "--group-by", "load", "-o", "{dir}/model.json"]  # noqa: E731
    # Known and left: the file's residual autocorrelation of an exact fit is that of rounding noise (not printed).
    check_metamorphic(tmp_path, "exact", frame, argv, group="load", ignore=("residual_autocorrelation_lag1",))
    text = run(tmp_path, "exact-truth", argv(tmp_path / "exact-table0" / "exact.csv"))[0]
    assert "training RMSE per output: Fx 0 N, Fy 0 N, Fz 0 N, Tx 0 N·m, Ty 0 N·m, Tz 0 N·m" in text


def test_degree_selection_holds_under_rounding_changes(tmp_path):
    argv = lambda table: ["fit", str(table), "--degree", "auto", "--max-degree", "2", "--folds", "4",  # noqa: E731
                          "--group-by", "load", "-o", "{dir}/model.json"]
    check_metamorphic(tmp_path, "select", calibration_table(8, 50, 1), argv, group="load")


@pytest.mark.parametrize("truth", [1, 2])
def test_degree_selection_on_noiseless_readings_picks_the_true_degree_on_every_cpu(tmp_path, truth):
    """References computed exactly from the readings: every degree at least the truth's fits them exactly, so
    their validation errors are 0 in exact arithmetic and rounding residues (6e-09 N here) ranked them (np4
    "best", np3 runner-up). Stated to their precision they are 0: tied, and ties go to the simpler model."""
    rng = np.random.default_rng(7)
    frame = calibration_table(6, 40, 5)
    u = (frame[CHANNELS[:3]].to_numpy() - 5000.0) / 800.0
    mixing = rng.normal(size=(3, 6))
    frame[OUTPUTS] = u @ mixing + (0.3 * (u ** 2) @ mixing if truth == 2 else 0.0)
    argv = lambda table: ["fit", str(table), "--inputs", "u1,u2,u3", "--degree", "auto", "--max-degree", "4",  # noqa: E731
                          "--folds", "3", "--group-by", "load", "-o", "{dir}/model.json"]
    check_metamorphic(tmp_path, "noiseless", frame, argv, group="load", chunked=False,
                      ignore=("residual_autocorrelation_lag1",))
    text = run(tmp_path, "noiseless-truth", argv(tmp_path / "noiseless-table0" / "noiseless.csv"))[0]
    assert f"selected (per block): np{truth}\n" in text
    for degree in range(truth, 5):
        if re.search(rf"^  {degree} ", text, re.M):  # a degree searched: its validation errors are exactly 0
            assert re.search(rf"^  {degree}\s+np{degree}\s+0\s+0$", text, re.M), text


@pytest.fixture(scope="module")
def model(tmp_path_factory) -> Path:
    folder = tmp_path_factory.mktemp("model")
    calibration_table(8, 50, 1).to_csv(folder / "train.csv", index=False, float_format="%.17g")
    done = subprocess.run([sys.executable, "-m", "ftcal", "fit", str(folder / "train.csv"), "--degree", "2",
                           "--group-by", "load", "-o", str(folder / "model.json")],
                          env=dict(os.environ, **ONE_THREAD), capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    return folder / "model.json"


def test_acceptance_verdict_holds_under_rounding_changes(tmp_path, model):
    argv = lambda table: ["check", "--accept", str(model), str(table), "--group-by", "load",  # noqa: E731
                          "--max-error-percent", "2"]
    # check --accept reads each table whole: no chunks to change
    check_metamorphic(tmp_path, "accept", calibration_table(4, 50, 2), argv, group="load", chunked=False)


def test_evaluate_holds_under_rounding_changes(tmp_path, model):
    argv = lambda table: ["evaluate", str(model), str(table)]  # noqa: E731
    # evaluate reports the residuals' lag-1 autocorrelation: row order is part of its input
    check_metamorphic(tmp_path, "evaluate", calibration_table(4, 50, 2), argv, group=None)
