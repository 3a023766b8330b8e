"""Hostile input to the live calibrator, found by attacking it: poisoned state files, inputs whose squares overflow,
replays that cannot resume, malformed and mistimed Zenoh messages, hostile queryable requests, and a re-tare during
a contact. Each case says what the input is and what must happen (refused in one line, or counted and run on)."""

from __future__ import annotations

import json
import math
import struct
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from ftcal.core.limits import (C_RUNTIME_MAX_TOOL_NAME, LIVE_CLOCK_RESTART_MESSAGES, LIVE_MAX_QUERY_BYTES,
                               LIVE_MAX_STAMP_JUMP_S)
from ftcal.files.payload_json import payload_document, save_payload
from ftcal.live import LiveCalibrator
from ftcal.live.cdr import IMU_DOUBLES, decode_stamped, encode_stamped
from ftcal.live.health import BIT
from ftcal.live.zenoh_node import LiveNode, ZenohOptions
from ftcal.payload.parameters import PayloadParameters
from ftcal.runtime.errors import FtcalError

from test_live_zenoh_node import Sample, Sink  # a Zenoh sample and publisher, without a network

FTCAL = str(Path(sys.executable).with_name("ftcal"))
NOISE = np.r_[np.full(3, 0.05), np.full(3, 0.004)]
DOWN = [0.0, 0.0, -9.81]
GRIPPER = PayloadParameters(1.2, np.array([0.004, -0.003, 0.06]), np.zeros(3), np.zeros(3), 9.81,
                            stderr={"mass": 1e-3, "com": np.full(3, 1e-4), "force_bias": np.full(3, .01),
                                    "torque_bias": np.full(3, 1e-3)},
                            fit={"n_samples": 100, "residual_rms": NOISE, "condition_number": 1.0,
                                 "wrench_columns": ["Fx", "Fy", "Fz", "Tx", "Ty", "Tz"]})


def still_block(live: LiveCalibrator, t0: float, seconds: float, offset=(0.0,) * 6, rate=500.0, seed=0):
    """A still sensor, gripper mounted, gravity -z: the readings are the gripper's gravity wrench + offset + noise."""
    rng = np.random.default_rng(seed)
    t = t0 + np.arange(int(seconds * rate)) / rate
    m, c = GRIPPER.mass, GRIPPER.com
    tool = np.r_[m * np.array(DOWN), m * np.cross(c, DOWN)]  # F = m g, T = (m c) x g
    w = tool + np.asarray(offset) + rng.normal(size=(t.size, 6)) * NOISE
    return live.run(t, wrench=w, gravity=np.tile(DOWN, (t.size, 1))), t, w


# ----- the state file -------------------------------------------------------------------------------------------
@pytest.fixture()
def saved_state(tmp_path):
    live = LiveCalibrator(tools={"gripper": GRIPPER}, tool="gripper", noise_std=NOISE)
    still_block(live, 0.0, 2.0, offset=(0.5, 0, 0, 0, 0, 0))
    path = live.save_state(tmp_path / "state.json")
    return path, json.loads(path.read_text())


def poisoned(doc: dict, **fields) -> str:
    out = json.loads(json.dumps(doc))
    out.update(fields)
    return json.dumps(out)


@pytest.mark.parametrize("edit, message", [
    (lambda d: '{"format": "ftcal-live-state", "form', "cannot read"),
    (lambda d: "[" * 100_000 + "]" * 100_000, "nested too deeply"),
    (lambda d: json.dumps(d).replace(json.dumps(d["variance"]), "[NaN, 1, 1, 1, 1, 1]"), "'variance' must be finite"),
    (lambda d: json.dumps(d).replace(json.dumps(d["bias"]), "[Infinity, 0, 0, 0, 0, 0]"), "'bias' must be finite"),
    (lambda d: poisoned(d, bias=[1e308] * 6), "'bias' must be finite and at most 1e+100"),
    (lambda d: poisoned(d, variance=[-1.0, 1, 1, 1, 1, 1]), "'variance' must be >= 0"),
    (lambda d: poisoned(d, variance=np.eye(6).tolist()), "'variance' must be a number; got list"),  # a matrix
    (lambda d: poisoned(d, bias=[[1, 2, 3], [4, 5, 6]]), "'bias' must be a list of 6 numbers"),
    (lambda d: poisoned(d, variance=[True] * 6), "'variance' must be a number; got bool"),
    (lambda d: poisoned(d, time="abc"), "'time' must be a number; got str"),
    (lambda d: poisoned(d, time=[1.0]), "'time' must be a number; got list"),
    (lambda d: json.dumps(d).replace(f'"time": {d["time"]}', '"time": NaN'), "'time' must be finite"),
    (lambda d: poisoned(d, counters={**d["counters"], "samples": 1.7}), "'counters' must hold 'samples'"),
    (lambda d: poisoned(d, counters={**d["counters"], "updates": -5}), "'counters' must hold 'updates'"),
    (lambda d: poisoned(d, counters={**d["counters"], "retares": True}), "'counters' must hold 'retares'"),
    (lambda d: poisoned(d, counters=[1, 2]), "'counters' must be an object"),
    (lambda d: poisoned(d, tools=[1]), "'tools' must be an object"),
    (lambda d: poisoned(d, tools={"none": payload_document(GRIPPER)}), "a tool needs a name other than 'none'"),
    (lambda d: poisoned(d, tools={"": payload_document(GRIPPER)}), "a tool needs a name other than 'none'"),
    (lambda d: poisoned(d, tool="hammer"), "tool 'hammer' is not in the library"),
    (lambda d: poisoned(d, tool=5), "'tool' must be a tool name"),
    (lambda d: {k: v for k, v in d.items() if k != "time"} and json.dumps({k: v for k, v in d.items() if k != "time"}),
     "'time' is missing"),
    # a 5,000-digit integer: Python's int() refuses more than 4,300 digits with a ValueError (it was a traceback)
    (lambda d: json.dumps(d).replace(f'"samples": {d["counters"]["samples"]}', '"samples": ' + "9" * 5000),
     "cannot read the live state"),
])
def test_a_poisoned_state_is_refused_in_one_line_naming_the_file_and_field(saved_state, edit, message):
    path, doc = saved_state
    path.write_text(edit(doc))
    with pytest.raises(FtcalError, match=None) as caught:
        LiveCalibrator(tools={"gripper": GRIPPER}, tool="gripper", noise_std=NOISE, state_path=path)
    text = str(caught.value)
    assert message in text and str(path) in text and "\n" not in text, text


