"""What a static fit no longer computes twice (issue 32, item 4): the inputs' spread from the statistics'
moments, and the allocator settings of the ``ftcal fit`` process.

References: numpy's mean and ``np.cov(bias=True)`` over the raw inputs as pandas/pyarrow read them (the
direct two-pass computation), and glibc's own account of its heap (``mallinfo2``) in a fresh process.
"""

import os
import subprocess
import sys
import textwrap

import numpy as np
import pandas as pd
import pytest
from conftest import sensor_like_data

import ftcal.data.streaming as streaming
from ftcal.core.dataset import DEFAULT_OUTPUTS
from ftcal.core.excitation import Spread
from ftcal.core.features import MonomialBasis, RegressorLayout
from ftcal.core.normalization import normalization_from_range
from ftcal.core.statistics import StatisticsAccumulator, input_spread
from ftcal.files.model_files import load_model_file
from ftcal.workflow.fitting import fit

INPUTS = ("u1", "u2", "u3", "u4", "u5", "u6", "T")


def direct(u):
    """Mean and covariance (divided by N) of the rows of ``u``, computed from the centred data."""
    return u.mean(axis=0), np.cov(u.T, bias=True)


def moments_spread(u, y, degree, mode="center", chunk=4096):
    norm = normalization_from_range(u.min(axis=0), u.max(axis=0), mode)
    basis = MonomialBasis(u.shape[1], degree)
    total = StatisticsAccumulator(RegressorLayout(basis, y.shape[1]), norm)
    for start in range(0, len(u), chunk):
        total.add(u[start:start + chunk], y[start:start + chunk])
    return input_spread(total.statistics(), basis, norm)


def skewed(rng, n):
    """A channel at one value but for 5 samples (a temperature that barely moves) beside ADC-like counts."""
    u, y = sensor_like_data(rng, n)
    u[:, -1] = 35.0
    u[rng.choice(n, 5, replace=False), -1] = 35.5
    return u, y


@pytest.mark.parametrize("make", [sensor_like_data, skewed])
@pytest.mark.parametrize("degree", [1, 3])
def test_input_spread_from_the_moments_equals_the_direct_computation(make, degree):
    u, y = make(np.random.default_rng(3), 20_000)
    spread = moments_spread(u, y, degree)
    mean, covariance = direct(u)
    assert spread.n == len(u)
    np.testing.assert_allclose(spread.mean, mean, rtol=1e-13)
    scale = np.sqrt(np.outer(np.diag(covariance), np.diag(covariance)))  # relative to the variances
    assert np.max(np.abs(spread.covariance - covariance) / scale) < 1e-10


def test_a_basis_that_does_not_centre_refuses_and_the_fit_reads_the_inputs_instead(tmp_path, monkeypatch):
    """Counts of 10⁶ ± 1 in the paper's max-abs basis: ū_n² / var(u_n) ~ 10¹², the moments would lose 12
    digits. input_spread says so (None), and the streamed ridge fit in that basis takes the spread from
    the data."""
    rng = np.random.default_rng(5)
    u = 1e6 + rng.uniform(-1.0, 1.0, (6000, 2))
    y = np.c_[u[:, 0] - 1e6, u[:, 1] - 1e6]
    assert moments_spread(u, y, 1, mode="maxabs") is None
    assert moments_spread(u, y, 1, mode="center") is not None  # the same data centred: within the bound
    path = tmp_path / "offset.csv"
    pd.DataFrame(np.c_[u, y], columns=["a", "b", "Fx", "Fy"]).to_csv(path, index=False, float_format="%.17g")
    passes = []
    original = streaming.file_input_spread
    monkeypatch.setattr(streaming, "file_input_spread", lambda *a: passes.append(a) or original(*a))
    fit([str(path)], inputs=("a", "b"), outputs=("Fx", "Fy"), degree=1, ridge=1e-6, normalization="maxabs",
        output=tmp_path / "m.json")
    assert len(passes) == 1
    spread = load_model_file(tmp_path / "m.json").model.input_spread_
    read = pd.read_csv(path)[["a", "b"]].to_numpy()
    mean, covariance = direct(read)
    np.testing.assert_allclose(spread.mean, mean, rtol=1e-14)
    np.testing.assert_allclose(spread.covariance, covariance, rtol=1e-10)


