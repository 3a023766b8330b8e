"""Check a sensor's conventions, test a calibration for acceptance, read a sensor's history: ``ftcal check``.

:func:`check_sensor` runs the conventions check on a recording of static holds, or (with ``accept=``) the
acceptance test of a calibration model; :func:`sensor_history` reads the per-sensor history.
Each returns a :class:`CheckResult` whose ``summary()`` is what the command prints and whose
``passed`` decides its exit code.
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from dataclasses import dataclass, field, replace

import numpy as np

from .arguments import CHECK, check_arguments
from ..core.limits import HOLD_SAMPLE_RATE, MAX_COM_DISTANCE, MAX_FORCE_ERROR, MAX_TORQUE_ERROR
from ..runtime.deprecation import renamed_keyword
from ..runtime.errors import FtcalError, ParameterError
from .result import StepResult
from .sources import DEFAULT_WRENCH, gravity_source, reads_tables, source_options

MAX_POSES_PRINTED = 8


@dataclass(frozen=True)
class ConventionsRun:
    """What the conventions check's text takes beside its report.

    Attributes
    ----------
    n_holds : int, the static holds read
    scales : (float, float), RMS of the force and torque readings: the residuals are stated to
        :data:`~ftcal.core.precision.SOLUTION` of them (a fit of exactly zero torques prints 0 N·m)
    reaction : bool, the sign declared (a fix that adds ``--reaction`` then says to leave it out)
    notes : tuple of str, the report's notes with the tables' names
    """

    n_holds: int
    scales: tuple[float, float]
    reaction: bool = False
    notes: tuple[str, ...] = ()

    def stated(self, pair) -> tuple[float, float]:
        """(force, torque) residuals stated to the readings' precision."""
        from ..core.precision import SOLUTION, settle

        return tuple(settle(v, SOLUTION, scale) for v, scale in zip(pair, self.scales))


@dataclass(frozen=True)
class AcceptanceRun:
    """What the acceptance test's text takes beside its result (which holds the errors and thresholds).

    Attributes
    ----------
    model_name : str, the model file tested
    retare : str or None, the re-tare verdict of a failed test (:func:`ftcal.check.accept.retare_verdict`)
    recorded : (str, str, int) or None, the history file, the sensor serial and its calibrations recorded
    """

    model_name: str
    retare: str | None = None
    recorded: tuple[str, str, int] | None = None


@dataclass(frozen=True)
class HistoryRun:
    """What a sensor's history text takes beside its calibration records: its acceptance tests and drift."""

    serial: str
    acceptances: tuple = ()
    drift: object = None


@dataclass(repr=False)
class CheckResult(StepResult):
    """What a check found: whether it passed, the report object behind it; :meth:`summary` renders the text.

    Attributes
    ----------
    mode : {"conventions", "acceptance", "history"}
    passed : bool, no finding (conventions) / the calibration passes (acceptance)
    report : the check's own report (``ConventionReport``, ``AcceptanceResult`` or the history's records)
    written : list of str, files written (HTML page)
    run : ConventionsRun, AcceptanceRun or HistoryRun
        The mode's other numbers the text states (holds, thresholds, history).

    Examples
    --------
    >>> result = CheckResult("history", True, [], run=HistoryRun("FT-1"))
    >>> result.exit_code, result.summary().splitlines()[0]
    (0, 'sensor FT-1: 0 calibration(s), 0 acceptance test(s)')
    """

    mode: str
    passed: bool
    report: object
    written: list[str] = field(default_factory=list)
    run: object = None

    @property
    def exit_code(self) -> int:
        """0 no finding / pass, 1 findings / fail (the command's exit code)."""
        return 0 if self.passed else 1

    @property
    def lines(self) -> list[str]:
        """The text of :meth:`summary`, line by line."""
        return self.summary().split("\n")

    def summary(self) -> str:
        render = {"conventions": _conventions_lines, "acceptance": _acceptance_lines, "history": _history_lines}
        return "\n".join(render[self.mode](self.report, self.run))

    def to_dict(self) -> dict:
        from .result import plain

        out = {"mode": self.mode, "passed": self.passed, "written": self.written}
        report = self.report
        if self.mode == "conventions":
            out.update(mass=report.mass, mass_stderr=report.mass_stderr, residual=report.residual,
                       findings=[{"kind": f.kind, "confidence": f.confidence, "message": f.message, "fix": f.fix,
                                  "before": f.before, "after": f.after} for f in report.findings],
                       notes=list(report.notes))
        elif self.mode == "acceptance":
            out.update(outputs=list(report.outputs), rmse=report.rmse, max_abs_error=report.max_abs_error,
                       n_poses=len(report.poses), failed_poses=[p.label for p in report.failed_poses],
                       channel_issues=list(report.channel_issues), problems=list(report.problems))
        return plain(out)


