"""ROS 1 / ROS 2 bags: exact values and stamps back, tf chains, the topics and dataset commands, bad input."""

import warnings
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from bag_data import KINDS, Bag
from rosbags.highlevel import AnyReader
from scipy.spatial.transform import Rotation
from test_robot_expected import FOREARM, static_wrench
from test_robot_model import TINY_URDF

from ftcal.cli import main
from ftcal.data import bags
from ftcal.data.bags import BagTopics, read_bag
from ftcal.data.logs import read_recording
from ftcal.runtime.errors import FtcalError, FtcalWarning

T0 = 1_700_000_000 * 10**9  # a realistic epoch stamp, ns
MS = 10**6


def wrench_values(n, seed=0):
    return np.random.default_rng(seed).normal(0.0, 50.0, size=(n, 6))


def secs(ns):
    return np.asarray(ns, dtype=np.int64) * 1e-9


@pytest.mark.parametrize("kind", KINDS)
def test_wrench_values_and_header_stamps_exact(tmp_path, kind):
    n = 50
    values = wrench_values(n)
    receive = T0 + np.arange(n) * 10 * MS
    stamps = receive - 3 * MS + np.arange(n) * 7  # header stamps differ from the receive times
    bag = Bag(kind)
    for k in range(n):
        # frame_id lengths 0..7 exercise every CDR padding case
        bag.wrench("/ft", receive[k], values[k], stamp_ns=stamps[k], frame="f" * (k % 8))
    path = bag.write(tmp_path / "run")
    stream = read_bag(path, BagTopics("/ft")).ft["/ft"]
    np.testing.assert_array_equal(stream.data, values)
    np.testing.assert_array_equal(stream.time, secs(stamps))
    assert stream.clock == "header stamps" and stream.columns == ("u1", "u2", "u3", "u4", "u5", "u6")
    by_receive = read_bag(path, BagTopics("/ft", receive_time=True)).ft["/ft"]
    np.testing.assert_array_equal(by_receive.time, secs(receive))
    assert by_receive.clock == "receive time"


@pytest.mark.parametrize("generic", [False, True])
@pytest.mark.parametrize("kind", KINDS)
def test_wrench_matches_rosbags_deserializer(tmp_path, monkeypatch, kind, generic):
    """Both the storage-level readers and rosbags' message loop (used when its internals differ)."""
    if generic:
        monkeypatch.setattr(bags, "_fastest_batches", lambda path, reader, info: bags._batches(reader, info))
    bag = Bag(kind)
    values = wrench_values(200, seed=3)
    for k in range(200):
        bag.wrench("/wrench", T0 + k * MS, values[k], frame="wrist_ft_sensor_link")
    path = bag.write(tmp_path / "run")
    with AnyReader([path]) as reader:
        rows, stamps = [], []
        for conn, _, raw in reader.messages():
            msg = reader.deserialize(raw, conn.msgtype)
            f, t = msg.wrench.force, msg.wrench.torque
            rows.append((f.x, f.y, f.z, t.x, t.y, t.z))
            stamps.append(msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9)
    stream = read_bag(path, BagTopics("/wrench")).ft["/wrench"]
    np.testing.assert_array_equal(stream.data, np.array(rows))
    np.testing.assert_allclose(stream.time, stamps, rtol=0, atol=1e-6)
    assert stream.frame == "wrist_ft_sensor_link"


@pytest.mark.parametrize("kind,compress", [("ros1", False), ("ros1", True), ("mcap", False), ("mcap", True),
                                           ("mcap-file", True)])
