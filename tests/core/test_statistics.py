"""Sufficient statistics against AᵀA, AᵀB built explicitly with numpy."""

from contextlib import nullcontext

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from ftcal.core import kernels
from ftcal.core.dataset import Dataset
from ftcal.core.features import MonomialBasis, RegressorLayout
from ftcal.core.kernels import use_numpy_kernel
from ftcal.core.model import CalibrationModel
from ftcal.core.normalization import Normalization
from ftcal.core.statistics import (
    SufficientStatistics,
    dense_statistics,
    layout_statistics,
    moment_plan,
    static_statistics,
    sum_statistics,
)


@pytest.fixture(params=["compiled", "numpy"])
def kernel(request):
    """Run the test with each statistics kernel (the compiled one where it was built)."""
    if request.param == "compiled" and not kernels.compiled_kernel_available():
        pytest.skip("the compiled statistics kernel was not built (no C compiler at install)")
    with use_numpy_kernel() if request.param == "numpy" else nullcontext():
        yield request.param


def _assert_stats_equal(stats, a, y):
    gram = a.T @ a
    np.testing.assert_allclose(stats.gram, gram, rtol=1e-12, atol=1e-12 * np.abs(gram).max())
    cross = a.T @ y
    np.testing.assert_allclose(stats.cross, cross, rtol=1e-12, atol=1e-12 * np.abs(cross).max())
    np.testing.assert_allclose(stats.target_sq, (y**2).sum(axis=0), rtol=1e-12)
    np.testing.assert_allclose(stats.target_sum, y.sum(axis=0), rtol=1e-12, atol=1e-12)
    np.testing.assert_array_equal(stats.column_maxabs, np.abs(a).max(axis=0))
    assert stats.n_samples == a.shape[0]


@pytest.mark.parametrize("nu, degree", [(1, 1), (1, 5), (2, 3), (3, 4), (4, 5), (7, 3), (8, 2), (8, 3)])
def test_moment_statistics_equal_explicit_products(rng, ref_features, kernel, nu, degree):
    u = rng.uniform(-1, 1, size=(700, nu))
    y = rng.normal(size=(700, 3))
    # chunk=128 leaves a partial last chunk (700 = 5·128 + 60)
    stats = static_statistics(MonomialBasis(nu, degree), u, y, chunk=128)
    _assert_stats_equal(stats, ref_features(u, degree), y)


def test_moment_statistics_of_a_single_sample_and_default_chunk(rng, ref_features, kernel):
    basis = MonomialBasis(3, 3)
    u1 = rng.uniform(-1, 1, size=(1, 3))
    _assert_stats_equal(static_statistics(basis, u1, np.ones((1, 1))), ref_features(u1, 3), np.ones((1, 1)))
    u = rng.uniform(-1, 1, size=(2500, 3))  # more than the default chunk
    y = rng.normal(size=(2500, 2))
    _assert_stats_equal(static_statistics(basis, u, y), ref_features(u, 3), y)


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(nu=st.integers(1, 8), degree=st.integers(1, 4), n=st.integers(1, 60), seed=st.integers(0, 2**31))
def test_moment_statistics_property(ref_features, kernel, nu, degree, n, seed):
    r = np.random.default_rng(seed)
    u = r.uniform(-1.5, 1.5, size=(n, nu))
    y = r.normal(size=(n, 1))
    stats = static_statistics(MonomialBasis(nu, degree), u, y, chunk=16)
    _assert_stats_equal(stats, ref_features(u, degree), y)


def test_statistics_add_up_across_chunks(rng, ref_features, kernel):
    u = rng.uniform(-1, 1, size=(900, 4))
    y = rng.normal(size=(900, 2))
    basis = MonomialBasis(4, 3)
    parts = [static_statistics(basis, u[a:b], y[a:b]) for a, b in [(0, 1), (1, 400), (400, 401), (401, 900)]]
    total = sum_statistics(parts)
    _assert_stats_equal(total, ref_features(u, 3), y)
    assert isinstance(parts[0] + parts[1], SufficientStatistics)


