"""``ftcal convert``: write a model in another format."""

from __future__ import annotations


SUFFIXES = {"json": (".json",), "paper-xml": (".xml",)}


def safe_name(text: str) -> str:
    import argparse

    from .._checks import check_safe_name
    from ..errors import FtcalError

    try:
        return check_safe_name(text, "")
    except FtcalError:
        raise argparse.ArgumentTypeError(f"{text!r}: use 1 to 64 letters, digits, '_', '-' or '.' (not first); "
                                         "it becomes part of a file name") from None


def register(sub) -> None:
    p = sub.add_parser("convert", help="convert a model file (json, paper-xml, icub-firmware, wbd)")
    p.add_argument("model", metavar="MODEL", help="ftcal JSON or paper XML model file")
    p.add_argument("--to", required=True, choices=("json", "paper-xml", "icub-firmware", "wbd"))
    p.add_argument("-o", "--output", required=True, metavar="OUT",
                   help="output file (for icub-firmware: a file or a directory for matrix_<serial>.txt)")
    p.add_argument("--serial", type=safe_name, help="sensor serial number for the firmware file name "
                                                  "(letters, digits, '_', '-', '.')")
    p.add_argument("--sensor", help="sensor name in the wholeBodyDynamics configuration (wbd)")
    p.set_defaults(func=run)


def run(args) -> int:
    from ..io.model_files import read_model_file, write_model

    from ._common import require_suffix

    if args.to in SUFFIXES:
        require_suffix(args.output, SUFFIXES[args.to], "-o")
    loaded = read_model_file(args.model)
    written = write_model(loaded.model, args.output, args.to, sources=loaded.sources or (args.model,),
                          input_units=loaded.input_units, output_units=loaded.output_units,
                          serial=args.serial, sensor=args.sensor)
    print(f"wrote {written}")
    return 0
