"""CSV and Parquet tables: one row per sample, named columns (docs/formats.md §5).

Each file is one segment and one group unless ``segment_by`` / ``group_by``
name a column; then every distinct value of that column (within a file) is a
segment or group of its own.
"""

from __future__ import annotations

import io
import os
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path

import numpy as np

from ..core.columns import LOAD_COLUMN, OLD_LOAD_COLUMN
from ..core.dataset import DEFAULT_INPUTS, DEFAULT_OUTPUTS, Dataset, concatenate
from ..core.limits import MAX_CELL_MAGNITUDE, MAX_HEADER_BYTES, MAX_TABLE_COLUMNS
from ..runtime.atomic import atomic_path
from ..runtime.checks import check_path
from ..runtime.deprecation import deprecated_alias, old_spelling
from ..runtime.errors import FtcalError, ParameterError
from ..runtime.inputs import check_input_file
from .parquet_checks import PLAIN_NUMBERS as _PLAIN_NUMBERS
from .parquet_checks import FooterCheck, locate_unreadable

TABLE_SUFFIXES = (".csv", ".parquet", ".pq")


def read_table(path: str | os.PathLike):
    """Read a CSV or Parquet file into a pandas DataFrame, with clear errors."""
    return read_arrow(path).to_pandas()


def read_arrow(path: str | os.PathLike):
    """Read a CSV or Parquet file into a pyarrow Table (no pandas), with clear errors.

    Raises
    ------
    FtcalError
        No such file, not a table, a repeated column name, or no rows.
    """
    path = check_input_file(path, "CSV or Parquet table")
    suffix = path.suffix.lower()
    if suffix in TABLE_SUFFIXES:
        header_columns(path)  # encoding and column count checked before pyarrow allocates
    try:
        if suffix in (".parquet", ".pq"):
            import pyarrow.parquet as pq

            table = pq.read_table(path, page_checksum_verification=True)
            footer = FooterCheck(path, pq.read_metadata(path), table.column_names)
            footer.feed(table)
            footer.finish()
        elif suffix == ".csv":
            import pyarrow.csv as pv

            # multi-threaded, and keeps repeated column names (so they can be refused); empty cells are missing
            table = pv.read_csv(path, convert_options=pv.ConvertOptions(strings_can_be_null=True))
        else:
            raise FtcalError(f"{path}: unknown table type {suffix!r}; use .csv or .parquet.")
    except FtcalError:
        raise
    except Exception as exc:  # pyarrow raises many types for corrupt files
        where = locate_unreadable(path, header_columns(path)) if suffix in (".parquet", ".pq") else None
        raise FtcalError(f"{path}: {where + ' ' if where else ''}cannot be read as {suffix[1:].upper()} "
                         f"({type(exc).__name__}: {str(exc).splitlines()[0] if str(exc) else 'no detail'}).") from None
    names = table.column_names
    twice = next((n for n in names if names.count(n) > 1), None)
    if twice is not None:
        raise FtcalError(f"{path}: the column name {twice!r} appears {names.count(twice)} times; "
                         "column names must be unique.")
    if table.num_rows == 0:
        raise FtcalError(f"{path}: the table has no rows.")
    return table


# Arrow types whose values buffer is a plain little-endian numpy array.


_DROPPED: dict | None = None  # (file, first row of the chunk) -> rows dropped, inside drop_incomplete()


@contextmanager
def drop_incomplete() -> Iterator[dict]:
    """Within this block, table reads drop the rows with an empty (null) or NaN cell in the columns they use.

    Yields a dict (file, first row of a chunk) -> rows dropped, filled as files are read;
    reading a file twice (several passes) overwrites its entries, so ``sum(d.values())``
    counts every dropped row once. In-process reads only (not on Dask workers).
    """
    global _DROPPED
    previous, _DROPPED = _DROPPED, {}
    try:
        yield _DROPPED
    finally:
        _DROPPED = previous