@reads_tables()
def check_sensor(data, *, accept=None, inputs: Sequence[str] = DEFAULT_WRENCH, group_by: str | None = None,
          rate: float = HOLD_SAMPLE_RATE, reaction: bool = False, max_com_distance: float = MAX_COM_DISTANCE,
          html=None, payload_json=None, max_force_error: float | None = None,
          max_torque_error: float | None = None, max_error_percent: float | None = None,
          rated_force: float | None = None, rated_torque: float | None = None, serial: str | None = None,
          history_dir=None, **source) -> CheckResult:
    """Check conventions on static holds, or (``accept=MODEL``) a calibration's acceptance: ``ftcal check``.

    Parameters
    ----------
    data : path, list of paths, DataFrame, list or dict of DataFrames, or Dataset
        CSV or Parquet recordings, or the same tables in memory (as
        :func:`ftcal.workflow.payload.identify_payload`). There is no ``executor``: the holds are read in
        this process (``ftcal check`` has no ``--scheduler``).
    accept : path of a calibration model to test on ``data``, or None for the conventions check
    inputs, reaction, rate, max_com_distance : the conventions check's wrench columns (``wrench=``, the old
        spelling, still works), declared sign, sample rate without a time column (Hz), and farthest plausible
        centre of mass (m)
    group_by : column naming the static holds (conventions) or the poses (acceptance)
    html : path or None; an HTML page of the result is written there
    payload_json : path of a payload file: the acceptance reference is its bias + weight (else ``data``'s
        output columns)
    max_force_error, max_torque_error, max_error_percent, rated_force, rated_torque : acceptance thresholds
    serial, history_dir : record the acceptance result in this sensor's history (SQLite, one per folder)
    **source
        The gravity source, as :func:`ftcal.workflow.payload.identify_payload`.

    Returns
    -------
    CheckResult

    Raises
    ------
    FtcalError
        Bad input, or options of one mode given to the other.

    Examples
    --------
    >>> import numpy as np, pandas as pd, tempfile, os
    >>> from scipy.spatial.transform import Rotation
    >>> rows = []
    >>> for k, rotation in enumerate(Rotation.random(8, random_state=3)):
    ...     gravity = rotation.inv().apply([0.0, 0.0, -9.81])
    ...     force = 1.2 * gravity                                  # a 1.2 kg tool at the sensor origin
    ...     wrench = np.r_[force, np.cross([0.0, 0.0, 0.04], force)]
    ...     rows += [[0.01 * (100 * k + i), *wrench, *gravity] for i in range(100)]
    >>> path = os.path.join(tempfile.mkdtemp(), "holds.csv")
    >>> pd.DataFrame(rows, columns=["time", "u1", "u2", "u3", "u4", "u5", "u6", "gx", "gy", "gz"]).to_csv(
    ...     path, index=False)
    >>> result = check_sensor(path, gravity_columns=("gx", "gy", "gz"))
    >>> result.passed, round(result.report.mass, 3)
    (True, 1.2)
    """
    check_arguments(CHECK, locals(), "ftcal.check_sensor")
    wrench = renamed_keyword(source, "wrench", "inputs", inputs, DEFAULT_WRENCH)
    options = source_options(source, "check")
    if html is not None:
        from ..runtime.atomic import check_not_an_input

        check_not_an_input(html, "html")
    if options["dynamic"]:  # both modes read static holds: the motion columns would be ignored
        raise ParameterError("dynamic", "{dynamic} is for ftcal payload (the inertia fit); ftcal check reads static holds.")
    if accept is None:
        for option, value in (("payload_json", payload_json), ("serial", serial),
                              ("max_force_error", max_force_error), ("max_torque_error", max_torque_error),
                              ("max_error_percent", max_error_percent), ("rated_force", rated_force),
                              ("rated_torque", rated_torque), ("history_dir", history_dir)):
            if value is not None:
                raise ParameterError((option, 'accept'), f"{{{option}}} goes with {{accept}} MODEL.")
        return _conventions(data, options, wrench=wrench, group_by=group_by, rate=rate, reaction=reaction,
                            max_com_distance=max_com_distance, html=html)
    # Options of the conventions mode that an acceptance test does not use are refused, not ignored.
    for option, given in (("inputs", tuple(wrench) != DEFAULT_WRENCH), ("reaction", reaction),
                          ("max_com_distance", max_com_distance != MAX_COM_DISTANCE),
                          ("rate", rate != HOLD_SAMPLE_RATE)):
        if given:
            raise ParameterError((option, "accept"), f"{{{option}}} is for the conventions check (ftcal check DATA); "
                                 "{accept} reads the model's input columns and does not use it.")
    if payload_json is None:
        for option, given in (("orientation", options["orientation"]),
                              ("gravity_columns", options["gravity_columns"]), ("urdf", options["urdf"]),
                              ("robot", options["robot"]), ("dynamic", options["dynamic"] or None)):
            if given is not None:
                raise ParameterError((option, "payload_json"),
                                     f"{{{option}}} goes with {{payload_json}} (the reference "
                                     "from a payload file); without it the reference is DATA's output columns.")
    return _acceptance(data, accept, options, group_by=group_by, html=html, payload_json=payload_json,
                       limits=(max_force_error, max_torque_error, max_error_percent, rated_force, rated_torque),
                       serial=serial, history_dir=history_dir)


