"""Sensor-frame kinematics and the payload regressor of a link, against independent references.

References: finite differences of the UR5 forward kinematics composed by hand (scipy
rotations), and iDynTree's ExtWrenchesAndJointTorquesEstimator (expected wrench with and
without an attached payload) for the payload regressor, fixed and floating base.
"""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation
from test_robot_declare import G_BASE, UR5, ur5_chain_rotation

from ftcal.robot import Payload, RobotModel, SensorDeclaration
from ftcal.robot.expected import FloatingBase, expected_wrenches
from ftcal.robot.kinematics import frame_kinematics, payload_regressor, sensor_kinematics
from ftcal.runtime.errors import FtcalError

pytestmark = pytest.mark.skipif(not UR5.is_file(), reason="example-robot-data is not installed")


@pytest.fixture(scope="module")
def ur5():
    return RobotModel.load(UR5, declared=[SensorDeclaration("ee_fixed_joint", "tool0")])


def pi_of(payload: Payload) -> np.ndarray:
    """[m, m c, I about the frame origin (xx, xy, xz, yy, yz, zz)] by the parallel-axis theorem."""
    m, c = payload.mass, np.array(payload.com)
    ixx, iyy, izz, ixy, ixz, iyz = payload.inertia
    inertia = np.array([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]]) + m * (c @ c * np.eye(3) - np.outer(c, c))
    return np.r_[m, m * c, inertia[0, 0], inertia[0, 1], inertia[0, 2], inertia[1, 1], inertia[1, 2], inertia[2, 2]]


def test_static_sensor_gravity_from_hand_kinematics(ur5):
    q = np.random.default_rng(0).uniform(-3, 3, (5, 6))
    kin = sensor_kinematics(ur5, "ee_fixed_joint", q, base="base_link")
    for k in range(len(q)):
        rotation, _ = ur5_chain_rotation(q[k], "tool0")
        np.testing.assert_allclose(kin.gravity[k], rotation.T @ G_BASE, atol=1e-12)
    np.testing.assert_allclose(kin.proper_acceleration, -kin.gravity, atol=1e-12)
    assert not kin.angular_velocity.any() and not kin.angular_acceleration.any()


def test_moving_frame_against_finite_differences(ur5):
    rng = np.random.default_rng(1)
    q, dq, ddq = rng.uniform(-2, 2, 6), rng.normal(size=6), rng.normal(size=6)
    kin = frame_kinematics(ur5, "tool0", q[None], dq[None], ddq[None], base="base_link")
    h = 1e-4

    def pose(t):
        return ur5_chain_rotation(q + dq * t + 0.5 * ddq * t * t, "tool0")

    (r_minus, p_minus), (r0, p0), (r_plus, p_plus) = pose(-h), pose(0.0), pose(h)
    accel = (p_plus - 2 * p0 + p_minus) / h**2
    np.testing.assert_allclose(kin.proper_acceleration[0], r0.T @ (accel - G_BASE), atol=1e-5)

    def omega_world(t):
        # ω from the rotation's derivative, by central differences around t
        r_a, r_b = pose(t - h)[0], pose(t + h)[0]
        return Rotation.from_matrix(r_b @ r_a.T).as_rotvec() / (2 * h)

    np.testing.assert_allclose(kin.angular_velocity[0], r0.T @ omega_world(0.0), atol=1e-6)
    alpha = (omega_world(h) - omega_world(-h)) / (2 * h)
    np.testing.assert_allclose(kin.angular_acceleration[0], r0.T @ alpha, atol=1e-4)


def test_payload_regressor_against_idyntree_fixed_base(ur5):
    rng = np.random.default_rng(2)
    q, dq, ddq = rng.uniform(-3, 3, (6, 6)), rng.normal(size=(6, 6)), rng.normal(size=(6, 6))
    payload = Payload("ee_link", 2.0, (0.01, 0.02, 0.1), (0.01, 0.02, 0.03, 0.001, 0.002, 0.003))
    bare = expected_wrenches(ur5, q, dq=dq, ddq=ddq, base="base_link", workers=1)[:, 0]
    loaded = expected_wrenches(ur5.with_payloads([payload]), q, dq=dq, ddq=ddq, base="base_link", workers=1)[:, 0]
    y = payload_regressor(ur5, "ee_fixed_joint", "ee_link", q, dq, ddq, base="base_link")
    assert y.shape == (6, 6, 10)
    np.testing.assert_allclose(y @ pi_of(payload), loaded - bare, atol=1e-10)
    static = payload_regressor(ur5, "ee_fixed_joint", "ee_link", q, base="base_link", static=True)
    assert static.shape == (6, 6, 4)


