"""Hostile files that are well formed on the outside and wrong on the inside (issue 27, item 8).

Class (a): a ROS 2 ``.db3`` bag is an SQLite database, and SQLite stores any type in any column:
text timestamps, NULL or integer message data, negative or dangling topic ids. rosbags reads them
into Python and fails with a TypeError/ValueError traceback (before the fix: ``topics`` and
``dataset`` both ended in tracebacks). Class (b): a model or payload file that is schema-valid and
correctly signed (its digest recomputed after editing) but contradicts itself: an input range with
min > max (a traceback in ``convert --to paper-xml`` before the fix, silently accepted by every
other consumer), a scale too small to divide by, metrics for other outputs, a covariance that is
not one, an inertia no rigid body has.

The first class extends to a ROS 2 bag folder's ``metadata.yaml`` (a count written as text, a
topic name as a number: TypeErrors inside rosbags before the fix).

Every case runs the real command line as a subprocess and asserts exit 2, one line on stderr naming
the file and the field, no traceback and no output file.
"""

from __future__ import annotations

import json
import os
import shutil
import sqlite3
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from bag_data import Bag  # noqa: E402

FTCAL = str(Path(sys.executable).with_name("ftcal"))
SRC = str(Path(__file__).resolve().parents[2] / "src")


def run(*args, cwd):
    env = {**os.environ, "PYTHONPATH": SRC}
    return subprocess.run([FTCAL, *map(str, args)], capture_output=True, text=True, cwd=cwd, env=env, timeout=300)


def assert_refused(result, *names):
    lines = [line for line in result.stderr.splitlines() if line.strip()]
    assert result.returncode == 2, result.stderr
    assert "Traceback" not in result.stderr and len(lines) == 1, result.stderr
    for name in names:
        assert name in lines[0], (name, lines[0])


# ---------------------------------------------------------------- (a) db3 columns of the wrong type

@pytest.fixture(scope="module")
def good_db3(tmp_path_factory):
    rng = np.random.default_rng(0)
    bag = Bag("db3-file")
    for i in range(150):
        bag.wrench("/ft", 10**9 + i * 10**7, rng.normal(size=6))
        bag.joints("/joint_states", 10**9 + i * 10**7, ["a", "b"], [0.01 * i, 0.2])
    return bag.write(tmp_path_factory.mktemp("bag") / "good")


def _hostile_db3(good: Path, out: Path, sql: str) -> Path:
    """A copy of ``good`` whose tables have no NOT NULL constraints (SQLite allows that), then ``sql``."""
    shutil.copy(good, out)
    con = sqlite3.connect(out)
    for table, columns in (("messages", "id INTEGER PRIMARY KEY, topic_id, timestamp, data"),
                           ("topics", "id, name, type, serialization_format, offered_qos_profiles, "
                                      "type_description_hash")):
        con.execute(f"ALTER TABLE {table} RENAME TO old_{table}")
        con.execute(f"CREATE TABLE {table}({columns})")
        con.execute(f"INSERT INTO {table} SELECT * FROM old_{table}")
        con.execute(f"DROP TABLE old_{table}")
    con.execute(sql)
    con.commit()
    con.close()
    return out


DB3_CASES = {
    "text timestamp": ("UPDATE messages SET timestamp = 'abc' WHERE id = 3", "timestamp"),
    "blob timestamp": ("UPDATE messages SET timestamp = x'0102' WHERE id = 3", "timestamp"),
    "real timestamp": ("UPDATE messages SET timestamp = 1.5 WHERE id = 3", "timestamp"),
    "NULL timestamp": ("UPDATE messages SET timestamp = NULL WHERE id = 3", "timestamp"),
    "negative timestamp": ("UPDATE messages SET timestamp = -5 WHERE id = 3", "timestamp"),
    "int64 max timestamp": ("UPDATE messages SET timestamp = 9223372036854775807 WHERE id = 3", "timestamp"),
    "NULL data": ("UPDATE messages SET data = NULL WHERE id = 3", "data"),
    "integer data": ("UPDATE messages SET data = 5 WHERE id = 3", "data"),
    "text data of joints": ("UPDATE messages SET data = 'hello' WHERE topic_id = 2", "data"),
    "negative topic id": ("UPDATE messages SET topic_id = -1 WHERE id = 3", "topic_id"),
    "text topic id": ("UPDATE topics SET id = 'x' WHERE id = 1", "id"),
    "NULL topic name": ("UPDATE topics SET name = NULL WHERE id = 1", "name"),
    "integer message type": ("UPDATE topics SET type = 5 WHERE id = 1", "type"),
    "integer qos": ("UPDATE topics SET offered_qos_profiles = 7", "offered_qos_profiles"),
}


