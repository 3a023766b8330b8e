"""Steps that take objects (issue 43): ``fit(data, model)`` with a model, a network or a ``ModelSearch``; the
simulate and live steps as library calls, equal to their commands.

References: scikit-learn's PolynomialFeatures and numpy's lstsq (the fitted models, a grouped cross-validation
by hand), the simulated truth (a cubic term only degree 3 holds; a constant bias under gravity that turns), and
the commands themselves for the CLI/Python equality.
"""

from __future__ import annotations

import inspect
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from sklearn.preprocessing import PolynomialFeatures

import ftcal
from ftcal.core.mlp import MLPModel
from ftcal.core.solvers.least_squares import Ridge
from ftcal.runtime.errors import NotFittedError, ParameterError
from ftcal.workflow.fitting import payload_keywords

FTCAL = str(Path(sys.executable).with_name("ftcal"))


@pytest.fixture(scope="module")
def cubic():
    """Four load cases of a sensor whose Fx holds u1²·u2: degree 3 and above represent it, 1 and 2 do not."""
    rng = np.random.default_rng(0)
    u, groups = rng.uniform(-1, 1, (400, 2)), np.repeat(np.arange(4), 100)
    y = 2 * u[:, 0] + u[:, 0] ** 2 * u[:, 1] + 0.05 * rng.normal(size=400)
    return u, y, groups, pd.DataFrame({"u1": u[:, 0], "u2": u[:, 1], "Fx": y, "load": groups})


COLUMNS = dict(inputs=["u1", "u2"], outputs=["Fx"])


def test_a_search_is_an_estimator_whose_scores_are_a_grouped_cross_validation_by_hand(cubic):
    u, y, groups, frame = cubic
    search = ftcal.ModelSearch(max_degree=3, penalties=(), folds=4)
    with pytest.raises(NotFittedError):
        search.predict(u)
    assert search.fit(frame, group_by="load", **COLUMNS) is search
    by_hand = []
    for degree in (1, 2, 3):
        A = PolynomialFeatures(degree).fit_transform(u)
        rmse = []
        for held in range(4):
            train = groups != held
            coef = np.linalg.lstsq(A[train], y[train], rcond=None)[0]
            rmse.append(np.sqrt(np.mean((A[~train] @ coef - y[~train]) ** 2)))
        by_hand.append(rmse)
    assert search.cv_results_["degree"] == [1, 2, 3] and search.metric_ == "mean RMSE"
    # one fold per load case (their order is the search's)
    np.testing.assert_allclose(np.sort(search.cv_results_["split_test_scores"]), np.sort(by_hand), rtol=1e-8)
    np.testing.assert_allclose(search.cv_results_["mean_test_score"], np.mean(by_hand, axis=1), rtol=1e-8)
    assert search.best_params_ == {"degree": 3, "penalty": "none", "lambda": None}
    # best_estimator_: degree 3 refitted on every group, as lstsq on all the rows
    A = PolynomialFeatures(3).fit_transform(u)
    expected = A @ np.linalg.lstsq(A, y, rcond=None)[0]
    np.testing.assert_allclose(search.predict(u)[:, 0], expected, rtol=1e-8, atol=1e-10)
    table = search.to_frame()
    assert list(table["degree"]) == [1, 2, 3] and np.allclose(table["mean_test_score"], np.mean(by_hand, axis=1))
    # the same search through fit()'s keywords gives the same model and report
    keywords = ftcal.fit(frame, degree="auto", max_degree=3, penalties=(), folds=4, group_by="load", **COLUMNS)
    np.testing.assert_array_equal(keywords.model.coef_, search.best_estimator_.coef_)
    assert keywords.selection.as_dict()["candidates"] == search.selection_.as_dict()["candidates"]


def test_a_model_object_is_fitted_as_its_keywords_say(cubic, ref_features):
    u, y, _, frame = cubic
    plain = ftcal.fit(frame, ftcal.CalibrationModel(2), **COLUMNS).model
    A = ref_features(u, 2)
    np.testing.assert_allclose(plain.predict(u)[:, 0], A @ np.linalg.lstsq(A, y, rcond=None)[0], rtol=1e-8,
                               atol=1e-10)
    ridge = ftcal.fit(frame, ftcal.CalibrationModel(3, solver=Ridge(0.5)), **COLUMNS)
    same = ftcal.fit(frame, degree=3, ridge=0.5, **COLUMNS)
    np.testing.assert_array_equal(ridge.model.coef_, same.model.coef_)
    assert ridge.summary() == same.summary()


