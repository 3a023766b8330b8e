"""Worker processes that a Ctrl-C or an error always stops: an ordered map over jobs.

``multiprocessing.Pool.terminate`` can deadlock: a worker blocked writing a large
result into the shared result pipe holds the pipe's lock after the pool has stopped
reading it, and ``terminate`` then waits for that lock forever (seen with
``ftcal expected --workers 2`` interrupted mid-run). Here each worker has a pipe of
its own and at most one job in flight, nothing is shared between workers, and
stopping on an error or a signal kills the workers outright.

Workers are spawned, so each one imports the calling script again as ``__mp_main__``. A script
that calls ftcal at its top level without ``if __name__ == "__main__":`` would then run its
calls again in every worker (which fail as they try to spawn their own: three tracebacks for
README's pipeline saved as a file). :func:`spawn_reruns_main` detects that case from the
script's source, and :class:`WorkerProcesses` then does the jobs in this process, with one
warning saying what to add to use the workers.
"""

from __future__ import annotations

import ast
import multiprocessing
import os
import pickle
import signal
import sys
import threading
import warnings
from collections.abc import Callable, Iterable, Iterator
from multiprocessing.connection import wait
from typing import Any

from .errors import FtcalError, FtcalWarning, ParameterError

STOP_TIMEOUT_S = 10.0  # a worker told to stop after a clean run gets this long before it is killed


class WorkerProcesses:
    """``workers`` spawned processes, each first running ``initializer(*initargs)``.

    Use as a context manager; leaving the block by an exception (a worker's error,
    Ctrl-C, a signal turned into an exception) kills every worker before the
    exception goes on; leaving it normally stops them.

    Parameters
    ----------
    workers : number of processes, at least 1
    initializer, initargs : a module-level function run once in each worker, and its arguments

    Examples
    --------
    >>> with WorkerProcesses(2, abs, (0,)) as processes:  # doctest: +SKIP
    ...     list(processes.map(abs, [-1, -2, 3]))
    [1, 2, 3]
    """

    def __init__(self, workers: int, initializer: Callable[..., Any], initargs: tuple = ()):
        if workers < 1:
            raise FtcalError(f"workers must be at least 1; got {workers}.")
        self.workers, self.initializer, self.initargs = workers, initializer, initargs
        self._processes: list = []
        self._connections: list = []
        self._inline = False

    def __enter__(self) -> "WorkerProcesses":
        script = spawn_reruns_main()
        self._inline = script is not None
        if self._inline:
            warnings.warn(f"{script} calls ftcal at its top level without 'if __name__ == \"__main__\":', so "
                          f"{self.workers} worker processes would each run the script again: the work runs in this "
                          "process instead; put the calls under that guard to use the workers.",
                          FtcalWarning, stacklevel=2)
            self.initializer(*self.initargs)
            return self
        context = multiprocessing.get_context("spawn")  # not fork: the parent may run threads
        # An ignored SIGINT survives the exec of a spawned worker: a terminal's Ctrl-C (sent to the
        # whole process group) then reaches only the parent, which stops the workers itself.
        in_main = threading.current_thread() is threading.main_thread()
        previous = signal.signal(signal.SIGINT, signal.SIG_IGN) if in_main else None
        try:
            for _ in range(self.workers):
                mine, theirs = context.Pipe(duplex=True)
                process = context.Process(target=_serve, args=(theirs, self.initializer, self.initargs),
                                          daemon=True)
                process.start()
                theirs.close()
                self._processes.append(process)
                self._connections.append(mine)
        except BaseException:
            self._kill()
            raise
        finally:
            if in_main:
                signal.signal(signal.SIGINT, previous)
        return self

    def __exit__(self, kind, value, traceback) -> None:
        if self._inline:
            return
        if kind is None:
            self._stop()
        else:
            self._kill()

    def map(self, function: Callable[[Any], Any], jobs: Iterable[Any]) -> Iterator[Any]:
        """``function(job)`` for each job, computed in the workers, yielded in the order of ``jobs``.

        Raises
        ------
        Exception
            The first error a worker raised (re-raised here), or FtcalError when a
            worker process died.
        """
        if self._inline:
            yield from (function(job) for job in jobs)
            return
        pending = iter(enumerate(jobs))
        busy: dict[Any, int] = {}  # connection -> index of its job in flight
        done: dict[int, Any] = {}
        next_index = 0

        def give(connection) -> None:
            item = next(pending, None)
            if item is not None:
                connection.send((function, *item))
                busy[connection] = item[0]

        for connection in self._connections:
            give(connection)
        while busy or done:
            while next_index in done:
                yield done.pop(next_index)
                next_index += 1
            if not busy:
                break
            for connection in wait(list(busy)):
                try:
                    index, ok, value = connection.recv()
                except (EOFError, OSError):
                    raise ParameterError('workers', f"a worker process died while computing job {busy[connection]} "
                                     "(possibly out of memory); nothing was written. Retry with fewer "
                                     "{workers}.") from None
                if not ok:
                    raise value
                del busy[connection]
                done[index] = value
                give(connection)

    def _stop(self) -> None:
        for connection in self._connections:
            try:
                connection.send(None)
            except OSError:
                pass
        for process in self._processes:
            process.join(STOP_TIMEOUT_S)
        self._kill()

    def _kill(self) -> None:
        for process in self._processes:
            if process.is_alive():
                process.kill()
        for process in self._processes:
            process.join()
        for connection in self._connections:
            connection.close()
        self._processes, self._connections = [], []


