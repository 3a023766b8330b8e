"""Chunked table reads, streamed metrics and predictions, and the Dask executor (a real LocalCluster).

References: pandas/pyarrow whole-table reads, ftcal.core.metrics on whole arrays (numpy),
hand-computed row numbers and reduction orders, and the single-process run for Dask.
"""

import json
import os
import socket
import subprocess
import sys

import numpy as np
import pandas as pd
import pytest
from conftest import sensor_like_data, write_frame

from ftcal.core import metrics
from ftcal.core.dataset import DEFAULT_OUTPUTS, Dataset
from ftcal.core.model import CalibrationModel
from ftcal.data.streaming import ErrorSums, add_error_sums, file_error_sums
from ftcal.data.table_chunks import iter_table_chunks
from ftcal.files.model_files import save_model
from ftcal.runtime.errors import FtcalError
from ftcal.runtime.executors import LocalExecutor, open_executor, parse_scheduler, tree_reduce

INPUTS = ("u1", "u2", "u3", "u4", "u5", "u6", "T")
FTCAL = os.path.join(os.path.dirname(sys.executable), "ftcal")


def write_files(folder, rng, sizes, suffix=".parquet"):
    """Tables of sensor-like samples; Parquet files get row groups of 1000 rows."""
    paths = []
    for index, n in enumerate(sizes):
        u, y = sensor_like_data(rng, n)
        frame = pd.DataFrame(np.c_[u, y], columns=[*INPUTS, *DEFAULT_OUTPUTS])
        path = folder / f"part{index}{suffix}"
        paths.append(write_frame(frame, path))
    return paths


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    folder = tmp_path_factory.mktemp("streaming")
    rng = np.random.default_rng(7)
    paths = write_files(folder, rng, [2500, 1200, 3100])
    u, y = sensor_like_data(rng, 4000)
    model = CalibrationModel(2).fit(Dataset.from_arrays(u, y, input_names=INPUTS, output_names=DEFAULT_OUTPUTS))
    model_path = folder / "model.json"
    save_model(model, model_path)
    return paths, model, str(model_path)


@pytest.fixture(scope="module")
def cluster():
    with open_executor("local:2") as executor:
        yield executor


def whole(paths):
    return pd.concat([pd.read_parquet(p) if p.endswith(".parquet") else pd.read_csv(p) for p in paths],
                     ignore_index=True)


@pytest.mark.parametrize("suffix", [".parquet", ".csv"])
def test_chunks_equal_the_whole_table(tmp_path, suffix):
    (path,) = write_files(tmp_path, np.random.default_rng(1), [2600], suffix)
    chunks = list(iter_table_chunks(path, ["T", "u1"], ["Fz"], labels=["u2"], chunk_rows=700))
    frame = pd.read_parquet(path) if suffix == ".parquet" else pd.read_csv(path)
    assert np.array_equal(np.vstack([c.inputs for c in chunks]), frame[["T", "u1"]].to_numpy())
    assert np.array_equal(np.vstack([c.outputs for c in chunks]), frame[["Fz"]].to_numpy())
    assert np.array_equal(np.concatenate([c.labels["u2"] for c in chunks]).astype(float), frame["u2"].to_numpy())
    assert [c.first_row for c in chunks] == list(np.cumsum([0] + [c.n_rows for c in chunks[:-1]]))
    # Batches of 700 rows: across Parquet row groups of 1000, and from a small CSV file read whole.
    assert [c.n_rows for c in chunks] == [700, 700, 700, 500]


@pytest.fixture(params=["whole", "blocks"])
def csv_reader(request, monkeypatch):
    """Both CSV readers: small files parsed whole, larger ones block by block (forced here)."""
    from ftcal.data import table_chunks

    if request.param == "blocks":
        monkeypatch.setattr(table_chunks, "CSV_READ_WHOLE_BYTES", 0)
    return request.param


