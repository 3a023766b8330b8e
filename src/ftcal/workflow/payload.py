"""Identify a payload (bias, mass, centre of mass, inertia) and re-tare a payload file: ``ftcal payload``.

:func:`identify_payload` and :func:`retare` take CSV/Parquet paths (or DataFrames) and the keywords of the
command's flags, keep only the static samples by default (as the command does), and return a
:class:`PayloadResult` / :class:`RebiasResult` whose ``summary()`` is the text the command prints
and whose ``save(path)`` writes the payload file.
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from dataclasses import dataclass, field, replace

import numpy as np

from .arguments import PAYLOAD, REBIAS, check_arguments
from ..runtime.deprecation import deprecated_alias, renamed_keyword
from ..runtime.errors import FtcalError, ParameterError
from .result import StepResult
from .sources import DEFAULT_WRENCH, gravity_source, reads_tables, source_options

MAX_GROUPS_PRINTED = 8
# A re-tared bias further than this many standard errors from the identified one is drift, not noise.
REBIAS_SIGNIFICANT = 3.0
AXIS_NAMES = ("Fx", "Fy", "Fz", "Tx", "Ty", "Tz")
# The column `ftcal dataset` writes: the still pose's number (-1 moving); the default validation groups.
HOLD_COLUMN = "hold"


class StaticRows:
    """The ``select`` of :func:`ftcal.payload.tables.read_payload_tables`: the static rows of each table.

    Motion is read from the ``orientation`` quaternion columns, else from the joint columns of a
    robot model (``joints``), else from the gravity direction, over the ``time`` column (default
    ``time``); a table without that column keeps the samples its ``static`` column marks still
    (written by ``ftcal dataset``), else is used whole (said in :attr:`notes`, one line per table).

    Parameters
    ----------
    source : KinematicsSource
    time : time column, s (None: ``time``)
    orientation : quaternion columns, or None
    joints : whether gravity comes from a robot model and its joint columns
    degrees : the joint columns are in degrees
    """

    def __init__(self, source, *, time: str | None = None, orientation: Sequence[str] | None = None,
                 joints: bool = False, degrees: bool = False) -> None:
        self.source = source
        self.time = time
        self.orientation = None if orientation is None else tuple(orientation)
        self.joints = joints
        self.degrees = degrees
        self.notes: list[str] = []

    def __call__(self, frame, kinematics, path: str):
        from pathlib import Path

        from ..data.holds import MIN_HOLD_S, find_holds
        from ..data.tables import numeric_columns

        time_column = self.time or "time"
        if time_column not in frame.columns and "static" in frame.columns:
            # The marks `ftcal dataset` wrote (data.holds, from the same signals), for a table without its clock.
            marks = numeric_columns(frame, ("static",), Path(path), "static")[:, 0]
            if not np.all((marks == 0) | (marks == 1)):
                raise FtcalError(f"{path}: column 'static' must hold 1 (still) or 0 (moving).")
            static = marks == 1
            if not static.any():
                raise ParameterError('keep_moving',
                                     f"{path}: column 'static' marks no sample still; give {{keep_moving}} to use "
                                 "every sample.")
            moving = int(static.size - np.count_nonzero(static))
            self.notes.append(f"{path}: no time column {time_column!r}: its 'static' column marks {moving} of "
                              f"{static.size} samples moving; " + ("excluded" if moving else "all used")
                              + " (--keep-moving keeps them)")
            return static
        if time_column not in frame.columns:
            self.notes.append(f"{path}: no time column {time_column!r}: all {len(frame)} samples used as static "
                              "(give --time COL to find and drop the moving ones)")
            return None
        time = numeric_columns(frame, (time_column,), Path(path), "time")[:, 0]
        segments = frame["segment"].to_numpy() if "segment" in frame.columns else None
        signal = {}
        if self.orientation is not None:
            signal["orientation"] = numeric_columns(frame, self.orientation, Path(path), "orientation")
        elif self.joints:
            names = set(self.source.columns)
            joints = numeric_columns(frame, [c for c in frame.columns if c in names], Path(path), "joint")
            signal["joints"] = np.deg2rad(joints) if self.degrees else joints
        else:
            signal["gravity"] = kinematics.gravity
        holds = find_holds(time, segments=segments, where=path, time_column=time_column, **signal)
        if not holds.static.any():
            raise ParameterError('keep_moving',
                                 f"{path}: no static hold of {MIN_HOLD_S:g} s or more (every sample moves, from the "
                             f"{holds.signal}); record still poses, or give {{keep_moving}} to use every sample.")
        self.notes.append(f"{path}: {holds.describe(time)}; "
                          + ("excluded" if holds.n_moving else "all used") + " (--keep-moving keeps them)")
        return holds.static


@dataclass(frozen=True)
class PayloadExcitation:
    """How far the poses determine the payload's parameters (:func:`~ftcal.core.excitation.regressor_excitation`).

    Attributes
    ----------
    singular_values : ndarray, of the payload regressor with columns scaled to unit norm, relative, descending
    n_determined : int, the directions at or above :data:`~ftcal.core.excitation.UNEXCITED`
    """

    singular_values: np.ndarray
    n_determined: int

    def summary(self) -> str:
        """One line: the relative singular values, and how many directions they determine."""
        return (f"excitation: the poses determine {self.n_determined} of {len(self.singular_values)} parameter "
                f"directions (relative singular values of the payload regressor, columns scaled to unit norm: "
                f"{', '.join(f'{v:.2g}' for v in self.singular_values)})")


def payload_excitation(groups) -> PayloadExcitation:
    """The excitation of the payload regressor summed over ``groups`` (group -> its statistics)."""
    from ..core.excitation import regressor_excitation

    total = None
    for stats in groups.values():
        total = stats if total is None else total + stats
    singular, n_determined = regressor_excitation(total.gram())
    return PayloadExcitation(singular, n_determined)


def _axes(values, per: str = "") -> str:
    units = ("N", "N", "N", "N·m", "N·m", "N·m")
    return "  ".join(f"{a} {v:+.4g} {u}{per}" for a, v, u in zip(AXIS_NAMES, values, units))


def _default_groups(paths: list[str]) -> str | None:
    """``hold`` when every table has the column `ftcal dataset` writes, else None (one group per file)."""
    from ..data.table_chunks import table_has_columns

    return HOLD_COLUMN if all(table_has_columns(p, [HOLD_COLUMN]) for p in paths) else None


@dataclass(repr=False)
class PayloadResult(StepResult):
    """What :func:`identify_payload` found: the fit, its bias model, and the payload file's content.

    Attributes
    ----------
    payload : PayloadParameters, what ``save`` writes
    fit : PayloadFit, the chosen model's fit (mass, com, bias, standard errors, cross-validation)
    drift : DriftResult, the bias model and its comparison with a constant bias
    excitation : PayloadExcitation, how well the poses determine the parameters (one line of the text)
    notes : list of str, how the samples and groups were chosen (printed first)
    sources : list of str, the tables

    Examples
    --------
    ``identify_payload`` makes it (see its example); its text is what ``ftcal payload`` prints:

    >>> import numpy as np, pandas as pd, tempfile, os
    >>> from scipy.spatial.transform import Rotation
    >>> rotations = Rotation.random(10, random_state=2)
    >>> force = 0.5 * rotations.inv().apply([0.0, 0.0, -9.81])     # a 0.5 kg tool at the sensor origin
    >>> table = pd.DataFrame(np.c_[force, np.zeros((10, 3)), rotations.as_quat()],
    ...                      columns=["u1", "u2", "u3", "u4", "u5", "u6", "qx", "qy", "qz", "qw"])
    >>> path = os.path.join(tempfile.mkdtemp(), "poses.csv")
    >>> table.to_csv(path, index=False)
    >>> result = identify_payload(path, orientation=("qx", "qy", "qz", "qw"))
    >>> isinstance(result, PayloadResult), round(result.mass, 6)
    (True, 0.5)
    """

    payload: object
    fit: object
    drift: object
    excitation: PayloadExcitation
    notes: list[str] = field(default_factory=list)
    sources: list[str] = field(default_factory=list)
    scale: tuple[float, float] | None = None  # RMS of the force and torque readings: what the figures are stated to

    @property
    def mass(self) -> float:
        """Identified mass, kg."""
        return float(self.fit.mass)

    @property
    def com(self) -> np.ndarray:
        """Centre of mass in the sensor frame, m, shape (3,)."""
        return np.asarray(self.fit.com)

    def summary(self) -> str:
        return "\n".join([*self.notes, *_fit_lines(self.fit, self.drift.n_groups, self.payload.gravity, self.scale),
                          gain_note(self.fit.mass, self.fit.stderr["mass"]), *_drift_lines(self.drift),
                          self.excitation.summary()])

    def to_dict(self) -> dict:
        from .result import plain

        fit = self.fit
        out = {"mass": fit.mass, "com": fit.com, "force_bias": fit.force_bias, "torque_bias": fit.torque_bias,
               "inertia": fit.inertia, "stderr": dict(fit.stderr), "n_samples": fit.n_samples,
               "n_groups": self.drift.n_groups, "gravity": self.payload.gravity, "residual_rms": fit.residual_rms,
               "condition_number": fit.condition_number, "weighting": fit.weighting,
               "bias_model": "none" if self.drift.drift is None else self.drift.drift.model,
               "excitation": {"singular_values": self.excitation.singular_values,
                              "n_determined": self.excitation.n_determined},
               "notes": list(self.notes), "sources": list(self.sources)}
        return plain(out)

    def save(self, path) -> None:
        """Write the payload file (atomically), for ``ftcal compensate`` and ``ftcal convert``."""
        from ..files.payload_json import save_payload

        save_payload(self.payload, path, sources=self.sources)


# The relative gain error the printout converts into a mass shift (1 %: a gain a workbench calibration can miss).
GAIN_EXAMPLE = 0.01


def gain_note(mass: float, mass_se: float) -> str:
    """One line: the standard errors assume a right gain, and how a relative gain error e moves the mass.

    A wrench read (1 + e) times too large is fitted by (1 + e) times the mass, bias and first moment
    (the model is linear in them), so the mass moves by e·m, the centre of mass not at all when forces and
    torques share the error; no standard error computed from the residuals can see it.
    """
    shift = GAIN_EXAMPLE * mass
    ratio = ""
    if np.isfinite(mass_se) and mass_se > 0:
        # beyond a thousand the count says only "far beyond", and on a noiseless fit it is rounding's quotient
        times = shift / mass_se
        ratio = f", {times:.2g} of its standard errors" if times < 1000 else ", over 1000 of its standard errors"
    return (f"gain: the standard errors assume the sensor's gain is right; a relative gain error e moves the mass "
            f"by about e·m = {mass:.4g} kg × e ({100 * GAIN_EXAMPLE:g} %: {shift:.2g} kg{ratio}) and the bias by "
            "e × the bias; the centre of mass does not move when forces and torques share the error")


def _with_gain_note(payload):
    """The payload file's ``fit.standard_errors`` with the gain assumption said (the file says it too)."""
    fit = dict(payload.fit)
    fit["standard_errors"] = (f"{fit.get('standard_errors') or 'classical'}; assume the sensor's gain is right: a "
                              f"relative gain error e moves the mass by about e*m = {payload.mass:.4g} kg * e")
    return replace(payload, fit=fit)