def test_many_chunks_interleaved_topics_compression(tmp_path, kind, compress):
    """Over 1 MB of messages (MCAP chunks at 1 MB; ROS 1 chunks forced to 4 kB), two wrench topics, a third one."""
    n = 12_000
    values = wrench_values(2 * n, seed=11)
    bag = Bag(kind)
    for k in range(n):
        bag.wrench("/left", T0 + k * MS, values[k], frame="left_ft")
        bag.wrench("/right", T0 + k * MS + 1, values[n + k], frame="right_ft_frame")
        if k % 10 == 0:
            bag.temperature("/temp", T0 + k * MS + 2, 30.0)
    path = bag.write(tmp_path / "run", compress=compress, ros1_chunk_bytes=4096)
    with AnyReader([path]) as reader:
        want = {}
        for conn, receive, raw in reader.messages():
            if conn.topic != "/temp":
                msg = reader.deserialize(raw, conn.msgtype)
                f, t = msg.wrench.force, msg.wrench.torque
                want.setdefault(conn.topic, []).append((f.x, f.y, f.z, t.x, t.y, t.z))
    rec_right = read_bag(path, BagTopics("/right")).ft["/right"]
    rec_left = read_bag(path, BagTopics("/left")).ft["/left"]
    np.testing.assert_array_equal(rec_left.data, want["/left"])
    np.testing.assert_array_equal(rec_right.data, want["/right"])
    np.testing.assert_array_equal(rec_right.data, values[n:])
    np.testing.assert_array_equal(rec_left.time, secs(T0 + np.arange(n) * MS))
    assert (rec_left.frame, rec_right.frame) == ("left_ft", "right_ft_frame")
    with bags.open_bag(path) as reader:
        assert bags._indexed_spans(reader) == {"/left": (T0, T0 + (n - 1) * MS),
                                               "/right": (T0 + 1, T0 + (n - 1) * MS + 1),
                                               "/temp": (T0 + 2, T0 + (n - 10) * MS + 2)}


@pytest.mark.parametrize("kind", ["ros1", "mcap"])
def test_unstamped_wrench_uses_receive_time(tmp_path, kind):
    bag = Bag(kind)
    values = wrench_values(20, seed=5)
    receive = T0 + np.arange(20) * 4 * MS
    for k in range(20):
        bag.wrench("/ft_raw", receive[k], values[k], stamped=False)
    stream = read_bag(bag.write(tmp_path / "run"), BagTopics("/ft_raw")).ft["/ft_raw"]
    np.testing.assert_array_equal(stream.data, values)
    np.testing.assert_array_equal(stream.time, secs(receive))
    assert stream.clock == "receive time"


@pytest.mark.parametrize("kind", ["ros1", "db3"])
def test_joints_temperature_imu(tmp_path, kind):
    bag = Bag(kind)
    bag.wrench("/ft", T0, np.ones(6))
    bag.wrench("/ft", T0 + MS, np.ones(6))
    for k in range(5):
        t = T0 + k * 3 * MS
        names = ("b", "a") if k % 2 else ("a", "b")  # by name, whatever the order
        pos = {"a": 0.1 * k, "b": -0.2 * k}
        bag.joints("/joint_states", t, names, [pos[n] for n in names])
        bag.temperature("/temp", t, 30.0 + k)
        bag.temperature("/temp64", t, 40.0 - k, float64=True)
        angle = 0.1 * k
        bag.imu("/imu", t, Rotation.from_rotvec([0, 0, angle]).as_quat(), (k, 2 * k, 3 * k), (0, 0, 9.81 + k))
    path = bag.write(tmp_path / "run")
    rec = read_bag(path, BagTopics("/ft", joints="/joint_states", temperature="/temp", imu="/imu"))
    k = np.arange(5)
    assert rec.joints.columns == ("a", "b")
    np.testing.assert_allclose(rec.joints.data, np.c_[0.1 * k, -0.2 * k], atol=0)
    np.testing.assert_array_equal(rec.temperature["/temp"].data[:, 0], 30.0 + k)
    np.testing.assert_array_equal(rec.gyros["/imu"].data, np.c_[k, 2 * k, 3 * k])
    np.testing.assert_array_equal(rec.accelerometers["/imu"].data, np.c_[0 * k, 0 * k, 9.81 + k])
    expected_q = Rotation.from_rotvec(np.c_[0 * k, 0 * k, 0.1 * k]).as_quat()
    np.testing.assert_allclose(rec.orientations["/imu"].data, expected_q, atol=1e-15)
    np.testing.assert_array_equal(rec.joints.time, secs(T0 + k * 3 * MS))
    float64 = read_bag(path, BagTopics("/ft", temperature="/temp64")).temperature["/temp64"]
    np.testing.assert_array_equal(float64.data[:, 0], 40.0 - k)
    assert float64.clock == "receive time"


