"""Payload identification and compensation over CSV/Parquet tables (what the CLI commands call)."""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from ..runtime.errors import FtcalError
from .accumulate import AxisStatistics, payload_statistics
from .compensate import contact_wrench
from .kinematics import KinematicsSource
from .parameters import PayloadParameters

WRENCH_COLUMNS = ("u1", "u2", "u3", "u4", "u5", "u6")  # what the sensor reads, in ftcal datasets
CONTACT_COLUMNS = ("Fx", "Fy", "Fz", "Tx", "Ty", "Tz")


def _check_wrench_columns(columns: Sequence[str]) -> tuple[str, ...]:
    if len(columns) != 6:
        raise FtcalError(f"--wrench needs 6 columns Fx,Fy,Fz,Tx,Ty,Tz; got {','.join(columns)}.")
    return tuple(columns)


def table_statistics(paths: Sequence[str | os.PathLike], source: KinematicsSource, *,
                     wrench: Sequence[str] = WRENCH_COLUMNS, group_by: str | None = None,
                     reaction: bool = False, dynamic: bool = False) -> dict[str, AxisStatistics]:
    """Payload statistics of tables, one entry per validation group.

    Parameters
    ----------
    paths : CSV or Parquet files, one row per sample
    source : KinematicsSource
        Gives each table's sensor-frame kinematics.
    wrench : six column names of the measured wrench (N, N·m)
    group_by : column naming the groups; None: one group per file
    reaction : negate the readings (sensor reporting the opposite sign)
    dynamic : the 16-parameter model (inertia) instead of the static 10

    Returns
    -------
    dict of group label to AxisStatistics, in order of first appearance

    Raises
    ------
    FtcalError
        Missing, non-numeric or non-finite columns, bad kinematics (naming file, column, row).
    """
    from ..data.tables import numeric_columns, read_table

    if not paths:
        raise FtcalError("No data files given.")
    wrench = _check_wrench_columns(wrench)
    sign = -1.0 if reaction else 1.0
    groups: dict[str, AxisStatistics] = {}
    for path in paths:
        frame = read_table(path)
        measured = sign * numeric_columns(frame, wrench, Path(path), "wrench")
        kinematics = source(frame, str(path))
        if group_by is None:
            labels = np.full(len(frame), str(path), dtype=object)
        elif group_by not in frame.columns:
            raise FtcalError(f"{path}: no group column {group_by!r}; the file has "
                             f"{', '.join(map(str, frame.columns))}.")
        else:
            labels = frame[group_by].astype(str).to_numpy()
        for label in dict.fromkeys(labels):
            rows = np.flatnonzero(labels == label)
            if len(rows) == len(labels):
                stats = payload_statistics(measured, kinematics, dynamic=dynamic)
            else:
                stats = payload_statistics(measured[rows], kinematics.take(rows), dynamic=dynamic)
            groups[label] = stats if label not in groups else groups[label] + stats
    return groups


def compensate_table(path: str | os.PathLike, payload: PayloadParameters, source: KinematicsSource, *,
                     wrench: Sequence[str] | None = None, model=None, warn_out_of_range: bool = True):
    """One table with its contact wrench as ``Fx..Tz`` (replacing such columns), other columns kept.

    Parameters
    ----------
    path : CSV or Parquet file
    payload : PayloadParameters
    source : KinematicsSource
    wrench : six measured-wrench columns; default the ones the payload was identified from
    model : CalibrationModel or None
        When given, the measured wrench is its prediction from its input columns.
    warn_out_of_range : bool
        Let the model warn about inputs outside its training range (off when the caller
        warns once for several tables).

    Returns
    -------
    pandas.DataFrame
    """
    from ..data.tables import numeric_columns, read_table

    frame = read_table(path)
    if model is not None:
        if len(model.output_names_) != 6:
            raise FtcalError(f"the calibration model has {len(model.output_names_)} outputs; a wrench needs 6.")
        measured = model.predict(numeric_columns(frame, model.input_names_, Path(path), "input"),
                                 warn_out_of_range=warn_out_of_range)
    else:
        columns = _check_wrench_columns(wrench or payload.fit.get("wrench_columns", WRENCH_COLUMNS))
        measured = numeric_columns(frame, columns, Path(path), "wrench")
    contact = contact_wrench(measured, payload, source(frame, str(path)))
    out = frame.copy()
    for j, name in enumerate(CONTACT_COLUMNS):
        out[name] = contact[:, j]
    return out