def calibrated_tables(data, calibration, notes: list[str]) -> tuple[dict, tuple[str, ...]]:
    """The tables with the calibrated wrench added: ({name: DataFrame}, the six calibrated columns).

    ``calibration`` (a model file or fitted static model with six outputs) is applied to its input
    columns of each table; the result is stored as ``<output>_calibrated`` beside the raw columns.
    """
    from ..data.tables import numeric_columns, read_table
    from .evaluation import _model_and_segments

    model, _, name = _model_and_segments(calibration)
    if not model.is_static or len(model.output_names_) != 6:
        raise ParameterError("calibration", f"{{calibration}} {name}: needs a static model with six outputs (a wrench); it has "
                         f"{len(model.output_names_)} output(s)" + ("" if model.is_static else " and ARX lags") + ".")
    columns = tuple(f"{o}_calibrated" for o in model.output_names_)
    frames = {}
    for path, source in zip(data.paths, data.sources):
        from pathlib import Path

        frame = read_table(path)
        u = numeric_columns(frame, model.input_names_, Path(source), "calibration input")
        wrench = model.predict(u, warn_out_of_range=False)
        frames[source] = frame.assign(**{c: wrench[:, j] for j, c in enumerate(columns)})
    notes.append(f"wrench: {name} applied to {','.join(model.input_names_)} (columns {','.join(columns)})")
    return frames, columns


