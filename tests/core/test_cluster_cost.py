"""A local Dask cluster that costs what its work costs (issue 32): a fit's statistics tasks in threads of the command
(no start-up), worker processes without Dask's per-process housekeeping (stack sampling every 10 ms, memory checks
every 100 ms) for the rest, and the start-up said once, with its seconds. Results are checked against the
single-process run (the same sums in the same order: bit-identical).
"""

import json
import os
import re
import subprocess
import sys

import numpy as np
import pandas as pd
import pytest
from conftest import sensor_like_data

from ftcal.core.dataset import DEFAULT_OUTPUTS
from ftcal.runtime.executors import open_executor

INPUTS = ("u1", "u2", "u3", "u4", "u5", "u6", "T")
FTCAL = os.path.join(os.path.dirname(sys.executable), "ftcal")


def _worker_settings() -> dict:
    import dask

    return {"threads": os.environ.get("FTCAL_THREADS"),
            "profile": dask.config.get("distributed.worker.profile.enabled"),
            "monitor": dask.config.get("distributed.worker.memory.monitor-interval")}


def test_local_workers_skip_the_profiler_and_keep_this_processs_thread_split():
    with open_executor("local:2") as executor:
        seen = executor.client.run(_worker_settings)
    assert len(seen) == 2
    for settings in seen.values():
        # Each worker splits a chunk into ranges as this process does: its sums are bit-identical to the local run.
        assert settings["threads"] == os.environ.get("FTCAL_THREADS")
        assert settings["profile"] is False
        assert settings["monitor"] == "1s"


def _csv_files(folder, count: int, rows: int, seed: int = 11) -> list[str]:
    rng = np.random.default_rng(seed)
    paths = []
    for index in range(count):
        u, y = sensor_like_data(rng, rows)
        path = folder / f"part{index}.csv"
        pd.DataFrame(np.c_[u, y], columns=[*INPUTS, *DEFAULT_OUTPUTS]).to_csv(path, index=False, float_format="%.17g")
        paths.append(str(path))
    return paths


@pytest.mark.parametrize("extra, said", [
    # A static fit's passes run in two threads of the command: no worker process, and it says so once.
    ([], r"local:2: 2 threads of this process ran the tasks \(0\.0 s start-up: no worker process was needed\)"),
    # An ARX fit's statistics are not marked releases_gil: two worker processes start, and that is said once.
    (["--na", "1"], r"Dask local:2: 2 worker processes started in \d+\.\d s"),
])
def test_fit_on_local_workers_says_its_start_up_once_and_equals_the_local_fit(tmp_path, extra, said):
    paths = _csv_files(tmp_path, 3, 400)
    env = dict(os.environ, FTCAL_PROGRESS="0")
    models, errors = {}, {}
    for name, scheduler in (("here", []), ("dask", ["--scheduler", "local:2"])):
        out = tmp_path / f"{name}.json"
        done = subprocess.run([FTCAL, "fit", *paths, "--degree", "2", *extra, "-o", str(out), *scheduler],
                              capture_output=True, text=True, env=env, timeout=600)
        assert done.returncode == 0, done.stderr
        models[name], errors[name] = json.loads(out.read_text()), done.stderr
    lines = [line for line in errors["dask"].splitlines() if re.match(r"(Dask )?local:", line)]
    assert len(lines) == 1 and re.fullmatch(said, lines[0]), errors["dask"]
    assert "local:" not in errors["here"]
    for model in models.values():
        del model["created"], model["sha256"]
    assert models["here"] == models["dask"]


def _blas_threads() -> list[int]:
    from threadpoolctl import threadpool_info

    return [library["num_threads"] for library in threadpool_info() if library["user_api"] == "blas"]