def test_a_good_state_resumes_and_a_state_for_another_model_is_refused(saved_state, tmp_path):
    from ftcal.core.dataset import Dataset
    from ftcal.core.model import CalibrationModel

    path, doc = saved_state
    live = LiveCalibrator(tools={"gripper": GRIPPER}, tool="gripper", noise_std=NOISE, state_path=path)
    assert live.tool == "gripper" and live.counters == doc["counters"] and live.last_time == doc["time"]
    np.testing.assert_array_equal(live.bias, doc["bias"])
    # A state written for one calibration model is refused with another (its bias is in that model's wrench).
    rng = np.random.default_rng(0)
    raw = rng.uniform(-20, 20, size=(500, 6))
    one = CalibrationModel(degree=1).fit(Dataset.from_arrays(raw, raw))
    other = CalibrationModel(degree=1).fit(Dataset.from_arrays(raw, 2.0 * raw))
    first = LiveCalibrator(one, noise_std=NOISE)
    first.step(1.0, raw=[0.0] * 6, gravity=DOWN)
    first.save_state(tmp_path / "one.json")
    assert LiveCalibrator(one, noise_std=NOISE, state_path=tmp_path / "one.json").last_time == 1.0
    with pytest.raises(FtcalError, match="written for another calibration model"):
        LiveCalibrator(other, noise_std=NOISE, state_path=tmp_path / "one.json")
    with pytest.raises(FtcalError, match="written for another calibration model"):
        LiveCalibrator(noise_std=NOISE, state_path=tmp_path / "one.json")  # and without a model


# ----- inputs whose squares overflow ------------------------------------------------------------------------------
@pytest.mark.parametrize("value", [1e101, 1e200, -1e308])
def test_inputs_beyond_1e100_are_refused_by_step_and_run_so_chi2_stays_finite(value):
    live = LiveCalibrator(noise_std=NOISE)
    with pytest.raises(FtcalError, match="beyond 1e\\+100 in magnitude, at sample 0"):
        live.step(1.0, wrench=[value, 0, 0, 0, 0, 0], gravity=DOWN)
    with pytest.raises(FtcalError, match="gravity has .* at sample 1"):
        live.run(np.array([1.0, 1.1]), wrench=np.zeros((2, 6)), gravity=np.array([DOWN, [value, 0.0, 0.0]]))
    assert live.last_time is None and live.counters["samples"] == 0  # nothing changed
    r = live.run(np.array([2.0]), wrench=np.array([[1e99, 0, 0, 0, 0, 0]]), gravity=np.array([DOWN]))
    assert np.isfinite(r.chi2).all() and np.isfinite(r.compensated).all()  # (1e99)^2 / noise^2 is finite


# ----- replay -----------------------------------------------------------------------------------------------------
def still_table(path: Path, seconds=6.0, rate=200.0, seed=1):
    rng = np.random.default_rng(seed)
    t = np.arange(int(seconds * rate)) / rate
    m, c = GRIPPER.mass, GRIPPER.com
    w = np.r_[m * np.array(DOWN), m * np.cross(c, DOWN)] + rng.normal(size=(t.size, 6)) * NOISE
    frame = pd.DataFrame({"time": t, "gx": 0.0, "gy": 0.0, "gz": -9.81,
                          **{a: w[:, j] for j, a in enumerate(("Fx", "Fy", "Fz", "Tx", "Ty", "Tz"))}})
    frame.to_parquet(path)
    return frame


def test_replay_of_a_recording_older_than_the_resumed_state_is_one_line(tmp_path):
    still_table(tmp_path / "rec.parquet")
    save_payload(GRIPPER, tmp_path / "gripper.json")
    args = [FTCAL, "live", "--replay", "rec.parquet", "--gravity-columns", "gx,gy,gz", "--inputs", "Fx,Fy,Fz,Tx,Ty,Tz",
            "--tool", "gripper=gripper.json", "--state", "state.json"]
    first = subprocess.run([*args, "-o", "a.parquet"], cwd=tmp_path, capture_output=True, text=True, timeout=300)
    assert first.returncode == 0, first.stderr
    again = subprocess.run([*args, "-o", "b.parquet"], cwd=tmp_path, capture_output=True, text=True, timeout=300)
    assert again.returncode == 2 and len(again.stderr.strip().splitlines()) == 1, again.stderr
    assert "rec.parquet: row 0 is at t=0 s, not after the calibrator's last sample (t=5.995 s, from state.json)" \
        in again.stderr
    assert not (tmp_path / "b.parquet").exists() and not list(tmp_path.glob(".*tmp*"))


