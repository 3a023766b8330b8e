"""``ftcal predict``: apply a model to raw sensor data."""

from __future__ import annotations

from ..core.limits import FREE_RUN_STARTS, PREDICTION_MODES
from ._common import add_scheduler_option, require_suffix
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
    p.add_argument("--segment-by", metavar="COL", help="column separating segments (ARX)")
    add_scheduler_option(p)
    p.set_defaults(func=run)


def run(args) -> int:
    import sys
    import warnings

    from ..core.ranges import describe, loads_text
    from ..files.model_files import read_model
    from ..runtime.errors import OutOfRangeWarning

    require_suffix(args.output, (".csv", ".parquet"), "-o")
    model = read_model(args.model)
    if not model.is_static:
        print(f"ARX model: {args.mode} prediction"
              + (f" from {args.start} history" if args.mode == "free-run" else " (measured past outputs)"),
              file=sys.stderr)
    n_rows, ranges = predict_streaming(args, model)
    # One warning for the whole command (as CalibrationModel.predict on data read whole), never per file.
    message = ranges and describe(ranges.summary(model.input_names_))
    loads = ranges and ranges.loads and loads_text(ranges.loads.summary(model.output_range_, model.output_names_),
                                                   "the predicted loads")
    message = " ".join(part for part in (message, loads) if part)  # one line: inputs, then loads
    if message:
        warnings.warn(message, OutOfRangeWarning, stacklevel=2)
    print(f"wrote {n_rows} predictions to {args.output}", file=sys.stderr)
    return 0


def predict_streaming(args, model) -> tuple[int, int]:
    """Predict file by file (``--scheduler``: one Dask task per file); static models chunk by chunk.

    Each task writes a part file in a temporary folder beside the output (on
    Dask, the workers must see that folder too); the parts are then joined in
    input order into the output, which appears only when everything worked.

    Returns
    -------
    (n_rows, ranges) : int and :class:`~ftcal.core.ranges.RangeSums` (None without rows)
    """
    import os
    import shutil
    import tempfile
    from pathlib import Path

    from ..data.streaming import join_parts, predict_part
    from ..runtime.atomic import check_not_an_input
    from ..runtime.errors import FtcalError
    from ..runtime.executors import open_executor

    output = Path(args.output)
    check_not_an_input(output, "-o")
    try:
        output.parent.mkdir(parents=True, exist_ok=True)
        folder = tempfile.mkdtemp(prefix=f".{output.name}.parts-", dir=output.parent)
    except OSError as exc:
        raise FtcalError(f"{output}: cannot create the output file ({exc.strerror or exc}).") from None
    try:
        tasks = [(path, os.path.join(folder, f"part-{index:05d}{output.suffix.lower()}"))
                 for index, path in enumerate(args.data)]
        with open_executor(args.scheduler) as executor:
            counts = executor.map(predict_part, tasks, model, args.mode, args.segment_by, args.start,
                                  description="predict")
        join_parts([part for _, part in tasks], output)
    finally:
        shutil.rmtree(folder, ignore_errors=True)
    ranges = [r for _, r in counts if r is not None]
    return sum(n for n, _ in counts), (sum(ranges[1:], ranges[0]) if ranges else None)
