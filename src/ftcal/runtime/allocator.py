"""The allocator settings of a command that streams large tables through numpy and pyarrow.

Each chunk of a streamed pass makes temporaries of a few MB (normalized inputs, the
fingerprint's row-major copy, column conversions). glibc serves blocks that size with a
fresh ``mmap`` until its dynamic threshold has grown, and returns freed heap to the system
whenever more than twice that threshold is free at its top, so the next chunk faults the same
pages in again, each zeroed by the kernel (numpy advises huge pages for its large arrays: 2 MiB
zeroed per fault). Measured on ``ftcal fit`` of a 10⁶-row Parquet table at degree 4: 56,000
page faults and 0.64 s of kernel time by default, 22,000 and 0.23 s with the settings below.

These are the settings ``local:N`` cluster workers get (:data:`ftcal.runtime.executors.WORKER_MALLOC`),
applied to the running process by ``mallopt`` (the environment variables are read only at a
process's start). pyarrow's record batches get the same treatment from its jemalloc pool. The
``ftcal fit`` command applies them; a program calling the library keeps its own.
"""

from __future__ import annotations

import ctypes
import gc
import sys

from .executors import WORKER_MALLOC

# Allocations between two collections of the youngest generation in a command that runs once (Python's: 700).
COMMAND_GC_THRESHOLD = 50_000
# glibc's mallopt parameters (malloc.h)
_M_TRIM_THRESHOLD = -1
_M_MMAP_THRESHOLD = -3


def keep_freed_memory() -> bool:
    """Set glibc's mmap and trim thresholds of this process to :data:`WORKER_MALLOC`'s, and pyarrow's
    buffers to a pool that keeps freed pages for reuse.

    Returns
    -------
    bool
        Whether they were set (False where the C library is not glibc: nothing is changed).
    """
    if not sys.platform.startswith("linux"):
        return False
    try:
        mallopt = ctypes.CDLL(None).mallopt
    except (OSError, AttributeError):  # musl and others: no mallopt
        return False
    mallopt.argtypes, mallopt.restype = (ctypes.c_int, ctypes.c_int), ctypes.c_int
    if not (mallopt(_M_MMAP_THRESHOLD, WORKER_MALLOC["MALLOC_MMAP_THRESHOLD_"])
            and mallopt(_M_TRIM_THRESHOLD, WORKER_MALLOC["MALLOC_TRIM_THRESHOLD_"])):
        return False
    import pyarrow

    # pyarrow's default pool (mimalloc) returns pages freed 10 ms ago to the system: between two record
    # batches the statistics take longer than that, so each batch's buffers were faulted in afresh.
    # jemalloc's (decay 1 s) keeps them; glibc's heap, set as above, where pyarrow was built without it.
    try:
        pool = pyarrow.jemalloc_memory_pool()
    except NotImplementedError:
        pool = pyarrow.system_memory_pool()
    pyarrow.set_memory_pool(pool)
    return True


def collect_less() -> None:
    """Collect cycles less often in a command that runs once and exits.

    The objects loaded so far (modules, classes, functions) move to the collector's permanent
    generation (``gc.freeze``) and the youngest generation is collected every
    :data:`COMMAND_GC_THRESHOLD` allocations: ``ftcal fit`` of a 200,000-row CSV spent ~0.05 of
    its 1.15 CPU s in collections that walked them again and again.
    """
    gc.freeze()
    _, second, third = gc.get_threshold()
    gc.set_threshold(COMMAND_GC_THRESHOLD, second, third)
