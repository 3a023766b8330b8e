"""Benchmark cases. Each runs in a fresh process (``python -m benchmarks.cases NAME JSON``)
so its peak resident memory is its own; it prints one JSON line with the
measured seconds and peak RSS (MB, including ~150 MB of interpreter and imports).

Data: inputs like the paper's (6 raw channels in wrench units plus temperature
25–44 °C), outputs a smooth nonlinear function of them; generated before the
clock starts.
"""

from __future__ import annotations

import json
import os
import resource
import sys
import time
from itertools import combinations_with_replacement

import numpy as np

from benchmarks.bench_bags import CASES as BAG_CASES
from benchmarks.bench_c import CASES as C_CASES
from benchmarks.bench_cost import CASES as COST_CASES
from benchmarks.bench_select_rates import SELECT_RATE_CASES
from benchmarks.bench_real_like import REAL_LIKE_CASES
from benchmarks.bench_payload_errors import PAYLOAD_ERROR_CASES
from benchmarks.bench_floor import CASES as FLOOR_CASES
from benchmarks.bench_live import LIVE_CASES
from benchmarks.bench_closed_loop import CASES as CLOSED_LOOP_CASES
from benchmarks.bench_payload_cli import CASES as PAYLOAD_CLI_CASES
from benchmarks.bench_cluster import CASES as CLUSTER_CASES
from benchmarks.bench_mlp import CASES as MLP_CASES
from benchmarks.bench_plan import CASES as PLAN_CASES
from benchmarks.load_cases import N_OUTPUTS, make_data, make_load_cases



def paper_features(u: np.ndarray, degree: int) -> np.ndarray:
    """The dense regressor as the paper's code builds it: one column per monomial, offset last."""
    combos = [c for p in range(1, degree + 1) for c in combinations_with_replacement(range(u.shape[1]), p)]
    a = np.empty((u.shape[0], len(combos) + 1))
    for k, combo in enumerate(combos):
        a[:, k] = np.prod(u[:, list(combo)], axis=1)
    a[:, -1] = 1.0
    return a


def peak_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


# ----------------------------------------------------------------- fitting
def ftcal_fit(n: int, degree: int, kernel: str = "compiled") -> dict:
    """``CalibrationModel(degree).fit``; ``kernel="numpy"``: without the compiled kernels."""
    from contextlib import nullcontext

    from ftcal.core.dataset import Dataset
    from ftcal.core.kernels import use_numpy_kernel
    from ftcal.core.model import CalibrationModel

    u, y = make_data(n)
    data = Dataset.from_arrays(u, y)
    start = time.perf_counter()
    with use_numpy_kernel() if kernel == "numpy" else nullcontext():
        model = CalibrationModel(degree).fit(data)
    seconds = time.perf_counter() - start
    return {"seconds": seconds, "train_force_norm_rmse": model.training_metrics_["force_norm_rmse"]}


def ftcal_statistics(n: int, degree: int) -> dict:
    """Only the streaming pass (the part that scales with N)."""
    from ftcal.core.features import MonomialBasis
    from ftcal.core.normalization import normalization_from_range
    from ftcal.core.statistics import static_statistics

    u, y = make_data(n)
    norm = normalization_from_range(u.min(0), u.max(0))
    u_norm = norm.apply(u)
    start = time.perf_counter()
    static_statistics(MonomialBasis(u.shape[1], degree), u_norm, y)
    return {"seconds": time.perf_counter() - start}


def paper_recipe_fit(n: int, degree: int, eps: float = 1e-4) -> dict:
    """Dense max-abs scaled regressor, then OSQP per output (the paper's least-squares QP)."""
    from ftcal.core.solvers.osqp_qp import OsqpLeastSquares

    u, y = make_data(n)
    start = time.perf_counter()
    a = paper_features(u, degree)
    a /= np.abs(a).max(axis=0)
    result = OsqpLeastSquares(eps=eps).fit_dense(a, y)
    seconds = time.perf_counter() - start
    return {"seconds": seconds, "osqp_iterations": result.info["iterations"]}


