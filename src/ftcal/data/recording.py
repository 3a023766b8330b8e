"""What every log reader returns: streams, each on its own clock, grouped as a recording.

A :class:`Recording` keeps every stream with its own timestamps;
:func:`ftcal.data.alignment.align` puts the streams one sensor needs on one clock,
and :mod:`ftcal.data.signals` checks and smooths them.

Units: time in seconds, joint positions in radians, velocities rad/s,
accelerations rad/s², F/T channels as logged, temperature in °C.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..runtime.errors import FtcalError


@dataclass(frozen=True)
class Stream:
    """One logged signal with its own clock.

    time : ndarray of shape (n_samples,), seconds
    data : ndarray of shape (n_samples, n_columns)
    columns : one name per column
    name : where it came from, for messages (e.g. ``FTs/r_arm_ft``)
    clock : what the timestamps are, when the format says (e.g. ``"header stamps"`` or
        ``"receive time"`` for ROS bags), else None
    frame : the frame the data is expressed in, when the format says (``header.frame_id``), else None
    """

    name: str
    time: np.ndarray
    data: np.ndarray
    columns: tuple[str, ...]
    clock: str | None = None
    frame: str | None = None

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
    orientations : source name → stream ``qx, qy, qz, qw`` (sensor or IMU frame to a
        gravity-aligned world), e.g. from an IMU or a tf chain
    """

    path: Path
    ft: dict[str, Stream]
    temperature: dict[str, Stream] = field(default_factory=dict)
    joints: Stream | None = None
    joint_velocities: Stream | None = None
    joint_accelerations: Stream | None = None
    accelerometers: dict[str, Stream] = field(default_factory=dict)
    gyros: dict[str, Stream] = field(default_factory=dict)
    orientations: dict[str, Stream] = field(default_factory=dict)

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
