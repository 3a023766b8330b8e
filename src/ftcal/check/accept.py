"""Acceptance test of an installed calibration: errors per axis and per pose against thresholds.

The reference wrench of each test sample is either the recording's own output columns
(named like the model's outputs, e.g. ``Fx..Tz`` from ``ftcal dataset``), or, with a payload
file, the bias plus the payload's weight seen through the orientation (a tool at rest and
nothing else touching it). An installation passes when, in every pose, every axis' RMS error
is within its threshold and no input channel is saturated, stuck or dead.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..core.limits import MAX_FORCE_ERROR, MAX_TORQUE_ERROR
from ..core.metrics import force_torque_columns
from ..data.tables import table_label_column
from ..runtime.errors import FtcalError, ParameterError

# A stuck run covering this fraction of the recording is a dead channel.
DEAD_FRACTION = 0.9
# A change of more than this many noise levels (and two quantisation steps) is a load change, not noise.
LOAD_CHANGE_NOISE = 10.0
# A channel that repeats its value in fewer than this share of its steps is analog (noise above one step).
ANALOG_REPEAT_SHARE = 0.5
# Converter widths whose full scale an integer channel may show.
ADC_BITS = (8, 10, 12, 14, 16, 18, 20, 24, 32)
# A reference wrench no larger than this anywhere (N, N·m) is "zero everywhere".
ZERO_REFERENCE = 1e-6


@dataclass(frozen=True)
class Thresholds:
    """Largest RMS error allowed on each force axis (N) and torque axis (N·m), and where they come from."""

    force: float = MAX_FORCE_ERROR
    torque: float = MAX_TORQUE_ERROR
    origin: str = "defaults"

    @classmethod
    def from_percent(cls, percent: float, rated_force: float, rated_torque: float, origin: str) -> "Thresholds":
        """``percent`` % of the rated force and torque ranges."""
        return cls(percent / 100.0 * rated_force, percent / 100.0 * rated_torque,
                   f"{percent:g} % of the rated range {rated_force:.4g} N, {rated_torque:.4g} N·m ({origin})")


@dataclass(frozen=True)
class PoseError:
    """RMS error of one pose (configuration) of the test recording."""

    label: str
    n_samples: int
    rmse: np.ndarray  # shape (6,)
    failed: tuple[str, ...]  # axes over threshold


@dataclass(frozen=True)
class Acceptance:
    """Result of :func:`acceptance_test`.

    Attributes
    ----------
    outputs : the six output names
    rmse, max_abs_error : ndarray of shape (6,), over all samples
    poses : per-pose errors, in order of appearance
    channel_issues : saturated / stuck / dead input channels, as text
    thresholds : Thresholds
    error : ndarray of shape (n_samples, 6), prediction minus reference
    labels : ndarray of shape (n_samples,), the pose of each sample
    reference : ndarray of shape (n_samples, 6) or None, the reference wrench (for the page)
    problems : reasons the test cannot pass whatever the errors (non-finite errors or thresholds,
        an unusable reference, a dead sensor); any fails the test
    """

    outputs: tuple[str, ...]
    rmse: np.ndarray
    max_abs_error: np.ndarray
    poses: list[PoseError]
    channel_issues: list[str]
    thresholds: Thresholds
    error: np.ndarray
    labels: np.ndarray
    reference: np.ndarray | None = field(repr=False, default=None)
    problems: list[str] = field(default_factory=list)

    @property
    def failed_poses(self) -> list[PoseError]:
        return [p for p in self.poses if p.failed]

    @property
    def passed(self) -> bool:
        return not self.failed_poses and not self.channel_issues and not self.problems


def axis_limits(outputs: Sequence[str], thresholds: Thresholds) -> np.ndarray:
    """Per-output threshold, shape (6,): force axes get ``thresholds.force``, torque axes ``.torque``."""
    forces, torques = force_torque_columns(outputs)
    if forces is None or torques is None:
        raise FtcalError(f"the model's outputs {', '.join(outputs)} are not three forces and three torques.")
    limits = np.empty(len(outputs))
    limits[forces] = thresholds.force
    limits[torques] = thresholds.torque
    return limits


def acceptance_test(error: np.ndarray, labels: np.ndarray, outputs: Sequence[str], thresholds: Thresholds,
                    channel_issues: Sequence[str] = (), reference: np.ndarray | None = None,
                    problems: Sequence[str] = ()) -> Acceptance:
    """Per-axis and per-pose errors against thresholds.

    Parameters
    ----------
    error : ndarray of shape (n_samples, 6)
        Calibrated prediction minus reference wrench, N and N·m.
    labels : ndarray of shape (n_samples,)
        Pose of each sample.
    outputs : the six output names
    thresholds : Thresholds
    channel_issues : problems of the input channels (any fails the test)
    reference : ndarray of shape (n_samples, 6), kept for the page
    problems : reasons the verdict cannot be PASS (e.g. from :func:`read_test_data`); more are added here:
        non-finite errors, metrics or thresholds

    Returns
    -------
    Acceptance
        A pose fails on an axis unless its RMS error is finite and within the threshold, so a NaN
        never passes.
    """
    if error.shape[0] == 0:
        raise FtcalError("the test recording has no samples.")
    limits = axis_limits(outputs, thresholds)
    problems = list(problems)
    bad_limits = [outputs[j] for j in np.flatnonzero(~(np.isfinite(limits) & (limits > 0)))]
    if bad_limits:
        problems.append(f"no usable threshold on {', '.join(bad_limits)} (not a finite positive number): "
                        "nothing can be judged against it")
    with np.errstate(over="ignore", invalid="ignore"):
        squares = error ** 2
        bad = ~np.isfinite(error)
        if bad.any():
            axes = [outputs[j] for j in np.flatnonzero(bad.any(axis=0))]
            problems.append(f"{int(bad.any(axis=1).sum())} of {error.shape[0]} samples have a non-finite error "
                            f"(NaN or infinite prediction or reference) on {', '.join(axes)}")
        codes, names = _pose_codes(labels)
        sizes = np.bincount(codes, minlength=len(names))
        sums = np.column_stack([np.bincount(codes, squares[:, j], len(names)) for j in range(squares.shape[1])])
        pose_rmse = np.sqrt(sums / sizes[:, None])
        poses = [PoseError(str(label), int(size), r, tuple(outputs[j] for j in np.flatnonzero(~(r <= limits))))
                 for label, size, r in zip(names, sizes, pose_rmse)]
        rmse = np.sqrt(np.mean(squares, axis=0))
        max_abs = np.abs(error).max(axis=0)
    if not bad.any() and not np.all(np.isfinite(rmse)):
        axes = [outputs[j] for j in np.flatnonzero(~np.isfinite(rmse))]
        problems.append(f"the RMS error overflows on {', '.join(axes)} (errors near 1e154 or more)")
    return Acceptance(tuple(outputs), rmse, max_abs, poses, list(channel_issues), thresholds, error, labels,
                      reference, problems)


def _pose_codes(labels: np.ndarray) -> tuple[np.ndarray, list]:
    """Integer code of each sample's pose, and the poses in order of appearance (one pass, any number of poses)."""
    import pandas as pd

    codes, names = pd.factorize(pd.Series(labels, dtype=object), sort=False, use_na_sentinel=False)
    return codes, list(names)


