"""``ftcal predict``: apply a model to raw sensor data."""

from __future__ import annotations

from ..core.limits import FREE_RUN_STARTS, PREDICTION_MODES
from ._common import ARX_SEGMENT_HELP, add_label_options, add_scheduler_option, require_suffix
from ._examples import epilog


def register(sub) -> None:
    p = sub.add_parser("predict", **epilog("predict"), help="predict the wrench from raw channels")
    p.add_argument("model", metavar="MODEL", help="model file (ftcal JSON or paper XML)")
    p.add_argument("data", nargs="+", metavar="DATA", help="CSV or Parquet files with the model's input columns")
    p.add_argument("-o", "--output", required=True, metavar="OUT.csv|OUT.parquet",
                   help="predicted wrench, one column per model output (Fx..Tz: N, N·m), one row per input row "
                        "of all DATA files in order; .csv or .parquet")
    p.add_argument("--mode", choices=PREDICTION_MODES, default="free-run",
                   help="ARX prediction mode: free-run (default: fed-back predictions, as on the robot, where no "
                        "reference wrench exists) or one-step (measured past outputs, which DATA must hold; "
                        "'ftcal evaluate' defaults to it, the paper's evaluation). The mode that ran is printed")
    p.add_argument("--start", choices=FREE_RUN_STARTS, default="zeros",
                   help="ARX free-run history at each segment start: zeros (default, the paper's code: the "
                        "first max(na,nb) rows predict 0) or measured (the first measured output when DATA "
                        "holds the output columns, else the steady state of the first input, as the "
                        "generated C code's NAME_init(s, u0, NULL))")
    add_label_options(p, ARX_SEGMENT_HELP, group_help=None)
    add_scheduler_option(p)
    p.set_defaults(func=run)


def run(args) -> int:
    import sys

    from ..workflow.evaluation import predict

    require_suffix(args.output, (".csv", ".parquet"), "-o")
    result = predict(args.model, args.data, output=args.output, mode=args.mode, start=args.start,
                     segment_by=args.segment_by, scheduler=args.scheduler)
    for note in result.notes:
        print(note, file=sys.stderr)
    print(result.summary(), file=sys.stderr)
    return 0
