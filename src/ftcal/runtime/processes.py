"""Worker processes that a Ctrl-C or an error always stops: an ordered map over jobs.

``multiprocessing.Pool.terminate`` can deadlock: a worker blocked writing a large
result into the shared result pipe holds the pipe's lock after the pool has stopped
reading it, and ``terminate`` then waits for that lock forever (seen with
``ftcal expected --workers 2`` interrupted mid-run). Here each worker has a pipe of
its own and at most one job in flight, nothing is shared between workers, and
stopping on an error or a signal kills the workers outright.
"""

from __future__ import annotations

import multiprocessing
import pickle
import signal
import threading
from collections.abc import Callable, Iterable, Iterator
from multiprocessing.connection import wait
from typing import Any

from .errors import FtcalError

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

    def __enter__(self) -> "WorkerProcesses":
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
                    raise FtcalError(f"a worker process died while computing job {busy[connection]} "
                                     "(possibly out of memory); nothing was written. Retry with fewer "
                                     "--workers.") from None
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
