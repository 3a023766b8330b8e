"""Corruption checks for Parquet files without page checksums: the footer against the data.

ftcal writes page checksums and pyarrow verifies them on every read. A file from
another writer usually has none, so a flipped bit in a data page decodes to a
different number without a word. What the file still says about itself is its
footer: the row count of every row group and, per column chunk, the number of
values, the number of empty cells and the exact minimum and maximum. This module
checks the decoded values against those, row group by row group, as the rows
stream by (memory: one accumulator per column). A flip that changes a value
outside [min, max], an extreme itself, a null or a row count is caught; a flip
that moves a value within [min, max] cannot be seen without checksums
(docs/security.md gives the measured fractions). Decoding and decompression
errors are located to the column chunk (:func:`locate_unreadable`).
"""

from __future__ import annotations

import math
from pathlib import Path

from ..runtime.errors import FtcalError

_ADVICE = "the file is corrupt (it has no page checksums; tables written by `ftcal dataset` have them)"


class FooterCheck:
    """Feed the batches of a Parquet read in file order; each row group is checked as it completes.

    Parameters
    ----------
    path : the file, for messages
    metadata : its ``pyarrow.parquet.FileMetaData``
    columns : the top-level columns being read (flat numeric ones are compared with their statistics)
    """

    def __init__(self, path: Path, metadata, columns):
        self.path, self.meta = path, metadata
        leaves = {metadata.schema.column(i).path: i for i in range(metadata.num_columns)}
        self.columns = {name: leaves[name] for name in columns if name in leaves}  # flat columns only
        rows = [metadata.row_group(g).num_rows for g in range(metadata.num_row_groups)]
        if sum(rows) != metadata.num_rows:
            raise FtcalError(f"{path}: the footer declares {metadata.num_rows:,} rows but its row groups hold "
                             f"{sum(rows):,}; {_ADVICE}.")
        self.rows, self.group, self.done = rows, 0, 0
        self._reset()

    def _reset(self) -> None:
        self.seen = {name: [0, None, None] for name in self.columns}  # nulls, min, max

    def feed(self, batch) -> None:
        """Account for the next rows of the read (a pyarrow RecordBatch or Table)."""
        start = 0
        while start < batch.num_rows:
            self._skip_empty_groups()
            if self.group >= len(self.rows):
                raise FtcalError(f"{self.path}: the data hold more rows than the footer's {self.meta.num_rows:,}; "
                                 f"{_ADVICE}.")
            take = min(batch.num_rows - start, self.rows[self.group] - self.done)
            part = batch.slice(start, take)
            for name, seen in self.seen.items():
                values = part.column(name)
                seen[0] += values.null_count
                if not _comparable(values.type):
                    continue
                low, high = _extremes(values)
                if low is not None:
                    seen[1] = low if seen[1] is None else _nan_min(seen[1], low)
                    seen[2] = high if seen[2] is None else _nan_max(seen[2], high)
            start += take
            self.done += take
            if self.done == self.rows[self.group]:
                self._check_group()

    def finish(self) -> None:
        """Call after the last batch: every row group the footer declares must have been read."""
        self._skip_empty_groups()
        if self.group < len(self.rows):
            read = sum(self.rows[:self.group]) + self.done
            raise FtcalError(f"{self.path}: the data end after {read:,} rows but the footer declares "
                             f"{self.meta.num_rows:,}; {_ADVICE}.")

    def _skip_empty_groups(self) -> None:
        while self.group < len(self.rows) and self.rows[self.group] == 0 and self.done == 0:
            self._check_group()

    def _check_group(self) -> None:
        group = self.meta.row_group(self.group)
        for name, index in self.columns.items():
            chunk = group.column(index)
            where = f"{self.path}: column {name!r}, row group {self.group}"
            if chunk.num_values != group.num_rows:
                raise FtcalError(f"{where}: the footer declares {chunk.num_values:,} values in "
                                 f"{group.num_rows:,} rows; {_ADVICE}.")
            nulls, low, high = self.seen[name]
            stats = chunk.statistics if chunk.is_stats_set else None
            if stats is None:
                continue
            if stats.has_null_count and nulls != stats.null_count:
                raise FtcalError(f"{where}: {nulls:,} empty cells where the footer counts {stats.null_count:,}; "
                                 f"{_ADVICE}.")
            if stats.has_min_max and low is not None and not (_same(low, stats.min) and _same(high, stats.max)):
                raise FtcalError(f"{where}: the values range over [{low!r}, {high!r}] where the footer says "
                                 f"[{stats.min!r}, {stats.max!r}]; {_ADVICE}.")
        self.group += 1
        self.done = 0
        self._reset()


def _comparable(arrow_type) -> bool:
    """Integer and floating columns: their footer extremes are exact numbers."""
    import pyarrow.types as pt

    return pt.is_integer(arrow_type) or pt.is_float32(arrow_type) or pt.is_float64(arrow_type)


