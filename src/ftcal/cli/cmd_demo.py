"""``ftcal demo``: the paper's experiment on simulated data, end to end."""

from __future__ import annotations

import os
from pathlib import Path

from ._common import nonnegative_int


def register(sub) -> None:
    p = sub.add_parser("demo", help="simulate the paper's experiment and calibrate (no robot needed)")
    p.add_argument("--out", default="ftcal-demo", metavar="DIR",
                   help="folder for recordings, summary.json and report.html (default ftcal-demo/)")
    p.add_argument("--seed", type=nonnegative_int, default=0, help="simulation seed, >= 0 (default 0)")
    p.add_argument("--quick", action="store_true", help="a smaller experiment (a few recordings)")
    p.set_defaults(func=run)


def run(args) -> int:
    from ..demo import DemoConfig, format_tables, run_demo

    from ..errors import FtcalError

    out = Path(args.out)
    if out.exists() and not out.is_dir():
        raise FtcalError(f"--out {out}: exists and is not a folder; give a folder for the demo's files.")
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise FtcalError(f"--out {out}: cannot create the folder ({exc.strerror or exc}).") from None
    if not os.access(out, os.W_OK | os.X_OK):
        raise FtcalError(f"--out {out}: the folder is not writable.")
    summary = run_demo(DemoConfig(out_dir=out, seed=args.seed, quick=args.quick))
    print(format_tables(summary))
    print(f"\n{summary['n_train_samples']} training / {summary['n_validation_samples']} validation samples; "
          f"done in {summary['elapsed_s']:.0f} s")
    print(f"wrote {out / 'summary.json'} and {out / 'report.html'}")
    return 0