@pytest.mark.parametrize("nu, degree, n", [(7, 4, 5003), (7, 5, 700), (2, 10, 300), (6, 1, 999)])
def test_both_kernels_give_the_same_statistics(rng, nu, degree, n):
    if not kernels.compiled_kernel_available():
        pytest.skip("the compiled statistics kernel was not built (no C compiler at install)")
    # Tiles of the compiled kernel and chunks of numpy's differ, and n is no multiple of either.
    u, y = rng.uniform(-1, 1, size=(n, nu)), rng.normal(size=(n, 6))
    basis = MonomialBasis(nu, degree)
    compiled = static_statistics(basis, u, y)
    with use_numpy_kernel():
        reference = static_statistics(basis, u, y)
    for name in ("gram", "cross", "target_sq", "target_sum"):
        expected = getattr(reference, name)
        np.testing.assert_allclose(getattr(compiled, name), expected, rtol=1e-12,
                                   atol=1e-12 * np.abs(expected).max(), err_msg=name)
    np.testing.assert_array_equal(compiled.column_maxabs, reference.column_maxabs)
    assert compiled.n_samples == reference.n_samples == n


def test_the_compiled_kernel_refuses_tables_outside_its_buffers(rng):
    if not kernels.compiled_kernel_available():
        pytest.skip("the compiled statistics kernel was not built (no C compiler at install)")
    from ftcal.core import _polynomial

    plan = moment_plan(3, 2)
    p = plan.basis.n_terms
    u, y = rng.uniform(-1, 1, size=(10, 3)), rng.normal(size=(10, 2))

    def run(steps=plan.steps, blocks=plan.blocks, columns=plan.columns, moments=None, u=u, cross=None):
        moments = plan.new_moments() if moments is None else moments
        cross = np.zeros((p, 2)) if cross is None else cross
        _polynomial.accumulate(u, y, p, steps, blocks, columns, moments, cross, np.zeros(p))

    run()  # the plan itself is accepted
    bad_step = plan.steps.copy()
    bad_step[0, 1] = p  # a source row past the terms
    bad_block = plan.blocks.copy()
    bad_block[-1, 3] = plan.n_moments  # moments written past the end
    bad_column = plan.columns.copy()
    bad_column[0] = -1
    for kwargs, message in [(dict(steps=bad_step), "step"), (dict(blocks=bad_block), "block"),
                            (dict(columns=bad_column), "column"), (dict(moments=np.zeros(3)), "moments"),
                            (dict(u=u.astype(np.float32)), "u"), (dict(cross=np.zeros((p, 1))), "cross")]:
        with pytest.raises(ValueError, match=message):
            run(**kwargs)


def test_dense_statistics_add_up_across_splits(rng):
    a = rng.normal(size=(50, 5)) * np.array([1, 10, 0.1, 3, 1])
    y = rng.normal(size=(50, 2))
    total = dense_statistics(a[:20], y[:20]) + dense_statistics(a[20:], y[20:])
    _assert_stats_equal(total, a, y)
    # Empty block is neutral.
    _assert_stats_equal(dense_statistics(a[:0], y[:0]) + dense_statistics(a, y), a, y)


def test_restrict_to_lower_degree_equals_lower_degree_statistics(rng, ref_features):
    u = rng.uniform(-1, 1, size=(500, 5))
    y = rng.normal(size=(500, 2))
    high, low = MonomialBasis(5, 4), MonomialBasis(5, 2)
    restricted = static_statistics(high, u, y).restrict(low.index_in(high))
    _assert_stats_equal(restricted, ref_features(u, 2), y)


def _hand_arx_regressor(u, y_past, na, nb):
    """Degree-1 ARX rows k = max(na, nb)..n-1 of one segment, the paper's column order (docs/formats.md §1)."""
    lag = max(na, nb)
    rows = []
    for k in range(lag, len(u)):
        row = [y_past[k - j, l] for j in range(1, na + 1) for l in range(y_past.shape[1])]
        row += [u[k - j, i] for j in range(nb + 1) for i in range(u.shape[1])]
        rows.append(row + [1.0])
    return np.array(rows).reshape(-1, y_past.shape[1] * na + u.shape[1] * (nb + 1) + 1)


