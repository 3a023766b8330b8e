"""``ftcal compensate``: the contact wrench, with the bias and the tool's weight (and inertia) removed."""

from __future__ import annotations

from ._common import require_suffix
from ._examples import epilog
from ._gravity import add_kinematics_options, add_robot_source_options, check_not_input, source_keywords
from ._inputs import add_inputs_option, inputs_of


def register(sub) -> None:
    p = sub.add_parser("compensate", **epilog("compensate"), help="subtract the bias and the payload's gravity wrench",
                       description="Contact wrench = measured wrench (or the wrench a calibration model "
                                   "predicts from the raw channels) minus the bias minus the payload's gravity "
                                   "wrench (and, with --dynamic, its inertial wrench), written as Fx..Tz in the "
                                   "sign of the readings (replacing any Fx..Tz columns of DATA); the other "
                                   "columns are kept. A bias that drifts (payload file from --bias-drift linear "
                                   "or random-walk) is taken at each sample's time (--time, default the "
                                   "payload file's time column); beyond the identification recording the "
                                   "nearest end is held, with a warning.")
    p.add_argument("payload", metavar="PAYLOAD.json", help="payload file from `ftcal payload`")
    p.add_argument("data", nargs="+", metavar="DATA", help="CSV or Parquet files")
    p.add_argument("-o", "--output", required=True, metavar="OUT.csv|OUT.parquet",
                   help="one table with the rows of all DATA files in order")
    p.add_argument("--calibration", metavar="CAL.json",
                   help="calibration model: the measured wrench is its prediction from its input columns")
    add_inputs_option(p, "measured wrench columns without --calibration (default: the payload file's, else "
                         "u1,...,u6); with --calibration the model's own input columns are read")
    add_kinematics_options(p)
    add_robot_source_options(p, named_models=False)
    # Outside the --urdf/--model group: the old spelling `--model CAL.json` (a calibration) may come with --urdf.
    p.add_argument("--model", dest="robot_model", metavar="NAME",
                   help="robot model from icub-models, e.g. iCubGenova04 (with --sensor); a calibration model "
                        "file given here (the old spelling) is read as --calibration, with a notice")
    for action in p._actions:
        if action.dest == "g":
            action.help = "gravity magnitude, m/s² (default: the payload file's, which its mass was identified with)"
    p.set_defaults(func=run, g=None)


CALIBRATION_SUFFIXES = (".json", ".xml")


def run(args) -> int:
    import os
    import sys

    from ..runtime.errors import FtcalError
    from ..workflow.compensation import compensate

    model = args.robot_model
    if model is not None and (model.lower().endswith(CALIBRATION_SUFFIXES) or os.path.isfile(model)):
        if args.calibration is not None:
            raise FtcalError(f"--calibration {args.calibration}: {model} is a calibration model file too; give "
                             "one calibration, as --calibration CAL.json.")
        print(f"notice: {model} read as --calibration (the calibration model's option is now --calibration "
              "CAL.json; --model NAME names a robot model, as in the other commands)", file=sys.stderr)
        args.calibration, args.robot_model = model, None
    if args.robot_model is not None and args.robot_urdf is not None:
        raise FtcalError("--model: not allowed with --urdf (give one robot model).")
    require_suffix(args.output, (".csv", ".parquet"), "-o")
    inputs, gravity = inputs_of(args), source_keywords(args)
    check_not_input(args.output, [args.payload, *args.data] + ([args.calibration] if args.calibration else []))
    result = compensate(args.payload, args.data, calibration=args.calibration, inputs=inputs, **gravity)
    result.save(args.output)
    print(f"wrote {len(result.table)} contact wrenches to {args.output}", file=sys.stderr)
    return 0
