"""Run per-file tasks in this process or on a Dask distributed cluster.

Commands that work file by file (statistics for ``fit``, metrics for
``evaluate``, predictions, expected wrenches) describe each file's work as one
task and hand the list to an executor. A task is a path, run as
``function(path, *args)``, or a tuple ``(path, *more)`` run as
``function(path, *more, *args)``: ``args`` are shared by all tasks.

- :class:`LocalExecutor` runs them here, one after another (Dask is never
  imported);
- :class:`DaskExecutor` submits them to a Dask distributed scheduler, either an
  existing cluster (``tcp://host:8786``) or a local one (``local:N``: N worker
  processes on this machine). Workers read the files themselves, so the paths
  must be visible to every worker at the same place (a shared file system).

Additive results (sufficient statistics, metric sums) are combined by
:func:`tree_reduce`, pairing neighbours in the same order in both executors so
a cluster run sums in exactly the order of a local run.
"""

from __future__ import annotations

import os
import uuid
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from typing import Any, TypeVar, Union

from .errors import FtcalError
from .progress import progress_bar

T = TypeVar("T")
Task = Union[str, os.PathLike, tuple]

CONNECT_TIMEOUT_S = 10.0  # to reach a scheduler; a wrong address fails in this time
NO_WORKERS_TIMEOUT_S = 60.0  # a cluster without any worker this long is an error, not a wait
TASK_RETRIES = 1  # local:N clusters run a task whose worker died once more, then fail the run
POLL_S = 1.0
LOCAL_PREFIX = "local:"
MAX_LOCAL_WORKERS = 64


def tree_reduce(parts: Sequence[T], combine: Callable[[T, T], T]) -> T:
    """Combine ``parts`` pairwise, neighbours first: ((p0+p1)+(p2+p3))+p4.

    Parameters
    ----------
    parts : sequence of additive results, at least one
    combine : callable(a, b) -> result

    Returns
    -------
    The combination of all parts, in an order that depends only on ``len(parts)``.
    """
    if not parts:
        raise FtcalError("Nothing to combine: no task produced a result.")
    level = list(parts)
    while len(level) > 1:
        level = [combine(level[i], level[i + 1]) if i + 1 < len(level) else level[i]
                 for i in range(0, len(level), 2)]
    return level[0]


class LocalExecutor:
    """Run tasks in this process, one after another, with a progress bar over tasks."""

    def map(self, function: Callable[..., T], tasks: Sequence[Task], *args: Any,
            description: str = "tasks") -> list[T]:
        """``[function(*task, *args) for task in tasks]``.

        Parameters
        ----------
        function : callable(path, ..., *args) -> result
        tasks : a path, or a tuple (path, per-task arguments...), per task
        args : arguments shared by all tasks
        description : label of the progress bar

        Returns
        -------
        list of results, in the order of ``tasks``.
        """
        results = []
        with progress_bar(description, len(tasks)) as advance:
            for task in tasks:
                results.append(function(*_task_arguments(task), *args))
                advance(1)
        return results

    def map_reduce(self, function: Callable[..., T], tasks: Sequence[Task], *args: Any,
                   combine: Callable[[T, T], T], description: str = "tasks") -> T:
        """:func:`tree_reduce` of :meth:`map`."""
        return tree_reduce(self.map(function, tasks, *args, description=description), combine)


