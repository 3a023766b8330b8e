"""Property-based tests (Hypothesis) over the live surfaces (issue 39): what a careless user or an attacker can hand
the live calibrator, its Zenoh node, its C step and the Python steps.

* a live state file, any field of it replaced by any JSON value, or its text truncated or bit-flipped: resumed with
  finite, plausible values, or refused in one line (``FtcalError``); never another exception, never a hang;
* CDR messages on every key the Zenoh node reads (wrench, IMU, temperature, joint states): random bytes, mutated
  messages, messages of another type, NaN/inf/huge/denormal fields: each either taken (finite answers, a plausible
  pose) or dropped and counted, never an exception in the callback;
* queryable key expressions (wildcards, odd keys) never re-tare, switch or identify: only a query for the action's own
  key acts; over real Zenoh peers on 127.0.0.1 as well;
* the C step (compiled once per session with the real ``cc``, under AddressSanitizer and UBSan, through its public
  ``rt_init``/``rt_step``/... API only): NaN/inf/huge/denormal inputs and wrong tool indices never write outside its
  state, are refused with -1 leaving the state untouched, and a sample far outside the training range is flagged;
* the Python steps given a wrong type or value for any parameter: a ``ParameterError`` naming it (or another
  ``FtcalError`` naming it), never ``TypeError``/``AttributeError`` from deep inside.

Example budgets are small (the whole file runs in well under a minute here); every run draws the same examples
(tests/conftest.py), ``HYPOTHESIS_PROFILE=explore`` new ones.
"""

from __future__ import annotations

import contextlib
import json
import math
import os
import shutil
import signal
import socket
import struct
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from hypothesis import HealthCheck, assume, example, given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from ftcal.core.limits import MAX_CELL_MAGNITUDE
from ftcal.files.payload_json import save_payload
from ftcal.live import LiveCalibrator
from ftcal.live.cdr import IMU_DOUBLES, TEMPERATURE_DOUBLES, WRENCH_DOUBLES, decode_stamped, encode_stamped
from ftcal.live.node_core import COMMANDS
from ftcal.live.zenoh_node import JOINT_STATE_TYPE, LiveNode, ZenohOptions, typestore
from ftcal.payload.parameters import PayloadParameters
from ftcal.runtime.errors import FtcalError, ParameterError

from test_live_zenoh_node import Sample, Sink  # a Zenoh sample and publisher, without a network

FEW = settings(max_examples=40, deadline=None, suppress_health_check=list(HealthCheck))
SOME = settings(max_examples=60, deadline=None, suppress_health_check=list(HealthCheck))

FTCAL = str(Path(sys.executable).with_name("ftcal"))
NOISE = np.r_[np.full(3, 0.05), np.full(3, 0.004)]
DOWN = [0.0, 0.0, -9.81]
AXES = ("Fx", "Fy", "Fz", "Tx", "Ty", "Tz")
GRIPPER = PayloadParameters(1.2, np.array([0.004, -0.003, 0.06]), np.zeros(3), np.zeros(3), 9.81,
                            stderr={"mass": 1e-3, "com": np.full(3, 1e-4), "force_bias": np.full(3, .01),
                                    "torque_bias": np.full(3, 1e-3)},
                            fit={"n_samples": 100, "residual_rms": NOISE, "condition_number": 1.0,
                                 "wrench_columns": list(AXES)})
HOSTILE_FLOATS = st.one_of(st.floats(width=64), st.sampled_from([math.nan, math.inf, -math.inf, 1e308, -1e308, 1e101,
                                                                  5e-324, -5e-324, 2.2e-308, 0.0, -0.0]))


@contextlib.contextmanager
def bounded(seconds: float = 10.0):
    """Fail (a hang) if the block takes longer than ``seconds``."""
    def hang(*_):
        raise AssertionError(f"no answer within {seconds} s: a hang")

    old = signal.signal(signal.SIGALRM, hang)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, old)


def one_line(exc: BaseException) -> None:
    assert isinstance(exc, FtcalError), repr(exc)
    assert "\n" not in str(exc) and str(exc), repr(exc)


# ---------------------------------------------------------------------------------- the live state file
json_values = st.recursive(
    st.one_of(st.none(), st.booleans(), st.floats(width=64), st.integers(-10**30, 10**30),
              st.sampled_from([10**4000, -10**400, 2**63, -1]), st.text(max_size=8)),
    lambda children: st.one_of(st.lists(children, max_size=7), st.dictionaries(st.text(max_size=6), children,
                                                                                max_size=4)),
    max_leaves=10)


@pytest.fixture(scope="module")
def state_doc(tmp_path_factory):
    """A state as save_state writes it, with a tool identified in place (the 'tools' field holds a payload)."""
    from test_live_attacks import still_block

    live = LiveCalibrator(tools={"gripper": GRIPPER}, tool="gripper", noise_std=NOISE)
    still_block(live, 0.0, 1.0, offset=(0.5, 0, 0, 0, 0, 0))
    live.tools["found"], live.identified = GRIPPER, {"found"}
    path = live.save_state(tmp_path_factory.mktemp("state") / "state.json")
    return json.loads(path.read_text())


def _paths(doc, prefix=()):
    yield prefix
    if isinstance(doc, dict):
        for k, v in doc.items():
            yield from _paths(v, prefix + (k,))
    elif isinstance(doc, list):
        for i, v in enumerate(doc):
            yield from _paths(v, prefix + (i,))


