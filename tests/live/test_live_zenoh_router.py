"""``ftcal live --zenoh`` where ROS 2 users run Zenoh: behind a router, as rmw_zenoh (``rmw_zenohd``) and
zenoh-bridge-ros2dds set it up, with a real Zenoh router process on 127.0.0.1; the endpoints' failures in one line;
queryables that act only when asked by name; a message of another type on the wrench key refused.

The router and the robot's peer are configured here from rmw_zenoh's own files (rmw_zenoh_cpp/config/
DEFAULT_RMW_ZENOH_ROUTER_CONFIG.json5 and DEFAULT_RMW_ZENOH_SESSION_CONFIG.json5, ros2/rmw_zenoh at bfc065f8):
multicast scouting off, gossip on (one hop, autoconnect to routers and peers), peers listening on an ephemeral port;
not from ftcal's configuration, so that the test says whether ftcal's node meets theirs.
"""

from __future__ import annotations

import json
import os
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np

import zenoh

from ftcal.live.cdr import WRENCH_DOUBLES, decode_stamped, encode_stamped
from ftcal.live.zenoh_node import DEFAULT_ENDPOINT, typestore, zenoh_config

FTCAL = str(Path(sys.executable).with_name("ftcal"))

ROUTER = """
import json, sys, time
import zenoh
config = zenoh.Config()
config.insert_json5("mode", '"router"')
config.insert_json5("listen/endpoints", json.dumps([sys.argv[1]]))
config.insert_json5("scouting/multicast/enabled", "false")
config.insert_json5("scouting/gossip/enabled", "true")
config.insert_json5("scouting/gossip/multihop", "false")
session = zenoh.open(config)
print("ready", flush=True)
time.sleep(600)
"""


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def rmw_zenoh_peer(router: str):
    """A session configured as rmw_zenoh's DEFAULT_RMW_ZENOH_SESSION_CONFIG.json5 configures every ROS 2 node."""
    config = zenoh.Config()
    config.insert_json5("mode", '"peer"')
    config.insert_json5("connect/endpoints", json.dumps([router]))
    config.insert_json5("listen/endpoints", '["tcp/127.0.0.1:0"]')
    config.insert_json5("scouting/multicast/enabled", "false")
    config.insert_json5("scouting/gossip/enabled", "true")
    config.insert_json5("scouting/gossip/multihop", "false")
    config.insert_json5("scouting/gossip/autoconnect", '{router: [], peer: ["router", "peer"]}')
    return zenoh.open(config)


def reply_of(session, key: str, payload=None) -> list:
    return [json.loads(bytes(r.ok.payload.to_bytes())) for r in session.get(key, payload=payload, timeout=10.0)
            if r.ok is not None]