class DaskExecutor:
    """Run tasks on a Dask distributed cluster; results come back to this process.

    Parameters
    ----------
    client : distributed.Client, connected and checked by :func:`open_executor`
    """

    def __init__(self, client):
        self.client = client

    def _submit(self, function, tasks, args):
        # pure=False: two runs of one file are two tasks (no stale cached results between commands)
        return [self.client.submit(_run_on_worker, function, _task_arguments(task), args, pure=False,
                                   key=f"ftcal-{os.path.basename(os.fspath(_task_arguments(task)[0]))}-"
                                       f"{uuid.uuid4().hex}")
                for task in tasks]

    def map(self, function: Callable[..., T], tasks: Sequence[Task], *args: Any,
            description: str = "tasks") -> list[T]:
        """Like :meth:`LocalExecutor.map`, one Dask task per entry of ``tasks``."""
        futures = self._submit(function, tasks, args)
        try:
            self._wait(futures, description)
            return self.client.gather(futures)
        except Exception as exc:
            self.client.cancel(futures)
            raise _explain(exc) from None

    def map_reduce(self, function: Callable[..., T], tasks: Sequence[Task], *args: Any,
                   combine: Callable[[T, T], T], description: str = "tasks") -> T:
        """:func:`tree_reduce` on the workers; only the total travels back."""
        futures = self._submit(function, tasks, args)
        level = list(futures)
        try:
            while len(level) > 1:
                level = [self.client.submit(combine, level[i], level[i + 1], pure=False)
                         if i + 1 < len(level) else level[i] for i in range(0, len(level), 2)]
                futures.extend(level)
            self._wait(futures[:len(tasks)], description)
            if len(futures) > len(tasks):  # the sums are watched too: no hang if workers die
                self._wait(futures[len(tasks):], f"{description}: tree sum")
            return level[0].result()
        except Exception as exc:
            self.client.cancel(futures)
            raise _explain(exc) from None

    def _wait(self, futures, description: str) -> None:
        """Wait for ``futures`` with a progress bar; fail when the cluster has had no worker for too long."""
        import time

        pending = set(futures)
        without_workers_since = None
        with progress_bar(description, len(futures)) as advance:
            while pending:
                done = _wait_quietly(pending)
                for future in done:
                    if future.status == "error":
                        future.result()  # raises the task's own exception
                advance(len(done))
                pending -= done
                if not pending:
                    break
                if self.client.scheduler_info(n_workers=-1).get("workers"):
                    without_workers_since = None
                elif without_workers_since is None:
                    without_workers_since = time.monotonic()
                elif time.monotonic() - without_workers_since > NO_WORKERS_TIMEOUT_S:
                    raise FtcalError(f"the Dask cluster at {self.client.scheduler.address} has had no worker for "
                                     f"{NO_WORKERS_TIMEOUT_S:.0f} s with {len(pending)} task(s) left; start workers "
                                     "or run without --scheduler.")


def _wait_quietly(pending) -> set:
    """The futures done within one poll interval (none on timeout)."""
    from distributed import wait

    try:
        return set(wait(pending, timeout=POLL_S, return_when="FIRST_COMPLETED").done)
    except TimeoutError:
        return set()


def _task_arguments(task: Task) -> tuple:
    return task if isinstance(task, tuple) else (task,)


def _run_on_worker(function, task: tuple, args: tuple):
    """A task as a worker runs it: first check this worker can see the task's file."""
    path = task[0]
    if not os.access(path, os.R_OK):
        import socket

        raise FtcalError(f"{os.fspath(path)}: the Dask worker on {socket.gethostname()} cannot read this file; "
                         "with --scheduler the paths must be visible to every worker at the same place "
                         "(a shared file system).")
    return function(*task, *args)


def _explain(exc: BaseException) -> BaseException:
    """Errors of the cluster itself as one-line FtcalErrors; the tasks' own FtcalErrors pass through."""
    if isinstance(exc, FtcalError):
        return exc
    from distributed.scheduler import KilledWorker

    if isinstance(exc, KilledWorker):
        return FtcalError(f"a Dask worker died while running {exc.task!r} (each worker that ran it died, "
                          "possibly out of memory); nothing was written. Give the workers more memory or "
                          "split the files.")
    return FtcalError(f"the Dask run failed ({type(exc).__name__}: "
                      f"{str(exc).splitlines()[0] if str(exc) else 'no detail'}); nothing was written.")


def parse_scheduler(text: str) -> str:
    """Check a ``--scheduler`` value: ``tcp://host:port`` (or another Dask protocol) or ``local:N``.

    Raises
    ------
    FtcalError
        Neither form, or N outside 1..MAX_LOCAL_WORKERS.
    """
    if text.startswith(LOCAL_PREFIX):
        count = text[len(LOCAL_PREFIX):]
        if not count.isdigit() or not 1 <= int(count) <= MAX_LOCAL_WORKERS:
            raise FtcalError(f"--scheduler {text}: local:N needs N worker processes, 1 to {MAX_LOCAL_WORKERS}.")
        return text
    if "://" not in text or not text.split("://", 1)[1]:
        raise FtcalError(f"--scheduler {text}: expected a scheduler address such as tcp://host:8786, "
                         "or local:N for N local worker processes.")
    return text


