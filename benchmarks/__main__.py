"""Run every benchmark and write BENCHMARKS.md: ``python -m benchmarks`` (``make bench``).

Every case runs in its own process (peak memory is per case) and every ratio
compares cases measured in this same run on this machine.
Options: ``--quick`` (small sizes, to check the harness), ``--out FILE``.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
# Filled by the sections: the figures the issues set targets for.
HEADLINE: dict[str, str] = {}


def run_case(name: str, **kwargs) -> dict:
    env = dict(os.environ, FTCAL_PROGRESS="0", PYTHONWARNINGS="ignore")
    done = subprocess.run([sys.executable, "-m", "benchmarks.cases", name, json.dumps(kwargs)],
                          cwd=ROOT, env=env, capture_output=True, text=True)
    if done.returncode != 0:
        raise RuntimeError(f"benchmark case {name} {kwargs} failed:\n{done.stderr[-2000:]}")
    result = json.loads(done.stdout.strip().splitlines()[-1])
    print(f"  {name:<18} {json.dumps(kwargs):<32} {result['seconds']:9.3f} s  "
          f"{result['peak_rss_mb']:8.0f} MB", file=sys.stderr, flush=True)
    return result


def fmt_s(seconds: float) -> str:
    return f"{seconds:.2f} s" if seconds < 100 else f"{seconds:.0f} s"


def machine() -> str:
    import numpy as np

    cpu = "unknown CPU"
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    from ftcal.core.kernels import compiled_kernel_available

    kernel = "compiled" if compiled_kernel_available() else "numpy (no C compiler at install)"
    return (f"{os.cpu_count()} cores ({cpu}), Python {platform.python_version()}, numpy {np.__version__}, "
            f"kernels {kernel}, {time.strftime('%Y-%m-%d')}")


def fit_section(sizes: dict) -> list[str]:
    n_big, n_mid = sizes["fit_big"], sizes["fit_mid"]
    ours_big = run_case("ftcal_fit", n=n_big, degree=5)
    paper_big = run_case("paper_recipe_fit", n=n_big, degree=5)
    ours = run_case("ftcal_fit", n=n_mid, degree=5)
    ours_numpy = run_case("ftcal_fit", n=n_mid, degree=5, kernel="numpy")
    paper = run_case("paper_recipe_fit", n=n_mid, degree=5)
    lstsq = run_case("numpy_lstsq_fit", n=n_mid, degree=5)
    sk = run_case("sklearn_fit", n=n_mid, degree=5)
    HEADLINE["fit"] = (f"degree 5, N = {n_big:,}: {fmt_s(ours_big['seconds'])}, "
                       f"{paper_big['seconds'] / ours_big['seconds']:.1f}× faster than the paper recipe "
                       f"(target ≥ 10×); peak memory {ours_big['peak_rss_mb']:,.0f} MB (target ≤ 1,500 MB; "
                       f"the recipe: {paper_big['peak_rss_mb']:,.0f} MB)")
    rows = [
        ("ftcal (streaming moments, exact LSQ)", n_big, ours_big, ours_big),
        ("paper recipe (dense max-abs regressor + OSQP per output, eps 1e-4)", n_big, paper_big, ours_big),
        ("ftcal", n_mid, ours, ours),
        ("ftcal, numpy kernels (an install without a C compiler)", n_mid, ours_numpy, ours),
        ("paper recipe", n_mid, paper, ours),
        ("numpy.linalg.lstsq on the dense regressor", n_mid, lstsq, ours),
        ("scikit-learn PolynomialFeatures + MaxAbsScaler + LinearRegression", n_mid, sk, ours),
    ]
    out = ["## Fit: degree 5, 7 inputs (6 channels + temperature), 6 outputs (4752 coefficients)", "",
           "| method | N | time | vs ftcal | peak memory |", "|---|---:|---:|---:|---:|"]
    for label, n, res, ref in rows:
        ratio = res["seconds"] / ref["seconds"]
        out.append(f"| {label} | {n:,} | {fmt_s(res['seconds'])} | {ratio:.1f}× | {res['peak_rss_mb']:,.0f} MB |")
    return out + [""]


def cli_section(sizes: dict) -> list[str]:
    """Whole processes from a CSV file: what a user waits for, start-up and reading included."""
    n = sizes["cli_n"]
    baseline = os.environ.get("FTCAL_BASELINE_SRC")
    pair = run_case("cli_fit_pair", n=n, degree=4, repeats=sizes["cli_repeats"], baseline_src=baseline)
    ours, paper = pair["ftcal"], pair["paper"]
    HEADLINE["cli"] = (f"`ftcal fit data.csv --degree 4`, N = {n:,}, whole process: {fmt_s(ours['seconds'])} "
                       f"({ours['cpu_seconds']:.2f} CPU s), {pair['ratio']:.1f}× faster than the paper's recipe run "
                       f"as a script on the same CSV (target ≥ 5×; {pair['cpu_ratio']:.1f}× in CPU)")
    out = [f"## Whole process from a CSV file: degree 4, N = {n:,}", "",
           "Start-up, imports, reading the CSV, the fit and writing the model, as a user runs it. "
           f"Each command runs {ours['repeats']} times, alternating with the other; the median is shown, "
           "with the fastest and slowest run, each child's CPU (user + system, median) and its peak memory; "
           "the ratio is the median of the rounds' ratios. Load average "
           f"{pair['load_average'][0]:.2f} before, {pair['load_average'][1]:.2f} after.", "",
           "| method | time (median) | min – max | CPU s | vs ftcal (wall, CPU) | peak memory |",
           "|---|---:|---:|---:|---:|---:|"]
    rows = [("`ftcal fit data.csv --degree 4 -o m.json`", ours, "1.0×, 1.0×"),
            ("paper recipe as a script (pandas.read_csv, dense max-abs regressor, OSQP per output)", paper,
             f"{pair['ratio']:.1f}×, {pair['cpu_ratio']:.1f}×")]
    if "baseline" in pair:
        b = pair["baseline"]
        rows.append((f"the same ftcal command on `{b['src']}` (before)", b,
                     f"{b['seconds'] / ours['seconds']:.2f}×, {b['cpu_seconds'] / ours['cpu_seconds']:.2f}×"))
    for label, res, ratio in rows:
        out.append(f"| {label} | {fmt_s(res['seconds'])} | {fmt_s(res['min_seconds'])} – "
                   f"{fmt_s(res['max_seconds'])} | {res['cpu_seconds']:.2f} | {ratio} | "
                   f"{res['child_peak_rss_mb']:,.0f} MB |")
    return out + [""]


def scaling_section(sizes: dict) -> list[str]:
    out = ["## Fit time against N (degree 4)", "",
           "| N | ftcal | numpy lstsq | paper recipe | ftcal peak memory |", "|---:|---:|---:|---:|---:|"]
    for n in sizes["scaling_n"]:
        ours = run_case("ftcal_fit", n=n, degree=4)
        dense_ok = n <= sizes["dense_max_n"]
        lstsq = run_case("numpy_lstsq_fit", n=n, degree=4) if dense_ok else None
        paper = run_case("paper_recipe_fit", n=n, degree=4) if dense_ok else None
        out.append(f"| {n:,} | {fmt_s(ours['seconds'])} | "
                   f"{fmt_s(lstsq['seconds']) if lstsq else '—'} | {fmt_s(paper['seconds']) if paper else '—'} | "
                   f"{ours['peak_rss_mb']:,.0f} MB |")
    n = sizes["degree_n"]
    out += ["", f"## Fit time against degree (N = {n:,})", "",
            "| degree | coefficients | ftcal | numpy lstsq | lstsq / ftcal |", "|---:|---:|---:|---:|---:|"]
    from ftcal.core.features import n_coefficients

    for degree in range(1, 6):
        ours = run_case("ftcal_fit", n=n, degree=degree)
        lstsq = run_case("numpy_lstsq_fit", n=n, degree=degree)
        out.append(f"| {degree} | {n_coefficients(7, degree, 6)} | {fmt_s(ours['seconds'])} | "
                   f"{fmt_s(lstsq['seconds'])} | {lstsq['seconds'] / ours['seconds']:.1f}× |")
    return out + [""]


def lasso_section(sizes: dict) -> list[str]:
    n = sizes["lasso_n"]
    ours = run_case("ftcal_lasso", n=n, degree=4)
    sk = run_case("sklearn_lasso", n=n, degree=4)
    small = sizes["paper_lasso_n"]
    paper = run_case("paper_lasso", n=small, degree=4, outputs=1, lam=50.0)
    ours_small = run_case("ftcal_lasso", n=small, degree=4)
    # The paper's QP is far too slow to run at full size; scale its one-output,
    # one-λ time linearly in N, outputs and λ (optimistic for it: its cost grows faster than N).
    extrapolated = paper["seconds"] * (n / small) * 6 * 6
    HEADLINE["lasso"] = (f"degree 4, six λ, N = {n:,}: {fmt_s(ours['seconds'])}, ≈ {extrapolated / ours['seconds']:,.0f}× "
                         f"faster than the paper's OSQP LASSO extrapolated from N = {small:,} (target ≥ 100×); "
                         f"{sk['seconds'] / ours['seconds']:.1f}× faster than scikit-learn")
    return [
        "## LASSO: degree 4 (1980 coefficients), the paper's six λ (0.5 … 200), all 6 outputs", "",
        "| method | N | time | vs ftcal | peak memory |", "|---|---:|---:|---:|---:|",
        f"| ftcal (statistics + warm-started ADMM path, exact active-set polish) | {n:,} | "
        f"{fmt_s(ours['seconds'])} | 1.0× | {ours['peak_rss_mb']:,.0f} MB |",
        f"| scikit-learn lasso_path (α = λ/N) on PolynomialFeatures + MaxAbsScaler | {n:,} | "
        f"{fmt_s(sk['seconds'])} | {sk['seconds'] / ours['seconds']:.1f}× | {sk['peak_rss_mb']:,.0f} MB |",
        f"| paper's OSQP LASSO (one variable per sample), **1 output, 1 λ** | {small:,} | "
        f"{fmt_s(paper['seconds'])} | {paper['seconds'] / ours_small['seconds']:.0f}× vs ftcal's full "
        f"6-output 6-λ path at the same N ({fmt_s(ours_small['seconds'])}) | {paper['peak_rss_mb']:,.0f} MB |",
        f"| paper's OSQP LASSO, extrapolated linearly to {n:,} samples × 6 outputs × 6 λ | {n:,} | "
        f"≈ {extrapolated:,.0f} s | ≈ {extrapolated / ours['seconds']:,.0f}× | — |", "",
        f"ftcal nonzero coefficients per λ at N = {n:,}: {ours['n_nonzero']} (exact zeros).", ""]


def predict_section(sizes: dict) -> list[str]:
    n = sizes["predict_n"]
    ours = run_case("ftcal_predict", n=n, degree=4)
    sk = run_case("sklearn_predict", n=n, degree=4)
    HEADLINE["predict"] = (f"degree 4: {ours['samples_per_s'] / 1e6:.2f} M samples/s (target ≥ 5 M/s); "
                           f"{ours['samples_per_s'] / sk['samples_per_s']:.0f}× scikit-learn")
    return ["## Prediction: degree 4, 7 inputs, 6 outputs", "",
            "| method | N | samples/s | vs ftcal | peak memory |", "|---|---:|---:|---:|---:|",
            f"| ftcal | {n:,} | {ours['samples_per_s'] / 1e6:.2f} M | 1.0× | {ours['peak_rss_mb']:,.0f} MB |",
            f"| scikit-learn pipeline (chunks of 100k) | {n:,} | {sk['samples_per_s'] / 1e6:.2f} M | "
            f"{sk['samples_per_s'] / ours['samples_per_s']:.2f}× | {sk['peak_rss_mb']:,.0f} MB |", ""]


def selection_section(sizes: dict) -> list[str]:
    n = sizes["select_n"]
    ours = run_case("select_auto_new", n=n)
    base = run_case("select_auto_baseline", n=n)
    cli = run_case("select_auto", n=n)
    HEADLINE["select"] = (f"`--degree auto`, N = {n:,}, 8 inputs, 60 load cases, 5 folds: {fmt_s(ours['seconds'])}, "
                          f"{base['seconds'] / ours['seconds']:.1f}× faster than the previous strategy "
                          f"(target ≥ 5×), with {ours['n_candidates']} candidates against its 35")
    return ["## Model selection: `--degree auto`, 8 inputs, 60 load cases (groups), 5 folds", "",
            "| method | N | time | vs ftcal | best | peak memory |", "|---|---:|---:|---:|---|---:|",
            f"| ftcal `select_model` (scores from statistics, data-driven λ grid, LASSO + ridge, early stop) | "
            f"{n:,} | {fmt_s(ours['seconds'])} | 1.0× | {ours['best']} | {ours['peak_rss_mb']:,.0f} MB |",
            f"| previous strategy (paper's six λ, LASSO only, every candidate predicted per fold) | {n:,} | "
            f"{fmt_s(base['seconds'])} | {base['seconds'] / ours['seconds']:.1f}× | {base['best']} | "
            f"{base['peak_rss_mb']:,.0f} MB |",
            f"| `ftcal fit --degree auto` (whole command in-process, file read and final fit included) | {n:,} | "
            f"{fmt_s(cli['seconds'])} | {cli['seconds'] / ours['seconds']:.1f}× | | {cli['peak_rss_mb']:,.0f} MB |",
            ""]


def mlp_section(sizes: dict) -> list[str]:
    n = sizes["mlp_n"]
    r = run_case("mlp_vs_polynomial", n=n, hidden=sizes["mlp_hidden"], max_iter=sizes["mlp_iterations"])
    HEADLINE["mlp"] = (f"MLP {r['hidden']} fit {fmt_s(r['mlp_fit_s'])} (early stopping on 5 grouped folds) vs "
                       f"degree {r['degree']} {fmt_s(r['polynomial_fit_s'])}; prediction "
                       f"{r['mlp_predict_samples_per_s'] / 1e6:.2f} M vs "
                       f"{r['polynomial_predict_samples_per_s'] / 1e6:.2f} M samples/s")
    return [f"## MLP family against degree {r['degree']}: 8 inputs, 60 load cases, 12 held out", "",
            "| model | N train | fit | predict (one thread) | held-out force error-norm RMSE |",
            "|---|---:|---:|---:|---:|",
            f"| MLP {r['hidden']} tanh, {r['mlp_weights']} weights, early-stopped at {r['mlp_iterations']} "
            f"iterations | {r['n_train']:,} | {fmt_s(r['mlp_fit_s'])} | "
            f"{r['mlp_predict_samples_per_s'] / 1e6:.2f} M/s | {r['mlp_held_out_force_error_norm_rmse']:.3f} N |",
            f"| polynomial degree {r['degree']}, least squares | {r['n_train']:,} | {fmt_s(r['polynomial_fit_s'])} | "
            f"{r['polynomial_predict_samples_per_s'] / 1e6:.2f} M/s | "
            f"{r['polynomial_held_out_force_error_norm_rmse']:.3f} N |", ""]


def payload_section(sizes: dict) -> list[str]:
    n = sizes["payload_n"]
    ours = run_case("ftcal_payload", n=n)
    base = run_case("numpy_payload_lstsq", n=n)
    constant = run_case("ftcal_payload_drift", n=n, model="none")
    walk = run_case("ftcal_payload_drift", n=n, model="random-walk")
    HEADLINE["payload"] = (f"{n:,} static samples: {ours['seconds']:.2f} s (target < 1 s); "
                           f"{base['seconds'] / ours['seconds']:.1f}× numpy lstsq on the stacked regressor; "
                           f"random-walk bias {walk['seconds']:.2f} s (target ≤ 2 s)")
    drift = [f"| ftcal, bias as a random walk (state-space model on ≤ 1,000 block averages) | {n:,} | "
             f"{fmt_s(walk['seconds'])} | {walk['seconds'] / constant['seconds']:.2f}× the constant-bias fit | "
             f"{walk['peak_rss_mb']:,.0f} MB (constant-bias fit {constant['peak_rss_mb']:,.0f} MB) |",
             f"| ftcal, constant bias with grouped-jackknife standard errors (same data) | {n:,} | "
             f"{fmt_s(constant['seconds'])} | — | {constant['peak_rss_mb']:,.0f} MB |"]
    return ["## Payload and bias identification (10 parameters, static poses)", "",
            "| method | N | time | vs ftcal | peak memory |", "|---|---:|---:|---:|---:|",
            f"| ftcal (quaternions → gravity, streaming statistics, weighted fit + stderr) | {n:,} | "
            f"{fmt_s(ours['seconds'])} | 1.0× | {ours['peak_rss_mb']:,.0f} MB |",
            f"| numpy: stacked 6N × 10 regressor + lstsq | {n:,} | {fmt_s(base['seconds'])} | "
            f"{base['seconds'] / ours['seconds']:.2f}× | {base['peak_rss_mb']:,.0f} MB |", *drift, ""]


def plan_section(sizes: dict) -> list[str]:
    n_poses, n_candidates = sizes["plan"]
    rows = {objective: run_case("plan_design", n_poses=n_poses, n_candidates=n_candidates, objective=objective)
            for objective in ("calibration", "payload")}
    cal = rows["calibration"]
    HEADLINE["plan"] = (f"`ftcal plan`, {n_poses} poses from {n_candidates:,} configurations × 4 loads: "
                        f"{fmt_s(cal['seconds'])} (target ≤ 5 s); log det planned {cal['log_det_planned']:.1f} "
                        f"against random {cal['log_det_random']:.1f}")
    out = [f"## Experiment design: `ftcal plan`, {n_poses} poses from {n_candidates:,} configurations × 4 loads", "",
           "| objective | candidate poses | time | candidates (iDynTree) | design | log det planned | "
           "log det random | peak memory |", "|---|---:|---:|---:|---:|---:|---:|---:|"]
    for objective, r in rows.items():
        out.append(f"| {objective} | {r['n_candidate_poses']:,} | {fmt_s(r['seconds'])} | "
                   f"{fmt_s(r['candidates_seconds'])} | {fmt_s(r['design_seconds'])} | {r['log_det_planned']:.1f} | "
                   f"{r['log_det_random']:.1f} | {r['peak_rss_mb']:,.0f} MB |")
    return out + [""]


def closed_loop_section(sizes: dict) -> list[str]:
    """Every condition of every closed-loop variant, per seed; the seeds' ties and the issue's targets."""
    runs = [run_case("closed_loop", variant=variant, seeds=list(seeds), quick=sizes["closed_loop_quick"])
            for variant, seeds in sizes["closed_loop_variants"].items()]
    tracked = [run_case("tracking", variant="long-task", seed=seed)
               for seed in sizes["closed_loop_variants"].get("long-task", ())]
    return closed_loop_lines(runs, sizes["closed_loop_quick"]) + tracking_lines(tracked)


def tracking_lines(results: list[dict]) -> list[str]:
    """What ``ftcal.live`` saw and did per phase of the long task (:func:`benchmarks.bench_closed_loop.tracking`)."""
    if not results:
        return []
    out = ["### long-task: what the live tracker saw and did, per phase", "",
           "`python -m benchmarks.bench_closed_loop tracking long-task SEED`: condition (c) rerun with a recorder around "
           "`LiveCalibrator.step`. Static / updated: the share of the phase's samples the tracker called static and "
           "updated its bias on. Error: ftcal's calibrated force minus MuJoCo's sensor force (drift and model error) "
           "since the start pose's tare, each stretch of the phase by its mean (the 0.15 N noise averages out), RMS "
           "over the stretches; untracked is what (b) carries, tracked what is left after (c)'s bias. In contact the "
           "world-z error shifts the contact force one for one.", "",
           "| seed | phase | static | updated | world-z error untracked [N] | tracked [N] | force error untracked [N] "
           "| tracked [N] |", "|---:|---|---:|---:|---:|---:|---:|---:|"]
    for r in results:
        for name, ph in r["phases"].items():
            out.append(f"| {r['seed']} | {name} | {ph['static']:.0%} | {ph['updated']:.0%} | {ph['untracked_z']:.3f} | "
                       f"{ph['tracked_z']:.3f} | {ph['untracked_force']:.3f} | {ph['tracked_force']:.3f} |")
    out.append("")
    for r in results:
        flags = ", ".join(f"{name} on {count:,} samples" for name, count in r["flags"].items()) or "none"
        out.append(f"- seed {r['seed']}: flags raised {flags}; {fmt_s(r['cpu_seconds'])} CPU")
    return out + [""]


def closed_loop_lines(runs: list[dict], quick: bool) -> list[str]:
    """The closed-loop section's tables from :func:`benchmarks.bench_closed_loop.closed_loop` results."""
    from ftcal.sim.closed_loop import tie_lines, target_lines

    out = ["## Closed loop: the calibrated sensor in a MuJoCo force controller (`ftcal demo --scenario closed-loop`)",
           "", "Contact force against MuJoCo's own contact force (50 ms average) while force-controlled; phantom: the "
           "force the controller perceives in free motion. Not timed targets: the simulation's known truth. "
           "Conditions: (a) factory + one tare, (a') factory + ROS-style gravity compensation (tool identified on "
           "the factory wrench at the same poses, re-tared at the start), (b0) in-situ affine + tool, (b) ftcal "
           "degree 3 + tool, (c) (b) + `ftcal.live` bias tracking, (d) the true wrench. "
           + ("Calibration at `--quick` size. " if quick else "")
           + "Variants not listed were not run in this measurement.", ""]
    heads = []
    for run in runs:
        variant = run["variant"]
        out += [f"### {variant}: {run['description']}", "",
                "| seed | condition | contact RMSE [N] | max error [N] | settling [s] | phantom RMS [N] | "
                "phantom max [N] |", "|---:|---|---:|---:|---:|---:|---:|"]
        for seeded in run["per_seed"]:
            for r in seeded["conditions"]:
                if not r["available"]:
                    out.append(f"| {seeded['seed']} | {r['condition']} | not available: {r['reason']} | | | | |")
                    continue
                settle = "–" if r["settling_s"] is None else f"{r['settling_s']:.2f}"
                out.append(f"| {seeded['seed']} | {r['condition']} | {r['contact_rmse']:.3f} | "
                           f"{r['contact_max_error']:.3f} | {settle} | {r['phantom_rms']:.3f} | "
                           f"{r['phantom_max']:.3f} |")
        summary = {"seeds": run["seeds"], "ties": run["ties"], "targets": run["targets"]}
        out += [""] + [f"- {line}" for line in tie_lines(summary) + target_lines(summary)]
        cal = run["calibration"]
        out += [f"- in-situ calibration held-out force RMSE (seed {run['seeds'][0]}): affine "
                f"{cal['validation_force_rmse']['affine']:.3f} N, degree {cal['degree']} "
                f"{cal['validation_force_rmse']['nonlinear']:.3f} N; {run['per_seed'][0]['conditions'][0].get('contacts', 1)} "
                f"contact(s), {run['per_seed'][0]['conditions'][0].get('duration_s', 0):.0f} s per condition; "
                f"{fmt_s(run['seconds'])} wall, {fmt_s(run['cpu_seconds'])} CPU for {len(run['seeds'])} seed(s)", ""]
        if run["targets"]:
            heads.append(f"{variant}: " + ", ".join(
                f"{t['what']} {t['ratio']:.2f} (≤ {t['bound']:.2g}, {'met' if t['met'] else 'NOT MET'}"
                + (f"; seeds {min(t['per_seed']):.2f}-{max(t['per_seed']):.2f}" if len(t["per_seed"]) > 1 else "")
                + ")" for t in run["targets"] if t["ratio"] is not None))
    HEADLINE["closed_loop"] = "; ".join(heads) if heads else "no targets in the variants run"
    return out


