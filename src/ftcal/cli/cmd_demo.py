"""``ftcal demo``: the paper's experiment on simulated data, end to end."""

from __future__ import annotations

from pathlib import Path


def register(sub) -> None:
    p = sub.add_parser("demo", help="simulate the paper's experiment and calibrate (no robot needed)")
    p.add_argument("--out", default="ftcal-demo", metavar="DIR",
                   help="folder for recordings, summary.json and report.html (default ftcal-demo/)")
    p.add_argument("--seed", type=int, default=0, help="simulation seed (default 0)")
    p.add_argument("--quick", action="store_true", help="a smaller experiment (a few recordings)")
    p.set_defaults(func=run)


def run(args) -> int:
    from ..demo import DemoConfig, format_tables, run_demo

    out = Path(args.out)
    summary = run_demo(DemoConfig(out_dir=out, seed=args.seed, quick=args.quick))
    print(format_tables(summary))
    print(f"\n{summary['n_train_samples']} training / {summary['n_validation_samples']} validation samples; "
          f"done in {summary['elapsed_s']:.0f} s")
    print(f"wrote {out / 'summary.json'} and {out / 'report.html'}")
    return 0
