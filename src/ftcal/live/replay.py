"""Replay a recorded table through the live calibrator, chunk by chunk, with scripted re-tares and tool switches.

Memory stays at one chunk (input read by :func:`ftcal.data.table_chunks.iter_table_chunks`, output
written batch by batch into a temporary file renamed into place), so an hour of 1 kHz data replays
in the memory of a few seconds of it. Scripted events split the chunks at their times: an event at
``t`` acts before the first sample at or after ``t``.
"""

from __future__ import annotations

import os
import time as wallclock
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..data.tables import parquet_write_options
from ..runtime.errors import FtcalError, ParameterError
from .calibrator import LiveCalibrator, LiveResult
from .health import names_of

AXES = ("Fx", "Fy", "Fz", "Tx", "Ty", "Tz")


@dataclass(frozen=True)
class ScriptedEvent:
    """``retare`` (no argument) or ``switch`` (a tool name) at a time, s."""

    time: float
    action: str
    argument: str | None = None

    def apply(self, live: LiveCalibrator) -> None:
        if self.action == "retare":
            live.retare()
        elif self.action == "switch":
            live.switch_tool(self.argument)
        else:
            raise FtcalError(f"unknown scripted action {self.action!r}.")


@dataclass(frozen=True)
class ReplayColumns:
    """Which columns of the table feed the calibrator.

    Attributes
    ----------
    time : time column, s
    signal : raw inputs (the model's) or the wrench columns
    raw : True when ``signal`` are the model's inputs
    gravity_kind : "quaternion", "gravity", "imu" or "joints" (the calibrator's robot model gives gravity)
    gravity : 4 quaternion columns (x, y, z, w), 3 gravity / accelerometer columns, or the joint columns
    temperature : temperature column or None
    """

    time: str
    signal: tuple[str, ...]
    raw: bool
    gravity_kind: str
    gravity: tuple[str, ...]
    temperature: str | None = None


@dataclass
class ReplaySummary:
    """What a replay did."""

    n_samples: int = 0
    seconds: float = 0.0  # wall time spent in the calibrator and I/O
    cpu_seconds: float = 0.0
    flag_samples: dict = field(default_factory=dict)  # flag -> samples flagged
    events: list = field(default_factory=list)  # (time, flag, kind, reason), the first MAX_LISTED
    dropped: int = 0  # incomplete rows skipped (the caller's drop_incomplete)

    def line(self) -> str:
        flagged = ", ".join(f"{k} {v}" for k, v in self.flag_samples.items() if v) or "none"
        rate = self.n_samples / self.seconds if self.seconds > 0 else float("inf")
        return (f"{self.n_samples} samples in {self.seconds:.2f} s wall ({self.cpu_seconds:.2f} s CPU, "
                f"{rate:,.0f} samples/s); samples flagged: {flagged}")


MAX_LISTED = 50
# Samples per block when pacing at the recording's speed.
REALTIME_BLOCK = 32


def result_columns(result: LiveResult) -> dict[str, np.ndarray]:
    """The output table's columns for one block: compensated ``Fx..Tz`` (the contact wrench, as
    ``ftcal compensate`` names it), ``calibrated_*``, ``bias_*``, ``bias_std_*``, ``static``, ``updated``,
    ``chi2``, ``flags`` (bit mask), ``flag_names`` and ``tool``."""
    cols = {"time": result.time}
    cols.update({a: result.compensated[:, j] for j, a in enumerate(AXES)})
    cols.update({f"calibrated_{a}": result.calibrated[:, j] for j, a in enumerate(AXES)})
    cols.update({f"bias_{a}": result.bias[:, j] for j, a in enumerate(AXES)})
    cols.update({f"bias_std_{a}": result.bias_std[:, j] for j, a in enumerate(AXES)})
    cols["static"], cols["updated"], cols["chi2"] = result.static, result.updated, result.chi2
    cols["flags"] = result.flags.astype(np.int32)
    masks, which = np.unique(result.flags, return_inverse=True)  # a handful of distinct masks: name each once
    cols["flag_names"] = np.array([";".join(names_of(int(m))) for m in masks], dtype=object)[which.ravel()]
    cols["tool"] = np.full(result.time.size, result.tool, dtype=object)
    return cols


