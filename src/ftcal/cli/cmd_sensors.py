"""``ftcal sensors``: the F/T sensors, joints and mass beyond each sensor of a robot model."""

from __future__ import annotations

import argparse

from ._examples import epilog
from ._robot import add_robot_arguments, load_robot


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
        from ._common import flag_of

        print(f"F/T sensors: none; {no_sensor_hint(robot.urdf_text, flag_of)}")
    else:
        print(f"F/T sensors ({len(rows) - 1}):")
        widths = [max(len(r[i]) for r in rows) for i in range(len(rows[0]))]
        for r in rows:
            print("  " + "  ".join(c.ljust(w) for c, w in zip(r, widths)).rstrip())
    print(f"joints ({len(robot.joint_names)}): " + ", ".join(robot.joint_names))
    return 0