def _noise(x: np.ndarray, labels: np.ndarray) -> np.ndarray:
    """Per-column noise level, shape (n_columns,): the median over poses of the within-pose standard deviation."""
    codes, names = _pose_codes(labels)
    sizes = np.bincount(codes, minlength=len(names))[:, None]
    mean = np.column_stack([np.bincount(codes, x[:, j], len(names)) for j in range(x.shape[1])]) / sizes
    centred = x - mean[codes]
    var = np.column_stack([np.bincount(codes, centred[:, j] ** 2, len(names)) for j in range(x.shape[1])]) / sizes
    return np.median(np.sqrt(var), axis=0)


def _step(column: np.ndarray) -> float:
    """The smallest difference between two distinct values of ``column`` (its quantisation step); inf if constant."""
    gaps = np.diff(np.unique(column))
    return float(gaps.min()) if gaps.size else float("inf")


def _spread(x: np.ndarray) -> np.ndarray:
    """Robust range per column (1st to 99th percentile), shape (n_columns,)."""
    low, high = np.percentile(x, [1.0, 99.0], axis=0)
    return high - low


def _full_scale(column: np.ndarray) -> tuple[float, ...]:
    """The rails of the converter an integer channel may come from (observed full scale); () for other channels."""
    if not np.all(column == np.round(column)):
        return ()
    top, bottom = float(column.max()), float(column.min())
    rails = []
    for bits in ADC_BITS:
        if bottom >= 0 and top == 2.0 ** bits - 1:
            rails += [top, 0.0]
        if bottom < 0 and (top == 2.0 ** (bits - 1) - 1 or bottom == -2.0 ** (bits - 1)):
            rails += [2.0 ** (bits - 1) - 1, -2.0 ** (bits - 1)]
    return tuple(rails)