def numpy_lstsq_fit(n: int, degree: int) -> dict:
    from ftcal.core.features import MonomialBasis

    u, y = make_data(n)
    start = time.perf_counter()
    u_norm = (u - u.mean(0)) / u.std(0)
    a = MonomialBasis(u.shape[1], degree).evaluate(u_norm)
    np.linalg.lstsq(a, y, rcond=None)
    return {"seconds": time.perf_counter() - start}


def sklearn_fit(n: int, degree: int) -> dict:
    from sklearn.linear_model import LinearRegression
    from sklearn.pipeline import make_pipeline
    from sklearn.preprocessing import MaxAbsScaler, PolynomialFeatures

    u, y = make_data(n)
    start = time.perf_counter()
    make_pipeline(PolynomialFeatures(degree), MaxAbsScaler(), LinearRegression()).fit(u, y)
    return {"seconds": time.perf_counter() - start}


# ------------------------------------------------------------------- LASSO
LAMBDAS = (0.5, 1.0, 10.0, 50.0, 100.0, 200.0)


def ftcal_lasso(n: int, degree: int) -> dict:
    """Statistics pass + warm-started path over the six λ, all six outputs."""
    from ftcal.core.dataset import Dataset
    from ftcal.core.select import Candidate, fit_candidates

    u, y = make_data(n)
    data = Dataset.from_arrays(u, y)
    start = time.perf_counter()
    models = fit_candidates(data, [Candidate(degree, "lasso", lam) for lam in LAMBDAS])
    seconds = time.perf_counter() - start
    return {"seconds": seconds, "n_nonzero": [int(np.count_nonzero(m.coef_)) for m in models.values()]}


def paper_lasso(n: int, degree: int, outputs: int = 1, lam: float = 50.0) -> dict:
    """The paper's OSQP LASSO (one residual variable per sample), ``outputs`` outputs, one λ."""
    from ftcal.core.solvers.osqp_qp import OsqpLasso

    u, y = make_data(n)
    start = time.perf_counter()
    a = paper_features(u, degree)
    a /= np.abs(a).max(axis=0)
    OsqpLasso(lam).fit_dense(a, y[:, :outputs])
    return {"seconds": time.perf_counter() - start}


def sklearn_lasso(n: int, degree: int) -> dict:
    """PolynomialFeatures + MaxAbsScaler + lasso_path over the six λ (α = λ/N), all outputs."""
    from sklearn.linear_model import lasso_path
    from sklearn.preprocessing import MaxAbsScaler, PolynomialFeatures

    u, y = make_data(n)
    start = time.perf_counter()
    a = MaxAbsScaler().fit_transform(PolynomialFeatures(degree).fit_transform(u))
    alphas = np.array(sorted(LAMBDAS, reverse=True)) / n
    for i in range(y.shape[1]):
        lasso_path(a, y[:, i], alphas=alphas, max_iter=5000, tol=1e-4)
    return {"seconds": time.perf_counter() - start}


# -------------------------------------------------------- model selection
def select_auto(n: int, folds: int = 5) -> dict:
    """``ftcal fit --degree auto`` (the default grid) in-process on ``n`` samples of 60 load cases, 8 inputs.

    The same command line works on every ftcal version, so its time before and after a
    change compares like with like.
    """
    import tempfile
    from pathlib import Path

    import pandas as pd

    from ftcal.cli import main

    u, y, groups = make_load_cases(n)
    with tempfile.TemporaryDirectory() as folder:
        table = Path(folder) / "cases.parquet"
        frame = pd.DataFrame(u, columns=[f"s{i + 1}" for i in range(u.shape[1])])
        frame[["Fx", "Fy", "Fz", "Tx", "Ty", "Tz"]] = y
        frame["group"] = groups
        frame.to_parquet(table)
        inputs = ",".join(frame.columns[:u.shape[1]])
        start = time.perf_counter()
        code = main(["fit", str(table), "--inputs", inputs, "--degree", "auto", "--group-by", "group",
                     "--folds", str(folds), "-o", str(Path(folder) / "best.json")])
        seconds = time.perf_counter() - start
    if code != 0:
        raise RuntimeError(f"ftcal fit --degree auto exited with {code}")
    return {"seconds": seconds}


