"""The calibration and an unknown payload fitted together (ftcal fit --estimate-payload).

Simulated data: the iCub right-arm sensor (ftcal.sim's strain-gauge model with its default
noise; its nonlinear effects turned off so the affine sensor model is exact) with a plate of
known mass and centre of mass on the forearm, static poses of the whole arm. References: the
plate's true parameters, the likelihood criterion evaluated densely with numpy least squares,
and a calibration fitted with the true payload.
"""

import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from test_insitu import make_recording
from test_logs_mat import write_v73
from test_robot_expected import gravity_in_sensor
from test_robot_model import TINY_URDF

from ftcal.core.dataset import DEFAULT_OUTPUTS, Dataset
from ftcal.core.model import CalibrationModel
from ftcal.insitu.recordings import InsituOptions, recordings_dataset as build_dataset
from ftcal.payload.unknown_load import estimate_payload, fit_with_payload, payload_column
from ftcal.robot import Payload, RobotModel, SensorDeclaration
from ftcal.robot.expected import expected_wrenches
from ftcal.robot.kinematics import payload_regressor
from ftcal.runtime.errors import FtcalError
from ftcal.sim.sensor import SensorParams, StrainGaugeSensor
from ftcal.sim.trajectories import ARM_JOINTS

PLATE = Payload("r_forearm", 2.0, (-0.06, 0.01, 0.03))
LINEAR_SENSOR = SensorParams(stiffening=0.0, creep=0.0, sensitivity_tc=0.0, sensitivity_tc_spread=0.0,
                             asymmetry=0.0, drift=0.0, saturation=50.0)
INPUTS = ("u1", "u2", "u3", "u4", "u5", "u6")
FTCAL = str(Path(sys.executable).with_name("ftcal"))


@pytest.fixture(scope="module")
def icub_plate():
    """Known-part wrench, payload regressor, raw readings and the true wrench for 800 static arm poses."""
    robot = RobotModel.load(name="iCubGenova04")
    rng = np.random.default_rng(7)
    arm = rng.uniform(np.deg2rad([-90, 10, -30, 20, -50, -40, -20]), np.deg2rad([10, 100, 60, 100, 50, 20, 30]),
                      (800, len(ARM_JOINTS)))
    q = robot.joint_matrix(ARM_JOINTS, arm, "poses")
    index = robot.sensor("r_arm_ft").index
    known = expected_wrenches(robot, q, workers=1)[:, index]
    true = expected_wrenches(robot.with_payloads([PLATE]), q, workers=1)[:, index]
    sensor = StrainGaugeSensor.create(LINEAR_SENSOR, seed=3)
    raw = sensor.measure(true, np.full(len(q), 25.0), rng=np.random.default_rng(1))
    y = payload_regressor(robot, "r_arm_ft", "r_forearm", q, static=True)
    data = Dataset.from_arrays(raw, known, input_names=INPUTS, output_names=DEFAULT_OUTPUTS)
    return data, y, true


def test_recovers_plate_mass_and_com_within_standard_errors(icub_plate):
    data, y, _ = icub_plate
    model, estimate = fit_with_payload(data, y, "r_forearm")
    assert estimate.parameters == ("m", "mcx", "mcy", "mcz")
    truth = np.r_[PLATE.mass, PLATE.mass * np.array(PLATE.com)]
    assert np.all(estimate.stderr > 0)
    assert np.all(np.abs(estimate.values - truth) < 3 * estimate.stderr)
    assert np.all(np.abs(estimate.com - PLATE.com) < 3 * estimate.com_stderr())
    assert estimate.stderr[0] < 0.2  # the data pin the mass down to a few percent


def test_independent_samples_jackknife_agrees_with_the_curvature(icub_plate):
    # White noise, random pose order: both standard errors estimate the same spread. The
    # jackknife over 20 blocks is itself uncertain by about 1/sqrt(2 * 19) = 16 %, and t-scaled
    # by t(19)/z = 1.07; a refit that did not move (a stalled search) would make it far smaller.
    data, y, _ = icub_plate
    estimate = estimate_payload(data, y, "r_forearm")
    assert estimate.stderr_kind.startswith("grouped jackknife over 20 contiguous blocks")
    ratio = estimate.stderr / estimate.curvature_stderr
    assert np.all((ratio > 0.7) & (ratio < 1.6)), ratio