def _set(doc, path, value):
    if not path:
        return value
    node = doc
    for k in path[:-1]:
        node = node[k]
    node[path[-1]] = value
    return doc


def resume(path: Path) -> LiveCalibrator:
    return LiveCalibrator(tools={"gripper": GRIPPER}, noise_std=NOISE, state_path=path)


def check_resumed(live: LiveCalibrator, path: Path) -> None:
    """A state taken: finite, plausible values, and the calibrator runs and saves again."""
    assert np.all(np.isfinite(live.bias)) and np.all(np.abs(live.bias) <= MAX_CELL_MAGNITUDE)
    assert np.all(np.isfinite(live.variance)) and np.all(live.variance >= 0)
    assert live.tool in live.tools
    assert all(isinstance(v, int) and 0 <= v < 2**63 for v in live.counters.values())
    t0 = 0.0 if live.last_time is None else live.last_time
    t1 = np.nextafter(t0, np.inf) if abs(t0) > 1e15 else t0 + 0.01
    result = live.step(t1, wrench=np.zeros(6), gravity=DOWN)
    assert np.all(np.isfinite(result.compensated)) and np.all(np.isfinite(result.bias))
    live.save_state(path.with_name("again.json"))


def resumes_or_refuses(path) -> None:
    """The state file at ``path`` resumes as saved (:func:`check_resumed`) or is refused in one FtcalError line;
    anything else (another exception, 10 s or more) fails."""
    with bounded(10):
        try:
            live = resume(path)
        except FtcalError as exc:
            one_line(exc)
            return
        except Exception as exc:  # noqa: BLE001
            raise AssertionError(f"{type(exc).__name__}: {exc}") from exc
        check_resumed(live, path)


@SOME
@given(st.data())
def test_a_state_file_with_any_field_replaced_resumes_or_is_refused_in_one_line(state_doc, tmp_path_factory, data):
    doc = json.loads(json.dumps(state_doc))
    paths = list(_paths(doc))
    where = data.draw(st.sampled_from(paths), label="path")
    action = data.draw(st.sampled_from(["set", "delete", "deep"]), label="action")
    if action == "delete" and where:
        parent = doc
        for k in where[:-1]:
            parent = parent[k]
        del parent[where[-1]]
    elif action == "deep":  # nested 100,000 deep, written as text
        doc = _set(doc, where, "__deep__")
    else:
        doc = _set(doc, where, data.draw(json_values, label="value"))
    path = tmp_path_factory.mktemp("s") / "state.json"
    path.write_text(json.dumps(doc, allow_nan=True).replace('"__deep__"', "[" * 100_000 + "]" * 100_000))
    resumes_or_refuses(path)


@FEW
@given(st.data())
def test_a_truncated_or_bit_flipped_state_file_resumes_or_is_refused(state_doc, tmp_path_factory, data):
    raw = bytearray(json.dumps(state_doc, indent=1).encode())
    kind = data.draw(st.sampled_from(["flip", "truncate", "bytes", "number"]))
    if kind == "flip":
        for _ in range(data.draw(st.integers(1, 4))):
            i = data.draw(st.integers(0, len(raw) - 1))
            raw[i] ^= 1 << data.draw(st.integers(0, 7))
    elif kind == "truncate":
        raw = raw[:data.draw(st.integers(0, len(raw) - 1))]
    elif kind == "bytes":
        raw = bytearray(data.draw(st.binary(max_size=300)))
    else:  # a number token replaced by a hostile literal
        token = data.draw(st.sampled_from(["1e999", "-1e999", "NaN", "Infinity", "9" * 5000, "1" + "0" * 400,
                                           "-0", "1e-400", "0x10", "1_000"]))
        text = raw.decode()
        at = [i for i, c in enumerate(text) if c.isdigit() and not text[i - 1].isdigit()]
        i = data.draw(st.sampled_from(at))
        j = i
        while j < len(text) and (text[j].isdigit() or text[j] in ".eE-+"):
            j += 1
        raw = bytearray((text[:i] + token + text[j:]).encode())
    path = tmp_path_factory.mktemp("s") / "state.json"
    path.write_bytes(bytes(raw))
    resumes_or_refuses(path)


# ---------------------------------------------------------------------------------- CDR on every key the node reads
def node(**options) -> LiveNode:
    n = LiveNode(LiveCalibrator(tools={"gripper": GRIPPER}, tool="gripper", noise_std=NOISE), ZenohOptions(**options),
                 echo=lambda *a, **k: None)
    n.publishers = {name: Sink() for name in ("calibrated", "compensated", "diagnostics")}
    return n


def joints_node() -> LiveNode:
    from test_live_joints import sensor_gravity

    n = LiveNode(LiveCalibrator(tools={"gripper": GRIPPER}, tool="gripper", noise_std=NOISE, robot=sensor_gravity()),
                 ZenohOptions(joints_topic="/joint_states"), robot=sensor_gravity(), echo=lambda *a, **k: None)
    n.publishers = {name: Sink() for name in ("calibrated", "compensated", "diagnostics")}
    return n


STORE = typestore()


