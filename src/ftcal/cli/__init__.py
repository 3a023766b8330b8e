"""The ``ftcal`` command line: thin commands over the library.

Each command lives in its own module with ``register(subparsers)``, which adds
a sub-parser whose ``func`` default takes the parsed arguments and returns an
exit code. Heavy imports happen inside the commands so ``ftcal --help`` is fast.
"""

from __future__ import annotations

import argparse
import errno
import importlib
import os
import re
import signal
import sys
import threading
import time
import warnings
from collections.abc import Iterator
from contextlib import contextmanager

from .. import _INTERRUPTS, _note_interrupt

# In workflow order: `ftcal --help` lists them so (PIPELINE sketches it).
COMMAND_MODULES = (
    "demo", "plan", "simulate", "sensors", "expected", "topics", "dataset", "fit", "evaluate", "report",
    "check", "predict", "convert", "info", "payload", "compensate", "live",
)

PIPELINE = """In-situ nonlinear calibration of six-axis force/torque sensors.

calibration:  sensors -> expected -> dataset -> fit -> evaluate / report -> convert (predict: apply a model)
bias and tool: topics -> dataset -> payload -> compensate (convert --to ros-yaml|ft-tools-ros2) -> live
try it:       ftcal demo --out ftcal-demo, then any command's --help shows examples on its files"""

ENVIRONMENT = """environment variables:
  FTCAL_PROGRESS=0|1   progress bars off / on (default: on when stderr is a terminal)
  FTCAL_THREADS=N      worker threads for chunked fitting (default: usable cores, at most 8)
  XDG_CACHE_HOME       the expected-wrench cache is $XDG_CACHE_HOME/ftcal (default ~/.cache/ftcal)

exit codes: 0 success, 2 bad input (one line on stderr), 130 Ctrl-C, 143 SIGTERM, 129 SIGHUP
(temporary files are removed on every one of them)"""

# Argument names (dest) of output files and folders: never inputs, never equal to one.
# Options naming files a command writes (never its inputs). ``live --state`` is the session's own file: read to
# resume and written back (docs/live.md), never an input the atomic write must keep.
OUTPUT_OPTIONS = ("output", "out", "html", "state")


class OneLineParser(argparse.ArgumentParser):
    """An argument parser whose refusals are one line (no usage block), ending with where help is."""

    def error(self, message: str):
        self.exit(2, f"{self.prog}: error: {message} (see '{self.prog} --help').\n")


def build_parser(command: str | None = None) -> argparse.ArgumentParser:
    """The ``ftcal`` parser: every command's, or only ``command``'s (a command line naming one, which
    needs no other: importing and registering all of them costs ~50 ms of every run)."""
    parser = OneLineParser(
        prog="ftcal", epilog=ENVIRONMENT, formatter_class=argparse.RawDescriptionHelpFormatter,
        description=PIPELINE)
    parser.add_argument("--version", action="store_true", help="print the version and exit")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name in (command,) if command in COMMAND_MODULES else COMMAND_MODULES:
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


def check_no_empty_values(args: argparse.Namespace) -> None:
    """Refuse an option given an empty text value (``--group-by ""``): no file, column or name is empty,
    and an empty value would otherwise be read as "not given" in one place and used in another."""
    from ..runtime.errors import FtcalError

    for name, value in vars(args).items():
        if name in ("func", "command"):
            continue
        for item in value if isinstance(value, list) else [value]:
            if isinstance(item, str) and not item.strip():
                raise FtcalError(f"--{name.replace('_', '-')}: empty value; give a name (or leave the option out).")


