"""The same text and files on every machine: other OpenBLAS kernels and thread counts.

OpenBLAS picks its kernels by CPU (``OPENBLAS_CORETYPE`` forces one) and splits work by thread
count; both change the rounding of every BLAS and LAPACK call, and LAPACK may return either sign
of an eigenvector. These tests run the product and the numerics-sensitive test files again under a
second kernel that this CPU can execute and with one thread, as a stranger's machine would.
"""

import json
import os
import subprocess
import sys
from functools import cache
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from scipy.spatial.transform import Rotation

FTCAL = str(Path(sys.executable).with_name("ftcal"))
TESTS = Path(__file__).parents[1]

# Kernels to try as "another machine", newest first; AVX-512 kernels (SkylakeX, Cooperlake) die with
# SIGILL on CPUs without it, so each candidate is probed in a child process before use.
CANDIDATE_CORETYPES = ("Haswell", "Sandybridge", "Nehalem")

# The test files whose results depend most on LAPACK (eigen-decompositions, null spaces, selection ties).
NUMERICS_SENSITIVE = ("test_payload_undetermined.py", "test_excitation.py", "test_solvers.py",
                      "test_statistics.py", "test_payload_identify.py")


def _kernel(env: dict) -> str | None:
    """The OpenBLAS kernel a child process runs under ``env``, or None when it cannot run it."""
    probe = ("import numpy as np, threadpoolctl; a = np.random.default_rng(0).random((64, 64)); "
             "np.linalg.eigh(a + a.T); print(threadpoolctl.threadpool_info()[0].get('architecture', ''))")
    done = subprocess.run([sys.executable, "-c", probe], env=env, capture_output=True, text=True, timeout=120)
    return done.stdout.strip() if done.returncode == 0 else None


@cache
def other_machine() -> dict | None:
    """An environment whose OpenBLAS kernel differs from this process's default, with one thread."""
    base = {k: v for k, v in os.environ.items() if not k.startswith("OPENBLAS_")}
    default = _kernel(base)
    for coretype in CANDIDATE_CORETYPES:
        env = dict(base, OPENBLAS_CORETYPE=coretype, OPENBLAS_NUM_THREADS="1", OMP_NUM_THREADS="1")
        kernel = _kernel(env)
        if kernel and kernel != default:
            return env
    return None


def _needs_other_machine() -> dict:
    env = other_machine()
    if env is None:
        pytest.skip("this CPU runs no second OpenBLAS kernel")
    return env


def _undetermined_table(path: Path) -> None:
    """Tool down and on its side only: one undetermined COM direction, (1, 0, −1)/√2, whose sign is LAPACK's."""
    rng = np.random.default_rng(5)
    g = 9.81
    mass, com, bias = 1.3, np.array([0.012, -0.025, 0.071]), np.array([3.0, -2.0, 5.0, 0.1, -0.2, 0.05])
    turns = Rotation.from_euler("y", np.tile([0.0, 90.0], 6)[:, None], degrees=True)
    rotations = Rotation.from_quat(np.repeat(turns.as_quat(), 40, axis=0))
    gravity = rotations.inv().apply([0.0, 0.0, -g])
    wrench = np.c_[mass * gravity, np.cross(com, mass * gravity)] + bias
    wrench += rng.normal(size=wrench.shape) * [0.3, 0.3, 0.3, 0.01, 0.01, 0.01]
    frame = pd.DataFrame(np.c_[rotations.as_quat(), wrench], columns=["qx", "qy", "qz", "qw", *map("u{}".format, range(1, 7))])
    frame["pose"] = np.repeat(np.arange(12), 40)
    frame.to_csv(path, index=False)


def _numbers_and_text(document):
    """Split a JSON document into its strings/structure (compared exactly) and its numbers (compared to rounding)."""
    numbers = []

    def walk(node):
        if isinstance(node, dict):
            return {k: walk(v) for k, v in node.items() if k not in ("sha256", "created")}
        if isinstance(node, list):
            return [walk(v) for v in node]
        if isinstance(node, float):
            numbers.append(node)
            return "<number>"
        return node

    return walk(document), np.array(numbers)


