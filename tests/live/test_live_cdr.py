"""The live node's CDR codec (ftcal.live.cdr) against rosbags' serializer, both ways and both byte orders."""

from __future__ import annotations

import numpy as np
import pytest

from ftcal.live.cdr import IMU_DOUBLES, WRENCH_DOUBLES, decode_stamped, encode_like, encode_stamped
from ftcal.live.zenoh_node import IMU_TYPE, WRENCH_TYPE, typestore


def wrench(store, sec, nanosec, frame, values):
    types = store.types
    vec = types["geometry_msgs/msg/Vector3"]
    return types[WRENCH_TYPE](
        header=types["std_msgs/msg/Header"](stamp=types["builtin_interfaces/msg/Time"](sec=sec, nanosec=nanosec),
                                            frame_id=frame),
        wrench=types["geometry_msgs/msg/Wrench"](force=vec(x=values[0], y=values[1], z=values[2]),
                                                 torque=vec(x=values[3], y=values[4], z=values[5])))


@pytest.mark.parametrize("frame", ["", "f", "ft", "ftx", "wrist_ft_sensor", "капля"])
@pytest.mark.parametrize("little_endian", [True, False])
def test_wrench_stamped_matches_rosbags(frame, little_endian):
    store = typestore()
    rng = np.random.default_rng(len(frame))
    values = rng.normal(scale=30.0, size=6).tolist()
    data = bytes(store.serialize_cdr(wrench(store, 1_700_000_123, 987_654_321, frame, values), WRENCH_TYPE,
                                     little_endian=little_endian))
    msg = decode_stamped(data, WRENCH_DOUBLES)
    assert msg.stamp_ns == 1_700_000_123 * 10 ** 9 + 987_654_321 and msg.frame_id == frame
    assert list(msg.values) == values
    other = rng.normal(size=6).tolist()
    answer = store.deserialize_cdr(encode_like(msg, other), WRENCH_TYPE)
    assert answer.header.frame_id == frame and answer.header.stamp.nanosec == 987_654_321
    f, t = answer.wrench.force, answer.wrench.torque
    assert [f.x, f.y, f.z, t.x, t.y, t.z] == other
    if little_endian:
        assert encode_stamped(msg.stamp_ns, frame, values) == data


def test_imu_matches_rosbags():
    store = typestore()
    types = store.types
    vec = types["geometry_msgs/msg/Vector3"]
    rng = np.random.default_rng(5)
    cov = [rng.normal(size=9) for _ in range(3)]
    msg = types[IMU_TYPE](
        header=types["std_msgs/msg/Header"](stamp=types["builtin_interfaces/msg/Time"](sec=3, nanosec=5),
                                            frame_id="imu_link"),
        orientation=types["geometry_msgs/msg/Quaternion"](x=0.1, y=0.2, z=0.3, w=0.9),
        orientation_covariance=cov[0], angular_velocity=vec(x=1.0, y=2.0, z=3.0), angular_velocity_covariance=cov[1],
        linear_acceleration=vec(x=0.5, y=-0.25, z=9.75), linear_acceleration_covariance=cov[2])
    values = decode_stamped(bytes(store.serialize_cdr(msg, IMU_TYPE)), IMU_DOUBLES).values
    assert values[:4] == (0.1, 0.2, 0.3, 0.9) and list(values[4:13]) == cov[0].tolist()
    assert values[13:16] == (1.0, 2.0, 3.0) and values[25:28] == (0.5, -0.25, 9.75)
    assert list(values[28:]) == cov[2].tolist()


@pytest.mark.parametrize("data", [b"", b"\x00\x01\x00\x00" + b"\x00" * 8, b"\x07\x01\x00\x00" + b"\x00" * 80,
                                  b"\x00\x01\x00\x00" + b"\x00" * 8 + b"\xff\xff\x00\x00" + b"\x00" * 60])
def test_broken_messages_are_refused(data):
    with pytest.raises(ValueError):
        decode_stamped(data, WRENCH_DOUBLES)


def test_a_truncated_wrench_is_refused():
    store = typestore()
    data = bytes(store.serialize_cdr(wrench(store, 1, 2, "ft", [1.0] * 6), WRENCH_TYPE))
    with pytest.raises(ValueError, match="ends before"):
        decode_stamped(data[:-1], WRENCH_DOUBLES)


def test_many_random_wrenches_and_frame_ids_match_rosbags():
    """400 random messages: frame ids of 0-40 characters (ASCII, '/', '_', 2-, 3- and 4-byte UTF-8, so every padding
    length occurs), stamps over int32 seconds, values from subnormal to huge and ±inf, both byte orders."""
    store = typestore()
    rng = np.random.default_rng(2026)
    alphabet = list("abcxyz_/0189") + ["é", "ß", "感", "ф", "🤖"]
    specials = [0.0, -0.0, 5e-324, -2.2250738585072014e-308, 1.7976931348623157e308, float("inf"), float("-inf")]
    for k in range(400):
        frame = "".join(rng.choice(alphabet, size=int(rng.integers(0, 41))))
        sec, nanosec = int(rng.integers(0, 2 ** 31)), int(rng.integers(0, 10 ** 9))
        values = (rng.normal(size=6) * 10.0 ** rng.integers(-300, 300, size=6)).tolist()
        values[int(rng.integers(0, 6))] = specials[k % len(specials)]
        little_endian = bool(k % 2)
        data = bytes(store.serialize_cdr(wrench(store, sec, nanosec, frame, values), WRENCH_TYPE,
                                         little_endian=little_endian))
        msg = decode_stamped(data, WRENCH_DOUBLES)
        assert (msg.stamp_ns, msg.frame_id, list(msg.values)) == (sec * 10 ** 9 + nanosec, frame, values)
        if little_endian:
            assert encode_stamped(msg.stamp_ns, frame, values) == data
        other = rng.normal(scale=50.0, size=6).tolist()
        assert encode_like(msg, other) == bytes(store.serialize_cdr(wrench(store, sec, nanosec, frame, other),
                                                                    WRENCH_TYPE, little_endian=little_endian))