def input_channel_issues(inputs: np.ndarray, names: Sequence[str], time: np.ndarray, source: str,
                         reference: np.ndarray | None = None, labels: np.ndarray | None = None,
                         adc_limits: tuple[float, float] | None = None) -> list[str]:
    """Saturated, stuck and dead input channels (temperature columns skipped: they move slowly).

    See the module docstring for the rules: a channel resting on one value is a fault only when the
    load changed meanwhile (the reference, or the other channels, moved), or when the channel is
    analog (it changes at most steps elsewhere, so a long exact repeat cannot be noise).

    Parameters
    ----------
    inputs : ndarray of shape (n_samples, n_inputs)
    names : input names
    time : ndarray of shape (n_samples,), s
    source : the file, for messages
    reference : ndarray of shape (n_samples, 6) or None, the reference wrench (tells load changes)
    labels : ndarray of shape (n_samples,) or None, the pose of each sample (noise is measured within poses)
    adc_limits : the converter's declared (low, high) full scale, or None to infer it from integer channels
    """
    from ..data.signals import SATURATION_RUN, STUCK_RUN
    from ..report.runs import temperature_column

    n = inputs.shape[0]
    if n < 2:
        return []
    labels = np.zeros(n) if labels is None else labels
    skip = temperature_column(names)
    keep = [j for j in range(len(names)) if j != skip]
    x = inputs[:, keep]
    noise = _noise(x, labels)
    steps = np.array([_step(x[:, c]) for c in range(x.shape[1])])
    floor = np.maximum(LOAD_CHANGE_NOISE * noise, 2.0 * steps)
    ref_floor = None
    if reference is not None and np.all(np.isfinite(reference)):
        scale = float(np.abs(reference).max())
        ref_floor = np.maximum(LOAD_CHANGE_NOISE * _noise(reference, labels), 1e-9 * max(scale, 1.0))

    def load_changed(rows: slice, but: int) -> bool:
        if ref_floor is not None and np.any(_spread(reference[rows]) > ref_floor):
            return True
        spread = _spread(x[rows])
        return any(spread[o] > floor[o] for o in range(x.shape[1]) if o != but)

    out = []
    for c, j in enumerate(keep):
        col = x[:, c]
        name = f"{source} channel {names[j]}"
        edges = np.flatnonzero(np.diff(np.r_[0, np.diff(col) == 0, 0].astype(np.int8)))
        if not edges.size:
            continue
        longest = int(np.argmax(edges[1::2] - edges[::2]))
        start, stop = int(edges[2 * longest]), int(edges[2 * longest + 1]) + 1  # the run of equal steps spans one more sample
        length, value = stop - start, float(col[start])
        where = f"{length} samples from t={float(time[start]):.3f} s"
        at_rail = (value <= adc_limits[0] or value >= adc_limits[1]) if adc_limits is not None \
            else value in _full_scale(col)
        if length >= SATURATION_RUN and at_rail:
            out.append(f"{name} looks saturated: at the converter's full scale {value:g} for {where}")
            continue
        repeats = np.r_[np.diff(col[:start + 1]) == 0, np.diff(col[stop - 1:]) == 0]
        analog = repeats.size >= SATURATION_RUN and repeats.mean() < ANALOG_REPEAT_SHARE
        extreme = value in (col.min(), col.max()) and np.ptp(col) > 0
        needed = SATURATION_RUN if extreme else STUCK_RUN
        if length < needed or not (analog or load_changed(slice(start, stop), c)):
            continue
        if length >= DEAD_FRACTION * n:
            out.append(f"{name} looks dead: constant over {length} of {n} samples while the load changes")
        elif extreme:
            out.append(f"{name} looks saturated: held at its extreme value {value:g} for {where} while it "
                       "should move")
        else:
            out.append(f"{name} looks stuck: {where}")
    return out


