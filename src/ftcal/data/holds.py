"""Static holds: which samples of a recording were taken while the robot stood still.

A payload identification with the static model (and an installation check)
must use only samples where the sensor does not move: during a move the tool's
inertial wrench reads as error and, with moves between holds taking most of a
recording, pushes the estimates far from the truth. :func:`find_holds` marks
each sample static or moving and numbers the static holds (0, 1, ... in time
order; -1 while moving), from the best signal available:

* ``orientation`` (unit quaternions, any order of the four components as long
  as it is the same in every row): the rotation angle between samples;
* ``gravity`` (gravity vector in sensor axes): its change of direction;
* ``joints`` (joint positions, rad): the fastest joint;
* else ``wrench``: the wrench's own variation, a rolling standard deviation per
  channel against the noise floor estimated from the data (the quietest tenth
  of the recording), so that no noise level needs to be given.

A kinematic rate is the angle (or joint travel) over half a window
(:data:`HOLD_WINDOW_S`) before and after each sample, over that time, which
averages encoder noise out; a sample is still when it does not move on at
least one side (above :data:`MIN_ANGULAR_RATE`), so an instant jump between two
still poses (a table of poses) leaves both poses whole and starts a new hold.
Still stretches shorter than :data:`MIN_HOLD_S` (a pause inside a move) count
as moving, unless the whole recording (segment) is still.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..runtime.errors import FtcalError

# Rolling window of the motion signal, s: long enough to average noise, short beside a hold.
HOLD_WINDOW_S = 0.1
# Still stretches shorter than this are pauses inside a move, not holds.
MIN_HOLD_S = 0.2
# Angular rate (rad/s) and joint rate (rad/s) below which a kinematic signal is still.
MIN_ANGULAR_RATE = 0.01
# Moving: the signal exceeds this many times its noise floor.
NOISE_FACTOR = 4.0
# The noise floor is this quantile of the rolling signal (assumes at least this share of still samples).
FLOOR_QUANTILE = 0.1
MAX_STRETCHES_SHOWN = 3


@dataclass(frozen=True)
class Holds:
    """Static samples and hold numbers of one recording.

    Attributes
    ----------
    static : ndarray of bool, shape (n_samples,)
    hold : ndarray of int, shape (n_samples,), 0, 1, ... per hold in time order, -1 while moving
    signal : str, what motion was read from: orientation, gravity, joints or wrench
    """

    static: np.ndarray
    hold: np.ndarray
    signal: str

    @property
    def n_samples(self) -> int:
        return int(self.static.size)

    @property
    def n_moving(self) -> int:
        return int(self.n_samples - np.count_nonzero(self.static))

    @property
    def n_holds(self) -> int:
        return int(self.hold.max()) + 1 if self.hold.size else 0

    def moving_stretches(self) -> list[tuple[int, int]]:
        """(first row, last row + 1) of each run of moving samples."""
        edges = np.flatnonzero(np.diff(np.r_[0, (~self.static).astype(np.int8), 0]))
        return list(zip(edges[::2].tolist(), edges[1::2].tolist()))

    def describe(self, time: np.ndarray | None = None) -> str:
        """One line: how many samples move and where (rows, and seconds from the first sample)."""
        stretches = self.moving_stretches()
        if not stretches:
            return f"no moving samples ({self.n_holds} hold(s), from the {self.signal})"
        shown = []
        for a, b in stretches[:MAX_STRETCHES_SHOWN]:
            where = f"rows {a}-{b - 1}"
            if time is not None:
                where += f" ({time[a] - time[0]:.2f}-{time[b - 1] - time[0]:.2f} s)"
            shown.append(where)
        more = "" if len(stretches) <= MAX_STRETCHES_SHOWN else f", ... {len(stretches) - MAX_STRETCHES_SHOWN} more"
        return (f"{self.n_moving} of {self.n_samples} samples moving (from the {self.signal}) in "
                f"{len(stretches)} stretch(es): {', '.join(shown)}{more}; {self.n_holds} hold(s)")


def find_holds(time: np.ndarray, *, orientation: np.ndarray | None = None, gravity: np.ndarray | None = None,
               joints: np.ndarray | None = None, wrench: np.ndarray | None = None,
               segments: np.ndarray | None = None, where: str = "data", time_column: str = "time") -> Holds:
    """Mark the static samples of a recording and number its holds.

    Parameters
    ----------
    time : ndarray of shape (n_samples,), s, increasing within each segment
    orientation : ndarray of shape (n_samples, 4) or None
        Unit quaternions of the sensor (or of any link rigidly attached to it).
    gravity : ndarray of shape (n_samples, 3) or None
        Gravity in sensor axes (any unit: only its direction is used).
    joints : ndarray of shape (n_samples, n_joints) or None
        Joint positions, rad.
    wrench : ndarray of shape (n_samples, 6) or None
        The measured wrench; used only when no kinematic signal is given.
    segments : ndarray of shape (n_samples,) or None
        Recording labels: holds never span two recordings.
    where, time_column : names for error messages.

    Returns
    -------
    Holds

    Raises
    ------
    FtcalError
        No signal given, or time not increasing inside a segment (names the row).
    """
    time = np.asarray(time, dtype=np.float64).ravel()
    n = time.size
    labels = np.zeros(n, dtype=np.int8) if segments is None else np.asarray(segments)
    bounds = np.flatnonzero(np.r_[True, labels[1:] != labels[:-1], True]) if n else np.array([0])
    for a, b in zip(bounds[:-1], bounds[1:]):
        bad = np.flatnonzero(np.diff(time[a:b]) <= 0)
        if bad.size:
            raise FtcalError(f"{where}: column {time_column!r} does not increase at row {a + bad[0] + 1}; "
                             "sort the table by time (or, for a ROS bag, rebuild it with --receive-time).")
    jumps = np.zeros(n, dtype=bool)
    if orientation is not None:
        q = np.asarray(orientation, dtype=np.float64)
        q = q / np.linalg.norm(q, axis=1, keepdims=True)
        signal, (still, jumps) = "orientation", _kinematic_still(time, lambda i, j: _rotation_angle(q[i], q[j]),
                                                                 bounds)
    elif gravity is not None:
        g = np.asarray(gravity, dtype=np.float64)
        signal, (still, jumps) = "gravity direction", _kinematic_still(
            time, lambda i, j: _direction_angle(g[i], g[j]), bounds)
    elif joints is not None:
        qj = np.asarray(joints, dtype=np.float64)
        signal, (still, jumps) = "joints", _kinematic_still(
            time, lambda i, j: np.abs(qj[j] - qj[i]).max(axis=1, initial=0.0), bounds)
    elif wrench is not None:
        signal, still = "wrench variation", _wrench_still(time, np.asarray(wrench, dtype=np.float64), bounds)
    else:
        raise FtcalError(f"{where}: no orientation, gravity, joint or wrench columns to find the static holds from.")
    hold = np.full(n, -1, dtype=np.int64)
    step = np.median(np.diff(time)) if n > 1 else 1.0
    count = 0
    for a, b in zip(bounds[:-1], bounds[1:]):
        # A jump between two still samples (a table of poses) starts a new hold.
        runs = np.flatnonzero(np.diff(np.r_[0, still[a:b].astype(np.int8), 0]))
        runs = _split(runs, np.flatnonzero(jumps[a:b]))
        for start, stop in zip(runs[::2], runs[1::2]):
            # Duration of the stretch, counting each sample as one time step; a recording that never
            # moves is one hold however short (a file per pose).
            whole = start == 0 and stop == b - a
            if whole or time[a + stop - 1] - time[a + start] + step >= MIN_HOLD_S:
                hold[a + start:a + stop] = count
                count += 1
    return Holds(hold >= 0, hold, signal)


def _rotation_angle(p: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Rotation angle between unit quaternions, row by row, rad."""
    return 2.0 * np.arccos(np.minimum(np.abs(np.einsum("ij,ij->i", p, q)), 1.0))


