"""``ftcal fit FILES --degree 4`` as a user runs it, in one process and with ``--scheduler local:N``.

Each run is one whole ``ftcal fit`` process (imports, the cluster's start-up and shutdown, the ranges,
statistics and training-metrics passes, writing the model): CPU seconds of the process and every worker
it waited for (user + system from wait4), wall seconds, the command's own peak memory, and the start-up
seconds the command printed. One-process and cluster runs alternate (one, cluster, one, cluster) so a
machine whose speed drifts moves both; the figures are medians, the ratios cluster / one process.
The two models are compared (their coefficients must be equal: the sums run in the same order).

Run: ``python -m benchmarks.bench_cluster N_FILES ROWS [WORKERS [PAIRS]]``.
"""

from __future__ import annotations

import json
import os
import re
import sys
import tempfile
from pathlib import Path

import numpy as np

from benchmarks.bench_payload_cli import run_child


def cluster_fit(n_files: int, rows: int, workers: int = 2, pairs: int = 2, degree: int = 4) -> dict:
    """Paired whole-process fits, one process against ``local:workers``, on ``n_files`` Parquet files."""
    from benchmarks.bench_scale import write_files
    from ftcal.files.model_files import load_model

    with tempfile.TemporaryDirectory(prefix="ftcal-bench-cluster-") as tmp:
        folder = Path(tmp)
        paths = write_files(folder, n_files, rows)
        runs = {"one": [], "cluster": []}
        for _ in range(pairs):
            for name, extra in (("one", []), ("cluster", ["--scheduler", f"local:{workers}"])):
                out = folder / f"{name}.json"
                result = run_child(["fit", *paths, "--degree", str(degree), "-o", str(out), *extra])
                started = re.search(r"started in ([0-9.]+) s", result["stderr"])
                result["startup_s"] = float(started.group(1)) if started else 0.0
                result["startup_lines"] = result["stderr"].count(" started in ")
                runs[name].append(result)
        same = bool(np.array_equal(load_model(folder / "one.json").coef_, load_model(folder / "cluster.json").coef_))
    summary = {name: {key: float(np.median([r[key] for r in rows_])) for key in
                      ("wall_s", "cpu_s", "peak_rss_mb", "startup_s")} for name, rows_ in runs.items()}
    ratios = {key: float(np.median([c[key] / o[key] for o, c in zip(runs["one"], runs["cluster"])]))
              for key in ("wall_s", "cpu_s")}
    return {"n_files": n_files, "rows": rows, "workers": workers, "pairs": pairs, **summary, "ratio": ratios,
            "startup_lines": max(r["startup_lines"] for r in runs["cluster"]), "same_coefficients": same,
            "seconds": summary["cluster"]["wall_s"]}


CASES = {f.__name__: f for f in (cluster_fit,)}


if __name__ == "__main__":
    print(json.dumps(cluster_fit(*map(int, sys.argv[1:]))))
