"""Payload and bias identification on synthetic poses: estimates, standard errors, excitation."""

import warnings

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from ftcal.payload.accumulate import payload_statistics
from ftcal.payload.identify import identify_from_statistics
from ftcal.payload.kinematics import (
    GravityColumnsSource,
    Kinematics,
    MotionSource,
    OrientationSource,
    angular_acceleration_from,
    gravity_from_quaternions,
)
from ftcal.runtime.errors import FtcalError, IllPosedFitWarning, UndeterminedWarning

G = 9.81
MASS = 1.3
COM = np.array([0.012, -0.025, 0.071])
BIAS = np.array([3.0, -2.0, 5.0, 0.1, -0.2, 0.05])
NOISE = np.array([0.3, 0.3, 0.3, 0.01, 0.01, 0.01])


def readings(gravity, rng=None, noise=NOISE):
    """Hand statics: F = m g + f_b, T = c × m g + t_b (plus Gaussian noise per axis)."""
    w = np.c_[MASS * gravity, np.cross(COM, MASS * gravity)] + BIAS
    return w if rng is None else w + rng.normal(size=w.shape) * noise


def random_gravity(n_poses, per_pose, seed):
    g = Rotation.random(n_poses, random_state=seed).inv().apply([0.0, 0.0, -G])
    return np.repeat(g, per_pose, axis=0)


def fit(gravity, wrench, n_groups=1):
    parts = np.array_split(np.arange(len(gravity)), n_groups)
    groups = {f"g{k}": payload_statistics(wrench[idx], Kinematics(gravity[idx])) for k, idx in enumerate(parts)}
    return identify_from_statistics(groups)


# ---------------------------------------------------------------- gravity sources
def test_gravity_from_quaternions_matches_scipy():
    rot = Rotation.random(20, random_state=3)
    want = rot.inv().apply([0.0, 0.0, -G])  # world gravity seen in the sensor frame
    np.testing.assert_allclose(gravity_from_quaternions(rot.as_quat(), G), want, atol=1e-12)


def test_non_unit_quaternion_names_column_and_row():
    q = Rotation.random(5, random_state=0).as_quat()
    q[3] *= 1.01
    with pytest.raises(FtcalError, match=r"data.csv: quaternion columns qx,qy,qz,qw are not unit length at row 3"):
        gravity_from_quaternions(q, source="data.csv")


def test_gravity_columns_must_be_m_per_s2():
    import pandas as pd

    frame = pd.DataFrame({"gx": [0.0], "gy": [0.0], "gz": [-1.0]})
    with pytest.raises(FtcalError, match=r"norm 1 at row 0, not the gravity magnitude 9.81"):
        GravityColumnsSource()(frame, "d.csv")


def test_orientation_source_reads_columns():
    import pandas as pd

    rot = Rotation.from_euler("x", 90, degrees=True)  # sensor y axis points down in the world
    frame = pd.DataFrame([rot.as_quat()], columns=["qx", "qy", "qz", "qw"])
    np.testing.assert_allclose(OrientationSource()(frame, "d.csv").gravity, [[0.0, -G, 0.0]], atol=1e-12)


def test_angular_acceleration_is_derivative():
    t = np.linspace(0.0, 2.0, 2001)
    omega = np.column_stack([np.sin(3 * t), np.cos(2 * t), t ** 2])
    want = np.column_stack([3 * np.cos(3 * t), -2 * np.sin(2 * t), 2 * t])
    got = angular_acceleration_from(omega, t)
    np.testing.assert_allclose(got[1:-1], want[1:-1], atol=1e-4)


def test_motion_source_needs_time_or_columns():
    import pandas as pd

    frame = pd.DataFrame({"gx": [0.0, 0.0], "gy": [0.0, 0.0], "gz": [-G, -G], "wx": [0, 0], "wy": [0, 0],
                          "wz": [0, 0]})
    with pytest.raises(FtcalError, match="no 'time' column"):
        MotionSource(GravityColumnsSource())(frame, "d.csv")