def _reading_scales(wrench) -> tuple[float, float]:
    """RMS of the force and of the torque readings: what :meth:`ConventionsRun.stated` states residuals to."""
    return tuple(float(np.sqrt(np.mean(wrench[:, block] ** 2))) for block in (slice(0, 3), slice(3, 6)))


def _conventions(tables, options, *, wrench, group_by, rate, reaction, max_com_distance, html) -> CheckResult:
    from ..check.conventions import check_conventions, read_holds

    paths, names = tables.paths, tables.sources
    holds = read_holds(paths, gravity_source(options), wrench=wrench, group_by=group_by, reaction=reaction,
                       time=options["time"], rate=rate)
    report = check_conventions(holds, wrench_columns=tuple(wrench), max_com_distance=max_com_distance,
                               source=", ".join(names))
    run = ConventionsRun(holds.n_holds, _reading_scales(holds.wrench), bool(reaction),
                         tuple(tables.named(note) for note in report.notes))
    written = []
    if html is not None:
        from ..check.page import conventions_page

        conventions_page(report, html, source=", ".join(names))
        written.append(str(html))
    return CheckResult("conventions", not report.findings, report, written, run)


def _conventions_lines(report, run: ConventionsRun) -> list[str]:
    force, torque = run.stated(report.residual)
    lines = [f"{run.n_holds} static holds; payload-fit residual RMS as declared {force:.4g} N, {torque:.4g} N·m; "
             f"tool mass {report.mass:.4g} ± {report.mass_stderr:.2g} kg (with the fixes below; a constant bias: "
             "if the bias drifts, `ftcal payload --time COL --bias-drift auto` compares bias models and says which "
             "mass to trust)"]
    for k, f in enumerate(report.findings, 1):
        fix = f.fix
        if run.reaction and f.reaction:
            fix = fix.replace("--reaction", "leave out --reaction", 1)
        lines.append(f"finding {k}: {f.kind} (confidence {100 * f.confidence:.2f} %): {f.message}")
        lines.append(f"  fix: {fix}")
        before, after = run.stated(f.before), run.stated(f.after)
        lines.append(f"  residual RMS before {before[0]:.4g} N, {before[1]:.4g} N·m; after {after[0]:.4g} N, "
                     f"{after[1]:.4g} N·m")
    lines += [f"note: {note}" for note in run.notes]
    if not report.findings:
        lines.append("no finding: sign, axes, frame, zeroing and torque reference look as declared")
    return lines