def _load_case_dataset(n: int):
    from ftcal.core.dataset import Dataset

    u, y, groups = make_load_cases(n)
    return Dataset.from_arrays(u, y, input_names=[f"s{i + 1}" for i in range(u.shape[1])], groups=groups)


def select_auto_baseline(n: int, folds: int = 5) -> dict:
    """The strategy ``--degree auto`` used before issue 9, kept here as the baseline.

    The paper's six λ for LASSO at degrees 1-5 plus least squares (35 candidates), one
    statistics pass per fold at degree 5 (lower degrees as sub-blocks), every candidate
    scored by predicting its validation and training samples, then the winner refitted.
    """
    import warnings

    from ftcal.core import metrics
    from ftcal.core.features import MonomialBasis, RegressorLayout
    from ftcal.core.model import CalibrationModel, model_from_fitted
    from ftcal.core.normalization import normalization_from_range
    from ftcal.core.select import grouped_folds
    from ftcal.core.solvers import Lasso, LeastSquares, ScaledProblem
    from ftcal.core.statistics import sum_statistics

    data = _load_case_dataset(n)
    start = time.perf_counter()
    warnings.simplefilter("ignore")
    u, y = data.inputs, data.outputs
    masks = grouped_folds(data.groups, folds)
    in_norm = normalization_from_range(u.min(0), u.max(0), "center")
    out_norm = normalization_from_range(y.min(0), y.max(0), "center")
    layouts = {d: RegressorLayout(MonomialBasis(u.shape[1], d), y.shape[1]) for d in range(1, 6)}
    parts = [CalibrationModel.statistics(data.subset(m), layouts[5], in_norm, out_norm) for m in masks]
    scores: dict = {}
    for f, mask in enumerate(masks):
        train = sum_statistics([parts[g] for g in range(len(parts)) if g != f])
        val, rest = data.subset(mask), data.subset(~mask)
        for d, layout in layouts.items():
            problem = ScaledProblem.from_statistics(train.restrict(layout.basis.index_in(layouts[5].basis)))
            results = [("none", None, LeastSquares().fit(problem))]
            results += [("lasso", lam, r) for lam, r in zip(LAMBDAS, Lasso(1.0).fit_path(problem, LAMBDAS))]
            for penalty, lam, result in results:
                model = model_from_fitted(
                    degree=d, na=0, nb=0, normalization="center", coef=result.coef / problem.column_scale[:, None],
                    input_normalization=in_norm, output_normalization=out_norm, input_names=data.input_names,
                    output_names=data.output_names, input_range=np.c_[u.min(0), u.max(0)],
                    output_range=np.c_[y.min(0), y.max(0)])
                for part, kind in ((val, "val"), (rest, "train")):
                    p = model.predict(part, warn_out_of_range=False)
                    scores.setdefault((d, penalty, lam, kind), []).append(
                        metrics.norm_rmse(part.outputs[:, :3], p[:, :3]))
    best = min((k for k in scores if k[3] == "val"), key=lambda k: np.mean(scores[k]))
    solver = Lasso(best[2]) if best[1] == "lasso" else LeastSquares()
    CalibrationModel(best[0], solver=solver, normalization="center").fit(data)
    label = f"np{best[0]} lasso λ={best[2]:g}" if best[1] == "lasso" else f"np{best[0]} least squares"
    return {"seconds": time.perf_counter() - start, "best": label}


def select_auto_new(n: int, folds: int = 5) -> dict:
    """Today's ``--degree auto`` in the library (the same work as :func:`select_auto` without file I/O)."""
    import warnings

    from ftcal.core.select import fit_best, select_model

    data = _load_case_dataset(n)
    start = time.perf_counter()
    warnings.simplefilter("ignore")
    result = select_model(data, n_folds=folds)
    fit_best(data, result)
    return {"seconds": time.perf_counter() - start, "best": result.best.label,
            "n_candidates": len(result.scores)}