def test_payload_regressor_against_idyntree_floating_icub():
    icub = RobotModel.load(name="iCubGenova04")
    rng = np.random.default_rng(3)
    n = len(icub.joint_names)
    q, dq, ddq = rng.uniform(-0.3, 0.3, (4, n)), rng.normal(size=(4, n)), rng.normal(size=(4, n))
    imu = FloatingBase("root_link", rng.normal(size=(4, 3)) + [0, 0, 9.81], rng.normal(size=(4, 3)),
                       rng.normal(size=(4, 3)))
    payload = Payload("r_hand", 1.5, (0.01, 0.02, 0.03), (0.01, 0.02, 0.03, 0.0, 0.0, 0.0))
    index = icub.sensor("r_arm_ft").index
    bare = expected_wrenches(icub, q, dq=dq, ddq=ddq, floating=imu, workers=1)[:, index]
    loaded = expected_wrenches(icub.with_payloads([payload]), q, dq=dq, ddq=ddq, floating=imu, workers=1)[:, index]
    y = payload_regressor(icub, "r_arm_ft", "r_hand", q, dq, ddq, floating=imu)
    np.testing.assert_allclose(y @ pi_of(payload), loaded - bare, atol=1e-10)
    assert np.abs(loaded - bare).max() > 1.0


def test_floating_base_at_rest_matches_fixed_base_gravity():
    icub = RobotModel.load(name="iCubGenova04")
    rng = np.random.default_rng(4)
    q = rng.uniform(-0.5, 0.5, (3, len(icub.joint_names)))
    g_root = np.array([1.0, -2.0, -9.5])  # gravity in root_link axes; the IMU reads its opposite
    imu = FloatingBase("root_link", np.tile(-g_root, (3, 1)), np.zeros((3, 3)))
    floating = sensor_kinematics(icub, "l_leg_ft", q, floating=imu)
    fixed = sensor_kinematics(icub, "l_leg_ft", q, base="root_link", gravity=g_root)
    np.testing.assert_allclose(floating.gravity, fixed.gravity, atol=1e-12)
    np.testing.assert_allclose(floating.proper_acceleration, fixed.proper_acceleration, atol=1e-12)


def test_payload_link_must_be_beyond_the_sensor(ur5):
    with pytest.raises(FtcalError, match="not on the far side of F/T sensor"):
        payload_regressor(ur5, "ee_fixed_joint", "forearm_link", np.zeros((1, 6)), base="base_link")


