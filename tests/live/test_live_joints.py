"""The live calibrator with gravity from joint positions and a URDF: library, ``live --replay`` of a table and of a
ROS bag, and ``/joint_states`` over Zenoh.

Truth: a UR5 (example-robot-data) whose sensor-frame gravity is composed by hand from the URDF's joint origins and
axes (``test_robot_declare.ur5_chain_rotation``, scipy rotations, no iDynTree), holding a known tool
(F = m g_s, T = c × m g_s) with a known bias and simulated noise.
"""

from __future__ import annotations

import json
import signal
import socket
import subprocess
import sys
import time

import numpy as np
import pandas as pd
import pytest
from bag_data import Bag
from test_robot_declare import G_BASE, UR5, ur5_chain_rotation

from ftcal.cli import main
from ftcal.files.payload_json import save_payload
from ftcal.live import LiveCalibrator
from ftcal.payload.parameters import PayloadParameters

pytestmark = pytest.mark.skipif(not UR5.is_file(), reason="example-robot-data is not installed")

JOINTS = ["shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint", "wrist_1_joint", "wrist_2_joint",
          "wrist_3_joint"]
MASS, COM = 1.6, np.array([0.015, -0.01, 0.09])
BIAS = np.array([3.0, -2.0, 5.0, 0.2, -0.1, 0.05])
NOISE = np.array([0.05, 0.05, 0.05, 0.002, 0.002, 0.002])
RATE = 200.0
AXES = ["Fx", "Fy", "Fz", "Tx", "Ty", "Tz"]


