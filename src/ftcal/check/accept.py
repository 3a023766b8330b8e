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
from ..runtime.errors import FtcalError

# A stuck run covering this fraction of the recording is a dead channel.
DEAD_FRACTION = 0.9


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

    @property
    def failed_poses(self) -> list[PoseError]:
        return [p for p in self.poses if p.failed]

    @property
    def passed(self) -> bool:
        return not self.failed_poses and not self.channel_issues


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
                    channel_issues: Sequence[str] = (), reference: np.ndarray | None = None) -> Acceptance:
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

    Returns
    -------
    Acceptance
    """
    if error.shape[0] == 0:
        raise FtcalError("the test recording has no samples.")
    limits = axis_limits(outputs, thresholds)
    poses = []
    for label in dict.fromkeys(labels.tolist()):
        rows = labels == label
        rmse = np.sqrt(np.mean(error[rows] ** 2, axis=0))
        poses.append(PoseError(str(label), int(rows.sum()), rmse,
                               tuple(outputs[j] for j in np.flatnonzero(rmse > limits))))
    return Acceptance(tuple(outputs), np.sqrt(np.mean(error ** 2, axis=0)), np.abs(error).max(axis=0), poses,
                      list(channel_issues), thresholds, error, labels, reference)


def input_channel_issues(inputs: np.ndarray, names: Sequence[str], time: np.ndarray, source: str) -> list[str]:
    """Saturated, stuck and dead input channels (temperature columns skipped: they move slowly).

    Parameters
    ----------
    inputs : ndarray of shape (n_samples, n_inputs)
    names : input names
    time : ndarray of shape (n_samples,), s
    source : the file, for messages
    """
    from ..data.recording import Stream
    from ..data.signals import channel_issues
    from ..report.runs import temperature_column

    skip = temperature_column(names)
    keep = [j for j in range(len(names)) if j != skip]
    stream = Stream(source, time, inputs[:, keep], tuple(names[j] for j in keep))
    out = []
    for issue in channel_issues(stream):
        dead = issue.kind == "stuck" and issue.samples >= DEAD_FRACTION * inputs.shape[0]
        out.append(f"{stream.name} channel {issue.column} looks dead: constant over {issue.samples} of "
                   f"{inputs.shape[0]} samples" if dead else str(issue))
    return out


def read_test_data(paths: Sequence[str | os.PathLike], model, *, payload=None, source=None,
                   group_by: str | None = None, time_column: str = "time"):
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

    Returns
    -------
    error : ndarray of shape (n_samples, 6)
    reference : ndarray of shape (n_samples, 6)
    labels : ndarray of shape (n_samples,)
    issues : list of str
    """
    from ..data.tables import numeric_columns, read_table
    from ..payload.compensate import contact_wrench

    if not model.is_static:
        raise FtcalError("ftcal check --accept takes static models (no ARX lags); evaluate ARX models with "
                         "ftcal evaluate.")
    if len(model.output_names_) != 6:
        raise FtcalError(f"the calibration model has {len(model.output_names_)} outputs; a wrench needs 6.")
    if payload is not None and source is None:
        raise FtcalError("--payload needs the sensor's orientation (--orientation, --gravity-columns or --urdf).")
    errors, references, labels, issues = [], [], [], []
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
        if group_by is None:
            label = np.full(len(frame), str(path), dtype=object)
        elif group_by not in frame.columns:
            raise FtcalError(f"{path}: no pose column {group_by!r} (--group-by); the file has "
                             f"{', '.join(map(str, frame.columns))}.")
        else:
            label = frame[group_by].astype(str).to_numpy(dtype=object)
        time = (numeric_columns(frame, (time_column,), path, "time")[:, 0] if time_column in frame.columns
                else np.arange(len(frame), dtype=float))
        issues += input_channel_issues(u, model.input_names_, time, str(path))
        errors.append(error)
        references.append(reference)
        labels.append(label)
    return np.concatenate(errors), np.concatenate(references), np.concatenate(labels), issues


def rated_ranges(model) -> tuple[float, float]:
    """Largest |training output| over the force axes and over the torque axes (the default rated range)."""
    forces, torques = force_torque_columns(model.output_names_)
    if forces is None or torques is None:
        raise FtcalError(f"the model's outputs {', '.join(model.output_names_)} are not three forces and three "
                         "torques.")
    extent = np.abs(model.output_range_).max(axis=1)  # output_range_ is (n_outputs, 2): min, max
    return float(extent[forces].max()), float(extent[torques].max())