def check_input_paths(args: argparse.Namespace) -> None:
    """Refuse any argument naming a FIFO, device or socket (never opened: reading one may never end).

    The readers make the same check (:func:`ftcal.runtime.inputs.check_input_file`);
    doing it here first covers every option of every command before any work starts.
    """
    import stat

    from ..runtime.errors import FtcalError
    from ..runtime.inputs import kind_of

    for name, value in vars(args).items():
        if name in OUTPUT_OPTIONS or name == "func":
            continue
        for item in value if isinstance(value, (list, tuple)) else [value]:
            if not isinstance(item, (str, os.PathLike)) or not item:
                continue
            try:
                mode = os.stat(item).st_mode
            except OSError as exc:
                if exc.errno == errno.ELOOP:
                    raise FtcalError(f"{os.fspath(item)}: a loop of symbolic links, not a file.") from None
                continue  # not a path (a name, an address) or missing: the command says so if it needs one
            except ValueError:
                continue
            if not (stat.S_ISREG(mode) or stat.S_ISDIR(mode)):
                raise FtcalError(f"{os.fspath(item)}: is {kind_of(mode)}, not a regular file "
                                 "(ftcal never reads from pipes or devices).")


# Characters never printed raw to a terminal: C0/C1 controls and the bidirectional overrides.
_UNPRINTABLE = re.compile("[\x00-\x1f\x7f-\x9f\u200e\u200f\u202a-\u202e\u2066-\u2069]")
# Longest error line: longer ones quote a file's text, shown by its start and end.
MAX_MESSAGE_CHARS = 1000
# Option values this far from 1 are where float arithmetic overflows or underflows.
_EXTREME = 1e150


def one_line(message: object) -> str:
    """``message`` as one line that cannot drive the terminal: newlines become spaces, controls escapes.

    Messages quote names and text from files, which ftcal does not trust.
    """
    text = " ".join(str(message).splitlines())
    if len(text) > MAX_MESSAGE_CHARS:  # a 5,000-character name quoted from a file
        half = MAX_MESSAGE_CHARS // 2
        text = f"{text[:half]} … {text[-half:]}"
    return _UNPRINTABLE.sub(lambda m: m.group(0).encode("unicode_escape").decode("ascii"), text)


class EscapingStream:
    """A text stream that writes controls (except newline and tab) and bidi overrides as escapes.

    Commands print names from files (``ftcal info`` lists a model's inputs); an escape
    sequence in such a name must not drive the user's terminal.
    """

    _CONTROLS = re.compile("[\x00-\x08\x0b-\x1f\x7f-\x9f\u200e\u200f\u202a-\u202e\u2066-\u2069]")

    def __init__(self, stream) -> None:
        self._stream = stream

    def write(self, text: str) -> int:
        self._stream.write(self._CONTROLS.sub(lambda m: m.group(0).encode("unicode_escape").decode("ascii"), text))
        return len(text)

    def __getattr__(self, name: str):
        return getattr(self._stream, name)


def numerical_failure(exc: BaseException, args: argparse.Namespace) -> str:
    """One line for an arithmetic, memory or nesting failure, naming the options that can cause it."""
    extreme = []
    for name, value in vars(args).items():
        for item in value if isinstance(value, (list, tuple)) else [value]:
            if isinstance(item, float) and item != 0 and not 1 / _EXTREME < abs(item) < _EXTREME:
                extreme.append(f"--{name.replace('_', '-')} {item:g}")
    kind = ("met text that is not valid Unicode" if isinstance(exc, UnicodeError) else
            {"MemoryError": "ran out of memory", "RecursionError": "met a structure nested too deeply"}.get(
                type(exc).__name__, "failed numerically"))
    detail = f" ({type(exc).__name__}{': ' + str(exc).splitlines()[0] if str(exc) else ''})"
    if extreme:
        return one_line(f"the computation {kind}{detail}: option {', '.join(extreme)} is too far from "
                        "physical values; give a realistic value.")
    files = ", ".join(input_files(args)) or "the inputs"
    return one_line(f"the computation {kind}{detail}; check {files} for values near the limits of floating "
                    "point (about 1e308), constant or degenerate columns, or ask for a smaller model.")


def _interrupt(signum, frame) -> None:
    """Python's Ctrl-C, remembered: C code that imports a module turns the KeyboardInterrupt into an
    ImportError (numpy's does), which must still end as an interruption."""
    _INTERRUPTS.append(signum)
    raise KeyboardInterrupt


