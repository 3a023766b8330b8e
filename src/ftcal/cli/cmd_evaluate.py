"""``ftcal evaluate``: metrics of a model on data with reference outputs."""

from __future__ import annotations

from ..core.limits import ARX_WARMUP, FREE_RUN_STARTS, PREDICTION_MODES, TARE_MODES
from ._common import ARX_SEGMENT_HELP, add_label_options, add_scheduler_option, print_json
from ._examples import epilog


def register(sub) -> None:
    p = sub.add_parser("evaluate", **epilog("evaluate"), help="metrics of a model on held-out data")
    p.add_argument("model", metavar="MODEL", help="model file (ftcal JSON or paper XML)")
    p.add_argument("data", nargs="+", metavar="DATA", help="CSV or Parquet files with the model's columns")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.add_argument("--mode", choices=PREDICTION_MODES, default="one-step",
                   help="ARX prediction mode: one-step (default, the paper's evaluation: measured past outputs, "
                        "which evaluation data hold) or free-run (fed-back predictions, as on the robot and "
                        "'ftcal predict''s default); the table scores this mode and says so, the other mode's "
                        "norm RMSE follows it")
    p.add_argument("--start", choices=FREE_RUN_STARTS, default="zeros",
                   help="ARX free-run history at each segment start: zeros (default, the paper's code: the "
                        "first max(na,nb) rows predict 0) or measured (ftcal's: the first measured output)")
    p.add_argument("--warmup", choices=ARX_WARMUP, default="drop",
                   help="ARX metrics: drop (default, as the paper's code) or keep the first max(na,nb) rows "
                        "of each segment")
    add_label_options(p, ARX_SEGMENT_HELP,
                      "groups of the baseline comparison, one fold each (default: the 'load' column ftcal "
                      "dataset writes when every file has one, else one per file)")
    p.add_argument("--baseline", metavar="identity|MODEL",
                   help="compare with a baseline on the same samples: 'identity' (the model's first six inputs "
                        "already are the wrench: the vendor's matrix) or another model file; prints each "
                        "axis' ratio to it and the verdict of the grouped folds (better, ties, worse)")
    p.add_argument("--tare", choices=TARE_MODES, default="none",
                   help="remove each recording's offset at its first static hold from the model and the baseline "
                        "alike, as users re-tare: first-hold (each recording), per-file (once per file) or none "
                        "(default)")
    add_scheduler_option(p)
    p.set_defaults(func=run)


def run(args) -> int:
    from ..workflow.evaluation import evaluate

    result = evaluate(args.model, args.data, mode=args.mode, start=args.start, warmup=args.warmup,
                      segment_by=args.segment_by, group_by=args.group_by, scheduler=args.scheduler,
                      baseline=args.baseline, tare=args.tare)
    if args.json:
        print_json(result.to_dict())
    else:
        print(result.summary())
    return 0
