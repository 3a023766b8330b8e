"""Payload identification and compensation over CSV/Parquet tables (what the CLI commands call).

``read_payload_tables`` joins the files into one :class:`PayloadRecording`;
``identify_recording`` fits it with the bias model asked for (constant, linear,
random walk, or chosen by evidence) and grouped-jackknife or state-space standard
errors; ``rebias`` re-tares; ``compensate_table`` applies a payload file.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..core.jackknife import block_edges, t_scale
from ..runtime.errors import FtcalError
from .accumulate import AxisStatistics, payload_statistics
from .compensate import contact_wrench, undetermined_samples, warn_undetermined
from .drift import MAX_KNOTS, BiasDrift
from .identify import PayloadFit, model_fit
from .kinematics import Kinematics, KinematicsSource
from .parameters import PayloadParameters

WRENCH_COLUMNS = ("u1", "u2", "u3", "u4", "u5", "u6")  # what the sensor reads, in ftcal datasets
CONTACT_COLUMNS = ("Fx", "Fy", "Fz", "Tx", "Ty", "Tz")


def _check_wrench_columns(columns: Sequence[str]) -> tuple[str, ...]:
    if len(columns) != 6:
        raise FtcalError(f"--wrench needs 6 columns Fx,Fy,Fz,Tx,Ty,Tz; got {','.join(columns)}.")
    return tuple(columns)


@dataclass(frozen=True)
class PayloadRecording:
    """The tables of a payload identification, concatenated in the order given."""

    measured: np.ndarray  # (N, 6), readings in ftcal's sign convention
    kinematics: Kinematics
    labels: np.ndarray  # (N,) validation group of each sample
    time: np.ndarray | None  # (N,) s, strictly increasing, when a time column was asked for
    temperature: np.ndarray | None  # (N,)

    @property
    def n_samples(self) -> int:
        return self.measured.shape[0]

    def hours(self) -> np.ndarray | None:
        """Time since the first sample, h (None without a time column)."""
        return None if self.time is None else (self.time - self.time[0]) / 3600.0


def read_payload_tables(paths: Sequence[str | os.PathLike], source: KinematicsSource, *,
                        wrench: Sequence[str] = WRENCH_COLUMNS, group_by: str | None = None,
                        reaction: bool = False, time: str | None = None,
                        temperature: str | None = None, select: Callable | None = None) -> PayloadRecording:
    """Read the tables of a payload identification into one recording.

    Parameters
    ----------
    paths : CSV or Parquet files, one row per sample, in time order
    source : KinematicsSource
    wrench : six measured-wrench columns (N, N·m)
    group_by : column naming the validation groups; None: one group per file
    reaction : negate the readings (sensor reporting the opposite sign)
    time : time column in s (strictly increasing across all files), or None
    temperature : temperature column, or None
    select : callable or None
        ``select(frame, kinematics, path)`` gives the rows to use (a boolean
        mask, e.g. the static samples) or None for all of them.

    Returns
    -------
    PayloadRecording

    Raises
    ------
    FtcalError
        Missing, non-numeric or non-finite columns, time not increasing, bad kinematics.
    """
    from ..data.tables import numeric_columns, read_table
    from .drift import check_time

    if not paths:
        raise FtcalError("No data files given.")
    wrench = _check_wrench_columns(wrench)
    sign = -1.0 if reaction else 1.0
    measured, kinematics, labels, times, temps = [], [], [], [], []
    for path in paths:
        frame = read_table(path)
        measured.append(sign * numeric_columns(frame, wrench, Path(path), "wrench"))
        kinematics.append(source(frame, str(path)))
        if group_by is None:
            labels.append(np.full(len(frame), str(path), dtype=object))
        elif group_by not in frame.columns:
            raise FtcalError(f"{path}: no group column {group_by!r}; the file has "
                             f"{', '.join(map(str, frame.columns))}.")
        else:
            labels.append(frame[group_by].astype(str).to_numpy(dtype=object))
        if time is not None:
            t = numeric_columns(frame, (time,), Path(path), "time")[:, 0]
            check_time(t, time, str(path))
            if times and len(t) and t[0] <= times[-1][-1]:
                raise FtcalError(f"{path}: time column {time!r} starts at {t[0]!r}, not after the previous "
                                 f"file's last time {times[-1][-1]!r}; give the files in time order.")
            times.append(t)
        if temperature is not None:
            temps.append(numeric_columns(frame, (temperature,), Path(path), "temperature")[:, 0])
        keep = None if select is None else select(frame, kinematics[-1], str(path))
        if keep is not None:
            measured[-1], kinematics[-1], labels[-1] = measured[-1][keep], kinematics[-1].take(keep), labels[-1][keep]
            if time is not None:
                times[-1] = times[-1][keep]
            if temperature is not None:
                temps[-1] = temps[-1][keep]

    def join(arrays):
        return None if any(a is None for a in arrays) else np.concatenate(arrays)

    joined = Kinematics(np.concatenate([k.gravity for k in kinematics]),
                        *(join([getattr(k, name) for k in kinematics])
                          for name in ("angular_velocity", "angular_acceleration", "proper_acceleration")))
    return PayloadRecording(np.concatenate(measured), joined, np.concatenate(labels),
                            np.concatenate(times) if time is not None else None,
                            np.concatenate(temps) if temperature is not None else None)


def group_statistics(recording: PayloadRecording, *, dynamic: bool = False,
                     extra: np.ndarray | None = None) -> dict[str, AxisStatistics]:
    """Payload statistics per validation group, in order of first appearance (see ``payload_statistics``)."""
    import pandas as pd

    groups: dict[str, AxisStatistics] = {}
    codes, uniques = pd.factorize(recording.labels)  # order of first appearance
    for code, label in enumerate(uniques):
        rows = np.flatnonzero(codes == code) if len(uniques) > 1 else np.arange(len(codes))
        if len(rows) == len(codes):
            groups[label] = payload_statistics(recording.measured, recording.kinematics, dynamic=dynamic, extra=extra)
        else:
            groups[label] = payload_statistics(recording.measured[rows], recording.kinematics.take(rows),
                                               dynamic=dynamic, extra=None if extra is None else extra[rows])
    return groups


def block_statistics(recording: PayloadRecording, n_blocks: int, *, dynamic: bool = False,
                     extra: np.ndarray | None = None) -> list[AxisStatistics]:
    """Payload statistics of ``n_blocks`` contiguous row blocks of equal size (clusters, held-out folds)."""
    edges = block_edges(recording.n_samples, n_blocks)
    return [payload_statistics(recording.measured[a:b], recording.kinematics.rows(a, b), dynamic=dynamic,
                               extra=None if extra is None else extra[a:b])
            for a, b in zip(edges[:-1], edges[1:])]


def table_statistics(paths: Sequence[str | os.PathLike], source: KinematicsSource, *,
                     wrench: Sequence[str] = WRENCH_COLUMNS, group_by: str | None = None,
                     reaction: bool = False, dynamic: bool = False,
                     select: Callable | None = None) -> dict[str, AxisStatistics]:
    """Payload statistics of tables, one entry per validation group (files or ``group_by``).

    Returns
    -------
    dict of group label to AxisStatistics, in order of first appearance

    Raises
    ------
    FtcalError
        Missing, non-numeric or non-finite columns, bad kinematics (naming file, column, row).
    """
    recording = read_payload_tables(paths, source, wrench=wrench, group_by=group_by, reaction=reaction,
                                    select=select)
    return group_statistics(recording, dynamic=dynamic)


def compensate_table(path: str | os.PathLike, payload: PayloadParameters, source: KinematicsSource, *,
                     wrench: Sequence[str] | None = None, model=None, time_column: str | None = None,
                     warn_out_of_range: bool = True):
    """One table with its contact wrench as ``Fx..Tz`` (replacing such columns), other columns kept.

    Parameters
    ----------
    path : CSV or Parquet file
    payload : PayloadParameters
    source : KinematicsSource
    wrench : six measured-wrench columns; default the ones the payload was identified from
    model : CalibrationModel or None
        When given, the measured wrench is its prediction from its input columns.
    time_column : time column (s) when the bias drifts in time; default the payload file's
    warn_out_of_range : bool
        Let the model warn about inputs outside its training range, and warn about samples outside
        the span of the payload's identification poses (off when the caller warns once for several
        tables: the count is then ``attrs["undetermined_samples"]`` of the result).

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
    drift = payload.drift
    time = temperature = None
    if payload.needs_time:
        time = numeric_columns(frame, (time_column or drift.time_column,), Path(path), "time")[:, 0]
    if payload.needs_temperature:
        temperature = numeric_columns(frame, (drift.temperature_column,), Path(path), "temperature")[:, 0]
    kinematics = source(frame, str(path))
    contact = contact_wrench(measured, payload, kinematics, time, temperature, str(path), warn=warn_out_of_range)
    out = frame.copy()
    for j, name in enumerate(CONTACT_COLUMNS):
        out[name] = contact[:, j]
    if not warn_out_of_range:  # the caller warns once: how many samples the undetermined parameters act on
        out.attrs["undetermined_samples"] = undetermined_samples(payload, kinematics)
    return out


