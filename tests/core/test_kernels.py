"""The compiled kernels against numpy: predictions, the build itself, and refused arguments."""

import shutil
import sysconfig
from pathlib import Path

import numpy as np
import pytest

from ftcal.core import kernels
from ftcal.core.dataset import Dataset
from ftcal.core.features import MonomialBasis
from ftcal.core.kernels import step_table, use_numpy_kernel
from ftcal.core.model import CalibrationModel

needs_compiled = pytest.mark.skipif(not kernels.compiled_kernel_available(),
                                    reason="the compiled kernels were not built (no C compiler at install)")


def test_the_compiled_kernels_are_built_wherever_a_c_compiler_is():
    headers = Path(sysconfig.get_paths()["include"], "Python.h").exists()
    if shutil.which("cc") is None or not headers:
        pytest.skip("no C compiler or no Python headers: the numpy paths are the expected ones here")
    assert kernels.compiled_kernel_available(), (
        "a C compiler is on PATH but ftcal.core._polynomial was not built; reinstall (pip install -e .) and read "
        "the build log")


@needs_compiled
@pytest.mark.parametrize("nu, degree, ny, n", [(7, 4, 6, 10_001), (7, 5, 6, 999), (3, 2, 1, 37), (2, 3, 2, 8),
                                               (1, 10, 4, 65), (6, 1, 7, 300), (4, 3, 5, 1)])
def test_compiled_predictions_equal_the_terms_times_the_coefficients(rng, nu, degree, ny, n):
    u = rng.uniform(-5, 5, size=(n, nu)) + 100.0  # raw inputs, away from the origin
    basis = MonomialBasis(nu, degree)
    offset, scale = u.mean(axis=0) if n > 1 else u[0] - 1, np.full(nu, 5.0)
    coef_t = rng.normal(size=(ny, basis.n_terms))
    out = np.full((n, ny), np.nan)
    kernels.compiled().predict(u, offset, 1.0 / scale, coef_t, step_table(nu, degree), out)
    expected = basis.evaluate((u - offset) / scale) @ coef_t.T  # numpy, the plain way
    np.testing.assert_allclose(out, expected, rtol=1e-12, atol=1e-12 * np.abs(expected).max())


@needs_compiled
def test_model_predictions_with_either_kernel_agree(rng, make_sensor_data):
    u, y = make_sensor_data(rng, 4000)
    model = CalibrationModel(4).fit(Dataset.from_arrays(u, y))
    compiled = model.predict(u)
    with use_numpy_kernel():
        assert kernels.compiled() is None
        reference = model.predict(u)
        refit = CalibrationModel(4).fit(Dataset.from_arrays(u, y))
    np.testing.assert_allclose(compiled, reference, rtol=1e-11, atol=1e-11 * np.abs(reference).max())
    np.testing.assert_allclose(model.coef_, refit.coef_, rtol=1e-9, atol=1e-9 * np.abs(refit.coef_).max())
    assert model.predict(u[:0]).shape == (0, y.shape[1])


@needs_compiled
def test_the_compiled_prediction_refuses_arguments_that_do_not_fit(rng):
    basis = MonomialBasis(3, 2)
    u, steps = rng.normal(size=(10, 3)), step_table(3, 2)
    coef_t, out = rng.normal(size=(2, basis.n_terms)), np.zeros((10, 2))
    predict = kernels.compiled().predict
    predict(u, np.zeros(3), np.ones(3), coef_t, steps, out)  # accepted
    bad_steps = steps.copy()
    bad_steps[0, 2] = 0  # would overwrite an input row
    for args, message in [((u, np.zeros(2), np.ones(3), coef_t, steps, out), "offset"),
                          ((u, np.zeros(3), np.ones(3), coef_t, steps, np.zeros((9, 2))), "out"),
                          ((u, np.zeros(3), np.ones(3), coef_t, bad_steps, out), "step"),
                          ((u.astype(np.float32), np.zeros(3), np.ones(3), coef_t, steps, out), "u"),
                          ((u, np.zeros(3), np.ones(3), np.ascontiguousarray(coef_t[:, :1]), steps, out), "coef"),
                          ((u, np.zeros(3), np.ones(3), coef_t[:, ::2], steps, out), "coef: .*C-contiguous")]:
        with pytest.raises(ValueError, match=message):
            predict(*args)
    read_only = np.zeros((10, 2))
    read_only.setflags(write=False)
    with pytest.raises(ValueError, match="out: .*read-only"):
        predict(u, np.zeros(3), np.ones(3), coef_t, steps, read_only)
