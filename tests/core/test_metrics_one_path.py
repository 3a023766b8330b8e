"""One evaluation path: the in-memory metrics are the streamed error sums over one chunk.

``ftcal.core.metrics.summarize`` (in memory, ``CalibrationModel.score``) and the streamed
evaluation (``ftcal.data.streaming.file_error_sums``, chunk by chunk) both feed
:class:`ftcal.core.metrics.ErrorSums`. These tests check, on generated residuals, that any
split into chunks gives the metrics of the whole array, and that both match a direct numpy
computation of each metric written here from its definition (docs/metrics.md). One case has a
residual whose mean is a million times its spread: raw sums (Σr, Σr², Σ r_t r_(t+1)) lose most
digits of its lag-1 autocorrelation there, the centred sums do not. The reference centred moments
(variance, acf) are computed exactly (integer arithmetic on the floats' mantissas), the other sums correctly
rounded (math.fsum), so the reference does not depend on a summation order.
"""

import functools
import math
from fractions import Fraction

import numpy as np
import pandas as pd
import pytest

from ftcal.core import metrics
from ftcal.core.dataset import DEFAULT_OUTPUTS, Dataset
from ftcal.core.model import CalibrationModel
from ftcal.data import streaming, table_chunks
from ftcal.runtime.executors import tree_reduce

NAMES = ("Fx", "Fy", "Fz", "Tx", "Ty", "Tz")
N_ROWS = 6000
RESIDUAL_OFFSET = 3000.0  # N: the large-mean case's residual mean; its spread is ~1e-3 N
OUTPUT_OFFSET = 2.0e5  # the offset-outputs case: raw-count-like outputs around 2e5 with a spread ~1


def _ar1(rng, n, columns, phi, scale):
    """AR(1) noise per column (lag-1 autocorrelation ~phi, far from 0 so relative errors mean something)."""
    e = rng.standard_normal((n, columns)) * scale
    out = np.empty_like(e)
    out[0] = e[0]
    for t in range(1, n):
        out[t] = phi * out[t - 1] + e[t]
    return out


def _case(name, rng):
    """(y, prediction) of one generated case."""
    wrench = rng.standard_normal((N_ROWS, 6)) * [80.0, 60.0, 120.0, 5.0, 7.0, 3.0] + [10.0, -4.0, 30.0, 0.5, 0, 1]
    if name == "ordinary":
        return wrench, wrench - _ar1(rng, N_ROWS, 6, 0.8, 0.3) - 0.05
    if name == "offset_outputs":
        y = OUTPUT_OFFSET + rng.standard_normal((N_ROWS, 6))
        return y, y - _ar1(rng, N_ROWS, 6, 0.6, 1e-2)
    assert name == "biased_residual"
    return wrench, wrench - (RESIDUAL_OFFSET + _ar1(rng, N_ROWS, 6, 0.9, 1e-3))


CASES = ("ordinary", "offset_outputs", "biased_residual")


