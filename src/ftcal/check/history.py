"""Per-sensor history of calibrations and acceptance results, in one SQLite database.

The database (``history.sqlite`` in the folder the user chooses) is append-only: triggers
refuse UPDATE and DELETE. It runs in WAL mode and every write is one ``BEGIN IMMEDIATE``
transaction, so concurrent writers queue (up to :data:`BUSY_TIMEOUT_S`) and a writer killed
mid-transaction leaves nothing behind. A file that is not an intact ftcal history is refused
with one line.

A calibration is summarised by its file's sha256, its *bias* (the wrench it predicts at zero
signal, other inputs such as temperature at the centre of their training range) and its *gain*
(the Jacobian of the wrench with respect to the signal inputs there). Drift between
consecutive calibrations is the change of force bias (N), torque bias (N·m) and the relative
change of the gain (Frobenius); a new calibration is *unusual* when a change exceeds
:data:`NORMAL_FACTOR` × the RMS of the earlier consecutive changes (which needs
:data:`MIN_CHANGES_FOR_NORMAL` of them).
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
import sqlite3
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from datetime import datetime, timezone
from pathlib import Path

import numpy as np

from ..runtime.errors import FtcalError, FtcalWarning

DATABASE_NAME = "history.sqlite"
FORMAT = "ftcal-history"
FORMAT_VERSION = "1"
BUSY_TIMEOUT_S = 60.0
NORMAL_FACTOR = 3.0
MIN_CHANGES_FOR_NORMAL = 2
DRIFT_KEYS = ("force_bias", "torque_bias", "gain")
DRIFT_UNITS = {"force_bias": "N", "torque_bias": "N·m", "gain": "(relative)"}
_SQLITE_MAGIC = b"SQLite format 3\x00"

_SCHEMA = """
CREATE TABLE IF NOT EXISTS meta (key TEXT PRIMARY KEY, value TEXT NOT NULL);
CREATE TABLE IF NOT EXISTS calibrations (
    id INTEGER PRIMARY KEY AUTOINCREMENT,
    serial TEXT NOT NULL,
    recorded_utc TEXT NOT NULL,
    model_sha256 TEXT NOT NULL,
    source TEXT NOT NULL,
    outputs TEXT NOT NULL,
    bias TEXT NOT NULL,
    gain TEXT NOT NULL,
    UNIQUE (serial, model_sha256)
);
CREATE TABLE IF NOT EXISTS acceptances (
    id INTEGER PRIMARY KEY AUTOINCREMENT,
    serial TEXT NOT NULL,
    recorded_utc TEXT NOT NULL,
    model_sha256 TEXT NOT NULL,
    passed INTEGER NOT NULL,
    rmse TEXT NOT NULL,
    thresholds TEXT NOT NULL,
    data TEXT NOT NULL
);
CREATE INDEX IF NOT EXISTS calibrations_serial ON calibrations (serial, id);
CREATE INDEX IF NOT EXISTS acceptances_serial ON acceptances (serial, id);
"""
_APPEND_ONLY = "".join(
    f"CREATE TRIGGER IF NOT EXISTS {table}_no_{action.lower()} BEFORE {action} ON {table} "
    f"BEGIN SELECT RAISE(ABORT, 'the ftcal history is append-only'); END;\n"
    for table in ("calibrations", "acceptances") for action in ("UPDATE", "DELETE"))


def default_history_dir() -> Path:
    """``$XDG_DATA_HOME/ftcal/history`` (default ``~/.local/share/ftcal/history``)."""
    base = os.environ.get("XDG_DATA_HOME") or os.path.join(os.path.expanduser("~"), ".local", "share")
    return Path(base) / "ftcal" / "history"


@dataclass(frozen=True)
class CalibrationSummary:
    """What the history keeps of a calibration.

    bias : ndarray of shape (6,), N and N·m
    gain : ndarray of shape (6, n_signals)
    """

    model_sha256: str
    source: str
    outputs: tuple[str, ...]
    bias: np.ndarray
    gain: np.ndarray


@dataclass(frozen=True)
class CalibrationRecord:
    """One calibration row of the history."""

    id: int
    recorded_utc: str
    summary: CalibrationSummary


@dataclass(frozen=True)
class AcceptanceRecord:
    """One acceptance row of the history."""

    id: int
    recorded_utc: str
    model_sha256: str
    passed: bool
    rmse: list[float]
    thresholds: dict
    data: list[str]


@dataclass(frozen=True)
class Drift:
    """Change between consecutive calibrations, and whether the last one is unusual."""

    changes: list[dict]  # per consecutive pair: recorded_utc of the later one and DRIFT_KEYS values
    normal: dict | None  # DRIFT_KEYS → limit, None when the history is too short
    unusual: list[str]  # keys whose last change exceeds its limit


def file_sha256(path: str | os.PathLike) -> str:
    """sha256 of a file's bytes."""
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def calibration_summary(model, path: str | os.PathLike) -> CalibrationSummary:
    """Bias and gain of a static calibration model (see the module docstring).

    Parameters
    ----------
    model : CalibrationModel
    path : its file (hashed)
    """
    from ..report.runs import temperature_column

    names = model.input_names_
    skip = temperature_column(names)
    signals = [j for j in range(len(names)) if j != skip]
    centre = model.input_range_.mean(axis=1)
    x0 = centre.copy()
    x0[signals] = 0.0
    width = np.ptp(model.input_range_, axis=1)
    step = np.where(width > 0, 1e-3 * width, 1e-3)
    points = [x0]
    for j in signals:
        for s in (1.0, -1.0):
            x = x0.copy()
            x[j] += s * step[j]
            points.append(x)
    y = model.predict(np.array(points), warn_out_of_range=False)
    gain = np.column_stack([(y[1 + 2 * k] - y[2 + 2 * k]) / (2.0 * step[j]) for k, j in enumerate(signals)])
    return CalibrationSummary(file_sha256(path), str(path), tuple(model.output_names_), y[0], gain)


