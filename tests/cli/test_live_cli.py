"""``ftcal live --replay``: the table it writes, scripted events, the state file, bad input, SIGTERM."""

from __future__ import annotations

import json
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from ftcal.files.payload_json import save_payload
from ftcal.payload.parameters import PayloadParameters
from ftcal.sim.live_scenario import LiveScenario, simulate_live

FTCAL = str(Path(sys.executable).with_name("ftcal"))
NOISE = np.r_[np.full(3, 0.05), np.full(3, 0.004)]


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    root = tmp_path_factory.mktemp("live")
    s = LiveScenario(duration=40.0, rate=200.0, hold_s=4.0, move_s=1.0, swaps=((21.0, "drill"),),
                     contacts=((10.5, 2.0, 10.0),), seed=6)
    rec = simulate_live(s)
    rec.frame().to_parquet(root / "rec.parquet")
    for name, tool in s.tools.items():
        payload = PayloadParameters(tool.mass, np.asarray(tool.com), np.zeros(3), np.zeros(3), 9.81,
                                    stderr={"mass": 0.001, "com": np.full(3, 1e-4), "force_bias": np.full(3, 0.01),
                                            "torque_bias": np.full(3, 0.001)},
                                    fit={"n_samples": 100, "residual_rms": NOISE, "condition_number": 1.0,
                                         "wrench_columns": ["Fx", "Fy", "Fz", "Tx", "Ty", "Tz"]})
        save_payload(payload, root / f"{name}.json")
    return root, rec


def ftcal(*args, cwd):
    return subprocess.run([FTCAL, *args], cwd=cwd, capture_output=True, text=True, timeout=300)


BASE = ("live", "--replay", "rec.parquet", "--orientation", "qx,qy,qz,qw", "--tool", "gripper=gripper.json",
        "--tool", "drill=drill.json")


def test_replay_writes_the_live_columns_and_runs_the_script(files):
    root, rec = files
    done = ftcal(*BASE, "--switch-tool", "21:drill", "--retare-at", "30", "--state", "state.json",
                 "-o", "out.parquet", cwd=root)
    assert done.returncode == 0, done.stderr
    out = pd.read_parquet(root / "out.parquet")
    assert len(out) == rec.time.size
    np.testing.assert_array_equal(out["time"], rec.time)
    assert list(out["tool"].unique()) == ["gripper", "drill"]
    assert out["tool"][rec.time >= 21.0].eq("drill").all() and out["tool"][rec.time < 21.0].eq("gripper").all()
    # Compensated = calibrated (here the wrench itself) − tool − bias: check against the truth where static.
    quiet = out["static"].to_numpy() & ~np.any(rec.contact != 0, axis=1) & (rec.time > 2.0)
    contact = out[["Fx", "Fy", "Fz"]].to_numpy()
    assert np.sqrt(np.mean(contact[quiet] ** 2)) < 1.5 * NOISE[0]
    np.testing.assert_array_equal(out[["calibrated_Fx", "calibrated_Tz"]].to_numpy(), rec.wrench[:, [0, 5]])
    pressing = np.linalg.norm(rec.contact[:, :3], axis=1) > 5.0
    assert out["flag_names"][pressing].str.contains("contact").mean() > 0.99
    state = json.loads((root / "state.json").read_text())
    assert state["tool"] == "drill" and state["counters"]["retares"] == 1 and state["counters"]["samples"] == len(out)
    assert "contact" in done.stdout and "wrote out.parquet" in done.stdout


@pytest.mark.parametrize("args, message", [
    (("--switch-tool", "5:hammer"), "no tool 'hammer'"),
    (("--inputs", "Fx,Fy,Fz,Tx,Ty,nope"), "nope"),
    (("--mount", "hammer"), "--mount hammer"),
    (("--walk-std", "1,2,3"), "--walk-std"),
])
def test_bad_input_is_one_line_and_leaves_no_output(files, args, message):
    root, _ = files
    done = ftcal(*BASE, *args, "-o", "bad.parquet", cwd=root)
    assert done.returncode == 2 and message in done.stderr and len(done.stderr.strip().splitlines()) == 1, done.stderr
    assert not (root / "bad.parquet").exists() and not list(root.glob("*.tmp*"))


