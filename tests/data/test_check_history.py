"""The per-sensor SQLite history: drift, concurrent writers, a writer killed mid-transaction, corruption."""

import multiprocessing
import os
import signal
import sqlite3
import warnings

import numpy as np
import pytest

from ftcal import CalibrationModel, Dataset, save_model
from ftcal.check.history import (NORMAL_FACTOR, CalibrationSummary, History, calibration_summary, drift,
                                 file_sha256)
from ftcal.cli import main
from ftcal.runtime.errors import FtcalError, FtcalWarning

AXES = ("Fx", "Fy", "Fz", "Tx", "Ty", "Tz")


def summary(tag: str, bias=0.0, gain=1.0) -> CalibrationSummary:
    return CalibrationSummary(f"{tag:0>64}", f"{tag}.json", AXES, np.r_[np.full(3, float(bias)), np.zeros(3)],
                              gain * np.eye(6))


def test_summary_of_an_affine_model_is_its_offset_and_matrix(tmp_path):
    rng = np.random.default_rng(0)
    matrix = np.eye(6) * 2.0 + 0.1 * rng.standard_normal((6, 6))
    offset = rng.normal(size=6)
    u = rng.uniform(-100.0, 100.0, (500, 6))
    names = [f"u{i}" for i in range(1, 7)]
    model = CalibrationModel(degree=1).fit(Dataset.from_arrays(u, u @ matrix.T + offset, input_names=names))
    path = tmp_path / "m.json"
    save_model(model, path)
    s = calibration_summary(model, path)
    np.testing.assert_allclose(s.bias, offset, atol=1e-8)
    np.testing.assert_allclose(s.gain, matrix, atol=1e-8)
    import hashlib
    assert s.model_sha256 == hashlib.sha256(path.read_bytes()).hexdigest() == file_sha256(path)


def test_drift_flags_a_change_larger_than_the_history_says_is_normal(tmp_path):
    with History(tmp_path) as history:
        # Weekly calibrations whose force bias moves 0.1 N, 0.2 N, 0.1 N, then 1.0 N.
        for k, bias in enumerate([0.0, 0.1, 0.3, 0.4, 1.4]):
            assert history.record_calibration("SN1", summary(str(k), bias / np.sqrt(3.0)),
                                              recorded_utc=f"2026-0{k + 1}-01T00:00:00")
        records = history.calibrations("SN1")
    result = drift(records)
    np.testing.assert_allclose([c["force_bias"] for c in result.changes], [0.1, 0.2, 0.1, 1.0], atol=1e-12)
    # By hand: 3 × RMS(0.1, 0.2, 0.1) = 3 × sqrt(0.06 / 3).
    assert result.normal["force_bias"] == pytest.approx(NORMAL_FACTOR * np.sqrt(0.06 / 3.0))
    assert result.unusual == ["force_bias"]
    assert drift(records[:4]).unusual == []


def test_the_same_model_is_recorded_once_and_rows_cannot_change(tmp_path):
    with History(tmp_path) as history:
        assert history.record_calibration("SN1", summary("a"))
        assert not history.record_calibration("SN1", summary("a"))
        assert history.record_calibration("SN2", summary("a"))
    conn = sqlite3.connect(tmp_path / "history.sqlite")
    for sql in ("UPDATE calibrations SET serial = 'x'", "DELETE FROM calibrations"):
        with pytest.raises(sqlite3.DatabaseError, match="append-only"):
            conn.execute(sql)
    conn.close()


def _writer(folder, worker, count):
    with History(folder) as history:
        for k in range(count):
            with history.transaction() as conn:
                history.append_calibration(conn, "SN1", summary(f"w{worker}k{k}", bias=k))
                history.append_acceptance(conn, "SN1", f"w{worker}k{k}", True, [0.1] * 6, {}, [f"w{worker}"])


@pytest.mark.slow
def test_concurrent_writers_lose_nothing(tmp_path):
    ctx = multiprocessing.get_context("spawn")
    workers, count = 4, 15
    procs = [ctx.Process(target=_writer, args=(str(tmp_path), w, count)) for w in range(workers)]
    for p in procs:
        p.start()
    for p in procs:
        p.join(120)
        assert p.exitcode == 0
    with History(tmp_path) as history:
        calibrations = history.calibrations("SN1")
        acceptances = history.acceptances("SN1")
    assert len(calibrations) == len(acceptances) == workers * count
    assert len({c.summary.model_sha256 for c in calibrations}) == workers * count
    tags = [c.summary.model_sha256.lstrip("0") for c in calibrations]
    for w in range(workers):  # each writer's records, in its own order
        mine = [int(t.split("k")[1]) for t in tags if t.split("k")[0] == f"w{w}"]
        assert mine == list(range(count))


def _killed_mid_transaction(folder, ready):
    history = History(folder)
    with history.transaction() as conn:
        history.append_calibration(conn, "SN1", summary("half"))
        ready.set()
        signal.pause()  # killed here, before COMMIT


def test_a_writer_killed_mid_transaction_leaves_nothing_behind(tmp_path):
    with History(tmp_path) as history:
        history.record_calibration("SN1", summary("before"))
    ctx = multiprocessing.get_context("spawn")
    ready = ctx.Event()
    child = ctx.Process(target=_killed_mid_transaction, args=(str(tmp_path), ready))
    child.start()
    assert ready.wait(60)
    os.kill(child.pid, signal.SIGKILL)
    child.join(30)
    assert child.exitcode == -signal.SIGKILL
    with History(tmp_path) as history:
        assert [c.summary.source for c in history.calibrations("SN1")] == ["before.json"]
        assert history.record_calibration("SN1", summary("after"))  # the lock died with the writer
        assert len(history.calibrations("SN1")) == 2


def test_a_corrupted_database_is_refused_in_one_line(tmp_path, capsys):
    with History(tmp_path) as history:
        for k in range(40):
            history.record_calibration("SN1", summary(str(k), bias=k))
    path = tmp_path / "history.sqlite"
    data = bytearray(path.read_bytes())
    assert len(data) > 3 * 4096
    data[4096 + 100: 3 * 4096] = os.urandom(3 * 4096 - 4096 - 100)  # garble pages 2 and 3
    path.write_bytes(bytes(data))
    with pytest.raises(FtcalError, match="not an intact ftcal history"):
        History(tmp_path).calibrations("SN1")
    with warnings.catch_warnings():
        warnings.simplefilter("error", FtcalWarning)
        assert main(["check", "--history", "SN1", "--history-dir", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and "not an intact ftcal history" in err


def test_a_file_that_is_not_a_history_is_refused(tmp_path):
    (tmp_path / "history.sqlite").write_text("hello, I am a text file\n" * 100)
    with pytest.raises(FtcalError, match="not an SQLite file"):
        History(tmp_path)
    other = tmp_path / "other"
    other.mkdir()
    conn = sqlite3.connect(other / "history.sqlite")
    conn.execute("CREATE TABLE meta (key TEXT PRIMARY KEY, value TEXT NOT NULL)")
    conn.execute("INSERT INTO meta VALUES ('format', 'something-else')")
    conn.commit()
    conn.close()
    with pytest.raises(FtcalError, match="format 'something-else'"):
        History(other)


def test_reading_a_history_that_does_not_exist_is_one_line_and_creates_nothing(tmp_path, capsys):
    folder = tmp_path / "none"
    assert main(["check", "--history", "SN1", "--history-dir", str(folder)]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and "no history database" in err
    assert not folder.exists()