@pytest.mark.parametrize("covariance_flag", [True, False])
def test_imu_without_orientation(tmp_path, covariance_flag):
    """REP 145's covariance[0] = -1, or all-zero quaternions, mean the IMU gives no orientation."""
    bag = Bag("mcap")
    bag.wrench("/ft", T0, np.ones(6))
    for k in range(3):
        bag.imu("/imu", T0 + k * MS, (0, 0, 0, 0), (1, 2, 3), (4, 5, 6), has_orientation=not covariance_flag)
    rec = read_bag(bag.write(tmp_path / "run"), BagTopics("/ft", imu="/imu"))
    assert rec.orientations == {} and rec.gyros["/imu"].n_samples == 3


def rz(angle):
    return Rotation.from_rotvec(np.c_[np.zeros_like(angle), np.zeros_like(angle), angle])


@pytest.mark.parametrize("kind", ["ros1", "mcap"])
def test_tf_chain_composed_and_slerped(tmp_path, kind):
    """world -> base (static), world -> arm (about z, angle linear in time), arm -> sensor (static).

    The chain base -> world -> arm -> sensor walks the first edge backwards; slerp of a rotation about a
    fixed axis is linear in the angle, so the reference is R_world_base⁻¹ · Rz(ω t) · R_arm_sensor.
    """
    r_world_base = Rotation.from_euler("xyz", [0.3, -0.2, 0.1])
    r_arm_sensor = Rotation.from_euler("zyx", [1.0, 0.4, -0.7])
    omega = 0.8  # rad/s
    bag = Bag(kind)
    s = "/" if kind == "ros1" else ""  # old ROS 1 bags name frames with a leading slash; tf2 drops it
    bag.tf(T0, [(s + "world", s + "base", r_world_base.as_quat(), T0),
                (s + "arm", s + "sensor", r_arm_sensor.as_quat(), T0),
                (s + "world", s + "camera", (0.0, 0.0, 0.0, 0.0), T0)], static=True)  # off the chain: not used
    for k in range(11):  # tf at 10 Hz over 0..1 s
        t = T0 + k * 100 * MS
        bag.tf(t, [(s + "world", s + "arm", rz(np.array([omega * k * 0.1])).as_quat()[0], t)])
    ft_times = T0 + np.arange(-20, 120) * 10 * MS  # F/T at 100 Hz, starting before and ending after the tf
    for t in ft_times:
        bag.wrench("/ft", t, np.ones(6), frame="sensor")
    path = bag.write(tmp_path / "run")
    rec = read_bag(path, BagTopics("/ft", tf=("base", "/sensor")))
    stream = rec.orientations["tf:base:/sensor"]
    inside = ft_times[(ft_times >= T0) & (ft_times <= T0 + 1000 * MS)]
    np.testing.assert_array_equal(stream.time, secs(inside))
    t = secs(inside) - secs(T0)
    expected = r_world_base.inv() * rz(omega * t) * r_arm_sensor
    got = Rotation.from_quat(stream.data)
    # 1e-6 rad: epoch seconds in float64 resolve 2.4e-7 s
    np.testing.assert_allclose((got.inv() * expected).magnitude(), 0.0, atol=1e-6)


def test_registry_reads_bags_and_rejects_unknown(tmp_path):
    bag = Bag("db3")
    bag.wrench("/ft", T0, np.arange(6.0))
    path = bag.write(tmp_path / "run")
    rec = read_recording(path, topics=BagTopics("/ft"))
    np.testing.assert_array_equal(rec.ft["/ft"].data, [np.arange(6.0)])
    (tmp_path / "x.txt").write_text("")
    with pytest.raises(FtcalError, match=r"x.txt: is of unknown format '.txt'; use .bag, .csv, .db3"):
        read_recording(tmp_path / "x.txt")


