"""Argument helpers shared by the commands."""

from __future__ import annotations

import argparse
import json
import math
import sys
from collections.abc import Sequence

from ..core.columns import DEFAULT_INPUTS, DEFAULT_OUTPUTS
from ..core.limits import MAX_OPTION_MAGNITUDE
from ..runtime.errors import single_line  # noqa: F401  (the commands import it from here)
from ..runtime.errors import FtcalError, ParameterError, ParameterWarning

# The one table from a library parameter to the flag that sets it, where the flag is not the rule
# ``--`` + the name with ``-`` for ``_`` (degree -> --degree, max_degree -> --max-degree).
FLAGS = {
    "output": "-o",  # every command's output file
    "robot": "--model",  # the robot description (a URDF or a robot_descriptions name)
    "recorded": "--from",  # ftcal plan: tables of poses already recorded
    "tools": "--tool",  # ftcal live: the tool library, one --tool NAME=PAYLOAD.json each
    "single_precision": "--float",  # ftcal convert: float code
    "payload_files": "--payload-file",  # ftcal convert --to c-runtime: one --payload-file [NAME=]TOOL.json each
}


def flag_of(parameter: str) -> str:
    """The command-line flag of a library parameter (:data:`FLAGS`, else ``--`` + name with dashes)."""
    return FLAGS.get(parameter, "--" + parameter.replace("_", "-"))


def cli_message(error: FtcalError | Warning) -> str:
    """What the command prints for ``error`` (or a warning): a :class:`ParameterError` or
    :class:`ParameterWarning` names the flags, not the Python names."""
    return error.render(flag_of) if isinstance(error, (ParameterError, ParameterWarning)) else str(error)


def column_list(text: str) -> tuple[str, ...]:
    """Parse ``"u1,u2,T"``; rejects empty names."""
    names = tuple(part.strip() for part in text.split(","))
    if not names or any(not n for n in names):
        raise argparse.ArgumentTypeError(f"expected comma-separated column names, got {text!r}")
    if len(set(names)) != len(names):
        raise argparse.ArgumentTypeError(f"column names repeat in {text!r}")
    return names


def finite_float(text: str) -> float:
    """A finite number of magnitude at most :data:`~ftcal.core.limits.MAX_OPTION_MAGNITUDE`."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"must be a finite number, got {text!r}")
    if abs(value) > MAX_OPTION_MAGNITUDE:
        # Values near 1e308 overflow the first product they meet (NaN fits, eigen-solvers failing).
        raise argparse.ArgumentTypeError(f"must be at most {MAX_OPTION_MAGNITUDE:g} in magnitude, got {text!r}")
    return value


def positive_float(text: str) -> float:
    """Like :func:`finite_float`, and > 0."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not math.isfinite(value) or value <= 0:
        raise argparse.ArgumentTypeError(f"must be a finite number > 0, got {text!r}")
    return finite_float(text)  # the magnitude limit


def nonnegative_int(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a whole number, got {text!r}") from None
    if value < 0:
        raise argparse.ArgumentTypeError(f"must be >= 0, got {text!r}")
    return value


def float_list(text: str) -> tuple[float, ...]:
    return tuple(positive_float(part) for part in text.split(","))


# The --segment-by and --group-by help of the commands that read tables (add_label_options).
SEGMENT_HELP = ("column whose runs of equal values are separate segments (default: the 'segment' column "
                "ftcal dataset writes when every file has one, else one per file)")
ARX_SEGMENT_HELP = ("column separating segments (ARX; default: the 'segment' column ftcal dataset writes when "
                    "every file has one)")
GROUP_HELP = ("column naming validation groups, e.g. the load case (default: one per file; for fit "
              "--degree auto, --family mlp or --estimate-payload, the 'load' column ftcal dataset "
              "writes when every file has one)")


def add_label_options(parser: argparse.ArgumentParser, segment_help: str | None = SEGMENT_HELP,
                      group_help: str | None = GROUP_HELP) -> None:
    """``--segment-by COL`` and ``--group-by COL`` (each left out when its help is None)."""
    if segment_help is not None:
        parser.add_argument("--segment-by", metavar="COL", help=segment_help)
    if group_help is not None:
        parser.add_argument("--group-by", metavar="COL", help=group_help)


def add_column_options(parser: argparse.ArgumentParser, outputs: bool = True) -> None:
    parser.add_argument("--inputs", type=column_list, metavar="C1,C2,...",
                        help=f"input columns (default {','.join(DEFAULT_INPUTS)}; T is optional)")
    if outputs:
        parser.add_argument("--outputs", type=column_list, metavar="C1,...",
                            help=f"reference output columns (default {','.join(DEFAULT_OUTPUTS)})")
    add_label_options(parser)


def default_inputs(paths: Sequence[str]) -> tuple[str, ...]:
    """u1..u6,T, or u1..u6 when the first file has no T column (temperature is optional)."""
    from ..data.tables import default_inputs as from_files

    return from_files(paths)


def add_scheduler_option(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--scheduler", metavar="ADDRESS",
                        help="run the per-file work on a Dask cluster: tcp://host:8786 (an existing scheduler; "
                             "the files must be visible to every worker at the same path) or local:N (N workers on "
                             "this machine: a static fit's statistics passes run in N threads of the command, "
                             "with no start-up; other tasks in N worker processes, started when first needed and "
                             "ended with the command, Ctrl-C included); many files "
                             "travel as a few tasks per worker, and the sums equal a run without Dask; default: "
                             "this process, without Dask")


def print_json(payload: dict) -> None:
    """Print ``payload`` as JSON, all or nothing: a non-finite number is an error, not partial output."""
    try:
        text = json.dumps(payload, indent=2, allow_nan=False)
    except ValueError:
        raise FtcalError("the result holds a non-finite number (inf or NaN); refusing to print invalid JSON.") from None
    sys.stdout.write(text + "\n")


def require_suffix(path: str, suffixes: Sequence[str], option: str) -> None:
    if not any(path.lower().endswith(s) for s in suffixes):
        raise FtcalError(f"{option} {path}: must end in {' or '.join(suffixes)}.")


def norm_rmse_text(metrics: dict, spec: str = ".4f", units: bool = True) -> str:
    """:func:`ftcal.core.metrics_text.norm_rmse_text` (numpy-free; imported when called)."""
    from ..core.metrics_text import norm_rmse_text as text

    return text(metrics, spec, units)


def frame_pair(text: str) -> tuple[str, str | None]:
    """``--tf BASE[:SENSOR_FRAME]`` (dataset, live): the base frame and the sensor frame (None: the wrench's)."""
    base, sep, frame = text.partition(":")
    if not base.strip() or (sep and not frame.strip()):
        raise argparse.ArgumentTypeError(f"expected BASE or BASE:SENSOR_FRAME, got {text!r}")
    return base.strip(), frame.strip() or None