def drift(records: Sequence[CalibrationRecord]) -> Drift:
    """Consecutive changes of bias and gain over ``records`` (oldest first), and the unusual ones."""
    changes = []
    for a, b in zip(records[:-1], records[1:]):
        pa, pb = a.summary, b.summary
        d_bias = pb.bias - pa.bias
        gain = (float(np.linalg.norm(pb.gain - pa.gain) / max(np.linalg.norm(pa.gain), 1e-300))
                if pa.gain.shape == pb.gain.shape else float("inf"))
        changes.append({"recorded_utc": b.recorded_utc, "model_sha256": pb.model_sha256,
                        "force_bias": float(np.linalg.norm(d_bias[:3])),
                        "torque_bias": float(np.linalg.norm(d_bias[3:])), "gain": gain})
    if len(changes) < MIN_CHANGES_FOR_NORMAL + 1:
        return Drift(changes, None, [])
    earlier = changes[:-1]
    normal = {k: NORMAL_FACTOR * float(np.sqrt(np.mean([c[k] ** 2 for c in earlier]))) for k in DRIFT_KEYS}
    unusual = [k for k in DRIFT_KEYS if changes[-1][k] > normal[k]]
    return Drift(changes, normal, unusual)


class History:
    """The history database in ``folder`` (made if missing).

    Parameters
    ----------
    folder : directory holding ``history.sqlite``

    Raises
    ------
    FtcalError
        The folder cannot be made, or the file is not an intact ftcal history.
    """

    def __init__(self, folder: str | os.PathLike) -> None:
        self.folder = Path(folder)
        self.path = self.folder / DATABASE_NAME
        try:
            self.folder.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise FtcalError(f"--history-dir {self.folder}: cannot make the folder ({exc.strerror}).") from None
        if self.path.exists():
            self._check_file()
        self._connection = self._connect()

    def _refuse(self, why: str) -> FtcalError:
        why = (why.splitlines() or ["unreadable"])[0]  # SQLite's reports can run over several lines
        return FtcalError(f"{self.path}: not an intact ftcal history database ({why}); move it aside to start "
                          "a new history.")

    def _check_file(self) -> None:
        with open(self.path, "rb") as fh:
            head = fh.read(len(_SQLITE_MAGIC))
        if head and head != _SQLITE_MAGIC:
            raise self._refuse("not an SQLite file")

    def _connect(self) -> sqlite3.Connection:
        try:
            conn = sqlite3.connect(self.path, timeout=BUSY_TIMEOUT_S, isolation_level=None)
            conn.execute("PRAGMA journal_mode=WAL")
            conn.execute("PRAGMA synchronous=FULL")
            check = conn.execute("PRAGMA quick_check").fetchone()[0]
            if check != "ok":
                conn.close()
                raise self._refuse(f"integrity check: {check}")
            # Every statement is idempotent, so writers opening a new history at once do not collide.
            conn.executescript(_SCHEMA + _APPEND_ONLY)
            conn.execute("INSERT OR IGNORE INTO meta VALUES ('format', ?), ('format_version', ?)",
                         (FORMAT, FORMAT_VERSION))
            fmt = dict(conn.execute("SELECT key, value FROM meta").fetchall())
            if fmt.get("format") != FORMAT:
                conn.close()
                raise self._refuse(f"format {fmt.get('format')!r}")
            if fmt.get("format_version") != FORMAT_VERSION:
                conn.close()
                raise FtcalError(f"{self.path}: ftcal history version {fmt.get('format_version')}; this ftcal "
                                 f"reads version {FORMAT_VERSION}.")
            return conn
        except sqlite3.DatabaseError as exc:
            raise self._refuse(str(exc) or type(exc).__name__) from None

    def close(self) -> None:
        self._connection.close()

    def __enter__(self) -> "History":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    @contextlib.contextmanager
    def transaction(self) -> Iterator[sqlite3.Connection]:
        """One write transaction (``BEGIN IMMEDIATE`` … ``COMMIT``; rolled back on any error)."""
        conn = self._connection
        try:
            conn.execute("BEGIN IMMEDIATE")
        except sqlite3.DatabaseError as exc:
            raise self._refuse(str(exc)) from None
        try:
            yield conn
        except BaseException:
            conn.execute("ROLLBACK")
            raise
        conn.execute("COMMIT")

    def append_calibration(self, conn: sqlite3.Connection, serial: str, summary: CalibrationSummary,
                           recorded_utc: str | None = None) -> bool:
        """Insert a calibration inside ``conn``'s transaction; False when this file is already recorded."""
        cursor = conn.execute(
            "INSERT OR IGNORE INTO calibrations (serial, recorded_utc, model_sha256, source, outputs, bias, gain) "
            "VALUES (?, ?, ?, ?, ?, ?, ?)",
            (serial, recorded_utc or _now(), summary.model_sha256, summary.source, json.dumps(summary.outputs),
             json.dumps(summary.bias.tolist()), json.dumps(summary.gain.tolist())))
        return cursor.rowcount == 1

    def append_acceptance(self, conn: sqlite3.Connection, serial: str, model_sha256: str, passed: bool,
                          rmse: Sequence[float], thresholds: dict, data: Sequence[str],
                          recorded_utc: str | None = None) -> None:
        """Insert an acceptance result inside ``conn``'s transaction."""
        conn.execute(
            "INSERT INTO acceptances (serial, recorded_utc, model_sha256, passed, rmse, thresholds, data) "
            "VALUES (?, ?, ?, ?, ?, ?, ?)",
            (serial, recorded_utc or _now(), model_sha256, int(bool(passed)), json.dumps([float(v) for v in rmse]),
             json.dumps(thresholds), json.dumps([str(d) for d in data])))

    def record_calibration(self, serial: str, summary: CalibrationSummary,
                           recorded_utc: str | None = None) -> bool:
        """Append a calibration (one transaction); False when this file is already recorded for ``serial``."""
        with self.transaction() as conn:
            return self.append_calibration(conn, serial, summary, recorded_utc)

    def calibrations(self, serial: str) -> list[CalibrationRecord]:
        """Calibrations of ``serial``, oldest first."""
        rows = self._read("SELECT id, recorded_utc, model_sha256, source, outputs, bias, gain FROM calibrations "
                          "WHERE serial = ? ORDER BY id", serial)
        return [CalibrationRecord(r[0], r[1], CalibrationSummary(r[2], r[3], tuple(json.loads(r[4])),
                                                                 np.array(json.loads(r[5]), dtype=float),
                                                                 np.array(json.loads(r[6]), dtype=float)))
                for r in rows]

    def acceptances(self, serial: str) -> list[AcceptanceRecord]:
        """Acceptance results of ``serial``, oldest first."""
        rows = self._read("SELECT id, recorded_utc, model_sha256, passed, rmse, thresholds, data FROM acceptances "
                          "WHERE serial = ? ORDER BY id", serial)
        return [AcceptanceRecord(r[0], r[1], r[2], bool(r[3]), json.loads(r[4]), json.loads(r[5]),
                                 json.loads(r[6])) for r in rows]

    def serials(self) -> list[str]:
        """Every serial with a record."""
        rows = self._read("SELECT serial FROM calibrations UNION SELECT serial FROM acceptances ORDER BY 1")
        return [r[0] for r in rows]

    def _read(self, sql: str, *params) -> list[tuple]:
        try:
            return self._connection.execute(sql, params).fetchall()
        except (sqlite3.DatabaseError, ValueError) as exc:
            raise self._refuse(str(exc)) from None


def _now() -> str:
    return datetime.now(timezone.utc).isoformat(timespec="microseconds")


class DriftWarning(FtcalWarning):
    """A new calibration differs from the last one more than the sensor's history says is normal."""
