"""Per-sample kinematics of the sensor frame, from table columns: the pluggable gravity source.

A *kinematics source* turns one table (a pandas DataFrame read from one data
file) into :class:`Kinematics`: the gravity vector in sensor axes for every
row and, for dynamic identification, angular velocity, angular acceleration
and proper acceleration. Sources shipped here:

* :class:`OrientationSource`: quaternion columns ``qx,qy,qz,qw`` (ROS order),
  the rotation from the sensor frame to a gravity-aligned world whose gravity
  is ``(0, 0, −g)``; a rotation from tf or an IMU orientation becomes such
  columns when the dataset is built;
* :class:`GravityColumnsSource`: the gravity vector in sensor axes, m/s²;
* :class:`MotionSource`: wraps either of them and adds ``wx,wy,wz`` (rad/s),
  accelerometer ``ax,ay,az`` (m/s², gravity included as an accelerometer
  reports it, i.e. ``+g`` upwards at rest) and angular acceleration, given as
  columns or differentiated from ω over a time column.

Any object with ``columns`` and ``__call__(frame, source)`` (the
:class:`KinematicsSource` protocol) works, e.g. one computing gravity from a
URDF and joint columns.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from ..runtime.errors import FtcalError, ParameterError

STANDARD_GRAVITY = 9.81  # m/s², the default of --g
QUATERNION_COLUMNS = ("qx", "qy", "qz", "qw")
GRAVITY_COLUMNS = ("gx", "gy", "gz")
ANGULAR_VELOCITY_COLUMNS = ("wx", "wy", "wz")
LINEAR_ACCELERATION_COLUMNS = ("ax", "ay", "az")
TIME_COLUMN = "time"
# |‖q‖ − 1| above this is a wrong column, not rounding (float32 logs stay near 1e-7).
QUATERNION_NORM_TOLERANCE = 1e-3
# Gravity columns whose norm differs from --g by more than this fraction are not m/s².
GRAVITY_NORM_TOLERANCE = 0.05


@dataclass(frozen=True)
class Kinematics:
    """Sensor-frame kinematics, one row per sample, all in sensor axes.

    Attributes
    ----------
    gravity : ndarray of shape (n_samples, 3)
        Gravity vector, m/s².
    angular_velocity, angular_acceleration : ndarray of shape (n_samples, 3) or None
        rad/s and rad/s²; None for static poses.
    proper_acceleration : ndarray of shape (n_samples, 3) or None
        ``a − g`` of the sensor origin (accelerometer reading), m/s²; None
        means no linear acceleration, i.e. ``−gravity``.
    """

    gravity: np.ndarray
    angular_velocity: np.ndarray | None = None
    angular_acceleration: np.ndarray | None = None
    proper_acceleration: np.ndarray | None = None

    @property
    def n_samples(self) -> int:
        return self.gravity.shape[0]

    @property
    def is_static(self) -> bool:
        return self.angular_velocity is None and self.angular_acceleration is None \
            and self.proper_acceleration is None

    def proper(self) -> np.ndarray:
        """Proper acceleration, ndarray of shape (n_samples, 3): ``−gravity`` unless measured."""
        return -self.gravity if self.proper_acceleration is None else self.proper_acceleration

    def rows(self, start: int, stop: int) -> "Kinematics":
        """The samples ``start:stop`` (views)."""
        return self.take(slice(start, stop))

    def take(self, index) -> "Kinematics":
        """The samples selected by ``index`` (a slice, integer or boolean array)."""
        def cut(a):
            return None if a is None else a[index]
        return Kinematics(self.gravity[index], cut(self.angular_velocity),
                          cut(self.angular_acceleration), cut(self.proper_acceleration))


class KinematicsSource(Protocol):
    """What ``ftcal payload`` / ``compensate`` need to know about the sensor's motion."""

    columns: tuple[str, ...]  # table columns the source reads

    def __call__(self, frame, source: str) -> Kinematics:
        """Kinematics of every row of ``frame`` (a DataFrame read from file ``source``)."""


def _columns(frame, names: Sequence[str], source: str, role: str) -> np.ndarray:
    from pathlib import Path

    from ..data.tables import numeric_columns

    return numeric_columns(frame, names, Path(source), role)


def gravity_from_quaternions(quaternions: np.ndarray, g: float = STANDARD_GRAVITY,
                             columns: Sequence[str] = QUATERNION_COLUMNS, source: str = "data") -> np.ndarray:
    """Gravity in sensor axes from sensor-to-world quaternions (ROS order x, y, z, w).

    Parameters
    ----------
    quaternions : ndarray of shape (n_samples, 4)
        Rotation from the sensor frame to a world frame whose gravity is (0, 0, −g).
    g : float
        Gravity magnitude, m/s².
    columns, source : names used in error messages.

    Returns
    -------
    ndarray of shape (n_samples, 3)
        ``Rᵀ (0, 0, −g)``, m/s².

    Raises
    ------
    FtcalError
        When a quaternion's norm differs from 1 by more than
        :data:`QUATERNION_NORM_TOLERANCE` (the message names the row).
    """
    q = np.asarray(quaternions, dtype=float).reshape(-1, 4)
    norm = np.sqrt(np.einsum("ij,ij->i", q, q))
    bad = np.abs(norm - 1.0) > QUATERNION_NORM_TOLERANCE
    if bad.any():
        row = int(np.flatnonzero(bad)[0])
        raise FtcalError(f"{source}: quaternion columns {','.join(columns)} are not unit length at row {row} "
                         f"(norm {norm[row]:.6g}; {int(bad.sum())} row(s) off by more than "
                         f"{QUATERNION_NORM_TOLERANCE:g}); give x,y,z,w in ROS order.")
    from ..data.holds import rotation_matrices  # the one quaternion -> rotation formula

    # Third row of R (sensor to world): the world z axis in sensor coordinates.
    return -g * rotation_matrices(q / norm[:, None])[:, 2, :]