def complete_rows(table, columns: Sequence[str], path, first_row: int = 0, *, with_breaks: bool = False):
    """``table`` without its incomplete rows (in ``columns``) inside :func:`drop_incomplete`, else ``table``.

    With ``with_breaks``, also a boolean array over the kept rows, True where rows were dropped just
    before (a gap: ARX lags must not bridge it), or None when nothing was dropped.
    """
    if _DROPPED is None:
        return (table, None) if with_breaks else table
    import pyarrow as pa
    import pyarrow.compute as pc

    keep = None
    for name in dict.fromkeys(columns):
        if name not in table.column_names:
            continue  # a missing column is refused, naming it, by the reader
        column = table.column(name)
        valid = pc.is_valid(column)
        if pa.types.is_floating(column.type):
            valid = pc.and_(valid, pc.invert(pc.fill_null(pc.is_nan(column), True)))
        keep = valid if keep is None else pc.and_(keep, valid)
    if keep is None:
        return (table, None) if with_breaks else table
    dropped = table.num_rows - int(pc.sum(pc.cast(keep, pa.int64())).as_py() or 0)
    _DROPPED[(str(path), first_row)] = dropped
    kept = table.filter(keep) if dropped else table
    if not with_breaks:
        return kept
    if not dropped:
        return kept, None
    index = np.flatnonzero(np.asarray(keep.to_numpy(zero_copy_only=False), dtype=bool))
    return kept, np.r_[False, np.diff(index) > 1]


def arrow_numbers(table, columns: Sequence[str], path: Path, role: str, *, first_row: int = 0) -> np.ndarray:
    """:func:`numeric_columns` of an arrow table.

    Float or integer columns without missing cells convert directly; anything
    else goes through pandas for the exact message.

    Parameters
    ----------
    table : pyarrow Table
    columns : the column names, in the order of the result's columns
    path : the table's file, for messages
    role : ``"input"`` or ``"output"``, for messages
    first_row : the file row of the table's first row (a chunk of a file), for messages

    Returns
    -------
    ndarray of shape (n_rows, len(columns)), float64

    Raises
    ------
    FtcalError
        A missing column, or a cell that is not a finite number.
    """
    names = set(table.column_names)
    if not all(c in names for c in columns):
        return numeric_columns(table.to_pandas(), columns, path, role, first_row=first_row)
    out = np.empty((table.num_rows, len(columns)))
    for j, name in enumerate(columns):
        column = table.column(name)
        dtype = _PLAIN_NUMBERS.get(str(column.type))
        if dtype is None or column.null_count:
            return numeric_columns(table.to_pandas(), columns, path, role, first_row=first_row)
        row = 0
        for chunk in column.chunks:
            # The values buffer itself: pyarrow's to_numpy would import pandas (half a second).
            n = len(chunk)
            out[row:row + n, j] = np.frombuffer(chunk.buffers()[1], dtype=dtype, count=n,
                                                offset=chunk.offset * np.dtype(dtype).itemsize)
            row += n
    if not (np.abs(out) <= MAX_CELL_MAGNITUDE).all():  # NaN fails too
        return numeric_columns(table.to_pandas(), columns, path, role, first_row=first_row)
    return out


def default_inputs(paths: Sequence[str | os.PathLike]) -> tuple[str, ...]:
    """u1..u6,T, or u1..u6 when the first file has no T column (temperature is optional)."""
    if not paths:
        return DEFAULT_INPUTS
    return DEFAULT_INPUTS if "T" in table_columns(paths[0]) else DEFAULT_INPUTS[:-1]


def table_columns(path: str | os.PathLike) -> tuple[str, ...]:
    """The column names of a CSV or Parquet file, read from its header only."""
    path = check_input_file(path, "CSV or Parquet table")
    if path.suffix.lower() in TABLE_SUFFIXES:
        names = header_columns(path)
        if names:
            return names
    return tuple(read_arrow(path).column_names)


