"""CSV and Parquet tables read chunk by chunk (Parquet record batches, CSV blocks).

Memory stays at one chunk whatever the file size. Each chunk is checked like a
whole-table read (:func:`ftcal.data.tables.load_dataset`): the file's header
first (repeated names, missing columns), then every chunk's cells (not a
number, boolean or date, empty, NaN or infinite), naming the file, column and
row. Numeric columns of a CSV are read as float64 from the start, so a column
whose first block holds only integers does not fail on a later ``0.5``.
"""

from __future__ import annotations

import os
import re
from collections.abc import Iterator, Mapping, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..runtime.errors import FtcalError
from ..runtime.executors import KEEP_FILES_ENV
from .parquet_checks import FooterCheck, locate_unreadable
from .tables import arrow_numbers, complete_rows, table_columns, table_label_column

CHUNK_ROWS = 1 << 16  # rows per chunk: ~4 MB of float64 inputs and outputs
CSV_BLOCK_BYTES = 1 << 22  # CSV bytes parsed per block (~CHUNK_ROWS rows of 13 numbers)
CSV_READ_WHOLE_BYTES = 1 << 27  # smaller CSV files are parsed whole, in parallel, then served in chunks
# Block size of those whole reads: a block that fits the core's cache parses faster, and the threads share
# more blocks evenly (a 49 MB file, 1 MiB against 4 MiB blocks: 0.30 against 0.34 CPU s, 0.33 against 0.51 s).
CSV_WHOLE_BLOCK_BYTES = 1 << 20
KEEP_IN_MEMORY_BYTES = 1 << 26  # files whose chunks total at most this stay in memory (see keep_in_memory)


@dataclass
class TableChunk:
    """Consecutive rows of one file.

    Attributes
    ----------
    first_row : int                          index of the chunk's first row in the file
    inputs : ndarray of shape (m, n_inputs)
    outputs : ndarray of shape (m, n_outputs), or None when the file has no output columns
    labels : dict of column name -> ndarray of shape (m,) (object), the requested label columns
    """

    first_row: int
    inputs: np.ndarray
    outputs: np.ndarray | None
    labels: dict[str, np.ndarray] = field(default_factory=dict)

    @property
    def n_rows(self) -> int:
        return self.inputs.shape[0]


def table_has_columns(path: str | os.PathLike, columns: Sequence[str]) -> bool:
    """Whether the file's header names every one of ``columns``."""
    names = set(table_columns(path))
    return all(c in names for c in columns)


@dataclass
class _KeptFile:
    """A file's chunks as one pass read them, and what that pass asked for."""

    identity: tuple[int, int]  # size and modification time when read
    inputs: tuple[str, ...]
    outputs: tuple[str, ...] | None  # None: the chunks have no outputs
    labels: tuple[str, ...]
    chunks: list[TableChunk]

    def serves(self, identity, inputs, outputs, labels) -> bool:
        """Whether these chunks answer a request for those columns of the unchanged file."""
        same_outputs = self.outputs == tuple(outputs or ()) or (not outputs and self.outputs is not None)
        return (identity == self.identity and self.inputs == tuple(inputs) and same_outputs
                and set(labels) <= set(self.labels))


# While keep_in_memory() is active: resolved path -> the file's kept chunks, or None for a file
# too large to keep. None outside the block.
_KEPT: dict[Path, _KeptFile | None] | None = None
# In a local cluster's worker process (KEEP_FILES_ENV set by runtime.executors): the files it kept, for its lifetime.
_WORKER_KEPT: dict[Path, _KeptFile | None] = {}


@contextmanager
def keep_in_memory():
    """Inside the block, a file's chunks are read once and served from memory on later passes.

    For commands that pass over the same small files several times in this
    process (``fit``: ranges, statistics, training metrics): parsing a CSV
    costs more than most passes. A file stays on the streaming path (read on
    every pass, one chunk in memory) once its chunks exceed
    ``KEEP_IN_MEMORY_BYTES``, or when a later pass asks for other columns.
    A file that changes between passes (size or modification time) is read again.
    """
    global _KEPT
    outer, _KEPT = _KEPT, {}
    try:
        yield
    finally:
        _KEPT = outer


def _identity(path: Path) -> tuple[int, int] | None:
    try:
        stat = path.stat()
    except OSError:
        return None  # the reader reports it
    return stat.st_size, stat.st_mtime_ns


