"""The ``ftcal`` command line: thin commands over the library.

Each command lives in its own module with ``register(subparsers)``, which adds
a sub-parser whose ``func`` default takes the parsed arguments and returns an
exit code. Heavy imports happen inside the commands so ``ftcal --help`` is fast.
"""

from __future__ import annotations

import argparse
import importlib
import os
import signal
import sys
import threading
import warnings
from collections.abc import Iterator
from contextlib import contextmanager

# In workflow order: `ftcal --help` lists them so (PIPELINE sketches it).
COMMAND_MODULES = (
    "demo", "sensors", "expected", "topics", "dataset", "fit", "evaluate", "report",
    "predict", "convert", "info", "payload", "compensate",
)

PIPELINE = """In-situ nonlinear calibration of six-axis force/torque sensors.

calibration:  sensors -> expected -> dataset -> fit -> evaluate / report -> convert (predict: apply a model)
bias and tool: topics -> dataset -> payload -> compensate (convert --to ros-yaml|ft-tools-ros2)
try it:       ftcal demo --out ftcal-demo, then any command's --help shows examples on its files"""

ENVIRONMENT = """environment variables:
  FTCAL_PROGRESS=0|1   progress bars off / on (default: on when stderr is a terminal)
  FTCAL_THREADS=N      worker threads for chunked fitting (default: usable cores, at most 8)
  XDG_CACHE_HOME       the expected-wrench cache is $XDG_CACHE_HOME/ftcal (default ~/.cache/ftcal)

exit codes: 0 success, 2 bad input (one line on stderr), 130 Ctrl-C, 143 SIGTERM, 129 SIGHUP
(temporary files are removed on every one of them)"""

# Argument names (dest) of output files and folders: never inputs, never equal to one.
OUTPUT_OPTIONS = ("output", "out")


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="ftcal", epilog=ENVIRONMENT, formatter_class=argparse.RawDescriptionHelpFormatter,
        description=PIPELINE)
    parser.add_argument("--version", action="store_true", help="print the version and exit")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name in COMMAND_MODULES:
        try:
            module = importlib.import_module(f"ftcal.cli.cmd_{name}")
        except ModuleNotFoundError as exc:
            if exc.name == f"ftcal.cli.cmd_{name}":
                continue  # command not built yet
            raise
        module.register(sub)
    return parser


class Terminated(BaseException):
    """SIGTERM or SIGHUP arrived: unwind like Ctrl-C (temporary files are removed) and exit 128 + signal."""

    def __init__(self, signum: int) -> None:
        super().__init__(signum)
        self.signum = signum


TERMINATING_SIGNALS = tuple(getattr(signal, name) for name in ("SIGTERM", "SIGHUP") if hasattr(signal, name))


def _raise_terminated(signum, frame) -> None:
    for sig in TERMINATING_SIGNALS:  # a second signal must not interrupt the clean-up
        signal.signal(sig, signal.SIG_IGN)
    raise Terminated(signum)


@contextmanager
def terminating_signals_unwind() -> Iterator[None]:
    """Inside the block, SIGTERM and SIGHUP raise :class:`Terminated` (main thread only)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = {sig: signal.signal(sig, _raise_terminated) for sig in TERMINATING_SIGNALS}
    try:
        yield
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)


def input_files(args: argparse.Namespace) -> list[str]:
    """Every argument value that names an existing file, except the outputs: the command's inputs."""
    found = []
    for name, value in vars(args).items():
        if name in OUTPUT_OPTIONS or name == "func":
            continue
        for item in value if isinstance(value, (list, tuple)) else [value]:
            if isinstance(item, str) and item and os.path.isfile(item):
                found.append(item)
    return found


def main(argv: list[str] | None = None) -> int:
    from ..runtime.atomic import check_not_an_input, protected_inputs
    from ..runtime.errors import FtcalError, FtcalWarning

    parser = build_parser()
    args = parser.parse_args(argv)
    if args.version:
        from .. import __version__
        print(__version__)
        return 0
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    # Our own warnings go to stderr as one line each, not as Python warning noise.
    def show(message, category, filename, lineno, file=None, line=None):
        if issubclass(category, FtcalWarning):
            print(f"warning: {message}", file=sys.stderr)
        else:
            print(f"{category.__name__}: {message}", file=sys.stderr)
    previous = warnings.showwarning
    warnings.showwarning = show
    try:
        with terminating_signals_unwind(), protected_inputs(input_files(args)):
            for option in OUTPUT_OPTIONS:
                if getattr(args, option, None):
                    check_not_an_input(getattr(args, option), f"--{option}")
            return int(args.func(args) or 0)
    except FtcalError as exc:
        print(f"ftcal {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except BrokenPipeError:
        # Output piped into e.g. `head`: stop quietly like other command-line tools.
        sys.stderr.close()
        return 0
    except OSError as exc:
        # The environment refused (read-only folder, full disk, ...): one line, like any bad input.
        where = f"{exc.filename}: " if exc.filename else ""
        print(f"ftcal {args.command}: error: {where}{exc.strerror or exc}.", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"ftcal {args.command}: interrupted", file=sys.stderr)
        return 130
    except Terminated as exc:
        print(f"ftcal {args.command}: terminated by {signal.Signals(exc.signum).name}", file=sys.stderr)
        return 128 + exc.signum
    finally:
        warnings.showwarning = previous  # main() may be called in-process (tests, scripts)


if __name__ == "__main__":
    sys.exit(main())