# -------------------------------------------------------------- prediction
def ftcal_predict(n: int, degree: int) -> dict:
    from ftcal.core.dataset import Dataset
    from ftcal.core.model import CalibrationModel

    u, y = make_data(20_000)
    model = CalibrationModel(degree).fit(Dataset.from_arrays(u, y))
    big, _ = make_data(n, seed=1)
    data = Dataset.from_arrays(big)
    model.predict(Dataset.from_arrays(big[:1000]))  # warm-up: thread pool, caches
    start = time.perf_counter()
    model.predict(data, warn_out_of_range=False)
    seconds = time.perf_counter() - start
    return {"seconds": seconds, "samples_per_s": n / seconds}


def sklearn_predict(n: int, degree: int) -> dict:
    from sklearn.linear_model import LinearRegression
    from sklearn.pipeline import make_pipeline
    from sklearn.preprocessing import MaxAbsScaler, PolynomialFeatures

    u, y = make_data(20_000)
    pipe = make_pipeline(PolynomialFeatures(degree), MaxAbsScaler(), LinearRegression()).fit(u, y)
    big, _ = make_data(n, seed=1)
    start = time.perf_counter()
    for s in range(0, n, 100_000):  # chunked, as anyone would at this size
        pipe.predict(big[s:s + 100_000])
    seconds = time.perf_counter() - start
    return {"seconds": seconds, "samples_per_s": n / seconds}


