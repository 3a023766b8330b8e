"""One scan per file (issue 43, item 2): accumulators fed by one read, merged with ``+`` across files.

References, computed without ftcal's streaming code: pandas reading each whole table (ranges by
min/max, segment run lengths, group counts, means and centred cross products, the Gram and cross
products of the monomial features by numpy on the whole array, residual RMSE and max |error|), and an
independent count of occupied pose cells (``np.unique`` of the floored grid coordinates). Fused
scans are compared with one scan per accumulator, bit for bit, over several chunk sizes.
"""

import functools
import warnings

import numpy as np
import pandas as pd
import pytest
from conftest import sensor_like_data, write_frame

from ftcal.core.dataset import DEFAULT_OUTPUTS, Dataset
from ftcal.core.features import MonomialBasis, RegressorLayout
from ftcal.core.model import CalibrationModel
from ftcal.core.normalization import normalization_from_range
from ftcal.core.select.poses import POSE_BINS
from ftcal.core.statistics import sum_statistics
from ftcal.data import streaming, table_chunks
from ftcal.data.streaming import (
    Errors,
    GroupStatistics,
    InputSpread,
    PoseCells,
    Statistics,
    Summary,
    add_scans,
    scan,
)
from ftcal.runtime.executors import LocalExecutor

INPUTS = ("u1", "u2", "u3", "u4", "u5", "u6", "T")
OUTPUTS = DEFAULT_OUTPUTS
SIZES = (1700, 900, 2300)


@pytest.fixture(scope="module")
def tables(tmp_path_factory):
    """Three files (Parquet with 1000-row groups, CSV, Parquet) with a group and a segment column."""
    folder = tmp_path_factory.mktemp("scan")
    rng = np.random.default_rng(43)
    paths, frames = [], []
    for index, (n, suffix) in enumerate(zip(SIZES, (".parquet", ".csv", ".parquet"))):
        u, y = sensor_like_data(rng, n)
        frame = pd.DataFrame(np.c_[u, y], columns=[*INPUTS, *OUTPUTS])
        frame["case"] = [f"c{(i // 600 + index) % 4}" for i in range(n)]  # groups shared between files
        frame["seg"] = [f"s{i // 450}" for i in range(n)]
        paths.append(write_frame(frame, folder / f"part{index}{suffix}"))
        frames.append(frame)
    u, y = sensor_like_data(rng, 3000)
    model = CalibrationModel(2).fit(Dataset.from_arrays(u, y, input_names=INPUTS, output_names=OUTPUTS))
    return paths, frames, model


@pytest.fixture(params=[257, 1000, 10**6], ids=lambda rows: f"chunks of {rows}")
def chunk_rows(request, monkeypatch):
    """Every scan reads the files in chunks of this many rows (a whole small file for the last)."""
    monkeypatch.setattr(streaming, "iter_table_chunks",
                        functools.partial(table_chunks.iter_table_chunks, chunk_rows=request.param))
    return request.param


def recipes(frames, model):
    whole = pd.concat(frames, ignore_index=True)
    low, high = whole[list(INPUTS)].min().to_numpy(), whole[list(INPUTS)].max().to_numpy()
    norm = normalization_from_range(low, high)
    layout = RegressorLayout(MonomialBasis(len(INPUTS), 2), len(OUTPUTS))
    return whole, norm, layout, [
        Summary(INPUTS, OUTPUTS, "seg", "case"), Statistics(layout, norm, None, INPUTS, OUTPUTS),
        GroupStatistics(layout.basis, norm, INPUTS, OUTPUTS, "case"), PoseCells(INPUTS, np.c_[low, high]),
        InputSpread(INPUTS), Errors(model)]


def features(u, norm, basis):
    """The monomial regressor by numpy: each column the product of the normalized inputs' powers."""
    z = norm.apply(u)
    return np.stack([np.prod(z ** e, axis=1) for e in basis.exponents], axis=1)


def close(a, b, tol=1e-12):
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    assert a.shape == b.shape
    assert np.max(np.abs(a - b)) <= tol * max(np.max(np.abs(b)), 1e-300)


