"""Whole-process ``ftcal fit TABLE.parquet --degree 4`` against the flop floor, measured in the same run.

The table: ``n`` rows of the benchmarks' synthetic sensor (:func:`benchmarks.load_cases.make_data`):
7 inputs (6 channels + temperature) and 6 outputs, one Parquet file, written before any clock starts.
A degree-4 basis over 7 inputs has p = 330 terms (offset included).

Two floors, each measured in a fresh child process with every BLAS pinned to one thread (the
highest multiply-add rate per CPU second this machine gives):

* **dense Gram floor** (the issue's definition): the multiply-adds of AᵀA and AᵀY for the
  N × p regressor A, N·p(p+1)/2 + N·p·n_outputs, timed as they run: ``scipy.linalg.blas.dsyrk``
  and ``Aᵀ @ Y`` (dgemm) on one in-memory block of 65,536 × p (the streaming chunk), repeated to
  N rows;
* **moment floor**: ftcal never forms AᵀA; each entry is one of the distinct moments
  Σ u^e of degree ≤ 8 (6,435 for 7 inputs), and each moment and each entry of AᵀY needs at least
  one multiply-add per sample: N·(n_moments + p·n_outputs) multiply-adds at the rate the
  dsyrk/dgemm run just measured. This is the stricter floor (about 6× below the dense one);

plus, for both, **reading the table** alone: pyarrow's Parquet reader, the 13 columns in record
batches of 65,536 rows, each batch made into one float64 array (no checks, one thread, the file in
the page cache as for the fit; the interpreter's start and the imports are left out of the floor).

The floor's child also times ftcal's statistics pass alone on the blocks it read (normalization and the
compiled moment kernel, one thread), against the moments' multiply-adds.

The whole process is ``ftcal fit TABLE --degree 4 -o MODEL`` in a fresh interpreter (start-up,
imports, every pass over the file, the solve, the training metrics, writing the model): CPU =
user + system of that child from wait4, wall, its own peak resident memory (VmHWM). Floor and fit
alternate (floor, fit, floor, fit, ...) so a change of machine load moves both; ratio = fit CPU /
floor CPU pair by pair, median reported. With ``FTCAL_BASELINE_SRC`` set, the same command on
that source tree runs in each pair too (the code before a change).

Run: ``python -m benchmarks.bench_floor [N [PAIRS]]``.
"""

from __future__ import annotations

import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from benchmarks.bench_payload_cli import run_child

ROOT = Path(__file__).resolve().parent.parent
INPUTS = ("u1", "u2", "u3", "u4", "u5", "u6", "T")
OUTPUTS = ("Fx", "Fy", "Fz", "Tx", "Ty", "Tz")
BLOCK_ROWS = 1 << 16  # ftcal.data.table_chunks.CHUNK_ROWS: the floor's block is the streaming chunk
ONE_THREAD = {"OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1", "FTCAL_THREADS": "1"}


def write_table(path: str, n: int) -> None:
    """The benchmark table: ``n`` rows of make_data, inputs then outputs (not timed)."""
    import pandas as pd

    from benchmarks.load_cases import make_data

    u, y = make_data(n)
    pd.DataFrame(np.c_[u, y], columns=[*INPUTS, *OUTPUTS]).to_parquet(path)


def measure_floor(table: str, degree: int) -> dict:
    """In this (one-thread) process: the dense Gram's and the read's CPU seconds over the table's N rows."""
    import pyarrow.parquet as pq
    from scipy.linalg.blas import dsyrk

    from ftcal.core.features import MonomialBasis
    from ftcal.core.statistics import moment_plan

    n = pq.ParquetFile(table).metadata.num_rows
    p, ny = MonomialBasis(len(INPUTS), degree).n_terms, len(OUTPUTS)
    n_moments = int(moment_plan(len(INPUTS), degree).n_moments)

    def read() -> list:
        blocks = []
        with pq.ParquetFile(table) as parquet:
            for batch in parquet.iter_batches(batch_size=BLOCK_ROWS, columns=[*INPUTS, *OUTPUTS],
                                              use_threads=False):
                values = np.empty((batch.num_rows, batch.num_columns))
                for j, column in enumerate(batch.columns):
                    values[:, j] = column.to_numpy()
                blocks.append(values)
        return blocks

    read()  # once outside the clock: pyarrow's first to_numpy imports pandas; the file enters the page cache
    start = time.process_time()
    blocks = read()
    read_s = time.process_time() - start
    statistics_s = ftcal_statistics_seconds(blocks, degree)

    rng = np.random.default_rng(0)
    block = np.asfortranarray(rng.uniform(-1.0, 1.0, (BLOCK_ROWS, p)))
    targets = rng.uniform(-1.0, 1.0, (BLOCK_ROWS, ny))
    dsyrk(1.0, block, trans=1)  # first call outside the clock (library set-up)
    rows, start = 0, time.process_time()
    while rows < n:
        dsyrk(1.0, block, trans=1)
        block.T @ targets
        rows += BLOCK_ROWS
    gram_s = (time.process_time() - start) * n / rows
    dense_fma = n * (p * (p + 1) / 2 + p * ny)
    rate = dense_fma / gram_s
    moment_fma = n * (n_moments + p * ny)
    return {"n": n, "p": p, "n_moments": n_moments, "read_s": read_s, "dense_gram_s": gram_s,
            "statistics_s": statistics_s,
            "fma_per_s": rate, "dense_fma": dense_fma, "moment_fma": moment_fma, "moment_s": moment_fma / rate,
            "load_average": os.getloadavg()[0]}