def test_many_scripted_events_give_the_table_the_library_computes_block_by_block(tmp_path):
    """Scripted re-tares split the replay into short blocks, gathered before they are written: the table is what
    the library computes with the same re-tares applied by hand between blocks."""
    from ftcal.live.replay import ReplayColumns, ScriptedEvent, replay_table

    frame = still_table(tmp_path / "rec.parquet")
    times = np.round(np.arange(0.25, 5.5, 0.05), 6)  # 105 re-tares, every 10 samples
    columns = ReplayColumns("time", ("Fx", "Fy", "Fz", "Tx", "Ty", "Tz"), False, "gravity", ("gx", "gy", "gz"))
    replay_table(tmp_path / "rec.parquet", LiveCalibrator(tools={"gripper": GRIPPER}, tool="gripper", noise_std=NOISE),
                 columns, tmp_path / "out.parquet", events=[ScriptedEvent(float(x), "retare") for x in times],
                 chunk_rows=500)
    out = pd.read_parquet(tmp_path / "out.parquet")
    by_hand = LiveCalibrator(tools={"gripper": GRIPPER}, tool="gripper", noise_std=NOISE)
    t = frame["time"].to_numpy()
    cuts = [0, *np.searchsorted(t, times), t.size]
    bias = []
    for a, b in zip(cuts[:-1], cuts[1:]):
        if a > 0:
            by_hand.retare()
        rows = frame.iloc[a:b]
        bias.append(by_hand.run(rows["time"].to_numpy(), wrench=rows[["Fx", "Fy", "Fz", "Tx", "Ty", "Tz"]].to_numpy(),
                                gravity=rows[["gx", "gy", "gz"]].to_numpy()).bias)
    assert len(out) == t.size
    np.testing.assert_array_equal(out[["bias_Fx", "bias_Fy", "bias_Fz", "bias_Tx", "bias_Ty", "bias_Tz"]].to_numpy(),
                                  np.vstack(bias))
    assert by_hand.counters["retares"] == times.size


# ----- the Zenoh node's inbound messages (its callbacks, without a network) -----------------------------------

def node(**options) -> LiveNode:
    n = LiveNode(LiveCalibrator(tools={"gripper": GRIPPER}, tool="gripper", noise_std=NOISE), ZenohOptions(**options),
                 echo=lambda *a, **k: None)
    n.publishers = {name: Sink() for name in ("calibrated", "compensated", "diagnostics")}
    return n


def reading(rng) -> list:
    m, c = GRIPPER.mass, GRIPPER.com
    return (np.r_[m * np.array(DOWN), m * np.cross(c, DOWN)] + rng.normal(size=6) * NOISE).tolist()


def feed(n: LiveNode, stamps_s, rng) -> None:
    for s in stamps_s:
        n._on_wrench(Sample(encode_stamped(int(round(s * 1e9)), "ft", reading(rng))))


def published_finite(n: LiveNode) -> bool:
    return all(all(map(math.isfinite, decode_stamped(m, 6).values))
               for key in ("calibrated", "compensated") for m in n.publishers[key].messages)


def hostile_wrenches(good: bytes) -> list[bytes]:
    stamp = good[4:12]
    return [b"", good[:10], good[:-1], b"\x07\x07" + good[2:], b"\x00\x02" + good[2:],
            good[:12] + struct.pack("<I", 0xFFFFFFFF) + good[16:],  # frame id length beyond the message
            good[:12] + struct.pack("<I", 0) + good[16:],  # no room for the NUL
            good[:16] + b"ft_" + good[19:],  # frame id not NUL-terminated
            good[:16] + b"\xff\x00\x00" + good[19:],  # frame id not UTF-8
            good[:4] + struct.pack("<iI", struct.unpack("<i", stamp[:4])[0], 1_000_000_000) + good[12:],  # nanosec
            *(encode_stamped(struct.unpack("<i", stamp[:4])[0] * 10 ** 9 + 999_000_000, "ft", [v, 0, 0, 0, 0, 0])
              for v in (math.nan, math.inf, -math.inf, 1e308, 1e101))]


def test_malformed_wrench_messages_are_counted_and_the_stream_goes_on():
    n, rng = node(), np.random.default_rng(4)
    feed(n, 1.0 + np.arange(600) / 500, rng)
    good = encode_stamped(2_300_000_000, "ft", [0.0] * 6)
    bad = hostile_wrenches(good)
    for data in bad:
        n._on_wrench(Sample(data))
    feed(n, 2.4 + np.arange(100) / 500, rng)
    status = json.loads(n._diagnostics_message())
    assert status["bad_messages"] == len(bad) and status["counters"]["samples"] == 700
    assert len(n.publishers["compensated"].messages) == 700 and published_finite(n)


def test_a_lone_far_future_stamp_is_held_back_and_a_confirmed_jump_is_taken():
    n, rng = node(), np.random.default_rng(5)
    feed(n, 1.0 + np.arange(300) / 500, rng)
    far = 1.6 + 10 * LIVE_MAX_STAMP_JUMP_S
    feed(n, [far], rng)  # alone: the stream must not go stale after it
    feed(n, 1.6 + np.arange(1, 101) / 500, rng)
    assert n.live.counters["samples"] == 400 and n.stamp_jumps == 1 and n.stale_samples == 0
    feed(n, far + np.arange(50) / 500, rng)  # a real gap: the second message after it confirms the new time line
    assert n.live.counters["samples"] == 449 and n.stamp_jumps == 2
    assert json.loads(n._diagnostics_message())["stamp_jumps"] == 2 and published_finite(n)


def test_a_publisher_clock_that_restarts_restarts_the_calibrators_clock():
    n, rng = node(), np.random.default_rng(6)
    feed(n, 100.0 + np.arange(500) / 500, rng)
    bias = n.live.bias.copy()
    feed(n, [50.0], rng)  # one stale message is dropped
    feed(n, 1.0 + np.arange(LIVE_CLOCK_RESTART_MESSAGES + 50) / 500, rng)  # the clock went back for good
    assert n.stale_samples == 1 + LIVE_CLOCK_RESTART_MESSAGES - 1  # the lone one and the run before the restart
    assert n.live.counters["samples"] == 500 + 51 and n.live.last_time == pytest.approx(1.0 + 149 / 500)
    assert any(e[1] == "clock" and e[2] == "restarted" for e in n.live.events)
    np.testing.assert_allclose(n.live.bias, bias, atol=0.05)  # the sensor's bias is kept across the restart