def test_same_calibration_as_with_the_true_payload(icub_plate):
    data, y, true = icub_plate
    model, estimate = fit_with_payload(data, y, "r_forearm")
    reference = CalibrationModel(1).fit(Dataset.from_arrays(data.inputs, true, input_names=INPUTS,
                                                            output_names=DEFAULT_OUTPUTS))
    truth = np.r_[PLATE.mass, PLATE.mass * np.array(PLATE.com)]
    # Both are least-squares projections onto the same column space; the targets differ by
    # Y (pi_hat - pi), so the fitted wrenches differ by at most that much (per output, in norm).
    gap = np.linalg.norm(model.predict(data) - reference.predict(data), axis=0)
    bound = np.linalg.norm(y @ (estimate.values - truth), axis=0)
    assert np.all(gap <= bound * (1 + 1e-6) + 1e-9)
    # With |pi_hat - pi| < 3 standard errors (test above), the calibrations agree within the
    # wrench those three standard errors can make.
    allowed = np.linalg.norm(np.abs(y) @ (3 * estimate.stderr), axis=0)
    assert np.all(gap <= allowed)


def dense_criterion(data, y, pi):
    """log det of the residual moments of u regressed (numpy lstsq) on [w_known + Y pi, 1]."""
    design = np.c_[data.outputs + y @ pi, np.ones(len(y))]
    residual = data.inputs - design @ np.linalg.lstsq(design, data.inputs, rcond=None)[0]
    return np.linalg.slogdet(residual.T @ residual / len(y))[1]


def test_estimate_minimises_the_dense_likelihood_criterion(icub_plate):
    data, y, _ = icub_plate
    estimate = estimate_payload(data, y, "r_forearm")
    best = dense_criterion(data, y, estimate.values)
    truth = np.r_[PLATE.mass, PLATE.mass * np.array(PLATE.com)]
    assert best <= dense_criterion(data, y, truth)
    for k in range(4):
        step = np.zeros(4)
        step[k] = estimate.stderr[k]
        assert best < dense_criterion(data, y, estimate.values + step)
        assert best < dense_criterion(data, y, estimate.values - step)


def test_one_linear_least_squares_would_collapse(icub_plate):
    # Why ftcal does not fit min ||A(u) theta - (w_known + Y pi)||²: with the noise in u, numpy's
    # solution of that problem cancels the known links (mass near minus the mass beyond the sensor).
    data, y, _ = icub_plate
    a = np.c_[data.inputs, np.ones(len(y))]
    n, p = a.shape
    rows = np.zeros((6 * n, 6 * p + 4))
    for i in range(6):
        rows[i * n:(i + 1) * n, i * p:(i + 1) * p] = a
        rows[i * n:(i + 1) * n, -4:] = -y[:, i]
    naive = np.linalg.lstsq(rows, data.outputs.T.reshape(-1), rcond=None)[0][-4:]
    assert naive[0] < 0 < estimate_payload(data, y, "r_forearm").mass


def test_known_mass_is_kept_and_the_rest_estimated(icub_plate):
    data, y, _ = icub_plate
    _, estimate = fit_with_payload(data, y, "r_forearm", payload_mass=PLATE.mass)
    assert estimate.mass == PLATE.mass and estimate.stderr[0] == 0
    np.testing.assert_allclose(estimate.com, PLATE.com, atol=3 * estimate.com_stderr().max())


def test_rigid_tool_on_a_wrist_cannot_fix_the_scale():
    from test_robot_declare import UR5

    if not UR5.is_file():
        pytest.skip("example-robot-data is not installed")
    robot = RobotModel.load(UR5, declared=[SensorDeclaration("ee_fixed_joint")])
    q = np.random.default_rng(8).uniform(-3, 3, (200, 6))
    tool = Payload("ee_link", 1.0, (0.0, 0.02, 0.08))
    known = expected_wrenches(robot, q, base="base_link", workers=1)[:, 0]
    true = expected_wrenches(robot.with_payloads([tool]), q, base="base_link", workers=1)[:, 0]
    raw = true @ np.linalg.inv(np.eye(6) + 0.1 * np.ones((6, 6))).T
    y = payload_regressor(robot, "ee_fixed_joint", "ee_link", q, base="base_link", static=True)
    data = Dataset.from_arrays(raw, known, input_names=INPUTS, output_names=DEFAULT_OUTPUTS)
    with pytest.raises(FtcalError, match="trade against the calibration's gains.*payload_mass"):
        fit_with_payload(data, y, "ee_link")


