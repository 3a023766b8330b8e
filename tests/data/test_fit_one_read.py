"""A static fit of Parquet files reads them once: ranges and statistics in one pass (issue 32, item 4).

The normalization of the statistics comes from the files' footers before the data are read; the
statistics are kept only when the ranges actually read give the same normalization. References:
the two-pass fit of the same rows from a Parquet file written without footer statistics (the path
before this change, bit for bit), the in-memory fit of the table (coefficients to 1e-12), numpy's
min/max over the table, and pyarrow.compute.min_max for the footer check's extremes.
"""

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.compute as pc
import pyarrow.parquet as pq
import pytest
from conftest import sensor_like_data

import ftcal.data.parquet_checks as parquet_checks
import ftcal.data.streaming as streaming
from ftcal.core.dataset import DEFAULT_OUTPUTS
from ftcal.core.model import CalibrationModel
from ftcal.core.ranges import column_extremes
from ftcal.data.tables import load_dataset
from ftcal.files.model_files import load_model_file
from ftcal.workflow.fitting import fit

INPUTS = ("u1", "u2", "u3", "u4", "u5", "u6", "T")
COLUMNS = (*INPUTS, *DEFAULT_OUTPUTS)


def write_table(path, n, seed=7, statistics=True, group_size=1000):
    u, y = sensor_like_data(np.random.default_rng(seed), n)
    frame = pd.DataFrame(np.c_[u, y], columns=list(COLUMNS))
    frame["case"] = [f"c{i // 900}" for i in range(n)]
    pq.write_table(pa.Table.from_pandas(frame, preserve_index=False), path, row_group_size=group_size,
                   write_statistics=statistics)
    return str(path), u, y


def count_passes(monkeypatch):
    """Record which per-file tasks the fit runs."""
    calls = []
    for name in ("file_summary", "file_statistics_and_poses", "file_summary_statistics_and_poses"):
        original = getattr(streaming, name)

        def counted(*args, _original=original, _name=name, **kwargs):
            calls.append(_name)
            return _original(*args, **kwargs)

        monkeypatch.setattr(streaming, name, counted)
    return calls


@pytest.mark.parametrize("options", [dict(degree=3), dict(degree=2, ridge=10.0), dict(degree=2, group_by="case")])
def test_one_read_equals_two_passes_bit_for_bit(tmp_path, monkeypatch, options):
    one, u, y = write_table(tmp_path / "stats.parquet", 5000)
    two, *_ = write_table(tmp_path / "nostats.parquet", 5000, statistics=False)
    assert parquet_checks.footer_ranges([two], COLUMNS) is None  # no footer figures: two passes
    calls = count_passes(monkeypatch)
    a = fit([one], output=tmp_path / "one.json", **options)
    assert calls == ["file_summary_statistics_and_poses"]
    calls.clear()
    b = fit([two], output=tmp_path / "two.json", **options)
    assert calls == ["file_summary", "file_statistics_and_poses"]
    ma, mb = load_model_file(tmp_path / "one.json"), load_model_file(tmp_path / "two.json")
    assert np.array_equal(ma.model.coef_, mb.model.coef_)
    assert ma.model.training_metrics_ == mb.model.training_metrics_
    assert ma.training_segments == mb.training_segments
    assert np.array_equal(ma.model.input_range_, np.c_[u.min(axis=0), u.max(axis=0)])
    assert a.lines[:-1] == b.lines[:-1]  # all but "wrote FILE"
    if "ridge" not in options and "group_by" not in options:
        whole = CalibrationModel(options["degree"]).fit(load_dataset([one], inputs=INPUTS, outputs=DEFAULT_OUTPUTS))
        assert np.max(np.abs(ma.model.coef_ - whole.coef_)) <= 1e-12 * np.max(np.abs(whole.coef_))


def test_several_files_and_a_footer_that_gives_another_normalization(tmp_path, monkeypatch):
    """Footer figures that do not match the rows read (here widened by hand) cost a second read, not a
    wrong model: the statistics are recomputed in the normalization of the ranges read."""
    paths = [write_table(tmp_path / f"part{i}.parquet", 2500 + 700 * i, seed=i)[0] for i in range(3)]
    reference = fit(paths, output=tmp_path / "reference.json", degree=3)
    widened = parquet_checks.footer_ranges(paths, COLUMNS) + np.array([-1.0, 1.0])
    monkeypatch.setattr(parquet_checks, "footer_ranges", lambda *_: widened)
    calls = count_passes(monkeypatch)
    again = fit(paths, output=tmp_path / "again.json", degree=3)
    assert calls == ["file_summary_statistics_and_poses"] * 3 + ["file_statistics_and_poses"] * 3
    ma, mb = load_model_file(tmp_path / "reference.json"), load_model_file(tmp_path / "again.json")
    assert np.array_equal(ma.model.coef_, mb.model.coef_)
    assert reference.lines[:-1] == again.lines[:-1]