def ur5_recording(n_poses=8, hold_s=1.5, move_s=0.5, seed=3):
    """Joint positions holding ``n_poses`` poses and moving between them, the wrench the tool puts on the sensor."""
    rng = np.random.default_rng(seed)
    targets = rng.uniform(-2.5, 2.5, (n_poses, 6))
    period = hold_s + move_s
    t = np.arange(0.0, n_poses * period - move_s, 1.0 / RATE)
    k = np.minimum((t // period).astype(int), n_poses - 1)
    phase = np.clip((t - k * period - hold_s) / move_s, 0.0, 1.0)
    blend = phase ** 3 * (10 - 15 * phase + 6 * phase ** 2)  # minimum jerk
    q = targets[k] + blend[:, None] * (targets[np.minimum(k + 1, n_poses - 1)] - targets[k])
    gravity = np.array([ur5_chain_rotation(row, "ee_link")[0].T @ G_BASE for row in q])
    force = MASS * gravity
    wrench = np.c_[force, np.cross(COM, force)] + BIAS + rng.normal(size=(t.size, 6)) * NOISE
    return t, q, gravity, wrench, phase == 0.0


@pytest.fixture(scope="module")
def recording():
    return ur5_recording()


def sensor_gravity():
    from ftcal.robot import RobotModel, SensorDeclaration
    from ftcal.robot.kinematics import SensorGravity

    robot = RobotModel.load(UR5, declared=[SensorDeclaration("ee_fixed_joint")])
    return SensorGravity(robot, "ee_fixed_joint", JOINTS, base="base_link")


def tool_payload() -> PayloadParameters:
    return PayloadParameters(MASS, COM, np.zeros(3), np.zeros(3), 9.81,
                             stderr={"mass": 1e-3, "com": np.full(3, 1e-4), "force_bias": np.full(3, .01),
                                     "torque_bias": np.full(3, 1e-3)},
                             fit={"n_samples": 100, "residual_rms": NOISE, "condition_number": 1.0,
                                  "wrench_columns": AXES})


def test_sensor_gravity_matches_the_hand_composed_chain(recording):
    t, q, gravity, *_ = recording
    source = sensor_gravity()
    rows = np.arange(0, t.size, 97)
    np.testing.assert_allclose(source(q[rows]), gravity[rows], atol=1e-9)
    np.testing.assert_allclose(source.one(q[5]), gravity[5], atol=1e-9)
    # Joints given in another order, with one the chain does not need left out: the same gravity.
    other = source.with_joints(JOINTS[::-1])
    np.testing.assert_allclose(other.one(q[5][::-1]), gravity[5], atol=1e-9)


def test_live_takes_joints_and_a_robot_model(recording):
    t, q, gravity, wrench, holding = recording
    make = lambda: LiveCalibrator(tools={"tool": tool_payload()}, tool="tool", robot=sensor_gravity())  # noqa: E731
    block = make().run(t, wrench=wrench, joints=q)
    live = make()
    steps = [live.step(t[k], wrench=wrench[k], joints=q[k]) for k in range(t.size)]
    np.testing.assert_array_equal(block.static, [s.static for s in steps])
    np.testing.assert_allclose(block.bias, [s.bias for s in steps], rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(block.compensated, [s.compensated for s in steps], rtol=1e-9, atol=1e-9)
    # The joints are the motion signal: static only while holding; the bias is the true one; compensated is noise.
    # (a minimum-jerk move starts and ends slower than the 0.01 rad/s threshold: a few such samples are still)
    assert block.static.sum() > 0.5 * holding.sum() and np.mean(~holding[block.static]) < 0.05
    known = np.arange(t.size) > np.argmax(block.updated) + RATE  # a second after the first update (bias unknown before)
    assert np.all(np.abs(block.bias[-1] - BIAS) < 4 * block.bias_std[-1]) and np.all(block.bias_std[-1] < NOISE)
    rms = np.sqrt(np.mean(block.compensated[known & holding] ** 2, axis=0))
    assert np.all(rms < 1.3 * NOISE), rms / NOISE
    # The sensor's orientation from the same (hand-composed) kinematics, with the same static samples: the same numbers.
    from scipy.spatial.transform import Rotation

    quat = Rotation.from_matrix([ur5_chain_rotation(row, "ee_link")[0] for row in q]).as_quat()
    by_quat = LiveCalibrator(tools={"tool": tool_payload()}, tool="tool").run(t, wrench=wrench, quaternion=quat,
                                                                             static=block.static)
    np.testing.assert_allclose(by_quat.compensated, block.compensated, atol=1e-6)
    np.testing.assert_allclose(by_quat.bias, block.bias, atol=1e-6)


def test_joints_without_a_robot_model_are_refused():
    from ftcal.runtime.errors import FtcalError

    with pytest.raises(FtcalError, match="robot model"):
        LiveCalibrator(noise_std=NOISE).run([0.0], wrench=np.zeros((1, 6)), joints=np.zeros((1, 6)))
    live = LiveCalibrator(noise_std=NOISE, robot=sensor_gravity())
    with pytest.raises(FtcalError, match="joints has 5 values"):
        live.step(0.0, wrench=np.zeros(6), joints=np.zeros(5))


def compensated_rms(out: pd.DataFrame, holding: np.ndarray) -> np.ndarray:
    known = np.arange(len(out)) > np.argmax(out["updated"].to_numpy()) + RATE
    return np.sqrt(np.mean(out[AXES].to_numpy()[known & holding] ** 2, axis=0))


def test_replay_a_table_with_joint_columns_and_the_urdf(recording, tmp_path, capsys):
    t, q, _, wrench, holding = recording
    table = tmp_path / "ur5.csv"
    pd.DataFrame({"time": t, **{n: q[:, j] for j, n in enumerate(JOINTS)},
                  **{a: wrench[:, j] for j, a in enumerate(AXES)}}).to_csv(table, index=False)
    save_payload(tool_payload(), tmp_path / "tool.json")
    out = tmp_path / "out.csv"
    assert main(["live", "--replay", str(table), "--urdf", str(UR5), "--ft-joint", "ee_fixed_joint", "--base",
                 "base_link", "--inputs", ",".join(AXES), "--tool", f"tool={tmp_path / 'tool.json'}",
                 "-o", str(out)]) == 0
    frame = pd.read_csv(out)
    assert np.all(compensated_rms(frame, holding) < 1.3 * NOISE)
    np.testing.assert_allclose(frame[[f"bias_{a}" for a in AXES]].to_numpy()[-1], BIAS, atol=0.05)
    capsys.readouterr()
    # The same options as `ftcal payload`: an unknown joint name for the sensor is one line, exit 2.
    code = subprocess.run([sys.executable, "-m", "ftcal", "live", "--replay", str(table), "--urdf", str(UR5),
                           "--ft-joint", "no_such_joint", "--inputs", ",".join(AXES), "-o", str(tmp_path / "x.csv")],
                          capture_output=True, text=True)
    assert code.returncode == 2 and len(code.stderr.strip().splitlines()) == 1 and not (tmp_path / "x.csv").exists()
    code = subprocess.run([sys.executable, "-m", "ftcal", "live", "--replay", str(table), "--urdf", str(UR5),
                           "--ft-joint", "ee_fixed_joint", "--orientation", "a,b,c,d", "--inputs", ",".join(AXES),
                           "-o", str(tmp_path / "x.csv")], capture_output=True, text=True)
    assert code.returncode == 2 and "one gravity source" in code.stderr


def test_replay_a_bag_with_joint_states(recording, tmp_path):
    t, q, _, wrench, holding = recording
    bag = Bag("mcap")
    t0 = 1_700_000_000 * 10 ** 9
    for k in range(t.size):
        stamp = t0 + int(round(t[k] * 1e9))
        bag.wrench("/ft", stamp, wrench[k])
        bag.joints("/joint_states", stamp, [*JOINTS, "gripper_finger"], [*q[k], 0.0])
    path = bag.write(tmp_path / "ur5")
    save_payload(tool_payload(), tmp_path / "tool.json")
    out = tmp_path / "out.parquet"
    assert main(["live", "--replay", str(path), "--wrench-topic", "/ft", "--joints-topic", "/joint_states",
                 "--urdf", str(UR5), "--ft-joint", "ee_fixed_joint", "--base", "base_link",
                 "--tool", f"tool={tmp_path / 'tool.json'}", "-o", str(out)]) == 0
    frame = pd.read_parquet(out)
    assert len(frame) == t.size
    np.testing.assert_allclose(frame["time"].to_numpy() - frame["time"].iloc[0], t, atol=1e-6)
    np.testing.assert_allclose(frame[[f"calibrated_{a}" for a in AXES]].to_numpy(), wrench, atol=1e-9)
    assert np.all(compensated_rms(frame, holding) < 1.3 * NOISE)


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_joint_states_over_zenoh(recording, tmp_path):
    import zenoh

    from ftcal.live.cdr import WRENCH_DOUBLES, decode_stamped, encode_stamped
    from ftcal.live.zenoh_node import JOINT_STATE_TYPE, typestore, zenoh_config

    t, q, _, wrench, holding = recording
    save_payload(tool_payload(), tmp_path / "tool.json")
    port = free_port()
    node = subprocess.Popen([str(__import__("pathlib").Path(sys.executable).with_name("ftcal")), "live", "--zenoh",
                             "--listen", f"tcp/127.0.0.1:{port}", "--joints-topic", "/joint_states", "--urdf",
                             str(UR5), "--ft-joint", "ee_fixed_joint", "--base", "base_link",
                             "--tool", "tool=tool.json", "--silence", "5"],
                            cwd=tmp_path, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    got = {}
    try:
        assert "listening on ft/raw and joint_states" in node.stdout.readline()
        session = zenoh.open(zenoh_config(connect=(f"tcp/127.0.0.1:{port}",)))
        store = typestore()
        types = store.types

        def on(sample):
            msg = decode_stamped(sample.payload.to_bytes(), WRENCH_DOUBLES)
            got[msg.stamp_ns] = msg.values

        sub = session.declare_subscriber("ft/compensated", on)
        joints_pub, wrench_pub = session.declare_publisher("joint_states"), session.declare_publisher("ft/raw")
        time.sleep(1.0)
        stamps = 10 ** 9 + np.round(t * 1e9).astype(np.int64)
        for k in range(t.size):
            sec, nanosec = divmod(int(stamps[k]), 10 ** 9)
            header = types["std_msgs/msg/Header"](stamp=types["builtin_interfaces/msg/Time"](sec=sec, nanosec=nanosec),
                                                  frame_id="")
            state = types[JOINT_STATE_TYPE](header=header, name=["gripper_finger", *JOINTS],
                                            position=np.r_[0.0, q[k]], velocity=np.zeros(0), effort=np.zeros(0))
            joints_pub.put(bytes(store.serialize_cdr(state, JOINT_STATE_TYPE)))
            wrench_pub.put(encode_stamped(int(stamps[k]), "ft", wrench[k].tolist()))
            if k % 5 == 0:  # about the recording's rate: a joint state is not far behind its wrench
                time.sleep(0.005)
        time.sleep(1.0)
        sub.undeclare()
        session.close()
    finally:
        node.send_signal(signal.SIGTERM)
        _, err = node.communicate(timeout=60)
    index = {int(s): k for k, s in enumerate(stamps)}
    rows = np.array([index[s] for s in got])
    values = np.array([got[s] for s in got])
    assert rows.size >= 0.95 * t.size, err
    settled = holding[rows] & (t[rows] > 2.0)
    assert np.all(np.sqrt(np.mean(values[settled] ** 2, axis=0)) < 1.5 * NOISE), err