def test_dataset_writes_the_payload_regressor_columns(tmp_path):
    # TINY_URDF: shoulder about x, sensor frame = forearm frame; static regressor of a payload on the
    # forearm is [g_s, (e_k × g_s)...]: force column m -> g_s, torque columns m c -> -[g_s]×.
    path = tmp_path / "rec.mat"
    t, _, _ = make_recording(path, write_v73)
    robot = RobotModel.from_text(TINY_URDF, "tiny.urdf")
    ds = build_dataset([path], robot, "arm_ft", options=InsituOptions(savgol_frame=None, payload_link="forearm"))
    names = ds.output_names
    assert names[:6] == DEFAULT_OUTPUTS and len(names) == 6 + 24
    column = {name: ds.outputs[:, i] for i, name in enumerate(names)}
    g = np.array([gravity_in_sensor(0.5 * tk) for tk in t])
    np.testing.assert_allclose(np.c_[[column[payload_column("forearm", a, "m")] for a in ("Fx", "Fy", "Fz")]].T,
                               g, atol=1e-9)
    # torque about x from a first moment along y: (e_y × g)_x = g_z
    np.testing.assert_allclose(column[payload_column("forearm", "Tx", "mcy")], g[:, 2], atol=1e-9)
    np.testing.assert_allclose(column[payload_column("forearm", "Fx", "mcx")], 0.0, atol=1e-12)


def run_cli(*args):
    return subprocess.run([FTCAL, *args], capture_output=True, text=True)


def test_cli_fit_estimate_payload(tmp_path, icub_plate):
    data, y, _ = icub_plate
    table = pd.DataFrame(data.inputs, columns=INPUTS)
    for i, axis in enumerate(DEFAULT_OUTPUTS):
        table[axis] = data.outputs[:, i]
        for k, parameter in enumerate(("m", "mcx", "mcy", "mcz")):
            table[payload_column("r_forearm", axis, parameter)] = y[:, i, k]
    table.to_parquet(tmp_path / "data.parquet")
    out = tmp_path / "model.json"
    done = run_cli("fit", str(tmp_path / "data.parquet"), "--estimate-payload", "r_forearm", "-o", str(out))
    assert done.returncode == 0, done.stderr
    mass_line = next(line for line in done.stdout.splitlines() if line.strip().startswith("m "))
    value, err = float(mass_line.split()[1]), float(mass_line.split()[3])
    assert abs(value - PLATE.mass) < 3 * err
    assert "standard errors: grouped jackknife over 20 contiguous blocks of samples" in done.stdout
    from ftcal.files.model_files import load_model

    assert load_model(out).predict(data).shape == (len(y), 6)

    bad = run_cli("fit", str(tmp_path / "data.parquet"), "--estimate-payload", "r_hand", "-o", str(tmp_path / "b.json"))
    assert bad.returncode == 2 and len(bad.stderr.strip().splitlines()) == 1
    assert "Y_r_hand_Fx_m" in bad.stderr and "--estimate-payload r_hand" in bad.stderr
    assert not (tmp_path / "b.json").exists()
    stray = run_cli("fit", str(tmp_path / "data.parquet"), "--payload-mass", "2", "-o", str(tmp_path / "c.json"))
    assert stray.returncode == 2 and "--payload-mass goes with --estimate-payload" in stray.stderr


def test_cli_dataset_estimate_payload_columns(tmp_path):
    path = tmp_path / "rec.mat"
    t, _, _ = make_recording(path, write_v73)
    (tmp_path / "tiny.urdf").write_text(TINY_URDF)
    out = tmp_path / "ds.csv"
    done = run_cli("dataset", str(path), "--urdf", str(tmp_path / "tiny.urdf"), "--sensor", "arm_ft", "--no-filter",
                   "--estimate-payload", "forearm", "-o", str(out))
    assert done.returncode == 0, done.stderr
    table = pd.read_csv(out)
    g = np.array([gravity_in_sensor(0.5 * tk) for tk in t])
    np.testing.assert_allclose(table[payload_column("forearm", "Fz", "m")], g[:, 2], atol=1e-9)
    assert payload_column("forearm", "Tz", "mcz") in table.columns
    assert payload_column("forearm", "Fx", "Ixx") not in table.columns  # static data: 4 parameters
    bad = run_cli("dataset", str(path), "--urdf", str(tmp_path / "tiny.urdf"), "--sensor", "arm_ft",
                  "--estimate-payload", "upper", "-o", str(tmp_path / "bad.csv"))
    assert bad.returncode == 2 and "not on the far side of F/T sensor 'arm_ft'" in bad.stderr
    assert not (tmp_path / "bad.csv").exists()
