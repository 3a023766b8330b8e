"""CSV and Parquet tables read chunk by chunk (Parquet record batches, CSV blocks).

Memory stays at one chunk whatever the file size. Each chunk is checked like a
whole-table read (:func:`ftcal.io.tables.read_dataset`): the file's header
first (repeated names, missing columns), then every chunk's cells (not a
number, boolean or date, empty, NaN or infinite), naming the file, column and
row. Numeric columns of a CSV are read as float64 from the start, so a column
whose first block holds only integers does not fail on a later ``0.5``.
"""

from __future__ import annotations

import os
import re
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import FtcalError
from .tables import _arrow_numbers, table_columns

CHUNK_ROWS = 1 << 16  # rows per chunk: ~4 MB of float64 inputs and outputs
CSV_BLOCK_BYTES = 1 << 22  # CSV bytes parsed per block (~CHUNK_ROWS rows of 13 numbers)


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
    chunk_rows : rows per Parquet chunk (CSV chunks are blocks of about that size)

    Yields
    ------
    TableChunk

    Raises
    ------
    FtcalError
        No such file, not a table, a repeated or missing column, a cell that is
        not a finite number (naming column and row), an empty label cell, or no rows.
    """
    path = Path(path)
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
    for column, role in labels.items():
        if column not in names:
            raise FtcalError(f"{path}: no {role} column {column!r}; the file has {', '.join(names)}.")
    numbers = list(dict.fromkeys((*inputs, *outputs)))
    needed = list(dict.fromkeys((*numbers, *labels)))
    first_row = 0
    roles = {**{c: "output" for c in outputs}, **{c: "input" for c in inputs}}
    for batch in _batches(path, needed, roles, chunk_rows, names):
        table = _as_table(batch)
        chunk = TableChunk(first_row, _arrow_numbers(table, inputs, path, "input", first_row=first_row),
                           _arrow_numbers(table, outputs, path, "output", first_row=first_row) if outputs else None)
        for column, role in labels.items():
            values = table.column(column)
            if values.null_count:
                raise FtcalError(f"{path}: {role} column {column!r} has empty cells.")
            chunk.labels[column] = np.asarray(values.to_pylist(), dtype=object)
        first_row += table.num_rows
        yield chunk
    if first_row == 0:
        raise FtcalError(f"{path}: the table has no rows.")


def _batches(path: Path, columns: list[str], roles: dict[str, str], chunk_rows: int, names: Sequence[str]):
    """Record batches of ``columns``; pyarrow's own errors as one FtcalError line.

    ``roles``: input or output, per numeric column; ``names``: the header.
    """
    suffix = path.suffix.lower()
    try:
        if suffix == ".csv":
            import pyarrow as pa
            import pyarrow.csv as pv

            reader = pv.open_csv(path, read_options=pv.ReadOptions(block_size=CSV_BLOCK_BYTES),
                                 convert_options=pv.ConvertOptions(
                                     include_columns=columns, strings_can_be_null=True,
                                     column_types={c: pa.float64() for c in roles}))
            with reader:
                yield from reader
        else:
            import pyarrow.parquet as pq

            with pq.ParquetFile(path) as parquet:
                yield from parquet.iter_batches(batch_size=chunk_rows, columns=columns)
    except FtcalError:
        raise
    except Exception as exc:  # pyarrow raises many types for corrupt files and bad CSV cells
        detail = str(exc).splitlines()[0] if str(exc) else "no detail"
        column = re.search(r"CSV column #(\d+)", detail)
        if column is not None and int(column.group(1)) < len(names):
            name = names[int(column.group(1))]
            if name in roles:
                _raise_at_bad_cell(path, name, roles[name])
            detail = f"column {name!r}: {detail}"
        raise FtcalError(f"{path}: cannot be read as {suffix[1:].upper()} ({type(exc).__name__}: {detail}).") \
            from None


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
    reader = pv.open_csv(path, read_options=pv.ReadOptions(block_size=CSV_BLOCK_BYTES),
                         convert_options=pv.ConvertOptions(include_columns=[name],
                                                           column_types={name: pa.string()}))
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
    import pyarrow as pa

    return pa.Table.from_batches([batch])