@pytest.mark.parametrize("case", list(DB3_CASES))
def test_db3_columns_of_the_wrong_type_are_refused_by_dataset_and_topics(tmp_path, good_db3, case):
    sql, column = DB3_CASES[case]
    bag = _hostile_db3(good_db3, tmp_path / "hostile.db3", sql)
    assert_refused(run("topics", bag, cwd=tmp_path), "hostile.db3", column)
    out = tmp_path / "d.parquet"
    assert_refused(run("dataset", bag, "--wrench-topic", "/ft", "--joints-topic", "/joint_states",
                       "--no-filter", "-o", out, cwd=tmp_path), "hostile.db3", column)
    assert not out.exists()


@pytest.fixture(scope="module")
def good_folder(tmp_path_factory):
    rng = np.random.default_rng(1)
    bag = Bag("db3")
    for i in range(150):
        bag.wrench("/ft", 10**9 + i * 10**7, rng.normal(size=6))
    return bag.write(tmp_path_factory.mktemp("folder") / "run")


METADATA_CASES = {
    "text message count": ("\n  message_count: 150", "\n  message_count: abc", "message_count"),
    "text duration": ("nanoseconds: 1490000000", "nanoseconds: xyz", "duration.nanoseconds"),
    "integer topic name": ("name: /ft", "name: 7", "topic_metadata.name"),
    "list message type": ("type: geometry_msgs/msg/WrenchStamped", "type: [1, 2]", "topic_metadata.type"),
    "null start time": ("\n  starting_time:\n    nanoseconds_since_epoch: 1000000000",
                        "\n  starting_time:\n    nanoseconds_since_epoch: null", "starting_time"),
    "integer file list": ("  files:", "  files: 7\n  old_files:", "files"),
    "text version": ("version: 9", "version: nine", "version"),
}


@pytest.mark.parametrize("case", list(METADATA_CASES))
def test_bag_folder_metadata_of_the_wrong_type_is_refused(tmp_path, good_folder, case):
    """The same class in a ROS 2 bag folder's metadata.yaml (TypeError tracebacks inside rosbags before)."""
    old, new, field = METADATA_CASES[case]
    folder = tmp_path / "hostile"
    shutil.copytree(good_folder, folder)
    text = (folder / "metadata.yaml").read_text()
    assert old in text
    (folder / "metadata.yaml").write_text(text.replace(old, new, 1))
    assert_refused(run("topics", folder, cwd=tmp_path), "hostile", "metadata.yaml", field)
    out = tmp_path / "d.parquet"
    assert_refused(run("dataset", folder, "--wrench-topic", "/ft", "--no-filter", "-o", out, cwd=tmp_path),
                   "hostile", field)
    assert not out.exists()


