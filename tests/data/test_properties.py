"""Property-based tests (Hypothesis) over the file formats ftcal reads and writes, and over the invariants
that must hold whatever the input (issue 28):

* NaN never passes acceptance; a threshold that is not finite never passes;
* a file we read either loads into finite, plausible values or is refused with one FtcalError (model,
  payload, plan ``--from`` tables, data tables, history databases, bags): never another exception;
* the history round-trips what it stores (a non-finite RMS as NaN), and a damaged history file is
  refused or read, never a traceback;
* an output written with exit 0 is complete and finite (``fit``), and a refusal leaves no output.

Example counts are kept modest (``max_examples`` 25–40, no deadline) so the suite stays fast.
"""

import json
import math
import shutil
import string
import sys
import warnings
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

from ftcal import CalibrationModel, Dataset, save_model
from ftcal.check.accept import Thresholds, acceptance_test
from ftcal.check.history import CalibrationSummary, History
from ftcal.files.model_json import digest
from ftcal.files.payload_json import parse_payload, save_payload
from ftcal.payload.parameters import PayloadParameters
from ftcal.runtime.errors import FtcalError

AXES = ("Fx", "Fy", "Fz", "Tx", "Ty", "Tz")
FAST = settings(max_examples=30, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
SLOW = settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])

finite = st.floats(allow_nan=False, allow_infinity=False, width=64)
anything_numeric = st.one_of(st.floats(width=64), st.integers(min_value=-10**30, max_value=10**30))
json_values = st.recursive(
    st.one_of(st.none(), st.booleans(), anything_numeric, st.text(max_size=8)),
    lambda children: st.one_of(st.lists(children, max_size=4), st.dictionaries(st.text(max_size=4), children,
                                                                                max_size=3)),
    max_leaves=8)


def reseal(doc: dict) -> None:
    """Recompute the digest as an attacker would (a document with NaN/inf has none that ftcal would accept)."""
    try:
        doc["sha256"] = digest(doc)
    except (ValueError, TypeError):
        pass


# ---------------------------------------------------------------------------------- acceptance
@FAST
@given(st.integers(1, 60), st.integers(1, 4), st.data())
def test_a_non_finite_error_never_passes(n, n_poses, data):
    error = np.array(data.draw(st.lists(st.lists(finite.map(lambda v: math.copysign(min(abs(v), 1e-3), v)),
                                                 min_size=6, max_size=6), min_size=n, max_size=n)))
    row, col = data.draw(st.integers(0, n - 1)), data.draw(st.integers(0, 5))
    error[row, col] = data.draw(st.sampled_from([np.nan, np.inf, -np.inf]))
    labels = np.array([f"p{k % n_poses}" for k in range(n)], dtype=object)
    result = acceptance_test(error, labels, AXES, Thresholds(1e300, 1e300))
    assert not result.passed and result.problems


@FAST
@given(st.sampled_from([np.nan, np.inf, -np.inf, 0.0, -1.0]), st.booleans())
def test_a_threshold_that_is_not_finite_and_positive_never_passes(bad, on_force):
    limits = (bad, 0.1) if on_force else (1.0, bad)
    result = acceptance_test(np.zeros((5, 6)), np.zeros(5), AXES, Thresholds(*limits))
    assert not result.passed


# ---------------------------------------------------------------------------------- payload files
@pytest.fixture(scope="module")
def payload_doc(tmp_path_factory):
    stderr = {"mass": 0.01, "com": np.full(3, 0.001), "force_bias": np.full(3, 0.01), "torque_bias": np.full(3, 0.001)}
    fit = {"n_samples": 100, "residual_rms": np.full(6, 0.01), "condition_number": 3.0,
           "wrench_columns": ["u1", "u2", "u3", "u4", "u5", "u6"]}
    payload = PayloadParameters(1.5, np.array([0.0, 0.01, 0.05]), np.array([1.0, -2.0, 0.5]),
                                np.array([0.1, 0.0, -0.1]), 9.81, stderr=stderr, fit=fit)
    path = tmp_path_factory.mktemp("payload") / "p.json"
    save_payload(payload, path)
    return json.loads(path.read_text())


@FAST
@given(st.sampled_from(["mass", "gravity", "com", "force_bias", "torque_bias", "frame", "reaction", "stderr", "fit"]),
       json_values)
def test_a_payload_file_loads_plausible_values_or_is_refused(payload_doc, key, value):
    doc = json.loads(json.dumps(payload_doc))
    doc[key] = value
    reseal(doc)
    text = json.dumps(doc, allow_nan=True)
    try:
        payload = parse_payload(text, "p.json")
    except FtcalError as exc:
        assert "\n" not in str(exc)
        return
    assert 0 < payload.mass <= 1000 and 0.1 <= payload.gravity <= 100
    assert np.all(np.isfinite(payload.com)) and np.all(np.isfinite(payload.bias))


