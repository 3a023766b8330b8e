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

from ..core.jackknife import COARSER_BLOCKS, block_edges, t_scale
from ..data.tables import table_label_column
from ..runtime.errors import FtcalError, ParameterError
from .accumulate import AxisStatistics, payload_statistics
from .compensate import contact_wrench, undetermined_samples, warn_undetermined
from .drift import MAX_KNOTS, BiasDrift
from .identify import UNCERTAIN_ERROR_TEXT, PayloadFit, model_fit, warn_uncertain_error
from .kinematics import Kinematics, KinematicsSource
from .parameters import PayloadParameters

WRENCH_COLUMNS = ("u1", "u2", "u3", "u4", "u5", "u6")  # what the sensor reads, in ftcal datasets
CONTACT_COLUMNS = ("Fx", "Fy", "Fz", "Tx", "Ty", "Tz")


def check_wrench_columns(columns: Sequence[str], source: KinematicsSource | None = None) -> tuple[str, ...]:
    """Six distinct wrench columns, none of them read by the gravity ``source`` too (a wrench made of
    orientation columns is a typo, not a measurement)."""
    if len(columns) != 6:
        raise ParameterError('inputs', f"{{inputs}} needs 6 wrench columns Fx,Fy,Fz,Tx,Ty,Tz; got {','.join(columns)}.")
    twice = next((c for c in columns if list(columns).count(c) > 1), None)
    if twice is not None:
        raise ParameterError('inputs', f"{{inputs}} {','.join(columns)}: the wrench column {twice!r} is given twice; name six "
                         "different columns.")
    shared = [c for c in columns if c in set(getattr(source, "columns", ()) or ())]
    if shared:
        raise ParameterError('inputs', f"{{inputs}} {','.join(columns)}: {', '.join(map(repr, shared))} {'is' if len(shared) == 1 else 'are'} also read by the gravity "
                         "source (orientation, gravity, joint or motion columns); a wrench column must hold the "
                         "sensor's readings.")
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
    wrench = check_wrench_columns(wrench, source)
    sign = -1.0 if reaction else 1.0
    measured, kinematics, labels, times, temps = [], [], [], [], []
    for path in paths:
        frame = read_table(path)
        measured.append(sign * numeric_columns(frame, wrench, Path(path), "wrench"))
        kinematics.append(source(frame, str(path)))
        column = table_label_column(list(frame.columns), group_by)
        if column is None:
            labels.append(np.full(len(frame), str(path), dtype=object))
        elif column not in frame.columns:
            raise FtcalError(f"{path}: no group column {column!r}; the file has "
                             f"{', '.join(map(str, frame.columns))}.")
        else:
            labels.append(frame[column].astype(str).to_numpy(dtype=object))
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
        loads = predicted_loads(model, measured)
        if warn_out_of_range:
            warn_predicted_loads(model, loads)
    else:
        loads = None
        columns = check_wrench_columns(wrench or payload.fit.get("wrench_columns", WRENCH_COLUMNS), source)
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
        if model is not None and loads is not None:
            # and which axes the model's wrench drives beyond its training, as plain lists (pandas compares
            # attrs when it concatenates tables)
            out.attrs["predicted_loads"] = [loads.n, loads.n_beyond, loads.count.tolist(), loads.low.tolist(),
                                            loads.high.tolist()]
    return out


def predicted_loads(model, measured: np.ndarray):
    """:class:`~ftcal.core.ranges.LoadSums` of a model's predicted wrench against its training loads, or None
    when the model file has no training loads."""
    from ..core.ranges import LoadSums

    output_range = getattr(model, "output_range_", None)
    if output_range is None:
        return None
    return LoadSums.of(measured, np.asarray(output_range, dtype=float), model.output_names_)


