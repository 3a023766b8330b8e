"""Static holds: runs of samples where the sensor's orientation (its gravity vector) stays put."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..core.limits import HOLD_ANGLE_DEG, HOLD_MIN_SAMPLES
from ..runtime.errors import FtcalError

# A hold shorter than this fraction of the longest one is a slow stretch of motion.
LONGEST_FRACTION = 0.25


@dataclass(frozen=True)
class Holds:
    """Per-hold means of a recording.

    Attributes
    ----------
    wrench : ndarray of shape (n_holds, 6)
        Mean reading, N and N·m.
    gravity : ndarray of shape (n_holds, 3)
        Mean gravity vector in the declared sensor frame, m/s².
    rotation : ndarray of shape (n_holds, 3, 3) or None
        Sensor-to-world rotation at the hold (when the orientation is known, not just gravity).
    start, stop : ndarray of shape (n_holds,)
        Row range of each hold in the recording.
    noise : ndarray of shape (n_holds, 6)
        Standard error of each hold's mean reading (sample std / √n).
    """

    wrench: np.ndarray
    gravity: np.ndarray
    rotation: np.ndarray | None
    start: np.ndarray
    stop: np.ndarray
    noise: np.ndarray

    @property
    def n_holds(self) -> int:
        return self.wrench.shape[0]

    def map(self, wrench: np.ndarray | None = None, gravity: np.ndarray | None = None) -> "Holds":
        """The same holds with the wrench and/or gravity replaced (a tested correction)."""
        return Holds(self.wrench if wrench is None else wrench, self.gravity if gravity is None else gravity,
                     self.rotation, self.start, self.stop, self.noise)


def hold_ranges(gravity: np.ndarray, *, angle_deg: float = HOLD_ANGLE_DEG,
                min_samples: int = HOLD_MIN_SAMPLES) -> list[tuple[int, int]]:
    """Row ranges ``(start, stop)`` where the gravity direction stays within ``angle_deg`` of the first row's.

    Parameters
    ----------
    gravity : ndarray of shape (n_samples, 3)
    angle_deg : degrees
    min_samples : shorter runs are motion, not holds (and so are runs shorter than
        :data:`LONGEST_FRACTION` of the longest)

    Returns
    -------
    list of (start, stop), in order
    """
    unit = gravity / np.maximum(np.linalg.norm(gravity, axis=1, keepdims=True), 1e-300)
    cos_limit = np.cos(np.deg2rad(angle_deg))
    n = unit.shape[0]
    out = []
    start = 0
    while start < n:
        # Look ahead in doubling windows: short while moving, long while still.
        window, stop = 64, None
        while stop is None:
            end = min(n, start + window)
            leave = np.flatnonzero(unit[start:end] @ unit[start] < cos_limit)
            if leave.size:
                stop = start + int(leave[0])
            elif end == n:
                stop = n
            window *= 2
        if stop - start >= min_samples:
            out.append((start, stop))
        start = max(stop, start + 1)
    # Slow motion passes the angle test for a few samples; real holds are of one order of length.
    longest = max((b - a for a, b in out), default=0)
    return [(a, b) for a, b in out if b - a >= LONGEST_FRACTION * longest]


def find_holds(wrench: np.ndarray, gravity: np.ndarray, rotation: np.ndarray | None = None, *,
               labels: np.ndarray | None = None, angle_deg: float = HOLD_ANGLE_DEG,
               min_samples: int = HOLD_MIN_SAMPLES, source: str = "data") -> Holds:
    """Static holds of a recording and their mean readings.

    Parameters
    ----------
    wrench : ndarray of shape (n_samples, 6)
    gravity : ndarray of shape (n_samples, 3)
        In the declared sensor frame, m/s².
    rotation : ndarray of shape (n_samples, 3, 3) or None
        Sensor-to-world rotations when known.
    labels : ndarray of shape (n_samples,) or None
        Hold labels (e.g. a pose column): each run of one label is a hold, and the
        gravity-based detection still drops its moving samples.
    angle_deg, min_samples : see :func:`hold_ranges`
    source : name for error messages

    Returns
    -------
    Holds

    Raises
    ------
    FtcalError
        No static hold found.
    """
    ranges = []
    if labels is None:
        ranges = hold_ranges(gravity, angle_deg=angle_deg, min_samples=min_samples)
    else:
        edges = np.flatnonzero(np.r_[True, labels[1:] != labels[:-1], True])
        for a, b in zip(edges[:-1], edges[1:]):
            inner = hold_ranges(gravity[a:b], angle_deg=angle_deg, min_samples=min_samples)
            if inner:  # the longest still run of the labelled stretch
                s, e = max(inner, key=lambda r: r[1] - r[0])
                ranges.append((a + s, a + e))
    if not ranges:
        raise FtcalError(f"{source}: no static hold found (gravity direction still within {angle_deg:g}° for "
                         f"{min_samples} samples); record the tool at rest in a few orientations.")
    w = np.array([wrench[a:b].mean(axis=0) for a, b in ranges])
    g = np.array([gravity[a:b].mean(axis=0) for a, b in ranges])
    noise = np.array([wrench[a:b].std(axis=0) / np.sqrt(b - a) for a, b in ranges])
    rot = None
    if rotation is not None:
        rot = np.array([_mean_rotation(rotation[a:b]) for a, b in ranges])
    start, stop = (np.array(x, dtype=np.int64) for x in zip(*ranges))
    return Holds(w, g, rot, start, stop, noise)


def _mean_rotation(rotations: np.ndarray) -> np.ndarray:
    """The rotation nearest (Frobenius) to the mean of ``rotations`` of shape (n, 3, 3)."""
    u, _, vt = np.linalg.svd(rotations.mean(axis=0))
    d = np.sign(np.linalg.det(u @ vt))
    return u @ np.diag([1.0, 1.0, d]) @ vt


def concatenate_holds(parts: list[Holds]) -> Holds:
    """The holds of several recordings as one set (row ranges stay per file)."""
    if len(parts) == 1:
        return parts[0]
    rotation = None if any(p.rotation is None for p in parts) else np.concatenate([p.rotation for p in parts])
    return Holds(*(np.concatenate([getattr(p, k) for p in parts]) for k in ("wrench", "gravity")), rotation,
                 *(np.concatenate([getattr(p, k) for p in parts]) for k in ("start", "stop", "noise")))


def read_holds(paths, source, *, wrench=("u1", "u2", "u3", "u4", "u5", "u6"), group_by: str | None = None,
               reaction: bool = False) -> Holds:
    """Static holds of CSV/Parquet recordings.

    Parameters
    ----------
    paths : table files
    source : KinematicsSource giving gravity in the declared sensor frame; with quaternion
        columns (``OrientationSource``) the full rotations are kept too (base-frame test)
    wrench : six wrench columns
    group_by : column naming the holds (each label's longest still stretch is its hold)
    reaction : negate the readings (the user declares the reaction sign)

    Returns
    -------
    Holds
    """
    from pathlib import Path

    from ..data.tables import numeric_columns, read_table
    from ..payload.kinematics import MotionSource, OrientationSource

    if len(wrench) != 6:
        raise FtcalError(f"--wrench needs 6 columns Fx,Fy,Fz,Tx,Ty,Tz; got {','.join(wrench)}.")
    if isinstance(source, MotionSource):
        source = source.gravity  # holds are static: gravity is all that matters
    parts = []
    for path in paths:
        frame = read_table(path)
        measured = (-1.0 if reaction else 1.0) * numeric_columns(frame, wrench, Path(path), "wrench")
        gravity = source(frame, str(path)).gravity
        rotation = None
        if isinstance(source, OrientationSource):
            from scipy.spatial.transform import Rotation

            q = numeric_columns(frame, source.columns, Path(path), "orientation")
            rotation = Rotation.from_quat(q).as_matrix()  # x, y, z, w (ROS order)
        labels = None
        if group_by is not None:
            if group_by not in frame.columns:
                raise FtcalError(f"{path}: no hold column {group_by!r} (--group-by); the file has "
                                 f"{', '.join(map(str, frame.columns))}.")
            labels = frame[group_by].astype(str).to_numpy(dtype=object)
        parts.append(find_holds(measured, gravity, rotation, labels=labels, source=str(path)))
    return concatenate_holds(parts)