def test_chunk_errors_name_the_file_row_and_column(tmp_path, csv_reader):
    frame = pd.DataFrame({"a": np.arange(3000.0), "b": np.ones(3000)})
    frame.loc[2345, "b"] = np.nan
    frame.to_parquet(tmp_path / "nan.parquet", row_group_size=1000)
    with pytest.raises(FtcalError, match=r"nan.parquet: column 'b' has 1 empty.*first at row 2345\."):
        list(iter_table_chunks(tmp_path / "nan.parquet", ["a", "b"], chunk_rows=500))
    frame.to_csv(tmp_path / "nan.csv", index=False)
    with pytest.raises(FtcalError, match=r"first at line 2347\."):  # header is line 1, row 0 is line 2
        list(iter_table_chunks(tmp_path / "nan.csv", ["a", "b"]))
    text = frame.fillna(1.0).astype({"b": object})
    text.loc[2900, "b"] = "true"
    text.to_csv(tmp_path / "word.csv", index=False)
    with pytest.raises(FtcalError, match=r"word.csv: .*column 'b'.*'true'"):
        list(iter_table_chunks(tmp_path / "word.csv", ["a", "b"]))
    with pytest.raises(FtcalError, match=r"missing output column\(s\) 'Fx'; the file has a, b"):
        list(iter_table_chunks(tmp_path / "word.csv", ["a"], ["Fx"]))


def test_error_sums_of_any_split_equal_the_metrics_of_the_whole():
    rng = np.random.default_rng(3)
    y = rng.normal(size=(500, 6)) * [100, 100, 100, 10, 10, 10] + 40.0
    prediction = y + rng.normal(size=y.shape).cumsum(axis=0) * 0.1  # correlated residuals
    cuts = [0, 1, 2, 90, 333, 500]  # includes blocks of one row
    parts = [ErrorSums.of(y[a:b], prediction[a:b], DEFAULT_OUTPUTS, 0) for a, b in zip(cuts[:-1], cuts[1:])]
    got = tree_reduce(parts, add_error_sums).to_dict(DEFAULT_OUTPUTS)
    expected = metrics.summarize(y, prediction, DEFAULT_OUTPUTS)
    for key in expected:
        if key == "outputs":
            assert got[key] == expected[key]
        else:
            assert np.allclose(got[key], expected[key], rtol=1e-10, atol=0), key


def test_tree_reduce_pairs_neighbours_in_order():
    assert tree_reduce(list("abcde"), lambda a, b: f"({a}{b})") == "(((ab)(cd))e)"
    assert LocalExecutor().map_reduce(str.upper, ["x", "y", "z"], combine=str.__add__) == "XYZ"


def test_dask_results_are_identical_to_the_local_run(files, cluster):
    paths, model, _ = files
    local = LocalExecutor().map_reduce(file_error_sums, paths, model, combine=add_error_sums)
    remote = cluster.map_reduce(file_error_sums, paths, model, combine=add_error_sums)
    assert json.dumps(remote.to_dict(model.output_names_)) == json.dumps(local.to_dict(model.output_names_))
    data = whole(paths)
    reference = model.metrics(Dataset.from_arrays(data[list(INPUTS)].to_numpy(), data[list(DEFAULT_OUTPUTS)].to_numpy(),
                                                input_names=INPUTS, output_names=DEFAULT_OUTPUTS),
                            warn_out_of_range=False)
    assert np.allclose(remote.to_dict(model.output_names_)["rmse"], reference["rmse"], rtol=1e-12, atol=0)


def test_dask_errors_are_one_clear_line(files, cluster, tmp_path):
    paths, model, _ = files
    with pytest.raises(FtcalError, match=r"missing\.parquet: the Dask worker on .* cannot read this file; with "
                                         r"scheduler the paths must be visible to every worker"):
        cluster.map(file_error_sums, [paths[0], str(tmp_path / "missing.parquet")], model)
    with pytest.raises(FtcalError, match=r"a Dask worker died while running"):
        cluster.map(lambda path: os._exit(1), [paths[0]])  # the worker process exits: retried once, then an error
    assert cluster.map(len, paths) == [len(p) for p in paths]  # the cluster still works