# Arrow type name -> numpy dtype of its values buffer, for the numeric types read without a copy.
PLAIN_NUMBERS = {"double": "<f8", "float": "<f4", "int64": "<i8", "int32": "<i4", "int16": "<i2", "int8": "i1",
                 "uint64": "<u8", "uint32": "<u4", "uint16": "<u2", "uint8": "u1"}


def _extremes(values) -> tuple:
    """Minimum and maximum of a numeric arrow array or chunked array, as pyarrow's ``min_max`` gives them.

    Columns without empty cells or NaN are reduced on their values buffer with numpy (the same
    exact numbers): importing ``pyarrow.compute`` costs more than the reductions of a whole 10⁶-row
    table. Any other column goes to ``min_max`` itself, whose result with NaN depends on where they are.
    """
    import numpy as np

    dtype = PLAIN_NUMBERS.get(str(values.type))
    if dtype is not None and not values.null_count and len(values):
        lows, highs = [], []
        for chunk in getattr(values, "chunks", [values]):
            if len(chunk):
                data = np.frombuffer(chunk.buffers()[1], dtype=dtype, count=len(chunk),
                                     offset=chunk.offset * np.dtype(dtype).itemsize)
                lows.append(np.minimum.reduce(data))  # NaN propagates: it sends the column to min_max
                highs.append(np.maximum.reduce(data))
        low, high = np.min(lows), np.max(highs)
        if low == low and high == high:
            return low.item(), high.item()
    import pyarrow.compute as pc

    extremes = pc.min_max(values)
    return extremes["min"].as_py(), extremes["max"].as_py()


def footer_ranges(paths, columns) -> "np.ndarray | None":
    """Min and max of each column over Parquet files, as their footers declare them, or None.

    None unless every file is a regular Parquet file whose every non-empty row group states the
    minimum and maximum of every column (plain numbers, no empty cells). What the data hold is
    checked against these figures as they are read (:class:`FooterCheck`); a caller that uses them
    before reading must still compare them with the ranges it reads.

    Parameters
    ----------
    paths : sequence of files
    columns : column names

    Returns
    -------
    ndarray of shape (len(columns), 2), float64, or None
    """
    import numpy as np

    low, high = np.full(len(columns), np.inf), np.full(len(columns), -np.inf)
    for path in map(Path, paths):
        if path.suffix.lower() not in (".parquet", ".pq") or not path.is_file():
            return None
        try:
            import pyarrow.parquet as pq

            meta = pq.read_metadata(path)
            leaves = {meta.schema.column(i).path: i for i in range(meta.num_columns)}
            for g in range(meta.num_row_groups):
                group = meta.row_group(g)
                if group.num_rows == 0:
                    continue
                for j, name in enumerate(columns):
                    chunk = group.column(leaves[name])
                    stats = chunk.statistics if chunk.is_stats_set else None
                    if (stats is None or not stats.has_min_max or not stats.has_null_count or stats.null_count
                            or str(chunk.physical_type) not in ("DOUBLE", "FLOAT", "INT32", "INT64")):
                        return None
                    low[j], high[j] = min(low[j], float(stats.min)), max(high[j], float(stats.max))
        except Exception:  # noqa: BLE001 - unreadable or other columns: the readers name the problem
            return None
    return np.c_[low, high] if np.isfinite(low).all() and np.isfinite(high).all() else None


def _same(decoded, declared) -> bool:
    if isinstance(declared, float) or isinstance(decoded, float):
        return float(decoded) == float(declared)  # -0.0 == 0.0; NaN matches nothing
    return decoded == declared


def _nan_min(a, b):
    """min ignoring NaN (as the footer and ``pc.min_max`` do), NaN only if both are."""
    return b if _is_nan(a) else a if _is_nan(b) else min(a, b)


def _nan_max(a, b):
    return b if _is_nan(a) else a if _is_nan(b) else max(a, b)


def _is_nan(value) -> bool:
    return isinstance(value, float) and math.isnan(value)


def locate_unreadable(path: Path, columns) -> str | None:
    """``"column 'fx', row group 3"`` for the first column chunk pyarrow cannot decode, else None.

    Reads one column chunk at a time, so it costs at most one more pass over the file
    and runs only after a read has failed.
    """
    import pyarrow.parquet as pq

    try:
        parquet = pq.ParquetFile(path, page_checksum_verification=True)
    except Exception:  # noqa: BLE001 - the footer itself: the caller's message says so
        return None
    with parquet:
        for group in range(parquet.metadata.num_row_groups):
            for name in columns:
                try:
                    parquet.read_row_group(group, columns=[name])
                except Exception:  # noqa: BLE001 - pyarrow raises many types for corrupt pages
                    return f"column {name!r}, row group {group}"
    return None