def joint_state(stamp_ns: int, names, positions) -> bytes:
    types = STORE.types
    header = types["std_msgs/msg/Header"](stamp=types["builtin_interfaces/msg/Time"](
        sec=int(stamp_ns // 10**9), nanosec=int(stamp_ns % 10**9)), frame_id="base")
    msg = types[JOINT_STATE_TYPE](header=header, name=list(names), position=np.asarray(positions, dtype=np.float64),
                                  velocity=np.zeros(0), effort=np.zeros(0))
    return bytes(STORE.serialize_cdr(msg, JOINT_STATE_TYPE))


COUNTS = {"wrench": WRENCH_DOUBLES, "imu": IMU_DOUBLES, "temperature": TEMPERATURE_DOUBLES}


@st.composite
def messages(draw, key: str):
    """Bytes for ``key``: valid-shaped with hostile fields, another type's, mutated, or random."""
    stamp = draw(st.one_of(st.integers(10**9, 2 * 10**9), st.integers(-2**31 * 10**9, (2**31 - 1) * 10**9)))
    frame = draw(st.one_of(st.just("ft"), st.text(max_size=20)))

    def stamped(count):
        values = draw(st.lists(HOSTILE_FLOATS, min_size=count, max_size=count))
        return encode_stamped(stamp, frame, values)

    from test_live_joints import JOINTS

    kind = draw(st.sampled_from(["own", "own", "wrench", "imu", "temperature", "joints", "mutated", "random"]))
    if kind == "random":
        return draw(st.binary(max_size=400))
    if kind in COUNTS:
        return stamped(COUNTS[kind])
    if kind == "joints" or (kind == "own" and key == "joints"):
        names = draw(st.one_of(st.just(list(JOINTS)), st.lists(st.sampled_from([*JOINTS, "x", ""]), max_size=8)))
        positions = draw(st.lists(HOSTILE_FLOATS, min_size=0, max_size=8))
        if draw(st.booleans()):
            positions = (positions + [0.1] * len(names))[:len(names)]
        return joint_state(stamp, names, positions)
    if kind == "own":
        return stamped(COUNTS[key])
    good = bytearray(stamped(COUNTS.get(key, 6)) if key != "joints" else joint_state(stamp, JOINTS, [0.1] * 6))
    how = draw(st.sampled_from(["flip", "truncate", "extend", "header"]))
    if how == "flip":
        i = draw(st.integers(0, len(good) - 1))
        good[i] ^= 1 << draw(st.integers(0, 7))
    elif how == "truncate":
        good = good[:draw(st.integers(0, len(good) - 1))]
    elif how == "extend":
        good += draw(st.binary(min_size=1, max_size=64))
    else:
        good[:4] = draw(st.binary(min_size=4, max_size=4))
    return bytes(good)


def answers_finite(n: LiveNode) -> bool:
    return all(all(map(math.isfinite, decode_stamped(m, 6).values))
               for key in ("calibrated", "compensated") for m in n.publishers[key].messages)


def taken_wrench(data: bytes) -> bool:
    """Whether these bytes are a WrenchStamped with finite fields within the magnitude limit (what may be taken)."""
    try:
        values = decode_stamped(data, WRENCH_DOUBLES).values
    except (ValueError, UnicodeDecodeError):
        return False
    return all(math.isfinite(v) and abs(v) <= MAX_CELL_MAGNITUDE for v in values)


@SOME
@given(st.lists(messages("wrench"), min_size=1, max_size=6))
def test_wrench_messages_are_answered_finite_or_dropped_and_counted(batch):
    n = node()
    for k in range(5):  # a live stream first, so that a hostile stamp meets a calibrator with a time
        n._on_wrench(Sample(encode_stamped(10**9 + k * 2 * 10**6, "ft", [0.0, 0.0, -11.8, 0.0, 0.0, 0.0])))
    for data in batch:
        before = (n.live.counters["samples"], n.bad_messages, n.stale_samples, n.stamp_jumps)
        with bounded(5):
            n._on_wrench(Sample(data))
        after = (n.live.counters["samples"], n.bad_messages, n.stale_samples, n.stamp_jumps)
        assert sum(after) == sum(before) + 1, (before, after)  # each message taken or counted once
        if after[0] > before[0]:
            assert taken_wrench(data)  # only a wrench of finite fields is ever taken
    assert answers_finite(n)
    assert len(n.publishers["compensated"].messages) == n.live.counters["samples"]
    json.loads(n._diagnostics_message())  # the diagnostics stay JSON


@SOME
@given(st.lists(messages("imu"), min_size=1, max_size=6))
def test_imu_messages_set_a_plausible_pose_or_are_counted(batch):
    n = node(imu_topic="/imu")
    for data in batch:
        before = (n.bad_messages, n.quaternion, n.gravity)
        with bounded(5):
            n._on_imu(Sample(data))
        if n.bad_messages == before[0]:
            if n.quaternion is not None:
                assert abs(math.sqrt(sum(v * v for v in n.quaternion)) - 1.0) < 1e-3
            g = np.asarray(n.gravity)
            assert np.all(np.isfinite(g)) and 0 < np.linalg.norm(g) <= math.sqrt(3) * MAX_CELL_MAGNITUDE
        else:
            assert n.bad_messages == before[0] + 1 and (n.quaternion, n.gravity) == before[1:]
    n._on_wrench(Sample(encode_stamped(10**9, "ft", [0.0, 0.0, -11.8, 0.0, 0.0, 0.0])))
    assert answers_finite(n)


@SOME
@given(st.lists(messages("temperature"), min_size=1, max_size=6))
def test_temperature_messages_are_finite_or_counted(batch):
    n = node(temperature_topic="/temperature")
    for data in batch:
        before = (n.bad_messages, n.temperature)
        with bounded(5):
            n._on_temperature(Sample(data))
        if n.bad_messages == before[0]:
            assert math.isfinite(n.temperature) and abs(n.temperature) <= MAX_CELL_MAGNITUDE
        else:
            assert n.bad_messages == before[0] + 1 and n.temperature == before[1]


@FEW
@given(st.lists(messages("joints"), min_size=1, max_size=5))
def test_joint_state_messages_give_a_finite_pose_or_are_counted(batch):
    n = joints_node()
    for data in batch:
        before = (n.bad_messages, n.pose)
        with bounded(5):
            n._on_joints(Sample(data))
        if n.pose is not before[1]:
            assert n.bad_messages == before[0]
            assert np.all(np.isfinite(n.pose[0])) and np.all(np.isfinite(n.pose[1]))
    n._on_wrench(Sample(encode_stamped(10**9, "ft", [0.0, 0.0, -11.8, 0.0, 0.0, 0.0])))
    assert answers_finite(n)


# ---------------------------------------------------------------------------------- queryable key expressions
KEY_PARTS = ("ft", "retare", "switch_tool", "identify_tool", "status", "*", "**", "$*", "re$*", "ft$*", "$*tare",
             "diagnostics", "raw", "FT", "Ft", "retare_", "status", "a", "ft ", "ft%2Fretare")
keys = st.lists(st.sampled_from(KEY_PARTS), min_size=1, max_size=4).map("/".join)
requests = st.sampled_from([None, b"", b"none", b"gripper", b"start x", b"finish", b"\xff", b"start none"])


class Query:
    def __init__(self, key: str, data: bytes | None) -> None:
        self.key_expr, self.payload = key, None if data is None else Sample(data)
        self.replies: list = []

    def reply(self, key, text) -> None:
        self.replies.append((key, json.loads(text)))


def unchanged(n: LiveNode) -> tuple:
    return n.live.counters.get("retares"), n.live.tool, n.live.identifying, list(n.live.tools)


@SOME
@given(keys, requests)
@example("ft/**", None)
@example("**", b"")
@example("ft/*", b"none")
@example("ft/re$*", None)
def test_only_a_query_for_an_actions_own_key_acts(key, data):
    n = node()
    n._on_wrench(Sample(encode_stamped(10**9, "ft", [0.0, 0.0, -11.8, 0.0, 0.0, 0.0])))
    start = unchanged(n)
    for name in COMMANDS:
        q = Query(key, data)
        with bounded(5):
            n._command(q, name)
        own = key == f"ft/{name}"
        if name == "status" or own:
            assert len(q.replies) == 1 and q.replies[0][0] == f"ft/{name}"
        else:
            assert q.replies == [] and unchanged(n) == start, (key, name)


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.fixture(scope="module")
def real_node(tmp_path_factory):
    """``ftcal live --zenoh`` on 127.0.0.1 and a peer session connected to it."""
    import zenoh

    from ftcal.live.zenoh_node import zenoh_config

    folder = tmp_path_factory.mktemp("node")
    save_payload(GRIPPER, folder / "gripper.json")
    port = free_port()
    proc = subprocess.Popen([FTCAL, "live", "--zenoh", "--listen", f"tcp/127.0.0.1:{port}", "--tool",
                             "gripper=gripper.json", "--duration", "120"], cwd=folder, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    try:
        assert "listening on ft/raw" in proc.stdout.readline()
        session = zenoh.open(zenoh_config(connect=(f"tcp/127.0.0.1:{port}",), listen=()))
        time.sleep(1.0)
        yield session
        session.close()
    finally:
        proc.send_signal(signal.SIGTERM)
        proc.communicate(timeout=30)


def ask(session, key: str, payload=None) -> list:
    return [json.loads(bytes(r.ok.payload.to_bytes())) for r in session.get(key, payload=payload, timeout=3.0)
            if r.ok is not None]


@settings(max_examples=30, deadline=None, suppress_health_check=list(HealthCheck), derandomize=True)
@given(keys, requests)
@example("ft/**", None)
@example("**", b"")
@example("*/retare", None)
@example("ft/$*", b"none")
def test_wildcard_queries_over_real_peers_never_act(real_node, key, data):
    import zenoh

    try:
        zenoh.KeyExpr(key)
    except Exception:  # noqa: BLE001 - not a key expression: zenoh refuses it before any peer sees it
        assume(False)
    with bounded(20):
        ask(real_node, key, data)
        status = ask(real_node, "ft/status")[0]["status"]
    assert status["counters"]["retares"] == 0 and status["tool"] == "gripper" and status["identifying"] is None


def test_the_own_key_acts_over_real_peers(real_node):
    """The control: the exact key still re-tares (the property above is not vacuous)."""
    reply = ask(real_node, "ft/retare")
    assert len(reply) == 1 and reply[0]["ok"] and reply[0]["status"]["counters"]["retares"] == 1


# ---------------------------------------------------------------------------------- the C step
DRIVER = r"""
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "rt.h"
#define GUARD 512
static struct { unsigned char pre[GUARD]; rt_state s; unsigned char post[GUARD]; } box;
static struct { unsigned char pre[GUARD]; rt_output o; unsigned char post[GUARD]; } obox;
static struct { unsigned char pre[GUARD]; rt_tool_fit f; rt_tool_se e; unsigned char post[GUARD]; } fbox;
static int guards(void) {
    int i;
    for (i = 0; i < GUARD; ++i)
        if (box.pre[i] != 0xA5 || box.post[i] != 0xA5 || obox.pre[i] != 0xA5 || obox.post[i] != 0xA5
            || fbox.pre[i] != 0xA5 || fbox.post[i] != 0xA5) return 0;
    return 1;
}
static unsigned long hash(const void *p, size_t n) {
    const unsigned char *b = p; unsigned long h = 1469598103934665603UL; size_t i;
    for (i = 0; i < n; ++i) h = (h ^ b[i]) * 1099511628211UL;
    return h;
}
static int finite_out(void) {
    int j;
    for (j = 0; j < 6; ++j)
        if (!isfinite(obox.o.calibrated[j]) || !isfinite(obox.o.compensated[j]) || !isfinite(obox.o.bias[j])
            || !isfinite(obox.o.bias_std[j])) return 0;
    return isfinite(obox.o.chi2);
}
int main(void) {
    char op[32], name[512];
    memset(box.pre, 0xA5, GUARD); memset(box.post, 0xA5, GUARD);
    memset(obox.pre, 0xA5, GUARD); memset(obox.post, 0xA5, GUARD);
    memset(fbox.pre, 0xA5, GUARD); memset(fbox.post, 0xA5, GUARD);
    while (scanf("%31s", op) == 1) {
        unsigned long h0 = hash(&box.s, sizeof box.s);
        int rc = 0, k, j, st;
        if (!strcmp(op, "init") || !strcmp(op, "set_tool")) {
            if (scanf("%d", &k) != 1) return 3;
            rc = op[0] == 'i' ? rt_init(&box.s, k) : rt_set_tool(&box.s, k);
        } else if (!strcmp(op, "step")) {
            double t, u[RT_N_INPUTS], g[3];
            if (scanf("%lf", &t) != 1) return 3;
            for (j = 0; j < RT_N_INPUTS; ++j) if (scanf("%lf", &u[j]) != 1) return 3;
            for (j = 0; j < 3; ++j) if (scanf("%lf", &g[j]) != 1) return 3;
            if (scanf("%d", &st) != 1) return 3;
            memset(&obox.o, 0x5A, sizeof obox.o);
            rc = rt_step(&box.s, t, u, g, st, &obox.o);
        } else if (!strcmp(op, "retare")) {
            rc = rt_retare(&box.s);
        } else if (!strcmp(op, "start") || !strcmp(op, "find")) {
            if (scanf("%511s", name) != 1) return 3;
            if (!strcmp(name, "-")) name[0] = 0;
            rc = op[0] == 's' ? rt_start_identification(&box.s, name) : rt_find_tool(&box.s, name);
        } else if (!strcmp(op, "finish")) {
            if (scanf("%d", &k) != 1) return 3;
            rc = rt_finish_identification(&box.s, &fbox.f, &fbox.e, k);
        } else return 3;
        {
            unsigned char pattern[sizeof obox.o];
            memset(pattern, 0x5A, sizeof pattern);
            printf("%s %d %u %d %d %d %d\n", op, rc, obox.o.flags, finite_out(), guards(),
                   h0 == hash(&box.s, sizeof box.s), !memcmp(pattern, &obox.o, sizeof pattern));
        }
        fflush(stdout);
    }
    return 0;
}
"""


@pytest.fixture(scope="session")
def c_step(tmp_path_factory):
    """The C runtime of a degree-1 model over 6 channels trained on ±20 and the gripper, driven by DRIVER, compiled
    once with the real cc under AddressSanitizer and UBSan (any write outside an object aborts the driver)."""
    from ftcal import CalibrationModel, Dataset, save_model

    cc = shutil.which("cc")
    assert cc is not None
    folder = tmp_path_factory.mktemp("c_step")
    raw = np.random.default_rng(0).uniform(-20, 20, size=(500, 6))
    model = CalibrationModel(degree=1).fit(Dataset.from_arrays(raw, raw @ np.diag([1, 2, 3, .1, .2, .3]) + 0.5))
    save_model(model, folder / "m.json")
    save_payload(GRIPPER, folder / "gripper.json")
    from ftcal.cli import main

    assert main(["convert", str(folder / "m.json"), "--to", "c-runtime", "--name", "rt", "--payload-file",
                 f"gripper={folder / 'gripper.json'}", "-o", str(folder / "rt.h")]) == 0
    (folder / "driver.c").write_text(DRIVER)
    built = subprocess.run([cc, "-std=c99", "-O0", "-g", "-fsanitize=address,undefined", "-fno-sanitize-recover=all",
                            "-Wall", "-Wextra", "driver.c", "-o", "driver", "-lm"], cwd=folder, capture_output=True,
                           text=True)
    assert built.returncode == 0, built.stderr
    import re

    header = (folder / "rt.h").read_text()
    define = {name: int(value) for name, value in re.findall(r"^#define RT_(\w+) (\d+)u?\b", header, re.M)}
    return folder / "driver", model, define


def c_number(x: float) -> str:
    return "nan" if math.isnan(x) else ("inf" if x == math.inf else "-inf" if x == -math.inf else float(x).hex())


c_ops = st.one_of(
    st.tuples(st.just("step"), st.floats(-1.0, 1e3) | HOSTILE_FLOATS,
              st.lists(st.floats(-30, 30) | HOSTILE_FLOATS, min_size=6, max_size=6),
              st.lists(st.sampled_from([0.0, -9.81]) | HOSTILE_FLOATS, min_size=3, max_size=3),
              st.sampled_from([-1, 0, 1, 2, -7, 2**31 - 1])),
    st.tuples(st.sampled_from(["init", "set_tool"]), st.sampled_from([-1, 0, 1, 2, 3, 64, 2**31 - 1, -2**31])),
    st.tuples(st.just("retare")),
    st.tuples(st.sampled_from(["start", "find"]), st.sampled_from(["-", "none", "gripper", "x" * 31, "x" * 32,
                                                                     "x" * 300, "tool2", "%n%s"])),
    st.tuples(st.just("finish"), st.sampled_from([0, 1, -1])),
)


@FEW
@given(st.lists(c_ops, min_size=1, max_size=25))
@example([("step", 0.0, [1e6, 0, 0, 0, 0, 0], [0, 0, -9.81], -1), ("step", 0.0, [5e-324] * 6, [0, 0, -9.81], 1),
          ("step", 0.0, [math.nan] * 6, [0, 0, -9.81], 1), ("step", 0.0, [0] * 6, [0, 0, 0], 1),
          ("init", 2**31 - 1), ("set_tool", -1), ("start", "x" * 300), ("finish", 1)])
def test_the_c_step_never_writes_outside_its_state_and_refuses_or_flags(c_step, ops):
    driver, model, define = c_step
    out_of_range, n_tools = define["FLAG_OUT_OF_RANGE"], define["N_TOOLS"]
    lines, t = [f"init {n_tools - 1}"], 0.0
    for op in ops:
        if op[0] == "step":
            _, t_in, u, g, st_ = op
            t = t + 0.01 if math.isfinite(t_in) and 0 <= t_in < 1e3 else t_in  # mostly increasing, sometimes hostile
            lines.append(" ".join(["step", c_number(t), *map(c_number, u), *map(c_number, g), str(st_)]))
            op = ("step", t, u, g, st_)
        else:
            lines.append(" ".join(map(str, op)))
    with bounded(30):
        ran = subprocess.run([str(driver)], input="\n".join(lines) + "\n", capture_output=True, text=True)
    assert ran.returncode == 0 and not ran.stderr, ran.stderr[-2000:]
    answers = ran.stdout.splitlines()
    assert len(answers) == len(lines)
    last_time = None
    for line, answer in zip(lines, answers):
        word, rc, flags, finite, guards, same, untouched = answer.split()
        rc, flags = int(rc), int(flags)
        assert guards == "1", line  # nothing outside the state, the output and the tool fit was written
        words = line.split()
        if word == "init":
            k = int(words[1])
            assert (rc == 0) == (0 <= k < n_tools), line
            if rc == 0:
                last_time = None
            else:
                assert same == "1", line  # a wrong tool index leaves the state untouched
        elif word == "set_tool":
            k = int(words[1])  # tools identified in place may have joined the library: at most MAX_TOOLS
            assert rc == (0 if 0 <= k < n_tools else rc) and (rc == -1 or 0 <= k < n_tools + define["MAX_ADDED_TOOLS"]), line
            if rc != 0:
                assert same == "1", line
        elif word == "step":
            t = float.fromhex(words[1]) if words[1] not in ("nan", "inf", "-inf") else float(words[1])
            values = [float.fromhex(w) if w not in ("nan", "inf", "-inf") else float(w) for w in words[2:11]]
            u, g = np.array(values[:6]), np.array(values[6:9])
            hostile = (not math.isfinite(t) or (last_time is not None and not t > last_time)
                       or not np.all(np.abs(values) <= MAX_CELL_MAGNITUDE)
                       or g[0] * g[0] + g[1] * g[1] + g[2] * g[2] == 0.0)  # no direction: its length underflows
            if not hostile:
                w = model.predict(u[None, :], warn_out_of_range=False)[0]
                hostile = not np.all(np.abs(w) <= MAX_CELL_MAGNITUDE)
            if hostile:
                assert rc == -1 and same == "1" and untouched == "1", line  # refused, nothing changed
            else:
                assert rc == 0 and finite == "1", line
                last_time = t
                if np.any(np.abs(u) > 40):  # trained on ±20: far outside its range
                    assert flags & out_of_range, line


# ---------------------------------------------------------------------------------- the Python steps' arguments
WRONG = (None, object(), 1j, math.nan, -1, 0, 1e308, "x", "", b"x", True, [], ["u1", "u1"], {"a": 1}, ("x",),
         "DEVICE", -1.5)  # DEVICE: a character device made for the test (as an output: refused, never replaced)


@pytest.fixture(scope="module")
def step_inputs(tmp_path_factory):
    folder = tmp_path_factory.mktemp("steps")
    make_device(folder / "device")
    rng = np.random.default_rng(0)
    n = 120
    u = rng.uniform(-1, 1, (n, 6))
    frame = pd.DataFrame(np.column_stack([u, u @ rng.normal(size=(6, 6)) + 0.01 * rng.normal(size=(n, 6))]),
                         columns=[f"u{i}" for i in range(1, 7)] + list(AXES))
    frame["load"] = np.repeat(["a", "b", "c"], n // 3)
    frame.to_csv(folder / "t.csv", index=False)
    frame.iloc[::-1].assign(**{a: frame[a][::-1].to_numpy() + 1e-3 for a in AXES}).to_csv(folder / "v.csv",
                                                                                      index=False)  # held out
    from ftcal import fit

    fit(folder / "t.csv", degree=1, output=folder / "m.json")
    g = np.repeat(Rotation.random(4, random_state=2).inv().apply([0.0, 0.0, -9.81]), 30, axis=0)
    force = GRIPPER.mass * g
    poses = pd.DataFrame(np.c_[np.c_[force, np.cross(GRIPPER.com, force)] + 0.01 * rng.normal(size=(n, 6)), g],
                         columns=[*AXES, "gx", "gy", "gz"]).assign(time=np.arange(n) * 0.01)
    poses.to_csv(folder / "poses.csv", index=False)
    save_payload(GRIPPER, folder / "gripper.json")
    from ftcal.sim.plan_arm import ARM_URDF

    (folder / "arm.urdf").write_text(ARM_URDF)
    return folder


def make_device(path: Path) -> None:
    """A character device node like /dev/null (root may make one), else a FIFO: a target no write may replace. The
    tests never point a write at a real device: if the refusal regressed, the copy would be replaced, not /dev/null."""
    import stat

    try:
        os.mknod(path, stat.S_IFCHR | 0o666, os.makedev(1, 3))
    except (PermissionError, AttributeError):
        os.mkfifo(path)


def special(path) -> bool:
    import stat

    mode = os.lstat(path).st_mode
    return stat.S_ISCHR(mode) or stat.S_ISFIFO(mode)


def calls(folder: Path) -> dict:
    """A quick valid call per step: step name -> (function, positional args, keyword args)."""
    import ftcal

    t, v, m = str(folder / "t.csv"), str(folder / "v.csv"), str(folder / "m.json")
    return {
        "fit": (ftcal.fit, (t,), {"degree": 1}),
        "evaluate": (ftcal.evaluate, (m, v), {}),
        "predict": (ftcal.predict, (m, v), {"output": str(folder / "p.csv")}),
        "convert": (ftcal.convert, (m, "paper-xml", str(folder / "m.xml")), {}),
        "identify_payload": (ftcal.identify_payload, (str(folder / "poses.csv"),),
                             {"inputs": AXES, "gravity_columns": ("gx", "gy", "gz"), "output": str(folder / "p.json")}),
        "compensate": (ftcal.compensate, (str(folder / "gripper.json"), str(folder / "poses.csv")),
                       {"inputs": AXES, "gravity_columns": ("gx", "gy", "gz")}),
        "plan_experiment": (ftcal.plan_experiment, (6,), {"urdf": str(folder / "arm.urdf"), "candidates": 100,
                                                         "load": ["none", "tool:1@0.03,0,0.04"]}),
    }


def _parameters(function) -> list[str]:
    import inspect

    return [p.name for p in inspect.signature(function).parameters.values()
            if p.kind is p.KEYWORD_ONLY and p.name not in ("executor", "echo", "cpu_start", "prior")]


@SOME
@given(st.data())
def test_a_step_given_a_wrong_value_names_the_parameter_or_runs(step_inputs, data):
    table = calls(step_inputs)
    step = data.draw(st.sampled_from(sorted(table)), label="step")
    function, args, kwargs = table[step]
    name = data.draw(st.sampled_from(_parameters(function)), label="parameter")
    value = data.draw(st.sampled_from(WRONG), label="value")
    value = str(step_inputs / "device") if value == "DEVICE" else value
    import warnings

    from ftcal.runtime.errors import FtcalWarning

    with bounded(60), warnings.catch_warnings():
        warnings.simplefilter("ignore", FtcalWarning)  # a warning is output in ftcal's words, not a failure
        try:
            function(*args, **{**kwargs, name: value})
        except ParameterError as exc:  # names it by its Python name, never by a command-line flag
            assert name in exc.parameters and "--" not in str(exc), (name, exc.parameters, str(exc))
            one_line(exc)
        except FtcalError as exc:  # a value of the right kind that is wrong: names the file, column or value
            one_line(exc)
        except Exception as exc:  # noqa: BLE001
            raise AssertionError(f"{step}({name}={value!r}): {type(exc).__name__}: {exc}") from exc
    assert special(step_inputs / "device")  # no step replaced the device with its output


# ---------------------------------------------------------------------------------- what this pass found (kept)
@pytest.mark.parametrize("step, name, value", [
    ("fit", "lambdas", 0.1), ("fit", "lambdas", "1e-3"), ("fit", "lambdas", [math.nan]),  # was TypeError, or taken
    ("fit", "hidden", (4,)), ("fit", "seed", 3),  # MLP-only: the library named them '--hidden', '--seed'
    ("evaluate", "baseline", object()),  # was "model: expected a model file name"
])
def test_the_wrong_values_this_pass_found_are_parameter_errors_naming_them(step_inputs, step, name, value):
    function, args, kwargs = calls(step_inputs)[step]
    with pytest.raises(ParameterError) as caught:
        function(*args, **{**kwargs, name: value})
    assert name in caught.value.parameters and "--" not in str(caught.value), str(caught.value)


@pytest.mark.parametrize("cells, shown", [([True, False] * 60, "holds bool values such as True,"),
                                          ([[1.0]] * 120, "holds [1.0], not a number")])
def test_a_cell_of_the_wrong_kind_is_named_as_written_not_as_numpys_repr(step_inputs, tmp_path, capsys, cells, shown):
    """A replayed table's boolean or list column printed np.True_ / array([1.]) (Python's words, not the user's)."""
    from ftcal.cli import main

    frame = pd.read_csv(step_inputs / "t.csv").assign(u1=cells, time=np.arange(120) * 0.01)
    frame.to_parquet(tmp_path / "odd.parquet")
    assert main(["live", "--replay", str(tmp_path / "odd.parquet"), "--gravity-columns", "Fx,Fy,Fz",
                 "-o", str(tmp_path / "o.csv")]) == 2
    err = capsys.readouterr().err
    assert shown in err and "np." not in err and "array(" not in err and not (tmp_path / "o.csv").exists(), err


@pytest.mark.parametrize("option, flag", [("wrench_topic", "--wrench-topic"), ("imu_topic", "--imu-topic"),
                                          ("temperature_topic", "--temperature-topic"), ("prefix", "--prefix")])
def test_a_topic_longer_than_ros_allows_is_refused_before_zenoh_sees_it(option, flag):
    """Found by the adversarial pass: a 100,000-character --prefix (or topic) made Zenoh abort the node (a Rust panic,
    SIGABRT) once it declared the key to a connected peer. 255 bytes (ROS 2's limit) are taken, 256 refused."""
    from ftcal.cli._common import flag_of
    from ftcal.core.limits import LIVE_MAX_TOPIC_BYTES

    taken = node(**{option: "/" + "k" * (LIVE_MAX_TOPIC_BYTES - 1)})
    assert any(len(k) >= LIVE_MAX_TOPIC_BYTES - 1 for k in taken.keys.values() if k)
    # the library names the parameter (the CLI shows it as flag through cli._common.flag_of)
    with pytest.raises(FtcalError, match=f"^{option}: a topic of 256 bytes; at most {LIVE_MAX_TOPIC_BYTES}"):
        node(**{option: "/" + "k" * LIVE_MAX_TOPIC_BYTES})
    assert flag_of(option) == flag
    with pytest.raises(FtcalError, match=f"^{option}: a topic of 200000 bytes"):  # UTF-8 bytes, not characters
        node(**{option: "\u00e9" * 100_000})


@pytest.mark.parametrize("source", ["gravity", "imu"])
@pytest.mark.parametrize("vector", [[0.0, 0.0, 5e-324], [1e-200, 0.0, 0.0], [0.0, -1e-170, 1e-170]])
def test_a_gravity_too_short_to_give_a_direction_is_refused_by_step_as_by_run(source, vector):
    """Found by the C step's property: step(gravity=[0, 0, 5e-324]) ended in ZeroDivisionError (the one-sample path
    checked for an exact zero vector, then the motion test divided by a length that underflows to 0). run() and the
    C step refuse it; step now does too, and takes a short vector whose length is still a number."""
    live = LiveCalibrator(tools={"gripper": GRIPPER}, tool="gripper", noise_std=NOISE)
    with pytest.raises(FtcalError, match="zero vector"):
        live.step(0.0, wrench=np.zeros(6), **{source: vector})
    with pytest.raises(FtcalError, match="zero vector"):
        live.run([0.0], wrench=np.zeros((1, 6)), **{source: [vector]})
    assert live.counters["samples"] == 0
    result = live.step(0.0, wrench=np.zeros(6), **{source: [0.0, 0.0, 1e-150]})  # 1e-300 squared: a direction
    assert np.all(np.isfinite(result.compensated))


@pytest.mark.parametrize("step, suffix", [("plan_experiment", ".csv"), ("predict", ".csv"),
                                          ("identify_payload", ".json")])
def test_an_output_that_is_a_device_or_a_fifo_is_refused_never_replaced(step_inputs, tmp_path, step, suffix):
    """Found by this pass (on the machine it ran on): plan_experiment(output=Path("/dev/zero")) renamed its CSV onto
    /dev/zero; running as root, the device node became a regular file. The atomic writer now refuses a target that is
    a device, FIFO or socket (a symbolic link is replaced as a name, as before). Tried on a device node made here."""
    fifo, device = tmp_path / f"fifo{suffix}", tmp_path / f"device{suffix}"
    os.mkfifo(fifo)
    make_device(device)
    function, args, kwargs = calls(step_inputs)[step]
    for target in (device, fifo):
        before = os.lstat(target)
        with pytest.raises(FtcalError, match="never replaces devices, pipes or sockets"):
            function(*args, **{**kwargs, "output": str(target)})
        after = os.lstat(target)
        assert (after.st_ino, after.st_mode) == (before.st_ino, before.st_mode) and special(target)


def test_an_integer_beyond_every_float_in_a_state_file_is_one_line(state_doc, tmp_path):
    """Found by the property above (a 401-digit integer is a JSON int that float() cannot convert)."""
    doc = json.loads(json.dumps(state_doc))
    doc["bias"][0] = 10 ** 400
    path = tmp_path / "state.json"
    path.write_text(json.dumps(doc))
    with pytest.raises(FtcalError, match="bias") as error:
        resume(path)
    one_line(error.value)