@dataclass(frozen=True)
class DriftResult:
    """A payload fit with its bias model, and the constant-bias fit it is compared with."""

    fit: PayloadFit  # the chosen model; its bias is the one at the end of the recording
    constant: PayloadFit  # constant bias (affine in temperature when asked), same samples
    drift: BiasDrift | None  # None: constant bias, no time or temperature recorded
    selection: str  # why this model, in words
    change: np.ndarray | None  # (6,) bias at the end minus at the start of the recording
    hours: float  # duration of the recording, h
    walk_std: np.ndarray | None  # (6,) random-walk standard deviation per √h
    n_groups: int = 1  # validation groups (files or --group-by)


def identify_recording(recording: PayloadRecording, *, bias_drift: str = "auto", dynamic: bool = False,
                       time_column: str | None = None, temperature_column: str | None = None,
                       cross_validate: bool = True) -> DriftResult:
    """Identify payload and bias with the bias model ``bias_drift`` (see :mod:`ftcal.payload.drift`).

    Parameters
    ----------
    recording : PayloadRecording
        With ``time`` for the time models and ``temperature`` for a bias affine in temperature.
    bias_drift : {"none", "linear", "random-walk", "auto"}
        ``auto`` without a time column is ``none``.
    dynamic : the 16-parameter model (constant bias only)
    time_column, temperature_column : column names, stored in the drift model
    cross_validate : leave-one-group-out residuals of the least-squares fits

    Returns
    -------
    DriftResult

    Raises
    ------
    FtcalError
        A time model without time, with ``dynamic``, a constant temperature, or data that cannot
        determine the model.
    """
    import warnings

    from ..core.limits import BIAS_DRIFTS, DRIFT_BLOCK_SECONDS
    from ..runtime.errors import UndeterminedWarning
    from .drift import BiasDrift, block_means, check_temperature, choose, covariates, fit_state_space
    from .identify import identify_payload

    if bias_drift not in BIAS_DRIFTS:
        raise FtcalError(f"--bias-drift: {bias_drift!r} is not one of {', '.join(BIAS_DRIFTS)}.")
    timed = bias_drift in ("linear", "random-walk")
    if timed and recording.time is None:
        raise FtcalError(f"--bias-drift {bias_drift} needs the time column: give --time COL.")
    if timed and dynamic:
        raise FtcalError(f"--bias-drift {bias_drift} works with static poses only; leave out --dynamic "
                         "or use --bias-drift none.")
    if dynamic and recording.temperature is not None:
        raise FtcalError("--temperature works with static poses only; leave out --dynamic or --temperature.")
    temperature = None
    if recording.temperature is not None:
        check_temperature(recording.temperature, temperature_column)
        reference = float(np.mean(recording.temperature))
        temperature = recording.temperature - reference
    hours = recording.hours()
    extra, names = covariates(None, temperature)
    groups, clusters = _groups_and_blocks(recording, dynamic, extra)
    n_groups = len(groups)
    constant = identify_payload(groups, clusters=clusters, covariates=names, cross_validate=cross_validate)
    held = () if constant.undetermined is None else constant.undetermined.held
    kind, selection = ("none", "") if bias_drift == "auto" and (hours is None or dynamic) else (bias_drift, "")
    fits = {}
    if hours is not None and not dynamic and kind in ("auto", "random-walk"):
        blocks = block_means(hours, recording.kinematics.gravity, recording.measured, temperature)
        for candidate in (("none", "linear", "random-walk") if kind == "auto" else ("random-walk",)):
            try:
                fits[candidate] = fit_state_space(blocks, candidate, temperature is not None, held)
            except FtcalError:
                if kind != "auto":
                    raise
                if candidate == "none":
                    break  # too few time blocks to compare bias models at all
        if kind == "auto" and "none" in fits:
            kind, selection = choose(fits)
        elif kind == "auto":
            kind, selection = "none", (f"{len(blocks.count)} time block(s) of at least "
                                       f"{DRIFT_BLOCK_SECONDS:g} s: too few to compare bias models")
    fit, change, walk = constant, None, None
    knot_times = knot_bias = None
    if kind == "linear":
        extra, names = covariates(hours, temperature)
        groups, clusters = _groups_and_blocks(recording, False, extra)
        with warnings.catch_warnings():  # the constant fit said what the poses do not determine
            warnings.simplefilter("ignore", UndeterminedWarning)
            fit = identify_payload(groups, clusters=clusters, covariates=names, cross_validate=cross_validate)
        slope = fit.theta[10:16]
        start = fit.theta[4:10]
        end_hours = hours[-1]
        at_end = np.zeros((6, fit.theta.size))
        at_end[np.arange(6), 4 + np.arange(6)] = 1.0
        at_end[np.arange(6), 10 + np.arange(6)] = end_hours
        fit = _with_end_bias(fit, start + slope * end_hours,
                             np.sqrt(np.einsum("jp,pq,jq->j", at_end, fit.covariance, at_end)))
        knot_times = recording.time[[0, -1]]
        knot_bias = np.vstack([start, start + slope * end_hours])
        change = slope * end_hours
    elif kind == "random-walk":
        ss = fits["random-walk"]
        knot_hours = blocks.hours
        keep = np.unique(np.r_[np.linspace(0, len(knot_hours) - 1, min(len(knot_hours), MAX_KNOTS)).astype(int)])
        knot_times = recording.time[0] + knot_hours[keep] * 3600.0
        knot_bias = ss.trajectory[keep]
        covariate_names = ("temperature",) if temperature is not None else ()
        residual = recording.measured - _static_wrench(ss.theta, recording.kinematics.gravity)
        for j in range(6):
            residual[:, j] -= np.interp(hours, knot_hours, ss.trajectory[:, j])
        if temperature is not None:
            residual -= np.outer(temperature, ss.theta[10:16])
        rms = np.sqrt(np.einsum("ij,ij->j", residual, residual) / recording.n_samples)
        del residual
        fit = model_fit(ss.names, ss.theta, ss.covariance, residual_rms=rms, n_samples=recording.n_samples,
                        stderr_kind=_state_space_kind(ss, len(blocks.count)),
                        covariates=covariate_names, undetermined=constant.undetermined)
        fit = _with_end_bias(fit, ss.trajectory[-1], ss.end_stderr)
        change = ss.trajectory[-1] - ss.trajectory[0]
        walk = np.sqrt(ss.walk_variance)
    drift = None
    if hours is not None or temperature is not None:
        t = recording.time
        coefficients = fit.covariates["temperature"][0] if temperature is not None else None
        drift = BiasDrift(kind, time_column if t is not None else None,
                          None if t is None else float(t[0]), None if t is None else float(t[-1]),
                          knot_times, knot_bias, temperature_column if temperature is not None else None,
                          reference if temperature is not None else None, coefficients, selection)
    return DriftResult(fit, constant, drift, selection, change, 0.0 if hours is None else float(hours[-1]), walk,
                       n_groups)


