"""``ftcal predict``: apply a model to raw sensor data."""

from __future__ import annotations

from ._common import require_suffix


def register(sub) -> None:
    p = sub.add_parser("predict", help="predict the wrench from raw channels")
    p.add_argument("model", metavar="MODEL", help="model file (ftcal JSON or paper XML)")
    p.add_argument("data", nargs="+", metavar="DATA", help="CSV or Parquet files with the model's input columns")
    p.add_argument("-o", "--output", required=True, metavar="OUT.csv|OUT.parquet")
    p.add_argument("--mode", choices=("free-run", "one-step"), default="free-run",
                   help="ARX prediction mode; one-step needs the measured outputs in DATA")
    p.add_argument("--segment-by", metavar="COL", help="column separating segments (ARX)")
    p.set_defaults(func=run)


def run(args) -> int:
    import sys

    import numpy as np
    import pandas as pd

    from ..io.model_files import read_model
    from ..io.tables import read_dataset, write_table

    require_suffix(args.output, (".csv", ".parquet"), "-o")
    model = read_model(args.model)
    data = read_dataset(args.data, model.input_names_, model.output_names_ if args.mode == "one-step" else None,
                        segment_by=args.segment_by)
    with np.errstate(over="ignore", invalid="ignore"):  # overflow is refused below, in one line
        prediction = model.predict(data, mode=args.mode)
    write_table(pd.DataFrame(prediction, columns=list(model.output_names_)), args.output)
    n_out = int(model.out_of_range(data.inputs).sum())
    print(f"wrote {len(prediction)} predictions to {args.output}"
          + (f" ({n_out} samples outside the training range)" if n_out else ""), file=sys.stderr)
    return 0