# ----------------------------------------------------------------- payload identification
def make_payload_data(n: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Sensor orientations (quaternions x, y, z, w) and static readings of a 1.3 kg tool plus bias and noise."""
    from scipy.spatial.transform import Rotation

    rot = Rotation.random(n, random_state=seed)
    g = rot.inv().apply([0.0, 0.0, -9.81])
    com, bias = np.array([0.01, -0.02, 0.07]), np.array([3.0, -2.0, 5.0, 0.1, -0.2, 0.05])
    wrench = np.c_[1.3 * g, np.cross(com, 1.3 * g)] + bias
    wrench += np.random.default_rng(seed).normal(size=wrench.shape) * [0.3, 0.3, 0.3, 0.01, 0.01, 0.01]
    return rot.as_quat(), wrench


def ftcal_payload(n: int) -> dict:
    """Quaternions → gravity, streaming per-axis statistics, weighted fit with standard errors."""
    from ftcal.payload.accumulate import payload_statistics
    from ftcal.payload.identify import identify_from_statistics
    from ftcal.payload.kinematics import Kinematics, gravity_from_quaternions

    q, wrench = make_payload_data(n)
    start = time.perf_counter()
    gravity = gravity_from_quaternions(q)
    fit = identify_from_statistics({"all": payload_statistics(wrench, Kinematics(gravity))})
    seconds = time.perf_counter() - start
    return {"seconds": seconds, "mass": fit.mass}


def ftcal_payload_drift(n: int, model: str = "random-walk") -> dict:
    """``identify_recording`` (what ``ftcal payload --time time --bias-drift MODEL`` runs after reading):
    the constant-bias fit with grouped-jackknife standard errors, then the bias model. ``random-walk``
    works on per-block averages (at most 1,000 time blocks), so its extra cost is one O(N) averaging
    pass plus O(blocks) filtering; the data (N rows, 100 Hz, random-walk bias) is made before the clock."""
    from ftcal.payload.kinematics import Kinematics, gravity_from_quaternions
    from ftcal.payload.tables import PayloadRecording, identify_recording

    q, wrench = make_payload_data(n)
    rng = np.random.default_rng(1)
    wrench += np.cumsum(rng.normal(size=wrench.shape), axis=0) * [0.003, 0.003, 0.003, 1e-4, 1e-4, 1e-4]
    time_s = np.arange(n) / 100.0
    labels = np.full(n, "all", dtype=object)
    start = time.perf_counter()
    recording = PayloadRecording(wrench, Kinematics(gravity_from_quaternions(q)), labels, time_s, None)
    result = identify_recording(recording, bias_drift=model, time_column="time", cross_validate=False)
    seconds = time.perf_counter() - start
    return {"seconds": seconds, "mass": result.fit.mass, "mass_stderr": result.fit.stderr["mass"]}


def numpy_payload_lstsq(n: int) -> dict:
    """The stacked 6N × 10 regressor built with numpy, then ``numpy.linalg.lstsq`` (no weights, no stderr)."""
    q, wrench = make_payload_data(n)
    start = time.perf_counter()
    x, y, z, w = q.T
    g = -9.81 * np.column_stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)])
    a = np.zeros((n, 6, 10))
    a[:, :3, 0] = g
    a[:, 3, 2], a[:, 3, 3] = g[:, 2], -g[:, 1]  # (m c) × g
    a[:, 4, 1], a[:, 4, 3] = -g[:, 2], g[:, 0]
    a[:, 5, 1], a[:, 5, 2] = g[:, 1], -g[:, 0]
    a[:, :, 4:] = np.eye(6)
    theta = np.linalg.lstsq(a.reshape(6 * n, 10), wrench.reshape(6 * n), rcond=None)[0]
    seconds = time.perf_counter() - start
    return {"seconds": seconds, "mass": float(theta[0])}
# ------------------------------------------------- generated C (one core)
C_DRIVER = r"""
#include <stdio.h>
#include <time.h>
#include "bench_model.h"
#define SAMPLES 1024
int main(int argc, char **argv)
{
    static double u[SAMPLES][BENCH_MODEL_N_INPUTS];
    double y[BENCH_MODEL_N_OUTPUTS], checksum = 0;
    long n = argc > 1 ? atol(argv[1]) : 1000000, k;
    struct timespec t0, t1;
    int s, i;
    for (s = 0; s < SAMPLES; ++s)
        for (i = 0; i < BENCH_MODEL_N_INPUTS; ++i)
            if (scanf("%lf", &u[s][i]) != 1) return 1;
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t0);
    for (k = 0; k < n; ++k) {
        bench_model_predict(u[k % SAMPLES], y);
        checksum += y[k % BENCH_MODEL_N_OUTPUTS];  /* keeps every call alive */
    }
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t1);
    printf("%.9f %.17g\n", (t1.tv_sec - t0.tv_sec) + 1e-9 * (t1.tv_nsec - t0.tv_nsec), checksum);
    return 0;
}
"""


def c_predict(n: int, degree: int) -> dict:
    """Generated C (``-O2``, one core): ``n`` calls of ``predict`` cycling over 1024 samples."""
    import shutil
    import subprocess
    import tempfile
    from pathlib import Path

    from ftcal.core.dataset import Dataset
    from ftcal.core.model import CalibrationModel
    from ftcal.files.c_code import generate_c

    cc = shutil.which("cc")
    if cc is None:
        raise RuntimeError("no system C compiler `cc` for the generated-C benchmark")
    u, y = make_data(20_000)
    model = CalibrationModel(degree).fit(Dataset.from_arrays(u, y))
    code = generate_c(model, name="bench_model")
    samples, _ = make_data(1024, seed=1)
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        (folder / "bench_model.h").write_text(code.header)
        (folder / "bench_model.c").write_text(code.source)
        (folder / "driver.c").write_text("#define _POSIX_C_SOURCE 199309L\n#include <stdlib.h>\n" + C_DRIVER)
        compile_start = time.perf_counter()
        subprocess.run([cc, "-std=c99", "-O2", "-c", "bench_model.c"], cwd=folder, check=True)
        compile_seconds = time.perf_counter() - compile_start
        subprocess.run([cc, "-std=c99", "-O2", "driver.c", "bench_model.o", "-o", "bench"], cwd=folder, check=True)
        text = "\n".join(" ".join(repr(float(v)) for v in row) for row in samples)
        out = subprocess.run([str(folder / "bench"), str(n)], input=text, capture_output=True, text=True,
                             check=True).stdout.split()
    seconds = float(out[0])
    return {"seconds": seconds, "ns_per_sample": seconds / n * 1e9, "compile_seconds": compile_seconds,
            "source_lines": code.source.count("\n")}


def ftcal_predict_one(n: int, degree: int) -> dict:
    """Python ``predict`` one sample per call (as a Python control loop would), and in one batch, one thread."""
    import os

    from ftcal.core.dataset import Dataset
    from ftcal.core.model import CalibrationModel

    u, y = make_data(20_000)
    model = CalibrationModel(degree).fit(Dataset.from_arrays(u, y))
    os.environ["FTCAL_THREADS"] = "1"  # one core, like the C figure
    samples, _ = make_data(n, seed=1)
    rows = [samples[k:k + 1] for k in range(n)]
    model.predict(rows[0], warn_out_of_range=False)  # warm-up
    start = time.perf_counter()
    for row in rows:
        model.predict(row, warn_out_of_range=False)
    seconds = time.perf_counter() - start
    batch, _ = make_data(200_000, seed=2)
    batch_start = time.perf_counter()
    model.predict(batch, warn_out_of_range=False)
    batch_seconds = time.perf_counter() - batch_start
    return {"seconds": seconds, "ns_per_call": seconds / n * 1e9, "batch_ns_per_sample": batch_seconds / 200_000 * 1e9}




# ----------------------------------------------------------------- whole process, from a CSV file
CSV_INPUTS = ("u1", "u2", "u3", "u4", "u5", "u6", "T")
CSV_OUTPUTS = ("Fx", "Fy", "Fz", "Tx", "Ty", "Tz")

PAPER_RECIPE_SCRIPT = """
import sys
import numpy as np
import pandas as pd
from benchmarks.cases import CSV_INPUTS, CSV_OUTPUTS, paper_features
from ftcal.core.solvers.osqp_qp import OsqpLeastSquares