def _state_space_kind(ss, n_blocks: int) -> str:
    """How the random-walk model's standard errors were made, in words."""
    fitted = n_blocks - ss.n_moving
    text = f"state-space model ({fitted} time blocks"
    if ss.n_moving:
        text += f"; {ss.n_moving} blocks in which the sensor turns left out, the walk spans them"
    text += ")"
    if ss.jackknife_stretches:
        text += (f", each raised to a grouped jackknife over {ss.jackknife_stretches} contiguous stretches "
                 "where that is larger")
    return text


def _groups_and_blocks(recording: PayloadRecording, dynamic: bool, extra: np.ndarray | None):
    """Statistics per validation group and per contiguous time block; one pass when there is one group."""
    from ..core.limits import ROBUST_CLUSTERS

    blocks = block_statistics(recording, ROBUST_CLUSTERS, dynamic=dynamic, extra=extra)
    first = recording.labels[0] if recording.n_samples else ""
    if recording.n_samples and np.all(recording.labels == first):
        total = blocks[0]
        for b in blocks[1:]:
            total = total + b
        return {first: total}, blocks
    return group_statistics(recording, dynamic=dynamic, extra=extra), blocks


def _static_wrench(theta: np.ndarray, gravity: np.ndarray) -> np.ndarray:
    """F = m g, T = (m c) × g for θ = [m, m·c, ...] (ftcal sign convention), written column by column."""
    out = np.empty((gravity.shape[0], 6))
    np.multiply(gravity, theta[0], out=out[:, :3])
    (x, y, z), (gx, gy, gz) = theta[1:4], gravity.T
    out[:, 3] = y * gz - z * gy
    out[:, 4] = z * gx - x * gz
    out[:, 5] = x * gy - y * gx
    return out