def test_one_scan_of_every_file_equals_pandas_on_the_whole_table(tables, chunk_rows):
    paths, frames, model = tables
    whole, norm, layout, wanted = recipes(frames, model)
    summary, stats, groups, cells, spread, errors = LocalExecutor().map_reduce(
        scan, paths, wanted, combine=add_scans)
    u, y = whole[list(INPUTS)].to_numpy(), whole[list(OUTPUTS)].to_numpy()
    s = summary.value
    assert np.array_equal(s.input_range, np.c_[u.min(axis=0), u.max(axis=0)])
    assert np.array_equal(s.output_range, np.c_[y.min(axis=0), y.max(axis=0)])
    # segments: runs of 'seg' inside each file (a file starts a new one)
    runs = [len(run) for f in frames for _, run in f.groupby((f.seg != f.seg.shift()).cumsum())]
    assert s.segment_lengths == runs
    assert s.group_sizes == whole.case.value_counts().to_dict()
    for got, x in ((s.output_spread, y), (s.input_spread, u), (spread.value, u)):
        assert got.n == len(x)
        close(got.mean, x.mean(axis=0))
        close(got.m2, (x - x.mean(axis=0)).T @ (x - x.mean(axis=0)))
    assert len(stats.value) == len(paths)  # one entry per static file, summed in file order
    for (label, rows), got in [((None, slice(None)), sum_statistics(stats.value)),
                               *[((c, (whole.case == c).to_numpy()), groups.value[c])
                                 for c in sorted(set(whole.case))]]:
        a = features(u[rows], norm, layout.basis)
        assert got.n_samples == len(a), label
        close(got.gram, a.T @ a)
        close(got.cross, a.T @ y[rows])
        close(got.target_sum, y[rows].sum(axis=0))
    grid = np.clip(np.floor((u - u.min(axis=0)) / (u.max(axis=0) - u.min(axis=0)) * POSE_BINS), 0, POSE_BINS - 1)
    assert len(cells.value) == len(np.unique(grid, axis=0))
    residual = y - model.predict(u, warn_out_of_range=False)
    metrics = errors.value.to_dict(OUTPUTS)
    close(metrics["rmse"], np.sqrt(np.mean(residual ** 2, axis=0)))
    close(metrics["max_abs_error"], np.abs(residual).max(axis=0))
    assert metrics["n_samples"] == len(whole)


def test_fused_scan_equals_one_scan_per_accumulator_bit_for_bit(tables, chunk_rows):
    paths, frames, model = tables
    _, _, _, wanted = recipes(frames, model)
    for path in paths:
        fused = scan(path, wanted)
        for recipe, together in zip(wanted, fused):
            (alone,) = scan(path, [recipe])
            assert_same(together.value, alone.value)


def assert_same(a, b):
    if isinstance(a, dict):
        assert a.keys() == b.keys()
        for key in a:
            assert_same(a[key], b[key])
    elif isinstance(a, (list, tuple)):
        assert len(a) == len(b)
        for x, y in zip(a, b):
            assert_same(x, y)
    elif hasattr(a, "__dataclass_fields__"):
        for name in a.__dataclass_fields__:
            assert_same(getattr(a, name), getattr(b, name))
    elif isinstance(a, np.ndarray):
        assert np.array_equal(a, b, equal_nan=True)
    else:
        assert a == b


def test_recipes_are_not_changed_and_finished_errors_carry_no_model(tables):
    paths, frames, model = tables
    _, _, _, wanted = recipes(frames, model)
    first = scan(paths[0], wanted)
    again = scan(paths[0], wanted)  # the same recipes again: nothing carried over from the first file
    assert_same([a.value for a in first], [a.value for a in again])
    assert first[-1].model is None and wanted[-1].model is model


def test_arx_whole_file_accumulators_read_the_file_once_and_share_it_with_chunked_ones(tables, monkeypatch):
    """An ARX model's errors take the file whole; its pose cells come from the same read (no chunked read)."""
    paths, frames, _ = tables
    u, y = sensor_like_data(np.random.default_rng(5), 2000)
    with warnings.catch_warnings():  # independent rows make the lag columns near collinear: any fitted ARX will do
        warnings.simplefilter("ignore")
        arx = CalibrationModel(1, na=1, nb=1).fit(Dataset.from_arrays(u, y, input_names=INPUTS, output_names=OUTPUTS))
    reads = []
    monkeypatch.setattr(streaming, "iter_table_chunks", lambda *a, **k: reads.append(a) or iter(()))
    sums = streaming.file_error_sums(paths[2], arx, count_poses=True)
    assert reads == []
    main, other = sums
    data = frames[2]
    expected = arx.metrics(Dataset.from_arrays(data[list(INPUTS)].to_numpy(), data[list(OUTPUTS)].to_numpy(),
                                               input_names=INPUTS, output_names=OUTPUTS), warn_out_of_range=False)
    close(main.to_dict(OUTPUTS)["rmse"], expected["rmse"], 1e-10)
    x = data[list(INPUTS)].to_numpy()
    low, high = arx.input_range_[:, 0], arx.input_range_[:, 1]
    grid = np.clip(np.floor((x - low) / (high - low) * POSE_BINS), 0, POSE_BINS - 1)
    assert len(main.pose_cells) == len(np.unique(grid, axis=0))


def test_one_scan_reads_one_set_of_inputs(tables):
    paths, _, _ = tables
    with pytest.raises(ValueError, match="one set of inputs"):
        scan(paths[0], [InputSpread(INPUTS), InputSpread(INPUTS[:3])])
