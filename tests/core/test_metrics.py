"""Metrics on tiny arrays computed by hand, and the paper's definitions."""

import json
from math import sqrt

import numpy as np
import pytest

from ftcal.core import metrics

Y = np.array([[1.0, 2.0], [3.0, 4.0], [5.0, 6.0]])
P = np.array([[1.0, 1.0], [4.0, 4.0], [5.0, 9.0]])
# errors: column 0 → 0, −1, 0; column 1 → 1, 0, −3. Both columns have variance 8/3.


def test_rmse_by_hand():
    np.testing.assert_allclose(metrics.rmse(Y, P), [sqrt(1 / 3), sqrt(10 / 3)], rtol=1e-15)


def test_max_abs_error_by_hand():
    np.testing.assert_array_equal(metrics.max_abs_error(Y, P), [1.0, 3.0])


def test_best_fit_by_hand():
    # BestFit = 1 − sqrt(MSE / mean((y − ȳ)²)) with the 1/N variance of the paper.
    np.testing.assert_allclose(metrics.best_fit(Y, P), [1 - sqrt((1 / 3) / (8 / 3)), 1 - sqrt((10 / 3) / (8 / 3))],
                               rtol=1e-14)


def test_best_fit_of_perfect_and_mean_predictors(rng):
    y = rng.normal(size=(50, 3)) * [1.0, 10.0, 0.1]
    np.testing.assert_array_equal(metrics.best_fit(y, y), 1.0)
    np.testing.assert_allclose(metrics.best_fit(y, np.broadcast_to(y.mean(axis=0), y.shape)), 0.0, atol=1e-14)


def test_best_fit_of_constant_output_is_undefined():
    y = np.array([[2.0, 1.0], [2.0, 3.0]])
    result = metrics.best_fit(y, y + 0.5)
    assert np.isnan(result[0]) and result[1] == pytest.approx(1 - sqrt(0.25 / 1.0))


def test_force_norm_rmse_by_hand():
    f = np.array([[3.0, 4.0, 0.0], [0.0, 0.0, 2.0]])
    f_hat = np.array([[0.0, 5.0, 0.0], [1.0, 1.0, 1.0]])
    # ‖f‖ = 5, 2; ‖f̂‖ = 5, √3.
    assert metrics.norm_rmse(f, f_hat) == pytest.approx(sqrt(((5 - 5) ** 2 + (2 - sqrt(3)) ** 2) / 2), rel=1e-14)
    # ‖f − f̂‖ = √10, √3: direction errors count here.
    assert metrics.error_norm_rmse(f, f_hat) == pytest.approx(sqrt((10 + 3) / 2), rel=1e-14)


def test_norm_rmse_ignores_direction_only_errors(rng):
    f = rng.normal(size=(20, 3))
    rotated = f[:, [1, 2, 0]]  # same norms, other directions
    assert metrics.norm_rmse(f, rotated) == pytest.approx(0.0, abs=1e-14)
    assert metrics.error_norm_rmse(f, rotated) > 0.1


def test_residual_autocorrelation_by_hand():
    y = np.array([[1.0], [-1.0], [1.0], [-1.0]])
    acf = metrics.residual_autocorrelation(y, np.zeros_like(y), max_lag=5)
    # lags 0..3 only (4 samples): sums 4, −3, 2, −1 over 4.
    np.testing.assert_allclose(acf[:, 0], [1.0, -0.75, 0.5, -0.25], rtol=1e-15)


@pytest.mark.parametrize("names, forces, torques", [
    (("Fx", "Fy", "Fz", "Tx", "Ty", "Tz"), [0, 1, 2], [3, 4, 5]),
    (("Tx", "Ty", "Tz", "Fx", "Fy", "Fz"), [3, 4, 5], [0, 1, 2]),
    (("r_arm_ft_Fx", "r_arm_ft_Fy", "r_arm_ft_Fz", "r_arm_ft_Mx", "r_arm_ft_My", "r_arm_ft_Mz"),
     [0, 1, 2], [3, 4, 5]),
    (("Fz", "Fx", "Fy", "Tx", "Tz", "Ty"), [0, 1, 2], [3, 4, 5]),  # order within a triple is irrelevant to norms
    (("Mx", "Fx", "My", "Fy", "Mz", "Fz"), [1, 3, 5], [0, 2, 4]),
    (("Fx", "Fy", "Fz"), [0, 1, 2], None),
    (("a", "b", "c", "d", "e", "f"), [0, 1, 2], [3, 4, 5]),  # six unnamed outputs: paper order
    (("a", "b", "c", "d"), None, None),
])
def test_force_torque_columns_by_name(names, forces, torques):
    assert metrics.force_torque_columns(names) == (forces, torques)


def test_forces_found_by_name_are_kept_when_torques_are_not():
    forces, _ = metrics.force_torque_columns(("tau_x", "tau_y", "tau_z", "Fx", "Fy", "Fz"))
    assert forces == [3, 4, 5]


def test_summarize_uses_named_force_columns_and_is_json_ready():
    names = ("Tx", "Ty", "Tz", "Fx", "Fy", "Fz")
    y = np.array([[0.0, 0.0, 1.0, 3.0, 4.0, 0.0], [1.0, 1.0, 1.0, 0.0, 0.0, 2.0], [5.0, 5.0, 5.0, 1.0, 1.0, 1.0]])
    p = y.copy()
    p[:, 3:] = [[0.0, 5.0, 0.0], [1.0, 1.0, 1.0], [1.0, 1.0, 1.0]]
    p[:, 2] = 1.0  # torque Tz predicted constant 1; true Tz = 1, 1, 5
    summary = metrics.summarize(y, p, names)
    # Forces (last three columns): norms 5, 2, √3 vs 5, √3, √3.
    assert summary["force_norm_rmse"] == pytest.approx(sqrt((2 - sqrt(3)) ** 2 / 3), rel=1e-14)
    # Torques (first three): ‖(0,0,1)‖ vs itself, ‖(1,1,1)‖ vs itself, ‖(5,5,5)‖ vs ‖(5,5,1)‖.
    assert summary["torque_norm_rmse"] == pytest.approx(sqrt((sqrt(75) - sqrt(51)) ** 2 / 3), rel=1e-14)
    assert summary["rmse"][2] == pytest.approx(sqrt(16 / 3))
    assert summary["best_fit"][0:2] == [1.0, 1.0]
    assert summary["n_samples"] == 3 and summary["outputs"] == list(names)
    json.dumps(summary, allow_nan=False)


def test_summarize_constant_output_gives_null_best_fit():
    y = np.c_[np.ones(4), np.arange(4.0)]
    summary = metrics.summarize(y, y, ("a", "b"))
    assert summary["best_fit"] == [None, 1.0]
    assert summary["force_norm_rmse"] is None and summary["torque_norm_rmse"] is None
    json.dumps(summary, allow_nan=False)
