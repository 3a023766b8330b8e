"""Generated C, compiled with the system compiler, against CalibrationModel.predict."""

from __future__ import annotations

import hashlib
import re
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from ftcal.cli import main
from ftcal.core.dataset import Dataset
from ftcal.core.model import CalibrationModel
from ftcal.core.solvers import Lasso
from ftcal.files.c_code import evaluate_like_c, generate_c
from ftcal.files.model_files import save_model
from ftcal.runtime.errors import FtcalError

CC = shutil.which("cc")
needs_cc = pytest.mark.skipif(CC is None, reason="no system C compiler `cc` on PATH to compile the generated code")
STRICT = ["-std=c99", "-Wall", "-Wextra", "-Werror", "-pedantic"]
INPUTS = ("u1", "u2", "u3", "u4", "u5", "u6", "T")

STATIC_DRIVER = r"""
#include <stdio.h>
#include "NAME.h"
int main(void)
{
    REAL u[NAMEU_N_INPUTS], y[NAMEU_N_OUTPUTS];
    double v;
    int i;
    for (;;) {
        for (i = 0; i < NAMEU_N_INPUTS; ++i) {
            if (scanf("%lf", &v) != 1) return 0;
            u[i] = (REAL)v;
        }
        NAME_predict(u, y);
        for (i = 0; i < NAMEU_N_OUTPUTS; ++i) printf("%.17g ", (double)y[i]);
        printf("%d\n", NAME_in_range(u));
    }
}
"""

ARX_DRIVER = r"""
#include <stdio.h>
#include <stdlib.h>
#include "NAME.h"
int main(int argc, char **argv)
{
    static double u[100000][NAMEU_N_INPUTS];
    double y0[NAMEU_N_OUTPUTS], y[NAMEU_N_OUTPUTS];
    NAME_state s;
    int n = 0, i, k;
    (void)argv;
    if (argc > 1)  /* measured first output given before the inputs */
        for (i = 0; i < NAMEU_N_OUTPUTS; ++i) if (scanf("%lf", &y0[i]) != 1) return 1;
    while (n < 100000) {
        for (i = 0; i < NAMEU_N_INPUTS; ++i) if (scanf("%lf", &u[n][i]) != 1) goto done;
        ++n;
    }
done:
    NAME_init(&s, u[0], argc > 1 ? y0 : NULL);
    for (k = 0; k < n; ++k) {
        NAME_step(&s, u[k], y);
        for (i = 0; i < NAMEU_N_OUTPUTS; ++i) printf("%.17g ", y[i]);
        printf("\n");
    }
    return 0;
}
"""


def sensor_data(n=600, seed=0, segments=None):
    """A nonlinear sensor: raw channels with large offsets (like ADC counts) and temperature."""
    rng = np.random.default_rng(seed)
    w = rng.uniform(-1, 1, (n, 6))
    t = rng.uniform(25, 45, n)
    u = np.column_stack([5000 + 3000 * w + 40 * w ** 2 + 2 * (t - 35)[:, None], t])
    y = np.column_stack([80 * w[:, :3] + 3 * w[:, :3] ** 3, 6 * w[:, 3:] + 0.4 * w[:, 3:] * w[:, :3]]) \
        + 0.05 * (t - 35)[:, None]
    return u, y


def build(tmp_path: Path, model: CalibrationModel, name: str, *, single=False, arx=False) -> Path:
    code = generate_c(model, name=name, single_precision=single)
    (tmp_path / f"{name}.h").write_text(code.header)
    (tmp_path / f"{name}.c").write_text(code.source)
    driver = (ARX_DRIVER if arx else STATIC_DRIVER).replace("NAMEU", name.upper()).replace("NAME", name)
    driver = driver.replace("REAL", "float" if single else "double")
    (tmp_path / "driver.c").write_text(driver)
    exe = tmp_path / f"{name}.exe"
    # Library warnings flags on the generated file; the driver (scanf) only needs to compile.
    subprocess.run([CC, *STRICT, "-O2", "-c", f"{name}.c", "-o", f"{name}.o"], cwd=tmp_path, check=True,
                   capture_output=True, text=True)
    subprocess.run([CC, "-std=c99", "-O2", "driver.c", f"{name}.o", "-o", exe.name], cwd=tmp_path, check=True,
                   capture_output=True, text=True)
    return exe


