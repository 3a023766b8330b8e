"""``ftcal sensors``: the F/T sensors, joints and mass beyond each sensor of a robot model."""

from __future__ import annotations

import argparse

from ._examples import epilog
from ._robot import add_robot_arguments, robot_keywords


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "sensors", **epilog("sensors"), help="list F/T sensors, joints and the mass beyond each sensor",
        description="List the six-axis F/T sensors of a robot model (name, joint, links), the mass "
                    "on the far side of each sensor as seen from the base frame (payloads included), "
                    "and the movable joints in the order ftcal uses.")
    add_robot_arguments(parser)
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from ..workflow.datasets import robot_sensors
    from ._common import flag_of

    result = robot_sensors(**robot_keywords(args), base=args.base)
    print("\n".join(result.lines(flag_of)))
    return 0
