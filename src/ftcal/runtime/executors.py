"""Run per-file tasks in this process or on a Dask distributed cluster.

Commands that work file by file (statistics for ``fit``, metrics for
``evaluate``, predictions, expected wrenches) describe each file's work as one
task and hand the list to an executor. A task is a path, run as
``function(path, *args)``, or a tuple ``(path, *more)`` run as
``function(path, *more, *args)``: ``args`` are shared by all tasks.

- :class:`LocalExecutor` runs them here, one after another (Dask is never
  imported);
- :class:`DaskExecutor` submits them to a Dask distributed scheduler, either an
  existing cluster (``tcp://host:8786``) or a local one. Workers read the files
  themselves, so the paths must be visible to every worker at the same place (a
  shared file system);
- :class:`LocalWorkers` is ``local:N``, N workers on this machine: tasks marked
  :func:`releases_gil` (the statistics passes of a fit: Parquet and CSV reads,
  numpy on whole chunks and the compiled kernel all run without the GIL) run in N
  threads of this process, with no start-up at all; any other task starts a Dask
  LocalCluster of N worker processes the first time one is mapped. On two cores,
  a cluster's start-up (~1 CPU s to import distributed here, ~3 more in the
  workers) cost more than its processes ever won back (issue 32).

On a cluster, tasks travel in batches (:func:`batch_size`): thousands of small
files become a few Dask tasks per worker, each running its files one after
another, instead of thousands of tasks that swamp the scheduler.

Additive results (sufficient statistics, metric sums) are combined by
:func:`tree_reduce`, pairing neighbours in the same order in both executors so
a cluster run sums in exactly the order of a local run (batches hold a power of
two of tasks, aligned, so the sum inside a batch is a subtree of the local one).

A local cluster (``local:N``) starts and stops with Ctrl-C, SIGTERM and SIGHUP
deferred until it is complete, and any process it started that is still alive
afterwards is ended: no process outlives the command.
"""

from __future__ import annotations

import os
import signal
import threading
import uuid
from collections.abc import Callable, Iterable, Iterator, Sequence
from contextlib import ExitStack, contextmanager
from typing import Any, TypeVar, Union

from .errors import FtcalError, ParameterError
from .progress import progress_bar
from .threads import single_threaded_blas

T = TypeVar("T")
Task = Union[str, os.PathLike, tuple]

CONNECT_TIMEOUT_S = 10.0  # to reach a scheduler; a wrong address fails in this time
NO_WORKERS_TIMEOUT_S = 60.0  # a cluster without any worker this long is an error, not a wait
TASK_RETRIES = 1  # local:N clusters run a task whose worker died once more, then fail the run
POLL_S = 1.0
LOCAL_PREFIX = "local:"
MAX_LOCAL_WORKERS = 64
TASKS_PER_WORKER = 4  # Dask tasks per worker when files outnumber them: balance without swamping the scheduler
MIN_DASK_TASKS = 16  # up to this many files, one task each: batching a few large files would unbalance workers
SHUTDOWN_TIMEOUT_S = 30.0  # a local cluster's orderly close; processes still alive after it are killed
# glibc's allocator in local workers: large blocks from the heap (32 MiB, glibc's largest mmap threshold), and
# the heap trimmed only past 256 MiB free.
WORKER_MALLOC = {"MALLOC_MMAP_THRESHOLD_": 32 * 1024 * 1024, "MALLOC_TRIM_THRESHOLD_": 256 * 1024 * 1024}
# A local cluster's own housekeeping, set to what a few batch tasks need: Dask's defaults (a stack sample
# every 10 ms in each worker, memory checks every 100 ms, an event-loop tick every 20 ms, disk and GIL
# monitors, work stealing) cost a local:2 run 30-40 % more CPU per pass than one process (issue 32).
LOCAL_CLUSTER_CONFIG = {
    "distributed.worker.profile.enabled": False,
    "distributed.worker.memory.monitor-interval": "1s",
    "distributed.admin.tick.interval": "500ms",
    "distributed.admin.system-monitor.interval": "5s",
    "distributed.admin.system-monitor.disk": False,
    "distributed.admin.system-monitor.gil.enabled": False,
    "distributed.scheduler.work-stealing": False,
}
# Set in a local cluster's worker processes, which live for one command: they keep the files they read in
# memory as the command's own process does (ftcal.data.table_chunks.keep_in_memory), so a file that several
# passes read is read once there too.
KEEP_FILES_ENV = "FTCAL_WORKER_KEEPS_FILES"
DEFERRED_SIGNALS = tuple(getattr(signal, name) for name in ("SIGINT", "SIGTERM", "SIGHUP") if hasattr(signal, name))
TASKS_AHEAD_PER_THREAD = 2  # local:N threads: tasks submitted ahead of the one awaited, per thread (held results)
_RELEASES_GIL: set = set()  # task functions that local:N runs in threads (see releases_gil)