def test_unreachable_scheduler_and_bad_addresses():
    with socket.socket() as probe:  # a loopback port that nothing listens on
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    with pytest.raises(FtcalError, match=rf"^scheduler tcp://127.0.0.1:{port}: cannot reach the Dask scheduler "
                                         r"within 1 s"):
        with open_executor(f"tcp://127.0.0.1:{port}", connect_timeout=1):
            pass
    for text in ("local:0", "local:x", "127.0.0.1:8786"):
        with pytest.raises(FtcalError, match="^scheduler"):
            parse_scheduler(text)


def test_cli_predict_on_a_local_cluster_matches_the_process(files, tmp_path):
    paths, model, model_path = files
    env = dict(os.environ, FTCAL_PROGRESS="0")
    for name, extra in (("here.csv", []), ("dask.csv", ["--scheduler", "local:2"])):
        done = subprocess.run([FTCAL, "predict", model_path, *paths, "-o", str(tmp_path / name), *extra],
                              capture_output=True, text=True, env=env, timeout=300)
        assert done.returncode == 0, done.stderr
    here, dask = pd.read_csv(tmp_path / "here.csv"), pd.read_csv(tmp_path / "dask.csv")
    assert list(dask.columns) == list(DEFAULT_OUTPUTS) and np.array_equal(here.to_numpy(), dask.to_numpy())
    inputs = whole(paths)[list(INPUTS)].to_numpy()
    assert np.allclose(dask.to_numpy(), model.predict(inputs, warn_out_of_range=False), rtol=1e-12, atol=1e-12)
    assert sorted(os.listdir(tmp_path)) == ["dask.csv", "here.csv"]  # no part folder left behind
    missing = subprocess.run([FTCAL, "predict", model_path, paths[0], str(tmp_path / "gone.parquet"), "-o",
                              str(tmp_path / "never.parquet")], capture_output=True, text=True, env=env, timeout=300)
    assert missing.returncode == 2 and missing.stderr.count("\n") == 1 and "gone.parquet: no such file" in missing.stderr
    assert not (tmp_path / "never.parquet").exists() and sorted(os.listdir(tmp_path)) == ["dask.csv", "here.csv"]