def test_behind_a_router_every_wrench_is_answered_and_the_queryables_reached(tmp_path):
    router_endpoint = f"tcp/127.0.0.1:{free_port()}"
    router = subprocess.Popen([sys.executable, "-c", ROUTER, router_endpoint], stdout=subprocess.PIPE, text=True)
    node = session = None
    try:
        assert router.stdout.readline().strip() == "ready"
        node = subprocess.Popen([FTCAL, "live", "--zenoh", "--connect", router_endpoint, "--noise-std", "0.05,0.004"],
                                cwd=tmp_path, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        assert "listening on ft/raw" in node.stdout.readline()
        session = rmw_zenoh_peer(router_endpoint)
        got, n, done = [], 300, threading.Event()

        def on(sample):
            got.append(decode_stamped(bytes(sample.payload.to_bytes()), WRENCH_DOUBLES))
            if len(got) == n:
                done.set()

        sub = session.declare_subscriber("ft/compensated", on)
        pub = session.declare_publisher("ft/raw")
        deadline = time.monotonic() + 20.0
        while not reply_of(session, "ft/status") and time.monotonic() < deadline:
            time.sleep(0.2)  # the node reached through the router (gossip, then a direct link)
        time.sleep(0.5)
        rng = np.random.default_rng(5)
        for k in range(n):
            row = np.r_[0.0, 0.0, -11.8, 0.0, 0.0, 0.0] + rng.normal(size=6) * np.r_[[0.05] * 3, [0.004] * 3]
            pub.put(encode_stamped(1_000_000_000 + k * 2_000_000, "ft", row.tolist()))
            time.sleep(0.002)
        done.wait(timeout=20.0)
        # A wildcard query, as a monitoring tool sends: the status answers; re-tare, tool switch and identify do not
        # act (nor answer). Asked by name, each acts once.
        wild = reply_of(session, "ft/**")
        status = reply_of(session, "ft/status")
        retared = reply_of(session, "ft/retare")
        switched = reply_of(session, "ft/switch_tool", "none")
        sub.undeclare()
    finally:
        if session is not None:
            session.close()
        if node is not None:
            node.terminate()
            _, err = node.communicate(timeout=60)
        router.kill()
        router.communicate()
    assert node.returncode == 143, err
    assert len(got) == n and sorted(m.stamp_ns for m in got) == [1_000_000_000 + k * 2_000_000 for k in range(n)]
    assert all(np.isfinite(m.values).all() for m in got)
    assert len(wild) == 1 and wild[0]["ok"] and wild[0]["status"]["counters"]["retares"] == 0
    assert status[0]["status"]["counters"]["retares"] == 0 and status[0]["status"]["counters"]["samples"] == n
    assert retared[0]["ok"] and retared[0]["status"]["counters"]["retares"] == 1
    assert switched[0]["ok"] and switched[0]["status"]["tool"] == "none"


def test_the_default_endpoint_is_not_the_routers():
    # rmw_zenohd and zenoh-bridge-ros2dds listen on 7447; the node's default must leave it to them.
    listen = json.loads(str(zenoh_config()))["listen"]["endpoints"]
    assert listen == [DEFAULT_ENDPOINT] and not DEFAULT_ENDPOINT.endswith(":7447")
    behind = json.loads(str(zenoh_config(connect=("tcp/127.0.0.1:7447",))))
    assert behind["listen"]["endpoints"] == ["tcp/127.0.0.1:0"] and behind["scouting"]["gossip"]["enabled"] is True


def test_a_taken_port_and_an_unreachable_router_are_one_line(tmp_path):
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        done = subprocess.run([FTCAL, "live", "--zenoh", "--listen", f"tcp/127.0.0.1:{port}"], cwd=tmp_path,
                              capture_output=True, text=True, timeout=60)
    assert done.returncode == 2 and done.stderr.count("\n") == 1, done.stderr
    assert f"--listen tcp/127.0.0.1:{port}: the address is in use" in done.stderr
    nobody = f"tcp/127.0.0.1:{free_port()}"
    done = subprocess.run([FTCAL, "live", "--zenoh", "--connect", nobody, "--state", "state.json"], cwd=tmp_path,
                          capture_output=True, text=True, timeout=60)
    assert done.returncode == 2 and done.stderr.count("\n") == 1, done.stderr
    assert f"--connect {nobody}: nothing answered" in done.stderr and "rmw_zenohd" in done.stderr
    assert not os.listdir(tmp_path)


def test_an_imu_message_on_the_wrench_key_is_a_bad_message():
    from test_live_zenoh_node import Sample, node_with_sinks

    from ftcal.live.zenoh_node import IMU_TYPE, wrench_message

    store = typestore()
    types = store.types
    header = types["std_msgs/msg/Header"](stamp=types["builtin_interfaces/msg/Time"](sec=1, nanosec=0), frame_id="ft")
    vec = types["geometry_msgs/msg/Vector3"]
    imu = bytes(store.serialize_cdr(types[IMU_TYPE](
        header=header, orientation=types["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0),
        orientation_covariance=np.zeros(9), angular_velocity=vec(x=0.0, y=0.0, z=0.0),
        angular_velocity_covariance=np.zeros(9), linear_acceleration=vec(x=0.0, y=0.0, z=9.81),
        linear_acceleration_covariance=np.zeros(9)), IMU_TYPE))
    node = node_with_sinks()
    node._on_wrench(Sample(imu))  # its first 6 doubles after the header are a unit quaternion and a covariance
    assert node.bad_messages == 1 and node.live.counters["samples"] == 0
    assert node.publishers["compensated"].messages == []
    node._on_wrench(Sample(wrench_message(store, 1_000_000_000, "ft", np.array([0, 0, -11.8, 0, 0, 0.0]))))
    assert node.bad_messages == 1 and len(node.publishers["compensated"].messages) == 1
