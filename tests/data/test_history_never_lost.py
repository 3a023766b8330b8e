"""The history is never lost (issue 28): reading writes nothing, a lock is called a lock, read-only storage
is called read-only, "corrupt" only after SQLite's integrity check failed; FIFOs, foreign SQLite files and
edited rows are refused in one line; a write error records nothing; a failed run is recorded as failed."""

import os
import sqlite3
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from ftcal import CalibrationModel, Dataset, save_model
from ftcal.check import history as history_module
from ftcal.check.history import History, CalibrationSummary
from ftcal.cli import main
from ftcal.runtime.errors import FtcalError

FTCAL = str(Path(sys.executable).with_name("ftcal"))
AXES = ("Fx", "Fy", "Fz", "Tx", "Ty", "Tz")


def summary(tag: str, bias=0.0) -> CalibrationSummary:
    return CalibrationSummary(f"{tag:0>64}", f"{tag}.json", AXES, np.r_[np.full(3, float(bias)), np.zeros(3)],
                              np.eye(6))


def snapshot(folder: Path) -> dict:
    return {p.name: p.read_bytes() for p in folder.iterdir()}


def one_line(capsys) -> str:
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1, err
    return err[0]


def test_reading_writes_nothing_and_does_not_wait_for_a_writer(tmp_path, capsys):
    with History(tmp_path) as history:
        history.record_calibration("SN1", summary("a"))
    before = snapshot(tmp_path)
    assert main(["check", "--history", "SN1", "--history-dir", str(tmp_path)]) == 0
    assert "1 calibration(s)" in capsys.readouterr().out
    after = snapshot(tmp_path)
    # Not a byte of the database; SQLite's WAL index (-shm) may appear beside it, and an empty -wal.
    assert after["history.sqlite"] == before["history.sqlite"] and not after.get("history.sqlite-wal", b"")
    writer = sqlite3.connect(tmp_path / "history.sqlite", isolation_level=None)
    writer.execute("BEGIN IMMEDIATE")  # another writer is in the middle of a transaction
    writer.execute("INSERT INTO meta VALUES ('pending', 'x')")
    try:
        assert main(["check", "--history", "SN1", "--history-dir", str(tmp_path)]) == 0
        assert "1 calibration(s)" in capsys.readouterr().out
    finally:
        writer.execute("ROLLBACK")
        writer.close()


def test_a_lock_is_named_as_a_lock_not_as_corruption(tmp_path, monkeypatch):
    with History(tmp_path) as history:
        history.record_calibration("SN1", summary("a"))
    monkeypatch.setattr(history_module, "BUSY_TIMEOUT_S", 0.2)
    writer = sqlite3.connect(tmp_path / "history.sqlite", isolation_level=None)
    writer.execute("BEGIN IMMEDIATE")
    try:
        with History(tmp_path) as history, pytest.raises(FtcalError) as caught:
            history.record_calibration("SN1", summary("b"))
    finally:
        writer.execute("ROLLBACK")
        writer.close()
    message = str(caught.value)
    assert "locked" in message and "intact" not in message and "move it aside" not in message
    with History(tmp_path) as history:  # nothing was lost, and the lock is gone
        assert history.record_calibration("SN1", summary("b"))
        assert len(history.calibrations("SN1")) == 2


@pytest.mark.parametrize("text, word", [("attempt to write a readonly database", "read-only"),
                                        ("database or disk is full", "cannot write"),
                                        ("database is locked", "locked")])
def test_sqlite_failures_are_named_for_what_they_are(tmp_path, text, word):
    with History(tmp_path) as history:
        history.record_calibration("SN1", summary("a"))
        message = str(history._failure(sqlite3.OperationalError(text), "write to"))
    assert word in message and "intact" not in message and "corrupt" not in message


def test_a_write_error_records_nothing_and_is_one_line(tmp_path, monkeypatch):
    def full(*args, **kwargs):
        raise sqlite3.OperationalError("database or disk is full")

    with History(tmp_path) as history:
        history.record_calibration("SN1", summary("a"))
        monkeypatch.setattr(History, "append_acceptance", full)
        with pytest.raises(FtcalError, match="cannot write the history"):
            with history.transaction() as conn:
                history.append_calibration(conn, "SN1", summary("b"))
                history.append_acceptance(conn, "SN1", "b", True, [0.1] * 6, {}, [])
        assert [c.summary.source for c in history.calibrations("SN1")] == ["a.json"]


