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

:func:`number_across` numbers the holds of several recordings one after the
other (``ftcal dataset``'s ``hold`` column, for bags and robot logs alike);
:func:`hold_averages` gives each hold's mean reading and gravity (``ftcal
check`` works on these), and :meth:`Holds.longest_per_segment` keeps one hold per
labelled stretch (a pose column).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ..runtime.errors import FtcalError, ParameterError

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
# rad (or rad of joint travel): two rows of a table of poses closer than this are the same pose
# (the still threshold over one rolling window, MIN_ANGULAR_RATE * HOLD_WINDOW_S).
SAME_POSE = MIN_ANGULAR_RATE * HOLD_WINDOW_S


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
    per_pose: bool = False  # rows far apart, no samples between them: each pose's row(s) taken as a hold

    @property
    def n_samples(self) -> int:
        return int(self.static.size)

    @property
    def n_moving(self) -> int:
        return int(self.n_samples - np.count_nonzero(self.static))

    @property
    def n_holds(self) -> int:
        return int(self.hold.max()) + 1 if self.hold.size else 0

    def ranges(self) -> tuple[np.ndarray, np.ndarray]:
        """(first row, last row + 1) of each hold, in hold order (a hold is one run of rows)."""
        edges = np.flatnonzero(np.diff(np.r_[-1, self.hold, -1]))
        starts, stops = edges[:-1], edges[1:]
        held = self.hold[starts] >= 0
        return starts[held], stops[held]

    def longest_per_segment(self, segments: np.ndarray) -> "Holds":
        """Only the longest hold of each run of one segment label (one hold per labelled pose), renumbered.

        Parameters
        ----------
        segments : ndarray of shape (n_samples,), the labels the holds were found within

        Returns
        -------
        Holds
        """
        labels = np.asarray(segments)
        run = np.r_[0, np.cumsum(labels[1:] != labels[:-1])] if labels.size else labels
        starts, stops = self.ranges()
        best: dict[int, tuple[int, int]] = {}  # label run -> its longest hold (the first of equal ones)
        for a, b in zip(starts.tolist(), stops.tolist()):
            r = int(run[a])
            if r not in best or b - a > best[r][1] - best[r][0]:
                best[r] = (a, b)
        hold = np.full(self.n_samples, -1, dtype=np.int64)
        for count, (a, b) in enumerate(best.values()):  # runs appear in time order
            hold[a:b] = count
        return Holds(hold >= 0, hold, self.signal, self.per_pose)

    def moving_stretches(self) -> list[tuple[int, int]]:
        """(first row, last row + 1) of each run of moving samples."""
        edges = np.flatnonzero(np.diff(np.r_[0, (~self.static).astype(np.int8), 0]))
        return list(zip(edges[::2].tolist(), edges[1::2].tolist()))

    def describe(self, time: np.ndarray | None = None) -> str:
        """One line: how many samples move and where (rows, and seconds from the first sample)."""
        stretches = self.moving_stretches()
        if self.per_pose:
            gap = f" a median {float(np.median(np.diff(time))):.3g} s apart" if time is not None and time.size > 1 else ""
            return (f"a table of static poses: rows{gap}, no samples between them to see motion, so each row (or "
                    f"run of rows at one {self.signal}) is a hold: {self.n_holds} hold(s) in {self.n_samples} rows")
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