def spawn_reruns_main() -> str | None:
    """The script's path when a spawned worker would run this call again, else None.

    That is when the main module is a file (``python script.py``, ``python -m module``) and this call
    comes from its top-level code outside an ``if __name__ == "__main__":`` block. An interactive
    session, ``python -c`` and notebooks have no file to import again: None.
    """
    main = sys.modules.get("__main__")
    path = getattr(main, "__file__", None)
    if main is None or path is None or multiprocessing.parent_process() is not None:
        return None
    # What multiprocessing.spawn itself never runs again: a package's __main__.py (python -m ftcal), ipython.
    module = getattr(getattr(main, "__spec__", None), "name", None) or ""
    if module == "__main__" or module.endswith(".__main__") or os.path.basename(path).split(".")[0] == "ipython":
        return None
    frame, line = sys._getframe(1), None
    while frame is not None:  # the outermost frame of the script's own top-level code
        if frame.f_globals is vars(main) and frame.f_code.co_name == "<module>":
            line = frame.f_lineno
        frame = frame.f_back
    if line is None:
        return None
    try:
        with open(path, encoding="utf-8") as file:
            tree = ast.parse(file.read())
    except (OSError, SyntaxError, ValueError):
        return None  # cannot tell: spawn, as before
    guarded = any(isinstance(node, ast.If) and _is_main_test(node.test) and node.lineno <= line <= node.end_lineno
                  for node in tree.body)
    return None if guarded else str(path)


def _is_main_test(test: ast.expr) -> bool:
    """``__name__ == "__main__"`` (either way round)."""
    if not (isinstance(test, ast.Compare) and len(test.ops) == 1 and isinstance(test.ops[0], ast.Eq)):
        return False
    sides = {ast.dump(test.left), ast.dump(test.comparators[0])}
    return sides == {ast.dump(ast.Name("__name__", ast.Load())), ast.dump(ast.Constant("__main__"))}


def _serve(connection, initializer: Callable[..., Any], initargs: tuple) -> None:
    """A worker: initialize, then answer ``(function, index, job)`` with ``(index, ok, value)`` until None."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # the parent handles Ctrl-C and stops the workers
    try:
        initializer(*initargs)
    except BaseException as exc:  # noqa: BLE001 - sent to the parent, which raises it
        connection.send((-1, False, _portable(exc)))
        return
    while True:
        try:
            message = connection.recv()
        except (EOFError, OSError):  # the parent is gone
            return
        if message is None:
            return
        function, index, job = message
        try:
            connection.send((index, True, function(job)))
        except BaseException as exc:  # noqa: BLE001 - sent to the parent, which raises it
            connection.send((index, False, _portable(exc)))


def _portable(exc: BaseException) -> BaseException:
    """``exc`` if it survives pickling, else a RuntimeError carrying its type and message."""
    try:
        pickle.loads(pickle.dumps(exc))
        return exc
    except Exception:  # noqa: BLE001 - any exception type may fail to pickle
        return RuntimeError(f"{type(exc).__name__}: {exc}")