def test_a_fifo_is_refused_without_hanging(tmp_path):
    os.mkfifo(tmp_path / "history.sqlite")
    for argv in (["check", "--history", "SN1", "--history-dir", tmp_path],):
        done = subprocess.run([FTCAL, *map(str, argv)], capture_output=True, text=True, timeout=120)
        assert done.returncode == 2 and "not a regular file" in done.stderr, done.stderr
        assert len(done.stderr.strip().splitlines()) == 1
    with pytest.raises(FtcalError, match="not a regular file"):
        History(tmp_path)


def test_a_foreign_sqlite_file_is_refused_and_left_untouched(tmp_path, capsys):
    path = tmp_path / "history.sqlite"
    conn = sqlite3.connect(path)
    conn.execute("CREATE TABLE users (name TEXT)")
    conn.execute("INSERT INTO users VALUES ('alice')")
    conn.commit()
    conn.close()
    before = snapshot(tmp_path)
    with pytest.raises(FtcalError, match="another application"):
        History(tmp_path).record_calibration("SN1", summary("a"))
    assert main(["check", "--history", "SN1", "--history-dir", str(tmp_path)]) == 2
    assert "another application" in one_line(capsys)
    assert snapshot(tmp_path) == before


def test_an_edited_row_is_one_line_naming_it(tmp_path, capsys):
    with History(tmp_path) as history:
        history.record_calibration("SN1", summary("a"))
    conn = sqlite3.connect(tmp_path / "history.sqlite")
    conn.execute("DROP TRIGGER calibrations_no_update")  # someone with the file edits it anyway
    conn.execute("UPDATE calibrations SET bias = '[\"nan\", {}]'")
    conn.commit()
    conn.close()
    assert main(["check", "--history", "SN1", "--history-dir", str(tmp_path)]) == 2
    line = one_line(capsys)
    assert "row 1 of table calibrations" in line and "intact" not in line


@pytest.fixture()
def model_and_dead_data(tmp_path):
    rng = np.random.default_rng(0)
    mixing = np.eye(6) * 40.0
    w = rng.uniform(-1.0, 1.0, (2000, 6)) * [60, 60, 60, 4, 4, 4]
    names = [f"u{i}" for i in range(1, 7)]
    model = CalibrationModel(degree=1).fit(Dataset.from_arrays(w @ mixing.T + rng.normal(size=w.shape), w,
                                                               input_names=names, output_names=list(AXES)))
    save_model(model, tmp_path / "m.json")
    loads = np.repeat([[0, 0, 0, 0, 0, 0], [30, -10, 20, 1, 1, 0], [-40, 10, 5, 0, -1, 1]], 200, axis=0)
    frame = pd.DataFrame(np.c_[np.full((600, 6), 7.0), loads], columns=names + list(AXES))  # a dead sensor
    frame["pose"] = np.repeat(["a", "b", "c"], 200)
    frame.to_csv(tmp_path / "dead.csv", index=False)
    return tmp_path / "m.json", tmp_path / "dead.csv"


def test_a_failed_run_is_recorded_as_failed_and_a_run_that_errors_is_not_recorded(tmp_path, capsys,
                                                                                   model_and_dead_data):
    model, data = model_and_dead_data
    folder = tmp_path / "history"
    base = ["check", "--accept", str(model), str(data), "--group-by", "pose", "--max-force-error", "1e6",
            "--max-torque-error", "1e6", "--serial", "SN9", "--history-dir", str(folder)]
    assert main(base) == 1
    capsys.readouterr()
    with History(folder, read_only=True) as history:
        (result,) = history.acceptances("SN9")
    assert not result.passed and any("dead" in p for p in result.thresholds["problems"])
    (tmp_path / "page.html").mkdir()  # the page cannot be written
    assert main(base + ["--html", str(tmp_path / "page.html")]) == 2
    capsys.readouterr()
    with History(folder, read_only=True) as history:
        assert len(history.acceptances("SN9")) == 1  # the run that failed to finish left no record