def test_the_untouched_db3_still_reads(tmp_path, good_db3):
    """The check must not refuse a bag rosbags' own writer made (same tables, constraints removed)."""
    bag = _hostile_db3(good_db3, tmp_path / "same.db3", "SELECT 1")
    result = run("dataset", bag, "--wrench-topic", "/ft", "--no-filter", "-o", tmp_path / "d.parquet", cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    assert len(pd.read_parquet(tmp_path / "d.parquet")) == 150


# ---------------------------------------------------------------- (b) signed but inconsistent files

@pytest.fixture(scope="module")
def models(tmp_path_factory):
    """A degree-2 polynomial and an MLP fitted by the CLI on a small known table."""
    folder = tmp_path_factory.mktemp("models")
    rng = np.random.default_rng(1)
    u = rng.normal(size=(300, 3))
    y = np.c_[u @ [1.0, 2.0, 3.0] + 0.1 * u[:, 0] ** 2, u @ [0.0, 1.0, -1.0]] + 0.01 * rng.normal(size=(300, 2))
    table = pd.DataFrame(np.c_[u, y], columns=["u1", "u2", "u3", "Fx", "Fy"])
    table["group"] = np.arange(300) // 50
    table.to_csv(folder / "t.csv", index=False)
    for name, extra in (("poly", ["--degree", "2"]), ("mlp", ["--family", "mlp"])):
        result = run("fit", "t.csv", "--inputs", "u1,u2,u3", "--outputs", "Fx,Fy", *extra, "-o", f"{name}.json",
                     cwd=folder)
        assert result.returncode == 0, result.stderr
    return folder


def _resigned(source: Path, out: Path, edit) -> Path:
    from ftcal.files.model_json import digest

    doc = json.loads(source.read_text())
    edit(doc)
    doc["sha256"] = digest(doc)
    out.write_text(json.dumps(doc))
    return out


def _set(path, value):
    def edit(doc):
        node = doc
        for key in path[:-1]:
            node = node[key]
        node[path[-1]] = value
    return edit


MODEL_CASES = {
    "input range min > max": ("poly", _set(["inputs", 0, "range"], [3.0, -3.0]), "inputs[0]"),
    "output range min > max": ("poly", _set(["outputs", 1, "range"], [3.0, -3.0]), "outputs[1]"),
    "subnormal input scale": ("poly", _set(["inputs", 0, "scale"], 5e-324), "inputs[0]"),
    "subnormal output scale": ("poly", _set(["outputs", 0, "scale"], 1e-320), "outputs[0]"),
    "offset that overflows the basis": ("poly", _set(["inputs", 0, "offset"], 1e308), "overflows"),
    "metrics for other outputs": ("poly", _set(["fit", "metrics", "outputs"], ["Fx", "Fy", "Fz"]), "fit.metrics"),
    "rank above the term count": ("poly", _set(["fit", "rank"], 10**9), "fit.rank"),
    "asymmetric covariance": ("poly", _set(["fit", "input_spread", "covariance", 0, 1], 5.0), "covariance"),
    "negative variance": ("poly", _set(["fit", "input_spread", "covariance", 0, 0], -1.0), "covariance"),
    "mlp input range min > max": ("mlp", _set(["inputs", 1, "range"], [2.0, -2.0]), "inputs[1]"),
    "mlp weights that overflow": ("mlp", lambda d: d["parameters"]["layers"][-1].__setitem__(
        "weights", [[1e308] * 2 for _ in d["parameters"]["layers"][-1]["weights"]]), "overflows"),
}


@pytest.mark.parametrize("case", list(MODEL_CASES))
def test_signed_but_inconsistent_model_files_are_refused_by_every_consumer(tmp_path, models, case):
    base, edit, field = MODEL_CASES[case]
    model = _resigned(models / f"{base}.json", tmp_path / "hostile.json", edit)
    shutil.copy(models / "t.csv", tmp_path / "t.csv")
    commands = [("info", model), ("predict", model, "t.csv", "-o", "p.csv"), ("evaluate", model, "t.csv"),
                ("report", model, "t.csv", "-o", "r.html"), ("convert", model, "--to", "onnx", "-o", "m.onnx")]
    if base == "poly":
        commands.append(("convert", model, "--to", "paper-xml", "-o", "m.xml"))
    for command in commands:
        assert_refused(run(*command, cwd=tmp_path), "hostile.json", field)
    assert not any((tmp_path / name).exists() for name in ("p.csv", "r.html", "m.onnx", "m.xml"))


def test_the_untouched_models_still_load(tmp_path, models):
    for base in ("poly", "mlp"):
        model = _resigned(models / f"{base}.json", tmp_path / f"{base}.json", lambda doc: None)
        assert run("info", model, cwd=tmp_path).returncode == 0


PAYLOAD = dict(mass=1.5, com=[0.0, 0.01, 0.08], force_bias=[0.3, -1.0, 2.0], torque_bias=[0.01, 0.02, -0.03])
PAYLOAD_CASES = {
    "asymmetric inertia": (_set(["inertia"], [[0.01, 0.005, 0.0], [0.0, 0.01, 0.0], [0.0, 0.0, 0.01]]), "inertia"),
    "inertia breaking the triangle inequality": (_set(["inertia"], [[0.01, 0, 0], [0, 0.01, 0], [0, 0, 0.05]]),
                                                 "inertia"),
    "drift that ends before it starts": (_set(["drift"], {"model": "linear", "time_column": "time",
                                                          "time_start": 10.0, "time_end": 2.0}), "drift.time_start"),
}


@pytest.mark.parametrize("case", list(PAYLOAD_CASES))
def test_signed_but_inconsistent_payload_files_are_refused(tmp_path, case):
    from ftcal.files.payload_json import save_payload
    from ftcal.payload.parameters import PayloadParameters

    good = tmp_path / "good.json"
    save_payload(PayloadParameters(**{k: np.asarray(v) if k != "mass" else v for k, v in PAYLOAD.items()},
                                   gravity=9.81, frame="ft",
                                   stderr={"mass": 0.01, "com": np.full(3, 1e-3), "force_bias": np.full(3, 0.01),
                                           "torque_bias": np.full(3, 1e-3)},
                                   fit={"n_samples": 100, "residual_rms": np.full(6, 0.01), "condition_number": 3.0,
                                        "wrench_columns": ["Fx", "Fy", "Fz", "Tx", "Ty", "Tz"]}), good)
    assert run("convert", good, "--to", "ros-yaml", "-o", "g.yaml", cwd=tmp_path).returncode == 0
    edit, field = PAYLOAD_CASES[case]
    payload = _resigned(good, tmp_path / "hostile.json", edit)
    assert_refused(run("convert", payload, "--to", "ros-yaml", "-o", "p.yaml", cwd=tmp_path), "hostile.json", field)
    assert not (tmp_path / "p.yaml").exists()