def label_column(paths: Sequence[str | os.PathLike], column: str | None) -> str | None:
    """The column to read for the label column ``column``: ``load`` is read from ``group``, its old
    spelling, when no table has ``load`` and every table has ``group`` (with a one-line notice).

    Parameters
    ----------
    paths : the tables (CSV or Parquet)
    column : the label column asked for (``group_by``), or None

    Returns
    -------
    str or None
        ``column``, or ``"group"`` for ``"load"`` in tables written before the load case had its one name.
    """
    if column != LOAD_COLUMN or not paths:
        return column
    names = [table_columns(p) for p in paths]
    if any(LOAD_COLUMN in n for n in names) or not all(OLD_LOAD_COLUMN in n for n in names):
        return column
    return table_label_column(names[0], column)


def table_label_column(names: Sequence[str], column: str | None) -> str | None:
    """The column of one table to read for the label ``column``: ``group`` for ``load`` in a table that has
    ``group`` but no ``load`` (the old spelling; a one-line notice), else ``column``.

    Examples
    --------
    >>> import warnings
    >>> with warnings.catch_warnings():
    ...     warnings.simplefilter("ignore")
    ...     table_label_column(["u1", "group"], "load"), table_label_column(["u1", "load"], "load")
    ('group', 'load')
    """
    if column != LOAD_COLUMN or LOAD_COLUMN in names or OLD_LOAD_COLUMN not in names:
        return column
    old_spelling(f"the table column {OLD_LOAD_COLUMN!r}", f"{LOAD_COLUMN!r} (read as the load case)", stacklevel=4)
    return OLD_LOAD_COLUMN


def default_label_column(paths: Sequence[str | os.PathLike], column: str,
                         why: list[str] | None = None) -> str | None:
    """``column`` (through :func:`label_column`) when every table has it without empty cells, else None.

    A default is never a reason to fail: a table whose column has empty cells (a validation table
    concatenated with a training one, say) leaves the default unused, and ``why`` (when given) gets a
    line saying so; a column the user names is still refused with its empty cells.

    Examples
    --------
    >>> default_label_column([], "load") is None
    True
    """
    if not paths:
        return None
    column = label_column(paths, column)
    if not all(column in table_columns(p) for p in paths):
        return None
    gaps = [str(p) for p in paths if _has_empty_cells(Path(p), column)]
    if gaps:
        if why is not None:
            why.append(f"{gaps[0]}: its {column!r} column has empty cells, so it is not used by default"
                       f"{f' (nor in {len(gaps) - 1} other table(s))' if len(gaps) > 1 else ''}")
        return None
    return column


def _has_empty_cells(path: Path, column: str) -> bool:
    """Whether ``column`` of the table at ``path`` has a missing cell (Parquet: from the footer's null
    counts where every row group has one; otherwise that one column is read)."""
    try:
        if path.suffix.lower() in (".parquet", ".pq"):
            import pyarrow.parquet as pq

            meta = pq.read_metadata(path)
            index = meta.schema.to_arrow_schema().get_field_index(column)
            stats = [meta.row_group(g).column(index).statistics for g in range(meta.num_row_groups)]
            if index >= 0 and all(st is not None and st.has_null_count for st in stats):
                return any(st.null_count for st in stats)
            return pq.read_table(path, columns=[column]).column(column).null_count > 0
        import pyarrow.csv as pv

        table = pv.read_csv(path, convert_options=pv.ConvertOptions(include_columns=[column],
                                                                    strings_can_be_null=True))
        return table.column(column).null_count > 0
    except Exception:  # noqa: BLE001 - an unreadable table: the reader that follows names the problem
        return False


def header_columns(path: Path) -> tuple[str, ...]:
    """The column names in a table's header, checked before any reader allocates for them.

    A CSV header is read as bytes up to :data:`~ftcal.core.limits.MAX_HEADER_BYTES`
    and must be UTF-8 (UTF-16 and Latin-1 text is refused naming the encoding,
    since pyarrow would read it as garbage names); a Parquet schema is read from
    the footer. Either may declare at most :data:`~ftcal.core.limits.MAX_TABLE_COLUMNS`
    columns. Returns ``()`` when the file is not readable as such (the full
    reader then names the problem).
    """
    if path.suffix.lower() == ".csv":
        names = _csv_header(path)
    else:
        try:
            import pyarrow.parquet as pq

            names = tuple(pq.read_schema(path).names)
        except Exception:  # noqa: BLE001 - a corrupt file: read_arrow names the problem
            return ()
    if len(names) > MAX_TABLE_COLUMNS:
        raise FtcalError(f"{path}: the header declares {len(names):,} columns, more than the limit of "
                         f"{MAX_TABLE_COLUMNS:,} for a calibration table.")
    return names