def test_cli_payload_with_gravity_from_the_urdf(tmp_path):
    import json
    import subprocess
    import sys
    from pathlib import Path

    import pandas as pd

    rng = np.random.default_rng(9)
    q = rng.uniform(-3, 3, (40, 6))
    mass, com = 1.3, np.array([0.01, -0.02, 0.07])
    force_bias, torque_bias = np.array([2.0, -1.0, 0.5]), np.array([0.1, 0.05, -0.2])
    rows = []
    for k in range(len(q)):
        rotation, _ = ur5_chain_rotation(q[k], "ee_link")
        g_sensor = rotation.T @ G_BASE
        wrench = np.r_[mass * g_sensor + force_bias, np.cross(com, mass * g_sensor) + torque_bias]
        names = ["shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint", "wrist_1_joint", "wrist_2_joint",
                 "wrist_3_joint"]
        rows.append({**dict(zip(names, q[k])), **{f"u{i + 1}": v for i, v in enumerate(wrench)}})
    pd.DataFrame(rows).to_csv(tmp_path / "poses.csv", index=False)
    ftcal = str(Path(sys.executable).with_name("ftcal"))
    done = subprocess.run([ftcal, "payload", str(tmp_path / "poses.csv"), "--urdf", str(UR5), "--ft-joint",
                           "ee_fixed_joint", "--base", "base_link", "--g", "9.81", "-o", str(tmp_path / "p.json")],
                          capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    result = json.loads((tmp_path / "p.json").read_text())
    assert result["mass"] == pytest.approx(mass, abs=1e-9)
    np.testing.assert_allclose(result["com"], com, atol=1e-9)
    np.testing.assert_allclose(result["force_bias"], force_bias, atol=1e-9)
    np.testing.assert_allclose(result["torque_bias"], torque_bias, atol=1e-9)
    nothing = subprocess.run([ftcal, "payload", str(tmp_path / "poses.csv"), "--urdf", str(UR5), "-o",
                              str(tmp_path / "q.json")], capture_output=True, text=True)
    assert nothing.returncode == 2 and "--ft-joint" in nothing.stderr and not (tmp_path / "q.json").exists()


def test_cli_compensate_with_gravity_from_the_urdf(tmp_path):
    """Issue 27: compensate takes the same robot-model gravity source as payload (--urdf/--ft-joint/--base).

    Truth by construction: readings = tool gravity wrench (hand kinematics) + bias + a known contact
    wrench; compensating with the payload identified from contact-free poses returns the contact.
    """
    import subprocess
    import sys
    from pathlib import Path

    import pandas as pd

    rng = np.random.default_rng(19)
    names = ["shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint", "wrist_1_joint", "wrist_2_joint",
             "wrist_3_joint"]
    mass, com = 0.9, np.array([-0.02, 0.01, 0.05])
    bias = np.array([1.0, -0.5, 0.3, 0.02, -0.04, 0.01])

    def table(q, contact):
        rows = []
        for k in range(len(q)):
            rotation, _ = ur5_chain_rotation(q[k], "ee_link")
            g_sensor = rotation.T @ G_BASE
            wrench = np.r_[mass * g_sensor, np.cross(com, mass * g_sensor)] + bias + contact[k]
            rows.append({**dict(zip(names, q[k])), **{f"u{i + 1}": v for i, v in enumerate(wrench)}})
        return pd.DataFrame(rows)

    q = rng.uniform(-3, 3, (30, 6))
    table(q, np.zeros((30, 6))).to_csv(tmp_path / "poses.csv", index=False)
    contact = rng.normal(size=(12, 6))
    table(rng.uniform(-3, 3, (12, 6)), contact).to_csv(tmp_path / "work.csv", index=False)
    ftcal = str(Path(sys.executable).with_name("ftcal"))
    robot = ["--urdf", str(UR5), "--ft-joint", "ee_fixed_joint", "--base", "base_link"]
    done = subprocess.run([ftcal, "payload", str(tmp_path / "poses.csv"), *robot, "-o", str(tmp_path / "p.json")],
                          capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    done = subprocess.run([ftcal, "compensate", str(tmp_path / "p.json"), str(tmp_path / "work.csv"), *robot,
                           "-o", str(tmp_path / "c.csv")], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    out = pd.read_csv(tmp_path / "c.csv")
    np.testing.assert_allclose(out[["Fx", "Fy", "Fz", "Tx", "Ty", "Tz"]].to_numpy(), contact, atol=1e-8)
    # no gravity source: the message names the robot options compensate accepts (--model NAME is a robot
    # model there too, since the calibration file became --calibration)
    none = subprocess.run([ftcal, "compensate", str(tmp_path / "p.json"), str(tmp_path / "work.csv"), "-o",
                           str(tmp_path / "d.csv")], capture_output=True, text=True)
    assert none.returncode == 2 and "--urdf PATH or --model NAME" in none.stderr


def test_a_missing_joint_on_the_sensor_chain_is_refused_not_held_at_zero(tmp_path):
    """Issue 27 (no silent zeros): a joint column left out was held at 0 rad, turning gravity in the
    sensor frame without a word. Joints on the chain from the base to the sensor are required."""
    import subprocess
    import sys
    from pathlib import Path

    import pandas as pd

    rng = np.random.default_rng(3)
    names = ["shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint", "wrist_1_joint", "wrist_2_joint"]
    table = pd.DataFrame(rng.uniform(-3, 3, (20, 5)), columns=names)  # no wrist_3_joint
    for i in range(6):
        table[f"u{i + 1}"] = rng.normal(size=20)
    table.to_csv(tmp_path / "poses.csv", index=False)
    ftcal = str(Path(sys.executable).with_name("ftcal"))
    done = subprocess.run([ftcal, "payload", str(tmp_path / "poses.csv"), "--urdf", str(UR5), "--ft-joint",
                           "ee_fixed_joint", "--base", "base_link", "-o", str(tmp_path / "p.json")],
                          capture_output=True, text=True)
    lines = done.stderr.strip().splitlines()
    assert done.returncode == 2 and len(lines) == 1 and "'wrist_3_joint'" in lines[0], done.stderr
    assert not (tmp_path / "p.json").exists()