def c_section(sizes: dict) -> list[str]:
    """Generated C (``ftcal convert --to c``, ``cc -O2``) against Python predict, one core."""
    out = ["## Generated C on one core: 7 inputs, 6 outputs", "",
           "CPU time per sample of `NAME_predict` (`cc -std=c99 -O2`, no `-march`), cycling over 1,024 "
           "samples; Python `predict` with `FTCAL_THREADS=1`, one sample per call and in one batch of 200,000.", "",
           "| degree | generated C | Python, one sample per call | Python, batched | C vs one call | C vs batched |",
           "|---:|---:|---:|---:|---:|---:|"]
    for degree in (4, 5):
        c = run_case("c_predict", n=sizes["c_evals"], degree=degree)
        py = run_case("ftcal_predict_one", n=sizes["python_calls"], degree=degree)
        if degree == 4:
            HEADLINE["c"] = f"degree 4: {c['ns_per_sample']:.0f} ns per sample on one core (target ≤ 1,000 ns)"
        out.append(f"| {degree} | {c['ns_per_sample']:,.0f} ns | {py['ns_per_call'] / 1e3:,.0f} µs | "
                   f"{py['batch_ns_per_sample']:,.0f} ns | {py['ns_per_call'] / c['ns_per_sample']:,.0f}× | "
                   f"{py['batch_ns_per_sample'] / c['ns_per_sample']:.1f}× |")
    return out + [""]