def iter_table_chunks(path: str | os.PathLike, inputs: Sequence[str], outputs: Sequence[str] | None = None, *,
                      labels: Sequence[str] | Mapping[str, str] = (), require_outputs: bool = True,
                      chunk_rows: int = CHUNK_ROWS) -> Iterator[TableChunk]:
    """Yield the named columns of a CSV or Parquet file, chunk by chunk.

    Parameters
    ----------
    path : CSV (``.csv``) or Parquet (``.parquet``, ``.pq``) file
    inputs : input column names, read as float64
    outputs : output column names, read as float64; None for none
    labels : columns yielded as they are; a mapping gives each one's role in messages
        (``{"load": "group"}``: "no group column 'load'"), a sequence the role "label"
    require_outputs : when False and the file lacks an output column, chunks have ``outputs=None``
    chunk_rows : rows per chunk (Parquet files, and CSV files read whole; larger CSV files come in ~4 MB blocks)

    Yields
    ------
    TableChunk

    Raises
    ------
    FtcalError
        No such file, not a table, a repeated or missing column, a cell that is
        not a finite number (naming column and row), an empty label cell, or no rows.
    """
    chunks = _read_table_chunks(Path(path), inputs, outputs, labels, require_outputs, chunk_rows)
    kept_files = _KEPT if _KEPT is not None else _WORKER_KEPT if os.environ.get(KEEP_FILES_ENV) == "1" else None
    if kept_files is None:
        yield from chunks
        return
    key, label_names = Path(path).resolve(), tuple(labels)
    identity, kept = _identity(key), kept_files.get(key, ())
    if kept and kept.serves(identity, inputs, outputs, label_names):
        for chunk in kept.chunks:
            yield TableChunk(chunk.first_row, chunk.inputs, chunk.outputs if outputs else None,
                             {name: chunk.labels[name] for name in label_names})
        return
    keep, size = kept == (), 0  # keep the chunks of a file's first read only
    read = []
    for chunk in chunks:
        if keep:
            size += chunk.inputs.nbytes + sum(v.nbytes for v in (chunk.outputs, *chunk.labels.values())
                                              if v is not None)
            if size <= KEEP_IN_MEMORY_BYTES:
                read.append(chunk)
            else:
                keep, read = False, []
                kept_files[key] = None
        yield chunk
    if keep:
        kept_files[key] = _KeptFile(identity, tuple(inputs), None if read[0].outputs is None else tuple(outputs),
                               label_names, read)


def _read_table_chunks(path: Path, inputs: Sequence[str], outputs: Sequence[str] | None,
                       labels: Sequence[str] | Mapping[str, str], require_outputs: bool,
                       chunk_rows: int) -> Iterator[TableChunk]:
    """:func:`iter_table_chunks` from the file itself."""
    names = table_columns(path)  # checks existence and type, reads the header only
    twice = next((n for n in names if names.count(n) > 1), None)
    if twice is not None:
        raise FtcalError(f"{path}: the column name {twice!r} appears {names.count(twice)} times; "
                         "column names must be unique.")
    outputs = tuple(outputs or ())
    if outputs and not require_outputs and not all(c in names for c in outputs):
        outputs = ()
    for role, wanted in (("input", inputs), ("output", outputs)):
        missing = [c for c in wanted if c not in names]
        if missing:
            raise FtcalError(f"{path}: missing {role} column(s) {', '.join(map(repr, missing))}; "
                             f"the file has {', '.join(names)}.")
    labels = dict(labels) if isinstance(labels, Mapping) else dict.fromkeys(labels, "label")
    # The label each chunk is keyed by -> the column read for it (an older table's 'group' for 'load').
    read_as = {column: table_label_column(names, column) for column in labels}
    labels = {read_as[column]: role for column, role in labels.items()}
    for column, role in labels.items():
        if column not in names:
            raise FtcalError(f"{path}: no {role} column {column!r}; the file has {', '.join(names)}.")
    numbers = list(dict.fromkeys((*inputs, *outputs)))
    needed = list(dict.fromkeys((*numbers, *labels)))
    first_row = 0
    roles = {**{c: "output" for c in outputs}, **{c: "input" for c in inputs}}
    for batch in _batches(path, needed, roles, chunk_rows, names):
        table = _as_table(batch)
        n_read = table.num_rows
        table = complete_rows(table, needed, path, first_row)
        chunk = TableChunk(first_row, arrow_numbers(table, inputs, path, "input", first_row=first_row),
                           arrow_numbers(table, outputs, path, "output", first_row=first_row) if outputs else None)
        for label, column in read_as.items():
            values = table.column(column)
            if values.null_count:
                raise FtcalError(f"{path}: {labels[column]} column {column!r} has empty cells.")
            chunk.labels[label] = np.asarray(values.to_pylist(), dtype=object)
        first_row += n_read
        yield chunk
    if first_row == 0:
        raise FtcalError(f"{path}: the table has no rows.")