@reads_tables()
def identify_payload(data, *, inputs: Sequence[str] = DEFAULT_WRENCH, group_by: str | None = None,
                     keep_moving: bool = False, reaction: bool = False, frame: str | None = None,
                     bias_drift: str = "auto", temperature: str | None = None, output=None,
                     calibration=None, **source) -> PayloadResult:
    """Identify the sensor bias and the tool's mass, centre of mass (and inertia): ``ftcal payload``.

    Parameters
    ----------
    data : path, list of paths, DataFrame, list or dict of DataFrames, or Dataset
        CSV or Parquet tables, one row per sample; or the same tables in memory (a dict names them,
        e.g. ``{"run1": frame}``; a :class:`~ftcal.workflow.datasets.DatasetResult`, such as a bag's
        dataset, is taken as its table; a Dataset as one table per segment of its input and output
        columns). The numbers are those of the same tables read from Parquet files. There is no
        ``executor``: the tables are read and summed in this process (``ftcal payload`` has no
        ``--scheduler``).
    inputs : six measured-wrench columns, N and N·m (``wrench=``, the old spelling, still works)
    group_by : str or None
        Column naming the cross-validation groups. Default: the ``hold`` column of ``ftcal dataset``
        (one group per still pose) when every table has it and the model is static, else one group per file.
    keep_moving : use every sample (default: only the static holds, as the command)
    reaction : the sensor reports the opposite sign: negate the readings
    frame : sensor frame name stored in the payload file
    bias_drift : {"auto", "none", "linear", "random-walk"}
    temperature : column the bias is also affine in
    output : path or None; when given, the payload file is written there
    calibration : model file or fitted static model, optional
        Identify on the calibrated wrench: the model is applied to its input columns (the raw channels)
        first, and ``inputs`` is not used.
    **source
        The gravity source: ``orientation``, ``gravity_columns``, ``g``, ``urdf``, ``robot``, ``sensor``,
        ``ft_joint``, ``ft_frame``, ``base``, ``degrees``, ``dynamic``, ``angular_velocity``,
        ``linear_acceleration``, ``angular_acceleration``, ``time`` (see ``ftcal payload --help``).

    Returns
    -------
    PayloadResult

    Raises
    ------
    FtcalError
        Bad input (missing columns, no still sample, an unknown option) or a mass that is not positive.

    Examples
    --------
    >>> import numpy as np, pandas as pd, tempfile, os
    >>> from scipy.spatial.transform import Rotation
    >>> rotations = Rotation.random(12, random_state=1)
    >>> gravity = rotations.inv().apply([0.0, 0.0, -9.81])         # in the sensor frame
    >>> com = np.array([0.01, -0.02, 0.05])
    >>> wrench = np.c_[2.0 * gravity, np.cross(com, 2.0 * gravity)]  # a 2 kg tool, no bias
    >>> table = pd.DataFrame(np.c_[wrench, rotations.as_quat()], columns=["u1", "u2", "u3", "u4", "u5", "u6",
    ...                                                                  "qx", "qy", "qz", "qw"])
    >>> path = os.path.join(tempfile.mkdtemp(), "poses.csv")
    >>> table.to_csv(path, index=False)
    >>> result = identify_payload(path, orientation=("qx", "qy", "qz", "qw"))
    >>> round(result.mass, 6)
    2.0
    """
    check_arguments(PAYLOAD, locals(), "ftcal.identify_payload")
    from ..check.conventions import ConventionWarning, HoldCollector, payload_warning
    from ..core.limits import BIAS_DRIFTS
    from ..files.payload_json import save_payload
    from ..payload.identify import check_mass_sign
    from ..payload.parameters import PayloadParameters
    from ..payload.tables import group_statistics, identify_recording, read_payload_tables

    wrench = renamed_keyword(source, "wrench", "inputs", inputs, DEFAULT_WRENCH)
    if calibration is not None:
        if tuple(wrench) != DEFAULT_WRENCH:
            raise ParameterError(("inputs", "calibration"),
                                 "{inputs} does not go with {calibration}: the model names its input columns.")
        calibrated: list[str] = []
        frames, columns = calibrated_tables(data, calibration, calibrated)
        result = identify_payload(frames, inputs=columns, group_by=group_by, keep_moving=keep_moving,
                                  reaction=reaction, frame=frame, bias_drift=bias_drift, temperature=temperature,
                                  output=output, **source)
        result.notes[:0] = calibrated
        return result
    paths, names = data.paths, data.sources
    options = source_options(source, "identify_payload")
    if bias_drift not in BIAS_DRIFTS:
        raise FtcalError(f"bias_drift {bias_drift!r}: must be one of {', '.join(BIAS_DRIFTS)}.")
    dynamic, time = options["dynamic"], options["time"]
    if time is None and bias_drift in ("linear", "random-walk"):
        from ..data.table_chunks import table_has_columns

        # As --time's help says: the column 'time' where every table has one.
        if not all(table_has_columns(path, ["time"]) for path in paths):
            raise ParameterError(('bias_drift', 'time'),
                                 f"{{bias_drift}} {bias_drift} needs the time column and {', '.join(paths)} "
                             "has none named 'time': give {time} COL.")
        time = options["time"] = "time"
    if dynamic and bias_drift in ("linear", "random-walk"):
        raise ParameterError(('bias_drift', 'dynamic'),
                             f"{{bias_drift}} {bias_drift} works with static poses only; leave out {{dynamic}} "
                         "or use {bias_drift} none.")
    gravity_from = gravity_source(options)
    static = None if dynamic or keep_moving else StaticRows(
        gravity_from, time=time, orientation=options["orientation"],
        joints=options["urdf"] is not None or options["robot"] is not None, degrees=options["degrees"])
    notes = []
    if group_by is None and static is not None:
        group_by = _default_groups(paths)
        if group_by is not None:
            notes.append(f"groups: the tables' {HOLD_COLUMN!r} column (one per still pose, from ftcal dataset; "
                         "--group-by COL for another)")
    # The convention check's holds are taken from the tables as the fit reads them (one read).
    holds = HoldCollector(gravity_from, static, wrench=wrench, reaction=reaction, time=time)
    recording = read_payload_tables(paths, gravity_from, wrench=wrench, group_by=group_by, reaction=reaction,
                                    time=time, temperature=temperature, select=holds)
    if group_by is None:  # one group per table: named as the caller named it
        recording = replace(recording, labels=data.named_labels(recording.labels))
    notes[:0] = [f"static samples: {data.named(line)}" for line in (() if static is None else static.notes)]
    result = identify_recording(recording, bias_drift=bias_drift, dynamic=dynamic, time_column=time,
                                temperature_column=temperature)
    fit = result.fit
    message = data.named(payload_warning(names, gravity_from, fit, options["g"], wrench=wrench, reaction=reaction,
                                         time=time, holds=holds))
    if message:  # the fit looks like a sign/frame/zeroing mistake: ftcal check's tests on the static holds
        warnings.warn(message, ConventionWarning, stacklevel=2)
    check_mass_sign(fit)
    excitation = payload_excitation(group_statistics(recording, dynamic=dynamic))
    payload = _with_gain_note(PayloadParameters.from_fit(fit, gravity=options["g"], frame=frame, reaction=reaction,
                                                         wrench_columns=tuple(wrench), drift=result.drift))
    measured = np.asarray(recording.measured, dtype=float)
    scale = tuple(float(np.sqrt(np.mean(measured[:, block] ** 2))) for block in (slice(0, 3), slice(3, 6)))
    # the file states the residual RMS as the text does
    payload = replace(payload, fit={**payload.fit, "residual_rms": stated_rms(payload.fit["residual_rms"], scale)})
    out = PayloadResult(payload, fit, result, excitation, notes, names, scale)
    if output is not None:
        save_payload(payload, output, sources=names)
    return out