class _Writer:
    """Appends blocks to a CSV or Parquet file (a temporary path the caller renames).

    Blocks are gathered up to ``rows`` rows before a write: a scripted event splits a chunk into blocks, and
    each write costs milliseconds however short the block (2000 re-tares in 20 s of data took 14 s).
    """

    def __init__(self, path: Path, suffix: str, rows: int) -> None:
        self.path, self.suffix, self.parquet, self.first = path, suffix, None, True
        self.rows, self.pending, self.pending_rows = rows, [], 0

    def write(self, cols: dict) -> None:
        self.pending.append(cols)
        self.pending_rows += cols["time"].size
        if self.pending_rows >= self.rows:
            self.flush()

    def flush(self) -> None:
        if not self.pending:
            return
        blocks, self.pending, self.pending_rows = self.pending, [], 0
        cols = blocks[0] if len(blocks) == 1 else {k: np.concatenate([b[k] for b in blocks]) for k in blocks[0]}
        self._write(cols)

    def _write(self, cols: dict) -> None:
        import pandas as pd

        frame = pd.DataFrame(cols)
        if self.suffix == ".csv":
            frame.to_csv(self.path, mode="w" if self.first else "a", header=self.first, index=False,
                         float_format="%.17g")
        else:
            import pyarrow as pa
            import pyarrow.parquet as pq

            table = pa.Table.from_pandas(frame, preserve_index=False)
            if self.parquet is None:
                self.parquet = pq.ParquetWriter(self.path, table.schema, **parquet_write_options(table.schema))
            self.parquet.write_table(table)
        self.first = False

    def close(self) -> None:
        """Close the file (call :meth:`flush` first to write what is gathered)."""
        if self.parquet is not None:
            self.parquet.close()