def _interrupt_again(unraisable, previous=sys.unraisablehook) -> None:
    """A Ctrl-C raised where Python ignores exceptions (a weakref callback of the import system, a
    ``__del__``) would be lost: the command would run on. Raise it again in the main thread."""
    if unraisable.exc_type is not None and issubclass(unraisable.exc_type, KeyboardInterrupt):
        _interrupt_soon()
        return
    previous(unraisable)


def _interrupt_soon() -> None:
    """Interrupt the main thread once this hook has returned. Called from the main thread itself,
    ``interrupt_main`` runs the handler at once, inside the hook, where its KeyboardInterrupt would be
    ignored again ("Exception ignored in sys.unraisablehook"): a helper thread raises it a moment later."""
    import _thread

    def later() -> None:
        time.sleep(0.01)
        _thread.interrupt_main(signal.SIGINT)

    threading.Thread(target=later, name="ftcal-interrupt", daemon=True).start()


def main(argv: list[str] | None = None) -> int:
    """Run one ftcal command and return its exit code; Ctrl-C at any moment is one line and 130."""
    command = signal.getsignal(signal.SIGINT) is _note_interrupt  # the `ftcal` command, not a call in a program
    try:
        if command:  # take over from ftcal/__init__.py's guard
            sys.unraisablehook = _interrupt_again
            signal.signal(signal.SIGINT, _interrupt)
        if _INTERRUPTS:
            raise KeyboardInterrupt
        return run(argv)  # the command modules import there
    except KeyboardInterrupt:
        print("ftcal: interrupted", file=sys.stderr)
        return 130
    except BaseException:
        if not _INTERRUPTS:
            raise
        print("ftcal: interrupted", file=sys.stderr)  # a Ctrl-C that an import turned into another error
        return 130
    finally:
        if command:  # what is left is Python's exit (joining threads): a Ctrl-C now changes nothing
            try:
                _ignore_further_interrupts()
            except KeyboardInterrupt:  # a pending one ran as the call began: it is moot too
                _ignore_further_interrupts()
            # A Ctrl-C that left a string exec/eval (scipy's imports run them: its array-API module execs
            # "from numpy import *", which imports numpy.f2py, which evals strings) set CPython's "unhandled
            # Ctrl-C" flag (run_eval_code_obj, bpo-1054041), though ftcal handled it: `python -m ftcal` then
            # killed itself with SIGINT at exit (-2, not 130). A string exec resets the flag. Measured under
            # load: 5-13 of 32 Ctrl-Cs 1 s into `fit --degree auto` went wrong without this, 0 of 96 with it.
            exec("pass")  # noqa: S102 - a constant, to reset the flag
        _INTERRUPTS.clear()


def _ignore_further_interrupts() -> None:
    """Ignore Ctrl-C from here on; ``signal.signal`` first runs a pending handler, whose interrupt is moot."""
    try:
        signal.signal(signal.SIGINT, signal.SIG_IGN)
    except KeyboardInterrupt:
        signal.signal(signal.SIGINT, signal.SIG_IGN)


def _leave_ctrl_c_to_ftcal() -> None:
    """Keep pyarrow from taking Ctrl-C during its reads: its temporary handler both cancels the read (one
    KeyboardInterrupt) and passes the signal on (a second, after ftcal has reported the first: exit by
    SIGINT instead of 130), or loses it when the read ends first (the command ran on). Measured: 6 of 24
    Ctrl-Cs under load went wrong with it, 0 of 24 without. A read now ends its chunk, then stops.

    Done as pyarrow is imported, not before: commands that read no table (``info``, ``topics``,
    ``--help``) do not pay its import (0.3-0.6 s)."""
    if "pyarrow" in sys.modules:
        sys.modules["pyarrow"].enable_signal_handlers(False)
    elif not any(isinstance(finder, _PyarrowSignals) for finder in sys.meta_path):
        sys.meta_path.insert(0, _PyarrowSignals())