def _batches(path: Path, columns: list[str], roles: dict[str, str], chunk_rows: int, names: Sequence[str]):
    """Record batches (or slices of a small CSV file read whole) of ``columns``.

    pyarrow's own errors become one FtcalError line. ``roles``: input or output, per numeric column; ``names``: the header.
    """
    suffix = path.suffix.lower()
    try:
        if suffix == ".csv":
            import pyarrow as pa
            import pyarrow.csv as pv

            options = dict(read_options=pv.ReadOptions(block_size=CSV_BLOCK_BYTES),
                           convert_options=pv.ConvertOptions(include_columns=columns, strings_can_be_null=True,
                                                             column_types={c: pa.float64() for c in roles}))
            if path.stat().st_size <= CSV_READ_WHOLE_BYTES:
                # Parsed in parallel blocks (faster than the streaming reader, which parses one at a
                # time), then served in chunks of chunk_rows: a 4 MB block holds only ~17k rows.
                whole = pv.ReadOptions(block_size=CSV_WHOLE_BLOCK_BYTES)
                table = pv.read_csv(path, **dict(options, read_options=whole))
                for start in range(0, table.num_rows, chunk_rows):
                    yield table.slice(start, chunk_rows)  # no copy: the rows stay in their parsed blocks
                return
            with pv.open_csv(path, **options) as reader:
                yield from reader
        else:
            import pyarrow.parquet as pq

            # pre_buffer off: pyarrow's pre-buffering kept every column chunk read so far (a 1-hour
            # 1 kHz table grew the reader by 250 MB); without it memory stays at one chunk.
            with pq.ParquetFile(path, page_checksum_verification=True, pre_buffer=False) as parquet:
                footer = FooterCheck(path, parquet.metadata, columns)
                for batch in parquet.iter_batches(batch_size=chunk_rows, columns=columns):
                    footer.feed(batch)
                    yield batch
                footer.finish()
    except FtcalError:
        raise
    except Exception as exc:  # pyarrow raises many types for corrupt files and bad CSV cells
        detail = str(exc).splitlines()[0] if str(exc) else "no detail"
        where = locate_unreadable(path, columns) if suffix != ".csv" else ""
        column = re.search(r"CSV column #(\d+)", detail)
        if column is not None and int(column.group(1)) < len(names):
            name = names[int(column.group(1))]
            if name in roles:
                _raise_at_bad_cell(path, name, roles[name])
            detail = f"column {name!r}: {detail}"
        raise FtcalError(f"{path}: {where + ' ' if where else ''}cannot be read as {suffix[1:].upper()} "
                         f"({type(exc).__name__}: {detail}).") from None


def _raise_at_bad_cell(path: Path, name: str, role: str) -> None:
    """Raise the whole-table reader's error (line and value) for the first non-number in CSV column ``name``.

    Only runs once pyarrow has refused the column, and reads it again as text,
    block by block. Returns without raising when no cell is refused (pyarrow
    and pandas disagree on that text): the caller then reports pyarrow's error.
    """
    import pandas as pd
    import pyarrow as pa
    import pyarrow.csv as pv

    first_row = 0
    try:
        reader = pv.open_csv(path, read_options=pv.ReadOptions(block_size=CSV_BLOCK_BYTES),
                             convert_options=pv.ConvertOptions(include_columns=[name],
                                                               column_types={name: pa.string()}))
    except pa.ArrowException:
        return  # not even text (invalid UTF-8): the caller reports pyarrow's own error
    with reader:
        for batch in reader:
            text = batch.column(0).to_pandas()
            bad = np.flatnonzero(pd.to_numeric(text, errors="coerce").isna() & text.notna()
                                 & (text.str.strip() != ""))
            if len(bad):
                row = int(bad[0])
                kind = _kind_of_text(text.iloc[row])
                if kind is not None:  # as the whole-table reader, which sees pyarrow's inferred type
                    raise FtcalError(f"{path}: {role} column {name!r} holds {kind} values such as "
                                     f"{text.iloc[row]!r}, not numbers.")
                raise FtcalError(f"{path}: column {name!r} line {first_row + row + 2} holds {text.iloc[row]!r}, "
                                 "not a number.")
            first_row += batch.num_rows


def _kind_of_text(text: str) -> str | None:
    """``"bool"`` or ``"date"`` for CSV text that pyarrow reads as such, else None."""
    import datetime

    if text.strip().lower() in ("true", "false"):
        return "bool"
    try:
        datetime.datetime.fromisoformat(text.strip())
    except ValueError:
        return None
    return "date"


def _as_table(batch):
    """A record batch, or a table slice as it is, as a table."""
    import pyarrow as pa

    return batch if isinstance(batch, pa.Table) else pa.Table.from_batches([batch])