frame = pd.read_csv(sys.argv[1])
a = paper_features(frame[list(CSV_INPUTS)].to_numpy(), int(sys.argv[2]))
a /= np.abs(a).max(axis=0)
OsqpLeastSquares(eps=1e-4).fit_dense(a, frame[list(CSV_OUTPUTS)].to_numpy())
"""


def _csv(folder: str, n: int) -> str:
    import pandas as pd

    u, y = make_data(n)
    path = f"{folder}/data.csv"
    frame = pd.DataFrame(np.hstack([u, y]), columns=[*CSV_INPUTS, *CSV_OUTPUTS])
    frame.to_csv(path, index=False)
    return path


def _timed_process(argv: list[str], env: dict | None = None) -> tuple[float, float, float]:
    """Wall time (s), peak RSS (MB) and CPU (user + system, s) of one child process, from its own rusage
    (os.wait4)."""
    import subprocess

    start = time.perf_counter()
    child = subprocess.Popen(argv, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True, env=env)
    stderr = child.stderr.read()
    _, status, usage = os.wait4(child.pid, 0)
    seconds = time.perf_counter() - start
    child.returncode = os.waitstatus_to_exitcode(status)
    if child.returncode != 0:
        raise RuntimeError(stderr[-2000:])
    return seconds, usage.ru_maxrss / 1024.0, usage.ru_utime + usage.ru_stime


def cli_fit_pair(n: int, degree: int, repeats: int = 5, baseline_src: str | None = None) -> dict:
    """`ftcal fit data.csv --degree D` and the paper's recipe as a script, on the same CSV, alternately.

    Each runs ``repeats`` times, interleaved so that a change of machine load
    hits both; the medians are reported (with min and max, and the median of the
    per-round ratios recipe / ftcal), each child's CPU (user + system) and its own
    peak RSS, and the load average before and after. ``baseline_src``: the same
    ftcal command on that source tree in each round too (the code before a change).
    """
    import statistics
    import tempfile
    from pathlib import Path

    load_before = os.getloadavg()[0]
    with tempfile.TemporaryDirectory() as folder:
        data = _csv(folder, n)
        ftcal = str(Path(sys.executable).with_name("ftcal"))
        commands = {"ftcal": ([ftcal, "fit", data, "--degree", str(degree), "-o", f"{folder}/m.json"], None),
                    "paper": ([sys.executable, "-c", PAPER_RECIPE_SCRIPT, data, str(degree)], None)}
        if baseline_src:
            path = os.pathsep.join([baseline_src, *os.environ.get("PYTHONPATH", "").split(os.pathsep)[1:]])
            commands["baseline"] = ([ftcal, "fit", data, "--degree", str(degree), "-o", f"{folder}/b.json"],
                                    dict(os.environ, PYTHONPATH=path))
        runs = {name: [] for name in commands}
        for _ in range(repeats):
            for name, (argv, env) in commands.items():
                runs[name].append(_timed_process(argv, env))
    result = {}
    for name, rows in runs.items():
        times = [t for t, _, _ in rows]
        result[name] = {"seconds": statistics.median(times), "min_seconds": min(times), "max_seconds": max(times),
                        "cpu_seconds": statistics.median(c for _, _, c in rows),
                        "child_peak_rss_mb": max(m for _, m, _ in rows), "repeats": repeats}
    result["ratio"] = statistics.median(p[0] / f[0] for p, f in zip(runs["paper"], runs["ftcal"]))
    result["cpu_ratio"] = statistics.median(p[2] / f[2] for p, f in zip(runs["paper"], runs["ftcal"]))
    if baseline_src:
        result["baseline"]["src"] = baseline_src
    result["load_average"] = [load_before, os.getloadavg()[0]]
    result["seconds"] = result["ftcal"]["seconds"]
    return result


CASES = {f.__name__: f for f in (ftcal_fit, ftcal_statistics, paper_recipe_fit, numpy_lstsq_fit, sklearn_fit,
                                 cli_fit_pair, ftcal_lasso, paper_lasso, sklearn_lasso,
                                 ftcal_predict, sklearn_predict, ftcal_payload, ftcal_payload_drift, numpy_payload_lstsq, c_predict,
                                 ftcal_predict_one, select_auto, select_auto_baseline, select_auto_new)}
CASES.update(BAG_CASES)  # bag reading: benchmarks/bench_bags.py
CASES.update(C_CASES)  # batch generated C and the c-runtime live step: benchmarks/bench_c.py
CASES.update(PLAN_CASES)  # experiment design: benchmarks/bench_plan.py
CASES.update(MLP_CASES)  # the MLP family against a polynomial: benchmarks/bench_mlp.py
CASES.update(COST_CASES)  # --degree auto's estimate against its CPU: benchmarks/bench_cost.py
CASES.update(SELECT_RATE_CASES)  # --degree auto's false wins and kept gains: benchmarks/bench_select_rates.py
CASES.update(REAL_LIKE_CASES)  # every path on real-like simulated sensors against OLS: benchmarks/bench_real_like.py
CASES.update(PAYLOAD_ERROR_CASES)  # payload standard errors' coverage per bias model: benchmarks/bench_payload_errors.py
CASES.update(LIVE_CASES)  # the live calibrator: benchmarks/bench_live.py
CASES.update(PAYLOAD_CLI_CASES)  # whole ftcal payload processes: benchmarks/bench_payload_cli.py
CASES.update(CLUSTER_CASES)  # whole ftcal fit, one process against local:N: benchmarks/bench_cluster.py
CASES.update(FLOOR_CASES)  # whole ftcal fit against the flop floor: benchmarks/bench_floor.py
CASES.update(CLOSED_LOOP_CASES)  # the calibrated sensor in a MuJoCo force-control loop: benchmarks/bench_closed_loop.py


if __name__ == "__main__":
    name, kwargs = sys.argv[1], json.loads(sys.argv[2])
    # The libraries every in-process case may use load before any case starts its clock (ftcal
    # imports SciPy on first use); whole-process cases time their own child processes.
    import osqp  # noqa: F401
    import scipy.linalg  # noqa: F401
    import scipy.sparse  # noqa: F401

    outcome = CASES[name](**kwargs)
    outcome["peak_rss_mb"] = peak_mb()
    print(json.dumps(outcome))