class _PyarrowSignals:
    """An import hook: once ``pyarrow`` has been imported, turn its signal handlers off, then step aside."""

    def find_spec(self, name, path=None, target=None):
        if name != "pyarrow":
            return None
        import importlib.util

        sys.meta_path.remove(self)
        spec = importlib.util.find_spec(name)
        if spec is None or spec.loader is None:
            return spec
        loader = spec.loader
        exec_module = loader.exec_module

        def exec_then_quiet(module):
            exec_module(module)
            module.enable_signal_handlers(False)

        loader.exec_module = exec_then_quiet
        return spec


def run(argv: list[str] | None) -> int:
    """:func:`main` without the outermost Ctrl-C catch."""
    from ..runtime.atomic import check_not_an_input, protected_inputs
    from ..runtime.deprecation import OldSpellingWarning
    from ..runtime.errors import FtcalError, FtcalWarning

    import time

    from .. import _command_starting

    # CPU seconds this command has used start here: at the process's start for the `ftcal` command (its imports
    # count), at this call when main() runs inside another program (a test, a notebook), whose earlier CPU
    # must not eat into --budget.
    cpu_start = 0.0 if _command_starting() else time.process_time()
    words = sys.argv[1:] if argv is None else argv
    parser = build_parser(words[0] if words else None)
    args = parser.parse_args(argv)
    args.cpu_start = cpu_start
    if args.version:
        from .. import __version__
        print(__version__)
        return 0
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    if signal.getsignal(signal.SIGINT) is _interrupt:
        _leave_ctrl_c_to_ftcal()
    # Our own warnings go to stderr as one line each, not as Python warning noise.
    def show(message, category, filename, lineno, file=None, line=None):
        if issubclass(category, OldSpellingWarning):
            print(f"notice: {one_line(message)}", file=sys.stderr)
        elif issubclass(category, FtcalWarning):
            from ._common import cli_message

            print(f"warning: {one_line(cli_message(message))}", file=sys.stderr)
        elif issubclass(category, RuntimeWarning):  # numpy's floating-point warnings, in ftcal's words
            print(f"warning: numerical {one_line(message)} (values near the limits of float64 in an input file?)",
                  file=sys.stderr)
        else:
            print(f"{category.__name__}: {one_line(message)}", file=sys.stderr)
    saved_filters = warnings.catch_warnings()  # main() may be called in-process: its filter goes on return
    saved_filters.__enter__()
    previous = warnings.showwarning
    warnings.showwarning = show
    warnings.filterwarnings("default", category=OldSpellingWarning)  # one notice each, even under -W error
    stdout = sys.stdout
    sys.stdout = EscapingStream(stdout)
    try:
        with terminating_signals_unwind(), protected_inputs(input_files(args)):
            check_no_empty_values(args)
            check_input_paths(args)
            for option in OUTPUT_OPTIONS:
                if getattr(args, option, None):
                    check_not_an_input(getattr(args, option), option)
            return int(args.func(args) or 0)
    except FtcalError as exc:
        from ._common import cli_message

        print(f"ftcal {args.command}: error: {one_line(cli_message(exc))}", file=sys.stderr)
        return 2
    except (ArithmeticError, MemoryError, RecursionError, UnicodeError) as exc:
        print(f"ftcal {args.command}: error: {numerical_failure(exc, args)}", file=sys.stderr)
        return 2
    except ValueError as exc:
        if type(exc).__name__ != "LinAlgError":  # numpy's; other ValueErrors are bugs: keep the traceback
            raise
        print(f"ftcal {args.command}: error: {numerical_failure(exc, args)}", file=sys.stderr)
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
        if threading.current_thread() is threading.main_thread():  # the process is on its way out: a second
            for sig in TERMINATING_SIGNALS:  # SIGTERM while Zenoh's or Dask's threads wind down must not kill it
                signal.signal(sig, signal.SIG_IGN)  # by the signal and lose the exit code
        print(f"ftcal {args.command}: terminated by {signal.Signals(exc.signum).name}", file=sys.stderr)
        return 128 + exc.signum
    finally:
        warnings.showwarning = previous  # main() may be called in-process (tests, scripts)
        saved_filters.__exit__(None, None, None)
        sys.stdout = stdout


if __name__ == "__main__":
    sys.exit(main())