@pytest.mark.parametrize("suffix", ["csv", "parquet"])
def test_a_streamed_fit_stores_the_spread_of_its_training_inputs(tmp_path, suffix):
    """CSV (two passes over the chunks kept in memory) and Parquet (one read, normalized by the footers)."""
    u, y = sensor_like_data(np.random.default_rng(11), 30_000)
    frame = pd.DataFrame(np.c_[u, y], columns=[*INPUTS, *DEFAULT_OUTPUTS])
    path = tmp_path / f"t.{suffix}"
    if suffix == "csv":
        frame.to_csv(path, index=False, float_format="%.17g")
    else:
        frame.to_parquet(path, row_group_size=7000)
    fit([str(path)], degree=4, output=tmp_path / "m.json")
    spread = load_model_file(tmp_path / "m.json").model.input_spread_
    mean, covariance = direct(u)
    np.testing.assert_allclose(spread.mean, mean, rtol=1e-13)
    np.testing.assert_allclose(spread.covariance, covariance, rtol=1e-10)
    assert isinstance(spread, Spread) and spread.n == len(u)


ALLOCATOR_PROBE = textwrap.dedent("""
    import ctypes, sys
    import numpy as np
    from ftcal.runtime.allocator import keep_freed_memory

    class Mallinfo2(ctypes.Structure):
        _fields_ = [(name, ctypes.c_size_t) for name in ("arena", "ordblks", "smblks", "hblks", "hblkhd",
                                                          "usmblks", "fsmblks", "uordblks", "fordblks", "keepcost")]

    mallinfo2 = ctypes.CDLL(None).mallinfo2
    mallinfo2.restype = Mallinfo2
    if sys.argv[1] == "set":
        assert keep_freed_memory()
    before = mallinfo2()
    block = np.ones(16 << 20, dtype=np.uint8)
    during = mallinfo2()
    del block
    after = mallinfo2()
    import pyarrow
    print(during.hblkhd - before.hblkhd, during.arena - after.arena, pyarrow.default_memory_pool().backend_name)
""")


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="glibc's allocator")
def test_the_fit_command_keeps_large_temporaries_on_a_heap_it_keeps():
    """In a fresh process, glibc maps a 16 MiB block for itself and unmaps it when freed (every statistics
    chunk would fault its pages in again); after keep_freed_memory() it comes from the heap, which keeps it,
    and pyarrow's buffers leave mimalloc (which returns freed pages to the system after 10 ms)."""
    # glibc's defaults: a local Dask cluster started earlier in this process leaves its workers' MALLOC_* here
    fresh = {k: v for k, v in os.environ.items() if not k.startswith("MALLOC_")}

    def probe(mode):
        done = subprocess.run([sys.executable, "-c", ALLOCATOR_PROBE, mode], capture_output=True, text=True,
                              check=True, env=fresh)
        mapped, trimmed, pool = done.stdout.split()
        return int(mapped), int(trimmed), pool

    mapped, _, pool = probe("default")
    assert mapped >= 16 << 20 and pool == "mimalloc"
    mapped, trimmed, pool = probe("set")
    assert mapped == 0 and trimmed == 0 and pool in ("jemalloc", "system")


def test_the_fit_command_collects_cycles_less_often_but_still_collects_them():
    """collect_less() in a fresh process: a later cycle of garbage is still freed (by a full collection, or
    by the raised threshold's own), and what was loaded before is in the permanent generation."""
    code = textwrap.dedent("""
        import gc, weakref
        from ftcal.runtime.allocator import COMMAND_GC_THRESHOLD, collect_less
        collect_less()
        assert gc.get_freeze_count() > 0 and gc.get_threshold()[0] == COMMAND_GC_THRESHOLD

        class Node:
            pass

        a, b = Node(), Node()
        a.other, b.other = b, a
        gone = weakref.ref(a)
        del a, b
        alive = [[] for _ in range(2 * COMMAND_GC_THRESHOLD)]  # containers kept: the youngest generation's count
        print(gone() is None)
    """)
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert done.stdout.split() == ["True"]