def c_batch_section(sizes: dict) -> list[str]:
    """The batch entry point of generated C against the scalar one and a vectorised floor; the C live step."""
    out = ["## Generated C in batches, and the C live step: 7 inputs, 6 outputs", "",
           "CPU ns per sample on one core, measured in one driver run per row (benchmarks/bench_c.py): "
           "`NAME_predict` per sample, `NAME_predict_batch` over 1,024 samples per call, and the floor: a "
           "register-blocked multiply-add kernel (GCC vector extensions, 2 vectors × 6 outputs of accumulators) "
           "doing the model's multiply-adds on monomials already in L1 (no monomials, normalisation or "
           "transposes), same flags, no fused multiply-add (`-std=c99` does not contract).", "",
           "| degree | flags | scalar | batch | floor | batch / floor | scalar / batch | CPU s | wall s |",
           "|---:|---|---:|---:|---:|---:|---:|---:|---:|"]
    for degree in (4, 5):
        for march in ("", "native"):
            r = run_case("c_batch", n=sizes["c_batch_evals"], degree=degree, march=march)
            out.append(f"| {degree} | `{r['flags']}` | {r['scalar_ns']:,.0f} ns | {r['batch_ns']:,.0f} ns | "
                       f"{r['floor_ns']:,.0f} ns | {r['batch_over_floor']:.2f} | {r['scalar_over_batch']:.2f} | "
                       f"{r['cpu_seconds']:.2f} | {r['seconds']:.2f} |")
    step = run_case("c_runtime_step", n=sizes["c_runtime_n"], degree=4)
    HEADLINE["c_batch"] = (f"C live step (`convert --to c-runtime`, degree 4, 7 inputs, `-O2`): "
                           f"{step['step_ns']:,.0f} ns per sample (target ≤ 2,000 ns)")
    out += ["", f"`NAME_step` of `ftcal convert --to c-runtime` (calibration + tool + bias filter + health, motion test "
                f"on), degree 4, 7 inputs, `cc -std=c99 -O2`, {sizes['c_runtime_n']:,} samples of a 500 Hz recording: "
                f"**{step['step_ns']:,.0f} ns per sample** CPU, of which the calibration alone "
                f"{step['calibrate_ns']:,.0f} ns (target ≤ 2,000 ns). With an identification in place running (each "
                f"static sample's hold moments collected): {step['identifying_step_ns']:,.0f} ns per sample; "
                f"`NAME_finish_identification` on its {step['holds']} holds: {step['finish_us']:,.0f} µs per call "
                f"(mass {step['identified_mass']:.4f} kg, simulated {step['true_mass']:.4f} kg); the whole case "
                f"{step['cpu_seconds']:.2f} CPU s, {step['seconds']:.2f} wall s.", ""]
    return out