def sensor_problems(inputs: np.ndarray, names: Sequence[str], reference: np.ndarray | None,
                    labels: np.ndarray, payload: bool) -> list[str]:
    """Reasons the test recording cannot judge the calibration: a dead sensor, a reference zero everywhere.

    Parameters
    ----------
    inputs : ndarray of shape (n_samples, n_inputs)
    names : input names
    reference : ndarray of shape (n_samples, 6) or None
    labels : ndarray of shape (n_samples,), the pose of each sample
    payload : the reference comes from a payload file (else from the recording's columns)
    """
    from ..report.runs import temperature_column

    if reference is None or inputs.shape[0] < 2 or not np.all(np.isfinite(reference)):
        return []
    skip = temperature_column(names)
    x = inputs[:, [j for j in range(len(names)) if j != skip]]
    floor = np.maximum(LOAD_CHANGE_NOISE * _noise(x, labels),
                       2.0 * np.array([_step(x[:, c]) for c in range(x.shape[1])]))
    channels_move = bool(np.any(_spread(x) > floor))
    scale = float(np.abs(reference).max())
    out = []
    if scale <= ZERO_REFERENCE and channels_move:
        out.append(f"the reference wrench is zero in every sample (|w| <= {ZERO_REFERENCE:g}) although the "
                   "sensor's channels change: unusable as a reference (was the load case named when the table "
                   "was made?)")
    ref_change = _spread(reference)
    ref_floor = np.maximum(LOAD_CHANGE_NOISE * _noise(reference, labels), 1e-9 * max(scale, 1.0))
    if not channels_move and np.any(ref_change > ref_floor):
        j = int(np.argmax(ref_change / np.maximum(ref_floor, 1e-300)))
        what = "the payload's weight" if payload else "the reference wrench"
        out.append(f"the sensor looks dead: no input channel changes beyond its noise while {what} changes by "
                   f"{ref_change[j]:.4g} on axis {j + 1}")
    return out


def read_test_data(paths: Sequence[str | os.PathLike], model, *, payload=None, source=None,
                   group_by: str | None = None, time_column: str = "time", rows: dict | None = None):
    """Model errors on test tables, their pose labels and the input-channel issues.

    Parameters
    ----------
    paths : CSV or Parquet files with the model's input columns (and its outputs, without ``payload``)
    model : CalibrationModel (static)
    payload : PayloadParameters or None
        The reference is then the bias plus the payload's wrench from ``source``.
    source : KinematicsSource, needed with ``payload``
    group_by : column naming the poses; default one pose per file
    time_column : seconds, for messages (row numbers when absent)
    rows : a dict that, when given, receives ``file`` (each sample's table) and ``time`` (seconds, or None
        when a table has no time column), for :func:`retare_verdict`

    Returns
    -------
    error : ndarray of shape (n_samples, 6)
    reference : ndarray of shape (n_samples, 6)
    labels : ndarray of shape (n_samples,)
    issues : list of str
        Saturated, stuck and dead channels.
    problems : list of str
        Reasons no verdict can pass (:func:`sensor_problems`).
    """
    from ..data.tables import numeric_columns, read_table
    from ..payload.compensate import contact_wrench

    if not model.is_static:
        raise ParameterError('accept', "ftcal check {accept} takes static models (no ARX lags); evaluate ARX models with "
                         "ftcal evaluate.")
    if len(model.output_names_) != 6:
        raise FtcalError(f"the calibration model has {len(model.output_names_)} outputs; a wrench needs 6.")
    if payload is not None and source is None:
        raise ParameterError(('payload', 'orientation', 'gravity_columns', 'urdf'), "{payload} needs the sensor's orientation ({orientation}, {gravity_columns} or {urdf}).")
    errors, references, labels, issues, inputs, files, times = [], [], [], [], [], [], []
    for path in paths:
        path = Path(path)
        frame = read_table(path)
        u = numeric_columns(frame, model.input_names_, path, "input")
        predicted = model.predict(u, warn_out_of_range=False)
        if payload is None:
            reference = numeric_columns(frame, model.output_names_, path, "reference output")
            error = predicted - reference
        else:
            error = contact_wrench(predicted, payload, source(frame, str(path)))
            reference = predicted - error
        column = table_label_column(list(frame.columns), group_by)
        if column is None:
            label = np.full(len(frame), str(path), dtype=object)
        elif column not in frame.columns:
            raise ParameterError('group_by', f"{path}: no pose column {column!r} ({{group_by}}); the file has "
                             f"{', '.join(map(str, frame.columns))}.")
        else:
            label = frame[column].astype(str).to_numpy(dtype=object)
        time = (numeric_columns(frame, (time_column,), path, "time")[:, 0] if time_column in frame.columns
                else np.arange(len(frame), dtype=float))
        issues += input_channel_issues(u, model.input_names_, time, str(path), reference, label)
        files.append(np.full(len(frame), str(path), dtype=object))
        times.append(time if time_column in frame.columns else None)
        errors.append(error)
        references.append(reference)
        labels.append(label)
        inputs.append(u)
    reference, label = np.concatenate(references), np.concatenate(labels)
    if rows is not None:
        rows["file"] = np.concatenate(files)
        rows["time"] = None if any(t is None for t in times) else np.concatenate(times)
    problems = sensor_problems(np.concatenate(inputs), model.input_names_, reference, label, payload is not None)
    return np.concatenate(errors), reference, label, issues, problems


