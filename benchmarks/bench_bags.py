"""Bag reading: ftcal's wrench reader against rosbags' own plain deserialize loop.

Both read the same bag of ``n`` ``geometry_msgs/WrenchStamped`` messages (1 kHz,
random values, frame_id ``ft_sensor``), written once per kind into a temporary
folder by ``bag_prepare`` before either is timed. Kinds: ROS 1 ``.bag``,
ROS 2 sqlite3 (``db3``) and MCAP (``mcap``) bag folders.
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

import numpy as np

TOPIC = "/ft"
WRENCH = "geometry_msgs/msg/WrenchStamped"


def bag_path(kind: str, n: int) -> Path:
    name = f"wrench-{kind}-{n}" + (".bag" if kind == "ros1" else "")
    return Path(tempfile.gettempdir()) / "ftcal-bench-bags" / name


def bag_prepare(kind: str, n: int) -> dict:
    """Write the bag (not timed as a reading case)."""
    from rosbags.rosbag1 import Writer as Writer1
    from rosbags.rosbag2 import StoragePlugin
    from rosbags.rosbag2 import Writer as Writer2
    from rosbags.typesys import Stores, get_typestore

    path = bag_path(kind, n)
    start = time.perf_counter()
    if path.exists():
        return {"seconds": 0.0}
    path.parent.mkdir(parents=True, exist_ok=True)
    ts = get_typestore(Stores.ROS1_NOETIC if kind == "ros1" else Stores.ROS2_HUMBLE)
    types = ts.types
    values = np.random.default_rng(0).normal(0.0, 50.0, (n, 6))
    tmp = path.with_name(path.name + ".partial")
    if kind == "ros1":
        writer = Writer1(tmp)
        serialize = ts.serialize_ros1
    else:
        writer = Writer2(tmp, version=9, storage_plugin=StoragePlugin.SQLITE3 if kind == "db3" else StoragePlugin.MCAP)
        serialize = ts.serialize_cdr
    with writer:
        conn = writer.add_connection(TOPIC, WRENCH, typestore=ts)
        for k in range(n):
            ns = 1_700_000_000 * 10**9 + k * 10**6
            stamp = types["builtin_interfaces/msg/Time"](ns // 10**9, ns % 10**9)
            header = (types["std_msgs/msg/Header"](k, stamp, "ft_sensor") if kind == "ros1"
                      else types["std_msgs/msg/Header"](stamp, "ft_sensor"))
            vec = types["geometry_msgs/msg/Vector3"]
            v = values[k]
            msg = types[WRENCH](header, types["geometry_msgs/msg/Wrench"](vec(*v[:3]), vec(*v[3:])))
            writer.write(conn, ns, serialize(msg, WRENCH))
    tmp.rename(path)
    return {"seconds": time.perf_counter() - start}


def ftcal_bag_read(kind: str, n: int) -> dict:
    from ftcal.data.bags import BagTopics, read_bag

    path = bag_path(kind, n)
    start = time.perf_counter()
    stream = read_bag(path, BagTopics(TOPIC)).ft[TOPIC]
    seconds = time.perf_counter() - start
    assert stream.n_samples == n
    return {"seconds": seconds, "messages_per_s": n / seconds, "checksum": float(stream.data.sum())}


def rosbags_bag_loop(kind: str, n: int) -> dict:
    """rosbags' documented way: deserialize every message, collect the six values and the stamp."""
    from rosbags.highlevel import AnyReader

    path = bag_path(kind, n)
    start = time.perf_counter()
    rows, stamps = [], []
    with AnyReader([path]) as reader:
        for connection, _, raw in reader.messages():
            msg = reader.deserialize(raw, connection.msgtype)
            f, t = msg.wrench.force, msg.wrench.torque
            rows.append((f.x, f.y, f.z, t.x, t.y, t.z))
            stamps.append(msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9)
    data = np.array(rows)
    seconds = time.perf_counter() - start
    return {"seconds": seconds, "messages_per_s": n / seconds, "checksum": float(data.sum())}


CASES = {f.__name__: f for f in (bag_prepare, ftcal_bag_read, rosbags_bag_loop)}


def bags_section(run_case, n: int) -> tuple[list[str], str]:
    """Table rows and the headline for BENCHMARKS.md."""
    out = [f"## Bag reading: {n:,} geometry_msgs/WrenchStamped messages", "",
           "| bag | ftcal msgs/s | rosbags deserialize loop msgs/s | ftcal / rosbags | ftcal peak memory | "
           "rosbags peak memory |", "|---|---:|---:|---:|---:|---:|"]
    worst = None
    for kind, label in (("ros1", "ROS 1 .bag"), ("db3", "ROS 2 .db3"), ("mcap", "ROS 2 .mcap")):
        run_case("bag_prepare", kind=kind, n=n)
        ours = run_case("ftcal_bag_read", kind=kind, n=n)
        base = run_case("rosbags_bag_loop", kind=kind, n=n)
        if abs(ours["checksum"] - base["checksum"]) > 1e-6 * abs(base["checksum"]):
            raise RuntimeError(f"bag benchmark {kind}: ftcal and rosbags read different values")
        ratio = ours["messages_per_s"] / base["messages_per_s"]
        out.append(f"| {label} | {ours['messages_per_s']:,.0f} | {base['messages_per_s']:,.0f} | {ratio:.1f}× | "
                   f"{ours['peak_rss_mb']:,.0f} MB | {base['peak_rss_mb']:,.0f} MB |")
        if worst is None or ours["messages_per_s"] < worst[1]:
            worst = (label, ours["messages_per_s"], ratio)
    headline = (f"slowest format ({worst[0]}): {worst[1]:,.0f} wrench messages/s (target ≥ 200,000/s), "
                f"{worst[2]:.1f}× rosbags' deserialize loop")
    return out + [""], headline
