"""Generated C on one core: the batch evaluator against the scalar one and a vectorised floor; the live step.

* ``c_batch``: one driver program times, in the same run, ``NAME_predict`` called per sample,
  ``NAME_predict_batch`` over 1,024 samples per call, and the **floor**: a register-blocked
  multiply-add kernel written with GCC vector extensions (two vectors of samples per block, six
  outputs, every accumulator in a register) doing the model's multiply-adds (one per monomial and
  output) on monomials already in L1. The floor leaves out the monomials themselves, the
  normalisation and the transposes, so it is below anything that evaluates the model; CPU time
  (``CLOCK_THREAD_CPUTIME_ID``), same compiler flags for all three (``-O2 -std=c99``, and with
  ``march="native"`` also ``-march=native``).
* ``c_runtime_step``: ``NAME_step`` of ``ftcal convert --to c-runtime`` (calibration + tool + bias
  filter + health) per sample over a simulated recording (motion test on, one tool), and the
  calibration alone (``NAME_calibrate``) in the same run; then the same steps with an identification
  in place running (each static hold's moments collected), and ``NAME_finish_identification`` on the
  holds they collected (µs per call, repeated on copies of the state).
"""

from __future__ import annotations

import shutil
import subprocess
import tempfile
import time
from pathlib import Path

import numpy as np

BATCH_DRIVER = r"""
#define _POSIX_C_SOURCE 199309L
#include <stdio.h>
#include <stdlib.h>
#include <time.h>
#include "bm.h"
#include "floor.h"
#define SAMPLES 1024
static double now(void)
{
    struct timespec t;
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
    return t.tv_sec + 1e-9 * t.tv_nsec;
}
static double wall(void)
{
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return t.tv_sec + 1e-9 * t.tv_nsec;
}
int main(int argc, char **argv)
{
    static double u[SAMPLES][BM_N_INPUTS], y[SAMPLES][BM_N_OUTPUTS];
    double w0, w1, w2, w3;
    static vec m[FLOOR_TERMS][2];
    double checksum = 0, t0, t1, t2, t3;
    long n = atol(argv[1]), rounds = n / SAMPLES, r, k;
    int s, i;
    (void)argc;
    for (s = 0; s < SAMPLES; ++s)
        for (i = 0; i < BM_N_INPUTS; ++i)
            if (scanf("%lf", &u[s][i]) != 1) return 1;
    for (k = 0; k < FLOOR_TERMS; ++k)
        for (i = 0; i < LANES; ++i) {
            m[k][0][i] = 1.0 / (k + i + 1);
            m[k][1][i] = 1.0 / (k + i + 2);
        }
    w0 = wall();
    t0 = now();
    for (r = 0; r < rounds; ++r)
        for (s = 0; s < SAMPLES; ++s) {
            bm_predict(u[s], y[s]);
            checksum += y[s][s % BM_N_OUTPUTS];
        }
    t1 = now();
    w1 = wall();
    for (r = 0; r < rounds; ++r) {
        bm_predict_batch(SAMPLES, &u[0][0], &y[0][0]);
        checksum += y[r % SAMPLES][0];
    }
    t2 = now();
    w2 = wall();
    for (r = 0; r < rounds * (SAMPLES / (2 * LANES)); ++r)
        checksum += floor_block(m);
    t3 = now();
    w3 = wall();
    printf("%.9f %.9f %.9f %.9f %.9f %.9f %.17g\n", t1 - t0, t2 - t1, t3 - t2, w1 - w0, w2 - w1, w3 - w2, checksum);
    return 0;
}
"""

FLOOR_TEMPLATE = r"""
#if defined(__AVX__)
typedef double vec __attribute__((vector_size(32)));
#define LANES 4
#else
typedef double vec __attribute__((vector_size(16)));
#define LANES 2
#endif
#define FLOOR_TERMS @TERMS@
static const double floor_c[FLOOR_TERMS][6] = {@COEFFICIENTS@};
/* 2 * LANES samples: 6 outputs x 2 vectors of accumulators, one multiply-add per term and output. */
__attribute__((noinline)) static double floor_block(vec m[][2])
{
    vec a[6][2];
    int t, k;
    double total = 0;
    for (k = 0; k < 6; ++k) a[k][0] = a[k][1] = m[0][0] * 0.0;
    for (t = 0; t < FLOOR_TERMS; ++t)
        for (k = 0; k < 6; ++k) {
            a[k][0] += floor_c[t][k] * m[t][0];
            a[k][1] += floor_c[t][k] * m[t][1];
        }
    for (k = 0; k < 6; ++k) total += a[k][0][0] + a[k][1][LANES - 1];
    return total;
}
"""


