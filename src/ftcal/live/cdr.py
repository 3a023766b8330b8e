"""CDR of the fixed-layout stamped messages the live node handles per sample, without building message objects.

``geometry_msgs/msg/WrenchStamped``, ``sensor_msgs/msg/Imu`` and ``sensor_msgs/msg/Temperature`` are a ``std_msgs/msg/Header``
(``int32`` seconds, ``uint32`` nanoseconds, a string frame id) followed by float64 fields only.
In CDR (the DDS encoding ROS 2 and zenoh-bridge-ros2dds carry) that is: a 4-byte encapsulation
header (``00 01`` little endian, ``00 00`` big endian, then two option bytes), the stamp, the
string as a ``uint32`` length counting its NUL, its bytes and the NUL, padding to 8 bytes (counted
from the end of the encapsulation header), then the doubles. ``rosbags`` serialises the same bytes
(the tests compare both ways); it builds a message object per call, which costs about 30 µs to
read and 45 µs to write a wrench, a large part of a 500 µs budget at 2 kHz. Messages of other
types (``sensor_msgs/msg/JointState``: sequences) go through ``rosbags``.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass

ENCAPSULATION_HEADER = 4
LITTLE_ENDIAN_CDR = b"\x00\x01\x00\x00"
WRENCH_DOUBLES = 6  # force x y z, torque x y z
# orientation (4), its covariance (9), angular velocity (3), covariance (9), linear acceleration (3), covariance (9)
IMU_DOUBLES = 37
TEMPERATURE_DOUBLES = 2  # sensor_msgs/msg/Temperature: temperature (°C), variance

_STAMP = {"<": struct.Struct("<iII"), ">": struct.Struct(">iII")}
_DOUBLES: dict = {}


def _doubles(endian: str, count: int) -> struct.Struct:
    key = (endian, count)
    if key not in _DOUBLES:
        _DOUBLES[key] = struct.Struct(f"{endian}{count}d")
    return _DOUBLES[key]


@dataclass(frozen=True)
class StampedDoubles:
    """A decoded message: stamp, frame id, its float64 fields in order, and what it takes to answer it.

    Attributes
    ----------
    stamp_ns : int, the header's stamp in nanoseconds
    frame_id : str
    values : tuple of float
    prefix : bytes, the encapsulation header and the header up to the doubles (reused by :func:`encode_like`)
    endian : "<" or ">"
    """

    stamp_ns: int
    frame_id: str
    values: tuple
    prefix: bytes
    endian: str


def decode_stamped(data: bytes, count: int) -> StampedDoubles:
    """Decode a stamped message whose body is ``count`` float64 fields (a wrench: 6; an Imu: 37).

    Raises
    ------
    ValueError
        Truncated data or bytes beyond the ``count`` doubles (another type), an unknown encapsulation, a stamp whose nanoseconds reach a second, or a frame id that is
        not a NUL-terminated UTF-8 string.
    """
    if len(data) < ENCAPSULATION_HEADER + 12 or data[0] != 0 or data[1] not in (0, 1):
        raise ValueError("not a CDR message (too short, or an unknown encapsulation header)")
    endian = "<" if data[1] == 1 else ">"
    sec, nanosec, length = _STAMP[endian].unpack_from(data, ENCAPSULATION_HEADER)
    if nanosec >= 1_000_000_000:  # builtin_interfaces/msg/Time: nanosec in [0, 1e9)
        raise ValueError(f"the header's stamp has nanosec {nanosec}, not below 1e9")
    text_end = ENCAPSULATION_HEADER + 12 + length
    if length < 1 or text_end > len(data) or data[text_end - 1] != 0:
        raise ValueError("the header's frame id is not a NUL-terminated string inside the message")
    frame = data[ENCAPSULATION_HEADER + 12:text_end - 1].decode("utf-8")
    start = text_end + (-(text_end - ENCAPSULATION_HEADER)) % 8
    body = _doubles(endian, count)
    if start + body.size > len(data):
        raise ValueError(f"the message ends before its {count} float64 fields")
    # Exactly that long (the encapsulation options' two low bits may declare up to 3 bytes of padding at the end): a
    # message of another type whose header is followed by more doubles (an Imu on the wrench key) is not this type.
    if len(data) - (data[3] & 0x03) != start + body.size:
        raise ValueError(f"the message has {len(data) - start - body.size} byte(s) after its {count} float64 fields: "
                         "another message type")
    return StampedDoubles(sec * 1_000_000_000 + nanosec, frame, body.unpack_from(data, start), bytes(data[:start]),
                          endian)


def encode_like(message: StampedDoubles, values) -> bytes:
    """A message with ``message``'s header (stamp, frame, byte order) and ``values`` as its float64 fields."""
    return message.prefix + _doubles(message.endian, len(values)).pack(*values)


def encode_stamped(stamp_ns: int, frame_id: str, values) -> bytes:
    """A little-endian CDR stamped message: header (stamp, frame id) and ``values`` as float64 fields."""
    frame = frame_id.encode("utf-8") + b"\x00"
    head = LITTLE_ENDIAN_CDR + _STAMP["<"].pack(int(stamp_ns // 1_000_000_000), int(stamp_ns % 1_000_000_000),
                                                len(frame)) + frame
    head += b"\x00" * ((-(len(head) - ENCAPSULATION_HEADER)) % 8)
    return head + _doubles("<", len(values)).pack(*values)