def test_a_fit_result_holds_its_training_errors_as_numbers(cubic, ref_features):
    u, y, _, frame = cubic
    result = ftcal.fit(frame, ftcal.CalibrationModel(2), **COLUMNS)
    A = ref_features(u, 2)
    residual = A @ np.linalg.lstsq(A, y, rcond=None)[0] - y
    table = result.to_frame()
    assert result.n_samples == 400 and list(table.index) == ["Fx"]
    np.testing.assert_allclose(table.loc["Fx", "rmse"], np.sqrt(np.mean(residual ** 2)), rtol=1e-8)
    if "max_abs_error" in table:  # a streamed fit scores from the statistics, which hold no maximum
        np.testing.assert_allclose(table.loc["Fx", "max_abs_error"], np.abs(residual).max(), rtol=1e-8)
    np.testing.assert_allclose(table.loc["Fx", "best_fit"],
                               1 - np.sqrt(np.mean(residual ** 2) / np.var(y)), rtol=1e-8)  # the paper's BestFit


def test_a_network_object_is_the_mlp_family(cubic):
    _, _, _, frame = cubic
    network = ftcal.fit(frame, MLPModel((4,), max_iter=30, seed=3), **COLUMNS).model
    keywords = ftcal.fit(frame, family="mlp", hidden=(4,), max_iter=30, seed=3, **COLUMNS).model
    assert network.family == "mlp" and network.describe()["hidden"] == [4]
    np.testing.assert_array_equal(network.predict(frame[["u1", "u2"]].to_numpy()),
                                  keywords.predict(frame[["u1", "u2"]].to_numpy()))


@pytest.mark.parametrize("model, keywords, named", [
    (ftcal.CalibrationModel(2), dict(degree=3), ("model", "degree")),
    (ftcal.ModelSearch(), dict(folds=3), ("model", "folds")),
    (3, {}, ("model",)),
    (None, dict(payload=7), ("payload",)),
])
def test_what_an_object_sets_cannot_be_given_beside_it(cubic, model, keywords, named):
    with pytest.raises(ParameterError) as caught:
        ftcal.fit(cubic[3], model, **keywords, **COLUMNS)
    assert caught.value.parameters == named and "--" not in str(caught.value)


def test_the_payload_argument_is_the_link_and_its_mass():
    assert payload_keywords("tool_link") == {"estimate_payload": "tool_link"}
    assert payload_keywords(("tool_link", 1.5)) == {"estimate_payload": "tool_link", "payload_mass": 1.5}
    assert payload_keywords({"link": "l", "mass": 2.0}) == {"estimate_payload": "l", "payload_mass": 2.0}