def expected_section(sizes: dict) -> list[str]:
    # In its own process: its worker processes' peak memory must not include other cases'.
    code = ("import contextlib, json, sys\nfrom benchmarks import bench_expected\n"
            "with contextlib.redirect_stdout(sys.stderr):\n"
            f"    rows = bench_expected.main(n_samples={sizes['expected_n']}, "
            f"baseline_samples={sizes['expected_baseline_n']})\nprint(json.dumps(rows))")
    done = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True,
                          env=dict(os.environ, FTCAL_PROGRESS="0"))
    if done.returncode != 0:
        raise RuntimeError(f"expected-wrench benchmark failed:\n{done.stderr[-2000:]}")
    rows = json.loads(done.stdout.strip().splitlines()[-1])
    out = ["## Expected wrenches (iDynTree, all six F/T sensors of an iCub)", "",
           "| method | samples | samples/s | vs per-sample loop | peak memory |", "|---|---:|---:|---:|---:|"]
    base = rows[0]["samples_per_s"]
    HEADLINE["expected"] = (f"all six iCub sensors: {rows[-1]['samples_per_s']:,.0f} samples/s (target ≥ 20,000/s); "
                            f"{rows[-1]['samples_per_s'] / base:.1f}× the plain per-sample loop")
    for row in rows:
        out.append(f"| {row['method']} | {row['samples']:,} | {row['samples_per_s']:,.0f} | "
                   f"{row['samples_per_s'] / base:.2f}× | {row['peak_rss_mb']:,.0f} MB |")
    return out + [""]


def bag_section(sizes: dict) -> list[str]:
    from benchmarks.bench_bags import bags_section

    rows, HEADLINE["bags"] = bags_section(run_case, sizes["bag_n"])
    return rows


def live_section(sizes: dict) -> list[str]:
    from benchmarks.bench_live import live_section as section

    rows, HEADLINE["live"] = section(run_case, sizes)
    return rows


def live_tracker_section(sizes: dict) -> list[str]:
    from benchmarks.bench_live import tracker_section

    rows, HEADLINE["live_tracker"] = tracker_section(run_case)
    return rows


def scale_section(sizes: dict) -> list[str]:
    # In its own process: it starts Dask clusters and fresh processes for the memory figures.
    n_files, rows, degree = sizes["scale"]
    code = ("import contextlib, json, sys\nfrom benchmarks import bench_scale\n"
            "with contextlib.redirect_stdout(sys.stderr):\n"
            f"    result = bench_scale.main({n_files}, {rows}, {degree})\nprint(json.dumps(result))")
    done = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True,
                          env=dict(os.environ, FTCAL_PROGRESS="0"))
    if done.returncode != 0:
        raise RuntimeError(f"scale-out benchmark failed:\n{done.stderr[-2000:]}")
    result = json.loads(done.stdout.strip().splitlines()[-1])
    stats, memory = result["statistics"], result["memory"]
    base = stats[0]["samples_per_s"]
    message_mb = result["message_bytes"] / 1e6
    streaming_peak = max(r["peak_rss_mb"] for r in memory[:2])
    HEADLINE["scale"] = (f"{n_files} Parquet files of {rows:,} rows, degree {degree}: streaming predict/evaluate peak "
                         f"{streaming_peak:,.0f} MB for a {result['table_mb']:,.0f} MB table; statistics on Dask "
                         f"local:2 at {stats[2]['samples_per_s'] / base:.2f}× the single process")
    out = [f"## Scale-out: {n_files} Parquet files × {rows:,} rows, degree {degree} statistics "
           "(one task per file, tree-summed)", "",
           "| where | time | samples/s | vs this process |", "|---|---:|---:|---:|"]
    for row in stats:
        out.append(f"| {row['method']} | {fmt_s(row['seconds'])} | {row['samples_per_s']:,.0f} | "
                   f"{row['samples_per_s'] / base:.2f}× |")
    out += ["", f"One statistics message (pickled `SufficientStatistics`): {result['message_bytes']:,} bytes.", "",
            f"| peak memory, fresh process ({result['table_mb']:,.0f} MB of float64 columns) | peak RSS |",
            "|---|---:|"]
    out += [f"| {row['method']} | {row['peak_rss_mb']:,.0f} MB |" for row in memory]
    fit = result["fit"]
    out += ["", "| fit, fresh process | peak RSS | time | per sample | vs in memory |", "|---|---:|---:|---:|---:|"]
    out += [f"| {row['method']} | {row['peak_rss_mb']:,.0f} MB | {fmt_s(row['seconds'])} | "
            f"{row['us_per_sample']:.3f} µs | {row['seconds'] / fit[1]['seconds']:.2f}× |" for row in fit]
    out += ["", f"Streamed and in-memory coefficients differ by {fit[0]['max_relative_coef_difference']:.1e} "
            "(relative to the largest).", ""]
    hop_s = message_mb * 8 / 1000  # one message over 1 Gbit/s
    bytes_per_sample = 8 * 13  # u1..u6, T, Fx..Tz as float64
    per_core = base / result["cores"]  # the single process keeps all its cores busy (ftcal's worker threads)
    out += ["", f"Projection for 16 single-core workers, from the figures above: the single process ran on "
            f"{result['cores']} core(s), so one core does ~{per_core:,.0f} samples/s and the statistics pass "
            f"takes N / (16 × {per_core:,.0f}) s (~{16 * per_core:,.0f} samples/s: files are independent tasks; "
            "Dask adds a few ms per task); the tree reduction adds log2(files) levels of one "
            f"{message_mb:.2f} MB message (~{hop_s * 1000:.0f} ms each at 1 Gbit/s) and a p × p addition; the "
            "solve on the client is O(p³) once, independent of N. File reading limits first: "
            f"{bytes_per_sample} bytes per sample from a shared file system is "
            f"{16 * per_core * bytes_per_sample / 1e6:,.0f} MB/s in aggregate, about what a 1 Gbit/s NFS "
            "server gives (~110 MB/s); past that, put the files on the workers' local disks.", ""]
    return out