@dataclass(frozen=True)
class OrientationSource:
    """Gravity from quaternion columns (sensor to gravity-aligned world, ROS x,y,z,w order)."""

    columns: tuple[str, ...] = QUATERNION_COLUMNS
    g: float = STANDARD_GRAVITY

    def __call__(self, frame, source: str) -> Kinematics:
        q = _columns(frame, self.columns, source, "orientation")
        return Kinematics(gravity_from_quaternions(q, self.g, self.columns, source))


@dataclass(frozen=True)
class GravityColumnsSource:
    """Gravity vector columns in sensor axes (m/s²); their norm must be close to ``g``."""

    columns: tuple[str, ...] = GRAVITY_COLUMNS
    g: float = STANDARD_GRAVITY

    def __call__(self, frame, source: str) -> Kinematics:
        gravity = _columns(frame, self.columns, source, "gravity")
        norm = np.linalg.norm(gravity, axis=1)
        bad = np.abs(norm - self.g) > GRAVITY_NORM_TOLERANCE * self.g
        if bad.any():
            row = int(np.flatnonzero(bad)[0])
            raise FtcalError(f"{source}: gravity columns {','.join(self.columns)} have norm {norm[row]:.6g} at "
                             f"row {row}, not the gravity magnitude {self.g:g} m/s² (--g); give m/s².")
        return Kinematics(gravity)


def angular_acceleration_from(omega: np.ndarray, time: np.ndarray, segments: np.ndarray | None = None,
                              source: str = "data", time_column: str = TIME_COLUMN) -> np.ndarray:
    """dω/dt by central differences (one-sided at the ends), within each segment.

    Parameters
    ----------
    omega : ndarray of shape (n_samples, 3), rad/s
    time : ndarray of shape (n_samples,), s, strictly increasing within a segment
    segments : ndarray of shape (n_samples,) or None
        Runs of equal values are differentiated separately.

    Returns
    -------
    ndarray of shape (n_samples, 3), rad/s²
    """
    out = np.empty_like(omega)
    labels = np.zeros(len(time)) if segments is None else segments
    edges = np.flatnonzero(np.r_[True, labels[1:] != labels[:-1], True])
    for start, stop in zip(edges[:-1], edges[1:]):
        t = time[start:stop]
        if stop - start < 2:
            raise FtcalError(f"{source}: cannot differentiate angular velocity over a single sample "
                             f"(row {start}); give angular acceleration columns.")
        if np.any(np.diff(t) <= 0):
            row = start + int(np.flatnonzero(np.diff(t) <= 0)[0]) + 1
            raise FtcalError(f"{source}: column {time_column!r} does not increase at row {row}; "
                             "cannot differentiate angular velocity.")
        out[start:stop] = np.gradient(omega[start:stop], t, axis=0)
    return out


@dataclass(frozen=True)
class MotionSource:
    """A gravity source plus gyroscope, accelerometer and angular acceleration (dynamic payloads).

    ``linear_acceleration`` columns are the accelerometer at the sensor origin
    in sensor axes (proper acceleration); when the table lacks them the
    origin is taken as not accelerating (``−gravity``). Angular acceleration
    comes from ``angular_acceleration`` columns, or else from differentiating
    ω over ``time``.
    """

    gravity: KinematicsSource
    angular_velocity: tuple[str, ...] = ANGULAR_VELOCITY_COLUMNS
    linear_acceleration: tuple[str, ...] = LINEAR_ACCELERATION_COLUMNS
    angular_acceleration: tuple[str, ...] | None = None
    time: str = TIME_COLUMN

    @property
    def columns(self) -> tuple[str, ...]:
        return tuple(self.gravity.columns) + self.angular_velocity

    def __call__(self, frame, source: str) -> Kinematics:
        base = self.gravity(frame, source)
        omega = _columns(frame, self.angular_velocity, source, "angular velocity")
        if self.angular_acceleration is not None:
            alpha = _columns(frame, self.angular_acceleration, source, "angular acceleration")
        else:
            if self.time not in frame.columns:
                raise ParameterError(('time', 'angular_acceleration'), f"{source}: no {self.time!r} column to differentiate angular velocity; "
                                 "give {time} COL or {angular_acceleration} COLS.")
            t = _columns(frame, (self.time,), source, "time")[:, 0]
            alpha = angular_acceleration_from(omega, t, source=source, time_column=self.time)
        proper = None
        if all(c in frame.columns for c in self.linear_acceleration):
            proper = _columns(frame, self.linear_acceleration, source, "linear acceleration")
        return Kinematics(base.gravity, omega, alpha, proper)
