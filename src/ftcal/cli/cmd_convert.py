"""``ftcal convert``: write a model in another format (targets: :mod:`ftcal.export.targets`)."""

from __future__ import annotations

from ..export.targets import TARGETS


def register(sub) -> None:
    listing = "; ".join(f"{name}: {spec.summary}" for name, spec in TARGETS.items())
    p = sub.add_parser("convert", help=f"convert a model file ({', '.join(TARGETS)})")
    p.add_argument("model", metavar="MODEL", help="ftcal JSON or paper XML model file")
    # Checked by the registry, not argparse choices, so an unknown target is one error line.
    p.add_argument("--to", required=True, metavar="TARGET", help=f"output format ({listing})")
    p.add_argument("-o", "--output", required=True, metavar="OUT",
                   help="output file; for icub-firmware a file or a directory for matrix_<serial>.txt; "
                        "for c a directory for NAME.h and NAME.c")
    p.add_argument("--serial", help="sensor serial number for the firmware file name")
    p.add_argument("--sensor", help="sensor name in the wholeBodyDynamics configuration (wbd)")
    p.add_argument("--name", help="C identifier prefixing the generated files and functions (c; default "
                                  "ftcal_model)")
    p.add_argument("--float", dest="single_precision", action="store_true",
                   help="generate single-precision C (c; reports the measured error against double)")
    p.set_defaults(func=run)


def run(args) -> int:
    from ..export.targets import convert

    written = convert(args.model, args.to, args.output,
                      {"serial": args.serial, "sensor": args.sensor, "name": args.name,
                       "single_precision": args.single_precision})
    for note in written.notes:
        print(note)
    print(f"wrote {', '.join(str(p) for p in written.paths)}")
    return 0
