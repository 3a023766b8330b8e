"""``ftcal compensate``: the contact wrench, with the bias and the tool's weight (and inertia) removed."""

from __future__ import annotations

from ._common import column_list, require_suffix
from ._examples import epilog
from ._gravity import add_kinematics_options, add_robot_source_options, check_not_input, kinematics_source


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
    p.add_argument("--model", metavar="CAL.json",
                   help="calibration model: the measured wrench is its prediction from its input columns")
    p.add_argument("--wrench", type=column_list, metavar="FX,FY,FZ,TX,TY,TZ",
                   help="measured wrench columns without --model (default: the payload file's, else u1,...,u6)")
    add_kinematics_options(p)
    add_robot_source_options(p, named_models=False)
    for action in p._actions:
        if action.dest == "g":
            action.help = "gravity magnitude, m/s² (default: the payload file's, which its mass was identified with)"
    p.set_defaults(func=run, g=None)


def run(args) -> int:
    import sys

    import pandas as pd

    from ..data.tables import write_table
    from ..files.model_files import read_model
    from ..files.payload_json import load_payload
    from ..payload.compensate import warn_undetermined
    from ..payload.tables import compensate_table
    from ..runtime.errors import FtcalError

    require_suffix(args.output, (".csv", ".parquet"), "-o")
    check_not_input(args.output, [args.payload, *args.data] + ([args.model] if args.model else []))
    payload = load_payload(args.payload)
    if args.dynamic and payload.inertia is None:
        raise FtcalError(f"{args.payload}: has no inertia (identified without --dynamic); "
                         "compensate without --dynamic or re-identify with it.")
    if args.g is None:
        args.g = payload.gravity
    elif abs(args.g - payload.gravity) > 1e-9 * payload.gravity:
        raise FtcalError(f"--g {args.g:g}: {args.payload} was identified with g = {payload.gravity:g} m/s² (its "
                         "mass times g is what the data determined); leave --g out.")
    source = kinematics_source(args)
    model = read_model(args.model) if args.model else None
    parts = [compensate_table(path, payload, source, wrench=args.wrench, model=model, time_column=args.time,
                              warn_out_of_range=False)
             for path in args.data]
    outside = sum(part.attrs.get("undetermined_samples", 0) for part in parts)
    table = pd.concat(parts, ignore_index=True) if len(parts) > 1 else parts[0]
    warn_undetermined(payload, outside, len(table), ", ".join(args.data))  # once for all the files
    if model is not None:  # one out-of-range warning for all the files
        import warnings

        from ..core.ranges import RangeSums, describe, span_of
        from ..runtime.errors import OutOfRangeWarning

        inputs = table[list(model.input_names_)].to_numpy(dtype=float)
        ranges = RangeSums.of(inputs, model.input_range_, outside_span=span_of(model, inputs))
        message = describe(ranges.summary(model.input_names_))
        if message:
            warnings.warn(message, OutOfRangeWarning, stacklevel=2)
    write_table(table, args.output)
    print(f"wrote {len(table)} contact wrenches to {args.output}", file=sys.stderr)
    return 0
