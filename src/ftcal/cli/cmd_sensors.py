"""``ftcal sensors``: the F/T sensors, joints and mass beyond each sensor of a robot model.

Also home of the robot arguments shared by ``expected`` and ``dataset``.
"""

from __future__ import annotations

import argparse


def add_robot_arguments(parser: argparse.ArgumentParser) -> None:
    """--urdf PATH | --model NAME, --payload SPEC..., --base FRAME."""
    which = parser.add_mutually_exclusive_group(required=True)
    which.add_argument("--urdf", metavar="PATH", help="URDF file of the robot")
    which.add_argument("--model", metavar="NAME",
                       help="robot model shipped by icub-models, e.g. iCubGenova04")
    parser.add_argument("--payload", metavar="SPEC", action="append", default=[],
                        help="attach a payload FRAME:MASS[@X,Y,Z][/IXX,IYY,IZZ[,IXY,IXZ,IYZ]] "
                             "(kg, m, kg m²; COM and inertia in FRAME); repeatable")
    parser.add_argument("--base", metavar="FRAME", default=None,
                        help="fixed base frame (default: root_link if the URDF has it, else its base link)")


def add_cache_arguments(parser: argparse.ArgumentParser) -> None:
    """--cache-dir DIR, --no-cache: where expected wrenches are cached (ftcal.robot.cache)."""
    parser.add_argument("--cache-dir", metavar="DIR",
                        help="folder of the expected-wrench cache (default $XDG_CACHE_HOME/ftcal, "
                             "else ~/.cache/ftcal)")
    parser.add_argument("--no-cache", action="store_true", help="neither read nor write the cache")


def load_robot(args: argparse.Namespace):
    """The robot model of the parsed arguments, with --payload specs attached."""
    from ..robot import RobotModel, parse_payload_spec

    robot = RobotModel.load(urdf=args.urdf, name=args.model)
    payloads = [parse_payload_spec(spec) for spec in args.payload]
    return robot.with_payloads(payloads) if payloads else robot


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "sensors", help="list F/T sensors, joints and the mass beyond each sensor",
        description="List the six-axis F/T sensors of a robot model (name, joint, links), the mass "
                    "on the far side of each sensor as seen from the base frame (payloads included), "
                    "and the movable joints in the order ftcal uses.")
    add_robot_arguments(parser)
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    robot = load_robot(args)
    _, base = robot.base_frame(args.base)
    print(f"model: {robot.source}")
    print(f"base frame: {base}; total mass {robot.total_mass():.4f} kg")
    if robot.payloads:
        print("payloads: " + "; ".join(f"{p.mass:g} kg on {p.frame}" for p in robot.payloads))
    rows = [("sensor", "joint", "parent link", "child link", "links beyond", "mass beyond [kg]")]
    for s in robot.ft_sensors:
        rows.append((s.name, s.joint, s.parent_link, s.child_link,
                     str(len(robot.links_beyond(s, base))), f"{robot.mass_beyond(s, base):.4f}"))
    if len(rows) == 1:
        print("F/T sensors: none")
    else:
        print(f"F/T sensors ({len(rows) - 1}):")
        widths = [max(len(r[i]) for r in rows) for i in range(len(rows[0]))]
        for r in rows:
            print("  " + "  ".join(c.ljust(w) for c, w in zip(r, widths)).rstrip())
    print(f"joints ({len(robot.joint_names)}): " + ", ".join(robot.joint_names))
    return 0