# ---------------------------------------------------------------------------------- model files
@pytest.fixture(scope="module")
def model_text(tmp_path_factory):
    rng = np.random.default_rng(0)
    u = rng.uniform(-1, 1, (300, 3))
    model = CalibrationModel(degree=2).fit(Dataset.from_arrays(u, u @ rng.normal(size=(3, 6)),
                                                               input_names=["u1", "u2", "u3"]))
    path = tmp_path_factory.mktemp("model") / "m.json"
    save_model(model, path)
    return path.read_text()


def _paths(doc, prefix=()):
    if isinstance(doc, dict):
        for k, v in doc.items():
            yield from _paths(v, (*prefix, k))
    elif isinstance(doc, list):
        for i, v in enumerate(doc[:3]):
            yield from _paths(v, (*prefix, i))
    if prefix and prefix[0] != "sha256":
        yield prefix


@FAST
@given(st.data(), json_values)
def test_a_model_file_loads_a_finite_model_or_is_refused(tmp_path_factory, model_text, data, value):
    from ftcal.files.model_files import load_model

    doc = json.loads(model_text)
    where = data.draw(st.sampled_from(sorted(_paths(doc), key=str)))
    holder = doc
    for k in where[:-1]:
        holder = holder[k]
    holder[where[-1]] = value
    reseal(doc)
    path = tmp_path_factory.mktemp("m") / "m.json"
    path.write_text(json.dumps(doc, allow_nan=True))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        try:
            model = load_model(path)
        except FtcalError as exc:
            assert "\n" not in str(exc)
            return
        prediction = model.predict(np.zeros((2, len(model.input_names_))), warn_out_of_range=False)
    assert prediction.shape[0] == 2


# ---------------------------------------------------------------------------------- tables and plans
cells = st.one_of(finite.map(lambda v: repr(float(v))), st.sampled_from(["nan", "inf", "-inf", "", "x", "1e400",
                                                                          "1e-400", "0x10", "true", '"1,5"']))


@pytest.mark.slow
@SLOW
@given(st.lists(st.lists(cells, min_size=4, max_size=4), min_size=0, max_size=12))
def test_fit_on_any_table_writes_a_finite_model_or_refuses_leaving_nothing(tmp_path_factory, rows):
    from ftcal.cli import main

    folder = tmp_path_factory.mktemp("fit")
    (folder / "t.csv").write_text("u1,u2,Fx,Fy\n" + "".join(",".join(r) + "\n" for r in rows))
    out = folder / "m.json"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        try:
            code = main(["fit", str(folder / "t.csv"), "--inputs", "u1,u2", "--outputs", "Fx,Fy", "--degree", "1",
                         "-o", str(out)])
        except SystemExit as exc:
            code = exc.code
    if code == 0:
        doc = json.loads(out.read_text())  # strict JSON has no NaN: a non-finite number would not parse back
        assert doc["sha256"] == digest(doc)
    else:
        assert code == 2 and not out.exists()
    shutil.rmtree(folder, ignore_errors=True)


@FAST
@given(st.lists(st.lists(anything_numeric, min_size=6, max_size=6), min_size=1, max_size=6))
def test_a_recorded_plan_table_is_finite_or_refused(tmp_path_factory, rows):
    from ftcal.plan.recorded import read_recorded
    from ftcal.robot import RobotModel
    from ftcal.sim.plan_arm import ARM_URDF

    folder = tmp_path_factory.mktemp("rec")
    pd.DataFrame(rows, columns=list(AXES)).to_csv(folder / "r.csv", index=False)
    robot = RobotModel.from_text(ARM_URDF)
    try:
        rec = read_recorded(folder / "r.csv", robot, robot.ft_sensors[0].name)
    except FtcalError:
        return
    assert np.all(np.isfinite(rec.wrench)) and np.abs(rec.wrench).max() <= 1e6


# ---------------------------------------------------------------------------------- history
names = st.text(alphabet=st.characters(blacklist_categories=("Cs",)), min_size=1, max_size=12)


@FAST
@given(names, st.lists(st.one_of(finite, st.just(math.nan), st.just(math.inf)), min_size=6, max_size=6),
       st.booleans())
