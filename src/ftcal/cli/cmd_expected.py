"""``ftcal expected``: expected F/T wrenches for a table of joint positions."""

from __future__ import annotations

import argparse

from ..core.limits import MISSING_JOINTS
from ._common import add_scheduler_option, finite_float, require_suffix
from ._examples import epilog
from ._robot import add_cache_arguments, add_robot_arguments, robot_keywords


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "expected", **epilog("expected"), help="expected F/T wrenches for joint positions (iDynTree)",
        description="Compute the wrench each F/T sensor should measure for every row of a joint table "
                    "(static, fixed base). Output: the wrench the sensor's child link applies on its "
                    "parent link, in the sensor frame, torque about the sensor origin (N, N m).")
    add_robot_arguments(parser)
    parser.add_argument("--joints", metavar="FILE", required=True,
                        help="CSV/Parquet, one column per joint named as in the URDF (radians); every joint the "
                             "sensors' wrench depends on (chain from the base, and beyond the sensor) must be "
                             "there unless --missing-joints zero; an optional 'time' column is copied to the output")
    parser.add_argument("--sensor", metavar="NAME", action="append", default=[],
                        help="F/T sensor (sensor or joint name); repeatable; default all")
    parser.add_argument("--gravity", metavar=("X", "Y", "Z"), nargs=3, type=finite_float,
                        default=(0.0, 0.0, -9.81), help="gravity in base-frame axes, m/s² (default 0 0 -9.81)")
    parser.add_argument("--degrees", action="store_true", help="joint positions are in degrees")
    parser.add_argument("--missing-joints", choices=MISSING_JOINTS, default="refuse",
                        help="a joint the wrench depends on that the table lacks: refuse (default), or zero "
                             "(you say it is at 0 rad)")
    parser.add_argument("--workers", type=int, default=2, help="worker processes (default 2)")
    add_scheduler_option(parser)
    add_cache_arguments(parser)
    parser.add_argument("-o", "--output", metavar="OUT", required=True, help="output .csv or .parquet")
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """With --scheduler the joints file is one task (a worker reads it and computes in one process)."""
    from ..runtime.executors import open_executor
    from ..workflow.datasets import expected

    require_suffix(args.output, (".csv", ".parquet", ".pq"), "-o")
    keywords = dict(robot_keywords(args), base=args.base, sensor=tuple(args.sensor), gravity=tuple(args.gravity),
                    degrees=args.degrees, workers=args.workers, no_cache=args.no_cache, cache_dir=args.cache_dir,
                    missing_joints=args.missing_joints)
    if args.scheduler:
        with open_executor(args.scheduler) as executor:
            result = expected(args.joints, executor=executor, **keywords)
    else:
        result = expected(args.joints, **keywords)
    result.save(args.output)
    print(f"wrote {result.summary()} to {args.output}")
    return 0
