"""``ftcal sensors``: the F/T sensors, joints and mass beyond each sensor of a robot model.

Also home of the robot arguments shared by ``expected`` and ``dataset``.
"""

from __future__ import annotations

import argparse

from ._examples import epilog


def add_robot_arguments(parser: argparse.ArgumentParser, required: bool = True) -> None:
    """--urdf PATH | --model NAME (optional unless ``required``), --ft-joint JOINT [--ft-frame LINK],
    --payload SPEC..., --base FRAME."""
    which = parser.add_mutually_exclusive_group(required=required)
    which.add_argument("--urdf", metavar="PATH", help="URDF file of the robot")
    which.add_argument("--model", metavar="NAME",
                       help="robot model shipped by icub-models, e.g. iCubGenova04")
    parser.add_argument("--ft-joint", metavar="JOINT",
                        help="declare an F/T sensor (named JOINT) on this fixed joint of a plain URDF; it reports "
                             "the wrench the child link applies on the parent link, in the sensor frame")
    parser.add_argument("--ft-frame", metavar="LINK",
                        help="sensor frame of --ft-joint: a link rigidly attached to the joint's child link "
                             "(default: the child link frame)")
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


def declared_sensors(args: argparse.Namespace) -> tuple:
    """The sensor declared by --ft-joint/--ft-frame, as a tuple of SensorDeclaration (empty if none)."""
    from ..robot import SensorDeclaration
    from ..runtime.errors import FtcalError

    if args.ft_joint is None:
        if args.ft_frame is not None:
            raise FtcalError("--ft-frame needs --ft-joint (the fixed joint the sensor sits on).")
        return ()
    return (SensorDeclaration(args.ft_joint, args.ft_frame),)


def load_robot(args: argparse.Namespace, payloads: bool = True):
    """The robot model of the parsed arguments, with its declared sensor and (if ``payloads``) --payload specs."""
    from ..robot import RobotModel, parse_payload_spec

    robot = RobotModel.load(urdf=args.urdf, name=args.model, declared=declared_sensors(args))
    if not payloads:
        return robot
    payloads = [parse_payload_spec(spec) for spec in args.payload]
    return robot.with_payloads(payloads) if payloads else robot


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "sensors", **epilog("sensors"), help="list F/T sensors, joints and the mass beyond each sensor",
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
        from ..robot.declare import no_sensor_hint

        print(f"F/T sensors: none; {no_sensor_hint(robot.urdf_text)}")
    else:
        print(f"F/T sensors ({len(rows) - 1}):")
        widths = [max(len(r[i]) for r in rows) for i in range(len(rows[0]))]
        for r in rows:
            print("  " + "  ".join(c.ljust(w) for c, w in zip(r, widths)).rstrip())
    print(f"joints ({len(robot.joint_names)}): " + ", ".join(robot.joint_names))
    return 0