def test_payload_text_and_file_are_the_same_under_another_blas_kernel(tmp_path):
    other = _needs_other_machine()
    data = tmp_path / "poses.csv"
    _undetermined_table(data)
    outputs = {}
    for name, env in (("here", {k: v for k, v in os.environ.items() if not k.startswith("OPENBLAS_")}),
                      ("other", other)):
        out = tmp_path / f"{name}.json"
        done = subprocess.run([FTCAL, "payload", str(data), "--orientation", "qx,qy,qz,qw", "--group-by", "pose",
                               "-o", str(out)], env=env, capture_output=True, text=True, timeout=600)
        assert done.returncode == 0, done.stderr
        text = done.stdout.replace(str(out), "OUT")
        outputs[name] = (text, done.stderr.replace(str(out), "OUT"), json.loads(out.read_text()))
    (text_a, err_a, doc_a), (text_b, err_b, doc_b) = outputs["here"], outputs["other"]
    assert "not determined" in err_a or "confounded" in err_a  # the case really has an undetermined direction
    assert text_a == text_b and err_a == err_b
    shape_a, numbers_a = _numbers_and_text(doc_a)
    shape_b, numbers_b = _numbers_and_text(doc_b)
    assert shape_a == shape_b
    np.testing.assert_allclose(numbers_b, numbers_a, rtol=1e-7, atol=1e-10)


@pytest.mark.slow
def test_numerics_sensitive_tests_pass_under_another_blas_kernel_and_one_thread():
    other = _needs_other_machine()
    files = [str(next(TESTS.rglob(name))) for name in NUMERICS_SENSITIVE]  # in their layer folders
    done = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "-x", *files],
                          env=other, capture_output=True, text=True, timeout=1800, cwd=TESTS.parent)
    assert done.returncode == 0, (f"under OPENBLAS_CORETYPE={other['OPENBLAS_CORETYPE']}, 1 thread:\n"
                                  + done.stdout[-4000:])


def test_mlp_model_file_is_the_same_under_another_blas_kernel(tmp_path):
    # A nonlinear sensor (tests/core/test_mlp.py's truth) the network beats affine on, so the file holds the network.
    # Before: scipy's L-BFGS-B and the BLAS products made weights 0.05 apart and early stopping pick 250
    # against 240 iterations under Haswell and Sandybridge.
    from test_mlp import INPUTS, OUTPUTS, sensor

    other = _needs_other_machine()
    data = sensor(1200, groups=6, noise=0.2)
    frame = pd.DataFrame(np.c_[data.inputs, data.outputs], columns=INPUTS + OUTPUTS)
    frame["case"] = data.groups
    table = tmp_path / "train.csv"
    frame.to_csv(table, index=False, float_format="%.17g")
    outputs = {}
    for name, env in (("here", {k: v for k, v in os.environ.items() if not k.startswith("OPENBLAS_")}),
                      ("other", other)):
        out = tmp_path / f"{name}.json"
        done = subprocess.run([FTCAL, "fit", str(table), "--inputs", ",".join(INPUTS), "--group-by", "case",
                               "--family", "mlp", "--hidden", "12", "--max-iter", "150", "--folds", "3",
                               "-o", str(out)], env=env, capture_output=True, text=True, timeout=900)
        assert done.returncode == 0, done.stderr
        outputs[name] = (done.stdout.replace(str(out), "OUT"), json.loads(out.read_text()))
    (text_a, doc_a), (text_b, doc_b) = outputs["here"], outputs["other"]
    assert doc_a["family"] == "mlp"
    assert text_a == text_b
    # the network's weights, bit for bit; the rest (the affine baseline's scores: BLAS) to rounding
    assert doc_a["parameters"]["layers"] == doc_b["parameters"]["layers"]
    shape_a, numbers_a = _numbers_and_text(doc_a)
    shape_b, numbers_b = _numbers_and_text(doc_b)
    assert shape_a == shape_b
    np.testing.assert_allclose(numbers_b, numbers_a, rtol=1e-9, atol=1e-12)
