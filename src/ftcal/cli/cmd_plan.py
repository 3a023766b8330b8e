"""``ftcal plan``: choose the poses and loads of a calibration experiment, and their order."""

from __future__ import annotations

import argparse

from ..core.limits import MAX_DEGREE, PLAN_DEFAULTS, PLAN_OBJECTIVES
from ._common import finite_float, nonnegative_int, require_suffix
from ._examples import epilog
from ._robot import add_robot_arguments, robot_keywords

PLAN_NOTE = "No collision checking: ftcal checks no pose against obstacles; check every pose on your robot before running it."


def positive_int(text: str) -> int:
    value = nonnegative_int(text)
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be >= 1, got {text!r}")
    return value


def joint_range(text: str) -> tuple[str, float, float]:
    """``J:LO:HI`` (rad)."""
    name, *bounds = text.rsplit(":", 2)
    if len(bounds) != 2 or not name:
        raise argparse.ArgumentTypeError(f"expected JOINT:LOW:HIGH in rad, got {text!r}")
    low, high = (finite_float(b) for b in bounds)
    return name, low, high


def joint_pin(text: str) -> tuple[str, float]:
    """``J=V`` (rad)."""
    name, sep, value = text.partition("=")
    if not sep or not name:
        raise argparse.ArgumentTypeError(f"expected JOINT=VALUE in rad, got {text!r}")
    return name, finite_float(value)


def noise_pair(text: str) -> tuple[float, float]:
    parts = text.split(",")
    if len(parts) != 2:
        raise argparse.ArgumentTypeError(f"expected FORCE,TORQUE (N, N m), got {text!r}")
    values = tuple(finite_float(p) for p in parts)
    if min(values) <= 0:
        raise argparse.ArgumentTypeError(f"noise must be > 0, got {text!r}")
    return values  # type: ignore[return-value]


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "plan", help="choose the poses and loads of a calibration experiment (D-optimal), in execution order",
        description="Design a calibration (or payload identification) experiment: draw random joint "
                    "configurations within the limits, try each with every load, and choose the poses that "
                    "add most information (greedy D-optimal design), then order them: each load mounted "
                    "once, short joint travel, a return to a reference pose every few poses so drift can be "
                    "measured. ftcal does NO collision checking: the only safety limits are the joint limits, "
                    "--joint-range, --fixed and --min-height; check every pose before running it.",
        **epilog("plan", PLAN_NOTE))
    add_robot_arguments(parser)
    parser.add_argument("--sensor", metavar="NAME", help="F/T sensor (sensor or joint name; default: the only one)")
    parser.add_argument("--load", metavar="SPEC", action="append", default=[],
                        help="a load you can mount, FRAME:MASS[@X,Y,Z][/IXX,IYY,IZZ[,...]] as --payload, or "
                             "'none' for nothing; repeatable; the plan's 'load' column is its 0-based index "
                             "(default: none)")
    parser.add_argument("--poses", metavar="N", type=positive_int, required=True,
                        help="poses to design (the reference-pose visits come on top)")
    parser.add_argument("--objective", choices=PLAN_OBJECTIVES, default="calibration",
                        help="calibration: a polynomial calibration of --degree (default); payload: bias + "
                             "mass + centre of mass of each load")
    parser.add_argument("--degree", metavar="D", type=positive_int, default=PLAN_DEFAULTS["degree"],
                        help=f"degree of the calibration to design for, 1..{MAX_DEGREE} "
                             f"(default {PLAN_DEFAULTS['degree']})")
    parser.add_argument("--joint-range", metavar="J:LO:HI", type=joint_range, action="append", default=[],
                        help="narrow a joint of the chain to the sensor to [LO, HI] rad; repeatable")
    parser.add_argument("--fixed", metavar="J=V", type=joint_pin, action="append", default=[],
                        help="pin a joint at V rad; repeatable (joints off the chain to the sensor are 0 "
                             "unless pinned)")
    parser.add_argument("--min-height", metavar="H", type=finite_float,
                        help="keep the sensor origin at least H m above the base frame's xy-plane "
                             "(not a collision check)")
    parser.add_argument("--candidates", metavar="M", type=positive_int, default=PLAN_DEFAULTS["candidates"],
                        help=f"random configurations to choose from, each tried with every load "
                             f"(default {PLAN_DEFAULTS['candidates']})")
    parser.add_argument("--reference-every", metavar="K", type=positive_int,
                        default=PLAN_DEFAULTS["reference_every"],
                        help=f"return to the reference pose after every K poses (default "
                             f"{PLAN_DEFAULTS['reference_every']})")
    parser.add_argument("--noise", metavar="F,T", type=noise_pair, default=PLAN_DEFAULTS["noise"],
                        help="noise of one pose's reading, N and N m, for the payload weights and standard "
                             "errors (default %s,%s)" % PLAN_DEFAULTS["noise"])
    parser.add_argument("--from", dest="recorded", metavar="DATA", action="append", default=[],
                        help="a table of poses already recorded (one row per pose: Fx..Tz and/or joint "
                             "columns, and 'load'); the plan adds the poses that add most to it; repeatable")
    parser.add_argument("--seed", type=nonnegative_int, default=0, help="random seed, >= 0 (default 0)")
    parser.add_argument("--html", metavar="PAGE", help="also write an HTML page (coverage figure, comparison)")
    parser.add_argument("-o", "--output", metavar="CSV", required=True,
                        help="the plan: one row per pose in execution order, joint columns (rad), load, "
                             "reference (1 for the reference pose), expected Fx..Tz (N, N m)")
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from ..runtime.atomic import check_not_an_input
    from ..workflow.planning import plan_experiment

    require_suffix(args.output, (".csv",), "-o")
    if args.html:
        require_suffix(args.html, (".html", ".htm"), "--html")
        check_not_an_input(args.html, "html")
    result = plan_experiment(args.poses, **robot_keywords(args), base=args.base, sensor=args.sensor,
                             load=tuple(args.load),
                             objective=args.objective, degree=args.degree, joint_range=tuple(args.joint_range),
                             fixed=tuple(args.fixed), min_height=args.min_height, candidates=args.candidates,
                             reference_every=args.reference_every, noise=tuple(args.noise),
                             recorded=tuple(args.recorded), seed=args.seed)
    # The plan and its page are written together or not at all: a failing page never replaces the plan.
    result.save(args.output, args.html or None)
    print(result.summary())
    print(f"wrote {args.output} ({len(result.table)} rows)")
    if args.html:
        print(f"wrote {args.html}")
    return 0
