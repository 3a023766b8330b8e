"""``ftcal fit --degree auto``: its printed cost estimate against the CPU it then uses, and ``--budget`` kept.

Each case is one whole ``ftcal fit`` process (imports, reading, search, final fit, writing):
CPU seconds (user + system, from the child's own rusage), wall seconds and peak memory, beside
the estimate the command printed before its search. Tables: the demo's dataset (168,420 rows,
7 inputs, condition number ~1.8e8; built by ``ftcal demo`` + ``ftcal dataset`` as README.md
does, when ``ftcal-demo/dataset.parquet`` exists) and synthetic load-case tables
(:func:`benchmarks.load_cases.make_load_cases`) of 2·10⁴, 2·10⁵ and 10⁶ rows with 6-8 inputs.
Targets (issues 27 and 32): estimate/measured within 2×, measured CPU ≤ 1.5× ``--budget``.

Run: ``python -m benchmarks.bench_cost N N_INPUTS [BUDGET]``.
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

ROOT = Path(__file__).resolve().parent.parent
DEMO_TABLE = ROOT / "ftcal-demo" / "dataset.parquet"


def _run_fit(table: str, extra: list[str], env: dict | None = None) -> dict:
    """One ``ftcal fit --degree auto`` child: its estimate, CPU, wall and peak memory."""
    ftcal = str(Path(sys.executable).with_name("ftcal"))
    with tempfile.TemporaryDirectory() as folder:
        argv = [ftcal, "fit", table, "--degree", "auto", "--group-by", "group", *extra, "-o", f"{folder}/best.json"]
        start = time.perf_counter()
        child = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                                 env=dict(os.environ, FTCAL_PROGRESS="0", **(env or {})))
        stdout, stderr = child.communicate()
        wall = time.perf_counter() - start
    if child.returncode != 0:
        raise RuntimeError(stderr[-2000:])
    return _parse(stdout, wall)


def _parse(stdout: str, wall: float) -> dict:
    estimate = re.search(r"about ([0-9.]+) s of CPU", stdout) or re.search(r"about ([0-9.]+) s on one core", stdout)
    dropped = re.search(r"^(degrees? [0-9, ]+ not tried[^\n]*)", stdout, re.M)
    selected = re.search(r"^selected[^\n]*", stdout, re.M) or re.search(r"^best single model[^\n]*", stdout, re.M)
    return {"estimate_s": float(estimate.group(1)) if estimate else float("nan"), "wall_s": wall,
            "dropped": dropped.group(1) if dropped else "", "selected": selected.group(0) if selected else ""}


def select_cost(n: int = 0, n_inputs: int = 7, budget: float | None = None, blas_threads: int | None = None) -> dict:
    """``ftcal fit TABLE --degree auto`` in a child process; ``n = 0`` is the demo's dataset."""
    import resource

    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    extra = ["--budget", str(budget)] if budget is not None else []
    # Every thread pool forced: OpenBLAS (NumPy's and SciPy's), OpenMP and MKL where present.
    env = {name: str(blas_threads) for name in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")} \
        if blas_threads else None
    if n == 0:
        if not DEMO_TABLE.exists():
            raise RuntimeError(f"{DEMO_TABLE} is missing: run ftcal demo --out ftcal-demo and README's ftcal dataset")
        result = _run_fit(str(DEMO_TABLE), extra, env)
    else:
        import pandas as pd

        from benchmarks.load_cases import make_load_cases

        u, y, groups = make_load_cases(n, n_channels=n_inputs)
        with tempfile.TemporaryDirectory() as folder:
            table = Path(folder) / "cases.parquet"
            frame = pd.DataFrame(u, columns=[f"s{i + 1}" for i in range(n_inputs)])
            frame[["Fx", "Fy", "Fz", "Tx", "Ty", "Tz"]] = y
            frame["group"] = groups
            frame.to_parquet(table)
            result = _run_fit(str(table), ["--inputs", ",".join(frame.columns[:n_inputs]), *extra], env)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    result.update(cpu_s=cpu, child_peak_rss_mb=after.ru_maxrss / 1024.0, n=n, n_inputs=n_inputs, budget=budget,
                  ratio=result["estimate_s"] / cpu if cpu > 0 else float("nan"), seconds=result["wall_s"])
    return result


def threads_pair(pairs: int = 2) -> dict:
    """The demo search with every thread pool forced to one thread against the default, in turn (default,
    forced, default, forced): CPU(forced) / CPU(default) per pair, its median (issue 32: ≥ 0.95 says no
    core is oversubscribed; below, the default's extra threads burn CPU without doing work)."""
    runs = {"default": [], "forced": []}
    for _ in range(pairs):
        runs["default"].append(select_cost(0, 7))
        runs["forced"].append(select_cost(0, 7, blas_threads=1))
    ratios = [f["cpu_s"] / d["cpu_s"] for d, f in zip(runs["default"], runs["forced"])]
    median = {name: {key: float(sorted(r[key] for r in rows)[len(rows) // 2]) for key in ("cpu_s", "wall_s")}
              for name, rows in runs.items()}
    return {"pairs": pairs, **median, "ratios": ratios, "ratio": sorted(ratios)[len(ratios) // 2] if pairs % 2
            else 0.5 * (sorted(ratios)[pairs // 2 - 1] + sorted(ratios)[pairs // 2]),
            "seconds": median["default"]["wall_s"]}


CASES = {f.__name__: f for f in (select_cost, threads_pair)}


if __name__ == "__main__":
    args = [float(a) for a in sys.argv[1:]]
    print(json.dumps(select_cost(int(args[0]), int(args[1]), args[2] if len(args) > 2 else None)))
