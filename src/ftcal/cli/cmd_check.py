"""``ftcal check``: conventions and mounting from a short recording; acceptance tests; per-sensor history."""

from __future__ import annotations

from ..core.limits import (FINDING_CONFIDENCE, HOLD_SAMPLE_RATE, MAX_COM_DISTANCE, MAX_FORCE_ERROR,
                           MAX_TORQUE_ERROR, MIN_HOLDS, MIN_ROTATION_DEG)
from ._common import column_list, positive_float, require_suffix
from ._examples import epilog
from ._gravity import add_kinematics_options, add_robot_source_options

MAX_POSES_PRINTED = 8

DEFAULT_WRENCH = ("u1", "u2", "u3", "u4", "u5", "u6")
EXIT_CODES = "exit codes: 0 no finding / pass, 1 findings / fail, 2 bad input"


def register(sub) -> None:

    p = sub.add_parser(
        "check", help="is the sensor signed, mounted and zeroed as declared; does the installation pass",
        **epilog("check", EXIT_CODES),
        description="Three modes. `ftcal check DATA`: from a few static holds at different orientations with "
                    "the tool attached, infer the sign (action/reaction), handedness, axis order, the rotation "
                    "between the data's frame and the declared sensor frame, a wrench already tared / "
                    "gravity-compensated / in the base frame, and torques about another point; each finding "
                    "with its confidence, the exact fix and the residual before/after (at least "
                    f"{MIN_HOLDS} holds; rotations under {MIN_ROTATION_DEG:g}° and findings under "
                    f"{100 * FINDING_CONFIDENCE:g} % confidence are not reported). "
                    "`ftcal check --accept MODEL DATA`: a calibration's error per axis and per pose on a test "
                    "recording, and its input channels, against thresholds. `ftcal check --history SERIAL`: "
                    "drift of bias and gain over the recorded calibrations.")
    p.add_argument("data", nargs="*", metavar="DATA", help="CSV or Parquet recordings")
    p.add_argument("--wrench", type=column_list, default=DEFAULT_WRENCH,
                   metavar="FX,FY,FZ,TX,TY,TZ", help="wrench columns, N and N·m (default u1,...,u6)")
    add_kinematics_options(p)
    add_robot_source_options(p)
    p.add_argument("--group-by", metavar="COL",
                   help="column naming the static holds (conventions) or the poses (--accept); default: holds "
                        "found from the orientation, one pose per file")
    p.add_argument("--rate", type=positive_float, default=HOLD_SAMPLE_RATE, metavar="HZ",
                   help=f"sample rate of DATA without a time column, to find the static holds "
                        f"(default {HOLD_SAMPLE_RATE:g} Hz)")
    p.add_argument("--reaction", action="store_true", help="the readings are declared to have the reaction sign")
    p.add_argument("--max-com-distance", type=positive_float, default=MAX_COM_DISTANCE, metavar="M",
                   help=f"a centre of mass farther from the sensor origin means torques about another point "
                        f"(default {MAX_COM_DISTANCE:g} m)")
    p.add_argument("--html", metavar="PAGE.html", help="also write an HTML page (residuals by pose, before/after)")
    accept = p.add_argument_group("acceptance test (--accept)")
    accept.add_argument("--accept", metavar="MODEL", help="calibration model to test on DATA (reference wrench: "
                        "DATA's output columns, or --payload)")
    accept.add_argument("--payload", metavar="PAYLOAD.json",
                        help="reference = bias + this payload's weight through the orientation options")
    accept.add_argument("--max-force-error", type=positive_float, metavar="N",
                        help=f"largest RMS error of a force axis in any pose (default {MAX_FORCE_ERROR:g} N)")
    accept.add_argument("--max-torque-error", type=positive_float, metavar="NM",
                        help=f"largest RMS error of a torque axis in any pose (default {MAX_TORQUE_ERROR:g} N·m)")
    accept.add_argument("--max-error-percent", type=positive_float, metavar="P",
                        help="threshold as a percentage of the rated range instead (--rated-force/--rated-torque, "
                             "default the model's largest training output)")
    accept.add_argument("--rated-force", type=positive_float, metavar="N", help="rated force range, N")
    accept.add_argument("--rated-torque", type=positive_float, metavar="NM", help="rated torque range, N·m")
    history = p.add_argument_group("history (an SQLite database per folder)")
    history.add_argument("--serial", metavar="SERIAL", help="record the calibration and the result for this sensor")
    history.add_argument("--history", metavar="SERIAL", dest="history_serial",
                         help="print this sensor's calibrations, acceptance results and drift")
    history.add_argument("--history-dir", metavar="DIR",
                         help="folder of the history database (default $XDG_DATA_HOME/ftcal/history, i.e. "
                              "~/.local/share/ftcal/history)")
    p.set_defaults(func=run)