def rated_ranges(model) -> tuple[float, float]:
    """Largest |training output| over the force axes and over the torque axes (the default rated range)."""
    forces, torques = force_torque_columns(model.output_names_)
    if forces is None or torques is None:
        raise FtcalError(f"the model's outputs {', '.join(model.output_names_)} are not three forces and three "
                         "torques.")
    extent = np.abs(model.output_range_).max(axis=1)  # output_range_ is (n_outputs, 2): min, max
    return float(extent[forces].max()), float(extent[torques].max())


def retare_verdict(result: Acceptance, files: np.ndarray, time: np.ndarray | None = None) -> str | None:
    """One line for a failed test: is the failure an offset alone, and what would a re-tare give?

    The errors are re-tared as a user re-tares before a test: each file's offset read at its first static
    hold (:func:`ftcal.data.tare.tare_offsets`, ``per-file``; holds from the reference's direction) and
    removed from every sample of the file; the test is then judged again on the same poses and thresholds.

    Parameters
    ----------
    result : the failed :class:`Acceptance` (its error, reference and labels)
    files : ndarray of shape (n_samples,), the table of each sample
    time : s, or None (rows at the hold sample rate)

    Returns
    -------
    str, or None when the test passed, or cannot pass for another reason (a channel issue, a problem)
    """
    from ..data.tare import tare_offsets

    if result.passed or result.problems or result.channel_issues or result.reference is None:
        return None
    notes: list[str] = []
    offset = tare_offsets([result.error], result.reference, files, files, "per-file", time=time, notes=notes)[0]
    if not np.any(offset):
        return "re-tare: no static hold in the test recording(s) to re-tare at; cannot tell an offset from a " \
               "calibration error"
    tared = acceptance_test(result.error - offset, result.labels, result.outputs, result.thresholds)
    removed = "  ".join(f"{a} {v:+.3g}" for a, v in zip(result.outputs, offset[np.flatnonzero(np.any(offset, axis=1))[0]]))
    rms = "  ".join(f"{a} {v:.4g}" for a, v in zip(result.outputs, tared.rmse))
    if tared.passed:
        return (f"the failure is an offset alone: re-tared at each file's first static hold (offset removed: "
                f"{removed}), every pose passes: RMS {rms}")
    return (f"not an offset alone: re-tared at each file's first static hold (offset removed: {removed}), "
            f"{len(tared.failed_poses)} of {len(tared.poses)} pose(s) still fail: RMS {rms}")