def test_a_broken_imu_message_is_counted_and_keeps_the_pose():
    n = node(imu_topic="/imu")
    level = [0.0, 0.0, 0.0, 1.0] + [0.0] * 33
    n._on_imu(Sample(encode_stamped(1, "imu", level)))
    assert n.quaternion == (0.0, 0.0, 0.0, 1.0)
    no_orientation = [0.0] * 4 + [-1.0] + [0.0] * 32
    for acceleration in ([math.nan, 0, 9.81], [0.0, 0.0, 0.0], [0.0, 0.0, 1e308], [0.0, 0.0, 1e150]):
        message = no_orientation[:25] + acceleration + no_orientation[28:]
        n._on_imu(Sample(encode_stamped(2, "imu", message)))
    n._on_imu(Sample(encode_stamped(3, "imu", [math.nan] * IMU_DOUBLES)))
    assert n.bad_messages == 5 and n.quaternion == (0.0, 0.0, 0.0, 1.0) and n.gravity == (0.0, 0.0, -9.81)


# ----- hostile queryable requests ----------------------------------------------------------------------------
class Query:
    key_expr = "ft/identify_tool"

    def __init__(self, data: bytes | None) -> None:
        self.payload = None if data is None else Sample(data)
        self.replies: list = []

    def reply(self, key, text) -> None:
        self.replies.append(json.loads(text))


def ask(n: LiveNode, name: str, data: bytes | None) -> dict:
    q = Query(data)
    q.key_expr = f"ft/{name}"
    n._command(q, name)
    assert len(q.replies) == 1  # every request is answered once
    return q.replies[0]


@pytest.mark.parametrize("data, message", [
    (b"start " + "x".encode() * (C_RUNTIME_MAX_TOOL_NAME + 1), f"at most {C_RUNTIME_MAX_TOOL_NAME}"),
    (b"start " + "\u00e9".encode() * 40, f"at most {C_RUNTIME_MAX_TOOL_NAME}"),  # 80 bytes in 40 characters
    ("start evil\u202etxt".encode(), "U+202E"),
    (b"start a\x01b", "U+0001"),
    (b"start none", "other than 'none'"),
    (b"start", "'start NAME' or 'finish'"),
    (b"finish", "no identification in progress"),
    (b"start a b", "'start NAME' or 'finish'"),
    (b"\xff\xfe", "not UTF-8"),
    (b"x" * (LIVE_MAX_QUERY_BYTES + 1), f"at most {LIVE_MAX_QUERY_BYTES}"),
    (b'{"start": ' * 300, "'start NAME' or 'finish'"),  # deep JSON is not JSON here: plain text
])
def test_hostile_identify_requests_get_an_error_reply_naming_the_problem(data, message):
    n = node()
    reply = ask(n, "identify_tool", data)
    assert reply["ok"] is False and message in reply["error"], reply
    assert n.live.identifying is None and list(n.live.tools) == ["none", "gripper"]


def test_switch_and_status_requests_with_hostile_payloads_and_an_unexpected_failure_are_answered():
    n = node()
    switch = "switch_tool"
    for data in (b"hammer", b"", b"\x00", "\u202e".encode(), b"x" * 10_000):
        reply = ask(n, switch, data)
        assert reply["ok"] is False and reply["error"]
    assert n.live.tool == "gripper"
    assert ask(n, switch, b" none \n")["status"]["tool"] == "none"

    def broken(_):
        raise ZeroDivisionError("a bug")

    n._identify = broken
    reply = ask(n, "identify_tool", b"")
    assert reply == {"ok": False, "error": "identify_tool: ZeroDivisionError: a bug"}


# ----- physics: a re-tare during a contact --------------------------------------------------------------------
def test_a_retare_during_a_held_contact_warns_and_the_release_is_flagged():
    """Re-tare says "nothing touches the sensor now"; during a 10 N contact the contact becomes the bias (no
    gate can tell a contact from a bias just forgotten). The calibrator says so when asked during a flagged
    contact, and when the contact is released the compensated wrench shows -10 N, flagged unexplained."""
    live = LiveCalibrator(tools={"gripper": GRIPPER}, tool="gripper", noise_std=NOISE)
    still_block(live, 0.0, 3.0, seed=1)
    pressed, _, _ = still_block(live, 3.0, 2.0, offset=(10.0, 0, 0, 0, 0, 0), seed=2)
    assert pressed.flags[-1] & BIT["unexplained"] and abs(pressed.bias[-1, 0]) < 0.1  # flagged, not absorbed
    warning = live.retare()
    assert "re-tare while contact" in warning or "re-tare while unexplained" in warning
    assert any(e[2] == "retare" and "becomes the bias" in e[3] for e in live.events)
    held, _, _ = still_block(live, 5.0, 2.0, offset=(10.0, 0, 0, 0, 0, 0), seed=3)
    assert abs(held.bias[-1, 0] - 10.0) < 0.1  # absorbed, as documented
    released, t, _ = still_block(live, 7.0, 2.0, seed=4)
    assert np.all(np.abs(released.compensated[t > 7.1, 0] + 10.0) < 0.5)
    assert released.flags[-1] & BIT["unexplained"]
    assert LiveCalibrator(noise_std=NOISE).retare() is None  # no flag raised: no warning


