"""Scale-out: statistics throughput on Dask workers, the size of one statistics message, peak memory of streaming.

Measured in one run on Parquet files written before the clocks start:

* statistics of a degree-``degree`` static model over all files (one task per file,
  each reading its file chunk by chunk, tree-summed): in this process
  (:class:`ftcal.runtime.executors.LocalExecutor`), and on ``local:1`` and ``local:2``
  Dask clusters (started before the clock; the time includes shipping the
  per-file statistics and the tree reduction);
* the size of one statistics message (``SufficientStatistics`` pickled as Dask
  sends it);
* peak resident memory of ``ftcal predict`` and ``ftcal evaluate`` streaming the
  files, each in a fresh process, against reading the same files whole and
  predicting in memory (the path before streaming);
* ``ftcal fit`` streaming the files (ranges pass, statistics pass, training-metrics
  pass) against reading them whole and fitting in memory, each in a fresh
  process: peak resident memory and wall time per sample (process start included
  in both), with the coefficients of the two compared.

Run: ``python -m benchmarks.bench_scale [n_files rows_per_file degree]``.
"""

from __future__ import annotations

import json
import os
import pickle
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
INPUTS = ("u1", "u2", "u3", "u4", "u5", "u6", "T")
OUTPUTS = ("Fx", "Fy", "Fz", "Tx", "Ty", "Tz")


def write_files(folder: Path, n_files: int, rows: int) -> list[str]:
    import pandas as pd

    from benchmarks.load_cases import make_data

    paths = []
    for index in range(n_files):
        u, y = make_data(rows, seed=index)
        path = folder / f"part{index:02d}.parquet"
        pd.DataFrame(np.c_[u, y], columns=[*INPUTS, *OUTPUTS]).to_parquet(path, row_group_size=1 << 16)
        paths.append(str(path))
    return paths


def statistics_on_a_worker(path: str, *args):
    """``file_statistics``, not marked ``releases_gil``: ``local:N`` runs it in its worker processes (the marked
    function runs in threads of this process, see bench_cluster)."""
    from ftcal.data.streaming import file_statistics

    return file_statistics(path, *args)


def statistics_rows(paths: list[str], rows: int, degree: int) -> tuple[list[dict], int]:
    from ftcal.core.features import MonomialBasis
    from ftcal.core.normalization import normalization_from_range
    from ftcal.data.streaming import add_statistics, file_statistics
    from ftcal.runtime.executors import LocalExecutor, open_executor

    basis = MonomialBasis(len(INPUTS), degree)
    # the generator's input ranges (benchmarks.cases.make_data)
    scale = np.array([120.0, 120.0, 110.0, 25.0, 25.0, 12.0, 0.0])
    norm = normalization_from_range(np.r_[-scale[:6], 25.0], np.r_[scale[:6], 44.0])
    samples = rows * len(paths)
    out = []
    start = time.perf_counter()
    local = LocalExecutor().map_reduce(file_statistics, paths, basis, norm, INPUTS, OUTPUTS, combine=add_statistics)
    seconds = time.perf_counter() - start
    out.append({"method": "this process (LocalExecutor)", "seconds": seconds, "samples_per_s": samples / seconds})
    for workers in (1, 2):
        with open_executor(f"local:{workers}") as executor:
            # imports on the workers happen before the clock, as on a long-lived cluster
            executor.map(statistics_on_a_worker, paths[:workers], basis, norm, INPUTS, OUTPUTS)
            start = time.perf_counter()
            total = executor.map_reduce(statistics_on_a_worker, paths, basis, norm, INPUTS, OUTPUTS,
                                        combine=add_statistics)
            seconds = time.perf_counter() - start
        assert np.array_equal(total.gram, local.gram) and np.array_equal(total.cross, local.cross)
        out.append({"method": f"Dask local:{workers} ({workers} worker process{'es' if workers > 1 else ''})",
                    "seconds": seconds, "samples_per_s": samples / seconds})
    message = len(pickle.dumps(local, protocol=5))
    return out, message


def peak_rss_of(code: str) -> float:
    """Peak RSS (MB) of a fresh Python process running ``code``.

    Read from VmHWM, which starts afresh at exec; ``ru_maxrss`` would carry this
    (larger) parent's peak over into the child.
    """
    runner = (f"{code}\n"
              "hwm = [l for l in open('/proc/self/status') if l.startswith('VmHWM')][0]\n"
              "print(int(hwm.split()[1]) / 1024.0)")
    done = subprocess.run([sys.executable, "-c", runner], cwd=ROOT, capture_output=True, text=True,
                          env=dict(os.environ, FTCAL_PROGRESS="0", PYTHONWARNINGS="ignore"))
    if done.returncode != 0:
        raise RuntimeError(done.stderr[-2000:])
    return float(done.stdout.strip().splitlines()[-1])