def _csv_header(path: Path) -> tuple[str, ...]:
    import csv

    with open(path, "rb") as fh:
        line = fh.readline(MAX_HEADER_BYTES + 1)
        while line.count(b'"') % 2 and len(line) <= MAX_HEADER_BYTES:  # a quoted name holds a line break
            more = fh.readline(MAX_HEADER_BYTES + 1 - len(line))
            if not more:
                break
            line += more
    if len(line) > MAX_HEADER_BYTES:
        raise FtcalError(f"{path}: the header line is longer than {MAX_HEADER_BYTES:,} bytes; "
                         "not a calibration table.")
    if line.startswith((b"\xff\xfe", b"\xfe\xff")) or b"\x00" in line:
        raise FtcalError(f"{path}: the file is UTF-16 encoded text; save it as UTF-8 (or plain ASCII) CSV.")
    try:
        text = line.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise FtcalError(f"{path}: the header is not UTF-8 (byte 0x{line[exc.start]:02X} at offset {exc.start}; "
                         "Latin-1 or Windows-1252 text?); save the file as UTF-8 CSV.") from None
    header = next(csv.reader(io.StringIO(text, newline="")), None)
    return tuple(header) if header else ()


def numeric_columns(frame, columns: Sequence[str], path: Path, role: str, *, finite: bool = True,
                    first_row: int = 0) -> np.ndarray:
    """The named columns as a float64 array, naming the first missing, non-numeric or (``finite``) non-finite cell.

    Booleans, dates and times are refused although they would convert to numbers. Rows are
    named counting from ``first_row`` (the file row of the frame's first row).
    """
    missing = [c for c in columns if c not in frame.columns]
    if missing:
        raise FtcalError(f"{path}: missing {role} column(s) {', '.join(map(repr, missing))}; "
                         f"the file has {', '.join(map(str, frame.columns))}.")
    out = np.empty((frame.shape[0], len(columns)))
    for j, name in enumerate(columns):
        column = frame[name]
        kind = column.dtype.kind
        if kind in "bMm" or (kind == "O" and column.map(_not_a_number).any()):
            first = column.iloc[int(np.argmax(column.map(_not_a_number)))] if kind == "O" else column.iloc[0]
            raise FtcalError(f"{path}: {role} column {name!r} holds {type(first).__name__} values such as "
                             f"{_cell_text(first)}, not numbers.")
        try:
            values = column.to_numpy(dtype=np.float64)
        except (TypeError, ValueError):
            import pandas as pd

            coerced = pd.to_numeric(column, errors="coerce")
            row = int(np.flatnonzero(coerced.isna() & column.notna())[0])
            where = f"line {first_row + row + 2}" if path.suffix.lower() == ".csv" else f"row {first_row + row}"
            raise FtcalError(f"{path}: column {name!r} {where} holds {_cell_text(column.iloc[row])}, "
                             "not a number.") from None
        bad = ~np.isfinite(values) if finite else np.zeros(0, dtype=bool)
        if bad.any():
            row = int(np.flatnonzero(bad)[0])
            where = f"line {first_row + row + 2}" if path.suffix.lower() == ".csv" else f"row {first_row + row}"
            raise ParameterError("drop_incomplete", f"{path}: column {name!r} has {int(bad.sum())} empty, NaN or "
                                 f"infinite cell(s), first at {where}. (The fit's {{drop_incomplete}} drops rows "
                                 "with empty cells.)")
        huge = np.abs(values) > MAX_CELL_MAGNITUDE if finite else bad
        if huge.any():
            row = int(np.flatnonzero(huge)[0])
            where = f"line {first_row + row + 2}" if path.suffix.lower() == ".csv" else f"row {first_row + row}"
            raise FtcalError(f"{path}: column {name!r} holds {values[row]:g} at {where}, beyond "
                             f"{MAX_CELL_MAGNITUDE:g} in magnitude: no sensor reads that, and its square overflows.")
        out[:, j] = values
    return out