def run(args) -> int:
    from ..runtime.errors import FtcalError

    if args.html is not None:  # never an input: cli.main checks the OUTPUT_OPTIONS
        require_suffix(args.html, (".html", ".htm"), "--html")
    if args.history_serial is not None:
        if args.data or args.accept:
            raise FtcalError("--history SERIAL takes no DATA and no --accept; run it on its own.")
        return show_history(args)
    if not args.data:
        raise FtcalError("give the recording(s) DATA to check (or --history SERIAL).")
    if args.accept is not None:
        # Options of the conventions mode that an acceptance test does not use are refused, not ignored.
        for option, given in (("--wrench", tuple(args.wrench) != DEFAULT_WRENCH),
                              ("--reaction", args.reaction),
                              ("--max-com-distance", args.max_com_distance != MAX_COM_DISTANCE),
                              ("--rate", args.rate != HOLD_SAMPLE_RATE)):
            if given:
                raise FtcalError(f"{option} is for the conventions check (ftcal check DATA); --accept reads the "
                                 "model's input columns and does not use it.")
        if args.payload is None:
            for option, given in (("--orientation", args.orientation), ("--gravity-columns", args.gravity_columns),
                                  ("--urdf", args.robot_urdf), ("--model", args.robot_model),
                                  ("--dynamic", args.dynamic or None)):
                if given is not None:
                    raise FtcalError(f"{option} goes with --payload (the reference from a payload file); without "
                                     "it the reference is DATA's output columns.")
        return run_accept(args)
    for option in ("payload", "serial", "max_force_error", "max_torque_error", "max_error_percent", "rated_force",
                   "rated_torque", "history_dir"):
        if getattr(args, option) is not None:
            raise FtcalError(f"--{option.replace('_', '-')} goes with --accept MODEL.")
    return run_conventions(args)


def run_conventions(args) -> int:
    from ..check.conventions import check_conventions, read_holds
    from ._gravity import kinematics_source

    holds = read_holds(args.data, kinematics_source(args), wrench=args.wrench, group_by=args.group_by,
                       reaction=args.reaction, time=args.time, rate=args.rate)
    report = check_conventions(holds, wrench_columns=tuple(args.wrench), max_com_distance=args.max_com_distance,
                               source=", ".join(args.data))
    force, torque = report.residual
    print(f"{holds.n_holds} static holds; payload-fit residual RMS as declared {force:.4g} N, {torque:.4g} N·m; "
          f"tool mass {report.mass:.4g} ± {report.mass_stderr:.2g} kg (with the fixes below; a constant bias: "
          "if the bias drifts, `ftcal payload --time COL --bias-drift auto` compares bias models and says which "
          "mass to trust)")
    for k, f in enumerate(report.findings, 1):
        fix = f.fix
        if args.reaction and f.reaction:
            fix = fix.replace("--reaction", "leave out --reaction", 1)
        print(f"finding {k}: {f.kind} (confidence {100 * f.confidence:.2f} %): {f.message}")
        print(f"  fix: {fix}")
        print(f"  residual RMS before {f.before[0]:.4g} N, {f.before[1]:.4g} N·m; after {f.after[0]:.4g} N, "
              f"{f.after[1]:.4g} N·m")
    for note in report.notes:
        print(f"note: {note}")
    if not report.findings:
        print("no finding: sign, axes, frame, zeroing and torque reference look as declared")
    if args.html is not None:
        from ..check.page import conventions_page

        conventions_page(report, args.html, source=", ".join(args.data))
        _wrote(args.html)
    return 1 if report.findings else 0