# ----- replay of ROS bags -----------------------------------------------------------------------------------------
def still_bag(tmp_path: Path, name: str, huge_at: int | None = None, repeat_stamp_at: int | None = None) -> Path:
    """A still sensor (gripper, level) as an MCAP bag: WrenchStamped on /ft and a level Imu on /imu at 200 Hz.
    ``huge_at``: that sample's Fx is 1e308; ``repeat_stamp_at``: that message's header stamp repeats the previous
    one (its receive time still increases)."""
    from bag_data import Bag

    rng = np.random.default_rng(2)
    bag, t0 = Bag("mcap-file"), 1_700_000_000 * 10 ** 9
    for k in range(400):
        receive = t0 + k * 5_000_000
        values = reading(rng)
        if k == huge_at:
            values[0] = 1e308
        stamp = receive - 5_000_000 if k == repeat_stamp_at else receive
        bag.wrench("/ft", receive, values, stamp_ns=stamp)
        bag.imu("/imu", receive, [0.0, 0.0, 0.0, 1.0], [0.0, 0.0, 0.0], [0.0, 0.0, 9.81])
    return bag.write(tmp_path / name)


def live_bag(tmp_path: Path, bag: Path, *extra: str):
    save_payload(GRIPPER, tmp_path / "gripper.json")
    return subprocess.run([FTCAL, "live", "--replay", str(bag), "--wrench-topic", "/ft", "--imu-topic", "/imu",
                           "--tool", "gripper=gripper.json", *extra, "-o", "out.parquet"], cwd=tmp_path,
                          capture_output=True, text=True, timeout=300)


def test_a_huge_value_in_a_bag_names_the_bag_topic_and_time_not_a_temporary_table(tmp_path):
    bag = still_bag(tmp_path, "huge", huge_at=100)
    done = live_bag(tmp_path, bag)
    assert done.returncode == 2 and len(done.stderr.strip().splitlines()) == 1, done.stderr
    assert f"{bag}: the wrench on /ft (Fx) holds 1e+308 at t=1700000000.500000 s" in done.stderr
    assert "ftcal-live-bag" not in done.stderr and not (tmp_path / "out.parquet").exists()


def test_receive_time_replays_a_bag_whose_stamps_repeat_as_the_error_suggests(tmp_path):
    bag = still_bag(tmp_path, "repeat", repeat_stamp_at=200)
    refused = live_bag(tmp_path, bag)
    assert refused.returncode == 2 and "--receive-time" in refused.stderr
    done = live_bag(tmp_path, bag, "--receive-time")
    assert done.returncode == 0, done.stderr
    out = pd.read_parquet(tmp_path / "out.parquet")
    assert len(out) == 400 and np.all(np.diff(out["time"].to_numpy()) > 0)
    table = subprocess.run([FTCAL, "live", "--replay", "out.parquet", "--gravity-columns", "Fx,Fy,Fz",
                            "--receive-time", "-o", "x.parquet"], cwd=tmp_path, capture_output=True, text=True,
                           timeout=300)
    assert table.returncode == 2 and "--receive-time applies to ROS bags" in table.stderr


# ----- generated C: compiled-in tool names ------------------------------------------------------------------------
def test_a_compiled_in_tool_name_longer_than_a_run_time_one_is_refused(tmp_path):
    """A 5000-byte name made a string literal C99 compilers need not accept (4095 bytes; cc -pedantic -Werror
    refused the header); compiled-in names now have the run-time limit."""
    from ftcal.core.dataset import Dataset
    from ftcal.core.model import CalibrationModel
    from ftcal.files.model_files import save_model

    raw = np.random.default_rng(0).uniform(-20, 20, size=(500, 6))
    save_model(CalibrationModel(degree=1).fit(Dataset.from_arrays(raw, raw)), tmp_path / "model.json")
    save_payload(GRIPPER, tmp_path / "gripper.json")
    name = "x" * (C_RUNTIME_MAX_TOOL_NAME + 1)
    done = subprocess.run([FTCAL, "convert", "model.json", "--to", "c-runtime", "--payload-file",
                           f"{name}=gripper.json", "-o", "rt.h"], cwd=tmp_path, capture_output=True, text=True,
                          timeout=300)
    assert done.returncode == 2 and len(done.stderr.strip().splitlines()) == 1, done.stderr
    assert f"a name of {C_RUNTIME_MAX_TOOL_NAME + 1} bytes; at most {C_RUNTIME_MAX_TOOL_NAME}" in done.stderr
    assert not (tmp_path / "rt.h").exists()


# ----- physics: a contact that builds up slowly ------------------------------------------------------------------
WALK = [3.0, 3.0, 3.0, 0.3, 0.3, 0.3]  # N/√h, N·m/√h: the UR wrist sensor's drift (0 → 4 N in 5 minutes)


def ramp_recording(ramp_n_per_s: float, seconds=40.0, rate=500.0, seed=1):
    """A still, level sensor with the gripper; from 10 s a contact along x grows at ``ramp_n_per_s`` up to 10 N."""
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, seconds, 1.0 / rate)
    contact = np.clip((t - 10.0) * ramp_n_per_s, 0.0, 10.0)
    bias = np.array([0.3, -0.2, 0.1, 0.01, 0.0, -0.01])
    m, c = GRIPPER.mass, GRIPPER.com
    w = np.r_[m * np.array(DOWN), m * np.cross(c, DOWN)] + bias + rng.normal(size=(t.size, 6)) * NOISE
    w[:, 0] += contact
    return t, w, contact, bias