def floor_section(sizes: dict) -> list[str]:
    """Whole-process ``ftcal fit --degree 4`` at 10⁶ rows against the flop floor measured in the same run (issue 32)."""
    from benchmarks.bench_floor import floor_section as section

    rows, HEADLINE["floor"] = section(run_case, sizes)
    return rows


def scan_section(sizes: dict) -> list[str]:
    """A streamed fit's passes through one scan against the per-file functions before it (issue 43)."""
    from benchmarks.bench_scan import scan_section as section

    rows, HEADLINE["scan"] = section(*sizes["scan"])
    return rows


def info_section(sizes: dict) -> list[str]:
    """``ftcal info MODEL``'s CPU as a user runs it (issue 43: at most 0.25 s)."""
    from benchmarks.bench_scan import info_section as section

    rows, HEADLINE["info"] = section(sizes["info_repeats"])
    return rows


def cost_section(sizes: dict) -> list[str]:
    """``--degree auto``: printed estimate against the whole command's CPU, the budget kept, BLAS threads."""
    from benchmarks.bench_cost import DEMO_TABLE

    cases = [(n, k, None) for n, k in sizes["cost"]]
    budget_n, budget_k, budget = sizes["cost_budget"]
    cases.append((budget_n, budget_k, budget))
    if DEMO_TABLE.exists():
        cases.insert(0, (0, 7, None))
    rows, ratios, kept = [], [], []
    for n, k, limit in cases:
        r = run_case("select_cost", n=n, n_inputs=k, budget=limit)
        table = "demo dataset.parquet (168,420 rows, cond. 1.8e8)" if n == 0 else f"load cases, {n:,} rows"
        ratios.append(max(r["ratio"], 1 / r["ratio"]))
        if limit is not None:
            kept.append(r["cpu_s"] / limit)
        rows.append(f"| {table} | {k} | {limit if limit is not None else 20:g} s | {r['estimate_s']:.1f} s | "
                    f"{r['cpu_s']:.1f} s | {r['ratio']:.2f} | {r['wall_s']:.1f} s | {r['child_peak_rss_mb']:,.0f} MB | "
                    f"{r['dropped'] or '-'} |")
    threads = ""
    if DEMO_TABLE.exists():
        one = run_case("select_cost", n=0, n_inputs=7, blas_threads=1)
        default = run_case("select_cost", n=0, n_inputs=7)
        threads = (f"Demo search with `OPENBLAS_NUM_THREADS=1` / default threads: CPU {one['cpu_s']:.1f} s / "
                   f"{default['cpu_s']:.1f} s = {one['cpu_s'] / default['cpu_s']:.2f} (target ≥ 0.95: no "
                   "oversubscription).")
    HEADLINE["cost"] = (f"`--degree auto` estimate within {max(ratios):.2f}× of the measured CPU on {len(ratios)} "
                        f"tables (target 2×); --budget {budget:g} s used {max(kept) * budget:.1f} s of CPU "
                        f"({max(kept):.2f}× the budget, target ≤ 1.5×)")
    return ["## Cost of `--degree auto`: printed estimate against the whole command's CPU", "",
            "Each row is one `ftcal fit TABLE --degree auto --group-by group` process (imports, reading, search, "
            "final fit): CPU = user + system from its rusage. Estimate/CPU is the ratio of the printed estimate "
            "to it.", "",
            "| table | inputs | --budget | estimate | CPU | estimate/CPU | wall | peak memory | left out |",
            "|---|---:|---:|---:|---:|---:|---:|---:|---|", *rows, "", threads, ""]


def threads_section(sizes: dict) -> list[str]:
    """The demo search with every thread pool forced to one thread against the default (issue 32)."""
    from benchmarks.bench_cost import DEMO_TABLE

    if not DEMO_TABLE.exists():
        return []
    r = run_case("threads_pair", pairs=sizes["threads_pairs"])
    HEADLINE["threads"] = (f"demo search CPU with threads forced to 1 / default: {r['ratio']:.2f} "
                           f"(median of {r['pairs']} pairs; target ≥ 0.95: no oversubscribed core)")
    return ["## No oversubscription: the demo search with every thread pool forced to one thread", "",
            "`ftcal fit ftcal-demo/dataset.parquet --degree auto --group-by group`, whole process, default threads "
            "and with `OPENBLAS_NUM_THREADS=OMP_NUM_THREADS=MKL_NUM_THREADS=1`, in turn; CPU = user + system.", "",
            "| threads | CPU (median) | wall (median) |", "|---|---:|---:|",
            f"| default | {fmt_s(r['default']['cpu_s'])} | {fmt_s(r['default']['wall_s'])} |",
            f"| forced to 1 | {fmt_s(r['forced']['cpu_s'])} | {fmt_s(r['forced']['wall_s'])} |", "",
            f"CPU(forced) / CPU(default) per pair: {', '.join(f'{x:.2f}' for x in r['ratios'])}; median "
            f"{r['ratio']:.2f} (target ≥ 0.95).", ""]


def cluster_section(sizes: dict) -> list[str]:
    """Whole ``ftcal fit --degree 4``: one process against ``--scheduler local:2`` (issue 32); against the
    tree in FTCAL_BASELINE_SRC's ``local:2`` too (the code before) when set."""
    baseline = os.environ.get("FTCAL_BASELINE_SRC")
    rows, heads, load = [], [], []
    for n_files, n_rows in sizes["cluster"]:
        r = run_case("cluster_fit", n_files=n_files, rows=n_rows, workers=2, pairs=sizes["cluster_pairs"],
                     baseline_src=baseline)
        load.extend(r["load_average"])
        one = r["one"]
        heads.append(f"{n_files} × {n_rows:,}: {r['ratio']['wall_s']:.2f}× wall, {r['ratio']['cpu_s']:.2f}× CPU")
        rows.append(f"| {n_files} × {n_rows:,} | one process | {fmt_s(one['wall_s'])} | {fmt_s(one['cpu_s'])} | "
                    f"{one['peak_rss_mb']:.0f} MB | | | | 1.00× | 1.00× | |")
        for name, label in (("cluster", "local:2"), ("baseline", "local:2, code before")):
            if name not in r:
                continue
            c = r[name]
            rows.append(f"| {n_files} × {n_rows:,} | {label} | {fmt_s(c['wall_s'])} | {fmt_s(c['cpu_s'])} | "
                        f"{c['peak_rss_mb']:.0f} MB + {c['worker_peak_rss_mb']:.0f} MB | {c['startup_s']:.1f} s | "
                        f"{c['worker_page_faults']:,.0f} | {fmt_s(c['worker_system_s'])} | "
                        f"{r['ratios'][name]['wall_s']:.2f}× | {r['ratios'][name]['cpu_s']:.2f}× | "
                        f"{'equal' if r['same_coefficients'] else 'DIFFERENT'} |")
    t = run_case("task_threads", rows=max(n_rows for _, n_rows in sizes["cluster"]),
                 rounds=max(3, sizes["cluster_pairs"]))
    load.extend(t["load_average"])
    HEADLINE["cluster"] = ("`ftcal fit --degree 4 --scheduler local:2` / one process, whole command: " + "; ".join(heads)
                           + " (targets ≤ 1.1× on 4 files, < 1× on 16)")
    threads = ["Why `local:N` runs a fit's statistics tasks in threads of the command (issue 32): two files of "
               f"{t['rows']:,} rows, their task (`file_summary_statistics_and_poses`) one after the other: "
               f"{fmt_s(t['sequential']['wall_s'])} wall, {fmt_s(t['sequential']['cpu_s'])} CPU; in two threads of "
               f"one process: {fmt_s(t['threads']['wall_s'])} wall, {fmt_s(t['threads']['cpu_s'])} CPU "
               f"({t['ratio']['wall_s']:.2f}× the wall, {t['ratio']['cpu_s']:.2f}× the CPU; medians of "
               f"{t['rounds']} alternated rounds). The reads, numpy on whole chunks and the compiled kernel run "
               "without the GIL, so threads overlap them with no start-up, where each Dask worker process "
               "costs ~1.5 CPU s of imports and the client ~1 s for `import distributed`. Tasks not marked "
               "`releases_gil` (ARX, `--degree auto`'s folds, evaluate, predict) still start worker processes.", ""]
    return ["## Dask `local:2` against one process: whole `ftcal fit FILES --degree 4`", "",
            "Each run is one whole process (start-up, the cluster's start and stop, the passes, writing); CPU = "
            "user + system of the command and every worker it waited for; memory: the command's peak + its largest "
            "worker's; the workers' page faults and kernel seconds (what their allocator settings change). The "
            f"variants alternate; medians of {sizes['cluster_pairs']} rounds, ratios to the one-process run of the "
            "same round, median. `local:2` is this tree: the fit's tasks in 2 threads of the command (no worker "
            "process; it says so in one line); `local:2, code before` (when run) is the tree in FTCAL_BASELINE_SRC: a "
            "Dask LocalCluster of 2 worker processes (start-up: the seconds it printed, `Dask local:2: 2 worker "
            f"processes started in X s`). 1-minute load average during the runs: {min(load):.1f}–{max(load):.1f} "
            f"on {os.cpu_count()} cores.", "",
            "| files × rows | run | wall | CPU | peak memory | start-up | worker page faults | worker kernel | "
            "wall ratio | CPU ratio | coefficients |", "|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---|",
            *rows, "", *threads]