def ftcal_statistics_seconds(blocks: list, degree: int) -> float:
    """CPU seconds of ftcal's statistics pass alone over blocks in memory (normalization, compiled kernel)."""
    from ftcal.core.features import MonomialBasis, RegressorLayout
    from ftcal.core.normalization import normalization_from_range
    from ftcal.core.statistics import StatisticsAccumulator

    k = len(INPUTS)
    low = np.min([b[:, :k].min(axis=0) for b in blocks], axis=0)
    high = np.max([b[:, :k].max(axis=0) for b in blocks], axis=0)
    total = StatisticsAccumulator(RegressorLayout(MonomialBasis(k, degree), len(OUTPUTS)),
                                  normalization_from_range(low, high))
    start = time.process_time()
    for block in blocks:
        total.add(block[:, :k], block[:, k:])
    total.statistics()
    return time.process_time() - start


def floor_child(table: str, degree: int) -> dict:
    """:func:`measure_floor` in a fresh process with every thread pool at one thread."""
    done = subprocess.run([sys.executable, "-m", "benchmarks.bench_floor", "--floor", table, str(degree)], cwd=ROOT,
                          capture_output=True, text=True, env=dict(os.environ, **ONE_THREAD))
    if done.returncode != 0:
        raise RuntimeError(f"floor measurement failed:\n{done.stderr[-2000:]}")
    return json.loads(done.stdout.strip().splitlines()[-1])


def fit_child(table: str, degree: int, model: str, src: str | None = None) -> dict:
    """One whole ``ftcal fit TABLE --degree D -o MODEL`` process (``src``: another ftcal tree)."""
    result = run_child(["fit", table, "--degree", str(degree), "-o", model], src)
    return {"wall_s": result["wall_s"], "cpu_s": result["cpu_s"], "peak_rss_mb": result["peak_rss_mb"]}


def fit_floor(n: int, pairs: int = 3, degree: int = 4, baseline_src: str | None = None) -> dict:
    """Paired floor and whole-process fit measurements on one ``n``-row table (see the module docstring)."""
    load_before = os.getloadavg()
    floors, fits, baselines, ratios, moment_ratios = [], [], [], [], []
    same_model = None
    with tempfile.TemporaryDirectory(prefix="ftcal-bench-floor-") as folder:
        table = str(Path(folder) / "table.parquet")
        write_table(table, n)
        for _ in range(pairs):
            floor = floor_child(table, degree)
            fit = fit_child(table, degree, f"{folder}/this.json")
            floors.append(floor)
            fits.append(fit)
            ratios.append(fit["cpu_s"] / (floor["dense_gram_s"] + floor["read_s"]))
            moment_ratios.append(fit["cpu_s"] / (floor["moment_s"] + floor["read_s"]))
            if baseline_src:
                baselines.append(fit_child(table, degree, f"{folder}/baseline.json", baseline_src))
                same_model = _same_coefficients(f"{folder}/this.json", f"{folder}/baseline.json")
    load_after = os.getloadavg()

    def median(rows, key):
        return float(statistics.median(r[key] for r in rows))

    result = {"n": n, "degree": degree, "pairs": pairs, "p": floors[0]["p"], "n_moments": floors[0]["n_moments"],
              "read_s": median(floors, "read_s"), "dense_gram_s": median(floors, "dense_gram_s"),
              "moment_s": median(floors, "moment_s"), "fma_per_s": median(floors, "fma_per_s"),
              "statistics_s": median(floors, "statistics_s"),
              "fit": {k: median(fits, k) for k in ("cpu_s", "wall_s", "peak_rss_mb")},
              "ratio_dense": float(statistics.median(ratios)), "ratios_dense": ratios,
              "ratio_moment": float(statistics.median(moment_ratios)), "ratios_moment": moment_ratios,
              "load_average": [load_before[0], load_after[0]], "seconds": median(fits, "wall_s")}
    if baselines:
        result["baseline"] = {k: median(baselines, k) for k in ("cpu_s", "wall_s", "peak_rss_mb")}
        result["baseline"]["src"] = baseline_src
        result["baseline"]["same_coefficients"] = same_model
    return result