# ------------------------------------------------------------------ commands
@pytest.mark.parametrize("kind", KINDS)
def test_topics_command(tmp_path, capfd, kind):
    bag = Bag(kind)
    for k in range(101):  # 100 Hz over 1 s
        bag.wrench("/ft", T0 + k * 10 * MS, np.ones(6))
    for k in range(11):
        bag.temperature("/temp", T0 + k * 100 * MS, 30.0)
    path = bag.write(tmp_path / "run")
    with bags.open_bag(path) as reader:  # from the indexes, without reading message data
        assert bags._indexed_spans(reader) == {"/ft": (T0, T0 + 1000 * MS), "/temp": (T0, T0 + 1000 * MS)}
    assert main(["topics", str(path)]) == 0
    out = capfd.readouterr().out.splitlines()
    assert out[0] == f"{path}: 2 topic(s)"
    rows = {line.split()[0]: line.split() for line in out[2:]}
    assert rows["/ft"][1:] == ["geometry_msgs/msg/WrenchStamped", "101", "100"]
    assert rows["/temp"][1:] == ["sensor_msgs/msg/Temperature", "11", "10"]
    # The command prints its step's summary; the step's JSON holds the same numbers.
    from ftcal.workflow import bag_topics

    result = bag_topics(path)
    assert result.summary().splitlines() == out
    assert [(t["name"], t["count"]) for t in result.to_dict()["topics"]] == [("/ft", 101), ("/temp", 11)]


