"""Real ROS bags for the tests, written with rosbags' own writers (no ftcal code involved).

``Bag(kind)`` collects messages (receive time in ns, header stamps in ns) and
``write(path)`` stores them as a ROS 1 ``.bag`` (``ros1``), a ROS 2 bag folder
with sqlite3 (``db3``) or MCAP (``mcap``) storage, or a lone ``.mcap``/``.db3``
file (``mcap-file``, ``db3-file``). Returns the path to hand to ftcal.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
from rosbags.rosbag1 import Writer as Writer1
from rosbags.rosbag2 import CompressionFormat, CompressionMode, StoragePlugin
from rosbags.rosbag2 import Writer as Writer2
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

KINDS = ("ros1", "db3", "mcap", "mcap-file", "db3-file")


class Bag:
    def __init__(self, kind: str) -> None:
        self.kind = kind
        self.ts = get_typestore(Stores.ROS1_NOETIC if kind == "ros1" else Stores.ROS2_HUMBLE)
        if "tf2_msgs/msg/TFMessage" not in self.ts.types:  # rosbags' Noetic store lacks it
            self.ts.register(get_types_from_msg("geometry_msgs/TransformStamped[] transforms",
                                                "tf2_msgs/msg/TFMessage"))
        self.messages: list[tuple[str, str, int, object]] = []

    def t(self, name: str):
        return self.ts.types[name]

    def header(self, stamp_ns: int, frame: str = ""):
        stamp = self.t("builtin_interfaces/msg/Time")(stamp_ns // 10**9, stamp_ns % 10**9)
        header = self.t("std_msgs/msg/Header")
        return header(0, stamp, frame) if self.kind == "ros1" else header(stamp, frame)

    def vec(self, x, y, z):
        return self.t("geometry_msgs/msg/Vector3")(float(x), float(y), float(z))

    def quat(self, q):
        return self.t("geometry_msgs/msg/Quaternion")(*map(float, q))

    def add(self, topic: str, msgtype: str, receive_ns: int, msg) -> None:
        self.messages.append((topic, msgtype, int(receive_ns), msg))

    def wrench(self, topic, receive_ns, values, stamp_ns=None, frame="ft_sensor", stamped=True):
        wrench = self.t("geometry_msgs/msg/Wrench")(self.vec(*values[:3]), self.vec(*values[3:]))
        if not stamped:
            return self.add(topic, "geometry_msgs/msg/Wrench", receive_ns, wrench)
        msg = self.t("geometry_msgs/msg/WrenchStamped")(self.header(receive_ns if stamp_ns is None else stamp_ns,
                                                                    frame), wrench)
        self.add(topic, "geometry_msgs/msg/WrenchStamped", receive_ns, msg)

    def temperature(self, topic, receive_ns, value, float64=False):
        if float64:
            return self.add(topic, "std_msgs/msg/Float64", receive_ns, self.t("std_msgs/msg/Float64")(float(value)))
        msg = self.t("sensor_msgs/msg/Temperature")(self.header(receive_ns), float(value), 0.0)
        self.add(topic, "sensor_msgs/msg/Temperature", receive_ns, msg)

    def joints(self, topic, receive_ns, names, positions):
        zeros = np.zeros(0)
        msg = self.t("sensor_msgs/msg/JointState")(self.header(receive_ns), list(names),
                                                   np.asarray(positions, dtype=np.float64), zeros, zeros)
        self.add(topic, "sensor_msgs/msg/JointState", receive_ns, msg)

    def imu(self, topic, receive_ns, q, w, a, has_orientation=True):
        cov = np.zeros(9)
        if not has_orientation:
            cov[0] = -1.0
        msg = self.t("sensor_msgs/msg/Imu")(self.header(receive_ns, "imu"), self.quat(q), cov, self.vec(*w),
                                            np.zeros(9), self.vec(*a), np.zeros(9))
        self.add(topic, "sensor_msgs/msg/Imu", receive_ns, msg)

    def tf(self, receive_ns, transforms, static=False):
        """transforms: (parent, child, quaternion xyzw, stamp_ns)."""
        items = [self.t("geometry_msgs/msg/TransformStamped")(
            self.header(stamp, parent), child,
            self.t("geometry_msgs/msg/Transform")(self.vec(0.1, 0.2, 0.3), self.quat(q)))
            for parent, child, q, stamp in transforms]
        self.add("/tf_static" if static else "/tf", "tf2_msgs/msg/TFMessage", receive_ns,
                 self.t("tf2_msgs/msg/TFMessage")(items))

    def write(self, path: Path, compress: bool = False, ros1_chunk_bytes: int | None = None) -> Path:
        """Write the bag; ``compress``: lz4 chunks (ROS 1) or zstd chunks (MCAP)."""
        path = Path(path)
        ordered = sorted(self.messages, key=lambda m: m[2])
        if self.kind == "ros1":
            target = path.with_suffix(".bag")
            writer = Writer1(target)
            if compress:
                writer.set_compression(Writer1.CompressionFormat.LZ4)
            if ros1_chunk_bytes:
                writer.chunk_threshold = ros1_chunk_bytes
            with writer:
                conns = {}
                for topic, msgtype, stamp, msg in ordered:
                    if topic not in conns:
                        conns[topic] = writer.add_connection(topic, msgtype, typestore=self.ts)
                    writer.write(conns[topic], stamp, self.ts.serialize_ros1(msg, msgtype))
            return target
        plugin = StoragePlugin.SQLITE3 if self.kind.startswith("db3") else StoragePlugin.MCAP
        writer = Writer2(path, version=9, storage_plugin=plugin)
        if compress:
            writer.set_compression(CompressionMode.STORAGE, CompressionFormat.ZSTD)
        with writer:
            conns = {}
            for topic, msgtype, stamp, msg in ordered:
                if topic not in conns:
                    conns[topic] = writer.add_connection(topic, msgtype, typestore=self.ts)
                writer.write(conns[topic], stamp, self.ts.serialize_cdr(msg, msgtype))
        if not self.kind.endswith("-file"):
            return path
        suffix = ".mcap" if self.kind == "mcap-file" else ".db3"
        lone = path.parent / (path.name + suffix)
        shutil.move(next(path.glob("*" + suffix)), lone)
        shutil.rmtree(path)
        return lone
