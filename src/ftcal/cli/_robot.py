"""Options of the robot commands (``sensors``, ``expected``, ``dataset``, ``plan``, ``simulate``): the robot model."""

from __future__ import annotations

import argparse


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


def robot_keywords(args: argparse.Namespace, payloads: bool = True) -> dict:
    """The parsed robot options as the steps' keywords (:func:`ftcal.workflow.sources.robot_model`)."""
    return {"urdf": args.urdf, "robot": args.model, "ft_joint": args.ft_joint, "ft_frame": args.ft_frame,
            "payload": tuple(args.payload) if payloads else ()}


def load_robot(args: argparse.Namespace, payloads: bool = True):
    """The robot model of the parsed arguments, with its declared sensor and (if ``payloads``) --payload specs."""
    from ..workflow.sources import robot_model

    return robot_model(**robot_keywords(args, payloads))