def _thresholds(args, model):
    import math

    from ..check.accept import Thresholds, rated_ranges
    from ..runtime.errors import FtcalError

    if args.max_error_percent is not None:
        if args.max_force_error is not None or args.max_torque_error is not None:
            raise FtcalError("--max-error-percent replaces --max-force-error/--max-torque-error; give one kind.")
        force, torque = rated_ranges(model)
        origin = "the model's training range"
        if args.rated_force is not None or args.rated_torque is not None:
            force = args.rated_force or force
            torque = args.rated_torque or torque
            origin = "--rated-force/--rated-torque"
        # A model without a training range (paper XML, null ranges) must not make the threshold infinite.
        for value, option in ((force, "--rated-force N"), (torque, "--rated-torque NM")):
            if not (math.isfinite(value) and value > 0):
                raise FtcalError(f"--max-error-percent: {args.accept} has no finite training output range to take "
                                 f"the percentage of; give {option} (or absolute --max-force-error/"
                                 "--max-torque-error).")
        return Thresholds.from_percent(args.max_error_percent, force, torque, origin)
    if args.rated_force is not None or args.rated_torque is not None:
        raise FtcalError("--rated-force/--rated-torque go with --max-error-percent.")
    given = args.max_force_error is not None or args.max_torque_error is not None
    return Thresholds(args.max_force_error or MAX_FORCE_ERROR, args.max_torque_error or MAX_TORQUE_ERROR,
                      "given" if given else "defaults")


def run_accept(args) -> int:
    import warnings

    from ..check.accept import acceptance_test, axis_limits, read_test_data
    from ..files.model_files import read_model_file
    from ..runtime.errors import FtcalError
    from ._gravity import kinematics_source

    if args.history_dir is not None and args.serial is None:
        raise FtcalError("--history-dir needs --serial SERIAL (the sensor the result belongs to).")
    model = read_model_file(args.accept).model
    thresholds = _thresholds(args, model)
    payload = source = None
    if args.payload is not None:
        from ..files.payload_json import load_payload

        payload = load_payload(args.payload)
        source = kinematics_source(args)
    error, reference, labels, issues, problems = read_test_data(
        args.data, model, payload=payload, source=source, group_by=args.group_by, time_column=args.time or "time")
    result = acceptance_test(error, labels, model.output_names_, thresholds, issues, reference, problems)
    limits = axis_limits(result.outputs, thresholds)
    print(f"acceptance of {args.accept} on {error.shape[0]} samples in {len(result.poses)} pose(s); thresholds "
          f"{thresholds.force:.4g} N, {thresholds.torque:.4g} N·m RMS per axis and pose ({thresholds.origin})")
    print(f"{'axis':<8}{'RMS error':>12}{'max |err|':>12}{'threshold':>12}")
    for name, r, m, lim in zip(result.outputs, result.rmse, result.max_abs_error, limits):
        print(f"{name:<8}{r:>12.4g}{m:>12.4g}{lim:>12.4g}{'  over' if r > lim else ''}")
    failed = sorted(result.failed_poses, key=lambda p: -float((p.rmse / limits).max()))
    for pose in failed[:MAX_POSES_PRINTED]:
        print(f"pose {pose.label} ({pose.n_samples} samples) fails on {', '.join(pose.failed)}: "
              + "  ".join(f"{a} {v:.4g}" for a, v in zip(result.outputs, pose.rmse)))
    if len(failed) > MAX_POSES_PRINTED:
        print(f"... {len(failed) - MAX_POSES_PRINTED} more failing pose(s)")
    for issue in result.channel_issues:
        print(f"channel: {issue}")
    for problem in result.problems:
        print(f"unusable: {problem}")
    print("PASS" if result.passed else f"FAIL ({len(failed)} of {len(result.poses)} pose(s) over threshold, "
                                       f"{len(result.channel_issues)} channel issue(s)"
                                       + (f", {len(result.problems)} reason(s) the test cannot pass" if result.problems
                                          else "") + ")")
    page = None
    if args.html is not None:  # made before anything is recorded: a run that fails is not in the history
        from ..check.page import acceptance_page_text

        page = acceptance_page_text(result, model=args.accept, data=args.data)
    from ..runtime.atomic import write_text_atomic

    def write_page() -> None:
        if page is not None:
            write_text_atomic(args.html, page)

    if args.serial is not None:
        # The page is written inside the history's transaction: if it fails, nothing is recorded.
        message = record(args, model, result, thresholds, before_commit=write_page)
        if message:
            from ..check.history import DriftWarning

            warnings.warn(message, DriftWarning, stacklevel=1)
    else:
        write_page()
    if page is not None:
        _wrote(args.html)
    return 0 if result.passed else 1