def thresholds_for(model, model_name: str, limits):
    """The acceptance thresholds from (max_force_error, max_torque_error, max_error_percent, rated_force,
    rated_torque), each None when not given."""
    import math

    from ..check.accept import Thresholds, rated_ranges

    max_force_error, max_torque_error, max_error_percent, rated_force, rated_torque = limits
    if max_error_percent is not None:
        if max_force_error is not None or max_torque_error is not None:
            raise ParameterError(('max_error_percent', 'max_force_error', 'max_torque_error'),
                                 "{max_error_percent} replaces {max_force_error}/{max_torque_error}; give one kind.")
        force, torque = rated_ranges(model)
        origin = "the model's training range"
        if rated_force is not None or rated_torque is not None:
            force = rated_force or force
            torque = rated_torque or torque
            origin = "the rated force/torque given"
        # A model without a training range (paper XML, null ranges) must not make the threshold infinite.
        for value, rated, unit in ((force, "rated_force", "N"), (torque, "rated_torque", "NM")):
            if not (math.isfinite(value) and value > 0):
                raise ParameterError(('max_error_percent', rated, 'max_force_error', 'max_torque_error'),
                                     f"{{max_error_percent}}: {model_name} has no finite training output range to "
                                     f"take the percentage of; give {{{rated}}} {unit} (or absolute "
                                     "{max_force_error}/{max_torque_error}).")
        return Thresholds.from_percent(max_error_percent, force, torque, origin)
    if rated_force is not None or rated_torque is not None:
        raise ParameterError(('rated_force', 'rated_torque', 'max_error_percent'),
                             "{rated_force}/{rated_torque} go with {max_error_percent}.")
    given = max_force_error is not None or max_torque_error is not None
    return Thresholds(max_force_error or MAX_FORCE_ERROR, max_torque_error or MAX_TORQUE_ERROR,
                      "given" if given else "defaults")


def _acceptance(tables, accept, options, *, group_by, html, payload_json, limits, serial,
                history_dir) -> CheckResult:
    from ..check.accept import acceptance_test, read_test_data, retare_verdict
    from ..files.model_files import load_model_file
    from ..runtime.atomic import write_text_atomic

    if history_dir is not None and serial is None:
        raise ParameterError(('history_dir', 'serial'),
                             "{history_dir} needs {serial} SERIAL (the sensor the result belongs to).")
    paths, names = tables.paths, tables.sources
    model_name = str(accept)
    model = load_model_file(accept).model
    thresholds = thresholds_for(model, model_name, limits)
    payload = source = None
    if payload_json is not None:
        from ..files.payload_json import load_payload

        payload = load_payload(payload_json)
        source = gravity_source(options)
    rows: dict = {}
    error, reference, labels, issues, problems = read_test_data(
        paths, model, payload=payload, source=source, group_by=group_by, time_column=options["time"] or "time",
        rows=rows)
    labels, issues, problems = tables.named_labels(labels), tables.named(issues), tables.named(problems)
    result = acceptance_test(error, labels, model.output_names_, thresholds, issues, reference, problems)
    run = AcceptanceRun(model_name, retare_verdict(result, rows["file"], rows["time"]))
    page = None
    if html is not None:  # made before anything is recorded: a run that fails is not in the history
        from ..check.page import acceptance_page_text

        page = acceptance_page_text(result, model=model_name, data=names)

    def write_page() -> None:
        if page is not None:
            write_text_atomic(html, page)

    if serial is not None:
        # The page is written inside the history's transaction: if it fails, nothing is recorded.
        message, recorded = _record(model, model_name, names, result, thresholds, serial, history_dir,
                                    before_commit=write_page)
        run = replace(run, recorded=recorded)
        if message:
            from ..check.history import DriftWarning

            warnings.warn(message, DriftWarning, stacklevel=3)
    else:
        write_page()
    return CheckResult("acceptance", result.passed, result, [str(html)] if page is not None else [], run)