def _cell_text(value) -> str:
    """A cell as the user wrote it: Python's repr of the plain value (``True``, ``[1.0]``, not numpy's ``np.True_``,
    ``array([1.])``), at most 60 characters."""
    if isinstance(value, np.generic):
        value = value.item()
    elif isinstance(value, np.ndarray):
        value = value.tolist()
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."


def _not_a_number(value) -> bool:
    """Cells a numeric column must not hold although they convert to float: booleans, dates, times."""
    import datetime

    return isinstance(value, (bool, np.bool_, datetime.date, datetime.time, datetime.timedelta))


def _labels(table, column: str | None, path: Path, role: str) -> np.ndarray | None:
    if column is None:
        return None
    column = table_label_column(table.column_names, column)
    if column not in table.column_names:
        raise FtcalError(f"{path}: no {role} column {column!r}; the file has "
                         f"{', '.join(map(str, table.column_names))}.")
    values = table.column(column)
    if values.null_count:
        raise FtcalError(f"{path}: {role} column {column!r} has empty cells.")
    return np.asarray(values.to_pylist(), dtype=object)


def _read_tables(paths: Sequence[str | os.PathLike], inputs: Sequence[str], outputs: Sequence[str] | None,
                 *, segment_by: str | None = None, group_by: str | None = None,
                 require_outputs: bool = True) -> Dataset:
    """Read tables into one :class:`Dataset` (:func:`load_dataset` with its columns chosen)."""
    if not paths:
        raise FtcalError("No data files given.")
    group_by = label_column(paths, group_by)
    parts = []
    for index, raw_path in enumerate(paths):
        path = Path(raw_path)
        table, breaks = complete_rows(read_arrow(path), [*inputs, *(outputs or ()),
                                                         *(c for c in (segment_by, group_by) if c)],
                                      path, with_breaks=True)
        u = arrow_numbers(table, inputs, path, "input")
        y = None
        if outputs:
            if require_outputs or all(c in table.column_names for c in outputs):
                y = arrow_numbers(table, outputs, path, "output")
        seg_labels = _labels(table, segment_by, path, "segment")
        grp_labels = _labels(table, group_by, path, "group")
        segments = _segment_ids(seg_labels, table.num_rows, breaks)
        groups = (np.full(table.num_rows, str(path), dtype=object) if grp_labels is None
                  else np.asarray(grp_labels, dtype=object))
        part = Dataset(u, y, tuple(inputs), tuple(outputs) if y is not None else (), segments, groups,
                       (str(path),))
        parts.append(part)
    if any(p.outputs is None for p in parts) and not all(p.outputs is None for p in parts):
        raise FtcalError("Some data files have the output columns and some do not.")
    return parts[0] if len(parts) == 1 else concatenate(parts)  # one file: already numbered from 0


