"""Options shared by ``payload``, ``check`` and ``compensate``: where gravity (and motion) in the sensor frame comes from.

The CLI only maps its options onto the steps' keywords (:func:`source_keywords`); the steps build
the source (:mod:`ftcal.workflow.sources`), so every command and every Python caller gets the same
sources and the same messages.
"""

from __future__ import annotations

import argparse

from ._common import column_list, positive_float


def add_kinematics_options(p: argparse.ArgumentParser) -> None:
    """Gravity source (orientation or gravity columns), --g and the --dynamic motion columns."""
    source = p.add_mutually_exclusive_group()
    source.add_argument("--orientation", type=column_list, metavar="QX,QY,QZ,QW",
                        help="quaternion columns, ROS order x,y,z,w: rotation from the sensor frame to a "
                             "world frame with gravity along -z (e.g. qx,qy,qz,qw)")
    source.add_argument("--gravity-columns", type=column_list, metavar="GX,GY,GZ",
                        help="gravity vector in the sensor frame, m/s² (e.g. gx,gy,gz)")
    p.add_argument("--g", type=positive_float, default=9.81, metavar="M/S2",
                   help="gravity magnitude (default 9.81 m/s²)")
    p.add_argument("--dynamic", action="store_true",
                   help="use angular velocity/acceleration and linear acceleration too (10 inertial parameters)")
    p.add_argument("--angular-velocity", type=column_list, default=("wx", "wy", "wz"), metavar="WX,WY,WZ",
                   help="gyroscope columns in the sensor frame, rad/s (default wx,wy,wz; --dynamic)")
    p.add_argument("--linear-acceleration", type=column_list, default=("ax", "ay", "az"), metavar="AX,AY,AZ",
                   help="accelerometer columns at the sensor origin, sensor frame, m/s², gravity included "
                        "(default ax,ay,az; used with --dynamic when present, else the origin is at rest)")
    p.add_argument("--angular-acceleration", type=column_list, metavar="C1,C2,C3",
                   help="angular acceleration columns, rad/s² (default: differentiate the angular velocity)")
    p.add_argument("--time", metavar="COL",
                   help="time column in s (default: the column 'time' where there is one, to find the static "
                        "holds; --dynamic differentiates ω over it; payload: enables --bias-drift; compensate: "
                        "default the payload file's)")


def add_robot_source_options(p: argparse.ArgumentParser, named_models: bool = True) -> None:
    """--urdf (and --model NAME where ``named_models``), --sensor, --ft-joint/--ft-frame, --base, --degrees.

    ``compensate`` passes ``named_models=False`` and adds its own ``--model`` (which also takes the old
    spelling ``--model CAL.json`` of its ``--calibration``).
    """
    robot = p.add_argument_group("gravity from a robot model and joint columns (named as the URDF's joints)")
    which = robot.add_mutually_exclusive_group()
    which.add_argument("--urdf", dest="robot_urdf", metavar="PATH", help="URDF of the robot (with --sensor)")
    if named_models:
        which.add_argument("--model", dest="robot_model", metavar="NAME",
                           help="robot model from icub-models, e.g. iCubGenova04 (with --sensor)")
    robot.add_argument("--sensor", metavar="NAME", help="F/T sensor of the model (sensor or joint name)")
    robot.add_argument("--ft-joint", metavar="JOINT", help="declare the F/T sensor on this fixed joint (plain URDFs)")
    robot.add_argument("--ft-frame", metavar="LINK", help="sensor frame of --ft-joint (default: its child link)")
    robot.add_argument("--base", metavar="FRAME", help="fixed base frame, gravity along its -z")
    robot.add_argument("--degrees", action="store_true", help="joint columns are in degrees")


def source_keywords(args) -> dict:
    """The parsed gravity-source options as the steps' keywords (:data:`ftcal.workflow.sources.SOURCE_OPTIONS`)."""
    return {"orientation": args.orientation, "gravity_columns": args.gravity_columns, "g": args.g,
            "urdf": getattr(args, "robot_urdf", None), "robot": getattr(args, "robot_model", None),
            "sensor": getattr(args, "sensor", None), "ft_joint": getattr(args, "ft_joint", None),
            "ft_frame": getattr(args, "ft_frame", None), "base": getattr(args, "base", None),
            "degrees": getattr(args, "degrees", False), "dynamic": args.dynamic,
            "angular_velocity": args.angular_velocity, "linear_acceleration": args.linear_acceleration,
            "angular_acceleration": args.angular_acceleration, "time": args.time}


def check_not_input(output: str, inputs) -> None:
    """Refuse an output path that is also one of the inputs."""
    from pathlib import Path

    from ..runtime.errors import FtcalError

    target = Path(output).resolve()
    if any(Path(p).resolve() == target for p in inputs):
        raise FtcalError(f"-o {output}: is also an input file; write to another file.")
