"""``ftcal fit FILES --degree 4`` as a user runs it, in one process and with ``--scheduler local:N``.

Each run is one whole ``ftcal fit`` process (imports, the cluster's start-up and shutdown, the ranges and
statistics passes, writing the model): CPU seconds of the process and every worker it waited for (user +
system from wait4), wall seconds, the command's own peak memory and its largest worker's, the workers'
page faults and kernel seconds (``getrusage(RUSAGE_CHILDREN)`` in the command: what the allocator settings
change), and the start-up seconds the command printed. The runs alternate (one process, cluster, and, with
``baseline_src``, the cluster of another source tree: the code before a change), so a machine whose speed
drifts moves them all; the figures are medians, the ratios medians of the pairs' cluster / one process.
The models are compared (their coefficients must be equal: the sums run in the same order).

``task_threads`` measures why ``local:N`` runs these tasks in threads: two files' task one after the other
against the same two in two threads of one process.

Run: ``python -m benchmarks.bench_cluster N_FILES ROWS [WORKERS [PAIRS [BASELINE_SRC]]]``, or
``python -m benchmarks.bench_cluster threads ROWS [ROUNDS]``.
"""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

# In the command's process, after it ran: its own peak memory, then its waited-for children's (the workers').
_REPORT = ("import resource, sys\nfrom ftcal.cli import main\ncode = main({argv!r})\n"
           "hwm = [l for l in open('/proc/self/status') if l.startswith('VmHWM')][0]\n"
           "kids = resource.getrusage(resource.RUSAGE_CHILDREN)\n"
           "print('VmHWM', int(hwm.split()[1]) / 1024.0, 'workers', kids.ru_maxrss / 1024.0, kids.ru_minflt, "
           "kids.ru_stime, file=sys.stderr)\nsys.exit(code)")


def run_fit(argv: list[str], src: str | None = None) -> dict:
    """One ``ftcal ARGV`` process (the ftcal tree ``src``, default this one): wall, CPU of it and its workers,
    peak memories, the workers' page faults and kernel seconds, the printed start-up seconds."""
    env = dict(os.environ, FTCAL_PROGRESS="0")
    if src is not None:
        env["PYTHONPATH"] = os.pathsep.join([src, *env.get("PYTHONPATH", "").split(os.pathsep)[1:]])
    with tempfile.TemporaryFile("w+") as err:
        start = time.perf_counter()
        child = subprocess.Popen([sys.executable, "-c", _REPORT.format(argv=argv)], stdout=subprocess.DEVNULL,
                                 stderr=err, env=env, text=True)
        _, status, usage = os.wait4(child.pid, 0)
        wall = time.perf_counter() - start
        err.seek(0)
        stderr = err.read()
    if os.waitstatus_to_exitcode(status) != 0:
        raise RuntimeError(stderr[-2000:])
    report = re.search(r"^VmHWM ([0-9.]+) workers ([0-9.]+) ([0-9]+) ([0-9.]+)", stderr, re.M)
    started = re.search(r"started in ([0-9.]+) s", stderr)
    startup_lines = len(re.findall(r"^(?:Dask )?local:[0-9]+: ", stderr, re.M))
    return {"wall_s": wall, "cpu_s": usage.ru_utime + usage.ru_stime, "peak_rss_mb": float(report.group(1)),
            "worker_peak_rss_mb": float(report.group(2)), "worker_page_faults": float(report.group(3)),
            "worker_system_s": float(report.group(4)),
            "startup_s": float(started.group(1)) if started else 0.0, "startup_lines": startup_lines}