def run_exe(exe: Path, u: np.ndarray, first: list[str] | None = None, args=()) -> np.ndarray:
    text = "\n".join(" ".join(repr(float(v)) for v in row) for row in u) + "\n"
    if first is not None:
        text = " ".join(first) + "\n" + text
    out = subprocess.run([str(exe), *args], input=text, capture_output=True, text=True, check=True).stdout
    return np.array([[float(v) for v in line.split()] for line in out.strip().splitlines()])


def assert_relative(actual, expected, rtol=1e-12):
    """Per output, relative to that output's largest magnitude (sums of signed terms cancel)."""
    scale = np.max(np.abs(expected), axis=0)
    assert np.all(np.abs(actual - expected) <= rtol * scale), np.max(np.abs(actual - expected) / scale)


def test_names_that_are_not_c_identifiers_are_refused():
    u, y = sensor_data(100)
    model = CalibrationModel(1).fit(u, y)
    with pytest.raises(FtcalError, match="not a C identifier"):
        generate_c(model, name="2fast")
    with pytest.raises(FtcalError, match="not a C identifier"):
        generate_c(model, name="double")


@needs_cc
@pytest.mark.parametrize("degree", [1, 2, 3, 4, 5])
def test_static_code_matches_predict(tmp_path, degree):
    u, y = sensor_data(900, seed=degree)
    model = CalibrationModel(degree).fit(u, y)
    exe = build(tmp_path, model, f"np{degree}")
    u_test, _ = sensor_data(300, seed=100 + degree)
    out = run_exe(exe, u_test)
    assert_relative(out[:, :6], model.predict(u_test, warn_out_of_range=False))
    np.testing.assert_array_equal(out[:, 6] == 1, ~model.out_of_range(u_test))


@needs_cc
def test_in_range_uses_the_training_box(tmp_path):
    u, y = sensor_data(400)
    model = CalibrationModel(2).fit(u, y)
    exe = build(tmp_path, model, "box")
    low, high = u.min(axis=0), u.max(axis=0)
    inside = (low + high) / 2
    hot, cold = inside.copy(), inside.copy()
    hot[6] = high[6] + 1.0
    cold[0] = low[0] - 1.0
    probes = np.array([inside, low, high, hot, cold])
    flags = run_exe(exe, probes)[:, 6]
    np.testing.assert_array_equal(flags, [1, 1, 1, 0, 0])


@needs_cc
def test_lasso_exact_zeros_emit_no_code(tmp_path):
    u, y = sensor_data(900, seed=7)
    model = CalibrationModel(3, solver=Lasso(20.0)).fit(u, y)
    n_zero = int(np.sum(model.coef_ == 0))
    assert n_zero > model.coef_.size // 4  # the λ gives many exact zeros
    code = generate_c(model, name="sparse")
    accumulations = [line for line in code.source.splitlines() if re.match(r"    a\d+_\d \+= ", line)]
    assert len(accumulations) == np.count_nonzero(model.coef_)
    # The batch loop's table holds one row per monomial with a nonzero coefficient (the offset aside).
    rows = re.search(r"sparse_batch_row\[(\d+)\]", code.source)
    assert int(rows.group(1)) == np.count_nonzero(np.any(model.coef_[:-1] != 0.0, axis=1))
    exe = build(tmp_path, model, "sparse")
    u_test, _ = sensor_data(200, seed=8)
    assert_relative(run_exe(exe, u_test)[:, :6], model.predict(u_test, warn_out_of_range=False))