def _acceptance_lines(result, run: AcceptanceRun) -> list[str]:
    from ..check.accept import axis_limits

    thresholds = result.thresholds
    limits_per_axis = axis_limits(result.outputs, thresholds)
    lines = [f"acceptance of {run.model_name} on {result.error.shape[0]} samples in {len(result.poses)} pose(s); "
             f"thresholds {thresholds.force:.4g} N, {thresholds.torque:.4g} N·m RMS per axis and pose "
             f"({thresholds.origin})",
             f"{'axis':<8}{'RMS error':>12}{'max |err|':>12}{'threshold':>12}"]
    for name, r, m, lim in zip(result.outputs, result.rmse, result.max_abs_error, limits_per_axis):
        lines.append(f"{name:<8}{r:>12.4g}{m:>12.4g}{lim:>12.4g}{'  over' if r > lim else ''}")
    failed = sorted(result.failed_poses, key=lambda p: -float((p.rmse / limits_per_axis).max()))
    for pose in failed[:MAX_POSES_PRINTED]:
        lines.append(f"pose {pose.label} ({pose.n_samples} samples) fails on {', '.join(pose.failed)}: "
                     + "  ".join(f"{a} {v:.4g}" for a, v in zip(result.outputs, pose.rmse)))
    if len(failed) > MAX_POSES_PRINTED:
        lines.append(f"... {len(failed) - MAX_POSES_PRINTED} more failing pose(s)")
    lines += [f"channel: {issue}" for issue in result.channel_issues]
    lines += [f"unusable: {problem}" for problem in result.problems]
    if run.retare is not None:
        lines.append(run.retare)
    lines.append("PASS" if result.passed else f"FAIL ({len(failed)} of {len(result.poses)} pose(s) over threshold, "
                                              f"{len(result.channel_issues)} channel issue(s)"
                 + (f", {len(result.problems)} reason(s) the test cannot pass" if result.problems else "") + ")")
    if run.recorded is not None:
        path, serial, n_records = run.recorded
        lines.append(f"recorded in {path} for sensor {serial} ({n_records} calibration(s))")
    return lines


def _record(model, model_name, paths, result, thresholds, serial, history_dir,
            before_commit=None) -> tuple[str | None, tuple[str, str, int]]:
    """Append the calibration (if new) and the result to the history; a drift warning (or None), and
    (the history file, ``serial``, its calibrations recorded).

    ``before_commit()`` runs inside the transaction (the other outputs): if it fails, nothing is recorded."""
    from ..check.history import History, calibration_summary, default_history_dir, drift

    summary = calibration_summary(model, model_name)
    with History(history_dir or default_history_dir()) as history:
        with history.transaction() as conn:
            new = history.append_calibration(conn, serial, summary)
            history.append_acceptance(conn, serial, summary.model_sha256, result.passed, result.rmse.tolist(),
                                      {"force": thresholds.force, "torque": thresholds.torque,
                                       "origin": thresholds.origin, "problems": list(result.problems)},
                                      paths)
            if before_commit is not None:
                before_commit()
        records = history.calibrations(serial)
        recorded = (str(history.path), serial, len(records))
    return (_drift_message(drift(records), serial) if new else None), recorded