def stated_rms(values, scale: tuple[float, float] | None) -> np.ndarray:
    """Residual RMS per axis (6,) stated to :data:`~ftcal.core.precision.SCORE` of ``scale``, the RMS of the
    force and of the torque readings: figures from sums of squares that cancel (a noiseless fit's Fx 1.9e-07
    is 0); unchanged when ``scale`` is None."""
    from ..core.precision import SCORE, settle

    values = np.asarray(values, dtype=float)
    if scale is None:
        return values
    return np.array([settle(v, SCORE, b) for v, b in zip(values, np.repeat(scale, 3))])


def _fit_lines(fit, n_groups: int, g: float, scale: tuple[float, float] | None = None) -> list[str]:
    from ..core.precision import SOLUTION, settle
    from ..payload.identify import AXES

    unit = {"mass": "kg", "com": "m", "force_bias": "N", "torque_bias": "N·m", "inertia": "kg·m²"}
    kind = "dynamic (inertia included)" if fit.dynamic else "static"
    lines = [f"payload from {fit.n_samples} samples in {n_groups} group(s), {kind} model, gravity {g:g} m/s²"]
    # Each estimate stated to SOLUTION of what it explains of the readings (forces RMS, torques RMS), so a
    # component that is 0 in exact arithmetic (noiseless data, a tool on the axis) prints 0 on every CPU.
    force, torque = scale if scale is not None else (None, None)
    of = {"mass": None if force is None else force / g,
          "com": None if torque is None else torque / max(abs(fit.mass) * g, 1e-300),
          "force_bias": force, "torque_bias": torque, "inertia": None}

    def line(name, value, se, unit_name, key):
        if np.isnan(se):  # the poses do not determine it: the file holds a convention, not an estimate
            return f"  {name:<14}{'undetermined':>14} (file: {settle(value, SOLUTION, of[key]):.6g} {unit_name} by convention)"
        value, se = settle(value, SOLUTION, of[key]), settle(se, SOLUTION, of[key])
        return f"  {name:<14}{value:>14.6g} ± {se:.2g} {unit_name}"

    lines.append(line("mass", fit.mass, fit.stderr["mass"], unit["mass"], "mass"))
    for key in ("com", "force_bias", "torque_bias"):
        for axis, value, se in zip("xyz", getattr(fit, key), fit.stderr[key]):
            lines.append(line(key.replace("_", " ") + " " + axis, value, se, unit[key], key))
    if fit.dynamic:
        for (i, j) in ((0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2)):
            name = "I" + "xyz"[i] + "xyz"[j] + " (com)"
            lines.append(line(name, fit.inertia[i, j], fit.stderr["inertia"][i, j], unit["inertia"], "inertia"))
    if fit.undetermined is not None:
        lines.append(f"undetermined: {fit.undetermined.message}")
    def rms(values) -> np.ndarray:
        return stated_rms(values, scale)

    residual = rms(fit.residual_rms)
    lines.append("residual RMS: " + "  ".join(f"{a} {v:.4g}" for a, v in zip(AXES, residual)) + "  (N, N·m)")
    if fit.cross_validation:
        scored = [g for g in fit.cross_validation if g.rms is not None]
        if scored:
            pooled = np.sqrt(sum(g.n_samples * g.rms ** 2 for g in scored) / sum(g.n_samples for g in scored))
            lines.append("cross-validated residual RMS (each group left out of the fit in turn): "
                         + "  ".join(f"{a} {v:.4g}" for a, v in zip(AXES, rms(pooled))))
        # The groups that fit worst when left out come first: they are the suspicious poses (ranked by the
        # stated figures, so rounding noise on an exactly fitted axis orders nothing).
        held = {id(g): None if g.rms is None else rms(g.rms) for g in fit.cross_validation}
        with np.errstate(over="ignore", invalid="ignore"):  # an axis fitted exactly (residual 0): inf, 0/0 ignored
            ranked = sorted(fit.cross_validation, key=lambda g: -np.inf if g.rms is None else -float(
                np.nansum((held[id(g)] / np.maximum(residual, 1e-300)) ** 2)))
        for g in ranked[:MAX_GROUPS_PRINTED]:
            text = ("not identifiable without this group" if g.rms is None
                    else "  ".join(f"{a} {v:.4g}" for a, v in zip(AXES, held[id(g)])))
            lines.append(f"  {g.group} ({g.n_samples} samples): {text}")
        if len(ranked) > MAX_GROUPS_PRINTED:
            lines.append(f"  ... {len(ranked) - MAX_GROUPS_PRINTED} more group(s) fit better")
    else:
        lines.append("cross-validation: one group only (give several files or --group-by COL)")
    lines.append(f"weighting: {fit.weighting} ({fit.weighting_evidence}); standard errors: {fit.stderr_kind}")
    lines.append(f"condition number of the weighted regressor: {fit.condition_number:.3g}"
                 + ("" if not fit.poorly_excited else f"; poorly excited: {', '.join(fit.poorly_excited)}"))
    return lines