def replay_table(path: str | os.PathLike, live: LiveCalibrator, columns: ReplayColumns, output: str | os.PathLike,
                 *, events: Sequence[ScriptedEvent] = (), realtime: bool = False,
                 on_block: Callable[[LiveResult], None] | None = None, chunk_rows: int | None = None,
                 before_commit: Callable[[], None] | None = None) -> ReplaySummary:
    """Run ``live`` over a CSV or Parquet table and write its results to ``output`` (atomically).

    Parameters
    ----------
    path : the recording
    live : the calibrator (its state continues from wherever it is)
    columns : ReplayColumns
    output : ``.csv`` or ``.parquet``
    events : scripted re-tares and tool switches
    realtime : pace the replay at the recording's speed (default: as fast as possible)
    on_block : called with each block's result (e.g. to print events)
    chunk_rows : rows read and run at a time (default :data:`ftcal.data.table_chunks.CHUNK_ROWS`); memory
        follows it, not the recording's length
    before_commit : called once the output is written, before it is renamed into place (e.g. saving the state):
        if it raises, no output is left behind

    Returns
    -------
    ReplaySummary

    Raises
    ------
    FtcalError
        Missing columns, non-finite cells, time that does not increase, or an event naming an unknown tool.
    """
    from ..data.table_chunks import CHUNK_ROWS, iter_table_chunks
    from ..data.holds import check_seconds
    from ..runtime.atomic import atomic_path
    from .health import FLAGS

    output = Path(output)
    suffix = output.suffix.lower()
    if suffix not in (".csv", ".parquet"):
        raise ParameterError("output", f"{{output}} {output}: the replay's output must end in .csv or .parquet.")
    for event in events:
        if event.action == "switch" and event.argument not in live.tools:
            raise ParameterError("switch_tool", f"{{switch_tool}} {event.time:g}:{event.argument}: no tool "
                                 f"{event.argument!r} in the library ({', '.join(live.tools)}).")
    names = (columns.time, *columns.signal, *columns.gravity) + ((columns.temperature,) if columns.temperature else ())
    if len(set(names)) != len(names):
        raise FtcalError(f"{path}: a column is named twice among {', '.join(names)}.")
    pending = sorted(events, key=lambda e: e.time)
    summary = ReplaySummary(flag_samples={name: 0 for name in FLAGS})
    wall0, cpu0 = wallclock.perf_counter(), wallclock.process_time()
    start_wall = start_time = None
    with atomic_path(output) as tmp:
        writer = _Writer(tmp, suffix, chunk_rows or CHUNK_ROWS)
        try:
            for chunk in iter_table_chunks(path, names, chunk_rows=chunk_rows or CHUNK_ROWS):
                x = chunk.inputs
                t = x[:, 0]
                check_seconds(t, columns.time, str(path))  # as payload checks it: a ns column is refused
                if np.any(np.diff(t) <= 0):
                    row = chunk.first_row + int(np.flatnonzero(np.diff(t) <= 0)[0]) + 1
                    raise FtcalError(f"{path}: time column {columns.time!r} does not increase at row {row}.")
                if live.last_time is not None and t[0] <= live.last_time:
                    raise FtcalError(f"{path}: row {chunk.first_row} is at t={t[0]:.9g} s, not after the calibrator's "
                                     f"last sample (t={live.last_time:.9g} s"
                                     + (f", from {live.state_path}" if live.state_path is not None else "")
                                     + "): a resumed calibrator goes on from where it stopped; replay a later "
                                       "recording, or start from another state.")
                if realtime:
                    start_wall = wallclock.perf_counter() if start_wall is None else start_wall
                    start_time = t[0] if start_time is None else start_time
                cuts = [0] + [int(np.searchsorted(t, e.time)) for e in pending if t[0] < e.time <= t[-1]] + [t.size]
                if realtime:  # small blocks, paced one by one
                    cuts = sorted(set(cuts) | set(range(0, t.size, REALTIME_BLOCK)))
                for a, b in zip(cuts[:-1], cuts[1:]):
                    while pending and (a < t.size and pending[0].time <= t[a]):
                        pending.pop(0).apply(live)
                    if b <= a:
                        continue
                    result = _run(live, x[a:b], columns)
                    if realtime:
                        ahead = (t[b - 1] - start_time) - (wallclock.perf_counter() - start_wall)
                        if ahead > 0:
                            wallclock.sleep(ahead)
                    writer.write(result_columns(result))
                    summary.n_samples += result.n_samples
                    for name in FLAGS:
                        from .health import BIT

                        summary.flag_samples[name] += int(np.count_nonzero(result.flags & BIT[name]))
                    room = MAX_LISTED - len(summary.events)
                    summary.events += [e for e in result.events if e[2] == "raised"][:max(room, 0)]
                    if on_block is not None:
                        on_block(result)
            while pending:  # events after the last sample still change the state that is saved
                pending.pop(0).apply(live)
            writer.flush()
        finally:
            writer.close()
        if summary.n_samples == 0:
            raise FtcalError(f"{path}: no samples to replay.")
        if before_commit is not None:
            before_commit()
    summary.seconds = wallclock.perf_counter() - wall0
    summary.cpu_seconds = wallclock.process_time() - cpu0
    return summary


def _run(live: LiveCalibrator, x: np.ndarray, columns: ReplayColumns) -> LiveResult:
    k = 1
    signal = x[:, k:k + len(columns.signal)]
    k += len(columns.signal)
    gravity = x[:, k:k + len(columns.gravity)]
    k += len(columns.gravity)
    temperature = x[:, k] if columns.temperature else None
    kinds = {"quaternion": "quaternion", "gravity": "gravity", "imu": "imu", "joints": "joints"}
    source = {kinds[columns.gravity_kind]: gravity}
    signals = {"raw": signal} if columns.raw else {"wrench": signal}
    return live.run(x[:, 0], temperature=temperature, **signals, **source)
