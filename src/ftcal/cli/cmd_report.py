"""``ftcal report``: evaluate model files on data files and write one self-contained HTML page."""

from __future__ import annotations

import argparse
from pathlib import Path

from ..core.limits import TARE_MODES
from ._common import add_label_options, column_list
from ._examples import epilog

MODEL_SUFFIXES = (".json", ".xml")
DATA_SUFFIXES = (".csv", ".parquet", ".pq")
REPORT_SUFFIXES = (".html", ".htm")


def register(sub) -> None:
    p = sub.add_parser(
        "report", **epilog("report"), help="HTML report comparing models on validation data",
        description="Evaluate every model file on the data files (the validation set) and write one "
                    "self-contained HTML page: per-axis validation errors with BestFit, force and torque "
                    "norms, the data coverage, the temperature effect, the validation curve over degree, "
                    "the LASSO path, and tables of all models. Model files (.json, .xml) and data files "
                    "(.csv, .parquet) are told apart by extension.")
    p.add_argument("files", nargs="+", metavar="FILE", help="model files (.json, .xml) and data files (.csv, .parquet)")
    p.add_argument("-o", "--output", metavar="HTML", required=True, help="the report file (.html)")
    p.add_argument("--train", action="append", default=[], metavar="DATA",
                   help="training data file (repeatable): adds training metrics and plots its coverage")
    p.add_argument("--inputs", type=column_list, metavar="C1,C2,...",
                   help="input columns to read (default: every input any model uses)")
    p.add_argument("--outputs", type=column_list, metavar="C1,...",
                   help="reference output columns (default: the models' outputs)")
    add_label_options(p, group_help="column naming groups, e.g. the load case (default: the 'load' column ftcal "
                                    "dataset writes when every file has one, else one per file)")
    p.add_argument("--title", default="ftcal calibration report", help="page title")
    p.add_argument("--baseline", metavar="identity|MODEL",
                   help="add a section comparing every model with a baseline, as ftcal evaluate --baseline: "
                        "'identity' (the inputs already are the wrench: the vendor's matrix) or a model file")
    p.add_argument("--tare", choices=TARE_MODES, default="none",
                   help="remove each recording's offset at its first static hold from the models and the baseline "
                        "alike (first-hold; per-file: once per file; none, the default), as ftcal evaluate --tare")
    p.set_defaults(func=run)


def split_files(files: list[str]) -> tuple[list[str], list[str]]:
    """(model files, data files) by extension; anything else is an error."""
    from ..runtime.errors import FtcalError

    models, data = [], []
    for name in files:
        suffix = Path(name).suffix.lower()
        if suffix in MODEL_SUFFIXES:
            models.append(name)
        elif suffix in DATA_SUFFIXES:
            data.append(name)
        else:
            raise FtcalError(f"{name}: unknown file type {suffix or '(no extension)'!r}; model files end in "
                             f"{', '.join(MODEL_SUFFIXES)} and data files in {', '.join(DATA_SUFFIXES)}.")
    if not models:
        raise FtcalError("No model files given (.json or .xml).")
    if not data:
        raise FtcalError("No data files given (.csv or .parquet) to evaluate the models on.")
    return models, data


def run(args: argparse.Namespace) -> int:
    from ..runtime.errors import FtcalError
    from ..workflow.evaluation import report

    model_paths, data_paths = split_files(args.files)
    out = Path(args.output)
    if out.suffix.lower() not in REPORT_SUFFIXES:
        raise FtcalError(f"--output {out}: must end in .html.")
    for name in args.train:
        if Path(name).suffix.lower() not in DATA_SUFFIXES:
            raise FtcalError(f"--train {name}: data files end in {', '.join(DATA_SUFFIXES)}.")
    result = report(model_paths, data_paths, out, train=args.train, inputs=args.inputs, outputs=args.outputs,
                    segment_by=args.segment_by, group_by=args.group_by, title=args.title,
                    baseline=args.baseline, tare=args.tare)
    print(result.summary())
    return 0