def test_the_simulate_step_is_the_command(tmp_path):
    from ftcal.robot.model import RobotModel
    from ftcal.sim.plan_arm import ARM_URDF
    from ftcal.sim.simulate import simulate

    urdf = tmp_path / "arm.urdf"
    urdf.write_text(ARM_URDF)
    joints = RobotModel.load(urdf).joint_names
    plan = tmp_path / "plan.csv"
    pd.DataFrame([[0.0] * len(joints), [0.4] * len(joints)], columns=joints).to_csv(plan, index=False)
    result = simulate(plan, urdf=urdf, hold=0.4, rate=20.0, formats=("table",), seed=4, output=tmp_path / "py")
    done = subprocess.run([FTCAL, "simulate", str(plan), "--urdf", str(urdf), "--hold", "0.4", "--rate", "20",
                           "--format", "table", "--seed", "4", "-o", str(tmp_path / "cli")],
                          capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == result.summary().replace(str(tmp_path / "py"), str(tmp_path / "cli"))
    truth = json.loads((tmp_path / "py" / "truth.json").read_text())
    assert truth == json.loads(json.dumps(result.truth))
    assert (tmp_path / "cli" / "truth.json").read_bytes() == (tmp_path / "py" / "truth.json").read_bytes()
    # two poses held 0.4 s at 20 Hz: each hold has floor(0.4 * 20) + 1 = 9 samples (by hand), plus the move
    recording = result.recordings[0]
    assert len(recording["holds"]) == 2 and recording["n_samples"] > 2 * 9


def test_the_info_step_is_the_command(tmp_path, cubic):
    from ftcal.files.model_files import save_model
    from ftcal.workflow.info import model_info

    u, y, _, _ = cubic
    path = tmp_path / "m.json"
    save_model(ftcal.CalibrationModel(2).fit(u, y[:, None]), path)
    result = model_info(path, terms=3)
    done = subprocess.run([FTCAL, "info", str(path), "--terms", "3"], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    assert done.stdout == result.summary() + "\n"
    # degree 2 over 2 inputs: C(4, 2) = 6 coefficients (by hand); three largest terms listed
    assert result.facts["n_coefficients"] == 6 and len(result.facts["largest"]) == 3
    assert json.loads(result.to_json())["facts"]["polynomial"] is True


def test_the_live_step_is_the_command_and_tracks_a_constant_bias(tmp_path):
    from ftcal.workflow.live import LiveSetup, replay_live

    # A bare sensor (no tool) reading a constant bias in holds of 5 s at turning orientations: what it
    # tracks is the bias.
    rng = np.random.default_rng(2)
    n, bias = 3000, np.array([3.0, -2.0, 1.0, 0.2, -0.1, 0.05])
    t = np.arange(n) / 100.0
    angle = 0.3 * (np.floor(t / 5.0) % 3)
    gravity = 9.81 * np.c_[np.sin(angle), np.zeros(n), -np.cos(angle)]
    wrench = bias + 0.02 * rng.normal(size=(n, 6))
    table = pd.DataFrame(np.c_[t, wrench, gravity], columns=["time", "Fx", "Fy", "Fz", "Tx", "Ty", "Tz",
                                                             "gx", "gy", "gz"])
    data = tmp_path / "live.parquet"
    table.to_parquet(data)
    columns = dict(inputs=("Fx", "Fy", "Fz", "Tx", "Ty", "Tz"), gravity_columns=("gx", "gy", "gz"))
    result = replay_live(data, LiveSetup(), output=tmp_path / "py.parquet", **columns)
    assert result.replay.n_samples == n and result.tool == "none"
    np.testing.assert_allclose(result.bias, bias, atol=0.02)
    done = subprocess.run([FTCAL, "live", "--replay", str(data), "--inputs", "Fx,Fy,Fz,Tx,Ty,Tz", "--gravity-columns",
                           "gx,gy,gz", "-o", str(tmp_path / "cli.parquet")], capture_output=True, text=True,
                          timeout=600)
    assert done.returncode == 0, done.stderr
    # the first line states wall and CPU time; the rest is the same
    lines = result.summary().replace(str(tmp_path / "py.parquet"), str(tmp_path / "cli.parquet")).splitlines()
    assert done.stdout.strip().splitlines()[1:] == lines[1:]
    pd.testing.assert_frame_equal(pd.read_parquet(tmp_path / "cli.parquet"), pd.read_parquet(tmp_path / "py.parquet"))


def test_old_names_still_work_and_say_the_new_one(tmp_path):
    """The shadowed lower functions and the re-tare's old argument order, kept one release."""
    from ftcal.files.targets import convert, write_target
    from ftcal.insitu.recordings import build_dataset, recordings_dataset
    from ftcal.payload import identify
    from ftcal.plan import design_experiment, plan_experiment
    from ftcal.report import evaluate, evaluate_run
    from ftcal.workflow import rebias_payload, retare

    for old, new in ((convert, write_target), (build_dataset, recordings_dataset), (evaluate, evaluate_run),
                     (plan_experiment, design_experiment),
                     (identify.identify_payload, identify.identify_from_statistics)):
        assert old.deprecated_for.endswith(new.__name__)
        with pytest.warns(DeprecationWarning, match=new.__name__), pytest.raises(TypeError):
            old()  # the same signature as the new name: no argument is an error of the call, after the notice
    assert list(inspect.signature(retare).parameters)[:2] == ["payload", "data"]  # (subject, data)
    assert rebias_payload.deprecated_for == "ftcal.workflow.retare(payload, data)"
