"""Recordings as CSV or Parquet tables: one row per sample, one clock.

Column convention (names are case-sensitive):

=====================  ==================================================
``time``               seconds (required)
``<sensor>_u1..u6``    the six raw channels of F/T sensor ``<sensor>``
``<sensor>_T``         its temperature
``<joint>``            joint position, radians, URDF joint name
``<joint>.vel``        joint velocity, rad/s (optional, all or none)
``<joint>.acc``        joint acceleration, rad/s² (optional, all or none)
=====================  ==================================================

Every other column is taken as a joint position.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from ..runtime.errors import FtcalError
from .recording import Recording, Stream
from .tables import numeric_columns, read_table

FT_COLUMN = re.compile(r"^(?P<sensor>.+)_u(?P<ch>[1-6])$")
TEMP_COLUMN = re.compile(r"^(?P<sensor>.+)_T$")


def read_table_recording(path: Path) -> Recording:
    """Read a CSV/Parquet recording following the column convention above."""
    frame = read_table(path)
    if "time" not in frame.columns:
        raise FtcalError(f"Recording {path}: no 'time' column (seconds).")
    # Every column is a number per sample; NaN cells are left to the stream checks, which name the stream.
    values = numeric_columns(frame, list(frame.columns), path, "recording", finite=False)
    frame = type(frame)(values, columns=frame.columns)
    time = frame["time"].to_numpy(np.float64)
    ft_cols: dict[str, dict[int, str]] = {}
    temp_cols: dict[str, str] = {}
    joints, vel, acc = [], {}, {}
    for col in frame.columns:
        if col == "time":
            continue
        if (m := FT_COLUMN.match(col)):
            ft_cols.setdefault(m["sensor"], {})[int(m["ch"])] = col
        elif (m := TEMP_COLUMN.match(col)):
            temp_cols[m["sensor"]] = col
        elif col.endswith(".vel"):
            vel[col[:-4]] = col
        elif col.endswith(".acc"):
            acc[col[:-4]] = col
        else:
            joints.append(col)
    ft = {}
    for sensor, chans in ft_cols.items():
        if sorted(chans) != list(range(1, 7)):
            missing = [f"{sensor}_u{i}" for i in range(1, 7) if i not in chans]
            raise FtcalError(f"Recording {path}: F/T sensor {sensor!r} lacks column(s) {', '.join(missing)}.")
        cols = [chans[i] for i in range(1, 7)]
        ft[sensor] = Stream(f"{path.name}:{sensor}", time, frame[cols].to_numpy(np.float64),
                            tuple(f"u{i}" for i in range(1, 7)))
    if not ft:
        raise FtcalError(f"Recording {path}: no F/T columns (<sensor>_u1 … <sensor>_u6).")
    temps = {s: Stream(f"{path.name}:{c}", time, frame[[c]].to_numpy(np.float64), ("T",))
             for s, c in temp_cols.items()}
    names = tuple(joints)
    positions = Stream(f"{path.name}:joints", time, frame[list(names)].to_numpy(np.float64), names) if names else None
    return Recording(path, ft, temps, positions, _derivative(path, frame, time, names, vel, "vel"),
                     _derivative(path, frame, time, names, acc, "acc"))


def _derivative(path: Path, frame, time: np.ndarray, joints: tuple[str, ...],
                cols: dict[str, str], kind: str) -> Stream | None:
    if not cols:
        return None
    if set(cols) != set(joints):
        odd = sorted(set(cols) ^ set(joints))
        raise FtcalError(f"Recording {path}: '.{kind}' columns must cover exactly the joint columns; "
                         f"mismatch for {', '.join(odd[:5])}.")
    return Stream(f"{path.name}:{kind}", time, frame[[cols[j] for j in joints]].to_numpy(np.float64), joints)
