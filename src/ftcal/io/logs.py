"""Robot recordings: raw F/T channels, temperatures and joint data, each on its own clock.

:func:`read_recording` opens

* YARP robot-logger ``.mat`` files, v7.3 (HDF5) and v5 (docs/formats.md §4), see
  :mod:`ftcal.io.logs_mat`;
* CSV/Parquet tables, one row per sample, see :mod:`ftcal.io.logs_table` for
  the column convention.

A :class:`Recording` keeps every stream with its own timestamps;
:func:`ftcal.io.logs_sync.align` puts the streams one sensor needs on one
clock, and :mod:`ftcal.io.logs_quality` checks and smooths them.

Units: time in seconds, joint positions in radians (``joint_units="deg"``
converts degrees), velocities rad/s, accelerations rad/s², F/T channels as
logged, temperature as logged (°C on the iCub).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import FtcalError


@dataclass(frozen=True)
class Stream:
    """One logged signal with its own clock.

    time : ndarray of shape (n_samples,), seconds
    data : ndarray of shape (n_samples, n_columns)
    columns : one name per column
    name : where it came from, for messages (e.g. ``FTs/r_arm_ft``)
    """

    name: str
    time: np.ndarray
    data: np.ndarray
    columns: tuple[str, ...]

    def __post_init__(self) -> None:
        if self.data.ndim != 2 or self.data.shape[1] != len(self.columns):
            raise FtcalError(f"{self.name}: data has shape {self.data.shape}; expected "
                             f"(n_samples, {len(self.columns)}).")
        if self.time.shape != (self.data.shape[0],):
            raise FtcalError(f"{self.name}: {self.time.shape[0] if self.time.ndim else 0} timestamps "
                             f"but {self.data.shape[0]} samples (mismatched lengths).")

    @property
    def n_samples(self) -> int:
        return int(self.time.shape[0])


@dataclass(frozen=True)
class Recording:
    """All streams of one recording file.

    ft, temperature : sensor name as in the file → stream (6 columns / 1 column)
    joints : joint positions (columns = joint names), or None
    joint_velocities, joint_accelerations : same columns as ``joints``, or None
    accelerometers, gyros : IMU name → stream with 3 columns
    """

    path: Path
    ft: dict[str, Stream]
    temperature: dict[str, Stream] = field(default_factory=dict)
    joints: Stream | None = None
    joint_velocities: Stream | None = None
    joint_accelerations: Stream | None = None
    accelerometers: dict[str, Stream] = field(default_factory=dict)
    gyros: dict[str, Stream] = field(default_factory=dict)

    def ft_stream(self, *aliases: str) -> Stream:
        """The F/T stream logged under any of ``aliases`` (``r_arm_ft`` / ``r_arm_ft_sensor``)."""
        return _pick(self.ft, aliases, f"{self.path}: no F/T stream for sensor", "FTs")

    def temperature_stream(self, *aliases: str) -> Stream:
        return _pick(self.temperature, aliases, f"{self.path}: no temperature stream for sensor", "temperatures")

    def joint_stream(self) -> Stream:
        if self.joints is None:
            raise FtcalError(f"{self.path}: no joint positions (joints_state.positions) in the recording.")
        return self.joints


def sensor_aliases(*names: str) -> tuple[str, ...]:
    """Both naming styles of each name: with and without the ``_sensor`` suffix."""
    out: list[str] = []
    for name in names:
        stem = name.removesuffix("_sensor")
        for alias in (name, stem, stem + "_sensor"):
            if alias not in out:
                out.append(alias)
    return tuple(out)


def _pick(streams: dict[str, Stream], aliases: tuple[str, ...], message: str, group: str) -> Stream:
    wanted = sensor_aliases(*aliases)
    found = [streams[a] for a in wanted if a in streams]
    if not found:
        have = ", ".join(sorted(streams)) or "none"
        raise FtcalError(f"{message} {aliases[0]!r} ({group} has: {have}).")
    return found[0]


def read_recording(path: str | Path, joint_units: str = "rad") -> Recording:
    """Read a ``.mat`` (v5 or v7.3), ``.csv`` or ``.parquet`` recording."""
    path = Path(path)
    if not path.is_file():
        raise FtcalError(f"Recording {path}: no such file.")
    suffix = path.suffix.lower()
    if suffix == ".mat":
        from .logs_mat import read_mat
        recording = read_mat(path)
    elif suffix in (".csv", ".parquet", ".pq"):
        from .logs_table import read_table_recording
        recording = read_table_recording(path)
    else:
        raise FtcalError(f"Recording {path}: unknown format {suffix!r}; use .mat, .csv or .parquet.")
    if joint_units == "deg":
        return _joints_in_radians(recording)
    if joint_units != "rad":
        raise FtcalError(f"The 'joint_units' parameter must be 'rad' or 'deg'. Got {joint_units!r} instead.")
    return recording


def _joints_in_radians(rec: Recording) -> Recording:
    def conv(s: Stream | None) -> Stream | None:
        return None if s is None else Stream(s.name, s.time, np.deg2rad(s.data), s.columns)

    return Recording(rec.path, rec.ft, rec.temperature, conv(rec.joints), conv(rec.joint_velocities),
                     conv(rec.joint_accelerations), rec.accelerometers, rec.gyros)
