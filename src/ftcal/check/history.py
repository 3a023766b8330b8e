"""Per-sensor history of calibrations and acceptance results, in one SQLite database.

The database (``history.sqlite`` in the folder the user chooses) is append-only: triggers
refuse UPDATE and DELETE. It runs in WAL mode and every write is one ``BEGIN IMMEDIATE``
transaction, so concurrent writers queue (up to :data:`BUSY_TIMEOUT_S`) and a writer killed
mid-transaction leaves nothing behind. Reading (``ftcal check --history``) opens the file
read-only (``mode=ro``) and writes nothing; it waits for a writer at most :data:`READ_TIMEOUT_S`.
A history carries :data:`APPLICATION_ID`; another application's SQLite file is refused, never
adopted. Every failure is one line that says which it is: a lock, read-only storage, a write
error, a foreign or non-regular file, an edited row, or, only after SQLite's integrity check
failed, a corrupt database.

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
import errno
import hashlib
import json
import os
import sqlite3
import stat
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from datetime import datetime, timezone
from pathlib import Path

import numpy as np

from ..runtime.errors import FtcalError, ParameterError, FtcalWarning

DATABASE_NAME = "history.sqlite"
FORMAT = "ftcal-history"
FORMAT_VERSION = "1"
BUSY_TIMEOUT_S = 60.0
# A reader waits this long at most for a writer to let go (reading a WAL database rarely waits at all).
READ_TIMEOUT_S = 5.0
# PRAGMA application_id of a history ("ftHi"): a foreign SQLite file is never adopted.
APPLICATION_ID = 0x66744869
_TABLES = {"meta", "calibrations", "acceptances"}
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
    """The history database in ``folder``.

    Parameters
    ----------
    folder : directory holding ``history.sqlite`` (made if missing, unless ``read_only``)
    read_only : open for reading only: nothing is created or written (not even the WAL
        mode), a writer is waited for at most :data:`READ_TIMEOUT_S`, and a history on
        read-only media is read as it is

    Raises
    ------
    FtcalError
        One line saying which: the folder cannot be made; the file is not a regular file (a
        FIFO, a device), not SQLite, another application's SQLite database, or a newer
        history version; the history is locked by a writer (after the wait); it is on
        read-only storage (when writing); it is corrupt (only after SQLite's integrity check
        failed).
    """

    def __init__(self, folder: str | os.PathLike, *, read_only: bool = False) -> None:
        self.folder = Path(folder)
        self.path = self.folder / DATABASE_NAME
        self.read_only = read_only
        self._connection: sqlite3.Connection | None = None
        if read_only:
            if not self.path.is_file() and not self.path.exists():
                raise ParameterError('history_dir', f"{{history_dir}} {self.folder}: no history database ({DATABASE_NAME}) there.")
        else:
            try:
                self.folder.mkdir(parents=True, exist_ok=True)
            except OSError as exc:
                raise ParameterError('history_dir', f"{{history_dir}} {self.folder}: cannot make the folder ({exc.strerror}"
                                 + ("; read-only storage" if exc.errno == errno.EROFS else "") + ").") from None
        exists = self.path.exists() or self.path.is_symlink()
        if exists:
            self._check_file()
        try:
            if exists:
                self._connection = self._open_existing()
            else:
                self._connection = self._create()
        except sqlite3.DatabaseError as exc:
            if self._connection is not None:
                self._connection.close()
            raise self._failure(exc, "open") from None
        except UnicodeDecodeError:  # a damaged byte in a text of the schema or the meta table
            check = self._integrity()
            raise FtcalError(f"{self.path}: " + (f"not an intact ftcal history database (integrity check: {check}); "
                                                 "move it aside to start a new history." if check else
                                                 "holds text that is not UTF-8 (edited?); not a usable history."
                                                 )) from None

    # -- opening ---------------------------------------------------------------------------------

    def _check_file(self) -> None:
        """Refuse a FIFO, device or folder (opening one could hang) and a file that is not SQLite, before SQLite sees it."""
        for path in (self.path, Path(f"{self.path}-wal"), Path(f"{self.path}-shm")):
            try:
                mode = path.stat().st_mode
            except FileNotFoundError:
                if path == self.path:
                    raise FtcalError(f"{self.path}: a link to nothing; not a history database.") from None
                continue
            except OSError as exc:
                raise FtcalError(f"{path}: cannot read it ({exc.strerror}).") from None
            if not stat.S_ISREG(mode):
                raise ParameterError('history_dir', f"{path}: not a regular file (a FIFO, device or folder); ftcal keeps its history "
                                 "in a plain file: choose another {history_dir}.")
        try:
            with open(self.path, "rb") as fh:
                head = fh.read(len(_SQLITE_MAGIC))
        except OSError as exc:
            raise FtcalError(f"{self.path}: cannot read it ({exc.strerror}).") from None
        if head and head != _SQLITE_MAGIC:
            raise ParameterError('history_dir', f"{self.path}: not an SQLite file, so not an ftcal history; move it aside or choose "
                             "another {history_dir}.")

    def _uri(self, immutable: bool = False) -> str:
        from urllib.parse import quote

        return f"file:{quote(str(self.path.resolve()))}?mode=ro" + ("&immutable=1" if immutable else "")

    def _open_existing(self) -> sqlite3.Connection:
        # Check what the file is with a read-only connection first: a foreign file is never written to.
        try:
            conn = sqlite3.connect(self._uri(), uri=True, timeout=READ_TIMEOUT_S, isolation_level=None)
            empty = self._identify(conn)
        except sqlite3.OperationalError as exc:
            if not (self.read_only and "unable to open" in str(exc) and not os.access(self.folder, os.W_OK)):
                raise
            # Read-only media: SQLite cannot make the WAL index beside the file; nobody can write it either.
            conn = sqlite3.connect(self._uri(immutable=True), uri=True, isolation_level=None)
            empty = self._identify(conn)
        if self.read_only:
            return conn
        conn.close()
        if empty:
            return self._create()
        conn = sqlite3.connect(self.path, timeout=BUSY_TIMEOUT_S, isolation_level=None)
        conn.execute("PRAGMA journal_mode=WAL")
        conn.execute("PRAGMA synchronous=FULL")
        return conn

    def _identify(self, conn: sqlite3.Connection) -> bool:
        """Check ``conn``'s database is an ftcal history of this version (reads only); True when it is empty."""
        application = conn.execute("PRAGMA application_id").fetchone()[0]
        tables = {r[0] for r in conn.execute("SELECT name FROM sqlite_master WHERE type = 'table'")}
        if not tables and application in (0, APPLICATION_ID):
            return True  # an empty database (another writer is making the history): an empty history
        if application not in (0, APPLICATION_ID) or "meta" not in tables:
            what = f"application id {application:#x}" if application else f"tables {', '.join(sorted(tables)[:5])}"
            raise ParameterError('history_dir', f"{self.path}: another application's SQLite database ({what}), not an ftcal history; "
                             "ftcal will not add to it: choose another {history_dir}.")
        fmt = dict(conn.execute("SELECT key, value FROM meta").fetchall())
        if fmt.get("format") != FORMAT or not _TABLES <= tables:
            raise ParameterError('history_dir', f"{self.path}: an SQLite database of format {fmt.get('format')!r}, not an ftcal history; "
                             "ftcal will not add to it: choose another {history_dir}.")
        if fmt.get("format_version") != FORMAT_VERSION:
            raise FtcalError(f"{self.path}: ftcal history version {fmt.get('format_version')}; this ftcal "
                             f"reads version {FORMAT_VERSION}.")
        return False

    def _create(self) -> sqlite3.Connection:
        conn = sqlite3.connect(self.path, timeout=BUSY_TIMEOUT_S, isolation_level=None)
        conn.execute("PRAGMA journal_mode=WAL")
        conn.execute("PRAGMA synchronous=FULL")
        conn.execute("BEGIN IMMEDIATE")  # two writers making the history at once: the second sees the first's
        try:
            tables = {r[0] for r in conn.execute("SELECT name FROM sqlite_master WHERE type = 'table'")}
            if not tables:
                conn.execute(f"PRAGMA application_id = {APPLICATION_ID}")
                for statement in (_SCHEMA + _APPEND_ONLY).split(";\n"):
                    if statement.strip():
                        conn.execute(statement)
                conn.execute("INSERT INTO meta VALUES ('format', ?), ('format_version', ?)", (FORMAT, FORMAT_VERSION))
            conn.execute("COMMIT")
        except BaseException:
            conn.execute("ROLLBACK")
            conn.close()
            raise
        self._identify(conn)
        return conn

    def _failure(self, exc: sqlite3.DatabaseError, doing: str) -> FtcalError:
        """One line naming what went wrong: a lock, read-only storage, a write error, or (checked) corruption."""
        text = (str(exc).splitlines() or [type(exc).__name__])[0]
        name = getattr(exc, "sqlite_errorname", "")
        low = text.lower()
        if "locked" in low or "busy" in low or name.startswith(("SQLITE_BUSY", "SQLITE_LOCKED")):
            wait = READ_TIMEOUT_S if self.read_only else BUSY_TIMEOUT_S
            return FtcalError(f"{self.path}: the history is locked by another process writing to it (waited "
                              f"{wait:g} s); try again when it has finished. Nothing was changed.")
        if "readonly" in low or "read-only" in low or name.startswith("SQLITE_READONLY") or (
                "unable to open" in low and not os.access(self.folder, os.W_OK)):
            return ParameterError("history_dir", f"{self.path}: the history is on read-only storage or not "
                                  f"writable by you (SQLite: {text}); nothing was recorded. Record to a writable "
                                  "{history_dir}.")
        if "full" in low or name in ("SQLITE_FULL", "SQLITE_IOERR") or name.startswith("SQLITE_IOERR"):
            return FtcalError(f"{self.path}: cannot write the history (SQLite: {text}); nothing was recorded.")
        if "not a database" in low or name == "SQLITE_NOTADB":
            return ParameterError("history_dir", f"{self.path}: SQLite cannot read it as a database ({text}); not "
                                  "a usable ftcal history: move it aside or choose another {history_dir}.")
        check = self._integrity()
        if check is not None:
            return FtcalError(f"{self.path}: not an intact ftcal history database (integrity check: {check}); "
                              "move it aside to start a new history.")
        return FtcalError(f"{self.path}: cannot {doing} the history (SQLite: {text}).")

    def _integrity(self) -> str | None:
        """SQLite's quick_check on a fresh read-only connection: its first complaint, or None when it passes."""
        try:
            conn = sqlite3.connect(self._uri(), uri=True, timeout=READ_TIMEOUT_S, isolation_level=None)
            conn.text_factory = lambda raw: raw.decode("utf-8", "replace")  # its report may quote damaged text
            try:
                result = conn.execute("PRAGMA quick_check").fetchone()[0]
            except UnicodeDecodeError:
                return "text that is not UTF-8 where SQLite keeps its schema"
            finally:
                conn.close()
        except sqlite3.DatabaseError as exc:
            if "malformed" in str(exc) or getattr(exc, "sqlite_errorname", "").startswith("SQLITE_CORRUPT"):
                return (str(exc).splitlines() or ["malformed"])[0]
            return None  # the check itself could not run (a lock, ...): corruption is not shown
        return None if result == "ok" else (str(result).splitlines() or ["failed"])[0]

    def close(self) -> None:
        if self._connection is not None:
            self._connection.close()

    def __enter__(self) -> "History":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    # -- writing ---------------------------------------------------------------------------------

    @contextlib.contextmanager
    def transaction(self) -> Iterator[sqlite3.Connection]:
        """One write transaction (``BEGIN IMMEDIATE`` … ``COMMIT``; rolled back on any error).

        Database errors inside it (a full disk, read-only storage, a lock) become one-line
        :class:`FtcalError`s; nothing of the transaction is kept.
        """
        if self.read_only:
            raise FtcalError(f"{self.path}: opened for reading only.")
        conn = self._connection
        try:
            conn.execute("BEGIN IMMEDIATE")
        except sqlite3.DatabaseError as exc:
            raise self._failure(exc, "write to") from None
        try:
            yield conn
        except sqlite3.DatabaseError as exc:
            _rollback(conn)
            raise self._failure(exc, "write to") from None
        except BaseException:
            _rollback(conn)
            raise
        try:
            conn.execute("COMMIT")
        except sqlite3.DatabaseError as exc:
            _rollback(conn)
            raise self._failure(exc, "write to") from None

    def append_calibration(self, conn: sqlite3.Connection, serial: str, summary: CalibrationSummary,
                           recorded_utc: str | None = None) -> bool:
        """Insert a calibration inside ``conn``'s transaction; False when this file is already recorded."""
        cursor = conn.execute(
            "INSERT OR IGNORE INTO calibrations (serial, recorded_utc, model_sha256, source, outputs, bias, gain) "
            "VALUES (?, ?, ?, ?, ?, ?, ?)",
            (serial, recorded_utc or _now(), summary.model_sha256, summary.source, json.dumps(summary.outputs),
             _json_numbers(summary.bias.tolist()), _json_numbers(summary.gain.tolist())))
        return cursor.rowcount == 1

    def append_acceptance(self, conn: sqlite3.Connection, serial: str, model_sha256: str, passed: bool,
                          rmse: Sequence[float], thresholds: dict, data: Sequence[str],
                          recorded_utc: str | None = None) -> None:
        """Insert an acceptance result inside ``conn``'s transaction (a non-finite RMS is stored as null)."""
        conn.execute(
            "INSERT INTO acceptances (serial, recorded_utc, model_sha256, passed, rmse, thresholds, data) "
            "VALUES (?, ?, ?, ?, ?, ?, ?)",
            (serial, recorded_utc or _now(), model_sha256, int(bool(passed)), _json_numbers([float(v) for v in rmse]),
             _json_numbers(thresholds), json.dumps([str(d) for d in data])))

    def record_calibration(self, serial: str, summary: CalibrationSummary,
                           recorded_utc: str | None = None) -> bool:
        """Append a calibration (one transaction); False when this file is already recorded for ``serial``."""
        with self.transaction() as conn:
            return self.append_calibration(conn, serial, summary, recorded_utc)

    # -- reading ---------------------------------------------------------------------------------

    def calibrations(self, serial: str) -> list[CalibrationRecord]:
        """Calibrations of ``serial``, oldest first."""
        rows = self._read("SELECT id, recorded_utc, model_sha256, source, outputs, bias, gain FROM calibrations "
                          "WHERE serial = ? ORDER BY id", serial)
        out = []
        for r in rows:
            with self._row("calibrations", r[0]):
                outputs = tuple(str(v) for v in _list(json.loads(r[4])))
                bias = _numbers(json.loads(r[5]))
                gain = _numbers(json.loads(r[6]))
                if bias.shape != (6,) or gain.ndim != 2 or gain.shape[0] != 6 or len(outputs) != 6:
                    raise ValueError("bias, gain or outputs of the wrong size")
                out.append(CalibrationRecord(int(r[0]), _text(r[1]),
                                             CalibrationSummary(_text(r[2]), _text(r[3]), outputs, bias, gain)))
        return out

    def acceptances(self, serial: str) -> list[AcceptanceRecord]:
        """Acceptance results of ``serial``, oldest first (a stored null RMS reads as NaN)."""
        rows = self._read("SELECT id, recorded_utc, model_sha256, passed, rmse, thresholds, data FROM acceptances "
                          "WHERE serial = ? ORDER BY id", serial)
        out = []
        for r in rows:
            with self._row("acceptances", r[0]):
                rmse = _numbers(json.loads(r[4]))
                thresholds = json.loads(r[5])
                data = [str(d) for d in _list(json.loads(r[6]))]
                if rmse.ndim != 1 or not isinstance(thresholds, dict) or r[3] not in (0, 1):
                    raise ValueError("rmse, thresholds or passed of the wrong kind")
                out.append(AcceptanceRecord(int(r[0]), _text(r[1]), _text(r[2]), bool(r[3]), rmse.tolist(),
                                            thresholds, data))
        return out

    def serials(self) -> list[str]:
        """Every serial with a record."""
        rows = self._read("SELECT serial FROM calibrations UNION SELECT serial FROM acceptances ORDER BY 1")
        return [str(r[0]) for r in rows]

    def _read(self, sql: str, *params) -> list[tuple]:
        if self._connection is None or not self._tables():
            return []  # an empty file read as an empty history
        try:
            return self._connection.execute(sql, params).fetchall()
        except (sqlite3.DatabaseError, ValueError) as exc:
            if isinstance(exc, sqlite3.DatabaseError):
                raise self._failure(exc, "read") from None
            raise FtcalError(f"{self.path}: cannot read the history ({exc}).") from None

    def _tables(self) -> set[str]:
        try:
            return {r[0] for r in self._connection.execute("SELECT name FROM sqlite_master WHERE type = 'table'")}
        except sqlite3.DatabaseError as exc:
            raise self._failure(exc, "read") from None
        except UnicodeDecodeError:
            raise FtcalError(f"{self.path}: its schema holds text that is not UTF-8; not a usable history.") from None

    @contextlib.contextmanager
    def _row(self, table: str, row_id) -> Iterator[None]:
        """A row that does not parse (edited by hand or by another program) is one line naming it."""
        try:
            yield
        except (ValueError, TypeError, KeyError, IndexError, RecursionError) as exc:
            raise FtcalError(f"{self.path}: row {row_id} of table {table} is not what ftcal wrote ("
                             f"{(str(exc).splitlines() or [type(exc).__name__])[0][:120]}); the file was edited. "
                             "Nothing else was changed.") from None