@pytest.mark.parametrize("holdoff", [0.0, None])
@pytest.mark.parametrize("ramp", [1.0, 0.3])
def test_a_slow_ramp_contact_is_not_absorbed_into_the_bias(ramp, holdoff):
    """The per-sample χ² gate alone let a 1 N/s ramp to 10 N through (the filter follows it with a lag of a few σ:
    the bias took all 10 N, nothing flagged). The drift test sends the bias back once it moved faster than the
    walk allows: the bias ends within 10 % of the contact of its true value and the held contact is flagged.
    With the gate's hold-off (the default) a sample that fails the gate stops updates for 0.15 s, so the filter
    may stop following a fast ramp before the drift test is needed; ``holdoff=0``: the drift test alone."""
    t, w, contact, bias = ramp_recording(ramp, seconds=10.0 + 10.0 / ramp + 15.0)
    extra = {} if holdoff is None else {"holdoff": holdoff}
    live = LiveCalibrator(tools={"gripper": GRIPPER}, tool="gripper", noise_std=NOISE, walk_std=WALK, **extra)
    r = live.run(t, wrench=w, gravity=np.tile(DOWN, (t.size, 1)))
    held = contact >= 10.0
    assert np.all(np.abs(r.bias[held, 0] - bias[0]) < 1.0)  # < 10 % of the 10 N contact
    np.testing.assert_allclose(r.compensated[held, 0], 10.0, atol=0.4)  # the contact, reported
    assert np.all(r.flags[held][t[held] > t[held][0] + 0.5] & BIT["unexplained"])
    if holdoff == 0.0:
        assert any(e[2] == "rollback" and e[0] > 10.0 for e in live.events)


def test_single_samples_roll_the_bias_back_where_blocks_do():
    t, w, _, _ = ramp_recording(1.0, seconds=16.0)
    g = np.tile(DOWN, (t.size, 1))
    # the drift test alone (the gate's hold-off can stop this ramp at the gate before the drift test is needed)
    block = LiveCalibrator(tools={"gripper": GRIPPER}, tool="gripper", noise_std=NOISE, walk_std=WALK, holdoff=0.0)
    r = block.run(t, wrench=w, gravity=g)
    one = LiveCalibrator(tools={"gripper": GRIPPER}, tool="gripper", noise_std=NOISE, walk_std=WALK, holdoff=0.0)
    steps = [one.step(t[k], wrench=w[k], gravity=g[k]) for k in range(t.size)]
    np.testing.assert_allclose(np.array([s.bias for s in steps]), r.bias, rtol=1e-9, atol=1e-9)
    np.testing.assert_array_equal([s.updated for s in steps], r.updated)
    rollbacks = [e[0] for e in block.events if e[2] == "rollback"]
    assert rollbacks and rollbacks == [e[0] for e in one.events if e[2] == "rollback"]


def test_a_bias_that_follows_the_walk_is_never_sent_back():
    """Drift as the model says (a random walk of the filter's own q, 3 N/√h, well beyond the acceptance threshold
    over 10 minutes) and a still sensor: no rollback, and the bias tracks the truth."""
    rng = np.random.default_rng(8)
    rate, seconds = 100.0, 600.0
    t = np.arange(0.0, seconds, 1.0 / rate)
    q = (np.asarray(WALK) ** 2) / 3600.0
    truth = np.cumsum(rng.normal(size=(t.size, 6)) * np.sqrt(q / rate), axis=0)
    m, c = GRIPPER.mass, GRIPPER.com
    w = np.r_[m * np.array(DOWN), m * np.cross(c, DOWN)] + truth + rng.normal(size=(t.size, 6)) * NOISE
    live = LiveCalibrator(tools={"gripper": GRIPPER}, tool="gripper", noise_std=NOISE, walk_std=WALK)
    r = live.run(t, wrench=w, gravity=np.tile(DOWN, (t.size, 1)))
    assert not any(e[2] == "rollback" for e in live.events)
    settled = t > 2.0
    assert np.sqrt(np.mean((r.bias[settled, :3] - truth[settled, :3]) ** 2)) < 0.1