def check_seconds(time: np.ndarray, column: str, where: str) -> None:
    """Refuse a time column that is not in seconds (nanoseconds or microseconds), saying what it looks like."""
    from ..core.limits import MAX_TIME_S, MAX_TIME_STEP_S

    if time.size == 0:
        return
    steps = np.diff(time)
    step = float(np.median(np.abs(steps))) if steps.size else 0.0
    top = float(np.max(np.abs(time)))
    if step > MAX_TIME_STEP_S or top > MAX_TIME_S:
        unit = "nanoseconds" if step > 1e6 or top > 1e16 else "microseconds or nanoseconds"
        raise FtcalError(f"{where}: time column {column!r} looks like {unit}, not seconds (median step {step:.4g}, "
                         f"largest value {top:.4g}); ftcal reads seconds: divide the column by 1e9 (or 1e6).")


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
    check_seconds(time, time_column, where)
    n = time.size
    labels = np.zeros(n, dtype=np.int8) if segments is None else np.asarray(segments)
    bounds = np.flatnonzero(np.r_[True, labels[1:] != labels[:-1], True]) if n else np.array([0])
    for a, b in zip(bounds[:-1], bounds[1:]):
        bad = np.flatnonzero(np.diff(time[a:b]) <= 0)
        if bad.size:
            raise ParameterError('receive_time', f"{where}: column {time_column!r} does not increase at row {a + bad[0] + 1}; "
                             "sort the table by time (or, for a ROS bag, rebuild it with {receive_time}).")
    jumps = np.zeros(n, dtype=bool)
    travel = None
    if orientation is not None:
        q = np.asarray(orientation, dtype=np.float64)
        q = q / np.linalg.norm(q, axis=1, keepdims=True)
        signal, travel = "orientation", lambda i, j: _rotation_angle(q[i], q[j])
    elif gravity is not None:
        g = np.asarray(gravity, dtype=np.float64)
        signal, travel = "gravity direction", lambda i, j: _direction_angle(g[i], g[j])
    elif joints is not None:
        qj = np.asarray(joints, dtype=np.float64)
        signal, travel = "joints", lambda i, j: np.abs(qj[j] - qj[i]).max(axis=1, initial=0.0)
    if travel is not None:
        poses = _pose_rows(time, travel, bounds)
        if poses is not None:
            return Holds(np.ones(n, dtype=bool), poses, signal, per_pose=True)
        still, jumps = _kinematic_still(time, travel, bounds)
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


def _pose_rows(time: np.ndarray, travel, bounds: np.ndarray) -> np.ndarray | None:
    """Hold numbers of a table of static poses (one averaged row per pose), else None.

    A recording samples its motion: consecutive rows a fraction of a second apart. A table whose
    rows lie a median :data:`MIN_HOLD_S` or more apart in every segment has no samples between its
    rows to see a motion in (a rate over a gap of seconds says nothing), which is the layout of
    tables of recorded poses (one averaged row each, with the time it was taken). Each row, or run
    of rows at one pose (travel below :data:`SAME_POSE`), is then a hold.
    """
    if time.size < 2:
        return None
    hold = np.empty(time.size, dtype=np.int64)
    count = 0
    for a, b in zip(bounds[:-1], bounds[1:]):
        if b - a >= 2 and float(np.median(np.diff(time[a:b]))) < MIN_HOLD_S:
            return None
        index = np.arange(a, b)
        new_pose = np.r_[True, travel(index[:-1], index[1:]) > SAME_POSE] if b - a > 1 else np.ones(1, bool)
        hold[a:b] = count + np.cumsum(new_pose) - 1
        count = int(hold[b - 1]) + 1
    return hold


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


def number_across(holds: Sequence[np.ndarray]) -> np.ndarray:
    """One ``hold`` column from several recordings' hold numbers (each counted from 0).

    Parameters
    ----------
    holds : sequence of ndarray of int (-1 while moving), one per recording, in writing order

    Returns
    -------
    ndarray of int, the concatenation, each recording's holds numbered after the previous ones'
    (a recording without a hold takes no number); -1 stays -1.
    """
    parts, offset = [], 0
    for hold in holds:
        hold = np.asarray(hold, dtype=np.int64)
        parts.append(np.where(hold >= 0, hold + offset, -1))
        if hold.size and hold.max() >= 0:
            offset += int(hold.max()) + 1
    return np.concatenate(parts) if parts else np.zeros(0, dtype=np.int64)