def test_the_history_round_trips_what_it_stores(tmp_path_factory, serial, rmse, passed):
    folder = tmp_path_factory.mktemp("history")
    summary = CalibrationSummary("a" * 64, "m.json", AXES, np.arange(6.0), np.eye(6))
    with History(folder) as history:
        with history.transaction() as conn:
            history.append_calibration(conn, serial, summary)
            history.append_acceptance(conn, serial, "a" * 64, passed, rmse, {"force": 1.0}, ["d.csv"])
    with History(folder, read_only=True) as history:
        (calibration,) = history.calibrations(serial)
        (acceptance,) = history.acceptances(serial)
        assert serial in history.serials()
    np.testing.assert_array_equal(calibration.summary.bias, np.arange(6.0))
    stored = np.array(acceptance.rmse)
    expected = np.array(rmse)
    assert acceptance.passed == passed
    assert np.array_equal(np.isfinite(stored), np.isfinite(expected))
    np.testing.assert_array_equal(stored[np.isfinite(expected)], expected[np.isfinite(expected)])


@pytest.fixture(scope="module")
def history_bytes(tmp_path_factory):
    folder = tmp_path_factory.mktemp("hist")
    with History(folder) as history:
        for k in range(30):
            history.record_calibration("SN1", CalibrationSummary(f"{k:064d}", f"{k}.json", AXES, np.full(6, k),
                                                                 np.eye(6)))
    return (folder / "history.sqlite").read_bytes()


@SLOW
@given(st.lists(st.tuples(st.integers(0, 10**9), st.integers(0, 7)), min_size=1, max_size=16), st.booleans())
@example(flips=[(2416, 7)], truncate=False)  # found by this test: a text byte that is not UTF-8 (UnicodeDecodeError)
def test_a_damaged_history_is_read_or_refused_in_one_line(tmp_path_factory, history_bytes, flips, truncate):
    data = bytearray(history_bytes)
    for position, bit in flips:
        data[position % len(data)] ^= 1 << bit
    if truncate:
        data = data[:flips[0][0] % len(data)]
    folder = tmp_path_factory.mktemp("damaged")
    (folder / "history.sqlite").write_bytes(bytes(data))
    try:
        with History(folder, read_only=True) as history:
            history.calibrations("SN1")
            history.acceptances("SN1")
            history.serials()
    except FtcalError as exc:
        assert "\n" not in str(exc)


# ---------------------------------------------------------------------------------- bags
@pytest.fixture(scope="module")
def bag_bytes(tmp_path_factory):
    from bag_data import Bag

    bag = Bag("mcap-file")
    rng = np.random.default_rng(0)
    for i in range(20):
        bag.wrench("/ft", 10**9 + i * 10**7, rng.normal(size=6))
        bag.joints("/joint_states", 10**9 + i * 10**7, ("a", "b")[: 1 + i % 2], [0.1] * (1 + i % 2))
    path = bag.write(tmp_path_factory.mktemp("bag") / "run")
    return path.read_bytes(), path.suffix


@pytest.mark.slow
@SLOW
@given(st.lists(st.tuples(st.integers(0, 10**9), st.integers(0, 7)), min_size=1, max_size=8))
@example(flips=[(14, 0)])  # found by this test: a record length of petabytes (MemoryError in rosbags)
@example(flips=[(22568, 4)])  # found by this test: a damaged MCAP message index (numpy buffer size)
def test_a_damaged_bag_lists_its_topics_or_is_refused(tmp_path_factory, bag_bytes, flips):
    from ftcal.data.bags import list_topics

    raw, suffix = bag_bytes
    data = bytearray(raw)
    for position, bit in flips:
        data[position % len(data)] ^= 1 << bit
    path = tmp_path_factory.mktemp("badbag") / f"run{suffix}"
    path.write_bytes(bytes(data))
    try:
        topics = list_topics(path)
    except FtcalError as exc:
        assert "\n" not in str(exc)
        return
    assert all(isinstance(t.name, str) for t in topics)


# ---------------------------------------------------------------------------------- options used or refused
@FAST
@given(st.sampled_from(["--dynamic", "--bias-drift linear", "--group-by g", "--frame f", "--temperature u1"]))
def test_rebias_refuses_every_option_it_would_ignore(tmp_path_factory, payload_doc, option):
    from ftcal.cli import main

    folder = tmp_path_factory.mktemp("rebias")
    (folder / "p.json").write_text(json.dumps(payload_doc))
    frame = pd.DataFrame(np.zeros((4, 10)) + [0, 0, 15, 0, 0, 0, 0, 0, 0, 1],
                         columns=["u1", "u2", "u3", "u4", "u5", "u6", "qx", "qy", "qz", "qw"])
    frame.to_csv(folder / "d.csv", index=False)
    try:
        code = main(["payload", "--rebias", str(folder / "p.json"), str(folder / "d.csv"), "--orientation",
                     "qx,qy,qz,qw", "-o", str(folder / "q.json"), *option.split()])
    except SystemExit as exc:
        code = exc.code
    assert code == 2 and not (folder / "q.json").exists()