def predicted_loads_text(model, loads) -> str | None:
    """Which axes the predicted wrench drives beyond the training loads, how far, in one sentence (or None).

    ``loads`` is a LoadSums, or a list of the ``predicted_loads`` attributes of :func:`compensate_table`'s
    tables (added up), or None."""
    from ..core.ranges import LoadSums, loads_text

    if isinstance(loads, list):
        parts = [LoadSums(n, beyond, np.array(count), np.array(low), np.array(high))
                 for n, beyond, count, low, high in loads]
        loads = sum(parts[1:], parts[0]) if parts else None
    if loads is None:
        return None
    return loads_text(loads.to_dict(np.asarray(model.output_range_, dtype=float), model.output_names_),
                      "the predicted loads")


def warn_predicted_loads(model, loads) -> None:
    """Warn (OutOfRangeWarning) when the calibrated wrench extrapolates beyond the training loads."""
    import warnings

    from ..runtime.errors import OutOfRangeWarning

    text = predicted_loads_text(model, loads)
    if text:
        warnings.warn(text, OutOfRangeWarning, stacklevel=3)


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
    held_out: HeldOut | None = None  # the bias models on the same held-out stretches of time

    def verdict(self) -> str:
        """Which mass to trust when the constant-bias and the chosen bias model disagree, and why (or "")."""
        return drift_verdict(self)


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
    from .drift import (BiasDrift, beside_wander, block_means, check_temperature, choose, covariates,
                        fit_state_space, within_hold_noise)
    from .identify import identify_from_statistics

    if bias_drift not in BIAS_DRIFTS:
        raise ParameterError('bias_drift', f"{{bias_drift}}: {bias_drift!r} is not one of {', '.join(BIAS_DRIFTS)}.")
    timed = bias_drift in ("linear", "random-walk")
    if timed and recording.time is None:
        raise ParameterError(('bias_drift', 'time'), f"{{bias_drift}} {bias_drift} needs the time column: give {{time}} COL.")
    if timed and dynamic:
        raise ParameterError(('bias_drift', 'dynamic'), f"{{bias_drift}} {bias_drift} works with static poses only; leave out {{dynamic}} "
                         "or use {bias_drift} none.")
    if dynamic and recording.temperature is not None:
        raise ParameterError(('temperature', 'dynamic'), "{temperature} works with static poses only; leave out {dynamic} or {temperature}.")
    temperature = None
    if recording.temperature is not None:
        check_temperature(recording.temperature, temperature_column)
        reference = float(np.mean(recording.temperature))
        temperature = recording.temperature - reference
    hours = recording.hours()
    extra, names = covariates(None, temperature)
    groups, clusters = _groups_and_blocks(recording, dynamic, extra)
    n_groups = len(groups)
    with warnings.catch_warnings(record=True) as said:
        warnings.simplefilter("always")
        constant = identify_from_statistics(groups, clusters=clusters, covariates=names, cross_validate=cross_validate,
                                    coarser=COARSER_BLOCKS)
    # The constant fit's uncertain-error warning is said only when the constant bias is the model kept (below):
    # a drift model that takes the drift out leaves no such error behind.
    uncertain = [w for w in said if str(w.message).startswith(UNCERTAIN_ERROR_TEXT)]
    for w in said:
        if w not in uncertain:
            warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
    held = () if constant.undetermined is None else constant.undetermined.held
    kind, selection = ("none", "") if bias_drift == "auto" and (hours is None or dynamic) else (bias_drift, "")
    fits = {}
    folds, stretches, held_out = {}, (), None
    if hours is not None and not dynamic and kind in ("auto", "random-walk", "linear"):
        blocks = block_means(hours, recording.kinematics.gravity, recording.measured, temperature)
        folds = _group_folds(recording, blocks, groups) if cross_validate and n_groups > 1 else {}
        stretches = stretch_folds(len(blocks.count))
        for candidate in ("none", "linear", "random-walk") if kind == "auto" else ("none", kind):
            try:
                fits[candidate] = fit_state_space(blocks, candidate, temperature is not None, held, stretches
                                                  + (tuple(folds.values()) if candidate == "random-walk" else ()))
            except FtcalError:
                if kind == candidate:
                    raise
                if candidate == "none" and kind == "random-walk":  # asked for: the walk has nothing to fit either
                    raise ParameterError('bias_drift', f"{{bias_drift}} random-walk: {len(blocks.count)} time block(s) of at least "
                                     f"{DRIFT_BLOCK_SECONDS:g} s: too few to fit a bias walk; record more samples, "
                                     "or give {bias_drift} none.") from None
                if candidate == "none":
                    break  # too few time blocks to compare bias models at all
        held_out = compare_held_out(blocks, fits)
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
            fit = identify_from_statistics(groups, clusters=clusters, covariates=names, cross_validate=cross_validate,
                                coarser=COARSER_BLOCKS)
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
        if temperature is not None:
            residual -= np.outer(temperature, ss.theta[10:16])
        within = within_hold_noise(residual, hours * 3600.0, blocks)  # what the live tracker sees
        if within is not None:  # a wander is noise: the trajectory does not follow it
            from dataclasses import replace

            ss = replace(ss, trajectory=beside_wander(ss, blocks, within, temperature is not None))
            knot_bias = ss.trajectory[keep]
        for j in range(6):
            residual[:, j] -= np.interp(hours, knot_hours, ss.trajectory[:, j])
        rms = np.sqrt(np.einsum("ij,ij->j", residual, residual) / recording.n_samples)
        del residual
        if ss.jackknife is not None:
            warn_uncertain_error(ss.jackknife, "the random-walk model's mass")
        fit = model_fit(ss.names, ss.theta, ss.covariance, residual_rms=rms, n_samples=recording.n_samples,
                        stderr_kind=_state_space_kind(ss, len(blocks.count)),
                        covariates=covariate_names, undetermined=constant.undetermined)
        fit = _with_end_bias(fit, ss.trajectory[-1], ss.end_stderr)
        if folds:
            from dataclasses import replace

            groups_only = replace(ss, held_out=ss.held_out[len(stretches):])
            fit = replace(fit, cross_validation=_walk_residuals(recording, folds, groups_only, knot_hours, hours,
                                                                temperature))
        change = ss.trajectory[-1] - ss.trajectory[0]
        walk = np.sqrt(ss.walk_variance)
    if kind == "none":
        for w in uncertain:
            warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
    drift = None
    if hours is not None or temperature is not None:
        t = recording.time
        coefficients = fit.covariates["temperature"][0] if temperature is not None else None
        variances = {}
        if kind == "random-walk":
            ss = fits["random-walk"]
            block_samples = float(blocks.count.mean())
            variances = {"walk_variance": np.asarray(ss.walk_variance, dtype=float),
                         "noise_variance": np.asarray(ss.noise_variance, dtype=float) * block_samples,
                         "block_samples": block_samples, "block_seconds": block_samples * float(np.median(np.diff(hours))) * 3600.0}
            if within is not None:
                variances.update(sample_variance=within.sample_variance, wander_variance=within.wander,
                                 wander_tau=within.tau, hold_seconds=within.hold_seconds,
                                 hold_walk_variance=within.walk)
        drift = BiasDrift(kind, time_column if t is not None else None,
                          None if t is None else float(t[0]), None if t is None else float(t[-1]),
                          knot_times, knot_bias, temperature_column if temperature is not None else None,
                          reference if temperature is not None else None, coefficients, selection, **variances)
    return DriftResult(fit, constant, drift, selection, change, 0.0 if hours is None else float(hours[-1]), walk,
                       n_groups, held_out)


