"""``ftcal live --zenoh --keys rmw_zenoh``: RIHS01 type hashes checked against published ROS 2 values, and a real
loopback Zenoh peer (multicast scouting off, explicit tcp/127.0.0.1 endpoints) talking to the node on rmw_zenoh's
keys, decoding the calibrated wrench with rosbags and the attachment with zenoh's own deserializer."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

import zenoh
import zenoh.ext

from ftcal.live.rmw_zenoh import Attachment, data_key, dds_type_name, type_hash
from ftcal.live.zenoh_node import typestore, wrench_message, zenoh_config

FTCAL = str(Path(sys.executable).with_name("ftcal"))

# RIHS01 hashes published in ROS 2 sources, found with the search tool (none of them comes from ftcal):
# - ZettaScaleLabs/ros-z, crates/ros-z-codegen/tests/hash_regression.rs (golden values of its resolver, which its
#   tests check against rmw_zenoh_cpp interop): String, Header, PoseStamped, TwistStamped, Imu, Odometry;
# - Pico-ROS/Pico-ROS-software, examples/example_types.h (made with rosidl_generator_type_description): Vector3,
#   Quaternion, Time, Pose, Twist (and String, Header, Odometry again);
# - janvanhulzen/test_ws_09112025, its top-level README (github.com/janvanhulzen/test_ws_09112025/blob/HEAD/readme.md):
#   `ros2 topic info /joint_states --verbose` printed by a running ROS 2 system ("Topic type hash: RIHS01_a13ee3a3...");
# - WrenchStamped and Wrench: a Pico-ROS type header generated from /opt/ros/jazzy/share (found by exact-string
#   search; the index does not name its repository) and a generated msgspec message module that carries the same
#   WrenchStamped value.
PUBLISHED = {
    "std_msgs/msg/String": "df668c740482bbd48fb39d76a70dfd4bd59db1288021743503259e948f6b1a18",
    "std_msgs/msg/Header": "f49fb3ae2cf070f793645ff749683ac6b06203e41c891e17701b1cb597ce6a01",
    "geometry_msgs/msg/PoseStamped": "10f3786d7d40fd2b54367835614bff85d4ad3b5dab62bf8bca0cc232d73b4cd8",
    "geometry_msgs/msg/TwistStamped": "5f0fcd4f81d5d06ad9b4c4c63e3ea51b82d6ae4d0558f1d475229b1121db6f64",
    "sensor_msgs/msg/Imu": "7d9a00ff131080897a5ec7e26e315954b8eae3353c3f995c55faf71574000b5b",
    "nav_msgs/msg/Odometry": "3cc97dc7fb7502f8714462c526d369e35b603cfc34d946e3f2eda2766dfec6e0",
    "geometry_msgs/msg/Vector3": "cc12fe83e4c02719f1ce8070bfd14aecd40f75a96696a67a2a1f37f7dbb0765d",
    "geometry_msgs/msg/Quaternion": "8a765f66778c8ff7c8ab94afcc590a2ed5325a1d9a076ffff38fbce36f458684",
    "builtin_interfaces/msg/Time": "b106235e25a4c5ed35098aa0a61a3ee9c9b18d197f398b0e4206cea9acf9c197",
    "geometry_msgs/msg/Pose": "d501954e9476cea2996984e812054b68026ae0bfae789d9a10b23daf35cc90fa",
    "geometry_msgs/msg/Twist": "9c45bf16fe0983d80e3cfe750d6835843d265a9a6c46bd2e609fcddde6fb8d2a",
    "sensor_msgs/msg/JointState": "a13ee3a330e346c9d87b5aa18d24e11690752bd33a0350f11c5882bc9179260e",
    "geometry_msgs/msg/Wrench": "018e8519d57c16adbe97c9fe1460ef21fec7e31bc541de3d653a35895677ce52",
    "geometry_msgs/msg/WrenchStamped": "8dc3deaf06b2ab281f9f9a742a8961c328ca7cec16e3fd6586d3a5c83fa78f77",
}
WRENCH_DDS = "geometry_msgs::msg::dds_::WrenchStamped_"  # rmw_zenoh's example keys: std_msgs::msg::dds_::String_


def free_port() -> int:
    import socket

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.mark.parametrize("msgtype", sorted(PUBLISHED))
def test_type_hashes_equal_published_values(msgtype):
    assert type_hash(msgtype) == "RIHS01_" + PUBLISHED[msgtype]


def test_key_expressions_follow_rmw_zenoh():
    # rmw_zenoh's example data key is 0/chatter/std_msgs::msg::dds_::String_/RIHS01_df668c74...; its C sibling
    # rmw_zenohpico formats "%zu/%s/%s/%s" with the topic after its leading slash.
    assert data_key(0, "/chatter", "std_msgs/msg/String") == \
        "0/chatter/std_msgs::msg::dds_::String_/RIHS01_" + PUBLISHED["std_msgs/msg/String"]
    assert dds_type_name("geometry_msgs/msg/WrenchStamped") == WRENCH_DDS
    assert data_key(42, "/robot1/ft/raw/", "geometry_msgs/msg/WrenchStamped") == \
        f"42/robot1/ft/raw/{WRENCH_DDS}/RIHS01_{PUBLISHED['geometry_msgs/msg/WrenchStamped']}"


def test_attachment_is_what_zenohs_serializer_writes():
    attachment = Attachment("0/ft/calibrated", "abc")
    first, second = attachment.next(1_700_000_000_123_456_789), attachment.next(5)
    # rmw_zenoh_cpp attachment_helpers.cpp: key string then value, for the three fields, with ze_serializer.
    expected = zenoh.ext.z_serialize(("sequence_number", zenoh.ext.Int64(1), "source_timestamp",
                                      zenoh.ext.Int64(1_700_000_000_123_456_789), "source_gid", attachment.gid))
    assert first == expected.to_bytes()
    decoded = zenoh.ext.z_deserialize(tuple[str, zenoh.ext.Int64, str, zenoh.ext.Int64, str, bytes],
                                      zenoh.ZBytes(second))
    assert decoded[:4] == ("sequence_number", 2, "source_timestamp", 5) and len(decoded[5]) == 16


def test_live_over_rmw_zenoh_keys(tmp_path):
    port = free_port()
    domain = 7
    hash_ = "RIHS01_" + PUBLISHED["geometry_msgs/msg/WrenchStamped"]
    raw_key, out_key = f"{domain}/ft/raw/{WRENCH_DDS}/{hash_}", f"{domain}/ft/calibrated/{WRENCH_DDS}/{hash_}"
    node = subprocess.Popen([FTCAL, "live", "--zenoh", "--keys", "rmw_zenoh", "--domain-id", str(domain), "--listen",
                             f"tcp/127.0.0.1:{port}", "--noise-std", "0.05,0.004"],
                            cwd=tmp_path, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    store = typestore()
    rng = np.random.default_rng(3)
    sent = {1_000_000_000 + k * 2_000_000: np.r_[0.0, 0.0, -11.8, 0.0, 0.0, 0.0] + rng.normal(scale=0.05, size=6)
            for k in range(200)}
    got, attachments = {}, []
    try:
        assert raw_key in node.stdout.readline()
        session = zenoh.open(zenoh_config(connect=(f"tcp/127.0.0.1:{port}",)))

        def on(sample):
            msg = store.deserialize_cdr(bytes(sample.payload.to_bytes()), "geometry_msgs/msg/WrenchStamped")
            f, t = msg.wrench.force, msg.wrench.torque
            got[msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec] = [f.x, f.y, f.z, t.x, t.y, t.z]
            attachments.append(zenoh.ext.z_deserialize(
                tuple[str, zenoh.ext.Int64, str, zenoh.ext.Int64, str, bytes], sample.attachment))

        sub = session.declare_subscriber(out_key, on)
        pub = session.declare_publisher(raw_key)
        time.sleep(1.0)  # routes established
        tokens = [str(reply.ok.key_expr) for reply in session.liveliness().get(f"@ros2_lv/{domain}/**", timeout=5.0)]
        for stamp, wrench in sent.items():
            pub.put(wrench_message(store, stamp, "ft", wrench))
            time.sleep(0.002)
        deadline = time.monotonic() + 10.0
        while len(got) < len(sent) and time.monotonic() < deadline:
            time.sleep(0.05)
        sub.undeclare()
        session.close()
    finally:
        node.send_signal(signal.SIGTERM)
        out, err = node.communicate(timeout=60)
    assert node.returncode == 143, err
    # No model: the calibrated wrench is the wrench sent, every sample, decoded by rosbags from rmw_zenoh's key.
    assert len(got) >= 0.95 * len(sent)
    for stamp, values in got.items():
        np.testing.assert_allclose(values, sent[stamp], rtol=0, atol=0)
    sequence = [a[1] for a in attachments]
    assert all(a[0] == "sequence_number" and a[2] == "source_timestamp" and a[4] == "source_gid" for a in attachments)
    assert sequence == list(range(1, len(sequence) + 1)) and len({a[5] for a in attachments}) == 1
    # The source timestamps are the system clock's ns at publication: within this test's run.
    assert all(abs(a[3] * 1e-9 - time.time()) < 120 for a in attachments)
    kinds = {token.split("/")[5] for token in tokens}
    assert {"NN", "MP", "MS"} <= kinds
    assert any(t.endswith(f"/%ft%calibrated/{WRENCH_DDS}/{hash_}/::,10:,:,:,,") for t in tokens)


def test_imu_topic_gets_its_own_type_and_hash(tmp_path):
    port = free_port()
    node = subprocess.Popen([FTCAL, "live", "--zenoh", "--keys", "rmw_zenoh", "--listen", f"tcp/127.0.0.1:{port}",
                             "--imu-topic", "/imu", "--duration", "0.5"], cwd=tmp_path, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    out, err = node.communicate(timeout=60)
    assert node.returncode == 0, err
    assert f"0/imu/sensor_msgs::msg::dds_::Imu_/RIHS01_{PUBLISHED['sensor_msgs/msg/Imu']}" in out


def _fifo_permitted() -> bool:
    """Whether this machine lets a process ask for SCHED_FIFO (asked in a child, so this one is unchanged)."""
    probe = "import os; os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(1))"
    return subprocess.run([sys.executable, "-c", probe], capture_output=True).returncode == 0


def test_rt_priority_asks_for_sched_fifo(tmp_path):
    port = free_port()
    node = subprocess.Popen([FTCAL, "live", "--zenoh", "--listen", f"tcp/127.0.0.1:{port}", "--rt-priority", "1",
                             "--duration", "1"], cwd=tmp_path, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True)
    node.stdout.readline()
    # /proc/PID/stat field 41 is the scheduling policy (1 = SCHED_FIFO), field 40 the real-time priority.
    fields = Path(f"/proc/{node.pid}/stat").read_text().rsplit(")", 1)[1].split()
    policy, rt_priority = int(fields[38]), int(fields[37])
    out, err = node.communicate(timeout=60)
    assert node.returncode == 0, err
    if _fifo_permitted():
        assert (policy, rt_priority) == (1, 1) and "not permitted" not in err
    else:
        assert policy == 0 and err.count("\n") == 1 and "SCHED_FIFO not permitted" in err


@pytest.mark.parametrize("argv, message", [
    (["--domain-id", "3"], "--domain-id goes with --keys rmw_zenoh"),
    (["--keys", "rmw_zenoh", "--domain-id", "233"], "--domain-id 233: ROS 2 domain ids go from 0 to 232"),
    (["--rt-priority", "0"], "--rt-priority 0: SCHED_FIFO priorities go from 1 to 99"),
    (["--rt-priority", "100"], "--rt-priority 100: SCHED_FIFO priorities go from 1 to 99"),
])
def test_bad_zenoh_options_are_one_line(tmp_path, argv, message):
    done = subprocess.run([FTCAL, "live", "--zenoh", *argv], cwd=tmp_path, capture_output=True, text=True, timeout=60)
    assert done.returncode == 2 and done.stderr.count("\n") == 1 and message in done.stderr, done.stderr
    assert not os.listdir(tmp_path)