def _drift_message(result, serial: str) -> str | None:
    from ..check.history import DRIFT_UNITS

    if not result.unusual:
        return None
    last = result.changes[-1]
    return (f"sensor {serial}: the new calibration differs from the last more than its history says is normal: "
            + "; ".join(f"{k.replace('_', ' ')} changed {last[k]:.4g} {DRIFT_UNITS[k]} (normal up to "
                        f"{result.normal[k]:.4g})" for k in result.unusual))


def sensor_history(serial: str, history_dir=None) -> CheckResult:
    """A sensor's recorded calibrations, acceptance tests and drift: ``ftcal check --history SERIAL``.

    Parameters
    ----------
    serial : the sensor's serial
    history_dir : folder of the history database (default ``$XDG_DATA_HOME/ftcal/history``)

    Returns
    -------
    CheckResult
        ``mode`` "history"; ``report`` is the list of calibration records.

    Raises
    ------
    FtcalError
        No database in the folder, or no record of the sensor.
    """
    import os
    from pathlib import Path

    from ..check.history import DATABASE_NAME, DriftWarning, History, default_history_dir, drift

    folder = Path(history_dir or default_history_dir())
    if not os.path.lexists(folder / DATABASE_NAME):
        raise ParameterError(('history_dir', 'accept', 'serial'),
                             f"{{history_dir}} {folder}: no history database ({DATABASE_NAME}) "
                             "there; an acceptance test ({accept} MODEL with {serial} SERIAL) records one.")
    with History(folder, read_only=True) as history:  # reading never writes (nor waits long for a writer)
        records = history.calibrations(serial)
        results = history.acceptances(serial)
        if not records and not results:
            known = history.serials()
            raise ParameterError('history', f"{{history}} {serial}: no record in {history.path}"
                             + (f"; sensors recorded: {', '.join(known)}." if known else " (empty history)."))
    result = drift(records)
    message = _drift_message(result, serial)
    if message:
        warnings.warn(message, DriftWarning, stacklevel=2)
    return CheckResult("history", True, records, run=HistoryRun(serial, tuple(results), result))


def _history_lines(records, run: HistoryRun) -> list[str]:
    from ..check.history import DRIFT_KEYS, DRIFT_UNITS

    lines = [f"sensor {run.serial}: {len(records)} calibration(s), {len(run.acceptances)} acceptance test(s)",
             f"{'recorded (UTC)':<28}{'model sha256':<14}{'|force bias| N':>15}{'|torque bias| N·m':>19}"
             f"{'gain norm':>11}"]
    for r in records:
        s = r.summary
        lines.append(f"{r.recorded_utc[:26]:<28}{s.model_sha256[:12]:<14}{np.linalg.norm(s.bias[:3]):>15.4g}"
                     f"{np.linalg.norm(s.bias[3:]):>19.4g}{np.linalg.norm(s.gain):>11.4g}")
    result = run.drift
    if result is not None and result.changes:
        lines.append("drift between consecutive calibrations:")
        for c in result.changes:
            lines.append(f"  {c['recorded_utc'][:26]}: " + "  ".join(
                f"{k.replace('_', ' ')} {c[k]:.4g} {DRIFT_UNITS[k]}" for k in DRIFT_KEYS))
        if result.normal is None:
            lines.append("  (too few calibrations to say what change is normal)")
        else:
            lines.append("  normal change (3 × RMS of the earlier ones): " + "  ".join(
                f"{k.replace('_', ' ')} {result.normal[k]:.4g}" for k in DRIFT_KEYS))
    for a in run.acceptances:
        lines.append(f"acceptance {a.recorded_utc[:26]} model {a.model_sha256[:12]}: "
                     f"{'PASS' if a.passed else 'FAIL'}, RMS " + " ".join(f"{v:.3g}" for v in a.rmse))
    return lines