def payload_cli_section(sizes: dict) -> list[str]:
    """Whole ``ftcal payload`` processes; against the tree in FTCAL_BASELINE_SRC (the code before) when set."""
    n = sizes["payload_cli_n"]
    baseline = os.environ.get("FTCAL_BASELINE_SRC")
    out = ["## `ftcal payload` as a user runs it: one Parquet table, 100 still poses, quaternions", "",
           f"`ftcal payload holds.parquet --orientation qx,qy,qz,qw --bias-drift MODEL`, {n:,} rows at 100 Hz "
           "(benchmarks/bench_payload_cli.py), whole process, each child's own CPU and peak memory"
           + (f"; baseline: the same command on `{baseline}`, run in turn with this tree's (median of 2 each)"
              if baseline else "") + ".", "",
           "| --bias-drift | CPU | wall | peak memory | mass (true 1.3 kg) | baseline CPU | baseline wall | "
           "baseline peak | CPU vs baseline |", "|---|---:|---:|---:|---:|---:|---:|---:|---:|"]
    heads = []
    for model in ("none", "random-walk"):
        r = run_case("payload_cli", n=n, bias_drift=model, baseline_src=baseline)
        this, base = r["this"], r.get("baseline")
        tail = (f"{fmt_s(base['cpu_s'])} | {fmt_s(base['wall_s'])} | {base['peak_rss_mb']:,.0f} MB | "
                f"{this['cpu_s'] / base['cpu_s']:.2f}×" if base else "— | — | — | —")
        out.append(f"| {model} | {fmt_s(this['cpu_s'])} | {fmt_s(this['wall_s'])} | {this['peak_rss_mb']:,.0f} MB | "
                   f"{this['mass']:.4f} kg | {tail} |")
        heads.append(f"{model} {this['cpu_s']:.2f} CPU s, {this['peak_rss_mb']:,.0f} MB"
                     + (f" (before: {base['cpu_s']:.2f} s, {base['peak_rss_mb']:,.0f} MB)" if base else ""))
    HEADLINE["payload_cli"] = f"whole `ftcal payload` at {n:,} rows: " + "; ".join(heads)
    return out + [""]


def selection_rates_section(sizes: dict) -> list[str]:
    """False wins on an affine truth and the oracle's gain kept on a nonlinear one, per seed set and pooled."""
    from concurrent.futures import ThreadPoolExecutor

    # (label suffix, case arguments): 40 load cases per block; --select-per output with 4 folds (three outputs
    # per block judged together, issue 44 measured 19 % false wins); small tables: 12 load cases in 5 folds (2-3
    # a fold, judged with nested cross-validation), 20 (4 a fold) and 54 rows of one sample a load case (the
    # oracle: least squares of degree 1 or 2).
    configs = (("", {}), (", per output, 4 folds", {"select_per": "output", "n_folds": 4}),
               (", 12 load cases", {"n_groups": 12}), (", 20 load cases", {"n_groups": 20}),
               (", 54 rows", {"n_groups": 54, "per_group": 1}))
    jobs = [(truth + suffix, first, seeds, dict(nonlinearity=nl, first=first, seeds=seeds, **kwargs))
            for suffix, kwargs in configs for first, seeds in sizes["select_rate_seeds"]
            for truth, nl in (("affine", 0.0), ("paper-level nonlinear", 1.0))]
    # Two cases at a time (each its own process; the table reports each one's CPU).
    with ThreadPoolExecutor(2) as pool:
        results = list(pool.map(lambda job: run_case("select_rates", **job[3]), jobs))
    rows = [(label, first, seeds, r) for (label, first, seeds, _), r in zip(jobs, results)]

    def pooled(label: str) -> dict:
        sets = [r for name, _, _, r in rows if name == label]
        n = sum(r["sums"]["seeds"] for r in sets)
        total = {k: np.sum([r["sums"][k] for r in sets], axis=0)
                 for k in ("selected", "oracle", "flat", "previous", "alone")}
        oracle_gain = n - total["oracle"]
        share = lambda k: ((n - total[k]) / np.maximum(oracle_gain, np.finfo(float).tiny)).tolist()  # noqa: E731
        return {"seeds": n, "richer": sum(r["sums"]["richer"] for r in sets) / n,
                "flat_richer": sum(r["sums"]["flat_richer"] for r in sets) / n,
                "alone_richer": sum(r["sums"]["alone_richer"] for r in sets) / n, "alone_gain_share": share("alone"),
                "previous_richer": sum(r["sums"]["previous_richer"] for r in sets) / n,
                "gain_share": share("selected"), "flat_gain_share": share("flat"),
                "previous_gain_share": share("previous"), "oracle_gain": (oracle_gain / n).tolist(),
                "cv_over_held_out": [min(r["cv_over_held_out"][0] for r in sets),
                                     float(np.median([r["cv_over_held_out"][1] for r in sets])),
                                     max(r["cv_over_held_out"][2] for r in sets)],
                "cpu_seconds": sum(r["cpu_seconds"] for r in sets)}

    import numpy as np

    labels = list(dict.fromkeys(label for label, _, _, _ in rows))
    pools = {label: pooled(label) for label in labels}
    span = (f"{sizes['select_rate_seeds'][0][0]}-"
            f"{sizes['select_rate_seeds'][-1][0] + sizes['select_rate_seeds'][-1][1] - 1}")

    def gains(label: str, key: str = "gain_share", block: int = 0) -> str:
        values = [r[key][block] for name, _, _, r in rows if name == label]
        return f"{min(values):.0%}-{max(values):.0%}"

    def richer(label: str, key: str = "richer") -> str:
        values = [r[key] for name, _, _, r in rows if name == label]
        return f"{min(values):.0%}-{max(values):.0%} (pooled {pools[label][key]:.1%})"

    HEADLINE["select_rates"] = (
        f"richer model on an affine truth in {richer('affine')} of seeds (target ≤ 5 %); share of the oracle "
        f"degree's held-out gain kept: force {gains('paper-level nonlinear')}, torque "
        f"{gains('paper-level nonlinear', block=1)} (target ≥ 90 %; the rule before issue 44, on the same folds: "
        f"force {gains('paper-level nonlinear', 'previous_gain_share')}); `--select-per output` with 4 folds: "
        f"richer model on an affine truth in {richer('affine, per output, 4 folds')}; 12 load cases (nested "
        f"cross-validation): {richer('affine, 12 load cases')} (before it: "
        f"{richer('affine, 12 load cases', 'flat_richer')}), force gain kept "
        f"{pools['paper-level nonlinear, 12 load cases']['gain_share'][0]:.0%} pooled (before: "
        f"{pools['paper-level nonlinear, 12 load cases']['flat_gain_share'][0]:.0%}); 20 load cases: "
        f"{richer('affine, 20 load cases')}; 54 rows: force gain kept {gains('paper-level nonlinear, 54 rows')} "
        f"(each block alone, before the anchor at the whole model's choice: "
        f"{gains('paper-level nonlinear, 54 rows', 'alone_gain_share')}; 12 load cases "
        f"{pools['paper-level nonlinear, 12 load cases']['alone_gain_share'][0]:.0%} pooled)")
    out = ["## Model selection's error rates: `--degree auto` (per block) on simulated sensors with a known truth", "",
           "The paper-like sensor of `benchmarks.load_cases.make_paper_sensor` (6 channels, 40 load cases of 30 "
           "samples unless the row says otherwise, the reference off by a constant per load case of 2 % of full "
           "scale), scored on 100 new load cases inside the training range; the oracle is the best least-squares "
           "degree (1-4; 1-2 for the 54-row table) on those. Now: a win over affine must exceed one standard error "
           "of the fold log ratio corrected for the shared training sets (Nadeau & Bengio 2003; 1.5 naive standard "
           "errors at 5 folds), ties within 1 %; folds of fewer than 4 load cases (12 load cases in 5 folds) are "
           "judged by the t test with the degrees as a Bonferroni factor and, since nested cross-validation "
           "(`core/select/scoring.py`, `nested_comparison`), the selection procedure must also beat affine on the "
           "outer folds it never saw (the inner CV of each outer fold chooses; one corrected standard error). "
           "A block takes the whole model's stable choice unless its own best beats that on the block beyond the "
           "fold noise (`anchored_choice`); *each block alone*: the same fold scores without that anchor. "
           "*Before nested CV*: the same fold scores without that test. *Rule before issue 44*: the one-sided t "
           "test at 5 % (2.13 standard errors), ties within 1 % or one standard error going to fewer nonzeros. "
           f"*Pooled* rows: the {len(sizes['select_rate_seeds'])} seed sets together (gain shares as ratios of the "
           "summed gains; CV / held-out: min and max over every seed, the median of the sets' medians).", "",
           "| truth | seeds | richer model chosen | gain kept, force / torque | oracle gain, force / torque | "
           "each block alone: richer / gain kept | before nested CV: richer / gain kept | "
           "rule before issue 44: richer / gain kept | CV / held-out error (min, median, max) | CPU |",
           "|---|---|---:|---:|---:|---:|---:|---:|---:|---:|"]

    def line(label: str, seeds: str, r: dict) -> str:
        affine = label.startswith("affine")
        kept = "—" if affine else f"{r['gain_share'][0]:.0%} / {r['gain_share'][1]:.0%}"
        flat = f"{r['flat_richer']:.1%} / " + ("—" if affine else
                                               f"{r['flat_gain_share'][0]:.0%}, {r['flat_gain_share'][1]:.0%}")
        previous = f"{r['previous_richer']:.1%} / " + ("—" if affine else f"{r['previous_gain_share'][0]:.0%}, "
                                                                           f"{r['previous_gain_share'][1]:.0%}")
        alone = f"{r['alone_richer']:.1%} / " + ("—" if affine else f"{r['alone_gain_share'][0]:.0%}, "
                                                                     f"{r['alone_gain_share'][1]:.0%}")
        honesty = ", ".join(f"{v:.2f}" for v in r["cv_over_held_out"])
        return (f"| {label} | {seeds} | {r['richer']:.1%} | {kept} | {r['oracle_gain'][0]:.0%} / "
                f"{r['oracle_gain'][1]:.0%} | {alone} | {flat} | {previous} | {honesty} | "
                f"{fmt_s(r['cpu_seconds'])} |")

    for label in labels:
        for name, first, seeds, r in rows:
            if name == label:
                out.append(line(label, f"{first}-{first + seeds - 1}", r))
        out.append(line(label, f"**{span} pooled**", pools[label]))
    return out + ["", "`--select-per output` is judged by the t test (Bonferroni over the outputs of a block) "
                  "after its block's test. With 2-3 load cases a fold the best candidate's fold log ratio reached "
                  "4.7 standard errors on an affine truth: the test of the best candidate alone chose a richer "
                  "model there; the selection procedure scored on folds it never saw (nested cross-validation, "
                  "its pair fits on sums of the fold statistics) does not carry that winner's curse.", ""]