def _direction_angle(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Angle between vectors, row by row, rad (atan2: exact at small angles)."""
    return np.arctan2(np.linalg.norm(np.cross(u, v), axis=1), np.einsum("ij,ij->i", u, v))


def _window(time: np.ndarray) -> int:
    """Samples in :data:`HOLD_WINDOW_S` at the recording's median rate, odd, at least 1."""
    if time.size < 2:
        return 1
    samples = int(round(HOLD_WINDOW_S / max(float(np.median(np.diff(time))), 1e-12)))
    return max(1, samples | 1)


def _split(runs: np.ndarray, cuts: np.ndarray) -> np.ndarray:
    """Run edges [start0, stop0, start1, stop1, ...] cut again at every index of ``cuts`` inside a run."""
    if cuts.size == 0:
        return runs
    edges = np.union1d(runs, cuts)
    starts, stops = runs[::2], runs[1::2]
    # Keep the pieces [edge, next edge) that lie inside a run.
    left = edges[:-1]
    inside = np.searchsorted(stops, left, side="right") == np.searchsorted(starts, left, side="right") - 1
    pieces = np.column_stack([left[inside], edges[1:][inside]])
    return pieces.ravel()


def _kinematic_still(time: np.ndarray, travel, bounds: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Still samples, and samples reached by a jump, from ``travel(i, j)``: the angle or joint travel
    between samples i and j (arrays of indices)."""
    n = time.size
    still = np.ones(n, dtype=bool)
    jumps = np.zeros(n, dtype=bool)
    for a, b in zip(bounds[:-1], bounds[1:]):
        if b - a < 2:
            continue
        t = time[a:b]
        h = min(max((_window(t) - 1) // 2, 1), b - a - 1)
        index = np.arange(a, b)
        back, ahead = np.maximum(index - h, a), np.minimum(index + h, b - 1)
        # Rates over h samples on either side: noise averages out, and a sample still on one side is still.
        before = travel(back, index) / np.maximum(time[index] - time[back], 1e-300)
        after = travel(index, ahead) / np.maximum(time[ahead] - time[index], 1e-300)
        before[0], after[-1] = after[0], before[-1]
        still[a:b] = np.minimum(before, after) <= MIN_ANGULAR_RATE
        # A single step that travels farther than a whole window may: a jump between two poses.
        jumps[a + 1:b] = travel(index[:-1], index[1:]) > MIN_ANGULAR_RATE * (t[h] - t[0])
    return still, jumps


def _wrench_still(time: np.ndarray, wrench: np.ndarray, bounds: np.ndarray) -> np.ndarray:
    """Still samples: every channel's rolling standard deviation within NOISE_FACTOR of its floor."""
    n = time.size
    spread = np.zeros_like(wrench)
    for a, b in zip(bounds[:-1], bounds[1:]):
        spread[a:b] = _rolling_std(wrench[a:b], _window(time[a:b]))
    if n == 0:
        return np.zeros(0, dtype=bool)
    floor = np.quantile(spread, FLOOR_QUANTILE, axis=0)
    # A channel that never changes in its quietest tenth (quantized, or exact data): any change is motion.
    scale = np.maximum(np.abs(wrench).max(axis=0), 1.0)
    floor = np.maximum(floor, 1e-9 * scale)
    return np.all(spread <= NOISE_FACTOR * floor, axis=1)


def _rolling_std(x: np.ndarray, window: int) -> np.ndarray:
    """Centred rolling standard deviation of each column (shrinking at the ends), from cumulative sums."""
    n = x.shape[0]
    if n == 0:
        return x.copy()
    half = window // 2
    centre = x - x.mean(axis=0)  # cumulative sums of centred values lose fewer digits
    first = np.vstack([np.zeros((1, x.shape[1])), np.cumsum(centre, axis=0)])
    second = np.vstack([np.zeros((1, x.shape[1])), np.cumsum(centre ** 2, axis=0)])
    lo = np.clip(np.arange(n) - half, 0, n)
    hi = np.clip(np.arange(n) + half + 1, 0, n)
    count = (hi - lo)[:, None]
    mean = (first[hi] - first[lo]) / count
    var = (second[hi] - second[lo]) / count - mean ** 2
    return np.sqrt(np.maximum(var, 0.0))