# ---------------------------------------------------------------- estimates and standard errors
def test_recovers_payload_within_standard_errors():
    rng = np.random.default_rng(11)
    gravity = random_gravity(24, 40, seed=5)
    result = fit(gravity, readings(gravity, rng), n_groups=4)
    assert abs(result.mass - MASS) < 4 * result.stderr["mass"]
    assert np.all(np.abs(result.com - COM) < 4 * result.stderr["com"])
    assert np.all(np.abs(result.force_bias - BIAS[:3]) < 4 * result.stderr["force_bias"])
    assert np.all(np.abs(result.torque_bias - BIAS[3:]) < 4 * result.stderr["torque_bias"])
    np.testing.assert_allclose(result.residual_rms, NOISE, rtol=0.1)
    assert len(result.cross_validation) == 4
    for group in result.cross_validation:
        np.testing.assert_allclose(group.rms, NOISE, rtol=0.25)
    assert result.poorly_excited == ()


def dense_regressor(gravity):
    """The stacked 6N × 10 regressor written out from the statics (not from ftcal)."""
    rows = []
    for g in gravity:
        block = np.zeros((6, 10))
        block[:3, 0] = g
        for j in range(3):
            e = np.eye(3)[j]
            block[3:, 1 + j] = np.cross(e, g)  # (m c) × g is linear in m c
        block[:, 4:] = np.eye(6)
        rows.append(block)
    return np.vstack(rows)


def test_stderr_matches_textbook_weighted_covariance():
    rng = np.random.default_rng(2)
    gravity = random_gravity(30, 20, seed=8)
    result = identify_from_statistics({"all": payload_statistics(readings(gravity, rng), Kinematics(gravity))},
                              weighting="wls")
    a = dense_regressor(gravity)
    weights = np.tile(1.0 / NOISE ** 2, len(gravity))  # the true per-axis noise
    covariance = np.linalg.inv(a.T @ (weights[:, None] * a))
    want = np.sqrt(np.diag(covariance))
    got = np.r_[result.stderr["mass"], np.sqrt(np.diag(result.covariance))[1:4],
                result.stderr["force_bias"], result.stderr["torque_bias"]]
    np.testing.assert_allclose(got, want, rtol=0.1)  # σ is estimated from 600 samples per axis


def test_stderr_matches_monte_carlo():
    gravity = random_gravity(12, 5, seed=4)
    rng = np.random.default_rng(0)
    exact = readings(gravity)
    estimates, reported = [], None
    for _ in range(300):
        result = fit(gravity, exact + rng.normal(size=exact.shape) * NOISE)
        estimates.append(np.r_[result.mass, result.com, result.force_bias, result.torque_bias])
        reported = np.r_[result.stderr["mass"], result.stderr["com"], result.stderr["force_bias"],
                         result.stderr["torque_bias"]] if reported is None else reported
    spread = np.std(estimates, axis=0, ddof=1)
    np.testing.assert_allclose(reported, spread, rtol=0.3)


# ---------------------------------------------------------------- excitation
def cone_gravity(tilt_deg, n):
    """The sensor turned about its own z axis, that axis tilted tilt_deg from the vertical."""
    phi = np.linspace(0.0, 2 * np.pi, n, endpoint=False)
    tilt = np.radians(tilt_deg)
    return G * np.column_stack([np.sin(tilt) * np.cos(phi), np.sin(tilt) * np.sin(phi),
                                -np.cos(tilt) * np.ones(n)])