@contextmanager
def open_executor(scheduler: str | None, *,
                  connect_timeout: float = CONNECT_TIMEOUT_S) -> Iterator[LocalExecutor | DaskExecutor]:
    """The executor for a ``--scheduler`` value (None: this process).

    Parameters
    ----------
    scheduler : None, ``local:N`` or a Dask scheduler address
    connect_timeout : seconds to wait for the scheduler to answer

    Yields
    ------
    LocalExecutor or DaskExecutor; a local cluster is shut down on exit.

    Raises
    ------
    FtcalError
        The scheduler cannot be reached within ``connect_timeout``, or its
        workers run another ftcal, numpy or Dask version than this process.
    """
    if scheduler is None:
        yield LocalExecutor()
        return
    scheduler = parse_scheduler(scheduler)
    import logging

    try:
        import dask
        from distributed import Client, LocalCluster
    except ImportError:
        raise FtcalError(f"--scheduler {scheduler}: needs Dask distributed; install it with "
                         "pip install 'ftcal[dask]'.") from None

    with dask.config.set({"distributed.comm.timeouts.connect": f"{connect_timeout}s",
                          "distributed.scheduler.allowed-failures": TASK_RETRIES}):
        cluster = None
        try:
            if scheduler.startswith(LOCAL_PREFIX):
                cluster = LocalCluster(n_workers=int(scheduler[len(LOCAL_PREFIX):]), threads_per_worker=1,
                                       processes=True, dashboard_address=":0", silence_logs=logging.CRITICAL)
            try:
                client = Client(cluster if cluster is not None else scheduler, timeout=connect_timeout)
            except (OSError, TimeoutError) as exc:
                raise FtcalError(f"--scheduler {scheduler}: cannot reach the Dask scheduler within "
                                 f"{connect_timeout:g} s ({type(exc).__name__}); check the address and "
                                 "that `dask scheduler` runs there.") from None
            except ValueError as exc:  # Dask's own address parser: a bad scheme, host or port
                raise FtcalError(f"--scheduler {scheduler}: not a Dask scheduler address "
                                 f"({str(exc).splitlines()[0] if str(exc) else type(exc).__name__}).") from None
            except Exception as exc:  # noqa: BLE001 - whatever answered sent garbage (Dask then
                # asked for exabytes: MemoryError, or failed to decode: many types)
                raise FtcalError(f"--scheduler {scheduler}: what answered there is not a Dask scheduler "
                                 f"({type(exc).__name__} while connecting); check the address.") from None
            with client:
                check_versions(client, scheduler)
                yield DaskExecutor(client)
        finally:
            if cluster is not None:
                cluster.close()


def check_versions(client, scheduler: str) -> None:
    """Refuse workers whose ftcal, numpy or distributed version differs from this process.

    Raises
    ------
    FtcalError
        Naming the package, the client's version and the first mismatching worker's.
    """
    mine = _versions()
    try:
        theirs = client.run(_versions)
    except Exception as exc:  # noqa: BLE001 - e.g. workers that cannot import ftcal at all
        raise FtcalError(f"--scheduler {scheduler}: the workers cannot run ftcal tasks ({type(exc).__name__}: "
                         f"{str(exc).splitlines()[0] if str(exc) else 'no detail'}); install this ftcal on them.") \
            from None
    for worker, versions in sorted(theirs.items()):
        for package, version in mine.items():
            if versions.get(package) != version:
                raise FtcalError(f"--scheduler {scheduler}: worker {worker} runs {package} "
                                 f"{versions.get(package)} but this client runs {version}; install the same "
                                 "versions on the workers.")


def _versions() -> dict[str, str]:
    from importlib import metadata

    return {package: metadata.version(package) for package in ("ftcal", "numpy", "distributed")}
