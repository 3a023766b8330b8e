"""The simulated arm bag: ftcal reads back the gripper and bias the simulator used (numpy least squares)."""

import numpy as np
import pandas as pd
import pytest
from scipy.spatial.transform import Rotation

from ftcal.cli import main
from ftcal.data.bags import BagTopics, read_bag
from ftcal.runtime.errors import FtcalError
from ftcal.sim.arm_bag import WRENCH_TOPIC, ArmScenario, write_arm_bag


def test_arm_bag_round_trip(tmp_path, capfd):
    scenario = ArmScenario(n_poses=8, rate=200.0, tf_rate=50.0, imu_rate=100.0, seed=3)
    truth = write_arm_bag(tmp_path / "arm", scenario)
    out = tmp_path / "arm.csv"
    assert main(["dataset", str(truth.path), "--wrench-topic", "/ft_sensor/wrench", "--tf", "base_link:ft_sensor",
                 "--imu-topic", "/imu", "--temperature-topic", "/ft_sensor/temperature", "--no-filter",
                 "-o", str(out)]) == 0
    frame = pd.read_csv(out)
    t = frame["time"].to_numpy()
    still = np.zeros(len(frame), bool)
    for start, end in truth.holds:
        still |= (t > start + 0.1) & (t < end - 0.1)
    rows = frame[still]
    rotation = Rotation.from_quat(rows[["qx", "qy", "qz", "qw"]].to_numpy())
    g_s = rotation.inv().apply([0.0, 0.0, -truth.gravity])  # gravity in the sensor frame
    # Resting accelerometer reads −g_s: the IMU path agrees with the tf chain.
    np.testing.assert_allclose(rows[["ax", "ay", "az"]].to_numpy(), -g_s, atol=1e-3)
    # f = b_f + tc (T − T0) + m g_s: 7 unknowns per axis set, solved by numpy on hand-built columns.
    n = len(rows)
    dT = rows["T"].to_numpy() - truth.temperature_reference
    a = np.zeros((3 * n, 7))
    for i in range(3):
        a[i::3, i] = 1.0
        a[i::3, 3 + i] = dT
        a[i::3, 6] = g_s[:, i]
    f = rows[["u1", "u2", "u3"]].to_numpy().ravel()
    x = np.linalg.lstsq(a, f, rcond=None)[0]
    np.testing.assert_allclose(x[6], truth.mass, rtol=2e-3)
    np.testing.assert_allclose(x[:3], truth.force_bias, atol=0.05)
    np.testing.assert_allclose(x[3:6], truth.force_bias_tc, atol=0.01)
    # τ = b_τ + (m c) × g_s = b_τ − [g_s]× (m c)
    b = np.zeros((3 * n, 6))
    for i in range(3):
        b[i::3, i] = 1.0
    skew = np.zeros((n, 3, 3))
    skew[:, 0, 1], skew[:, 0, 2], skew[:, 1, 2] = -g_s[:, 2], g_s[:, 1], -g_s[:, 0]
    skew -= skew.transpose(0, 2, 1)
    b[:, 3:] = -skew.reshape(3 * n, 3)
    y = np.linalg.lstsq(b, rows[["u4", "u5", "u6"]].to_numpy().ravel(), rcond=None)[0]
    np.testing.assert_allclose(y[:3], truth.torque_bias, atol=5e-3)
    np.testing.assert_allclose(y[3:] / truth.mass, truth.com, atol=1e-3)


def test_arm_bag_sqlite_and_bad_arguments(tmp_path):
    scenario = ArmScenario(n_poses=3, hold_s=0.5, move_s=0.5, rate=100.0)
    truth = write_arm_bag(tmp_path / "arm", scenario, storage="sqlite3")
    stream = read_bag(truth.path, BagTopics(WRENCH_TOPIC)).ft[WRENCH_TOPIC]
    assert stream.n_samples == 251 and stream.frame == "ft_sensor"  # 2.5 s at 100 Hz, both ends included
    with pytest.raises(FtcalError, match="already exists"):
        write_arm_bag(truth.path, scenario)
    with pytest.raises(FtcalError, match="'storage' parameter must be 'mcap' or 'sqlite3'"):
        write_arm_bag(tmp_path / "other", scenario, storage="db3")
    with pytest.raises(FtcalError, match="n_poses >= 3"):
        ArmScenario(n_poses=2)