@dataclass(frozen=True)
class HoldAverages:
    """Per-hold means of a recording (what ``ftcal check`` works on).

    Attributes
    ----------
    wrench : ndarray of shape (n_holds, 6)
        Mean reading, N and N·m.
    gravity : ndarray of shape (n_holds, 3)
        Mean gravity vector in the declared sensor frame, m/s².
    rotation : ndarray of shape (n_holds, 3, 3) or None
        Sensor-to-world rotation at the hold (when the orientation is known, not just gravity).
    start, stop : ndarray of shape (n_holds,)
        Row range of each hold in its recording.
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

    def map(self, wrench: np.ndarray | None = None, gravity: np.ndarray | None = None) -> "HoldAverages":
        """The same holds with the wrench and/or gravity replaced (a tested correction)."""
        return HoldAverages(self.wrench if wrench is None else wrench, self.gravity if gravity is None else gravity,
                            self.rotation, self.start, self.stop, self.noise)


def hold_averages(holds: Holds, wrench: np.ndarray, gravity: np.ndarray,
                  rotation: np.ndarray | None = None, *, quaternions: np.ndarray | None = None) -> HoldAverages:
    """Each hold's mean wrench, gravity and (when given) rotation, and its wrench's standard error.

    Parameters
    ----------
    holds : Holds of the recording (:func:`find_holds`)
    wrench : ndarray of shape (n_samples, 6)
    gravity : ndarray of shape (n_samples, 3)
    rotation : ndarray of shape (n_samples, 3, 3) or None
        Sensor-to-world rotations; each hold's is the rotation nearest to their mean.
    quaternions : ndarray of shape (n_samples, 4) or None
        The same rotations as quaternions (x, y, z, w, any norm), instead of ``rotation``: each
        hold's matrices are made from its own rows only (no n_samples × 3 × 3 array).

    Returns
    -------
    HoldAverages
    """
    start, stop = holds.ranges()
    w = np.asarray(wrench, dtype=np.float64)
    g = np.asarray(gravity, dtype=np.float64)
    rows = list(zip(start.tolist(), stop.tolist()))
    mean = np.array([w[a:b].mean(axis=0) for a, b in rows]).reshape(-1, w.shape[1])
    noise = np.array([w[a:b].std(axis=0) / np.sqrt(b - a) for a, b in rows]).reshape(-1, w.shape[1])
    g_mean = np.array([g[a:b].mean(axis=0) for a, b in rows]).reshape(-1, g.shape[1])
    rot = None
    if rotation is not None:
        rot = np.array([_mean_rotation(rotation[a:b]) for a, b in rows]).reshape(-1, 3, 3)
    elif quaternions is not None:
        q = np.asarray(quaternions, dtype=np.float64)
        rot = np.array([_mean_rotation(rotation_matrices(q[a:b])) for a, b in rows]).reshape(-1, 3, 3)
    return HoldAverages(mean, g_mean, rot, start.astype(np.int64), stop.astype(np.int64), noise)


def concatenate_averages(parts: Sequence[HoldAverages]) -> HoldAverages:
    """The holds of several recordings as one set (row ranges stay per recording)."""
    if len(parts) == 1:
        return parts[0]
    rotation = None if any(p.rotation is None for p in parts) else np.concatenate([p.rotation for p in parts])
    return HoldAverages(*(np.concatenate([getattr(p, k) for p in parts]) for k in ("wrench", "gravity")), rotation,
                        *(np.concatenate([getattr(p, k) for p in parts]) for k in ("start", "stop", "noise")))


def rotation_matrices(quaternions: np.ndarray) -> np.ndarray:
    """Rotation matrices of quaternions (x, y, z, w, ROS order; normalised first), shape (n, 3, 3).

    The textbook formula, what ``scipy.spatial.transform.Rotation.from_quat(q).as_matrix()`` gives,
    without importing SciPy for it.

    Examples
    --------
    >>> (rotation_matrices(np.array([[0.0, 0.0, 1.0, 1.0]])).round(12) + 0.0)[0].tolist()  # 90° about z
    [[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]
    """
    q = np.asarray(quaternions, dtype=np.float64).reshape(-1, 4)
    x, y, z, w = (q / np.linalg.norm(q, axis=1, keepdims=True)).T
    return np.stack([1.0 - 2.0 * (y * y + z * z), 2.0 * (x * y - z * w), 2.0 * (x * z + y * w),
                     2.0 * (x * y + z * w), 1.0 - 2.0 * (x * x + z * z), 2.0 * (y * z - x * w),
                     2.0 * (x * z - y * w), 2.0 * (y * z + x * w), 1.0 - 2.0 * (x * x + y * y)],
                    axis=1).reshape(-1, 3, 3)


def _mean_rotation(rotations: np.ndarray) -> np.ndarray:
    """The rotation nearest (Frobenius) to the mean of ``rotations`` of shape (n, 3, 3)."""
    u, _, vt = np.linalg.svd(rotations.mean(axis=0))
    d = np.sign(np.linalg.det(u @ vt))
    return u @ np.diag([1.0, 1.0, d]) @ vt