def test_rotations_about_one_nearly_vertical_axis_warn_about_mass():
    rng = np.random.default_rng(1)
    gravity = np.repeat(cone_gravity(3.0, 12), 10, axis=0)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        result = fit(gravity, readings(gravity, rng))
    messages = [str(w.message) for w in caught if issubclass(w.category, IllPosedFitWarning)]
    assert any(m.startswith("the poses hardly excite mass") and "tilt the sensor" in m for m in messages)
    # Gravity stays near -z: the weight is confounded with the z force bias, and the COM's x and y
    # (whose torque about y and x barely changes) with the torque biases.
    assert {"m", "Fz_bias", "mcx", "mcy"} <= set(result.poorly_excited)
    assert "mcz" not in result.poorly_excited


def test_rotations_about_the_vertical_are_degenerate():
    # Turning about the world vertical leaves gravity fixed in the sensor frame.
    gravity = np.repeat(cone_gravity(0.0, 1), 50, axis=0)
    with pytest.raises(FtcalError, match=r"the poses do not determine the mass .*tilt the sensor"):
        fit(gravity, readings(gravity, np.random.default_rng(0)))


def test_gravity_on_one_line_leaves_com_along_it_undetermined():
    # Tool down and tool up only: the COM along z makes no torque in either (tests/data/test_payload_undetermined.py
    # checks the estimates against the truth).
    gravity = np.repeat([[0.0, 0.0, -G], [0.0, 0.0, G]], 10, axis=0)
    with pytest.warns(UndeterminedWarning, match=r"centre of mass along the sensor's z axis is not determined"):
        result = fit(gravity, readings(gravity, np.random.default_rng(0)))
    assert result.undetermined.parameters == ("mcz",) and np.isnan(result.stderr["com"][2])


def test_well_spread_poses_do_not_warn():
    gravity = random_gravity(20, 5, seed=9)
    with warnings.catch_warnings():
        warnings.simplefilter("error", IllPosedFitWarning)
        fit(gravity, readings(gravity, np.random.default_rng(0)))


def test_too_few_samples():
    gravity = random_gravity(1, 1, seed=0)
    with pytest.raises(FtcalError, match=r"1 sample\(s\) give 6 equations for 10 unknowns"):
        fit(gravity, readings(gravity))


def test_statistics_add_over_chunks_and_threads():
    gravity = random_gravity(10, 300, seed=2)
    wrench = readings(gravity, np.random.default_rng(3))
    one = payload_statistics(wrench, Kinematics(gravity), chunk=50)
    other = payload_statistics(wrench, Kinematics(gravity))
    for a, b in zip(one.axes, other.axes):
        np.testing.assert_allclose(a.gram, b.gram, rtol=1e-12)
        np.testing.assert_allclose(a.cross, b.cross, rtol=1e-12)
    a = dense_regressor(gravity)
    np.testing.assert_allclose(one.gram(), a.T @ a, rtol=1e-12)


def test_mass_sign_checks():
    from ftcal.payload.identify import check_mass_sign

    gravity = random_gravity(20, 5, seed=6)
    rng = np.random.default_rng(4)
    bare = BIAS + rng.normal(size=(len(gravity), 6)) * NOISE  # nothing mounted: bias only
    with pytest.raises(FtcalError, match="not distinguishable from zero"):
        check_mass_sign(fit(gravity, bare))
    with pytest.raises(FtcalError, match="negative: .*re-run with reaction"):
        check_mass_sign(fit(gravity, -readings(gravity, rng)))
    check_mass_sign(fit(gravity, readings(gravity, rng)))


def test_a_full_turn_about_one_horizontal_axis_identifies_everything():
    # Gravity sweeps the sensor's y-z plane: m from Fy/Fz, com y/z from Tx, com x from Ty/Tz.
    phi = np.linspace(0.0, 2 * np.pi, 12, endpoint=False)
    gravity = np.repeat(G * np.column_stack([np.zeros(12), np.sin(phi), -np.cos(phi)]), 10, axis=0)
    with warnings.catch_warnings():
        warnings.simplefilter("error", IllPosedFitWarning)
        result = fit(gravity, readings(gravity, np.random.default_rng(0)))
    assert np.all(result.variance_inflation < 10)
