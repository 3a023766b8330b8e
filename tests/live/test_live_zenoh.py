"""``ftcal live --zenoh`` between real Zenoh peers on 127.0.0.1 (multicast scouting off, explicit tcp endpoints).

A peer in this process plays the robot: it publishes CDR WrenchStamped and Imu messages made from a
simulation with known truth, subscribes to the calibrated and compensated wrenches and the
diagnostics, and calls the queryables. Then it falls silent (the node must say so, not hang), and
SIGTERM must end the node with its state saved.
"""

from __future__ import annotations

import json
import signal
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest

import zenoh  # the test extra installs eclipse-zenoh: a missing one is a failure, not a skip

from ftcal.files.payload_json import save_payload  # noqa: E402
from ftcal.live.cdr import WRENCH_DOUBLES, decode_stamped, encode_stamped  # noqa: E402
from ftcal.live.zenoh_node import IMU_TYPE, topic_key, typestore, wrench_message, zenoh_config  # noqa: E402
from ftcal.payload.parameters import PayloadParameters  # noqa: E402
from ftcal.sim.live_scenario import LiveScenario, simulate_live  # noqa: E402

FTCAL = str(Path(sys.executable).with_name("ftcal"))
NOISE = np.r_[np.full(3, 0.05), np.full(3, 0.004)]


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def imu_message(store, stamp_ns: int, q: np.ndarray) -> bytes:
    types = store.types
    header = types["std_msgs/msg/Header"](stamp=types["builtin_interfaces/msg/Time"](
        sec=int(stamp_ns // 1_000_000_000), nanosec=int(stamp_ns % 1_000_000_000)), frame_id="ft")
    vec = types["geometry_msgs/msg/Vector3"]
    msg = types[IMU_TYPE](header=header, orientation=types["geometry_msgs/msg/Quaternion"](
        x=float(q[0]), y=float(q[1]), z=float(q[2]), w=float(q[3])), orientation_covariance=np.zeros(9),
        angular_velocity=vec(x=0.0, y=0.0, z=0.0), angular_velocity_covariance=np.zeros(9),
        linear_acceleration=vec(x=0.0, y=0.0, z=9.81), linear_acceleration_covariance=np.zeros(9))
    return bytes(store.serialize_cdr(msg, IMU_TYPE))


def test_topic_keys_follow_the_bridge():
    assert topic_key("/ft/raw") == "ft/raw"
    assert topic_key("/robot1/ft/raw/") == "robot1/ft/raw"


def test_live_over_zenoh(tmp_path):
    s = LiveScenario(duration=6.0, rate=500.0, hold_s=2.5, move_s=0.5, contacts=((3.2, 1.5, 10.0),), seed=13)
    rec = simulate_live(s)
    tool = s.tools["gripper"]
    save_payload(PayloadParameters(tool.mass, np.asarray(tool.com), np.zeros(3), np.zeros(3), 9.81,
                                   stderr={"mass": 1e-3, "com": np.full(3, 1e-4), "force_bias": np.full(3, .01),
                                           "torque_bias": np.full(3, 1e-3)},
                                   fit={"n_samples": 100, "residual_rms": NOISE, "condition_number": 1.0,
                                        "wrench_columns": ["Fx", "Fy", "Fz", "Tx", "Ty", "Tz"]}),
                 tmp_path / "gripper.json")
    port = free_port()
    node = subprocess.Popen([FTCAL, "live", "--zenoh", "--listen", f"tcp/127.0.0.1:{port}", "--imu-topic", "/imu",
                             "--tool", "gripper=gripper.json", "--state", "state.json", "--silence", "0.5"],
                            cwd=tmp_path, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        assert "listening on ft/raw" in node.stdout.readline()
        session = zenoh.open(zenoh_config(connect=(f"tcp/127.0.0.1:{port}",), listen=()))
        store = typestore()
        received = {"calibrated": [], "compensated": [], "diagnostics": []}
        arrival = {}

        def keep(name):
            def on(sample):
                data = bytes(sample.payload.to_bytes())
                if name == "diagnostics":
                    received[name].append(json.loads(data))
                    return
                msg = store.deserialize_cdr(data, "geometry_msgs/msg/WrenchStamped")
                stamp = msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec
                f, t = msg.wrench.force, msg.wrench.torque
                received[name].append((stamp, [f.x, f.y, f.z, t.x, t.y, t.z]))
                arrival.setdefault(stamp, time.perf_counter())
            return on

        subs = [session.declare_subscriber(f"ft/{name}", keep(name)) for name in received]
        wrench_pub, imu_pub = session.declare_publisher("ft/raw"), session.declare_publisher("imu")
        time.sleep(1.0)  # routes established
        sent = {}
        start = time.perf_counter()
        for k in range(rec.time.size):
            stamp = int(round(rec.time[k] * 1e9)) + 1_000_000_000
            imu_pub.put(imu_message(store, stamp, rec.quaternion[k]))
            sent[stamp] = time.perf_counter()
            wrench_pub.put(wrench_message(store, stamp, "ft", rec.wrench[k]))
            ahead = rec.time[k] - (time.perf_counter() - start)
            if ahead > 0:
                time.sleep(ahead)
        status = json.loads(bytes(next(iter(session.get("ft/status", timeout=10.0))).ok.payload.to_bytes()))["status"]
        switched = json.loads(bytes(next(iter(session.get("ft/switch_tool", payload="none", timeout=10.0)))
                                    .ok.payload.to_bytes()))
        refused = json.loads(bytes(next(iter(session.get("ft/switch_tool", payload="hammer", timeout=10.0)))
                                   .ok.payload.to_bytes()))
        retared = json.loads(bytes(next(iter(session.get("ft/retare", timeout=10.0))).ok.payload.to_bytes()))
        not_started = json.loads(bytes(next(iter(session.get("ft/identify_tool", payload="finish", timeout=10.0)))
                                       .ok.payload.to_bytes()))
        started = json.loads(bytes(next(iter(session.get("ft/identify_tool", payload="start probe", timeout=10.0)))
                                   .ok.payload.to_bytes()))
        time.sleep(1.5)  # silence
        for sub in subs:
            sub.undeclare()
        session.close()
    finally:
        node.send_signal(signal.SIGTERM)
        out, err = node.communicate(timeout=60)
    assert node.returncode == 143, err
    assert status["tool"] == "gripper" and status["counters"]["samples"] > 0.9 * rec.time.size
    assert switched["ok"] and switched["status"]["tool"] == "none"
    assert not refused["ok"] and "hammer" in refused["error"]
    assert retared["ok"] and retared["status"]["counters"]["retares"] == 1
    assert not not_started["ok"] and "no identification" in not_started["error"]
    assert started["ok"] and started["status"]["identifying"] == "probe"
    # Every sample came back, calibrated = the wrench sent (no model) and compensated = truth's contact + noise.
    got = dict(received["compensated"])
    assert len(got) >= 0.95 * rec.time.size
    stamps = (np.round(rec.time * 1e9) + 1e9).astype(np.int64)
    index = {int(s): k for k, s in enumerate(stamps)}
    rows = np.array([index[s] for s in got])
    values = np.array([got[s] for s in got])
    settled = rec.holding[rows] & ~np.any(rec.contact[rows] != 0, axis=1) & (rec.time[rows] > 1.0)
    assert np.sqrt(np.mean(values[settled, :3] ** 2)) < 2.0 * NOISE[0]
    pressing = np.linalg.norm(rec.contact[rows, :3], axis=1) > 5.0
    np.testing.assert_allclose(values[pressing, :3], rec.contact[rows][pressing, :3], atol=0.5)
    flags = [d["flags"] for d in received["diagnostics"]]
    assert any("contact" in f for f in flags) and any("silent" in f for f in flags)
    assert "no message on ft/raw" in err
    state = json.loads((tmp_path / "state.json").read_text())
    assert state["counters"]["samples"] >= status["counters"]["samples"] and state["tool"] == "none"
    latency = np.array([arrival[s] - sent[s] for s in sent if s in arrival])
    print(f"zenoh loopback latency: median {1e3 * np.median(latency):.2f} ms, p99 {1e3 * np.quantile(latency, .99):.2f}"
          " ms")


def test_a_peer_with_zenohs_default_transport_talks_to_the_node(tmp_path):
    """The node asks for Zenoh's low-latency transport (TRANSPORT_SETTINGS); a peer that does not (Zenoh's defaults:
    QoS on, the queued transport, as an unconfigured zenoh-bridge-ros2dds) must still exchange every message."""
    port = free_port()
    node = subprocess.Popen([FTCAL, "live", "--zenoh", "--listen", f"tcp/127.0.0.1:{port}", "--noise-std", "0.05,0.004"],
                            cwd=tmp_path, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        assert "listening on ft/raw" in node.stdout.readline()
        config = zenoh.Config()  # Zenoh's defaults but for discovery: loopback only, no multicast
        config.insert_json5("mode", '"peer"')
        config.insert_json5("scouting/multicast/enabled", "false")
        config.insert_json5("scouting/gossip/enabled", "false")
        config.insert_json5("connect/endpoints", json.dumps([f"tcp/127.0.0.1:{port}"]))
        unicast = json.loads(str(config))["transport"]["unicast"]
        assert unicast["lowlatency"] is False and unicast["qos"]["enabled"] is True
        session = zenoh.open(config)
        got = []
        done = threading.Event()
        n = 200

        def on(sample):
            got.append(bytes(sample.payload.to_bytes()))
            if len(got) == n:
                done.set()

        sub = session.declare_subscriber("ft/compensated", on)
        pub = session.declare_publisher("ft/raw")
        store = typestore()
        time.sleep(1.0)  # routes established
        for k in range(n):
            pub.put(wrench_message(store, 1_000_000_000 + k * 1_000_000, "ft", np.array([0, 0, -11.8, 0, 0, 0.0])))
            time.sleep(0.001)
        done.wait(timeout=20.0)
        sub.undeclare()
        session.close()
    finally:
        node.send_signal(signal.SIGTERM)
        node.communicate(timeout=60)
    assert len(got) == n
    stamps = sorted(store.deserialize_cdr(g, "geometry_msgs/msg/WrenchStamped").header.stamp.nanosec for g in got)
    assert stamps == [k * 1_000_000 for k in range(n)]



FROZEN_CONSUMER = """
import sys, time
import zenoh
from ftcal.live.zenoh_node import zenoh_config
config = zenoh_config(connect=(sys.argv[1],), low_latency=True)  # it asks for the transport without a queue
config.insert_json5("transport/link/tcp/so_rcvbuf", "4096")  # its socket fills as soon as it stops reading
session = zenoh.open(config)
subscriber = session.declare_subscriber("ft/**", lambda sample: None)
print("ready", flush=True)
time.sleep(600)
"""


def test_a_consumer_that_stops_reading_never_stalls_the_node(tmp_path):
    """A consumer frozen by SIGSTOP (a debugger, a stopped GUI) with a 4 kB receive buffer must not hold up the
    answers to another consumer: with the low-latency transport on both sides the node's puts blocked and every answer
    stopped after about 8 s at 2 kHz; on the node's default, Zenoh's queued transport, that consumer's answers are
    dropped instead. Every wrench is answered and no 2 s window is short; SIGTERM while wrenches still arrive ends the
    node without a traceback (callbacks in flight once the publishers are gone)."""
    port = free_port()
    endpoint = f"tcp/127.0.0.1:{port}"
    node = subprocess.Popen([FTCAL, "live", "--zenoh", "--listen", endpoint, "--noise-std", "0.05,0.004"],
                            cwd=tmp_path, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    frozen = session = None
    rate, seconds = 2000, 14
    try:
        assert "listening on ft/raw" in node.stdout.readline()
        frozen = subprocess.Popen([sys.executable, "-c", FROZEN_CONSUMER, endpoint], stdout=subprocess.PIPE, text=True)
        assert frozen.stdout.readline().strip() == "ready"
        session = zenoh.open(zenoh_config(connect=(endpoint,)))
        arrivals = []
        sub = session.declare_subscriber(
            "ft/compensated", lambda sample: arrivals.append((decode_stamped(sample.payload.to_bytes(),
                                                                            WRENCH_DOUBLES).stamp_ns, time.monotonic())))
        pub = session.declare_publisher("ft/raw")
        time.sleep(1.0)  # routes established
        frozen.send_signal(signal.SIGSTOP)
        start = time.monotonic()
        for k in range(rate * (seconds + 1)):  # ftcal's encoder: bytes equal to rosbags' (tests/live/test_live_cdr.py)
            pub.put(encode_stamped(1_000_000_000 + k * 500_000, "ft", [0.0, 0.0, -11.8, 0.0, 0.0, 0.0]))
            if k == rate * seconds + rate // 2:
                node.send_signal(signal.SIGTERM)  # half a second before the stream ends
            ahead = (k + 1) / rate - (time.monotonic() - start)
            if ahead > 0:
                time.sleep(ahead)
        time.sleep(0.5)
        sub.undeclare()
    finally:
        if frozen is not None:
            frozen.kill()
            frozen.communicate()
        node.send_signal(signal.SIGTERM)
        _, err = node.communicate(timeout=60)
        if session is not None:
            try:  # this test's own session, closed after the node is gone: on a loaded machine its close can time
                session.close()  # out waiting for the dead peer, which is not the node's behaviour under test
            except zenoh.ZError:
                pass
    answered = np.array([t for stamp, t in arrivals if stamp < 1_000_000_000 + rate * seconds * 500_000])
    windows = np.histogram(answered - start, bins=np.arange(0, seconds + 1, 2))[0]
    # each 2 s window holds its 4,000 answers give or take the few that cross a window's edge
    assert windows.min() > 0.9 * 2 * rate, windows
    assert len(answered) == rate * seconds
    assert node.returncode == 143 and "Traceback" not in err and "callback error" not in err, err[-2000:]  # 128 + SIGTERM


def test_a_second_sigterm_while_the_node_winds_down_keeps_its_exit_code(tmp_path):
    """systemd and ros2 launch may signal twice: once the node says it was terminated, a second SIGTERM (here sent
    as soon as that line is out, while Zenoh's threads wind down) neither kills it by the signal nor changes 143."""
    port = free_port()
    node = subprocess.Popen([FTCAL, "live", "--zenoh", "--listen", f"tcp/127.0.0.1:{port}", "--noise-std", "0.05,0.004",
                             "--state", str(tmp_path / "state.json")],
                            cwd=tmp_path, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        assert "listening on ft/raw" in node.stdout.readline()
        node.send_signal(signal.SIGTERM)
        lines = []
        for line in node.stderr:
            lines.append(line)
            if "terminated by SIGTERM" in line:
                node.send_signal(signal.SIGTERM)
                break
        rest = node.stderr.read()
        node.wait(timeout=60)
    finally:
        node.kill()
        node.communicate()
    assert node.returncode == 143, "".join(lines) + rest


def test_a_second_session_resumes_from_the_state_and_saves_it_back(tmp_path):
    """``live --zenoh --state S`` with an existing S: it resumes from S and writes S back at the end (before, the
    node ran and then refused to save S as 'an input of this command')."""
    rng = np.random.default_rng(4)

    def session(first_stamp_s: float, n: int) -> tuple[int, str]:
        port = free_port()
        node = subprocess.Popen([FTCAL, "live", "--zenoh", "--listen", f"tcp/127.0.0.1:{port}", "--noise-std",
                                 "0.05,0.004", "--state", "state.json"], cwd=tmp_path, stdout=subprocess.PIPE,
                                stderr=subprocess.PIPE, text=True)
        try:
            assert "listening on ft/raw" in node.stdout.readline()
            peer = zenoh.open(zenoh_config(connect=(f"tcp/127.0.0.1:{port}",), listen=()))
            store = typestore()
            publisher = peer.declare_publisher("ft/raw")
            time.sleep(1.0)  # routes established
            for k in range(n):
                stamp = int(round((first_stamp_s + k / 200.0) * 1e9))
                publisher.put(wrench_message(store, stamp, "ft", np.r_[1.0, -2.0, 0.5, 0, 0, 0]
                                             + rng.normal(size=6) * NOISE))
                time.sleep(1 / 200.0)
            reply = next(iter(peer.get("ft/status", timeout=10.0))).ok.payload.to_bytes()
            status = json.loads(bytes(reply))["status"]
            peer.close()
        finally:
            node.send_signal(signal.SIGTERM)
            _, err = node.communicate(timeout=60)
        assert node.returncode == 143, err
        return status["counters"]["samples"], err

    first, _ = session(10.0, 300)
    saved = json.loads((tmp_path / "state.json").read_text())
    assert saved["counters"]["samples"] == first > 0
    second, err = session(20.0, 300)
    assert "is also an input" not in err
    resumed = json.loads((tmp_path / "state.json").read_text())
    assert second > first and resumed["counters"]["samples"] == second and resumed["time"] > saved["time"]
    np.testing.assert_allclose(resumed["bias"][:3], [1.0, -2.0, 0.5], atol=0.05)