def test_an_existing_cluster_whose_workers_run_another_ftcal_is_refused(tmp_path):
    from distributed import Client, LocalCluster

    # A worker whose Python finds this ftcal 99.0 before the installed one, as after a partial upgrade.
    site = tmp_path / "site"
    (site / "ftcal-99.0.dist-info").mkdir(parents=True)
    (site / "ftcal-99.0.dist-info" / "METADATA").write_text("Metadata-Version: 2.1\nName: ftcal\nVersion: 99.0\n")
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(site), os.environ.get("PYTHONPATH", "")]))
    with LocalCluster(n_workers=0, processes=True, dashboard_address=":0") as cluster:
        worker = subprocess.Popen([os.path.join(os.path.dirname(sys.executable), "dask"), "worker",
                                   cluster.scheduler_address, "--nthreads", "1", "--no-nanny",
                                   "--no-dashboard"], env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        try:
            with Client(cluster.scheduler_address, timeout=30) as client:
                client.wait_for_workers(1, timeout=60)
            with pytest.raises(FtcalError, match=rf"^scheduler {cluster.scheduler_address}: worker tcp://\S+ runs "
                                                 r"ftcal 99.0 but this client runs \S+; install the same versions"):
                with open_executor(cluster.scheduler_address):
                    pass
        finally:
            worker.terminate()
            worker.wait(timeout=60)


def test_cli_predict_arx_one_task_per_file_matches_the_whole_data(files, tmp_path):
    from ftcal.core.solvers.least_squares import Ridge
    from ftcal.data.tables import load_dataset

    paths, _, _ = files
    data = load_dataset(paths, inputs=INPUTS, outputs=DEFAULT_OUTPUTS)
    # ridge: past outputs are nearly affine in past inputs on this data
    model = CalibrationModel(1, na=1, nb=1, solver=Ridge(1.0)).fit(data)
    save_model(model, tmp_path / "arx.json")
    env = dict(os.environ, FTCAL_PROGRESS="0")
    for name, extra in (("here.parquet", []), ("dask.parquet", ["--scheduler", "local:2"])):
        done = subprocess.run([FTCAL, "predict", str(tmp_path / "arx.json"), *paths, "--mode", "one-step", "-o",
                               str(tmp_path / name), *extra], capture_output=True, text=True, env=env, timeout=300)
        assert done.returncode == 0, done.stderr
    here, dask = pd.read_parquet(tmp_path / "here.parquet"), pd.read_parquet(tmp_path / "dask.parquet")
    assert np.array_equal(here.to_numpy(), dask.to_numpy())
    # each file is one segment: the same rows as predicting the concatenated data
    assert np.array_equal(dask.to_numpy(), model.predict(data, mode="one-step", warn_out_of_range=False))


def test_cli_evaluate_arx_on_a_local_cluster_matches_the_whole_data(files, tmp_path):
    from ftcal.core.solvers.least_squares import Ridge
    from ftcal.data.tables import load_dataset

    paths, _, _ = files
    model = CalibrationModel(1, na=2, nb=1, solver=Ridge(1.0)).fit(load_dataset(paths[:1], inputs=INPUTS, outputs=DEFAULT_OUTPUTS))
    save_model(model, tmp_path / "arx.json")
    env = dict(os.environ, FTCAL_PROGRESS="0")
    results = []
    for extra in ([], ["--scheduler", "local:2"]):
        done = subprocess.run([FTCAL, "evaluate", str(tmp_path / "arx.json"), *paths[1:], "--mode", "free-run",
                               "--json", *extra], capture_output=True, text=True, env=env, timeout=300)
        assert done.returncode == 0, done.stderr
        results.append(json.loads(done.stdout))
    here, dask = results  # here: the whole-data path (CalibrationModel.score on the files read together)
    assert dask["n_samples"] == here["n_samples"] == 1200 + 3100 - 2 * 2  # warm-up rows dropped per file
    for key in ("rmse", "best_fit", "max_abs_error", "residual_autocorrelation_lag1", "force_norm_rmse"):
        assert np.allclose(dask[key], here[key], rtol=1e-10, atol=0), key
    assert np.allclose(dask["one_step"]["rmse"], here["one_step"]["rmse"], rtol=1e-10, atol=0)


def test_file_statistics_tree_summed_on_dask_equal_the_dense_regressor(files, cluster):
    from conftest import reference_features

    from ftcal.core.features import MonomialBasis
    from ftcal.core.normalization import normalization_from_range
    from ftcal.data.streaming import add_statistics, file_statistics

    paths, _, _ = files
    data = whole(paths)
    u, y = data[list(INPUTS)].to_numpy(), data[list(DEFAULT_OUTPUTS)].to_numpy()
    norm = normalization_from_range(u.min(axis=0), u.max(axis=0))
    basis = MonomialBasis(len(INPUTS), 2)
    local = LocalExecutor().map_reduce(file_statistics, paths, basis, norm, INPUTS, DEFAULT_OUTPUTS,
                                       combine=add_statistics)
    remote = cluster.map_reduce(file_statistics, paths, basis, norm, INPUTS, DEFAULT_OUTPUTS, combine=add_statistics)
    assert np.array_equal(remote.gram, local.gram) and np.array_equal(remote.cross, local.cross)
    a = reference_features(norm.apply(u), 2)  # scikit-learn's monomials, offset last
    assert np.allclose(remote.gram, a.T @ a, rtol=1e-12, atol=1e-9) and np.allclose(remote.cross, a.T @ y, rtol=1e-12)
    assert remote.n_samples == len(u) == 2500 + 1200 + 3100


def _counting_reads(monkeypatch):
    """Patch the file reader behind iter_table_chunks; returns the list of files it actually reads."""
    from ftcal.data import table_chunks

    reads, original = [], table_chunks._read_table_chunks

    def counting(path, *rest):
        reads.append(str(path))
        yield from original(path, *rest)

    monkeypatch.setattr(table_chunks, "_read_table_chunks", counting)
    return reads


@pytest.mark.parametrize("suffix", [".csv", ".parquet"])
def test_kept_files_are_read_once_and_served_from_memory(tmp_path, monkeypatch, suffix):
    from ftcal.data.table_chunks import keep_in_memory

    (path,) = write_files(tmp_path, np.random.default_rng(4), [2600], suffix)
    frame = whole([path])
    reads = _counting_reads(monkeypatch)
    with keep_in_memory():
        first = list(iter_table_chunks(path, INPUTS, DEFAULT_OUTPUTS, labels={"u2": "group"}, chunk_rows=700))
        again = list(iter_table_chunks(path, INPUTS, DEFAULT_OUTPUTS, chunk_rows=700))
        inputs_only = list(iter_table_chunks(path, INPUTS, chunk_rows=700))
        assert len(reads) == 1
        other = list(iter_table_chunks(path, ["T"], ["Fz"], chunk_rows=700))  # other columns: the file again
        assert len(reads) == 2
    list(iter_table_chunks(path, INPUTS, DEFAULT_OUTPUTS))  # outside the block nothing is kept
    assert len(reads) == 3
    for chunks in (first, again, inputs_only):
        assert np.array_equal(np.vstack([c.inputs for c in chunks]), frame[list(INPUTS)].to_numpy())
    assert np.array_equal(np.vstack([c.outputs for c in again]), frame[list(DEFAULT_OUTPUTS)].to_numpy())
    assert all(c.outputs is None and not c.labels for c in inputs_only)
    assert all(set(c.labels) == set() for c in again)
    assert [c.first_row for c in again] == [c.first_row for c in first]
    assert np.array_equal(np.vstack([c.outputs for c in other]), frame[["Fz"]].to_numpy())


def test_a_kept_file_that_changes_or_is_too_large_is_read_again(tmp_path, monkeypatch):
    from ftcal.data import table_chunks
    from ftcal.data.table_chunks import keep_in_memory

    (path,) = write_files(tmp_path, np.random.default_rng(5), [1500], ".csv")
    reads = _counting_reads(monkeypatch)
    with keep_in_memory():
        list(iter_table_chunks(path, INPUTS, DEFAULT_OUTPUTS))
        frame = whole([path])
        frame["u1"] += 1.0
        frame.to_csv(path, index=False, float_format="%.17g")  # another size, another mtime
        changed = list(iter_table_chunks(path, INPUTS, DEFAULT_OUTPUTS))
    assert len(reads) == 2
    assert np.array_equal(np.vstack([c.inputs for c in changed]), frame[list(INPUTS)].to_numpy())
    # 1500 rows of 13 float64 columns are 156,000 bytes: over a 100,000-byte budget, streamed every time.
    monkeypatch.setattr(table_chunks, "KEEP_IN_MEMORY_BYTES", 100_000)
    with keep_in_memory():
        for _ in range(2):
            assert sum(c.n_rows for c in iter_table_chunks(path, INPUTS, DEFAULT_OUTPUTS, chunk_rows=500)) == 1500
    assert len(reads) == 4


def test_streamed_fit_without_keeping_files_equals_the_kept_fit(files, tmp_path, monkeypatch):
    """The fit's passes read every file each time when it is too large to keep: same model (1e-12)."""
    from ftcal.cli import main
    from ftcal.data import table_chunks
    from ftcal.files.model_files import load_model_file

    paths, _, _ = files
    assert main(["fit", *paths, "--degree", "3", "-o", str(tmp_path / "kept.json")]) == 0
    reads = _counting_reads(monkeypatch)
    monkeypatch.setattr(table_chunks, "KEEP_IN_MEMORY_BYTES", 0)
    assert main(["fit", *paths, "--degree", "3", "-o", str(tmp_path / "streamed.json")]) == 0
    # ranges and statistics in one read: the Parquet footers give the normalization (the training errors come
    # from the statistics); the explicit degree's grouped comparison with affine (issue 44) reads twice more,
    # the fold statistics of degree 3 and of affine
    assert len(reads) == 3 * len(paths)
    kept, streamed = (load_model_file(tmp_path / name).model for name in ("kept.json", "streamed.json"))
    assert np.max(np.abs(kept.coef_ - streamed.coef_)) <= 1e-12 * np.max(np.abs(streamed.coef_))
    assert kept.training_metrics_["rmse"] == pytest.approx(streamed.training_metrics_["rmse"], rel=1e-12)
