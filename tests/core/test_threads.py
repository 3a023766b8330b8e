"""One thread-control point: every BLAS loaded (NumPy's and SciPy's own OpenBLAS) runs one thread
inside the search's worker threads, whatever was imported first, and gets its threads back after."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

SRC = str(Path(__file__).resolve().parents[2] / "src")

# A fresh interpreter: SciPy must not be imported before the search (the case the limit used to miss),
# and the BLAS pools start at their default size.
SEARCH_IN_A_FRESH_PROCESS = textwrap.dedent("""
    import json, sys, threading
    import numpy as np
    assert "scipy" not in sys.modules
    from threadpoolctl import threadpool_info
    from ftcal.core.dataset import Dataset
    from ftcal.core import select
    from ftcal.core.solvers import lasso

    seen = []
    original_fit_path = lasso.Lasso.fit_path

    def spy(self, problem, lams, **kwargs):
        # Called inside the fold workers: look at the BLAS pools from there, while the solver runs.
        def inside(*args, **kw):
            seen.append({"thread": threading.current_thread().name,
                         "blas": [(i["filepath"], i["num_threads"]) for i in threadpool_info()
                                  if i["user_api"] == "blas"]})
            return original_solve(*args, **kw)
        original_solve = lasso._homotopy
        lasso._homotopy = inside
        try:
            return original_fit_path(self, problem, lams, **kwargs)
        finally:
            lasso._homotopy = original_solve

    lasso.Lasso.fit_path = spy
    rng = np.random.default_rng(0)
    u = rng.uniform(-1, 1, (3000, 3))
    y = np.c_[u @ [1.0, 2.0, 3.0] + 0.5 * u[:, 0] ** 2, u[:, 1] - u[:, 2] * u[:, 0]]
    y = y + 0.01 * rng.standard_normal(y.shape)
    data = Dataset.from_arrays(u, y, groups=np.repeat(np.arange(10), 300))
    select.select_model(data, degrees=(1, 2), penalties=("lasso",), n_folds=5)
    after = [(i["filepath"], i["num_threads"]) for i in threadpool_info() if i["user_api"] == "blas"]
    print(json.dumps({"seen": seen, "after": after}))
""")


def test_every_blas_runs_one_thread_inside_the_search_workers_and_is_restored_after():
    env = {k: v for k, v in os.environ.items() if not k.endswith("_NUM_THREADS")}
    env.update(PYTHONPATH=SRC, FTCAL_THREADS="2", OPENBLAS_NUM_THREADS="2", FTCAL_PROGRESS="0")
    done = subprocess.run([sys.executable, "-c", SEARCH_IN_A_FRESH_PROCESS], env=env, capture_output=True,
                          text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    report = json.loads(done.stdout.strip().splitlines()[-1])
    after = dict(report["after"])
    if max(after.values()) < 2:
        pytest.skip("OpenBLAS runs one thread here anyway (one usable core): nothing to limit")
    seen = report["seen"]
    assert seen, "the search never reached the solver"
    # The solver ran in the fold workers, not in the main thread.
    assert any(entry["thread"] != "MainThread" for entry in seen)
    for entry in seen:
        libraries = dict(entry["blas"])
        # Every library of the process (SciPy's own OpenBLAS included: the solver uses SciPy) is loaded
        # there already, and each is at one thread.
        assert set(libraries) == set(after), (libraries, after)
        assert set(libraries.values()) == {1}, libraries
    # Back to their default afterwards (OPENBLAS_NUM_THREADS=2 above): the limit is the block's only.
    assert set(after.values()) == {2}, after