def _drift_lines(result) -> list[str]:
    """What drift was found, and how much modelling it moved mass and centre of mass."""
    drift = result.drift
    if drift is None:
        return []
    lines = [f"bias model: {drift.model} ({result.selection})" if result.selection else f"bias model: {drift.model}"]
    if drift.temperature_coefficients is not None:
        lines.append(f"  bias per unit of {drift.temperature_column}: " + _axes(drift.temperature_coefficients))
    verdict = result.verdict()
    if result.change is None:
        return lines + ([verdict] if verdict else [])
    hours = max(result.hours, 1e-300)
    lines.append(f"  bias change over the recording ({result.hours * 60:.3g} min): " + _axes(result.change))
    lines.append("  drift rate: " + _axes(result.change / hours, "/h"))
    if result.walk_std is not None:
        lines.append("  random-walk std: " + _axes(result.walk_std, "/√h"))
    fit, constant = result.fit, result.constant
    dm = fit.mass - constant.mass
    dc = 1000.0 * (fit.com - constant.com)
    lines.append(f"  vs a constant bias: mass {dm:+.4g} kg ({dm / max(constant.stderr['mass'], 1e-300):+.2g} of its "
                 f"standard error, {100 * dm / constant.mass:+.2g} %), centre of mass "
                 + " ".join(f"{a} {v:+.3g}" for a, v in zip("xyz", dc)) + " mm")
    return lines + ([verdict] if verdict else [])