def _same_coefficients(a: str, b: str) -> bool:
    """Whether two model files hold the same coefficients to 1e-12 (relative to the largest)."""
    from ftcal.files.model_json import load_model

    ca, cb = load_model(a).coef_, load_model(b).coef_
    return bool(np.max(np.abs(ca - cb)) <= 1e-12 * np.max(np.abs(cb)))


def floor_section(run_case, sizes: dict) -> tuple[list[str], str]:
    """The BENCHMARKS.md block and the targets line (issue 32: whole-process fit within 3× the flop floor)."""
    baseline = os.environ.get("FTCAL_BASELINE_SRC")
    r = run_case("fit_floor", n=sizes["floor_n"], pairs=sizes["floor_pairs"], baseline_src=baseline)
    fit, n = r["fit"], r["n"]
    dense_floor, moment_floor = r["dense_gram_s"] + r["read_s"], r["moment_s"] + r["read_s"]
    head = (f"`ftcal fit TABLE.parquet --degree 4`, N = {n:,}, 7 inputs: {fit['cpu_s']:.2f} CPU s "
            f"({fit['wall_s']:.2f} s wall), {r['ratio_moment']:.2f}× the moment floor and "
            f"{r['ratio_dense']:.2f}× the dense Gram floor (target ≤ 3×)")
    rows = [f"## Whole-process fit against the flop floor: degree 4, N = {n:,}, 7 inputs (6 channels + temperature)",
            "",
            f"`ftcal fit table.parquet --degree 4 -o model.json` as a fresh process, against floors measured in the "
            f"same run with every BLAS on one thread (benchmarks/bench_floor.py): p = {r['p']} terms, "
            f"{r['n_moments']:,} distinct moments of degree ≤ 8; the machine's dsyrk/dgemm rate "
            f"{r['fma_per_s'] / 1e9:.1f} G multiply-adds per CPU s. Floor and fit alternate, "
            f"{r['pairs']} pair(s), medians; load average {r['load_average'][0]:.2f} before, "
            f"{r['load_average'][1]:.2f} after.", "",
            "| what | CPU s | wall s | peak memory | fit CPU / this |", "|---|---:|---:|---:|---:|",
            f"| read the table (pyarrow, 13 columns → float64, alone) | {r['read_s']:.2f} | | | |",
            f"| dense Gram: AᵀA (dsyrk) + AᵀY (dgemm), N·p(p+1)/2 + N·p·6 multiply-adds | {r['dense_gram_s']:.2f} | "
            "| | |",
            f"| moments: N·({r['n_moments']:,} + p·6) multiply-adds at the dsyrk rate | {r['moment_s']:.2f} | | | |",
            f"| **dense Gram floor** = read + dense Gram | {dense_floor:.2f} | | | {r['ratio_dense']:.2f}× |",
            f"| **moment floor** = read + moments | {moment_floor:.2f} | | | {r['ratio_moment']:.2f}× |",
            f"| ftcal's statistics pass alone (data in memory, compiled kernel, one thread; "
            f"{r['statistics_s'] / r['moment_s']:.2f}× the moments' floor) | {r['statistics_s']:.2f} | | | |",
            f"| `ftcal fit`, whole process | {fit['cpu_s']:.2f} | {fit['wall_s']:.2f} | "
            f"{fit['peak_rss_mb']:,.0f} MB | 1.00× |"]
    if "baseline" in r:
        b = r["baseline"]
        rows.append(f"| the same command on `{b['src']}` (before) | {b['cpu_s']:.2f} | {b['wall_s']:.2f} | "
                    f"{b['peak_rss_mb']:,.0f} MB | {b['cpu_s'] / fit['cpu_s']:.2f}× this fit's CPU; coefficients "
                    f"{'equal to 1e-12' if b['same_coefficients'] else 'DIFFERENT'} |")
    rows += ["", f"Per pair, fit CPU / moment floor: {', '.join(f'{x:.2f}' for x in r['ratios_moment'])}; "
                 f"/ dense Gram floor: {', '.join(f'{x:.2f}' for x in r['ratios_dense'])}.", ""]
    return rows, head


CASES = {f.__name__: f for f in (fit_floor,)}


if __name__ == "__main__":
    if sys.argv[1:2] == ["--floor"]:
        print(json.dumps(measure_floor(sys.argv[2], int(sys.argv[3]))))
    else:
        print(json.dumps(fit_floor(*map(int, sys.argv[1:3]))), flush=True)
