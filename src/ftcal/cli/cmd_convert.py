"""``ftcal convert``: write a model or payload file in another format (targets: :mod:`ftcal.files.targets`)."""

from __future__ import annotations

from ..files.targets import TARGETS
from ._examples import epilog


def safe_name(text: str) -> str:
    import argparse

    from ..runtime.checks import check_safe_name
    from ..runtime.errors import FtcalError

    try:
        return check_safe_name(text)
    except FtcalError as exc:  # argparse adds its own stop
        raise argparse.ArgumentTypeError(str(exc).rstrip(".")) from None


def register(sub) -> None:
    listing = "; ".join(f"{name}: {spec.summary}" for name, spec in TARGETS.items())
    p = sub.add_parser("convert", **epilog("convert"), help=f"convert a model or payload file ({', '.join(TARGETS)})")
    p.add_argument("model", metavar="FILE",
                   help="ftcal JSON or paper XML model file, or an ftcal payload file (ros-yaml, ft-tools-ros2)")
    # Checked by the registry, not argparse choices, so an unknown target is one error line.
    p.add_argument("--to", required=True, metavar="TARGET", help=f"output format ({listing})")
    p.add_argument("-o", "--output", required=True, metavar="OUT",
                   help="output file; for icub-firmware a file or a directory for matrix_<serial>.txt; "
                        "for c a directory for NAME.h and NAME.c; for c-runtime NAME.h; for cpp-runtime NAME.hpp "
                        "(NAME.h is written beside it)")
    p.add_argument("--serial", type=safe_name, help="sensor serial number for the firmware file name "
                                                  "(letters, digits, '_', '-', '.')")
    p.add_argument("--sensor", help="sensor name in the wholeBodyDynamics configuration (wbd)")
    p.add_argument("--name", help="C identifier prefixing the generated files and functions (c; default "
                                  "ftcal_model; c-runtime, cpp-runtime: default the header's name, e.g. ft_runtime)")
    p.add_argument("--float", dest="single_precision", action="store_true",
                   help="generate single-precision C (c; reports the measured error against double)")
    p.add_argument("--payload-file", dest="payload_files", action="append", metavar="[NAME=]TOOL.json",
                   help="c-runtime, cpp-runtime: a tool of the library compiled into the header (repeatable; "
                        "NAME defaults to the file's stem; tool 0 is none)")
    p.add_argument("--frame", help="ros-yaml, admittance-controller, gravity-compensation-filter: the F/T sensor "
                                   "frame (ros-yaml: gripper_com_frame_id; default: the "
                                   "payload file's frame); ignored by ft-tools-ros2, which has no frame names, "
                                   "and by model targets")
    p.add_argument("--com-frame", help="ros-yaml only: gripper_com_child_frame_id, the name of the COM frame "
                                       "(default gripper_com)")
    p.add_argument("--world-frame", help="gravity-compensation-filter only: world_frame, the fixed frame its "
                                         "gravity_field is given in (default world)")
    p.set_defaults(func=run)


def run(args) -> int:
    from ..workflow.export import convert

    result = convert(args.model, args.to, args.output, serial=args.serial, sensor=args.sensor, name=args.name,
                     single_precision=args.single_precision, frame=args.frame, com_frame=args.com_frame,
                     payload_files=args.payload_files, world_frame=args.world_frame)
    print(result.summary())
    return 0