@pytest.mark.parametrize("chunk", [1, 5, 1000])
def test_arx_layout_statistics_match_hand_regressor(rng, chunk):
    u = rng.uniform(-1, 1, size=(23, 2))
    y = rng.normal(size=(23, 2))
    y_past = rng.normal(size=(23, 2))
    layout = RegressorLayout(MonomialBasis(2, 1), n_outputs=2, na=2, nb=3)
    stats = layout_statistics(layout, u, y, y_past, chunk=chunk)
    _assert_stats_equal(stats, _hand_arx_regressor(u, y_past, 2, 3), y[3:])


def test_static_layout_statistics_take_the_moment_path(rng, ref_features):
    u = rng.uniform(-1, 1, size=(100, 3))
    y = rng.normal(size=(100, 1))
    stats = layout_statistics(RegressorLayout(MonomialBasis(3, 2), 1), u, y, None)
    _assert_stats_equal(stats, ref_features(u, 2), y)


def test_arx_lags_never_cross_segment_boundaries(rng):
    # Two recordings of 7 and 6 samples; na = 1, nb = 2 so each loses its first 2 rows.
    u = rng.uniform(-1, 1, size=(13, 2))
    y = rng.normal(size=(13, 1))
    data = Dataset.from_arrays(u, y, segments=np.r_[np.zeros(7), np.ones(6)].astype(int))
    layout = RegressorLayout(MonomialBasis(2, 1), n_outputs=1, na=1, nb=2)
    identity_in, identity_out = Normalization.identity(2), Normalization.identity(1)
    stats = CalibrationModel.statistics(data, layout, identity_in, identity_out)
    a = np.vstack([_hand_arx_regressor(u[:7], y[:7], 1, 2), _hand_arx_regressor(u[7:], y[7:], 1, 2)])
    assert a.shape == (5 + 4, 8)
    _assert_stats_equal(stats, a, np.vstack([y[2:7], y[9:]]))


def test_nested_parallel_work_runs_inline_and_a_forked_child_has_its_own_pool():
    """Work submitted from a pool thread runs in that thread (a full pool cannot deadlock); a
    forked child (multiprocessing's fork start method) gets a new pool instead of dead threads."""
    import multiprocessing
    import threading

    from ftcal.runtime.threads import map_ranges

    def outer(begin, end):
        return (threading.current_thread().name,
                map_ranges(lambda a, b: threading.current_thread().name, 10_000, 1000))

    for outer_thread, inner_threads in map_ranges(outer, 10_000, 1000):
        assert set(inner_threads) == {outer_thread}
    with multiprocessing.get_context("fork").Pool(1) as pool:
        assert pool.apply(_sum_in_threads) == sum(range(10_000))


def _sum_in_threads():
    from ftcal.runtime.threads import map_ranges

    return sum(map_ranges(lambda a, b: sum(range(a, b)), 10_000, 1000))


def test_parallel_work_runs_in_the_callers_numpy_error_state():
    """np.errstate is per context: the pool threads must see the caller's, not numpy's default."""
    import warnings

    from ftcal.runtime.threads import map_ranges

    def overflow(begin, end):
        return np.full(end - begin, 1e300) * 1e300

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        with np.errstate(over="ignore"):
            assert np.isinf(np.concatenate(map_ranges(overflow, 10_000, 1000))).all()
        assert not caught
        with np.errstate(over="raise"), pytest.raises(FloatingPointError):
            map_ranges(overflow, 10_000, 1000)


@pytest.mark.parametrize("nu, degree", [(40, 1), (27, 2)])
def test_moment_layout_of_more_inputs_than_one_int64_code_holds(rng, ref_features, kernel, nu, degree):
    assert float(2 * degree + 1) ** nu >= 2.0 ** 62  # the exponent-ranking path
    u, y = rng.uniform(-1, 1, size=(60, nu)), rng.normal(size=(60, 2))
    _assert_stats_equal(static_statistics(MonomialBasis(nu, degree), u, y), ref_features(u, degree), y)