def releases_gil(function: Callable[..., T]) -> Callable[..., T]:
    """Mark a per-file task function whose work runs almost all without the GIL; returns it unchanged.

    ``local:N`` (:class:`LocalWorkers`) runs such tasks in N threads of this process instead of
    worker processes. Mark only functions measured to gain from threads (two files in two threads
    against one after the other: ``benchmarks.bench_cluster.task_threads``) and safe to run
    concurrently on different files. A task so marked that runs out of memory takes the command
    with it (a worker process would be retried, then reported).
    """
    _RELEASES_GIL.add(function)
    return function


def tree_reduce(parts: Iterable[T], combine: Callable[[T, T], T]) -> T:
    """Combine ``parts`` pairwise, neighbours first: ((p0+p1)+(p2+p3))+p4.

    The parts are consumed as they come (a binary counter: two sums of 2^k
    parts are combined as soon as both exist), so at most log2(n) + 1 partial
    sums are held at once, never all n results.

    Parameters
    ----------
    parts : iterable of additive results, at least one
    combine : callable(a, b) -> result

    Returns
    -------
    The combination of all parts, in an order that depends only on their number:
    level by level, element 2i with element 2i + 1, an odd last one carried up.
    """
    stack: list[tuple[int, T]] = []  # (number of parts in the sum, sum), sizes strictly decreasing
    for part in parts:
        size, total = 1, part
        while stack and stack[-1][0] == size:
            left_size, left = stack.pop()
            size, total = left_size + size, combine(left, total)
        stack.append((size, total))
    if not stack:
        raise FtcalError("Nothing to combine: no task produced a result.")
    # The leftover sums of 2^k parts, largest first, combine from the right: the carried odd ones.
    total = stack.pop()[1]
    while stack:
        total = combine(stack.pop()[1], total)
    return total


