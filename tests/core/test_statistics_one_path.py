"""One statistics path: a dataset in memory is the streaming accumulator over one chunk.

In-memory statistics (``CalibrationModel.statistics``, cross-validation's ``DatasetStatistics``)
and streamed ones (``ftcal.data.streaming``, chunk by chunk) must agree; they agree because both
feed :class:`ftcal.core.statistics.StatisticsAccumulator`. These tests check the agreement on
generated data (against a dense regressor built by hand, too) and count the accumulator's calls.
"""

import functools

import numpy as np
import pandas as pd
import pytest

from ftcal.core.dataset import Dataset
from ftcal.core.model import CalibrationModel
from ftcal.core.select import DatasetStatistics, fold_of_groups
from ftcal.core.statistics import StatisticsAccumulator, SufficientStatistics, sum_statistics
from ftcal.data import streaming, table_chunks

INPUTS = ("s0", "s1", "s2", "temperature")
OUTPUTS = ("Fx", "Fy", "Tz")
N_ROWS, CHUNK_ROWS = 5000, 700  # 8 chunks, the last one short


def _generated(rng, n=N_ROWS, groups=10):
    """Raw strain-like inputs far from zero (so the normalization matters) and a smooth wrench."""
    u = np.c_[rng.uniform(-2000.0, 3000.0, (n, 3)), rng.uniform(25.0, 44.0, n)]
    z = (u - u.mean(axis=0)) / u.std(axis=0)
    y = np.c_[z[:, 0] + 0.3 * z[:, 1] ** 2, z[:, 1] - 0.2 * z[:, 0] * z[:, 3], 0.1 * z[:, 2] ** 3]
    y = 10.0 * y + 0.01 * rng.standard_normal(y.shape)
    group = np.repeat(np.arange(groups), n // groups)
    return u, y, group


def _write(tmp_path, u, y, group, name="data.parquet"):
    frame = pd.DataFrame(np.c_[u, y], columns=INPUTS + OUTPUTS)
    frame["group"] = group.astype(str)
    path = tmp_path / name
    frame.to_parquet(path)
    return str(path)


def _assert_same(a, b, rtol=1e-12):
    """Every statistic equal to ``rtol`` relative to the largest entry of its array (entries near zero,
    such as odd moments, have no relative precision of their own)."""
    assert a.n_samples == b.n_samples
    for name in ("gram", "cross", "target_sq", "target_sum", "column_maxabs"):
        x, z = getattr(a, name), getattr(b, name)
        np.testing.assert_allclose(x, z, rtol=0, atol=rtol * np.abs(x).max(), err_msg=name)


@pytest.fixture
def chunked_reads(monkeypatch):
    """Streamed reads in chunks of CHUNK_ROWS rows (the default chunk holds the whole test file)."""
    monkeypatch.setattr(streaming, "iter_table_chunks",
                        functools.partial(table_chunks.iter_table_chunks, chunk_rows=CHUNK_ROWS))


@pytest.fixture
def counted_adds(monkeypatch):
    """Every StatisticsAccumulator.add: the number of rows it was given, in call order."""
    rows = []
    original = StatisticsAccumulator.add

    def counting(self, u, y, *args, **kwargs):
        rows.append(len(u))
        return original(self, u, y, *args, **kwargs)

    monkeypatch.setattr(StatisticsAccumulator, "add", counting)
    return rows


@pytest.mark.parametrize("degree", [1, 3])
def test_in_memory_and_streamed_statistics_agree_and_match_the_dense_regressor(
        tmp_path, rng, ref_features, chunked_reads, counted_adds, degree):
    u, y, group = _generated(rng)
    path = _write(tmp_path, u, y, group)
    data = Dataset.from_arrays(u, y, input_names=INPUTS, output_names=OUTPUTS)
    frame = CalibrationModel(degree).frame(data)
    in_norm = frame.solve_input_normalization

    memory = CalibrationModel.statistics(data, frame.layout, in_norm, frame.solve_output_normalization)
    assert counted_adds == [N_ROWS]  # one chunk: the whole dataset
    streamed = streaming.file_statistics(path, frame.layout.basis, in_norm, INPUTS, OUTPUTS)
    assert counted_adds[1:] == [CHUNK_ROWS] * (N_ROWS // CHUNK_ROWS) + [N_ROWS % CHUNK_ROWS]
    _assert_same(memory, streamed)

    # Both against the normal equations of the dense regressor built by hand (offset last).
    a = ref_features(in_norm.apply(u), degree)
    reference = SufficientStatistics(a.T @ a, a.T @ y, (y * y).sum(axis=0), y.sum(axis=0),
                                   np.abs(a).max(axis=0), N_ROWS)
    _assert_same(reference, memory, rtol=1e-10)


def test_fold_statistics_in_memory_and_streamed_agree(tmp_path, rng, chunked_reads, counted_adds):
    u, y, group = _generated(rng)
    path = _write(tmp_path, u, y, group)
    data = Dataset.from_arrays(u, y, input_names=INPUTS, output_names=OUTPUTS, groups=group.astype(str))
    frame = CalibrationModel(2).frame(data)
    fold_of = fold_of_groups({str(g): int((group == g).sum()) for g in np.unique(group)}, n_folds=3)

    memory = DatasetStatistics(data).fold_statistics(frame, fold_of, 3)
    sizes = [int(sum((group == int(g)).sum() for g, f in fold_of.items() if f == fold)) for fold in range(3)]
    assert counted_adds == sizes  # one chunk per fold: its rows, whole
    streamed = streaming.file_group_statistics(path, frame.layout.basis, frame.solve_input_normalization, INPUTS,
                                               OUTPUTS, "group", fold_of)
    assert len(counted_adds) > 3 + 3  # the file came in several chunks, each split between folds
    for fold in range(3):
        _assert_same(memory[fold], streamed[fold])


def test_arx_statistics_in_memory_equal_the_streamed_segments_summed_in_file_order(tmp_path, rng, counted_adds):
    # Two files of two segments each: lags stay inside segments in both paths.
    u, y, _ = _generated(rng, n=1200)
    segment = np.repeat([0, 1, 2, 3], 300)
    paths = []
    for k in range(2):
        rows = slice(600 * k, 600 * (k + 1))
        frame = pd.DataFrame(np.c_[u[rows], y[rows]], columns=INPUTS + OUTPUTS)
        frame["segment"] = segment[rows]
        paths.append(str(tmp_path / f"part{k}.parquet"))
        frame.to_parquet(paths[-1])
    data = Dataset.from_arrays(u, y, input_names=INPUTS, output_names=OUTPUTS, segments=segment)
    fit_frame = CalibrationModel(2, na=1, nb=1).frame(data)
    args = (fit_frame.layout, fit_frame.solve_input_normalization, fit_frame.solve_output_normalization)

    memory = CalibrationModel.statistics(data, *args)
    assert counted_adds == [1200]
    parts = [part for path in paths
             for part in streaming.file_layout_statistics(path, *args, INPUTS, OUTPUTS, segment_by="segment")]
    assert len(parts) == 4 and counted_adds[1:] == [600, 600]
    assert memory.n_samples == 4 * (300 - 1)  # each segment loses max(na, nb) = 1 warm-up row
    _assert_same(memory, sum_statistics(parts))
