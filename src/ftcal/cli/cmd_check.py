"""``ftcal check``: conventions and mounting from a short recording; acceptance tests; per-sensor history."""

from __future__ import annotations

from ..core.limits import (FINDING_CONFIDENCE, HOLD_SAMPLE_RATE, MAX_COM_DISTANCE, MAX_FORCE_ERROR,
                           MAX_TORQUE_ERROR, MIN_HOLDS, MIN_ROTATION_DEG)
from ..workflow.sources import DEFAULT_WRENCH
from ._common import positive_float, require_suffix
from ._examples import epilog
from ._gravity import add_kinematics_options, add_robot_source_options, source_keywords
from ._inputs import add_inputs_option, inputs_of

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
    add_inputs_option(p, "wrench columns, N and N·m (default u1,...,u6)")
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
    accept.add_argument("--payload-json", metavar="PAYLOAD.json",
                        help="reference = bias + this payload file's weight through the orientation options")
    accept.add_argument("--payload", dest="payload_old", metavar="PAYLOAD.json",
                        help="old spelling of --payload-json (a notice says so; --payload SPEC is a mass/COM "
                             "spec in the robot commands)")
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
    import sys

    from ..runtime.errors import FtcalError
    from ..workflow.checking import check_sensor, sensor_history

    if args.html is not None:  # never an input: cli.main checks the OUTPUT_OPTIONS
        require_suffix(args.html, (".html", ".htm"), "--html")
    if args.payload_old is not None:
        if args.payload_json is not None:
            raise FtcalError("--payload-json: given twice (also as --payload, its old spelling); give it once.")
        print("notice: --payload PAYLOAD.json is now --payload-json PAYLOAD.json (in the robot commands, --payload "
              "is a mass/COM spec)", file=sys.stderr)
        args.payload_json = args.payload_old
    if args.history_serial is not None:
        if args.data or args.accept:
            raise FtcalError("--history SERIAL takes no DATA and no --accept; run it on its own.")
        given = _given_options(args, keep=("history_serial", "history_dir"))
        if given:
            raise FtcalError(f"--history SERIAL prints the recorded history and does not use {', '.join(given)} "
                             "(only --history-dir); leave them out.")
        print(sensor_history(args.history_serial, args.history_dir).summary())
        return 0
    if not args.data:
        raise FtcalError("give the recording(s) DATA to check (or --history SERIAL).")
    inputs = inputs_of(args, DEFAULT_WRENCH)
    result = check_sensor(args.data, accept=args.accept, inputs=inputs, group_by=args.group_by,
                          rate=args.rate,
                          reaction=args.reaction, max_com_distance=args.max_com_distance, html=args.html,
                          payload_json=args.payload_json, max_force_error=args.max_force_error,
                          max_torque_error=args.max_torque_error, max_error_percent=args.max_error_percent,
                          rated_force=args.rated_force, rated_torque=args.rated_torque, serial=args.serial,
                          history_dir=args.history_dir, **source_keywords(args))
    print(result.summary())
    for path in result.written:
        print(f"wrote {path}", file=sys.stderr)
    return result.exit_code


def _given_options(args, keep=()) -> list[str]:
    """The options of ``ftcal check`` that ``args`` sets to other than their defaults, but those in ``keep``
    (dests): a mode that does not use them refuses them instead of ignoring them."""
    import argparse

    sub = argparse.ArgumentParser().add_subparsers()
    register(sub)
    return [max(a.option_strings, key=len) for a in sub.choices["check"]._actions
            if a.option_strings and a.dest not in (*keep, "help") and getattr(args, a.dest, a.default) != a.default]
