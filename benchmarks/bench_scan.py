"""One scan (issue 43): the streamed passes through ``scan(path, accumulators)`` against the per-file
functions before the change, and ``ftcal info MODEL``'s CPU.

Scan: ``files`` Parquet files of ``n`` rows each (the benchmarks' synthetic sensor, 7 inputs, 6
outputs, written before any clock starts). The work is a streamed static fit's passes: the summary
(ranges, segments, fingerprints, spreads), the degree-``degree`` statistics with the pose cells, and
the training error sums of a model fitted beforehand; plus the same passes fused into one scan
(summary, statistics and pose cells together). Each case runs in a fresh child process: CPU is the
child's user + system time for the passes alone (after the imports and the model), peak memory its
VmHWM. The baseline is ``ftcal/data/streaming.py`` at commit ``BASELINE_COMMIT`` (the 9 per-file
tasks), loaded from git into the child beside today's package; before and after alternate pair by
pair, medians reported.

Info: ``ftcal info MODEL`` as a user runs it (fresh interpreter, CPU from wait4) on a degree-3 model.

Run: ``python -m benchmarks.bench_scan [N [FILES [PAIRS]]]``.
"""

from __future__ import annotations

import json
import os
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
BASELINE_COMMIT = "564762e"  # main before the scan: file_summary, file_statistics_and_poses, file_error_sums, ...
INPUTS = ("u1", "u2", "u3", "u4", "u5", "u6", "T")
OUTPUTS = ("Fx", "Fy", "Fz", "Tx", "Ty", "Tz")


def write_tables(folder: str, n: int, files: int) -> list[str]:
    import pandas as pd

    from benchmarks.load_cases import make_data

    paths = []
    for index in range(files):
        u, y = make_data(n, seed=index)
        path = os.path.join(folder, f"part{index}.parquet")
        pd.DataFrame(np.c_[u, y], columns=[*INPUTS, *OUTPUTS]).to_parquet(path, row_group_size=65_536)
        paths.append(path)
    return paths