def memory_rows(paths: list[str], folder: Path, degree: int) -> list[dict]:
    from benchmarks.load_cases import make_data
    from ftcal.core.dataset import Dataset
    from ftcal.core.model import CalibrationModel
    from ftcal.files.model_files import save_model

    u, y = make_data(20_000, seed=99)
    model = CalibrationModel(degree).fit(Dataset.from_arrays(u, y, input_names=INPUTS, output_names=OUTPUTS))
    model_path = folder / "model.json"
    save_model(model, model_path)
    files = json.dumps(paths)
    cli = "from ftcal.cli import main\n"
    rows = []
    for label, code in (
            ("ftcal predict (streaming)",
             f"{cli}assert main(['predict', {str(model_path)!r}, *{files}, '-o', {str(folder / 'p.parquet')!r}]) == 0"),
            ("ftcal evaluate (streaming)",
             f"{cli}assert main(['evaluate', {str(model_path)!r}, *{files}, '--json']) == 0"),
            ("whole tables read, then predict (before streaming)",
             "from ftcal.files.model_files import load_model\nfrom ftcal.data.tables import load_dataset\n"
             f"m = load_model({str(model_path)!r})\nd = load_dataset({files}, inputs=m.input_names_, outputs=None)\n"
             "m.predict(d, warn_out_of_range=False)"),
            ("Python + ftcal + pyarrow imported, nothing read",
             "import ftcal.data.streaming, pyarrow.parquet, pandas")):
        start = time.perf_counter()
        peak = peak_rss_of(code)
        rows.append({"method": label, "peak_rss_mb": peak, "seconds": time.perf_counter() - start})
    return rows


def fit_rows(paths: list[str], folder: Path, rows_per_file: int, degree: int) -> list[dict]:
    """Streamed ``ftcal fit`` against whole tables + in-memory fit: peak RSS, time per sample, fresh processes."""
    from ftcal.files.model_files import load_model

    files = json.dumps(paths)
    streamed, whole = folder / "fit-streamed.json", folder / "fit-whole.json"
    samples = len(paths) * rows_per_file
    rows = []
    for label, code in (
            ("ftcal fit (streaming)",
             "from ftcal.cli import main\n"
             f"assert main(['fit', *{files}, '--degree', '{degree}', '-o', {str(streamed)!r}]) == 0"),
            ("whole tables read, then fit in memory (before streaming)",
             "from ftcal.files.model_files import save_model\nfrom ftcal.data.tables import load_dataset\n"
             "from ftcal.core.model import CalibrationModel\n"
             f"d = load_dataset({files}, inputs={INPUTS!r}, outputs={OUTPUTS!r})\n"
             f"save_model(CalibrationModel({degree}).fit(d), {str(whole)!r})")):
        start = time.perf_counter()
        peak = peak_rss_of(code)
        seconds = time.perf_counter() - start
        rows.append({"method": label, "peak_rss_mb": peak, "seconds": seconds,
                     "us_per_sample": 1e6 * seconds / samples})
    a, b = load_model(streamed).coef_, load_model(whole).coef_
    rows[0]["max_relative_coef_difference"] = float(np.max(np.abs(a - b)) / np.max(np.abs(b)))
    return rows


def main(n_files: int = 10, rows_per_file: int = 300_000, degree: int = 4) -> dict:
    with tempfile.TemporaryDirectory(prefix="ftcal-bench-scale-") as tmp:
        folder = Path(tmp)
        paths = write_files(folder, n_files, rows_per_file)
        stats, message = statistics_rows(paths, rows_per_file, degree)
        memory = memory_rows(paths, folder, degree)
        fit = fit_rows(paths, folder, rows_per_file, degree)
    from ftcal.runtime.threads import worker_count

    result = {"n_files": n_files, "rows_per_file": rows_per_file, "degree": degree, "cores": worker_count(),
              "table_mb": n_files * rows_per_file * (len(INPUTS) + len(OUTPUTS)) * 8 / 1e6,
              "statistics": stats, "message_bytes": message, "memory": memory, "fit": fit}
    for row in stats:
        print(f"  {row['method']:<46} {row['seconds']:8.2f} s {row['samples_per_s']:>12,.0f} samples/s",
              file=sys.stderr)
    print(f"  one statistics message: {message:,} bytes", file=sys.stderr)
    for row in memory:
        print(f"  {row['method']:<52} {row['peak_rss_mb']:8.0f} MB", file=sys.stderr)
    for row in fit:
        print(f"  {row['method']:<58} {row['peak_rss_mb']:8.0f} MB {row['us_per_sample']:8.3f} us/sample",
              file=sys.stderr)
    return result


if __name__ == "__main__":
    print(json.dumps(main(*map(int, sys.argv[1:]))))