def test_local_workers_run_marked_tasks_in_threads_at_once_and_leave_blas_as_they_found_it(tmp_path):
    """Statistics in two threads sum bit for bit as this process does; no worker process starts for them; the
    BLAS thread count is the one before (threads that limited and restored it in turn left one thread behind,
    and the solve after the map then rounded otherwise than one process)."""
    import threading

    from ftcal.core.features import MonomialBasis
    from ftcal.core.normalization import normalization_from_range
    from ftcal.data.streaming import add_statistics, file_statistics
    from ftcal.runtime.executors import LocalExecutor, releases_gil

    paths = _csv_files(tmp_path, 4, 3000, seed=13)
    args = (MonomialBasis(len(INPUTS), 3), normalization_from_range(np.full(7, -200.0), np.full(7, 200.0)),
            INPUTS, DEFAULT_OUTPUTS)
    both_running = threading.Barrier(2, timeout=120)

    @releases_gil
    def meet(path: str) -> str:
        both_running.wait()  # passes only when two tasks run at the same time
        return threading.current_thread().name

    import psutil

    before, children = _blas_threads(), {child.pid for child in psutil.Process().children(recursive=True)}
    local = LocalExecutor().map_reduce(file_statistics, paths, *args, combine=add_statistics)
    with open_executor("local:2") as executor:
        total = executor.map_reduce(file_statistics, paths, *args, combine=add_statistics)
        names = executor.map(meet, paths)
        started = {child.pid for child in psutil.Process().children(recursive=True)} - children
        assert executor.startup_s is None and not started
    assert np.array_equal(total.gram, local.gram) and np.array_equal(total.cross, local.cross)
    assert len(set(names)) == 2 and threading.current_thread().name not in names
    assert _blas_threads() == before


@pytest.mark.parametrize("bad", ["local:0", "local:x"])
def test_bad_scheduler_still_one_line_and_no_start_up_line(tmp_path, bad):
    done = subprocess.run([FTCAL, "fit", str(tmp_path / "none.csv"), "--degree", "1", "-o", str(tmp_path / "m.json"),
                           "--scheduler", bad], capture_output=True, text=True, env=dict(os.environ, FTCAL_PROGRESS="0"))
    assert done.returncode == 2 and len(done.stderr.strip().splitlines()) == 1


def _kept_files() -> int:
    from ftcal.data import table_chunks

    return len([kept for kept in table_chunks._WORKER_KEPT.values() if kept is not None])


def test_local_workers_read_a_small_file_once_across_passes(tmp_path):
    """Three passes over small files on local:2: the workers keep each file as the command's own process does,
    and what they serve from memory sums exactly like reading the files (the local run's statistics)."""
    from ftcal.core.features import MonomialBasis
    from ftcal.core.normalization import normalization_from_range
    from ftcal.data.streaming import add_statistics, file_statistics
    from ftcal.data.table_chunks import keep_in_memory
    from ftcal.runtime.executors import LocalExecutor

    rng = np.random.default_rng(12)
    paths = []
    for index in range(4):
        u, y = sensor_like_data(rng, 500)
        path = tmp_path / f"f{index}.parquet"
        pd.DataFrame(np.c_[u, y], columns=[*INPUTS, *DEFAULT_OUTPUTS]).to_parquet(path)
        paths.append(str(path))
    basis = MonomialBasis(len(INPUTS), 2)
    norm = normalization_from_range(np.full(7, -200.0), np.full(7, 200.0))
    args = (basis, norm, INPUTS, DEFAULT_OUTPUTS)
    with keep_in_memory():
        local = LocalExecutor().map_reduce(file_statistics, paths, *args, combine=add_statistics)
    def on_a_worker(path, *args):  # not marked releases_gil, so local:2 runs it in its worker processes
        return file_statistics(path, *args)

    with open_executor("local:2") as executor:
        sums = [executor.map_reduce(on_a_worker, paths, *args, combine=add_statistics) for _ in range(3)]
        kept = executor.client.run(_kept_files)
    assert sum(kept.values()) >= len(paths)  # every file kept by the worker(s) that read it
    for total in sums:
        assert np.array_equal(total.gram, local.gram) and np.array_equal(total.cross, local.cross)
    assert _kept_files() == 0  # this process keeps nothing outside keep_in_memory()


