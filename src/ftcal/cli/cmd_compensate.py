"""``ftcal compensate``: the contact wrench, with the bias and the tool's weight (and inertia) removed."""

from __future__ import annotations

from ._common import column_list, require_suffix
from .cmd_payload import WRENCH_DEFAULT, add_kinematics_options, check_not_input, kinematics_source

OUTPUT_COLUMNS = ("Fx", "Fy", "Fz", "Tx", "Ty", "Tz")


def register(sub) -> None:
    p = sub.add_parser("compensate", help="subtract the bias and the payload's gravity wrench",
                       description="Contact wrench = measured wrench (or the wrench a calibration model "
                                   "predicts from the raw channels) minus the bias minus the payload's gravity "
                                   "wrench (and, with --dynamic, its inertial wrench), written as Fx..Tz in the "
                                   "sign of the readings (replacing any Fx..Tz columns of DATA); the other "
                                   "columns are kept.")
    p.add_argument("payload", metavar="PAYLOAD.json", help="payload file from `ftcal payload`")
    p.add_argument("data", nargs="+", metavar="DATA", help="CSV or Parquet files")
    p.add_argument("-o", "--output", required=True, metavar="OUT.csv|OUT.parquet",
                   help="one table with the rows of all DATA files in order")
    p.add_argument("--model", metavar="CAL.json",
                   help="calibration model: the measured wrench is its prediction from its input columns")
    p.add_argument("--wrench", type=column_list, metavar="FX,FY,FZ,TX,TY,TZ",
                   help="measured wrench columns without --model (default: the payload file's, else u1,...,u6)")
    add_kinematics_options(p)
    p.set_defaults(func=run)


def run(args) -> int:
    import sys
    from pathlib import Path

    import pandas as pd

    from ..errors import FtcalError
    from ..io.model_files import read_model
    from ..io.payload_json import load_payload
    from ..io.tables import numeric_columns, read_table, write_table
    from ..payload.compensate import contact_wrench

    require_suffix(args.output, (".csv", ".parquet"), "-o")
    check_not_input(args.output, [args.payload, *args.data] + ([args.model] if args.model else []))
    payload = load_payload(args.payload)
    if args.dynamic and payload.inertia is None:
        raise FtcalError(f"{args.payload}: has no inertia (identified without --dynamic); "
                         "compensate without --dynamic or re-identify with it.")
    source = kinematics_source(args)
    model = read_model(args.model) if args.model else None
    columns = args.wrench or tuple(payload.fit.get("wrench_columns", WRENCH_DEFAULT))
    if model is None and len(columns) != 6:
        raise FtcalError(f"--wrench needs 6 columns Fx,Fy,Fz,Tx,Ty,Tz; got {','.join(columns)}.")
    if model is not None and len(model.output_names_) != 6:
        raise FtcalError(f"{args.model}: the model has {len(model.output_names_)} outputs; a wrench needs 6.")
    parts = []
    for path in args.data:
        frame = read_table(path)
        if model is not None:
            measured = model.predict(numeric_columns(frame, model.input_names_, Path(path), "input"))
        else:
            measured = numeric_columns(frame, columns, Path(path), "wrench")
        contact = contact_wrench(measured, payload, source(frame, str(path)))
        out = frame.copy()
        for j, name in enumerate(OUTPUT_COLUMNS):
            out[name] = contact[:, j]
        parts.append(out)
    table = pd.concat(parts, ignore_index=True) if len(parts) > 1 else parts[0]
    write_table(table, args.output)
    print(f"wrote {len(table)} contact wrenches to {args.output}", file=sys.stderr)
    return 0