def batch_size(n_tasks: int, n_workers: int) -> int:
    """Tasks per Dask task: the smallest power of two giving at most TASKS_PER_WORKER per worker
    (or MIN_DASK_TASKS in all, whichever is more).

    A power of two, and batches that start at its multiples, make each batch's
    :func:`tree_reduce` exactly a subtree of the reduction of all tasks.

    Examples
    --------
    >>> batch_size(10, 2), batch_size(17, 2), batch_size(2000, 2), batch_size(2000, 100)
    (1, 2, 128, 8)
    """
    target = max(TASKS_PER_WORKER * max(1, n_workers), MIN_DASK_TASKS)
    size = 1
    while -(-n_tasks // size) > target:
        size *= 2
    return size


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
        return list(self._results(function, tasks, args, description))

    def map_reduce(self, function: Callable[..., T], tasks: Sequence[Task], *args: Any,
                   combine: Callable[[T, T], T], description: str = "tasks") -> T:
        """:func:`tree_reduce` of :meth:`map`, adding each result as it comes."""
        return tree_reduce(self._results(function, tasks, args, description), combine)

    @staticmethod
    def _results(function, tasks, args, description) -> Iterator:
        with progress_bar(description, len(tasks)) as advance:
            for task in tasks:
                yield function(*_task_arguments(task), *args)
                advance(1)


class DaskExecutor:
    """Run tasks on a Dask distributed cluster, in batches; results come back to this process.

    Parameters
    ----------
    client : distributed.Client, connected and checked by :func:`open_executor`
    """

    def __init__(self, client):
        self.client = client
        self._files: dict[str, list[str]] = {}  # Dask key -> the files its batch runs, for error messages

    def _submit(self, function, tasks, args, combine=None) -> tuple[list, list[int]]:
        """One future per batch of tasks, and the number of tasks in each."""
        tasks = [_task_arguments(task) for task in tasks]
        size = batch_size(len(tasks), len(self.client.scheduler_info(n_workers=-1).get("workers", {})))
        futures, counts = [], []
        for start in range(0, len(tasks), size):
            batch = tasks[start:start + size]
            files = [os.fspath(task[0]) for task in batch]
            # pure=False and a fresh key: two runs of one file are two tasks (no stale results between commands)
            key = f"ftcal-{os.path.basename(files[0])}-{uuid.uuid4().hex}"
            self._files[key] = files
            futures.append(self.client.submit(_run_batch, function, batch, args, combine, pure=False, key=key))
            counts.append(len(batch))
        return futures, counts

    def map(self, function: Callable[..., T], tasks: Sequence[Task], *args: Any,
            description: str = "tasks") -> list[T]:
        """Like :meth:`LocalExecutor.map`; the tasks run in batches, the bar counts tasks (files)."""
        futures, counts = self._submit(function, tasks, args)
        try:
            self._wait(futures, counts, description)
            return [result for batch in self.client.gather(futures) for result in batch]
        except Exception as exc:
            self.client.cancel(futures)
            raise self._explain(exc) from None

    def map_reduce(self, function: Callable[..., T], tasks: Sequence[Task], *args: Any,
                   combine: Callable[[T, T], T], description: str = "tasks") -> T:
        """:func:`tree_reduce` on the workers (in each batch, then across batches); only the total travels back."""
        if not tasks:
            return tree_reduce([], combine)  # the same one-line error as here
        futures, counts = self._submit(function, tasks, args, combine)
        n_batches = len(futures)
        level = list(futures)
        try:
            while len(level) > 1:
                level = [self.client.submit(combine, level[i], level[i + 1], pure=False,
                                            key=f"ftcal-sum-{uuid.uuid4().hex}")
                         if i + 1 < len(level) else level[i] for i in range(0, len(level), 2)]
                futures.extend(level)
            self._wait(futures[:n_batches], counts, description)
            if len(futures) > n_batches:  # the sums are watched too: no hang if workers die
                sums = futures[n_batches:]
                self._wait(sums, [1] * len(sums), f"{description}: tree sum")
            return level[0].result()
        except Exception as exc:
            self.client.cancel(futures)
            raise self._explain(exc) from None

    def _wait(self, futures, counts: Sequence[int], description: str) -> None:
        """Wait for ``futures``, the bar advancing by their ``counts``; fail after too long without workers."""
        import time

        count = dict(zip(futures, counts))
        pending = set(futures)
        without_workers_since = None
        with progress_bar(description, sum(counts)) as advance:
            while pending:
                done = _wait_quietly(pending)
                for future in done:
                    if future.status == "error":
                        future.result()  # raises the task's own exception
                advance(sum(count[future] for future in done))
                pending -= done
                if not pending:
                    break
                if self.client.scheduler_info(n_workers=-1).get("workers"):
                    without_workers_since = None
                elif without_workers_since is None:
                    without_workers_since = time.monotonic()
                elif time.monotonic() - without_workers_since > NO_WORKERS_TIMEOUT_S:
                    raise ParameterError('scheduler', f"the Dask cluster at {self.client.scheduler.address} has had no worker for "
                                     f"{NO_WORKERS_TIMEOUT_S:.0f} s with {len(pending)} task(s) left; start workers "
                                     "or run without {scheduler}.")

    def _explain(self, exc: BaseException) -> BaseException:
        """The cluster's own errors as one-line FtcalErrors naming the files; the tasks' FtcalErrors pass through."""
        if isinstance(exc, FtcalError):
            return exc
        from distributed.scheduler import KilledWorker

        if isinstance(exc, KilledWorker):
            files = self._files.get(str(exc.task))
            what = (f"the task of {_name_files(files)}" if files else
                    "the sum of the files' results" if str(exc.task).startswith("ftcal-sum-") else repr(exc.task))
            return FtcalError(f"a Dask worker died while running {what} (each worker that held it died, possibly "
                              "out of memory); nothing was written. Give the workers more memory or split the files.")
        return FtcalError(f"the Dask run failed ({type(exc).__name__}: "
                          f"{str(exc).splitlines()[0] if str(exc) else 'no detail'}); nothing was written.")


def _name_files(files: Sequence[str]) -> str:
    """``a.csv``, ``a.csv, b.csv`` or ``12 files, a.csv to l.csv`` (a batch is a run of consecutive files)."""
    if len(files) <= 2:
        return ", ".join(files)
    return f"{len(files)} files, {files[0]} to {files[-1]}"


def _wait_quietly(pending) -> set:
    """The futures done within one poll interval (none on timeout)."""
    from distributed import wait

    try:
        return set(wait(pending, timeout=POLL_S, return_when="FIRST_COMPLETED").done)
    except TimeoutError:
        return set()


def _task_arguments(task: Task) -> tuple:
    return task if isinstance(task, tuple) else (task,)


def _run_batch(function, tasks: Sequence[tuple], args: tuple, combine=None):
    """A batch as a worker runs it: the tasks' results, or their :func:`tree_reduce` with ``combine``."""
    results = (_run_on_worker(function, task, args) for task in tasks)
    return list(results) if combine is None else tree_reduce(results, combine)


def _run_on_worker(function, task: tuple, args: tuple):
    """A task as a worker runs it: first check this worker can see the task's file."""
    path = task[0]
    if not os.access(path, os.R_OK):
        import socket

        raise ParameterError('scheduler', f"{os.fspath(path)}: the Dask worker on {socket.gethostname()} cannot read this file; "
                         "with {scheduler} the paths must be visible to every worker at the same place "
                         "(a shared file system).")
    return function(*task, *args)


class LocalWorkers:
    """``local:N``: tasks marked :func:`releases_gil` in N threads of this process, the others on a Dask
    LocalCluster of N worker processes, started the first time such a task is mapped.

    Results are combined here in the order of the tasks, with :func:`tree_reduce`, as
    :class:`LocalExecutor` does: each task's result is the same wherever it runs (threads split
    a chunk as this process does), so the sums are bit-identical to a run without ``--scheduler``.

    Parameters
    ----------
    scheduler : ``local:N``, checked by :func:`parse_scheduler`
    connect_timeout : seconds to wait for the local scheduler to answer
    """

    def __init__(self, scheduler: str, connect_timeout: float = CONNECT_TIMEOUT_S):
        self.scheduler = scheduler
        self.workers = int(scheduler[len(LOCAL_PREFIX):])
        self.connect_timeout = connect_timeout
        self.startup_s: float | None = None  # seconds the worker processes took to start, once started
        self.threaded = False  # whether a task ran in this process's threads
        self._cleanup = ExitStack()
        self._dask: DaskExecutor | None = None

    @property
    def client(self):
        """The Dask client of the worker processes (started now if they are not yet)."""
        return self._cluster().client

    def _cluster(self) -> DaskExecutor:
        if self._dask is None:
            client, self.startup_s = _open_dask(self.scheduler, self.connect_timeout, self._cleanup,
                                                n_workers=self.workers)
            self._dask = DaskExecutor(client)
        return self._dask

    def map(self, function: Callable[..., T], tasks: Sequence[Task], *args: Any,
            description: str = "tasks") -> list[T]:
        """Like :meth:`LocalExecutor.map`."""
        if function in _RELEASES_GIL:
            return list(self._thread_results(function, tasks, args, description))
        return self._cluster().map(function, tasks, *args, description=description)

    def map_reduce(self, function: Callable[..., T], tasks: Sequence[Task], *args: Any,
                   combine: Callable[[T, T], T], description: str = "tasks") -> T:
        """Like :meth:`LocalExecutor.map_reduce`: the same order of additions."""
        if function in _RELEASES_GIL:
            return tree_reduce(self._thread_results(function, tasks, args, description), combine)
        return self._cluster().map_reduce(function, tasks, *args, combine=combine, description=description)

    def _thread_results(self, function, tasks, args, description) -> Iterator:
        """The tasks' results in their order, run by N threads, a few tasks ahead of the one awaited."""
        import contextvars
        from collections import deque
        from concurrent.futures import ThreadPoolExecutor

        self.threaded = True
        queued = iter([_task_arguments(task) for task in tasks])
        pending: deque = deque()
        # Each task runs in a copy of the caller's context (np.errstate lives there), as map_ranges does.
        pool = ThreadPoolExecutor(self.workers, thread_name_prefix="ftcal-task")

        def submit() -> None:
            task = next(queued, None)
            if task is not None:
                pending.append(pool.submit(contextvars.copy_context().run, function, *task, *args))

        try:
            # BLAS held to one thread from this thread, for the whole map: the tasks' own limits nest inside it
            # and the count is restored here. Left to the task threads, the last one out restored it, and
            # OpenBLAS (0.3.31) kept one thread: the solve after the map rounded otherwise than one process.
            with single_threaded_blas(), progress_bar(description, len(tasks)) as advance:
                for _ in range(TASKS_AHEAD_PER_THREAD * self.workers):
                    submit()
                while pending:
                    result = pending.popleft().result()  # a task's own error (an FtcalError) as it raised it
                    submit()
                    yield result
                    advance(1)
        finally:
            # On an error or Ctrl-C: queued tasks are dropped; running ones finish their file.
            pool.shutdown(wait=False, cancel_futures=True)

    def report(self) -> str | None:
        """The start-up line, said once after a run that succeeded (a failed run's stderr is its one error)."""
        processes = f"{self.workers} worker process{'es' if self.workers > 1 else ''}"
        if self.startup_s is not None:
            return f"Dask {self.scheduler}: {processes} started in {self.startup_s:.1f} s"
        if self.threaded:
            return (f"{self.scheduler}: {self.workers} thread{'s' if self.workers > 1 else ''} of this process "
                    "ran the tasks (0.0 s start-up: no worker process was needed)")
        return None

    def close(self) -> None:
        """Stop the worker processes, if any started; no process started here outlives this call."""
        self._cleanup.close()


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
            raise ParameterError('scheduler', f"{{scheduler}} {text}: local:N needs N worker processes, 1 to {MAX_LOCAL_WORKERS}.")
        return text
    if "://" not in text or not text.split("://", 1)[1]:
        raise ParameterError('scheduler', f"{{scheduler}} {text}: expected a scheduler address such as tcp://host:8786, "
                         "or local:N for N local worker processes.")
    return text


@contextmanager
def open_executor(scheduler: str | None, *, connect_timeout: float = CONNECT_TIMEOUT_S
                  ) -> Iterator[LocalExecutor | LocalWorkers | DaskExecutor]:
    """The executor for a ``--scheduler`` value (None: this process).

    Parameters
    ----------
    scheduler : None, ``local:N`` or a Dask scheduler address
    connect_timeout : seconds to wait for the scheduler to answer

    Yields
    ------
    LocalExecutor, LocalWorkers (``local:N``) or DaskExecutor; a local cluster is shut down on exit.

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
    if scheduler.startswith(LOCAL_PREFIX):
        workers = LocalWorkers(scheduler, connect_timeout)
        try:
            yield workers
            line = workers.report()
            if line is not None:
                import sys

                print(line, file=sys.stderr)
        finally:
            workers.close()
        return
    with ExitStack() as cleanup:
        client, _ = _open_dask(scheduler, connect_timeout, cleanup)
        yield DaskExecutor(client)


def _open_dask(scheduler: str, connect_timeout: float, cleanup: ExitStack, n_workers: int | None = None):
    """A checked Dask client on ``scheduler``, or on a LocalCluster of ``n_workers`` processes, and its start-up s.

    Closing ``cleanup`` closes the client, then the cluster, then ends every process started here that is still
    alive (Ctrl-C, SIGTERM and SIGHUP deferred while each step runs).
    """
    import logging
    import time

    started = time.perf_counter()
    try:
        import dask
        from distributed import LocalCluster
    except ImportError:
        raise ParameterError('scheduler', f"{{scheduler}} {scheduler}: needs Dask distributed; install it with "
                         "pip install 'ftcal[dask]'.") from None

    # A local scheduler hands each worker one batch at a time (worker-saturation 1): when a worker
    # dies, Dask blames every task the worker held, so a queued, innocent batch would be blamed too.
    # Local workers' allocator: Dask's default MALLOC_TRIM_THRESHOLD_ (64 KiB) with glibc's mmap threshold
    # maps and unmaps every large temporary of a statistics pass (2.5 M page faults, 6 s of kernel time on
    # 4 x 1e6 rows); a heap that keeps them makes local:2 as fast as one process (issue 32).
    environ = dict(dask.config.get("distributed.nanny.pre-spawn-environ", {}) or {}, **WORKER_MALLOC)
    local = n_workers is not None
    cleanup.enter_context(dask.config.set({
        "distributed.comm.timeouts.connect": f"{connect_timeout}s",
        "distributed.scheduler.allowed-failures": TASK_RETRIES,
        "distributed.scheduler.worker-saturation": 1.0,
        "distributed.nanny.pre-spawn-environ": environ,
        **({**LOCAL_CLUSTER_CONFIG, "distributed.nanny.environ": dict(
            dask.config.get("distributed.nanny.environ", {}) or {}, **{KEEP_FILES_ENV: "1"})} if local else {})}))
    import multiprocessing

    # Dask's nanny puts pre-spawn-environ into this process's os.environ to hand it to the workers it
    # spawns (and re-spawns): OPENBLAS_NUM_THREADS=1 and the MALLOC_* settings would then reach every
    # later subprocess of the caller. Put back what this process had once the workers are started, and at close.
    before_environ = {key: os.environ.get(key) for key in environ}
    cleanup.callback(_restore_environment, before_environ)
    before = set(multiprocessing.active_children())
    cleanup.callback(_deferred, lambda: _end_processes(set(multiprocessing.active_children()) - before))
    cluster = None
    if local:
        from .processes import spawn_reruns_main

        script = spawn_reruns_main()
        if script is not None:  # Dask spawns its workers: each would run the calling script again
            raise ParameterError('scheduler', f"{{scheduler}} {scheduler}: {script} calls ftcal at its top level without "
                             "'if __name__ == \"__main__\":', and each local worker process would run the script "
                             "again; put the calls under that guard, or leave out the scheduler.")
    with signals_deferred():  # a cluster half started by Ctrl-C would be left running
        if local:
            try:
                cluster = LocalCluster(n_workers=n_workers, threads_per_worker=1, processes=True,
                                       dashboard_address=":0", silence_logs=logging.CRITICAL)
            except Exception as exc:  # noqa: BLE001 - e.g. a worker process that could not start
                detail = str(exc).splitlines()[0] if str(exc) else "no detail"
                raise ParameterError('scheduler', f"{{scheduler}} {scheduler}: the local Dask cluster did not start "
                                 f"({type(exc).__name__}: {detail}); nothing was written.") from None
            cleanup.callback(_deferred, _close_quietly, cluster)
            _restore_environment(before_environ)
        client = _connect(cluster if cluster is not None else scheduler, scheduler, connect_timeout)
        cleanup.callback(_deferred, client.close)
    check_versions(client, scheduler)
    if local:
        client.register_plugin(_ignore_interrupts_plugin())
    return client, time.perf_counter() - started


def _restore_environment(values: dict) -> None:
    """Set each variable back to its value in ``values`` (None: it was not set)."""
    for key, value in values.items():
        if value is None:
            os.environ.pop(key, None)
        else:
            os.environ[key] = value


def _deferred(function, *args) -> None:
    """``function(*args)`` with Ctrl-C, SIGTERM and SIGHUP deferred until it returns."""
    with signals_deferred():
        function(*args)


def _connect(address, scheduler: str, connect_timeout: float):
    """A distributed.Client on ``address`` (a cluster or an address), failures as one line."""
    from distributed import Client

    try:
        return Client(address, timeout=connect_timeout)
    except (OSError, TimeoutError) as exc:
        raise ParameterError('scheduler', f"{{scheduler}} {scheduler}: cannot reach the Dask scheduler within "
                         f"{connect_timeout:g} s ({type(exc).__name__}); check the address and "
                         "that `dask scheduler` runs there.") from None
    except ValueError as exc:  # Dask's own address parser: a bad scheme, host or port
        raise ParameterError('scheduler', f"{{scheduler}} {scheduler}: not a Dask scheduler address "
                         f"({str(exc).splitlines()[0] if str(exc) else type(exc).__name__}).") from None
    except Exception as exc:  # noqa: BLE001 - whatever answered sent garbage (Dask then
        # asked for exabytes: MemoryError, or failed to decode: many types)
        raise ParameterError('scheduler', f"{{scheduler}} {scheduler}: what answered there is not a Dask scheduler "
                         f"({type(exc).__name__} while connecting); check the address.") from None


def _close_quietly(cluster) -> None:
    """Close a local cluster; if that fails, :func:`_end_processes` still ends its workers."""
    try:
        cluster.close(timeout=SHUTDOWN_TIMEOUT_S)
    except Exception:  # noqa: BLE001 - e.g. a worker killed mid-start; its process is ended next
        pass


def _end_processes(processes) -> None:
    """Terminate, then kill, the multiprocessing children still alive (a local cluster's worker processes)."""
    for process in processes:
        process.terminate()
    for process in processes:
        process.join(SHUTDOWN_TIMEOUT_S)
        if process.is_alive():
            process.kill()
            process.join()


@contextmanager
def signals_deferred() -> Iterator[None]:
    """Inside the block, Ctrl-C, SIGTERM and SIGHUP wait; the first one arrives again at its end.

    For steps that must not stop half way: starting or stopping a local cluster
    (a half-started one leaves processes that nothing stops). The signal arrives
    even if the block raised (a worker killed by the same Ctrl-C fails the
    cluster's start): the user asked to stop. Outside the main thread nothing is
    deferred (Python handles signals only there).
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    caught: list[int] = []
    previous = {sig: signal.signal(sig, lambda signum, frame: caught.append(signum)) for sig in DEFERRED_SIGNALS}
    try:
        yield
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)
        if caught:
            signal.raise_signal(caught[0])  # through the previous handler: KeyboardInterrupt, the CLI's Terminated


def _ignore_interrupts_plugin():
    """A Dask worker plugin by which the worker process ignores SIGINT (the client handles Ctrl-C).

    A terminal sends Ctrl-C to the whole process group, local workers included;
    they would die with a traceback each while the client shuts them down in
    order. Dask runs the plugin on every worker, replaced ones too.
    """
    from distributed import WorkerPlugin

    class IgnoreInterrupts(WorkerPlugin):
        name = "ftcal-ignore-interrupts"

        def setup(self, worker) -> None:
            if threading.current_thread() is threading.main_thread():
                signal.signal(signal.SIGINT, signal.SIG_IGN)

    return IgnoreInterrupts()


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
        raise ParameterError('scheduler', f"{{scheduler}} {scheduler}: the workers cannot run ftcal tasks ({type(exc).__name__}: "
                         f"{str(exc).splitlines()[0] if str(exc) else 'no detail'}); install this ftcal on them.") \
            from None
    for worker, versions in sorted(theirs.items()):
        for package, version in mine.items():
            if versions.get(package) != version:
                raise ParameterError('scheduler', f"{{scheduler}} {scheduler}: worker {worker} runs {package} "
                                 f"{versions.get(package)} but this client runs {version}; install the same "
                                 "versions on the workers.")


def _versions() -> dict[str, str]:
    from importlib import metadata

    return {package: metadata.version(package) for package in ("ftcal", "numpy", "distributed")}