def arm_bag(kind, tmp_path, *, n=300, temperature=True, imu=True, tf=True, joints=False):
    """F/T at 100 Hz with u = 10 + t per channel, the other topics at other rates, linear in time."""
    bag = Bag(kind)
    t_ft = np.arange(n) * 10 * MS
    for k, t in enumerate(t_ft):
        bag.wrench("/ft", T0 + t, 10.0 + t * 1e-9 + np.arange(6) + 1e-3 * np.sin(k * np.arange(1, 7)))
    for k in range(0, n // 3 + 1):
        t = k * 30 * MS
        if temperature:
            bag.temperature("/temp", T0 + t, 30.0 + 2.0 * t * 1e-9)
        if imu:
            bag.imu("/imu", T0 + t, rz(np.array([0.5 * t * 1e-9])).as_quat()[0], (0.1 * t * 1e-9, 0, 0),
                    (0, 0, 9.81))
        if joints:  # the gripper's joint is not in the URDF, and its position is unknown (NaN)
            bag.joints("/joint_states", T0 + t, ["gripper_finger", "shoulder"], [np.nan, 0.5 * t * 1e-9])
    if tf:
        bag.tf(T0, [("base", "ft_sensor", Rotation.from_rotvec([0.0, 0.3, 0.0]).as_quat(), T0)], static=True)
    return bag.write(tmp_path / "arm")


def test_dataset_from_bag_columns(tmp_path, capfd):
    path = arm_bag("db3", tmp_path)
    out = tmp_path / "data.csv"
    assert main(["dataset", str(path), "--wrench-topic", "/ft", "--temperature-topic", "/temp",
                 "--imu-topic", "/imu", "--tf", "base", "--no-filter", "-o", str(out)]) == 0  # frame: header.frame_id
    printed = capfd.readouterr().out
    assert "/ft 300 messages (header stamps, frame ft_sensor)" in printed
    assert printed.count(":/imu: ") == 1  # one line per topic, though the IMU gives several streams
    frame = pd.read_csv(out)
    assert list(frame.columns) == ["time", "u1", "u2", "u3", "u4", "u5", "u6", "T", "qx", "qy", "qz", "qw",
                                   "wx", "wy", "wz", "ax", "ay", "az", "static", "hold", "segment", "load"]
    # /tf_static holds the sensor still: the whole recording is one hold
    assert frame["static"].eq(1).all() and frame["hold"].eq(0).all()
    t = frame["time"].to_numpy() - secs(T0)
    # temperature and IMU at 33 Hz cover 0 .. 3.00 s, so no F/T sample is trimmed; epoch seconds in float64
    # resolve 2.4e-7 s, hence the tolerances
    assert len(frame) == 300 and t[-1] == pytest.approx(2.99)
    np.testing.assert_allclose(frame["T"], 30.0 + 2.0 * t, atol=1e-6)
    np.testing.assert_allclose(frame["wx"], 0.1 * t, atol=1e-6)
    np.testing.assert_allclose(frame["u1"] - 10.0 - t, 1e-3 * np.sin(np.round(t * 100)), atol=1e-6)
    expected_q = Rotation.from_rotvec([0.0, 0.3, 0.0]).as_quat()  # tf wins over the IMU's orientation
    np.testing.assert_allclose(frame[["qx", "qy", "qz", "qw"]].to_numpy(), np.tile(expected_q, (300, 1)),
                               atol=1e-12)


def test_dataset_from_bag_imu_orientation_slerped_and_no_temperature(tmp_path):
    path = arm_bag("ros1", tmp_path, temperature=False, tf=False)
    out = tmp_path / "data.parquet"
    assert main(["dataset", str(path), "--wrench-topic", "/ft", "--imu-topic", "/imu", "--no-filter",
                 "-o", str(out)]) == 0
    frame = pd.read_parquet(out)
    assert "T" not in frame.columns and "Fx" not in frame.columns
    t = frame["time"].to_numpy() - secs(T0)
    q = Rotation.from_quat(frame[["qx", "qy", "qz", "qw"]].to_numpy())
    np.testing.assert_allclose((q.inv() * rz(0.5 * t)).magnitude(), 0.0, atol=1e-6)
    # a uniform 40 Hz clock instead of the F/T stamps: every column on it, orientation slerped
    assert main(["dataset", str(path), "--wrench-topic", "/ft", "--imu-topic", "/imu", "--no-filter",
                 "--rate", "40", "-o", str(out)]) == 0
    frame = pd.read_parquet(out)
    t = frame["time"].to_numpy() - secs(T0)
    np.testing.assert_allclose(np.diff(t), 0.025, atol=1e-6)
    assert len(frame) == 120  # 0 .. 2.975 s: the F/T stream ends at 2.99 s
    np.testing.assert_allclose(frame["wx"], 0.1 * t, atol=1e-6)
    q = Rotation.from_quat(frame[["qx", "qy", "qz", "qw"]].to_numpy())
    np.testing.assert_allclose((q.inv() * rz(0.5 * t)).magnitude(), 0.0, atol=1e-6)


def test_dataset_from_bag_with_urdf_expected_wrench(tmp_path, capfd):
    path = arm_bag("mcap", tmp_path, temperature=False, imu=False, tf=False, joints=True)
    urdf = tmp_path / "tiny.urdf"
    urdf.write_text(TINY_URDF)
    out = tmp_path / "data.csv"
    with warnings.catch_warnings():
        warnings.simplefilter("always", FtcalWarning)
        assert main(["dataset", str(path), "--wrench-topic", "/ft", "--joints-topic", "/joint_states",
                     "--urdf", str(urdf), "--sensor", "arm_ft", "--savgol-frame", "21", "--workers", "1",
                     "-o", str(out)]) == 0
    assert "joint(s) gripper_finger are not in the URDF; ignored" in capfd.readouterr().err
    frame = pd.read_csv(out)
    t = frame["time"].to_numpy() - secs(T0)
    reference = np.array([static_wrench([FOREARM], 0.5 * tk) for tk in t])
    np.testing.assert_allclose(frame[["Fx", "Fy", "Fz", "Tx", "Ty", "Tz"]].to_numpy(), reference, atol=1e-5)
    assert "T" not in frame.columns  # no temperature topic asked for: the fit uses u1..u6 alone
    np.testing.assert_allclose(frame["shoulder"], 0.5 * t, atol=1e-6)  # the URDF's joint kept, named as it
    assert "gripper_finger" not in frame.columns
    model = tmp_path / "model.json"
    with warnings.catch_warnings():
        warnings.simplefilter("always", FtcalWarning)
        assert main(["fit", str(out), "--segment-by", "segment", "--group-by", "load", "-o", str(model)]) == 0
    assert model.is_file()
    # one joint turning one link: its reference wrench spans 2 of the 6 directions, and fit says so
    assert "warning: reference wrenches span 2 of 6 directions" in capfd.readouterr().err


def test_dataset_from_bags_on_a_local_cluster_equals_the_local_run(tmp_path):
    """--scheduler local:2: one task per bag on real Dask worker processes, which rebuild the robot
    from its URDF text; same table as in this process, and the workers' warnings come back."""
    import subprocess
    import sys

    for kind in ("mcap", "ros1"):
        (tmp_path / kind).mkdir()
    bags = [str(arm_bag(kind, tmp_path / kind, n=120, temperature=False, imu=False, tf=False, joints=True))
            for kind in ("mcap", "ros1")]
    urdf = tmp_path / "tiny.urdf"
    urdf.write_text(TINY_URDF)
    ftcal = str(Path(sys.executable).with_name("ftcal"))
    common = [ftcal, "dataset", *bags, "--wrench-topic", "/ft", "--joints-topic", "/joint_states",
              "--urdf", str(urdf), "--sensor", "arm_ft", "--no-filter", "--workers", "1"]
    here = subprocess.run([*common, "-o", str(tmp_path / "here.csv")], capture_output=True, text=True)
    there = subprocess.run([*common, "--scheduler", "local:2", "-o", str(tmp_path / "there.csv")],
                           capture_output=True, text=True)
    assert here.returncode == 0 and there.returncode == 0, there.stderr
    assert there.stderr.count("gripper_finger are not in the URDF") == 2  # one per bag, from the workers
    pd.testing.assert_frame_equal(pd.read_csv(tmp_path / "there.csv"), pd.read_csv(tmp_path / "here.csv"))
    frame = pd.read_csv(tmp_path / "there.csv")
    assert sorted(frame["segment"].unique()) == [0, 1] and len(frame) == 240


def fails(capfd, argv, message, out):
    """Exit 2, exactly one stderr line naming the problem, nothing written."""
    assert main(argv) == 2
    lines = capfd.readouterr().err.strip().splitlines()
    assert len(lines) == 1, lines
    assert lines[0].startswith(f"ftcal {argv[0]}: error: ") and message in lines[0], lines[0]
    assert not Path(out).exists()


def test_bad_bags(tmp_path, capfd):
    out = tmp_path / "data.csv"
    path = arm_bag("mcap", tmp_path, n=60)
    run = ["dataset", str(path), "-o", str(out), "--no-filter"]
    fails(capfd, [*run, "--wrench-topic", "/wrench"], "no topic '/wrench' (--wrench-topic); the bag has: "
          "/ft, /imu, /temp, /tf_static", out)
    fails(capfd, [*run, "--wrench-topic", "/imu"], "topic '/imu' has type sensor_msgs/msg/Imu; --wrench-topic "
          "needs geometry_msgs/msg/WrenchStamped or geometry_msgs/msg/Wrench", out)
    fails(capfd, [*run, "--wrench-topic", "/ft", "--temperature-topic", "/imu"], "topic '/imu' has type", out)
    fails(capfd, [*run, "--wrench-topic", "/ft", "--tf", "world"],
          "no tf chain from 'world' to 'ft_sensor' (frames known: base, ft_sensor); without one, record the "
          "joints: --joints-topic with --urdf", out)
    fails(capfd, [*run], "--wrench-topic is required", out)
    bag = Bag("mcap")  # a driver whose header stamps repeat: refused, and --receive-time reads it
    for k in range(20):
        bag.wrench("/ft", T0 + k * MS, np.ones(6) + np.sin(k + np.arange(6)), stamp_ns=T0 + (k // 2) * MS)
    repeats = bag.write(tmp_path / "repeats")
    fails(capfd, ["dataset", str(repeats), "--wrench-topic", "/ft", "--no-filter", "-o", str(out)],
          "repeats:/ft: timestamps do not increase at sample 1 (t=1700000000.000000 then 1700000000.000000); "
          "time the messages by the bag's receive time with --receive-time, or sort the bag by stamp", out)
    assert main(["dataset", str(repeats), "--wrench-topic", "/ft", "--no-filter", "--receive-time",
                 "-o", str(out)]) == 0
    assert "(receive time, frame ft_sensor)" in capfd.readouterr().out
    out.unlink()
    fails(capfd, ["dataset", str(tmp_path / "absent.bag"), "--wrench-topic", "/ft", "-o", str(out)],
          "absent.bag: no such file", out)

    bag = Bag("db3")  # the temperature stream ends before the F/T stream starts
    for k in range(10):
        bag.wrench("/ft", T0 + (k + 100) * MS, np.ones(6))
        bag.temperature("/temp", T0 + k * MS, 30.0)
    late = bag.write(tmp_path / "late")
    fails(capfd, ["dataset", str(late), "--wrench-topic", "/ft", "--temperature-topic", "/temp", "--no-filter",
                  "-o", str(out)], "do not overlap in time", out)

    bag = Bag("ros1")
    for k in range(10):
        bag.wrench("/ft", T0 + k * MS, [1, 2, np.nan if k == 4 else 3, 4, 5, 6])
    nan = bag.write(tmp_path / "nan")
    fails(capfd, ["dataset", str(nan), "--wrench-topic", "/ft", "--no-filter", "-o", str(out)],
          "nan.bag:/ft: NaN stretch in column 'u3'", out)

    bag = Bag("mcap")
    for k in range(10):
        bag.wrench("/ft", T0 + k * MS, np.ones(6))
        bag.imu("/imu", T0 + k * MS, (0, 0, 0.5, 0.5), (0, 0, 0), (0, 0, 9.81))
    loose = bag.write(tmp_path / "loose")
    fails(capfd, ["dataset", str(loose), "--wrench-topic", "/ft", "--imu-topic", "/imu", "--no-filter",
                  "-o", str(out)], "topic '/imu': quaternion at t=", out)

    bag = Bag("mcap")
    bag.wrench("/ft", T0, np.ones(6), frame="sensor")
    bag.tf(T0, [("base", "sensor", (0.0, 0.0, 0.0, 2.0), T0)], static=True)
    fails(capfd, ["dataset", str(bag.write(tmp_path / "badtf")), "--wrench-topic", "/ft", "--tf",
                  "base:sensor", "-o", str(out)], "tf base->sensor: quaternion at t=", out)
    bag = Bag("db3")
    bag.wrench("/ft", T0, np.ones(6), frame="")
    fails(capfd, ["dataset", str(bag.write(tmp_path / "noframe")), "--wrench-topic", "/ft", "--tf", "base",
                  "-o", str(out)], "names no frame (header.frame_id); give the sensor frame as --tf base:SENSOR_FRAME",
          out)

    fails(capfd, ["dataset", str(path), "--wrench-topic", "/ft", "--joints-topic", "/joint_states",
                  "--sensor", "arm_ft", "--urdf", str(tmp_path / "none.urdf"), "-o", str(out)], "none.urdf", out)
    fails(capfd, [*run, "--wrench-topic", "/ft", "--joints-topic", "/imu"],
          "topic '/imu' has type sensor_msgs/msg/Imu; --joints-topic needs sensor_msgs/msg/JointState", out)
    mat = tmp_path / "log.csv"
    mat.write_text("time\n0\n")
    fails(capfd, ["dataset", str(mat), "--wrench-topic", "/ft", "-o", str(out)],
          "--wrench-topic applies to ROS bags only", out)
    fails(capfd, ["dataset", str(path), str(mat), "--wrench-topic", "/ft", "-o", str(out)], "mix of ROS bags", out)
    fails(capfd, ["dataset", str(mat), "-o", str(out)], "--urdf or --model is required for .mat/.csv/.parquet", out)
    fails(capfd, ["dataset", str(mat), "--model", "iCubGenova04", "-o", str(out)], "--sensor is required", out)
    fails(capfd, ["topics", str(mat)], "cannot open it as a ROS 1 .bag", out)
    imu_bags = []
    for j, q in enumerate([(0, 0, 0, 1), (0, 0, 0, 0)]):  # the second IMU gives no orientation
        bag = Bag("db3")
        for k in range(10):
            bag.wrench("/ft", T0 + k * MS, np.ones(6) + k)
            bag.imu("/imu", T0 + k * MS, q, (0, 0, 0), (0, 0, 9.81))
        imu_bags.append(str(bag.write(tmp_path / f"imu{j}")))
    fails(capfd, ["dataset", *imu_bags, "--wrench-topic", "/ft", "--imu-topic", "/imu", "--no-filter", "-o", str(out)],
          "imu1: gives columns time,u1,u2,u3,u4,u5,u6,wx,wy,wz,ax,ay,az,static,hold,segment,load but", out)
    for kind in ("ros1", "mcap-file"):
        bag = Bag(kind)
        for k in range(2000):
            bag.wrench("/ft", T0 + k * MS, np.ones(6))
        whole = bag.write(tmp_path / f"whole-{kind}")
        cut = whole.with_name("cut" + whole.suffix)
        cut.write_bytes(whole.read_bytes()[: whole.stat().st_size // 2])
        fails(capfd, ["dataset", str(cut), "--wrench-topic", "/ft", "-o", str(out)], f"Bag {cut}: cannot", out)


def test_two_bags_segments_groups_and_gap_warning(tmp_path, capfd):
    paths = []
    for j, kind in enumerate(("mcap", "ros1")):
        bag = Bag(kind)
        ticks = [k for k in range(200) if not (j == 1 and 100 <= k < 110)]  # the second bag drops 10 messages
        for k in ticks:
            bag.wrench("/ft", T0 + k * 10 * MS, 10.0 + np.sin(0.1 * k + np.arange(6)))
        paths.append(str(bag.write(tmp_path / f"run{j}")))
    out = tmp_path / "data.csv"
    with warnings.catch_warnings():  # the CLI prints its warnings on stderr itself
        warnings.simplefilter("always", FtcalWarning)
        assert main(["dataset", *paths, "--wrench-topic", "/ft", "--savgol-frame", "11", "-o", str(out)]) == 0
    err = capfd.readouterr().err
    assert ("warning: run1.bag:/ft: 1 gap(s) in the timestamps, about 10 dropped sample(s) "
            "(largest gap 0.110 s)") in err
    frame = pd.read_csv(out)
    assert frame.groupby("segment").size().to_dict() == {0: 200, 1: 190}
    assert frame.groupby("segment")["load"].first().to_dict() == {0: "run0", 1: "run1"}


def test_tf_frame_other_than_the_wrench_frame_warns(tmp_path, capfd):
    bag = Bag("mcap")
    for k in range(5):
        bag.wrench("/ft", T0 + k * MS, np.ones(6) + k, frame="ft_sensor")
    bag.tf(T0, [("base", "tool0", (0.0, 0.0, 0.0, 1.0), T0)], static=True)
    out = tmp_path / "data.csv"
    with warnings.catch_warnings():
        warnings.simplefilter("always", FtcalWarning)
        assert main(["dataset", str(bag.write(tmp_path / "run")), "--wrench-topic", "/ft", "--tf", "base:tool0",
                     "--no-filter", "-o", str(out)]) == 0
    assert ("/ft is expressed in frame 'ft_sensor' (header.frame_id) but the tf chain ends at 'tool0'"
            in capfd.readouterr().err)
    np.testing.assert_array_equal(pd.read_csv(out)[["qx", "qy", "qz", "qw"]].to_numpy(), [[0, 0, 0, 1]] * 5)