def payload_errors_section(sizes: dict) -> list[str]:
    """Coverage of the payload mass's 95 % intervals per bias model, now and with the 20-block jackknife alone."""
    r = run_case("payload_errors", seeds=sizes["payload_error_seeds"])
    cases = r["cases"]
    HEADLINE["payload_errors"] = (
        f"95 % intervals of the payload mass cover the truth in {min(c['now']['coverage'] for c in cases.values()):.0%}"
        f" of seeds at worst over {len(cases)} scenario/bias-model cases (target ≥ 90 %; the 20-block jackknife "
        f"alone: {min(c['before']['coverage'] for c in cases.values()):.0%}); stated/delete-a-block spread, median "
        f"{min(c['now']['ratio'][1] for c in cases.values()):.2f}-{max(c['now']['ratio'][1] for c in cases.values()):.2f}"
        " (target 0.5-2)")
    out = ["## Payload standard errors: coverage per bias model on recordings with a known mass", "",
           f"`benchmarks/bench_payload_errors.py`, {r['seeds']} seeds per case (`benchmarks/payload_recordings.py`: "
           "*sweep* 100 poses of one row in a systematic order with a random-walk bias, so the drift follows the pose "
           "order; *holds* 20 still poses of 40 samples with a walk, AR(1) noise and an error constant per hold; "
           "*moves* the same with turns between the holds read through a lagging filter; the others are *holds* "
           "with slow coloured wander, a walk 5x faster in the second half, a 10-bit converter, or ±1.5 % gain "
           "errors with 1 % cross-talk). *Before*: the same fits with the 20-block jackknife alone. The reference "
           f"spread is the delete-a-contiguous-block jackknife (5 blocks, refits on the kept rows) over the first "
           "seeds.", "",
           "| recording | bias model | coverage now / before | worst \\|z\\| now / before | stated / delete-a-block "
           "spread, now (min, median, max) | before (median) | median mass error | CPU now |",
           "|---|---|---:|---:|---:|---:|---:|---:|"]
    for key, c in cases.items():
        scenario, model = key.split("/")
        now, before = c["now"], c["before"]
        out.append(f"| {scenario} | {model} | {now['coverage']:.0%} / {before['coverage']:.0%} | "
                   f"{now['worst_z']:.1f} / {before['worst_z']:.1f} | "
                   + ", ".join(f"{v:.2f}" for v in now["ratio"]) + f" | {before['ratio'][1]:.2f} | "
                   f"{100 * now['mass_error']:.2f} % | {fmt_s(now['cpu_seconds'])} |")
    return out + [""]


def real_like_section(sizes: dict) -> list[str]:
    """Every calibration path on the real-like simulated sensors, against OLS on the same outer folds (issue 44)."""
    from benchmarks.bench_real_like import CASES as REAL_LIKE, PATHS

    results = [run_case("real_like", sensor=sensor, split=split, seed=seed, mlp=sizes["real_like_mlp"])
               for seed in sizes["real_like_seeds"] for sensor, split in REAL_LIKE[:sizes["real_like_cases"]]]
    names = [p for p in PATHS if p in results[0]["paths"]]
    silent = {name: sum(len(r["paths"][name]["silent_loss_folds"]) for r in results) for name in names}
    explicit = [n for n in names if n not in ("default", "default, each block alone", "select_per model")]
    broken = sum(len(r["paths"][n]["broken_claim_folds"]) for r in results for n in names)
    HEADLINE["real_like"] = (
        f"{len(results)} sensor/split cases: explicit paths that lost to OLS by > 10 % on an outer fold without a "
        f"word: {sum(silent[n] for n in explicit)} folds (target 0); the default's held-out force/torque over OLS "
        + ", ".join(f"{r['sensor']} {r['split']} {r['paths']['default']['ratio'][0]:.2f}/"
                    f"{r['paths']['default']['ratio'][1]:.2f}" for r in results)
        + f"; MLP wins claimed beyond the noise that lost on their outer fold: {broken}")

    def cell(p):
        ratio = "refused" if p["ratio"] is None else f"{p['ratio'][0]:.2f} / {p['ratio'][1]:.2f}"
        return f"{ratio} ({p['said_folds']}, {len(p['silent_loss_folds'])})"

    out = ["## Real-like sensors: every path against OLS on the held-out folds (issue 44's splits)", "",
           "`benchmarks/bench_real_like.py` on the simulators of `ftcal.sim.real_like` (physics, not ftcal's "
           "model: an 8-photodiode optical sensor with erfc occlusion curves, 47 hung-weight load cases in 6 "
           "orientations, LED drift, AR(1) noise, 12 bits; a six-bridge plate, 60 averaged loads at 5 levels; a "
           "soft fingertip, magnet dipole and 8 saturating Hall sensors, 418 loads in 19 presses of one direction "
           "each, a press its load case; references off by an error per load case). Each path is `ftcal.fit` on the kept rows of each outer fold (their "
           "load cases as its validation groups), scored on the held-out rows against the reference: force / "
           "torque error-norm RMSE over all held-out rows divided by OLS's (`degree=1` on the same rows); in "
           "brackets, the outer folds where the path said it does not beat affine (a refusal, a warning naming "
           "the affine model, a comparison line without a win, or the affine model written instead of the "
           "network) and the folds it lost by more than 10 % without saying so (the `degree=\"auto\"` "
           "paths are not explicit: their counts are for information).", "",
           "| sensor, split (seed) | OLS force / torque | " + " | ".join(names) + " | CPU |",
           "|---|---:|" + "---:|" * len(names) + "---:|"]
    for r in results:
        out.append(f"| {r['sensor']}, {r['split']} ({r['seed']}) | {r['ols_rmse'][0]:.3g} N / {r['ols_rmse'][1]:.3g} "
                   "N·m | " + " | ".join(cell(r["paths"][n]) for n in names) + f" | {fmt_s(r['cpu_seconds'])} |")
    return out + [""]