def baseline_module():
    """The streaming module before the scan, imported from git as ``ftcal.data._streaming_before``."""
    import importlib.util

    text = subprocess.run(["git", "show", f"{BASELINE_COMMIT}:src/ftcal/data/streaming.py"], cwd=ROOT,
                          capture_output=True, text=True, check=True).stdout
    path = Path(tempfile.mkdtemp()) / "_streaming_before.py"
    path.write_text(text)
    spec = importlib.util.spec_from_file_location("ftcal.data._streaming_before", path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # dataclasses look their module up there
    spec.loader.exec_module(module)
    return module


def child(which: str, paths: list[str], degree: int) -> dict:
    """In this process: the passes with the old functions ('before'), today's ('after') or one fused scan."""
    import resource

    from ftcal.core.features import MonomialBasis
    from ftcal.core.model import CalibrationModel
    from ftcal.core.normalization import normalization_from_range
    from ftcal.data import streaming
    from ftcal.data.tables import load_dataset
    from ftcal.runtime.executors import LocalExecutor

    module = baseline_module() if which == "before" else streaming
    model = CalibrationModel(degree).fit(load_dataset(paths[:1], inputs=INPUTS, outputs=OUTPUTS))
    executor = LocalExecutor()
    import pyarrow.parquet as pq

    low = np.min([[pq.ParquetFile(p).metadata.row_group(0).column(j).statistics.min for j in range(7)]
                  for p in paths], axis=0)
    high = np.max([[pq.ParquetFile(p).metadata.row_group(0).column(j).statistics.max for j in range(7)]
                   for p in paths], axis=0)
    basis, norm, box = MonomialBasis(7, degree), normalization_from_range(low, high), np.c_[low, high]
    start = resource.getrusage(resource.RUSAGE_SELF)
    if which == "fused":
        summary, parts, cells = executor.map_reduce(
            streaming.scan, paths, [streaming.Summary(INPUTS, OUTPUTS, None, None, False),
                                    streaming.Statistics(streaming.RegressorLayout(basis, 6), norm, None, INPUTS,
                                                         OUTPUTS), streaming.PoseCells(INPUTS, box)],
            combine=streaming.add_scans)
        summary, parts, cells = summary.value, parts.value, cells.value
    else:
        summary = executor.map_reduce(module.file_summary, paths, INPUTS, OUTPUTS, None, None, False,
                                      combine=module.add_statistics)
        parts, cells = executor.map_reduce(module.file_statistics_and_poses, paths, basis, norm, INPUTS, OUTPUTS,
                                           box, combine=module.add_statistics_and_poses)
    sums = executor.map_reduce(module.file_error_sums, paths, model, [], "one-step", "zeros", "drop", None, True,
                               combine=module.add_error_sums)
    end = resource.getrusage(resource.RUSAGE_SELF)
    from ftcal.core.statistics import sum_statistics

    stats = sum_statistics(parts)
    peak = 0.0
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith("VmHWM:"):
            peak = int(line.split()[1]) / 1024
    return {"cpu_s": end.ru_utime + end.ru_stime - start.ru_utime - start.ru_stime, "peak_rss_mb": peak,
            "rows": int(sum(summary.segment_lengths)), "gram_trace": float(np.trace(stats.gram)),
            "cells": len(cells), "rmse": sums.to_dict(OUTPUTS)["rmse"]}


def run_child_case(which: str, paths: list[str], degree: int) -> dict:
    env = dict(os.environ, FTCAL_PROGRESS="0", PYTHONWARNINGS="ignore", PYTHONPATH=str(ROOT / "src"))
    code = ("import json, sys; from benchmarks.bench_scan import child; "
            "print(json.dumps(child(sys.argv[1], json.loads(sys.argv[2]), int(sys.argv[3]))))")
    done = subprocess.run([sys.executable, "-c", code, which, json.dumps(paths), str(degree)], cwd=ROOT, env=env,
                          capture_output=True, text=True)
    if done.returncode != 0:
        raise RuntimeError(done.stderr[-2000:])
    return json.loads(done.stdout.strip().splitlines()[-1])


def info_cpu(repeats: int = 5, baseline_src: str | None = None) -> dict:
    """``ftcal info MODEL``: median CPU (user + system, wait4) and wall of a fresh process, a bare interpreter's,
    and with ``baseline_src`` the same command on that source tree, runs alternating."""
    import time

    from ftcal.core.dataset import Dataset
    from ftcal.core.model import CalibrationModel
    from ftcal.files.model_files import save_model

    from benchmarks.load_cases import make_data

    folder = tempfile.mkdtemp()
    model_path = os.path.join(folder, "model.json")
    u, y = make_data(5_000)
    save_model(CalibrationModel(3).fit(Dataset.from_arrays(u, y, input_names=INPUTS, output_names=OUTPUTS)),
               model_path)

    def timed(argv, src):
        env = dict(os.environ, FTCAL_PROGRESS="0", PYTHONPATH=src)
        began = time.perf_counter()
        proc = subprocess.Popen(argv, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        _, status, usage = os.wait4(proc.pid, 0)
        if os.waitstatus_to_exitcode(status) != 0:
            raise RuntimeError(f"{argv} failed")
        return usage.ru_utime + usage.ru_stime, time.perf_counter() - began

    runs: dict[str, list] = {"info": [], "baseline": [], "bare": []}
    for _ in range(repeats):
        runs["info"].append(timed([sys.executable, "-m", "ftcal", "info", model_path], str(ROOT / "src")))
        if baseline_src:
            runs["baseline"].append(timed([sys.executable, "-m", "ftcal", "info", model_path], baseline_src))
        runs["bare"].append(timed([sys.executable, "-c", "pass"], str(ROOT / "src")))
    out = {"cpu_s": statistics.median(c for c, _ in runs["info"]),
           "wall_s": statistics.median(w for _, w in runs["info"]), "bare_cpu_s": statistics.median(c for c, _ in runs["bare"])}
    if baseline_src:
        out["baseline_cpu_s"] = statistics.median(c for c, _ in runs["baseline"])
        out["baseline_wall_s"] = statistics.median(w for _, w in runs["baseline"])
    return out


def scan_section(n: int, files: int, pairs: int, degree: int = 4) -> tuple[list[str], str]:
    folder = tempfile.mkdtemp()
    paths = write_tables(folder, n, files)
    runs: dict[str, list[dict]] = {"before": [], "after": [], "fused": []}
    for _ in range(pairs):
        for which in runs:
            runs[which].append(run_child_case(which, paths, degree))
    base = runs["before"][0]
    for which, results in runs.items():  # the same numbers, whichever code ran
        for r in results:
            assert r["rows"] == base["rows"] and r["cells"] == base["cells"], which
            assert abs(r["gram_trace"] - base["gram_trace"]) <= 1e-12 * abs(base["gram_trace"]), which
            assert np.allclose(r["rmse"], base["rmse"], rtol=1e-12, atol=0), which
    med = {w: {k: statistics.median(r[k] for r in rs) for k in ("cpu_s", "peak_rss_mb")} for w, rs in runs.items()}
    ratio = {w: statistics.median(a["cpu_s"] / b["cpu_s"] for a, b in zip(runs[w], runs["before"])) for w in runs}
    label = {"before": f"per-file functions at {BASELINE_COMMIT} (file_summary, file_statistics_and_poses, "
                       "file_error_sums)",
             "after": "the same functions, each a scan of fixed accumulators",
             "fused": "scan(Summary, Statistics, PoseCells) in one read, then the errors' scan"}
    rows = [f"## One scan: a streamed static fit's passes, {files} Parquet files × {n:,} rows, degree {degree}", "",
            "Summary, statistics with pose cells, training error sums of a fitted model; CPU of the passes alone "
            f"(fresh process per case, median of {pairs}, the ratio the median of the pairs'); the rows, pose "
            "cells, Gram trace (1e-12) and RMSE (1e-12) of every run equal the baseline's.", "",
            "| code | CPU s | vs before | peak memory |", "|---|---:|---:|---:|"]
    for which in runs:
        rows.append(f"| {label[which]} | {med[which]['cpu_s']:.2f} | {ratio[which]:.2f}× | "
                    f"{med[which]['peak_rss_mb']:,.0f} MB |")
    head = (f"{files} × {n:,} rows, degree {degree}: scan {ratio['after']:.2f}× the per-file functions' CPU "
            f"({med['after']['cpu_s']:.2f} s against {med['before']['cpu_s']:.2f} s), fused {ratio['fused']:.2f}×; "
            f"peak {med['after']['peak_rss_mb']:,.0f} MB against {med['before']['peak_rss_mb']:,.0f} MB")
    return rows + [""], head


def info_section(repeats: int = 5) -> tuple[list[str], str]:
    baseline = os.environ.get("FTCAL_BASELINE_SRC")
    r = info_cpu(repeats, baseline)
    rows = ["## Light commands: `ftcal info MODEL`", "",
            f"A fresh process, median of {repeats}: CPU = user + system of the child (wait4); with "
            "`FTCAL_BASELINE_SRC` the same command on that source tree, runs alternating. Load average "
            f"{os.getloadavg()[0]:.1f} (2 cores): under load every CPU figure here is inflated alike.", "",
            "| command | CPU s | wall | vs bare interpreter (CPU) |", "|---|---:|---:|---:|",
            f"| `ftcal info MODEL` (degree 3) | {r['cpu_s']:.2f} | {r['wall_s']:.2f} s | "
            f"{r['cpu_s'] / r['bare_cpu_s']:.1f}× |"]
    if baseline:
        rows.append(f"| the same on {baseline} (before) | {r['baseline_cpu_s']:.2f} | {r['baseline_wall_s']:.2f} s | "
                    f"{r['baseline_cpu_s'] / r['bare_cpu_s']:.1f}× |")
    rows += [f"| `python -c pass` | {r['bare_cpu_s']:.3f} | | 1.0× |", ""]
    head = (f"`ftcal info MODEL`: {r['cpu_s']:.2f} CPU s (target ≤ 0.25 s), "
            f"{r['cpu_s'] / r['bare_cpu_s']:.1f}× a bare interpreter")
    if baseline:
        head += f"; before {r['baseline_cpu_s']:.2f} s in the same run"
    return rows, head


if __name__ == "__main__":
    n = int(sys.argv[1]) if len(sys.argv) > 1 else 200_000
    files = int(sys.argv[2]) if len(sys.argv) > 2 else 3
    pairs = int(sys.argv[3]) if len(sys.argv) > 3 else 3
    rows, head = scan_section(n, files, pairs)
    print("\n".join(rows))
    print(head)
    rows, head = info_section()
    print("\n".join(rows))
    print(head)