def test_sigterm_saves_the_state_and_leaves_no_output(files):
    root, rec = files
    proc = subprocess.Popen([FTCAL, *BASE, "--realtime", "--state", "term.json", "-o", "term.parquet"], cwd=root,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    # Start-up (seconds of wall time on a loaded machine): until the output's temporary file exists; then a few
    # seconds of the 40 s real-time replay.
    deadline = time.monotonic() + 120.0
    while not list(root.glob(".term.parquet.*.tmp")) and proc.poll() is None and time.monotonic() < deadline:
        time.sleep(0.1)
    time.sleep(3.0)
    assert proc.poll() is None
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 143, err
    state = json.loads((root / "term.json").read_text())
    assert 0 < state["counters"]["samples"] < rec.time.size
    assert not (root / "term.parquet").exists()


def test_inputs_name_the_wrench_or_with_model_the_raw_channels_and_wrench_is_the_old_spelling(files):
    """--inputs is the wrench without --model and the model's raw channels (in its input order) with it;
    --wrench, the old spelling, reads the same with one notice. An identity calibration (fitted on
    raw = wrench) fed the wrench under other column names gives the wrench back."""
    from ftcal import fit as fit_model

    root, rec = files
    axes = ["Fx", "Fy", "Fz", "Tx", "Ty", "Tz"]
    frame = pd.read_parquet(root / "rec.parquet")
    for i, axis in enumerate(axes):
        frame[f"raw{i + 1}"] = frame[axis]
    frame.to_parquet(root / "raw.parquet")
    rng = np.random.default_rng(0)
    u = rng.uniform(-50.0, 50.0, size=(200, 6))
    fit_model(pd.DataFrame(np.c_[u, u], columns=[*(f"u{i}" for i in range(1, 7)), *axes]),
              inputs=[f"u{i}" for i in range(1, 7)], outputs=axes, output=root / "identity.json")
    base = ("live", "--replay", "raw.parquet", "--orientation", "qx,qy,qz,qw", "--tool", "gripper=gripper.json")
    done = ftcal(*base, "--inputs", ",".join(axes), "-o", "new.parquet", cwd=root)
    assert done.returncode == 0 and "notice" not in done.stderr, done.stderr
    old = ftcal(*base, "--wrench", ",".join(axes), "-o", "old.parquet", cwd=root)
    assert old.returncode == 0, old.stderr
    assert [line for line in old.stderr.splitlines() if line.startswith("notice:")] == [
        "notice: --wrench is now --inputs (the old spelling still works)"]
    pd.testing.assert_frame_equal(pd.read_parquet(root / "old.parquet"), pd.read_parquet(root / "new.parquet"))
    raw = ftcal(*base, "--model", "identity.json", "--inputs", ",".join(f"raw{i}" for i in range(1, 7)),
                    "-o", "raw.out.parquet", cwd=root)
    assert raw.returncode == 0, raw.stderr
    calibrated = pd.read_parquet(root / "raw.out.parquet")[[f"calibrated_{a}" for a in axes]].to_numpy()
    np.testing.assert_allclose(calibrated, rec.wrench, atol=1e-6)
    short = ftcal(*base, "--model", "identity.json", "--inputs", "raw1,raw2", "-o", "short.parquet", cwd=root)
    assert short.returncode == 2 and len(short.stderr.strip().splitlines()) == 1, short.stderr
    assert "name one column for each" in short.stderr and not (root / "short.parquet").exists()


def test_resume_from_an_existing_state_goes_on_and_saves_it(files):
    """The state file is the session's own: a second replay resumes from it and writes it back (it refused to save
    it, as if it were an input, after replaying everything)."""
    root, rec = files
    frame = rec.frame()
    half = rec.time.size // 2
    frame.iloc[:half].to_parquet(root / "first.parquet")
    frame.iloc[half:].to_parquet(root / "second.parquet")
    run = ("live", "--orientation", "qx,qy,qz,qw", "--tool", "gripper=gripper.json", "--state", "resume.json")
    first = ftcal(*run, "--replay", "first.parquet", "-o", "first_out.parquet", cwd=root)
    assert first.returncode == 0, first.stderr
    second = ftcal(*run, "--replay", "second.parquet", "-o", "second_out.parquet", cwd=root)
    assert second.returncode == 0, second.stderr
    state = json.loads((root / "resume.json").read_text())
    assert state["counters"]["samples"] == rec.time.size and state["time"] == rec.time[-1]
    whole = ftcal(*run[:-2], "--replay", "rec.parquet", "-o", "whole.parquet", cwd=root)
    assert whole.returncode == 0, whole.stderr
    # The resumed session's bias at its end is the one-session replay's (the motion test restarts without history).
    np.testing.assert_allclose(state["bias"][:3], pd.read_parquet(root / "whole.parquet")[
        ["bias_Fx", "bias_Fy", "bias_Fz"]].to_numpy()[-1], atol=0.05)


def test_a_negative_bias_is_taken(files):
    root, _ = files
    done = ftcal(*BASE, "--bias", "-1.5,2,-0.25,0,0,-0.01", "-o", "biased.parquet", cwd=root)
    assert done.returncode == 0, done.stderr
    out = pd.read_parquet(root / "biased.parquet")
    assert out["bias_Fx"].iloc[0] == pytest.approx(-1.5, abs=0.2)


@pytest.mark.parametrize("args, message", [
    (("--listen", "tcp/127.0.0.1:7447"), "--listen go with --zenoh"),
    (("--duration", "3"), "--duration go with --zenoh"),
    (("--keys", "rmw_zenoh", "--domain-id", "3"), "--keys, --domain-id go with --zenoh"),
    (("--imu-topic", "/imu"), "--imu-topic applies to --zenoh and to ROS bags"),
])
def test_replay_refuses_what_only_zenoh_reads(files, args, message):
    root, _ = files
    done = ftcal(*BASE, *args, "-o", "zenoh_only.parquet", cwd=root)
    assert done.returncode == 2 and message in done.stderr and len(done.stderr.strip().splitlines()) == 1, done.stderr
    assert not (root / "zenoh_only.parquet").exists()


@pytest.mark.parametrize("args, message", [
    (("--zenoh", "--keys", "rmw_zenoh", "--domain-id", "233"), "--domain-id 233: ROS 2 domain ids go from 0 to 232"),
    (("--zenoh", "--domain-id", "3"), "--domain-id goes with --keys rmw_zenoh"),
    (("--zenoh", "--rt-priority", "0"), "--rt-priority 0: SCHED_FIFO priorities go from 1 to 99"),
    (("--zenoh", "--joints-topic", "/joint_states"), "--joints-topic and --urdf go together"),
    (("--zenoh", "--imu-topic", "/imu", "--joints-topic", "/joint_states", "--urdf", "robot.urdf"),
     "give one gravity source: --imu-topic, or --joints-topic with --urdf"),
    (("--replay", "bag", "--model", "cal.json", "-o", "out.parquet"), "--model with a bag"),
    (("--replay", "bag", "--drop-incomplete", "--orientation", "qx,qy,qz,qw", "-o", "out.parquet"),
     "--drop-incomplete applies to tables"),
])
def test_the_steps_refusals_name_the_flags(tmp_path, monkeypatch, capsys, args, message):
    # The step (ftcal.workflow.live) names its parameters; the command prints them as its flags.
    from ftcal.cli import main

    monkeypatch.chdir(tmp_path)
    (tmp_path / "bag").mkdir()  # a folder: a ROS 2 bag by its kind, refused before it is read
    (tmp_path / "cal.json").write_text("{}")
    (tmp_path / "robot.urdf").write_text("<robot/>")
    assert main(["live", *args]) == 2
    err = capsys.readouterr().err
    assert message in err and len(err.strip().splitlines()) == 1, err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bag", "cal.json", "robot.urdf"]


def test_a_time_column_in_nanoseconds_is_refused(files):
    root, rec = files
    frame = rec.frame()
    frame["time"] = (frame["time"] * 1e9).round()
    frame.to_parquet(root / "ns.parquet")
    done = ftcal("live", "--replay", "ns.parquet", "--orientation", "qx,qy,qz,qw", "--tool", "gripper=gripper.json",
                 "-o", "ns_out.parquet", cwd=root)
    assert done.returncode == 2 and "looks like nanoseconds" in done.stderr, done.stderr
    assert len(done.stderr.strip().splitlines()) == 1


def test_a_lock_out_and_its_re_acquisition_are_said(tmp_path):
    """A sensor drifting 3x faster than identified (tests/helpers/live_truth.py): the replay's summary says the tracker was
    locked out and adapted (or re-acquired the bias), with the times (it said only 'contact' on most samples)."""
    import pandas as pd

    import live_truth as truth

    ident, oper = truth.CASES["walk 3x"]
    save_payload(truth.identify(ident), tmp_path / "tool.json")
    rec, _ = truth.operation(oper, duration=90.0)
    table = {"time": rec["time"], **{c: rec["quaternion"][:, i] for i, c in enumerate(("qx", "qy", "qz", "qw"))},
             **{c: rec["wrench"][:, i] for i, c in enumerate(("Fx", "Fy", "Fz", "Tx", "Ty", "Tz"))}}
    pd.DataFrame(table).to_parquet(tmp_path / "drift.parquet")
    done = ftcal("live", "--replay", "drift.parquet", "--orientation", "qx,qy,qz,qw", "--inputs", "Fx,Fy,Fz,Tx,Ty,Tz",
                 "--tool", "tool=tool.json", "-o", "out.parquet", cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    # the lock-out is said; the walk is matched over the moves (an adaptation) or the bias re-acquired
    assert "tracker: " in done.stdout and "locked_out: no bias update" in done.stdout
    assert "re-acquisition" in done.stdout or "adaptation" in done.stdout