# ----- the same over real Zenoh peers (loopback, multicast scouting off) ----------------------------------------
def test_a_real_node_survives_hostile_messages_and_requests(tmp_path):
    """``ftcal live --zenoh`` on 127.0.0.1: hostile wrench payloads, a far-future stamp and hostile queryable requests
    between good messages; every good message is answered with finite numbers, every request with one reply, and
    SIGTERM ends the node with its state saved."""
    import signal
    import socket
    import threading
    import time

    import zenoh

    from ftcal.live.zenoh_node import zenoh_config

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    save_payload(GRIPPER, tmp_path / "gripper.json")
    node = subprocess.Popen([FTCAL, "live", "--zenoh", "--listen", f"tcp/127.0.0.1:{port}", "--tool",
                             "gripper=gripper.json", "--state", "state.json"], cwd=tmp_path,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    rng = np.random.default_rng(9)
    try:
        assert "listening on ft/raw" in node.stdout.readline()
        session = zenoh.open(zenoh_config(connect=(f"tcp/127.0.0.1:{port}",), listen=()))
        got, lock = [], threading.Lock()

        def on(sample):
            with lock:
                got.append(decode_stamped(bytes(sample.payload.to_bytes()), 6))

        sub = session.declare_subscriber("ft/compensated", on)
        pub = session.declare_publisher("ft/raw")
        time.sleep(1.0)  # routes established

        def ask(key, payload=None):
            replies = list(session.get(key, payload=payload, timeout=10.0))
            assert len(replies) == 1
            return json.loads(bytes(replies[0].ok.payload.to_bytes()))

        good = 0
        for k in range(400):
            stamp = 1_000_000_000 + k * 2_000_000
            pub.put(encode_stamped(stamp, "ft", reading(rng)))
            good += 1
            if k == 200:
                for data in hostile_wrenches(encode_stamped(stamp, "ft", [0.0] * 6)):
                    pub.put(data)
                pub.put(encode_stamped(stamp + int(1e12), "ft", reading(rng)))  # 1000 s ahead, alone
            time.sleep(0.002)
        replies = [ask("ft/identify_tool", data) for data in
                   ("start " + "x" * 100, "start evil\u202etxt", "start", "finish", b"\xff\xfe", "x" * 5000)]
        switched = ask("ft/switch_tool", "hammer")
        status = ask("ft/status")
        time.sleep(0.5)
        sub.undeclare()
        session.close()
    finally:
        node.send_signal(signal.SIGTERM)
        out, err = node.communicate(timeout=60)
    assert node.returncode == 143, err
    assert all(r["ok"] is False and r["error"] for r in replies) and not switched["ok"]
    assert status["status"]["counters"]["samples"] >= 0.95 * good and status["status"]["tools"] == ["none", "gripper"]
    assert len(got) >= 0.95 * good and all(all(map(math.isfinite, m.values)) for m in got)
    assert max(m.stamp_ns for m in got) < 2_000_000_000  # the far-future message was not answered
    state = json.loads((tmp_path / "state.json").read_text())
    assert state["counters"]["samples"] == status["status"]["counters"]["samples"]
    assert state["time"] < 2.0  # the lone far-future stamp did not become the calibrator's time


def test_a_tool_identified_in_place_keeps_replacing_its_file_namesake_after_a_resume(tmp_path):
    """Identified in place under the name of a library tool, the new tool replaced it; the state carries it, and a
    resume with the old file under that name still mounts the identified tool (its gravity wrench is what the
    saved bias was tracked with)."""
    heavier = PayloadParameters(2.0, np.array([0.01, 0.0, 0.08]), np.zeros(3), np.zeros(3), 9.81,
                                stderr=GRIPPER.stderr, fit=GRIPPER.fit)
    live = LiveCalibrator(tools={"gripper": GRIPPER}, tool="gripper", noise_std=NOISE)
    live.add_tool("gripper", heavier)  # as finish_identification does for a name the library has
    live.identified.add("gripper")
    live.step(1.0, wrench=[0.0] * 6, gravity=DOWN)
    live.save_state(tmp_path / "state.json")
    resumed = LiveCalibrator(tools={"gripper": GRIPPER}, tool="gripper", noise_std=NOISE,
                             state_path=tmp_path / "state.json")
    assert resumed.tools["gripper"].mass == pytest.approx(2.0)
    before = resumed.bias.copy()
    sample = resumed.step(2.0, wrench=[0.0] * 6, gravity=DOWN)  # compensated = (w - m g) - bias, m = 2 kg
    assert sample.compensated[2] == pytest.approx(0.0 - 2.0 * DOWN[2] - before[2], abs=1e-9)
    assert any(e[2] == "replaced" for e in resumed.events)


# ----- the library's own arguments ----------------------------------------------------------------------------
@pytest.mark.parametrize("settings, message", [
    ({"walk_std": 1e200}, "walk_std must be six finite numbers >= 0 and at most 1e+100"),  # its square is inf
    ({"noise_std": 1e160}, "noise_std must be six finite numbers"),
    ({"initial_bias": 1e300}, "initial_bias must be six finite numbers of at most 1e+100"),
    ({"initial_bias": 0.0, "initial_bias_std": 1e200}, "initial_bias_std must be six finite numbers"),
    ({"unexplained_sigma": math.nan}, "unexplained_sigma must be a finite number > 0"),
    ({"unexplained_seconds": -1.0}, "unexplained_seconds must be a finite number >= 0"),
    ({"adc_limits": (5.0, -5.0)}, "adc_limits must be (low, high)"),
    ({"adc_limits": (math.nan, 1.0)}, "adc_limits must be (low, high)"),
    ({"temperature_range": (40.0, 20.0)}, "temperature_range must be (low, high)"),
    ({"motion_window": 0.0}, "motion_window must be a finite number > 0"),
    ({"min_hold": math.nan}, "min_hold must be a finite number >= 0"),
    ({"gravity_magnitude": 0.0}, "gravity_magnitude must be a finite number > 0"),
    ({"tools": {"a": 5}}, "tool 'a': give a payload"),
])
def test_settings_that_would_run_and_mean_nothing_are_refused(settings, message):
    with pytest.raises(FtcalError, match=None) as caught:
        LiveCalibrator(**settings)
    assert message in str(caught.value)


@pytest.mark.parametrize("kwargs, message", [
    ({"time": "abc"}, "time must be numbers"),
    ({"time": None}, "time must be finite"),
    ({"wrench": ["a"] * 6}, "wrench must be numbers"),
    ({"temperature": "hot"}, "temperature must be numbers"),
])
def test_a_single_sample_that_is_not_numbers_is_one_error(kwargs, message):
    live = LiveCalibrator(noise_std=NOISE)
    arguments = {"time": 1.0, "wrench": [0.0] * 6, "gravity": DOWN, **kwargs}
    with pytest.raises(FtcalError, match=message):
        live.step(arguments.pop("time"), **arguments)
    with pytest.raises(FtcalError, match="temperature has 3 values for 2 samples"):
        live.run(np.array([1.0, 2.0]), wrench=np.zeros((2, 6)), gravity=np.tile(DOWN, (2, 1)), temperature=np.ones(3))


def test_a_state_that_cannot_be_written_leaves_no_replay_output(tmp_path):
    """The replay's table used to be renamed into place before the state was saved: a --state whose parent is a
    file failed the command (exit 2) and left the table behind."""
    still_table(tmp_path / "rec.parquet")
    (tmp_path / "afile").write_text("")
    done = subprocess.run([FTCAL, "live", "--replay", "rec.parquet", "--gravity-columns", "gx,gy,gz", "--inputs",
                           "Fx,Fy,Fz,Tx,Ty,Tz", "--state", "afile/state.json", "-o", "out.parquet"], cwd=tmp_path,
                          capture_output=True, text=True, timeout=300)
    assert done.returncode == 2 and len(done.stderr.strip().splitlines()) == 1, done.stderr
    assert "afile/state.json: cannot create the output file (afile is a file, not a directory)" in done.stderr
    assert not (tmp_path / "out.parquet").exists() and not list(tmp_path.glob(".*tmp*"))


def test_drop_incomplete_replays_a_table_with_nan_samples_as_the_table_without_them(tmp_path):
    """A NaN sample mid-stream refuses the replay in one line naming column and row; with --drop-incomplete the
    stream goes on: the output is the replay of the same table with those rows removed (by pandas), all finite."""
    frame = still_table(tmp_path / "rec.parquet")
    frame.loc[300, "Fx"] = np.nan
    frame.loc[700, "gz"] = np.nan
    frame.to_parquet(tmp_path / "holes.parquet")
    frame.dropna().to_parquet(tmp_path / "complete.parquet")
    save_payload(GRIPPER, tmp_path / "gripper.json")
    args = ["live", "--gravity-columns", "gx,gy,gz", "--inputs", "Fx,Fy,Fz,Tx,Ty,Tz", "--tool", "gripper=gripper.json"]

    def replay(*more):
        return subprocess.run([FTCAL, *args, *more], cwd=tmp_path, capture_output=True, text=True, timeout=300)

    refused = replay("--replay", "holes.parquet", "-o", "a.parquet")
    assert refused.returncode == 2 and "column 'Fx' has 1 empty, NaN or infinite cell(s), first at row 300" \
        in refused.stderr and not (tmp_path / "a.parquet").exists()
    dropped = replay("--replay", "holes.parquet", "--drop-incomplete", "-o", "b.parquet")
    assert dropped.returncode == 0 and "; 2 incomplete row(s) dropped" in dropped.stdout, dropped.stderr
    assert replay("--replay", "complete.parquet", "-o", "c.parquet").returncode == 0
    b, c = pd.read_parquet(tmp_path / "b.parquet"), pd.read_parquet(tmp_path / "c.parquet")
    assert len(b) == len(frame) - 2
    pd.testing.assert_frame_equal(b, c)
    assert np.isfinite(b.select_dtypes("number").to_numpy(float)).all()


def test_the_c_step_refuses_inputs_beyond_1e100_as_python_does(tmp_path):
    """The C step took a 1e200 gauge value and answered chi2 = inf; it now returns -1 and changes nothing, as
    Python refuses the sample."""
    import shutil

    from ftcal.core.dataset import Dataset
    from ftcal.core.model import CalibrationModel
    from ftcal.live.c_runtime import generate_c_runtime

    cc = shutil.which("cc")
    assert cc is not None
    raw = np.random.default_rng(0).uniform(-20, 20, size=(500, 6))
    model = CalibrationModel(degree=1).fit(Dataset.from_arrays(raw, raw))
    (tmp_path / "rt.h").write_text(generate_c_runtime(model, {"gripper": GRIPPER}, name="rt"))
    (tmp_path / "main.c").write_text("""
#include <stdio.h>
#include "rt.h"
static rt_state s;
int main(void) {
    rt_output out; double u[6] = {0, 0, 0, 0, 0, 0}, g[3] = {0, 0, -9.81}; double big[3] = {1e101, 1e200, -1e308};
    int k, i;
    rt_init(&s, 1);
    for (k = 0; k < 100; ++k) if (rt_step(&s, k * 0.01, u, g, -1, &out)) return 1;
    for (i = 0; i < 3; ++i) {
        u[0] = big[i]; printf("%d ", rt_step(&s, 2.0, u, g, -1, &out)); u[0] = 0;
        g[1] = big[i]; printf("%d ", rt_step(&s, 2.0, u, g, -1, &out)); g[1] = 0;
    }
    printf("%d\\n", rt_step(&s, 2.0, u, g, -1, &out));  /* the state is untouched: time 2.0 is still new */
    return 0;
}
""")
    built = subprocess.run([cc, "-O2", "-std=c99", "-Wall", "-Wextra", "-Werror", "-pedantic", "main.c", "-o", "main",
                            "-lm"], cwd=tmp_path, capture_output=True, text=True)
    assert built.returncode == 0, built.stderr
    ran = subprocess.run([str(tmp_path / "main")], capture_output=True, text=True)
    assert ran.stdout.split() == ["-1"] * 6 + ["0"]
    live = LiveCalibrator(model, tools={"gripper": GRIPPER}, tool="gripper")
    for value in (1e101, 1e200, -1e308):
        with pytest.raises(FtcalError, match="beyond 1e\\+100"):
            live.step(2.0, raw=[value, 0, 0, 0, 0, 0], gravity=DOWN)


@pytest.mark.parametrize("kind", ["fifo", "device"])
def test_a_state_path_that_is_not_a_regular_file_is_refused_not_read(tmp_path, kind):
    """LiveCalibrator(state_path=FIFO) blocked forever and /dev/zero ran out of memory: the library checks as the CLI."""
    import os

    if kind == "fifo":
        path = tmp_path / "state.fifo"
        os.mkfifo(path)
    else:
        path = "/dev/zero"
    with pytest.raises(FtcalError, match="not a regular file"):
        LiveCalibrator(noise_std=NOISE, state_path=path)


@pytest.mark.parametrize("static", ["False", "yes", 2, 0.5, [True]])
def test_static_must_be_a_bool(static):
    """step(static='False') counted as static (a non-empty string is true); run() with text likewise."""
    live = LiveCalibrator(noise_std=NOISE)
    with pytest.raises(FtcalError, match="static must be"):
        live.step(0.0, wrench=np.zeros(6), gravity=DOWN, static=static)
    with pytest.raises(FtcalError, match="static must be"):
        live.run([0.0], wrench=np.zeros((1, 6)), gravity=[DOWN], static=np.array([str(static)]))
    assert live.counters["samples"] == 0
    assert live.step(0.0, wrench=np.zeros(6), gravity=DOWN, static=np.bool_(False)).static is False
    assert bool(live.run([0.1, 0.2], wrench=np.zeros((2, 6)), gravity=[DOWN, DOWN], static=[1, 0]).static[0])