def _group_folds(recording: PayloadRecording, blocks, groups) -> dict[str, np.ndarray]:
    """Per validation group, the time blocks holding any of its samples (held out together)."""
    of_sample = blocks.of_samples(recording.n_samples)
    out = {}
    for label in groups:
        fold = np.zeros(len(blocks.count), bool)
        fold[of_sample[recording.labels == label]] = True
        out[label] = fold
    return out


def _held_out_rms(recording: PayloadRecording, rows: np.ndarray, refit, knot_hours, hours, temperature):
    """Residual RMS (6,) of the samples ``rows`` against a state-space refit made without them (None: none)."""
    if refit is None:
        return None
    theta, trajectory = refit
    residual = recording.measured[rows] - _static_wrench(theta, recording.kinematics.gravity[rows])
    for j in range(6):
        residual[:, j] -= np.interp(hours[rows], knot_hours, trajectory[:, j])
    if temperature is not None:
        residual -= np.outer(temperature[rows], theta[-6:])
    return np.sqrt(np.mean(residual ** 2, axis=0))


def _walk_residuals(recording: PayloadRecording, folds: dict, ss, knot_hours, hours, temperature):
    """Leave-one-group-out residual RMS of the random-walk model: each group's samples against the fit
    (mass, centre of mass and the smoothed bias path) made without that group's time blocks."""
    from .identify import GroupResidual

    out = []
    for (label, _), refit in zip(folds.items(), ss.held_out):
        rows = np.flatnonzero(recording.labels == label)
        out.append(GroupResidual(str(label), len(rows),
                                 _held_out_rms(recording, rows, refit, knot_hours, hours, temperature)))
    return tuple(out)


