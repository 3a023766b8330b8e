"""``--inputs`` for the payload-side commands (payload, compensate, check, live), with ``--wrench``, its old spelling."""

from __future__ import annotations

import argparse

from ..runtime.errors import FtcalError
from ._common import column_list


def add_inputs_option(parser, help: str, metavar: str = "FX,FY,FZ,TX,TY,TZ") -> None:
    """``--inputs``: the sensor columns the step reads (as in fit, evaluate, report), and ``--wrench``,
    its old spelling in payload, compensate, check and live (read by :func:`inputs_of`, with a notice)."""
    parser.add_argument("--inputs", type=column_list, metavar=metavar, help=help)
    parser.add_argument("--wrench", dest="inputs_old", type=column_list, metavar=metavar,
                        help="old spelling of --inputs (a notice says so)")


def inputs_of(args: argparse.Namespace, default=None):
    """``--inputs``, or ``--wrench`` (its old spelling: one notice line), or ``default``."""
    from ..runtime.deprecation import old_spelling

    if args.inputs_old is not None:
        if args.inputs is not None:
            raise FtcalError("--inputs: given twice (also as --wrench, its old spelling); give it once.")
        old_spelling("--wrench", "--inputs", stacklevel=2)
        args.inputs = args.inputs_old
    return default if args.inputs is None else args.inputs