def arx_data(n=1200, seed=3):
    u, y = sensor_data(n, seed)
    # A first-order lag in the output, so the ARX terms matter.
    for k in range(1, n):
        y[k] += 0.3 * (y[k - 1] - y[k])
    segments = np.repeat([0, 1], [n // 2, n - n // 2])
    return Dataset.from_arrays(u, y, input_names=INPUTS, output_names=("Fx", "Fy", "Fz", "Tx", "Ty", "Tz"),
                               segments=segments)


@needs_cc
@pytest.mark.parametrize("degree, na, nb", [(2, 1, 1), (1, 2, 0), (2, 0, 2), (3, 2, 1)])
def test_arx_free_run_matches_predict(tmp_path, degree, na, nb):
    data = arx_data()
    model = CalibrationModel(degree, na=na, nb=nb).fit(data)
    exe = build(tmp_path, model, "arx", arx=True)
    test = arx_data(300, seed=9).subset(np.arange(300) < 150)  # one segment
    # Steady-state start (no measured outputs) and measured first output.
    no_outputs = Dataset.from_arrays(test.inputs, None, input_names=INPUTS)
    # The generated code implements ftcal's free-run start ("measured"), not the paper's zeros.
    expected_steady = model.predict(no_outputs, start="measured", warn_out_of_range=False)
    expected_measured = model.predict(test, start="measured", warn_out_of_range=False)
    assert_relative(run_exe(exe, test.inputs), expected_steady)
    first = [repr(float(v)) for v in test.outputs[0]]
    assert_relative(run_exe(exe, test.inputs, first, args=("measured",)), expected_measured)


@needs_cc
def test_single_precision_compiles_and_matches_its_emulation(tmp_path):
    u, y = sensor_data(900, seed=4)
    model = CalibrationModel(4).fit(u, y)
    exe = build(tmp_path, model, "single", single=True)
    u_test, _ = sensor_data(200, seed=5)
    out = run_exe(exe, u_test)[:, :6]
    # The numpy float32 emulation performs the same IEEE single operations in the same order.
    emulated = evaluate_like_c(model, u_test, single_precision=True).astype(np.float64)
    np.testing.assert_array_equal(out, emulated)
    # Single precision of inputs near 5000 counts: a few 1e-4 of the output range, not more.
    exact = model.predict(u_test, warn_out_of_range=False)
    assert np.max(np.abs(out - exact) / np.ptp(exact, axis=0)) < 1e-3


@needs_cc
def test_cli_writes_both_files_and_reports_float_error(tmp_path, capsys):
    u, y = sensor_data(600)
    model = CalibrationModel(2).fit(u, y)
    path = tmp_path / "m.json"
    save_model(model, path, input_units=["count"] * 6 + ["degC"], output_units=["N"] * 3 + ["Nm"] * 3)
    out_dir = tmp_path / "gen" / "c"
    assert main(["convert", str(path), "--to", "c", "--name", "arm_ft", "-o", str(out_dir)]) == 0
    assert sorted(p.name for p in out_dir.iterdir()) == ["arm_ft.c", "arm_ft.h"]
    header = (out_dir / "arm_ft.h").read_text()
    assert hashlib.sha256(path.read_bytes()).hexdigest() in header
    assert "u1 [count]" in header and "Tz [Nm]" in header and "#define ARM_FT_N_INPUTS 7" in header
    subprocess.run([CC, *STRICT, "-c", "arm_ft.c"], cwd=out_dir, check=True)
    # C++ users include the header as is.
    if shutil.which("c++"):
        (out_dir / "use.cpp").write_text('#include "arm_ft.h"\nint main() { double u[7] = {0}, y[6];'
                                         ' arm_ft_predict(u, y); return 0; }\n')
        subprocess.run(["c++", "-Wall", "-Werror", "-c", "use.cpp"], cwd=out_dir, check=True)
    capsys.readouterr()
    assert main(["convert", str(path), "--to", "c", "--float", "-o", str(tmp_path / "f")]) == 0
    printed = capsys.readouterr().out
    assert "single precision: largest |float - double|" in printed
    assert sorted(p.name for p in (tmp_path / "f").iterdir()) == ["ftcal_model.c", "ftcal_model.h"]


def test_cli_refusals_write_nothing(tmp_path, capsys):
    u, y = sensor_data(300)
    path = tmp_path / "m.json"
    save_model(CalibrationModel(1).fit(u, y), path)
    blocker = tmp_path / "file.txt"
    blocker.write_text("x")
    arx = tmp_path / "arx.json"
    save_model(CalibrationModel(1, na=1).fit(arx_data()), arx)
    cases = [(["convert", path, "--to", "c", "-o", blocker], "is a file"),
             (["convert", path, "--to", "c", "--name", "9lives", "-o", tmp_path / "o"], "not a C identifier"),
             (["convert", path, "--to", "fortran", "-o", tmp_path / "o"], "unknown target"),
             (["convert", arx, "--to", "c", "--float", "-o", tmp_path / "o"], "--float is for static models")]
    for argv, fragment in cases:
        assert main([str(a) for a in argv]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and fragment in err[0], err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["arx.json", "file.txt", "m.json"]


def test_non_finite_coefficients_are_refused():
    u, y = sensor_data(300)
    model = CalibrationModel(1).fit(u, y)
    model.coef_[2, 1] = np.inf
    with pytest.raises(FtcalError, match="not all finite"):
        generate_c(model)


def test_code_is_self_contained_with_one_multiply_per_monomial():
    u, y = sensor_data(900)
    model = CalibrationModel(4).fit(u, y)
    code = generate_c(model, name="fold")
    includes = [line for line in (code.source + code.header).splitlines() if line.startswith("#include")]
    assert includes == ['#include "fold.h"']
    assert not any(word in code.source for word in ("malloc", "calloc", "static double"))
    # C(7+4, 4) − 1 = 329 monomials; the 7 inputs are normalized, each other one is a single product.
    products = re.findall(r"^    m\[(\d+)\] = m\[(\d+)\] \* m\[(\d+)\];$", code.source, flags=re.M)
    assert [int(t) for t, _, _ in products] == list(range(7, 329))


BATCH_DRIVER = r"""
#include <stdio.h>
#include "NAME.h"
static REAL u[4096][NAMEU_N_INPUTS], y[4096][NAMEU_N_OUTPUTS];
int main(void)
{
    double v;
    int n = 0, i, k;
    while (n < 4096) {
        for (i = 0; i < NAMEU_N_INPUTS; ++i) {
            if (scanf("%lf", &v) != 1) goto done;
            u[n][i] = (REAL)v;
        }
        ++n;
    }
done:
    NAME_predict_batch(n, &u[0][0], &y[0][0]);
    for (k = 0; k < n; ++k) {
        for (i = 0; i < NAMEU_N_OUTPUTS; ++i) printf("%.17g ", (double)y[k][i]);
        printf("\n");
    }
    return 0;
}
"""


@needs_cc
@pytest.mark.parametrize("degree, n, single", [(2, 301, False), (4, 97, False), (3, 5, True)])
def test_batch_entry_point_matches_predict(tmp_path, degree, n, single):
    """Blocks of 8 with a partial last block (301 = 37·8 + 5, 97 = 12·8 + 1, 5 < 8)."""
    u, y = sensor_data(900, seed=degree)
    model = CalibrationModel(degree).fit(u, y)
    name = f"b{degree}"
    code = generate_c(model, name=name, single_precision=single)
    (tmp_path / f"{name}.h").write_text(code.header)
    (tmp_path / f"{name}.c").write_text(code.source)
    driver = BATCH_DRIVER.replace("NAMEU", name.upper()).replace("NAME", name)
    (tmp_path / "driver.c").write_text(driver.replace("REAL", "float" if single else "double"))
    subprocess.run([CC, *STRICT, "-O2", "-c", f"{name}.c"], cwd=tmp_path, check=True, capture_output=True)
    subprocess.run([CC, "-std=c99", "-O2", "driver.c", f"{name}.o", "-o", "batch"], cwd=tmp_path, check=True,
                   capture_output=True)
    u_test, _ = sensor_data(n, seed=200 + degree)
    out = run_exe(tmp_path / "batch", u_test)
    assert out.shape == (n, 6)
    if single:  # the batch loop does the float evaluator's operations, summed in another order
        assert_relative(out, evaluate_like_c(model, u_test, single_precision=True).astype(float), rtol=1e-5)
    else:
        assert_relative(out, model.predict(u_test, warn_out_of_range=False))
    # Leaving the batch evaluator out still compiles (firmware that only needs predict).
    subprocess.run([CC, *STRICT, "-O2", f"-D{name.upper()}_NO_BATCH", "-c", f"{name}.c"], cwd=tmp_path,
                   check=True, capture_output=True)
