"""Thread control for the hot loops.

ftcal's loops run many small matrix products (chunks of 1024 samples, LASSO path
steps on p × p matrices). Multi-threaded BLAS gains nothing on those and, when
the other core is busy, its spinning threads make them ten times slower. So the
loops pin BLAS to one thread and use the cores themselves, one chunk range per
worker thread (numpy releases the GIL inside its kernels).
"""

from __future__ import annotations

import contextvars
import os
import sys
import threading
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from contextlib import contextmanager
from functools import cache
from typing import TypeVar

from threadpoolctl import ThreadpoolController

T = TypeVar("T")
SMALL_CALL_ROWS = 64


def worker_count() -> int:
    """Worker threads for chunked loops: FTCAL_THREADS, else the usable cores (at most 8)."""
    configured = os.environ.get("FTCAL_THREADS")
    if configured and configured.isdigit() and int(configured) > 0:
        return int(configured)
    return max(1, min(8, len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1))


class _BlasLimit:
    """One process-wide limit of every loaded BLAS to one thread, counted across nested and concurrent blocks.

    OpenBLAS's thread count is global to each library, so per-block limits that save and restore
    it race when worker threads enter and leave blocks at different times; here the first block in
    limits, the last one out restores. NumPy and SciPy each ship their own OpenBLAS, and a library
    loaded after the first scan (SciPy is imported lazily) would stay multi-threaded: every entry
    rescans when modules were imported since the last scan (a scan costs ~10 ms; a check of
    ``len(sys.modules)`` costs nothing).
    """

    def __init__(self):
        self.lock = threading.Lock()
        self.depth = 0
        self.modules_seen = -1
        self.libraries: dict[str, object] = {}      # filepath -> threadpoolctl library controller
        self.original: dict[str, int] = {}          # filepath -> thread count before the outermost block

    def _scan(self) -> None:
        if len(sys.modules) == self.modules_seen:
            return
        self.modules_seen = len(sys.modules)
        for library in ThreadpoolController().select(user_api="blas").lib_controllers:
            self.libraries.setdefault(library.filepath, library)

    def enter(self) -> None:
        with self.lock:
            self._scan()
            for path, library in self.libraries.items():
                if path not in self.original:
                    self.original[path] = library.num_threads
                    library.set_num_threads(1)
            self.depth += 1

    def exit(self) -> None:
        with self.lock:
            self.depth -= 1
            if self.depth == 0:
                for path, threads in self.original.items():
                    self.libraries[path].set_num_threads(threads)
                self.original.clear()


_BLAS = _BlasLimit()
# A forked child inherits the counts but none of the threads inside blocks: it starts unlimited.
os.register_at_fork(after_in_child=lambda: _BLAS.__init__())


@contextmanager
def single_threaded_blas(*, scipy: bool = False):
    """Limit every loaded BLAS (NumPy's, SciPy's) to one thread inside the block.

    Parameters
    ----------
    scipy : bool
        Import SciPy's linear algebra first, so that its own OpenBLAS is limited too when the
        block may be the first to use it (importing SciPy costs ~0.2-0.7 s; callers that never
        touch SciPy leave it out).
    """
    if scipy:
        import scipy.linalg  # noqa: F401  (loads libscipy_openblas before the scan)
    _BLAS.enter()
    try:
        yield
    finally:
        _BLAS.exit()


def split_range(n: int, parts: int, align: int) -> list[tuple[int, int]]:
    """``parts`` contiguous (start, stop) ranges covering 0..n, boundaries multiples of ``align``."""
    blocks = -(-n // align)
    per = -(-blocks // parts) if parts else blocks
    edges = [min(i * per * align, n) for i in range(parts + 1)]
    return [(a, b) for a, b in zip(edges[:-1], edges[1:]) if b > a]


# Set in the pool's threads: work they submit runs inline, so nested calls cannot wait on a full pool.
_POOL_THREAD = threading.local()


def _mark_pool_thread() -> None:
    _POOL_THREAD.active = True


@cache
def _pool(workers: int) -> ThreadPoolExecutor:
    # One pool per process: its threads keep their per-thread workspaces (MomentPlan's) from
    # call to call, which a file streamed in many chunks would otherwise allocate per chunk.
    return ThreadPoolExecutor(workers, thread_name_prefix="ftcal", initializer=_mark_pool_thread)


# A forked child has none of the parent's threads: it starts its own pool.
os.register_at_fork(after_in_child=_pool.cache_clear)


def map_ranges(work: Callable[[int, int], T], n: int, align: int) -> list[T]:
    """Run ``work(start, stop)`` over ranges of 0..n in parallel threads, BLAS single-threaded."""
    workers = worker_count()
    ranges = split_range(n, workers, align)
    if n <= SMALL_CALL_ROWS:
        # Products this small never start BLAS threads; limiting them costs more than the work.
        return [work(a, b) for a, b in ranges]
    with single_threaded_blas():
        if len(ranges) <= 1 or getattr(_POOL_THREAD, "active", False):
            return [work(a, b) for a, b in ranges]
        # Each task runs in a copy of the caller's context: np.errstate lives there, and pool
        # threads would otherwise warn about what the caller silenced.
        contexts = [contextvars.copy_context() for _ in ranges]
        return list(_pool(workers).map(lambda context, ab: context.run(work, *ab), contexts, ranges))