def identified_bias(payload, time):
    """The payload file's bias to compare a re-tare with, shape (6,): its trajectory averaged over ``time``
    when it drifts in time (so its own recording is compared like for like), else its constant bias."""
    drift = payload.drift
    if drift is None or drift.knot_times is None or time is None:
        return payload.bias
    return np.array([np.interp(time, drift.knot_times, drift.knot_bias[:, j]).mean() for j in range(6)])


@dataclass(repr=False)
class RebiasResult(StepResult):
    """What :func:`retare` found: the new bias, its change since identification, the updated file.

    Attributes
    ----------
    payload : PayloadParameters, the updated payload file's content (``save`` writes it)
    bias, stderr, change, z : ndarray of shape (6,)
        New bias (N, N·m), its standard error, the change since identification and that change in
        combined standard errors (NaN where the identification left the bias undetermined).
    drift_rate : ndarray of shape (6,) or None, per hour since the identification's recording ended
    hours : float or None, hours from the identification's recording's end to this one's mean time
    n_samples : int, the samples the bias was re-estimated from
    stderr_kind : str, how the new bias's standard errors were found
    notes : list of str, how the static samples were chosen (printed first)
    sources : list of str, the payload file, then the tables
    """

    payload: object
    bias: np.ndarray
    stderr: np.ndarray
    change: np.ndarray
    z: np.ndarray
    drift_rate: np.ndarray | None
    sources: list[str] = field(default_factory=list)
    n_samples: int = 0
    stderr_kind: str = ""
    hours: float | None = None
    notes: list[str] = field(default_factory=list)

    @property
    def drifted(self) -> list[str]:
        """The axes whose bias moved by more than :data:`REBIAS_SIGNIFICANT` combined standard errors."""
        return [a for a, zi in zip(AXIS_NAMES, self.z) if abs(zi) > REBIAS_SIGNIFICANT]

    def summary(self) -> str:
        name = self.sources[0] if self.sources else "the payload file"
        lines = list(self.notes)
        lines.append(f"bias re-estimated from {self.n_samples} samples with mass {self.payload.mass:.6g} kg and the "
                     f"centre of mass of {name} held fixed ({self.stderr_kind})")
        for a, new, se, d, zi in zip(AXIS_NAMES, self.bias, self.stderr, self.change, self.z):
            unit = "N" if a[0] == "F" else "N·m"
            if np.isnan(zi):  # undetermined at identification: the value follows the file's convention
                lines.append(f"  {a + ' bias':<10}{new:>12.6g} {unit}   undetermined by the identification poses "
                             f"(consistent with {name}'s convention; change {d:+.4g} {unit} not comparable)")
                continue
            lines.append(f"  {a + ' bias':<10}{new:>12.6g} ± {se:.2g} {unit}   change since identification "
                         f"{d:+.4g} {unit} ({zi:+.1f} standard errors)")
        if self.drift_rate is not None:
            lines.append(f"  drift rate since identification ({self.hours:.3g} h): " + _axes(self.drift_rate, "/h"))
        else:
            lines.append("  drift rate: unknown (needs --time, and a payload file whose recording ended before this "
                         "one)")
        if self.drifted:
            lines.append("  the bias moved more than the identification's uncertainty explains "
                         f"({REBIAS_SIGNIFICANT:g} standard errors) on {', '.join(self.drifted)}: the sensor drifted; "
                         "compensate with the new file")
        else:
            lines.append("  the change is within what the identification's uncertainty explains")
        return "\n".join(lines)

    def to_dict(self) -> dict:
        from .result import plain

        return plain({"bias": self.bias, "stderr": self.stderr, "change": self.change, "z": self.z,
                      "drift_rate": self.drift_rate, "hours": self.hours, "drifted": self.drifted,
                      "n_samples": self.n_samples, "mass": self.payload.mass, "com": self.payload.com,
                      "notes": self.notes, "sources": self.sources})

    def save(self, path) -> None:
        """Write the updated payload file (atomically)."""
        from ..files.payload_json import save_payload

        save_payload(self.payload, path, sources=self.sources)