def test_drop_incomplete_and_csv_read_twice(tmp_path, monkeypatch):
    path, *_ = write_table(tmp_path / "t.parquet", 3000)
    csv = tmp_path / "t.csv"
    pd.read_parquet(path).to_csv(csv, index=False, float_format="%.17g")
    calls = count_passes(monkeypatch)
    fit([path], output=tmp_path / "a.json", degree=2, drop_incomplete=True)
    fit([str(csv)], output=tmp_path / "b.json", degree=2)
    assert "file_summary_statistics_and_poses" not in calls


def test_footer_ranges_are_the_tables_extremes(tmp_path):
    path, u, y = write_table(tmp_path / "t.parquet", 4321, group_size=500)
    values = np.c_[u, y]
    ranges = parquet_checks.footer_ranges([path], COLUMNS)
    assert np.array_equal(ranges, np.c_[values.min(axis=0), values.max(axis=0)])
    other, v, _ = write_table(tmp_path / "o.parquet", 1000, seed=9)
    both = parquet_checks.footer_ranges([path, other], INPUTS)
    assert np.array_equal(both, np.c_[np.minimum(u.min(axis=0), v.min(axis=0)), np.maximum(u.max(axis=0),
                                                                                              v.max(axis=0))])
    holes = tmp_path / "holes.parquet"
    pq.write_table(pa.table({"u1": pa.array([1.0, None, 3.0])}), holes)
    assert parquet_checks.footer_ranges([holes], ["u1"]) is None  # empty cells: not the footer's figures
    assert parquet_checks.footer_ranges([tmp_path / "missing.parquet"], ["u1"]) is None


@pytest.mark.parametrize("values", [
    np.random.default_rng(0).normal(size=1000),
    np.array([0.0, -0.0, 2.5]),
    np.array([1.0, np.nan, -2.0, 7.0]),  # NaN: pyarrow's own min_max decides
    np.array([np.nan, np.nan]),
    np.arange(-5, 300, dtype=np.int32),
    np.arange(200, dtype=np.uint8),
    np.random.default_rng(1).normal(size=333).astype(np.float32),
])
def test_footer_check_extremes_are_pyarrows(values):
    array = pa.array(values)
    chunked = pa.chunked_array([array.slice(0, len(values) // 3), array.slice(len(values) // 3)]).slice(1)
    for arrow in (array, array.slice(1), chunked):
        expected = pc.min_max(arrow)
        low, high = parquet_checks._extremes(arrow)
        # equal as numbers (the footer check compares with ==: a zero extreme may carry either sign)
        assert np.array_equal([low, high], [expected["min"].as_py(), expected["max"].as_py()], equal_nan=True)
        assert type(low) is type(expected["min"].as_py())


@pytest.mark.parametrize("rows", [1, 63, 64, 65, 1000, 4097])
def test_column_extremes_are_numpys(rows):
    values = np.random.default_rng(rows).normal(size=(rows, 13)) * 10.0 ** np.arange(-6, 7)
    low, high = column_extremes(values)
    assert np.array_equal(low, values.min(axis=0)) and np.array_equal(high, values.max(axis=0))
    low, high = column_extremes(values[:, 3:9])  # a view that is not C-ordered
    assert np.array_equal(low, values[:, 3:9].min(axis=0)) and np.array_equal(high, values[:, 3:9].max(axis=0))


def test_one_read_on_a_local_cluster_equals_the_local_run(tmp_path):
    paths = [write_table(tmp_path / f"part{i}.parquet", 2000 + 500 * i, seed=20 + i)[0] for i in range(3)]
    fit(paths, output=tmp_path / "here.json", degree=3)
    fit(paths, output=tmp_path / "there.json", degree=3, scheduler="local:2")
    here, there = load_model_file(tmp_path / "here.json"), load_model_file(tmp_path / "there.json")
    # the tree sum pairs files in the same order on the cluster: the same bits
    assert np.array_equal(there.model.coef_, here.model.coef_)
    assert there.training_segments == here.training_segments