def record(args, model, result, thresholds, before_commit=None) -> str | None:
    """Append the calibration (if new) and the result to the history; a drift warning, or None.

    ``before_commit()`` runs inside the transaction (the other outputs): if it fails, nothing is recorded."""
    from ..check.history import History, calibration_summary, default_history_dir, drift

    summary = calibration_summary(model, args.accept)
    with History(args.history_dir or default_history_dir()) as history:
        with history.transaction() as conn:
            new = history.append_calibration(conn, args.serial, summary)
            history.append_acceptance(conn, args.serial, summary.model_sha256, result.passed, result.rmse.tolist(),
                                      {"force": thresholds.force, "torque": thresholds.torque,
                                       "origin": thresholds.origin, "problems": list(result.problems)},
                                      args.data)
            if before_commit is not None:
                before_commit()
        records = history.calibrations(args.serial)
        print(f"recorded in {history.path} for sensor {args.serial} ({len(records)} calibration(s))")
    return _drift_message(drift(records), args.serial) if new else None


def _drift_message(result, serial: str) -> str | None:
    from ..check.history import DRIFT_UNITS

    if not result.unusual:
        return None
    last = result.changes[-1]
    return (f"sensor {serial}: the new calibration differs from the last more than its history says is normal: "
            + "; ".join(f"{k.replace('_', ' ')} changed {last[k]:.4g} {DRIFT_UNITS[k]} (normal up to "
                        f"{result.normal[k]:.4g})" for k in result.unusual))


def show_history(args) -> int:
    import os
    import warnings

    import numpy as np

    from pathlib import Path

    from ..check.history import (DATABASE_NAME, DRIFT_KEYS, DRIFT_UNITS, DriftWarning, History,
                                 default_history_dir, drift)
    from ..runtime.errors import FtcalError

    folder = Path(args.history_dir or default_history_dir())
    if not os.path.lexists(folder / DATABASE_NAME):
        raise FtcalError(f"--history-dir {folder}: no history database ({DATABASE_NAME}) there; record one with "
                         "ftcal check --accept MODEL DATA --serial SERIAL.")
    with History(folder, read_only=True) as history:  # reading never writes (nor waits long for a writer)
        records = history.calibrations(args.history_serial)
        results = history.acceptances(args.history_serial)
        if not records and not results:
            known = history.serials()
            raise FtcalError(f"--history {args.history_serial}: no record in {history.path}"
                             + (f"; sensors recorded: {', '.join(known)}." if known else " (empty history)."))
    print(f"sensor {args.history_serial}: {len(records)} calibration(s), {len(results)} acceptance test(s)")
    print(f"{'recorded (UTC)':<28}{'model sha256':<14}{'|force bias| N':>15}{'|torque bias| N·m':>19}"
          f"{'gain norm':>11}")
    for r in records:
        s = r.summary
        print(f"{r.recorded_utc[:26]:<28}{s.model_sha256[:12]:<14}{np.linalg.norm(s.bias[:3]):>15.4g}"
              f"{np.linalg.norm(s.bias[3:]):>19.4g}{np.linalg.norm(s.gain):>11.4g}")
    result = drift(records)
    if result.changes:
        print("drift between consecutive calibrations:")
        for c in result.changes:
            print(f"  {c['recorded_utc'][:26]}: " + "  ".join(
                f"{k.replace('_', ' ')} {c[k]:.4g} {DRIFT_UNITS[k]}" for k in DRIFT_KEYS))
        if result.normal is None:
            print("  (too few calibrations to say what change is normal)")
        else:
            print("  normal change (3 × RMS of the earlier ones): " + "  ".join(
                f"{k.replace('_', ' ')} {result.normal[k]:.4g}" for k in DRIFT_KEYS))
    for a in results:
        print(f"acceptance {a.recorded_utc[:26]} model {a.model_sha256[:12]}: {'PASS' if a.passed else 'FAIL'}, "
              "RMS " + " ".join(f"{v:.3g}" for v in a.rmse))
    message = _drift_message(result, args.history_serial)
    if message:
        warnings.warn(message, DriftWarning, stacklevel=1)
    return 0


def _wrote(path: str) -> None:
    import sys

    print(f"wrote {path}", file=sys.stderr)