@reads_tables()
def retare(payload, data, *, inputs: Sequence[str] = DEFAULT_WRENCH, keep_moving: bool = False,
                   reaction: bool = False, temperature: str | None = None, output=None,
                   **source) -> RebiasResult:
    """Re-tare: the bias alone from new data, mass and centre of mass from a payload file (``payload --rebias``).

    Parameters
    ----------
    payload : path of the payload file (``ftcal payload -o``)
    data : path, list of paths, DataFrame, list or dict of DataFrames, or Dataset
        Contact-free CSV/Parquet tables, or the same in memory (as :func:`identify_payload`; no
        ``executor`` either).
    inputs, keep_moving, reaction, **source : as :func:`identify_payload`
    temperature : must be the payload file's temperature column, or None (taken from the file)
    output : path or None; when given, the updated payload file is written there

    Returns
    -------
    RebiasResult

    Raises
    ------
    FtcalError
        Bad input, or a sign convention or temperature column that differs from the file's.
    """
    check_arguments(REBIAS, locals(), "ftcal.workflow.retare")
    from ..files.payload_json import load_payload, save_payload
    from ..payload.drift import BiasDrift
    from ..payload.tables import read_payload_tables, rebias

    wrench = renamed_keyword(source, "wrench", "inputs", inputs, DEFAULT_WRENCH)
    paths, names = data.paths, data.sources
    options = source_options(source, "retare")
    name = str(payload)
    identified = load_payload(payload)
    if reaction != identified.reaction:
        raise ParameterError('reaction',
                             f"{{reaction}}: {name} was identified {'with' if identified.reaction else 'without'} "
                         "{reaction}; give the same sign convention.")
    own_temperature = identified.drift.temperature_column if identified.needs_temperature else None
    if temperature is not None and temperature != own_temperature:
        raise ParameterError(('temperature', 'rebias'), f"{{temperature}} {temperature}: {name} has "
                         + (f"its temperature term on column {own_temperature!r}" if own_temperature
                            else "no temperature term") + "; {rebias} uses the file's; leave it out.")
    gravity_from = gravity_source(options)
    # Like the identification: only the still samples (moving ones carry inertial forces the model lacks).
    static = None if keep_moving else StaticRows(
        gravity_from, time=options["time"], orientation=options["orientation"],
        joints=options["urdf"] is not None or options["robot"] is not None, degrees=options["degrees"])
    recording = read_payload_tables(paths, gravity_from, wrench=wrench, reaction=identified.reaction,
                                    time=options["time"], temperature=own_temperature, select=static)
    notes = [f"static samples: {data.named(line)}" for line in (() if static is None else static.notes)]
    found = rebias(recording, identified)
    old = identified_bias(identified, recording.time)
    old_se = np.r_[identified.stderr["force_bias"], identified.stderr["torque_bias"]]
    change = found.bias - old
    z = change / np.sqrt(found.stderr ** 2 + old_se ** 2)
    end = identified.drift.time_end if identified.drift is not None else None
    rate = hours = None
    if recording.time is not None and end is not None and recording.time[0] > end:
        hours = (float(np.mean(recording.time)) - end) / 3600.0
        rate = change / hours
    t = recording.time
    drift = BiasDrift("none", options["time"] if t is not None else None, None if t is None else float(t[0]),
                      None if t is None else float(t[-1]),
                      temperature_column=own_temperature,
                      temperature_reference=identified.drift.temperature_reference if own_temperature else None,
                      temperature_coefficients=identified.drift.temperature_coefficients if own_temperature else None,
                      selection=f"re-tared from {', '.join(names)}")
    new_se = np.where(np.isnan(old_se), np.nan, found.stderr)  # still undetermined where it was
    stderr = dict(identified.stderr, force_bias=new_se[:3], torque_bias=new_se[3:])
    updated = replace(identified, force_bias=found.bias[:3], torque_bias=found.bias[3:], stderr=stderr, drift=drift)
    out = RebiasResult(updated, found.bias, found.stderr, change, z, rate, [name, *names], recording.n_samples,
                       found.stderr_kind, hours, notes)
    if output is not None:
        save_payload(updated, output, sources=out.sources)
    return out


def _rebias_payload(data, payload, **keywords) -> RebiasResult:
    return retare(payload, data, **keywords)


# The old name and order (data first): the payload is the step's subject, as in compensate(payload, data).
rebias_payload = deprecated_alias(_rebias_payload, "ftcal.workflow.rebias_payload(data, payload)",
                                  "ftcal.workflow.retare(payload, data)")