@dataclass(frozen=True)
class HeldOut:
    """Bias models compared on the same held-out contiguous stretches of time (the walk interpolates across)."""

    stretches: int  # stretches left out in turn
    rms: dict  # kind -> (6,) pooled held-out residual RMS, N and N·m
    mass: dict  # kind -> (mass, its standard error) of the fit on all data


def compare_held_out(blocks, fits: dict) -> HeldOut | None:
    """Score each state-space fit in ``fits`` (kind -> StateSpaceFit whose first ``held_out`` refits are
    over :func:`stretch_folds`) on the block means of each stretch left out (O(blocks), no pass over the
    samples): the residual of a block mean is its mean wrench minus the refit's wrench at its mean gravity,
    bias and temperature (exact, the model is affine in them)."""
    from ..core.jackknife import block_edges
    from ..core.limits import ROBUST_CLUSTERS
    from .drift import _design

    edges = block_edges(len(blocks.count), ROBUST_CLUSTERS)
    rms, mass = {}, {}
    for kind, ss in fits.items():
        if len(ss.held_out) < len(edges) - 1:
            continue
        x = _design(blocks, kind == "linear", blocks.temperature is not None)
        at = 4  # the bias at the first block: the trajectory carries it (with the slope)
        sse, count = np.zeros(6), 0.0
        for (a, b), refit in zip(zip(edges[:-1], edges[1:]), ss.held_out[:len(edges) - 1]):
            if refit is None:
                continue
            theta, trajectory = refit
            without_bias = theta.copy()
            without_bias[at:at + 6] = 0.0
            if kind == "linear":
                without_bias[10:16] = 0.0
            residual = blocks.wrench[a:b] - np.einsum("bjp,p->bj", x[a:b], without_bias) - trajectory[a:b]
            sse += blocks.count[a:b] @ residual ** 2
            count += blocks.count[a:b].sum()
        if count:
            rms[kind] = np.sqrt(sse / count)
            mass[kind] = (float(ss.theta[0]), float(np.sqrt(ss.covariance[0, 0])))
    return HeldOut(len(edges) - 1, rms, mass) if len(rms) > 1 else None


def stretch_folds(n_blocks: int) -> tuple[np.ndarray, ...]:
    """:data:`~ftcal.core.limits.ROBUST_CLUSTERS` contiguous stretches of ``n_blocks`` time blocks, as masks."""
    from ..core.jackknife import block_edges
    from ..core.limits import ROBUST_CLUSTERS

    edges = block_edges(n_blocks, ROBUST_CLUSTERS)
    out = []
    for a, b in zip(edges[:-1], edges[1:]):
        fold = np.zeros(n_blocks, bool)
        fold[a:b] = True
        out.append(fold)
    return tuple(out)


def _state_space_kind(ss, n_blocks: int) -> str:
    """How the random-walk model's standard errors were made, in words."""
    fitted = n_blocks - ss.n_moving
    text = f"state-space model ({fitted} time blocks"
    if ss.n_moving:
        text += f"; {ss.n_moving} blocks in which the sensor turns left out, the walk spans them"
    text += ")"
    if ss.jackknife_stretches:
        runs = ss.jackknife.blocks if ss.jackknife is not None else (ss.jackknife_stretches,)
        text += (f", each raised to the largest grouped jackknife over {', '.join(map(str, runs))} contiguous "
                 "stretches where that is larger")
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