def load_dataset(path: str | os.PathLike | Sequence[str | os.PathLike], *, inputs: Sequence[str] | None = None,
                 outputs: Sequence[str] | None = DEFAULT_OUTPUTS, segment_by: str | None = None,
                 group_by: str | None = None, require_outputs: bool = True) -> Dataset:
    """Read CSV or Parquet file(s) (docs/formats.md) into a :class:`Dataset`, as ``ftcal fit DATA`` does.

    Parameters
    ----------
    path : a file name, or a sequence of them (each one segment and group unless
        ``segment_by`` / ``group_by`` name a column)
    inputs : input columns; default ``u1..u6,T``, or ``u1..u6`` when the first file has no ``T``
    outputs : reference output columns (default ``Fx..Tz``); None for inputs only
    segment_by, group_by : columns whose values name segments and validation groups
    require_outputs : with False, tables without the output columns give a dataset without outputs
        (for prediction); ``outputs=None`` always does

    Returns
    -------
    Dataset

    Raises
    ------
    FtcalError
        A missing file or column, or a cell that is not a finite number.

    Examples
    --------
    >>> import pathlib, tempfile
    >>> import numpy as np, pandas as pd
    >>> from ftcal import CalibrationModel, load_dataset, load_model, save_model
    >>> folder = pathlib.Path(tempfile.mkdtemp())
    >>> u = np.linspace(0.0, 1.0, 20)
    >>> pd.DataFrame({"u1": u, "Fx": 2.0 * u + 1.0}).to_csv(folder / "table.csv", index=False)
    >>> data = load_dataset(folder / "table.csv", inputs=["u1"], outputs=["Fx"])
    >>> _ = save_model(CalibrationModel(1).fit(data), folder / "model.json")
    >>> round(float(load_model(folder / "model.json").predict(np.array([[0.5]]))[0, 0]), 9)
    2.0
    """
    paths = [path] if isinstance(path, (str, os.PathLike)) or not isinstance(path, Sequence) else list(path)
    if not paths:
        raise FtcalError("No data files given.")
    for item in paths:
        check_path(item, "path", "ftcal.load_dataset")
    return _read_tables(paths, inputs or default_inputs(paths), outputs, segment_by=segment_by, group_by=group_by,
                        require_outputs=require_outputs)


# The old name, one release (runtime.deprecation): its columns were positional.
read_dataset = deprecated_alias(_read_tables, "ftcal.data.tables.read_dataset", "ftcal.load_dataset")


def _segment_ids(labels: np.ndarray | None, n: int, breaks: np.ndarray | None = None) -> np.ndarray:
    """Segment id per row: a new segment wherever the label changes, and after rows dropped
    (``breaks``, from :func:`complete_rows`): ARX lags never bridge a gap."""
    change = np.zeros(n, dtype=bool) if labels is None else np.r_[True, labels[1:] != labels[:-1]]
    if breaks is not None:
        change |= breaks
    if n:
        change[0] = True
    return np.cumsum(change) - 1


def check_finite_output(frame, path: Path) -> None:
    """Refuse to write a table with an infinite or NaN number (naming the column and count)."""
    for name in frame.columns:
        values = frame[name].to_numpy()
        if values.dtype.kind == "f":
            bad = ~np.isfinite(values)
            if bad.any():
                raise FtcalError(f"{path}: column {name!r} would hold {int(bad.sum())} non-finite value(s) "
                                 f"(inf or NaN), first at row {int(np.flatnonzero(bad)[0])}; nothing written. "
                                 "Inputs far outside the training range can overflow a high-degree model.")


def parquet_write_options(schema) -> dict:
    """Keyword arguments for every Parquet file ftcal writes (``pyarrow.parquet.ParquetWriter``, ``write_table``).

    Page checksums on (ftcal's readers verify every page), and dictionary encoding for text columns only: on float
    columns, whose values rarely repeat, pyarrow's default tried it on every page and gave up, which cost 4.4x the
    write's CPU (0.76 against 0.17 CPU s for 360,000 rows of 29 columns) for a 25 % larger file.

    Parameters
    ----------
    schema : pyarrow.Schema
        The table's schema.

    Returns
    -------
    dict
        ``write_page_checksum`` and ``use_dictionary`` (the text columns' names).
    """
    import pyarrow as pa

    text = [f.name for f in schema if pa.types.is_string(f.type) or pa.types.is_large_string(f.type)
            or pa.types.is_dictionary(f.type)]
    return {"write_page_checksum": True, "use_dictionary": text}


def write_table(frame, path: str | os.PathLike) -> None:
    """Write a DataFrame as CSV or Parquet (by suffix), atomically."""
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in TABLE_SUFFIXES:
        raise FtcalError(f"{path}: output must end in .csv or .parquet.")
    check_finite_output(frame, path)
    with atomic_path(path) as tmp:
        if suffix == ".csv":
            frame.to_csv(tmp, index=False, float_format="%.17g")
        else:
            import pyarrow as pa

            frame.to_parquet(tmp, index=False, **parquet_write_options(pa.Schema.from_pandas(frame, preserve_index=False)))