def cluster_fit(n_files: int, rows: int, workers: int = 2, pairs: int = 2, degree: int = 4,
                baseline_src: str | None = None) -> dict:
    """Paired whole-process fits, one process against ``local:workers`` (and ``baseline_src``'s), on
    ``n_files`` Parquet files of ``rows`` rows."""
    from benchmarks.bench_scale import write_files
    from ftcal.files.model_files import load_model

    baseline_src = baseline_src or None
    load = [os.getloadavg()[0]]
    with tempfile.TemporaryDirectory(prefix="ftcal-bench-cluster-") as tmp:
        folder = Path(tmp)
        paths = write_files(folder, n_files, rows)
        scheduler = ["--scheduler", f"local:{workers}"]
        variants = {"one": ([], None), "cluster": (scheduler, None)}
        if baseline_src:
            variants["baseline"] = (scheduler, baseline_src)
        runs = {name: [] for name in variants}
        for _ in range(pairs):
            for name, (extra, src) in variants.items():
                argv = ["fit", *paths, "--degree", str(degree), "-o", str(folder / f"{name}.json"), *extra]
                runs[name].append(run_fit(argv, src))
                load.append(os.getloadavg()[0])
        coef = {name: load_model(folder / f"{name}.json").coef_ for name in variants}
    keys = ("wall_s", "cpu_s", "peak_rss_mb", "worker_peak_rss_mb", "worker_page_faults", "worker_system_s",
            "startup_s")
    summary = {name: {key: float(np.median([r[key] for r in rows_])) for key in keys} for name, rows_ in runs.items()}
    ratios = {name: {key: float(np.median([c[key] / o[key] for o, c in zip(runs["one"], runs[name])]))
                     for key in ("wall_s", "cpu_s")} for name in variants if name != "one"}
    return {"n_files": n_files, "rows": rows, "workers": workers, "pairs": pairs, **summary,
            "ratio": ratios["cluster"], "ratios": ratios, "load_average": [min(load), max(load)],
            "startup_lines": max(r["startup_lines"] for r in runs["cluster"]),
            "same_coefficients": all(bool(np.array_equal(coef["one"], c)) for c in coef.values()),
            "seconds": summary["cluster"]["wall_s"],
            "peak_rss_mb": summary["cluster"]["peak_rss_mb"] + summary["cluster"]["worker_peak_rss_mb"]}


def task_threads(rows: int = 1_000_000, rounds: int = 3, degree: int = 4) -> dict:
    """How much of a fit's file task holds the GIL: two files' task (``file_summary_statistics_and_poses``,
    the one-read ranges + statistics pass) one after the other, against the same two in two threads of one
    process (``LocalWorkers``' path). Rounds alternate; CPU is this process's (all its threads)."""
    from concurrent.futures import ThreadPoolExecutor

    from benchmarks.bench_scale import INPUTS, OUTPUTS, write_files
    from ftcal.core.features import MonomialBasis
    from ftcal.core.normalization import normalization_from_range
    from ftcal.data.streaming import file_summary_statistics_and_poses

    # the generator's input ranges (benchmarks.load_cases.make_data), as bench_scale uses them
    scale = np.array([120.0, 120.0, 110.0, 25.0, 25.0, 12.0, 0.0])
    low, high = np.r_[-scale[:6], 25.0], np.r_[scale[:6], 44.0]
    args = (INPUTS, OUTPUTS, None, None, MonomialBasis(len(INPUTS), degree), normalization_from_range(low, high),
            np.c_[low, high])
    load = [os.getloadavg()[0]]
    with tempfile.TemporaryDirectory(prefix="ftcal-bench-threads-") as tmp:
        paths = write_files(Path(tmp), 2, rows)
        file_summary_statistics_and_poses(paths[0], *args)  # imports and the moment plan, outside the timing
        runs = {"sequential": [], "threads": []}
        for _ in range(rounds):
            for name in runs:
                wall, cpu = time.perf_counter(), time.process_time()
                if name == "sequential":
                    results = [file_summary_statistics_and_poses(path, *args) for path in paths]
                else:
                    with ThreadPoolExecutor(2) as pool:
                        results = list(pool.map(lambda path: file_summary_statistics_and_poses(path, *args), paths))
                runs[name].append({"wall_s": time.perf_counter() - wall, "cpu_s": time.process_time() - cpu})
                load.append(os.getloadavg()[0])
        del results
    median = {name: {key: float(np.median([r[key] for r in rs])) for key in ("wall_s", "cpu_s")}
              for name, rs in runs.items()}
    ratio = {key: float(np.median([t[key] / s[key] for s, t in zip(runs["sequential"], runs["threads"])]))
             for key in ("wall_s", "cpu_s")}
    return {"rows": rows, "rounds": rounds, **median, "ratio": ratio, "load_average": [min(load), max(load)],
            "seconds": median["threads"]["wall_s"]}


CASES = {f.__name__: f for f in (cluster_fit, task_threads)}


if __name__ == "__main__":
    if sys.argv[1] == "threads":
        print(json.dumps(task_threads(*map(int, sys.argv[2:4]))))
    else:
        print(json.dumps(cluster_fit(*map(int, sys.argv[1:5]), baseline_src=(sys.argv[5:] or [None])[0])))