def _rollback(conn: sqlite3.Connection) -> None:
    try:
        conn.execute("ROLLBACK")
    except sqlite3.DatabaseError:
        pass  # no transaction left to roll back (SQLite already did)


def _json_numbers(value) -> str:
    """JSON with non-finite floats as null (strict JSON has no NaN)."""
    def clean(v):
        if isinstance(v, float):
            return v if np.isfinite(v) else None
        if isinstance(v, dict):
            return {k: clean(x) for k, x in v.items()}
        if isinstance(v, (list, tuple)):
            return [clean(x) for x in v]
        return v
    return json.dumps(clean(value), allow_nan=False)


def _list(value) -> list:
    if not isinstance(value, list):
        raise ValueError("a list was expected")
    return value


def _numbers(value) -> np.ndarray:
    """Nested lists of numbers (null as NaN) as a float array; anything else is refused."""
    def check(v):
        if isinstance(v, list):
            return [check(x) for x in v]
        if v is None:
            return float("nan")
        if isinstance(v, bool) or not isinstance(v, (int, float)):
            raise ValueError(f"a number was expected, found {type(v).__name__}")
        return float(v)
    return np.array(check(value), dtype=float)


def _text(value) -> str:
    if not isinstance(value, str):
        raise ValueError(f"text was expected, found {type(value).__name__}")
    return value


def _now() -> str:
    return datetime.now(timezone.utc).isoformat(timespec="microseconds")


class DriftWarning(FtcalWarning):
    """A new calibration differs from the last one more than the sensor's history says is normal."""