# Two masses further apart than this many combined standard errors disagree beyond their errors.
DISAGREE_STDERR = 2.0
# Mean held-out error ratios (force, torque) within this fraction of 1 are ties; a model preferred on the
# mean may lose by at most HELD_OUT_WORSE on the other kind of axis (its extra parameters' noise).
HELD_OUT_TIE = 0.01
HELD_OUT_WORSE = 0.05
_MODEL_NAMES = {"none": "constant bias", "linear": "bias linear in time", "random-walk": "random-walk bias"}


def drift_verdict(result: DriftResult) -> str:
    """The bias models' held-out residuals and, when the chosen model's mass and the constant-bias mass
    disagree beyond their errors, which to trust and why. Empty without a comparison."""
    held = result.held_out
    if held is None or "none" not in held.rms:
        return ""
    chosen = result.drift.model if result.drift is not None else "none"
    base = held.rms["none"]
    lines = [f"held-out residual RMS of each bias model, on block means ({held.stretches} contiguous stretches of "
             "time left out in turn; the model bridges the gap):"]
    ratios = {}
    for kind, rms in held.rms.items():
        per_axis = rms / np.maximum(base, 1e-300)
        ratios[kind] = (float(np.mean(per_axis[:3])), float(np.mean(per_axis[3:])))
        lines.append(f"  {_MODEL_NAMES[kind]:<20}" + "  ".join(f"{a} {v:.4g}" for a, v in zip(CONTACT_COLUMNS, rms))
                     + ("" if kind == "none" else f"   ({ratios[kind][0]:.2f}x on force, {ratios[kind][1]:.2f}x on "
                                                   "torque vs constant)"))
    if chosen == "none":
        return "\n".join(lines)
    m_c, se_c = result.constant.mass, result.constant.stderr["mass"]
    m_f, se_f = result.fit.mass, result.fit.stderr["mass"]
    z = (m_f - m_c) / max(np.hypot(se_c, se_f), 1e-300)
    name = _MODEL_NAMES[chosen]
    if abs(z) <= DISAGREE_STDERR:
        lines.append(f"  mass: {name} {m_f:.6g} ± {se_f:.2g} kg and constant bias {m_c:.6g} ± {se_c:.2g} kg agree "
                     f"({z:+.1f} combined standard errors)")
        force, torque = ratios.get(chosen, (1.0, 1.0))
        if 0.5 * (force + torque) < 1.0 - HELD_OUT_TIE and max(force, torque) <= 1.0 + HELD_OUT_WORSE \
                and se_f < se_c:
            lines.append(f"  the {name} predicts held-out time better and states the smaller error: trust it")
        return "\n".join(lines)
    force, torque = ratios.get(chosen, (1.0, 1.0))
    lines.append(f"  mass: {name} {m_f:.6g} ± {se_f:.2g} kg and constant bias {m_c:.6g} ± {se_c:.2g} kg disagree "
                 f"beyond their errors ({z:+.1f} combined standard errors)")
    mean = 0.5 * (force + torque)
    if mean < 1.0 - HELD_OUT_TIE and max(force, torque) <= 1.0 + HELD_OUT_WORSE:
        lines.append(f"  trust the {name} ({m_f:.6g} kg): it predicts held-out time better, and a constant-bias fit "
                     "takes part of the drift into the mass and centre of mass when the poses follow time")
    elif mean > 1.0 + HELD_OUT_TIE and min(force, torque) >= 1.0 - HELD_OUT_WORSE:
        lines.append(f"  trust the constant bias ({m_c:.6g} kg): the {name} predicts held-out time worse, so its "
                     "extra freedom follows pose errors, not drift")
    else:
        lines.append(f"  held-out time cannot tell them apart: neither bias model describes the data; take the "
                     f"difference ({abs(m_f - m_c):.2g} kg) as the mass's uncertainty, not either standard error")
    return "\n".join(lines)