# One line per section; HEADLINE keys name the targets summary's rows.
SECTIONS = (fit_section, cli_section, lasso_section, predict_section, selection_section, selection_rates_section,
            real_like_section,
            payload_errors_section,
            cost_section,
            mlp_section, plan_section, closed_loop_section,
            c_section, c_batch_section,
            scaling_section, expected_section, payload_section, payload_cli_section, bag_section, scale_section,
            cluster_section, threads_section, live_section, live_tracker_section, floor_section, scan_section,
            info_section)
LABELS = {"fit": "Fit", "cli": "Whole-process fit", "lasso": "LASSO", "predict": "Prediction", "select": "Model selection",
          "select_rates": "Selection error rates", "payload_errors": "Payload standard errors",
          "real_like": "Real-like sensors, every path",
          "cost": "Cost of --degree auto", "closed_loop": "Closed loop",
          "mlp": "MLP family", "plan": "Experiment design",
          "c": "Generated C", "expected": "Expected wrenches", "payload": "Payload identification",
          "bags": "Bag reading", "scale": "Streaming and Dask", "live": "Live calibrator",
          "live_tracker": "Live tracker, issue 40's cases",
          "payload_cli": "Payload, whole command", "cluster": "Dask local:2, whole fit",
          "threads": "No oversubscription", "c_batch": "C live step", "floor": "Whole-process fit vs flop floor",
          "scan": "One scan", "info": "Light commands"}

FULL = {"fit_big": 1_000_000, "fit_mid": 100_000, "scaling_n": (10_000, 100_000, 1_000_000), "dense_max_n": 100_000,
        "degree_n": 100_000, "lasso_n": 200_000, "paper_lasso_n": 10_000, "predict_n": 2_000_000,
        "expected_n": 100_000, "expected_baseline_n": 10_000, "c_evals": 2_000_000, "python_calls": 2_000,
        "payload_n": 1_000_000, "bag_n": 500_000, "cli_n": 200_000, "cli_repeats": 5, "select_n": 74_000,
        "mlp_n": 20_000, "mlp_hidden": "16", "mlp_iterations": 200, "plan": (60, 10_000),
        "scale": (10, 1_000_000, 4), "cost": ((20_000, 6), (200_000, 7), (1_000_000, 8)),
        "cost_budget": (1_000_000, 8, 8.0), "live_n": 600_000, "live_steps_n": 50_000, "live_minutes": (6, 60),
        "live_zenoh_s": 10.0, "closed_loop_variants": {"standard": (0, 1, 2), "high-loads": (0, 1, 2), "tool-change": (0, 1, 2),
                                                       "long-task": (0, 1, 2)}, "closed_loop_quick": False,
        "payload_cli_n": 1_000_000, "cluster": ((4, 1_000_000), (16, 250_000)), "cluster_pairs": 3,
        "threads_pairs": 2, "c_batch_evals": 2_000_000, "c_runtime_n": 200_000, "floor_n": 1_000_000,
        "floor_pairs": 5, "scan": (500_000, 4, 3), "info_repeats": 5,
        "select_rate_seeds": ((0, 20), (20, 20), (40, 20)), "payload_error_seeds": 30,
        "real_like_seeds": (0, 1), "real_like_cases": 6, "real_like_mlp": True}
QUICK = {"fit_big": 20_000, "fit_mid": 5_000, "scaling_n": (2_000, 10_000), "dense_max_n": 10_000,
         "degree_n": 5_000, "lasso_n": 5_000, "paper_lasso_n": 1_000, "predict_n": 100_000,
         "expected_n": 2_000, "expected_baseline_n": 500, "c_evals": 100_000, "python_calls": 200,
         "payload_n": 20_000, "bag_n": 20_000, "cli_n": 5_000, "cli_repeats": 1, "select_n": 6_000,
         "mlp_n": 6_000, "mlp_hidden": "8", "mlp_iterations": 50, "plan": (20, 1_000),
         "scale": (4, 50_000, 4), "cost": ((4_000, 6),), "cost_budget": (20_000, 6, 3.0), "live_n": 50_000,
         "live_steps_n": 500, "live_minutes": (1, 2), "live_zenoh_s": 2.0, "closed_loop_variants": {"standard": (0,)},
         "closed_loop_quick": True, "payload_cli_n": 100_000, "cluster": ((2, 20_000),), "cluster_pairs": 1,
         "threads_pairs": 1, "c_batch_evals": 100_000, "c_runtime_n": 20_000, "floor_n": 50_000,
         "floor_pairs": 1, "scan": (20_000, 2, 1), "info_repeats": 1, "select_rate_seeds": ((0, 2),),
         "payload_error_seeds": 2, "real_like_seeds": (0,), "real_like_cases": 1, "real_like_mlp": False}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m benchmarks")
    parser.add_argument("--quick", action="store_true", help="small sizes, to check the harness")
    parser.add_argument("--out", default=str(ROOT / "BENCHMARKS.md"))
    parser.add_argument("--only", metavar="SECTION,...",
                        help="run only these sections (names without _section, e.g. cluster,payload_cli) and "
                             "put their tables and target lines into the existing --out file in place")
    args = parser.parse_args(argv)
    sizes = QUICK if args.quick else FULL
    if args.only:
        return update_sections(args.only.split(","), sizes, Path(args.out))
    started = time.perf_counter()
    lines = ["# Benchmarks", "",
             "Generated by `make bench` (`python -m benchmarks`). Every case runs in a fresh process; "
             "*peak memory* is that process's peak resident set size, including about 150 MB of "
             "interpreter and libraries. Ratios compare cases measured in the same run.", "",
             f"Machine: {machine()}.", ""]
    body = []
    for section in SECTIONS:
        print(f"{section.__name__} ...", file=sys.stderr, flush=True)
        body += section(sizes)
    lines += ["## Against the targets", ""] + [f"- **{LABELS[k]}**: {v}." for k, v in HEADLINE.items()] + [""]
    lines += body
    lines += [f"Total benchmark time: {time.perf_counter() - started:.0f} s.", ""]
    Path(args.out).write_text("\n".join(lines))
    print("\n".join(lines))
    return 0


def update_sections(names: list[str], sizes: dict, path: Path) -> int:
    """Run the named sections only; replace their ``## `` blocks and target lines in ``path`` (append new ones)."""
    chosen = {f.__name__[:-len("_section")]: f for f in SECTIONS}
    unknown = [n for n in names if n not in chosen]
    if unknown:
        raise SystemExit(f"--only: no section {', '.join(unknown)}; sections: {', '.join(chosen)}")
    text = path.read_text() if path.exists() else "# Benchmarks\n\n## Against the targets\n\n"
    for name in names:
        print(f"{name}_section ...", file=sys.stderr, flush=True)
        block = chosen[name](sizes)
        if not block:
            continue
        title = block[0]
        body = "\n".join(block).rstrip("\n") + "\n\n"
        start = text.find(title + "\n")
        if start >= 0:
            end = text.find("\n## ", start + len(title))
            end = len(text) if end < 0 else end + 1
            marker = text.find("\nTotal benchmark time", start)
            if 0 <= marker < end:
                end = marker + 1
            text = text[:start] + body + text[end:]
        else:
            marker = text.find("Total benchmark time")
            text = text + "\n" + body if marker < 0 else text[:marker] + body + text[marker:]
    lines = text.split("\n")
    for key, value in HEADLINE.items():
        line = f"- **{LABELS[key]}**: {value}."
        prefix = f"- **{LABELS[key]}**:"
        found = [i for i, old in enumerate(lines) if old.startswith(prefix)]
        if found:
            lines[found[0]] = line
        else:
            heads = [i for i, old in enumerate(lines) if old.startswith("- **")]
            lines.insert(heads[-1] + 1 if heads else len(lines), line)
    path.write_text("\n".join(lines))
    return 0


if __name__ == "__main__":
    sys.exit(main())