def _model(degree: int):
    from benchmarks.load_cases import make_data
    from ftcal.core.dataset import Dataset
    from ftcal.core.model import CalibrationModel

    u, y = make_data(20_000)
    return CalibrationModel(degree).fit(Dataset.from_arrays(u, y))


def _compile(folder: Path, flags: list[str], sources: list[str], output: str) -> None:
    cc = shutil.which("cc")
    if cc is None:
        raise RuntimeError("no system C compiler `cc` for the generated-C benchmark")
    subprocess.run([cc, *flags, *sources, "-o", output, "-lm"], cwd=folder, check=True, capture_output=True)


def c_batch(n: int, degree: int, march: str = "") -> dict:
    """Scalar, batch and floor ns per sample, paired in one driver run (see the module docstring)."""
    from benchmarks.load_cases import make_data
    from ftcal.files.c_code import generate_c

    model = _model(degree)
    code = generate_c(model, name="bm")
    terms = int(np.count_nonzero(model.coef_)) // 6  # multiply-adds per output and sample
    coefficients = ", ".join(f"{{{', '.join(repr(float(1e-3 * ((t * 6 + k) % 7 - 3))) for k in range(6))}}}"
                             for t in range(terms))
    samples, _ = make_data(1024, seed=1)
    flags = ["-std=c99", "-O2"] + ([f"-march={march}"] if march else [])
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        (folder / "bm.h").write_text(code.header)
        (folder / "bm.c").write_text(code.source)
        (folder / "floor.h").write_text(FLOOR_TEMPLATE.replace("@TERMS@", str(terms))
                                        .replace("@COEFFICIENTS@", coefficients))
        (folder / "driver.c").write_text(BATCH_DRIVER)
        start = time.perf_counter()
        _compile(folder, [*flags, "-c"], ["bm.c"], "bm.o")
        compile_seconds = time.perf_counter() - start
        # The floor uses GCC vector extensions: gnu99 for the driver, the same optimisation flags, and no
        # fused multiply-add (which -std=c99 does not contract either).
        _compile(folder, ["-std=gnu99", "-ffp-contract=off", *flags[1:]], ["driver.c", "bm.o"], "bench")
        text = "\n".join(" ".join(repr(float(v)) for v in row) for row in samples)
        out = subprocess.run([str(folder / "bench"), str(n)], input=text, capture_output=True, text=True,
                             check=True).stdout.split()
    total = (n // 1024) * 1024
    scalar, batch, floor = (float(v) / total * 1e9 for v in out[:3])
    return {"seconds": sum(float(v) for v in out[3:6]), "cpu_seconds": sum(float(v) for v in out[:3]),
            "scalar_ns": scalar, "batch_ns": batch, "floor_ns": floor,
            "batch_over_floor": batch / floor, "scalar_over_batch": scalar / batch, "terms_per_output": terms,
            "compile_seconds": compile_seconds, "flags": " ".join(flags)}


RUNTIME_DRIVER = r"""
#define _POSIX_C_SOURCE 199309L
#include <stdio.h>
#include <stdlib.h>
#include <time.h>
#include "rt.h"
static double now(void)
{
    struct timespec t;
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
    return t.tv_sec + 1e-9 * t.tv_nsec;
}
int main(int argc, char **argv)
{
    long n = atol(argv[1]), k;
    double *u = malloc(sizeof(double) * n * RT_N_INPUTS), *g = malloc(sizeof(double) * n * 3), w[6];
    double checksum = 0, t0, t1, t2, t3, t4, finish = 0.0;
    rt_state *s = malloc(sizeof *s), *saved = malloc(sizeof *s);
    rt_output o;
    rt_tool_fit fit;
    rt_tool_se se;
    int i, flagged = 0, status = 0, r, repeats = 20;
    long updates;
    (void)argc;
    for (k = 0; k < n; ++k) {
        for (i = 0; i < RT_N_INPUTS; ++i) if (scanf("%lf", &u[k * RT_N_INPUTS + i]) != 1) return 1;
        for (i = 0; i < 3; ++i) if (scanf("%lf", &g[k * 3 + i]) != 1) return 1;
    }
    rt_init(s, 1);
    t0 = now();
    for (k = 0; k < n; ++k) {
        if (rt_step(s, 0.002 * k, u + k * RT_N_INPUTS, g + 3 * k, -1, &o)) return 2;
        checksum += o.compensated[k % 6];
        flagged += o.flags != 0;
    }
    t1 = now();
    for (k = 0; k < n; ++k) {
        rt_calibrate(u + k * RT_N_INPUTS, w);
        checksum += w[k % 6];
    }
    t2 = now();
    updates = (long)s->updates;
    rt_init(s, 1);
    rt_start_identification(s, "tool");
    for (k = 0; k < n; ++k) {
        if (rt_step(s, 0.002 * k, u + k * RT_N_INPUTS, g + 3 * k, -1, &o)) return 2;
        checksum += o.compensated[k % 6];
    }
    t3 = now();
    *saved = *s;
    for (r = 0; r < repeats; ++r) {
        *s = *saved;
        t4 = now();
        status |= rt_finish_identification(s, &fit, &se, 1);
        finish += now() - t4;
        checksum += fit.mass;
    }
    printf("%.9f %.9f %ld %d %.17g %.9f %.9f %d %d %.17g\n", t1 - t0, t2 - t1, updates, flagged, checksum,
           t3 - t2, finish / repeats, fit.n_holds, status, fit.mass);
    return 0;
}
"""


def c_runtime_step(n: int, degree: int) -> dict:
    """ns per ``NAME_step`` (``-O2 -std=c99``) for a 7-input model over ``n`` samples of a 500 Hz recording."""
    from ftcal.live.c_runtime import generate_c_runtime
    from ftcal.payload.parameters import PayloadParameters
    from ftcal.sim.live_scenario import LiveScenario, simulate_live

    from ftcal.core.dataset import Dataset
    from ftcal.core.model import CalibrationModel

    # Six gauges mixing the axes, plus temperature: a model whose wrench is the recording's.
    rng = np.random.default_rng(0)
    mix = np.eye(6) + 0.05 * rng.normal(size=(6, 6))
    wrench = rng.uniform(-40, 40, size=(20_000, 6)) * np.r_[np.ones(3), np.full(3, 0.1)]
    temperature = rng.uniform(20.0, 45.0, size=(20_000, 1))
    model = CalibrationModel(degree).fit(Dataset.from_arrays(np.hstack([wrench @ mix.T, temperature]), wrench))
    rec = simulate_live(LiveScenario(duration=n / 500.0, rate=500.0, contacts=((3.5, 2.0, 10.0),), seed=1))
    tool = LiveScenario().tools["gripper"]
    payload = PayloadParameters(tool.mass, np.asarray(tool.com), np.zeros(3), np.zeros(3), 9.81,
                                fit={"residual_rms": np.r_[np.full(3, 0.05), np.full(3, 0.004)]})
    u = np.column_stack([rec.wrench @ mix.T, np.full(rec.time.size, 30.0)])
    header = generate_c_runtime(model, {"gripper": payload}, name="rt")
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        (folder / "rt.h").write_text(header)
        (folder / "driver.c").write_text(RUNTIME_DRIVER)
        _compile(folder, ["-std=c99", "-O2", "-Wall", "-Werror"], ["driver.c"], "bench")
        text = "\n".join(" ".join(repr(float(v)) for v in np.r_[a, b]) for a, b in zip(u, rec.gravity))
        start = time.perf_counter()
        out = subprocess.run([str(folder / "bench"), str(rec.time.size)], input=text, capture_output=True,
                             text=True, check=True).stdout.split()
        wall = time.perf_counter() - start
    step, calibrate, identifying, finish = float(out[0]), float(out[1]), float(out[5]), float(out[6])
    if int(out[8]) != 0:
        raise RuntimeError(f"rt_finish_identification returned {out[8]} on the benchmark's holds")
    return {"seconds": wall, "cpu_seconds": step + calibrate + identifying + 20 * finish,
            "step_ns": step / rec.time.size * 1e9, "calibrate_ns": calibrate / rec.time.size * 1e9,
            "identifying_step_ns": identifying / rec.time.size * 1e9, "finish_us": finish * 1e6,
            "holds": int(out[7]), "identified_mass": float(out[9]), "true_mass": tool.mass,
            "updates": int(out[2]), "flagged": int(out[3])}


CASES = {f.__name__: f for f in (c_batch, c_runtime_step)}