def _with_end_bias(fit: PayloadFit, bias: np.ndarray, stderr: np.ndarray) -> PayloadFit:
    from dataclasses import replace

    from .identify import undetermined_fields

    stderr = np.array(stderr, dtype=float)
    if fit.undetermined is not None:  # no standard error for what the poses do not determine
        fields = undetermined_fields(fit.undetermined.parameters)
        stderr[list(fields.get("force_bias", ()))] = np.nan
        stderr[[3 + j for j in fields.get("torque_bias", ())]] = np.nan
    errors = dict(fit.stderr, force_bias=stderr[:3], torque_bias=stderr[3:])
    return replace(fit, force_bias=bias[:3], torque_bias=bias[3:], stderr=errors)


@dataclass(frozen=True)
class Rebias:
    """A bias re-estimated with the mass and centre of mass held fixed."""

    bias: np.ndarray  # (6,)
    stderr: np.ndarray  # (6,)
    stderr_kind: str


def rebias(recording: PayloadRecording, payload: PayloadParameters) -> Rebias:
    """Re-tare: the bias that makes ``recording`` fit ``payload``'s mass and centre of mass.

    The bias is the mean of the readings minus the payload's gravity wrench (and
    the temperature term when the payload has one); its standard error is
    cluster-robust over :data:`~ftcal.core.limits.ROBUST_CLUSTERS` contiguous
    blocks (t-scaled), so correlated noise and leftover drift widen it. The mass
    and centre of mass are taken as exact.

    Parameters
    ----------
    recording : PayloadRecording
        Contact-free samples; readings already in ftcal's sign convention.
    payload : PayloadParameters

    Returns
    -------
    Rebias
    """
    from ..core.limits import ROBUST_CLUSTERS
    from .compensate import payload_wrench

    warn_undetermined(payload, undetermined_samples(payload, recording.kinematics), recording.n_samples,
                      "the re-tare data")
    residual = recording.measured - payload_wrench(payload, recording.kinematics)
    if payload.needs_temperature:
        drift = payload.drift
        residual -= np.outer(recording.temperature - drift.temperature_reference, drift.temperature_coefficients)
    n = recording.n_samples
    bias = residual.mean(axis=0)
    g = min(ROBUST_CLUSTERS, n)
    if g < 2:
        raise FtcalError("one sample cannot estimate the bias's uncertainty; record more samples.")
    edges = block_edges(n, g)
    sums = np.add.reduceat(residual - bias, edges[:-1], axis=0)
    stderr = t_scale(g - 1) * np.sqrt(g / (g - 1) * np.sum(sums ** 2, axis=0)) / n
    return Rebias(bias, stderr, f"cluster-robust ({g} contiguous blocks)")