def _centred_exactly(column):
    """(d, scale): integers d_t = n·X_t − Σ X with X = x·2^k integers (every float is m·2^e), so that
    x_t − mean(x) = d_t / scale exactly; centred moments are then sums of Python integers."""
    ratios = [float(v).as_integer_ratio() for v in column]
    common = max(den for _, den in ratios)  # a power of two
    scaled = [num * (common // den) for num, den in ratios]
    n, total = len(scaled), sum(scaled)
    return [n * x - total for x in scaled], n * common


def _exact_acf(r):
    """Lag-1 autocorrelation Σ c_t c_(t+1) / Σ c_t² per column, c = r − mean(r), computed exactly."""
    out = []
    for column in r.T:
        d, _ = _centred_exactly(column)
        out.append(float(Fraction(sum(a * b for a, b in zip(d[1:], d[:-1])), sum(a * a for a in d))))
    return np.array(out)


def _exact_variance(column):
    """mean((x − mean(x))²), computed exactly."""
    d, scale = _centred_exactly(column)
    return float(Fraction(sum(a * a for a in d), scale * scale * len(d)))


def _direct(y, prediction):
    """Every metric from its definition (docs/metrics.md), independent of ErrorSums: correctly rounded sums
    (math.fsum) of squares, and exact rational arithmetic for the centred moments."""
    r = y - prediction
    mse = np.array([math.fsum(column ** 2) for column in r.T]) / len(r)
    variance = np.array([_exact_variance(column) for column in y.T])
    truth = {"rmse": np.sqrt(mse), "best_fit": 1.0 - np.sqrt(mse / variance),
             "max_abs_error": np.max(np.abs(r), axis=0), "residual_autocorrelation_lag1": _exact_acf(r)}
    for block, columns in (("force", [0, 1, 2]), ("torque", [3, 4, 5])):
        norm_diff = np.linalg.norm(y[:, columns], axis=1) - np.linalg.norm(prediction[:, columns], axis=1)
        truth[f"{block}_norm_rmse"] = np.sqrt(math.fsum(norm_diff ** 2) / len(r))
        truth[f"{block}_error_norm_rmse"] = np.sqrt(math.fsum((r[:, columns] ** 2).ravel()) / len(r))
    return truth


def _naive_acf(r):
    """Lag-1 autocorrelation from raw sums, as the former streamed path computed it."""
    n, m = len(r), r.mean(axis=0)
    r_sum, r_sq, r_lag = r.sum(axis=0), np.sum(r * r, axis=0), np.sum(r[1:] * r[:-1], axis=0)
    return (r_lag - m * (2 * r_sum - r[0] - r[-1]) + (n - 1) * m * m) / (r_sq - n * m * m)


def _cuts(rng, n):
    """About 60 chunk boundaries, including chunks of one and two rows."""
    inner = np.unique(np.r_[1, 2, 4, rng.integers(5, n - 1, 57), n - 1])
    return [0, *inner.tolist(), n]


def _assert_metrics(got, expected, rtol=1e-12):
    for key, value in expected.items():
        np.testing.assert_allclose(np.asarray(got[key], dtype=float), value, rtol=rtol, atol=0, err_msg=key)


@pytest.mark.parametrize("case", CASES)
def test_in_memory_equals_streamed_in_many_chunks_and_the_direct_computation(case):
    rng = np.random.default_rng(29)
    y, prediction = _case(case, rng)
    in_memory = metrics.summarize(y, prediction, NAMES)
    cuts = _cuts(rng, N_ROWS)
    parts = [metrics.ErrorSums.of(y[a:b], prediction[a:b], NAMES) for a, b in zip(cuts[:-1], cuts[1:])]
    for streamed in (tree_reduce(parts, metrics.ErrorSums.__add__), functools.reduce(metrics.ErrorSums.__add__, parts),
                     functools.reduce(lambda a, b: b + a, parts[::-1])):  # three association orders
        summary = streamed.to_dict(NAMES)
        assert summary["n_samples"] == N_ROWS and summary["outputs"] == list(NAMES)
        _assert_metrics(summary, {key: np.asarray(value, dtype=float) for key, value in in_memory.items()
                                  if key not in ("n_samples", "outputs")})
    truth = _direct(y, prediction)
    _assert_metrics(in_memory, truth)
    _assert_metrics(tree_reduce(parts, metrics.ErrorSums.__add__).to_dict(NAMES), truth)


def test_raw_sums_lose_digits_where_the_centred_sums_do_not():
    rng = np.random.default_rng(29)
    y, prediction = _case("biased_residual", rng)
    r = y - prediction
    acf = _exact_acf(r)
    assert np.all(acf > 0.8)  # AR(1) with phi = 0.9: a value with digits to lose
    # The direct numpy computation keeps the digits (to its summation error, ~n·eps); raw sums do not
    # (error ~ eps·(mean/spread)² ~ 1e-4 here).
    c = r - r.mean(axis=0)
    np.testing.assert_allclose(np.sum(c[1:] * c[:-1], axis=0) / np.sum(c * c, axis=0), acf, rtol=1e-11, atol=0)
    assert np.max(np.abs(_naive_acf(r) - acf)) > 1e-7
    cuts = _cuts(rng, N_ROWS)
    streamed = tree_reduce([metrics.ErrorSums.of(y[a:b], prediction[a:b], NAMES)
                            for a, b in zip(cuts[:-1], cuts[1:])], metrics.ErrorSums.__add__)
    np.testing.assert_allclose(streamed.to_dict(NAMES)["residual_autocorrelation_lag1"], acf, rtol=1e-12, atol=0)
    np.testing.assert_allclose(metrics.summarize(y, prediction, NAMES)["residual_autocorrelation_lag1"], acf,
                               rtol=1e-12, atol=0)


def test_single_rows_and_constant_outputs_give_the_defined_values():
    y = np.array([[1.0, 5.0], [3.0, 5.0], [2.0, 5.0]])
    prediction = np.zeros_like(y)
    one_row = metrics.summarize(y[:1], prediction[:1], ("a", "b"))
    assert one_row["residual_autocorrelation_lag1"] == [0.0, 0.0]  # no lag pair: 0, as documented
    assert one_row["best_fit"] == [None, None]  # a constant output has no variance
    split = (metrics.ErrorSums.of(y[:1], prediction[:1], ("a", "b"))
             + metrics.ErrorSums.of(y[1:], prediction[1:], ("a", "b"))).to_dict(("a", "b"))
    assert split["best_fit"][1] is None and split["force_norm_rmse"] is None
    # column a by hand: r = (1, 3, 2), mean 2, centred (-1, 1, 0): acf(1) = (-1·1 + 1·0) / 2 = -0.5
    assert split["residual_autocorrelation_lag1"][0] == pytest.approx(-0.5, abs=1e-15)
    # column b: r = 5 everywhere, centred residual zero: acf defined as 0
    assert split["residual_autocorrelation_lag1"][1] == pytest.approx(0.0, abs=1e-15)


@pytest.fixture
def counted_sums(monkeypatch):
    """Rows given to every metrics.ErrorSums.of call (the streamed evaluation's included), in order."""
    rows = []
    original = metrics.ErrorSums.of.__func__

    def counting(cls, y, prediction, output_names, *counts):
        rows.append(len(y))
        return original(cls, y, prediction, output_names, *counts)

    monkeypatch.setattr(metrics.ErrorSums, "of", classmethod(counting))
    return rows


def test_in_memory_and_streamed_evaluation_both_go_through_the_error_sums(tmp_path, monkeypatch, counted_sums):
    rng = np.random.default_rng(7)
    u = np.c_[rng.uniform(4000.0, 6000.0, (3000, 6)), rng.uniform(25.0, 44.0, 3000)]
    inputs = ("u1", "u2", "u3", "u4", "u5", "u6", "T")
    y = (u[:, :6] - 5000.0) / 10.0 + 0.02 * (u[:, :1] - 5000.0) ** 2 / 1e3 + 0.05 * rng.standard_normal((3000, 6))
    data = Dataset.from_arrays(u, y, input_names=inputs, output_names=DEFAULT_OUTPUTS)
    model = CalibrationModel(2).fit(data)
    counted_sums.clear()

    in_memory = model.metrics(data, warn_out_of_range=False)
    assert counted_sums == [3000]  # one chunk: the whole dataset

    path = tmp_path / "data.parquet"
    pd.DataFrame(np.c_[u, y], columns=[*inputs, *DEFAULT_OUTPUTS]).to_parquet(path)
    monkeypatch.setattr(streaming, "iter_table_chunks",
                        functools.partial(table_chunks.iter_table_chunks, chunk_rows=700))
    counted_sums.clear()
    streamed = streaming.file_error_sums(str(path), model)
    assert isinstance(streamed, metrics.ErrorSums) and streamed.n_out_of_range == in_memory["n_out_of_range"]
    assert sum(counted_sums) == 3000 and len(counted_sums) >= 5  # 700-row chunks (threads may split them)
    summary = streamed.to_dict(model.output_names_)
    assert summary["n_out_of_range"] == 0
    _assert_metrics(summary, {key: np.asarray(value, dtype=float) for key, value in in_memory.items()
                              if key not in ("n_samples", "outputs", "n_out_of_range")})