def _allocator_behaviour() -> dict:
    """glibc's own account (mallinfo2) of where a 16 MiB block comes from, and of the heap after it is freed."""
    import ctypes

    class Mallinfo2(ctypes.Structure):
        _fields_ = [(name, ctypes.c_size_t) for name in ("arena", "ordblks", "smblks", "hblks", "hblkhd",
                                                          "usmblks", "fsmblks", "uordblks", "fordblks", "keepcost")]

    mallinfo2 = ctypes.CDLL(None).mallinfo2
    mallinfo2.restype = Mallinfo2
    before = mallinfo2()
    block = np.ones(16 << 20, dtype=np.uint8)
    during = mallinfo2()
    del block
    after = mallinfo2()
    return {"mapped": during.hblkhd - before.hblkhd, "trimmed": during.arena - after.arena}


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="glibc's allocator")
def test_local_workers_allocate_large_temporaries_from_a_heap_they_keep():
    """The settings in WORKER_MALLOC, checked by what glibc does rather than by the environment. With Dask's
    own default (MALLOC_TRIM_THRESHOLD_=65536, which pins the mmap threshold at 128 KiB) or glibc's
    fresh-process default, a 16 MiB block is mapped for itself and unmapped when freed: page faults on every
    statistics chunk."""
    with open_executor("local:2") as executor:
        seen = executor.client.run(_allocator_behaviour)
    assert len(seen) == 2
    for behaviour in seen.values():
        assert behaviour["mapped"] == 0
        assert behaviour["trimmed"] == 0  # freed to the heap, which keeps it: the next chunk reuses the pages


@pytest.mark.slow
@pytest.mark.parametrize("delay", [0.5, 1.5, 3.0])
def test_ctrl_c_during_a_fit_in_threads_stops_it_in_one_line_and_writes_nothing(tmp_path, delay):
    """local:2's threads run the statistics pass of a static fit; a Ctrl-C then ends the command as it ends one
    process: exit 130, one line, no model (or, if the fit ended first, a clean run with its model)."""
    import signal
    import time

    rng = np.random.default_rng(17)
    paths = []
    for index in range(4):
        u, y = sensor_like_data(rng, 300_000)
        path = tmp_path / f"part{index}.parquet"
        pd.DataFrame(np.c_[u, y], columns=[*INPUTS, *DEFAULT_OUTPUTS]).to_parquet(path)
        paths.append(str(path))
    out = tmp_path / "model.json"
    proc = subprocess.Popen([FTCAL, "fit", *paths, "--degree", "4", "-o", str(out), "--scheduler", "local:2"],
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
                            env=dict(os.environ, FTCAL_PROGRESS="0"))
    time.sleep(delay)
    sent = proc.poll() is None
    if sent:
        proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=600)
    assert "Traceback" not in err, err
    if sent and proc.returncode == 130:
        assert err.strip().splitlines()[-1] in ("ftcal fit: interrupted", "ftcal: interrupted"), err
        assert not out.exists() and sorted(os.listdir(tmp_path)) == sorted(os.path.basename(p) for p in paths)
    else:  # the fit ended before the signal could stop it
        assert proc.returncode == 0 and out.exists(), err


def _environment(keys) -> dict:
    return {key: os.environ.get(key) for key in keys}


def test_local_workers_leave_this_processs_environment_as_they_found_it(monkeypatch):
    # Dask's nanny writes its pre-spawn variables into the spawning process's os.environ; a library caller's
    # later subprocesses would inherit one BLAS thread and the workers' allocator settings.
    keys = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS",
            "MALLOC_MMAP_THRESHOLD_", "MALLOC_TRIM_THRESHOLD_")
    for key in keys:
        monkeypatch.delenv(key, raising=False)
    monkeypatch.setenv("OMP_NUM_THREADS", "3")  # one that was set: it must come back as it was, not vanish
    before = _environment(keys)
    with open_executor("local:1") as executor:
        seen = executor.client.run(_environment, keys)
        assert _environment(keys) == before
    assert _environment(keys) == before
    (worker,) = seen.values()
    # The worker itself still got them (the test of the heap above checks glibc reads the MALLOC_* ones).
    assert worker["OPENBLAS_NUM_THREADS"] == "1"
    assert worker["MALLOC_MMAP_THRESHOLD_"] is not None
