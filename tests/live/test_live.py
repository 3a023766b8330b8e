"""The live calibrator against simulated truth (ftcal.sim.live_scenario) and against the offline estimators.

Every reference number is the simulation's truth, a physical scale (the noise level the simulation
draws, the contact force), or an independent estimator run on the same recording (the offline
random-walk smoother of ``ftcal payload --bias-drift random-walk``, the batch ``ftcal payload``).
"""

from __future__ import annotations

import dataclasses
import json
import subprocess
import sys
import warnings

import numpy as np
import pytest

from ftcal.live import LiveCalibrator
from ftcal.payload.kinematics import Kinematics
from ftcal.payload.parameters import PayloadParameters
from ftcal.payload.tables import PayloadRecording, identify_recording
from ftcal.runtime.errors import FtcalError
from ftcal.sim.live_scenario import LiveScenario, Tool, simulate_live

NOISE = np.r_[np.full(3, 0.05), np.full(3, 0.004)]


def tool_payload(tool: Tool, noise=NOISE) -> PayloadParameters:
    """A payload file's content for a known tool (bias unknown: zero)."""
    return PayloadParameters(tool.mass, np.asarray(tool.com), np.zeros(3), np.zeros(3), 9.81,
                             fit={"residual_rms": noise})


def run_blocks(live: LiveCalibrator, rec, block: int = 20_000, events=None):
    """Replay a recording in blocks; ``events`` maps a sample index to a call made before it."""
    events = events or {}
    cuts = sorted(set(range(0, rec.time.size, block)) | set(events) | {rec.time.size})
    parts = []
    for a, b in zip(cuts[:-1], cuts[1:]):
        if a in events:
            events[a](live)
        parts.append(live.run(rec.time[a:b], wrench=rec.wrench[a:b], quaternion=rec.quaternion[a:b]))
    stack = {k: np.concatenate([getattr(p, k) for p in parts]) for k in
             ("bias", "bias_std", "compensated", "static", "updated", "flags", "chi2")}
    stack["events"] = [e for p in parts for e in p.events]
    return stack


def test_blocks_compute_what_single_samples_compute():
    s = LiveScenario(duration=6.0, rate=400.0, hold_s=1.5, move_s=0.5, contacts=((2.2, 0.6, 10.0),), seed=3)
    rec = simulate_live(s)
    tools = {"gripper": tool_payload(s.tools["gripper"])}
    block = run_blocks(LiveCalibrator(tools=tools, tool="gripper", walk_std=[3, 3, 3, .3, .3, .3]), rec)
    live = LiveCalibrator(tools=tools, tool="gripper", walk_std=[3, 3, 3, .3, .3, .3])
    steps = [live.step(t, wrench=w, quaternion=q) for t, w, q in zip(rec.time, rec.wrench, rec.quaternion)]
    assert block["updated"].any() and (~block["updated"]).any() and np.any(block["flags"])
    np.testing.assert_array_equal(block["updated"], [s.updated for s in steps])
    np.testing.assert_array_equal(block["static"], [s.static for s in steps])
    np.testing.assert_allclose(block["bias"], [s.bias for s in steps], rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(block["bias_std"], [s.bias_std for s in steps], rtol=1e-9)
    np.testing.assert_allclose(block["compensated"], [s.compensated for s in steps], rtol=1e-9, atol=1e-12)
    from ftcal.live.health import names_of

    assert [set(names_of(int(f))) for f in block["flags"]] == [set(s.flags) for s in steps]


@pytest.fixture(scope="module")
def drifting():
    """Identify the tool offline on one recording (payload file content), run live on another."""
    base = LiveScenario(duration=600.0, rate=100.0, hold_s=6.0, move_s=1.5, walk=(3.0, 0.3), ramp=(20.0, 1.0))
    first = simulate_live(dataclasses.replace(base, seed=11))
    offline_a = offline_fit(first)
    payload = PayloadParameters.from_fit(offline_a.fit, gravity=9.81, frame=None, reaction=False,
                                         wrench_columns=("Fx", "Fy", "Fz", "Tx", "Ty", "Tz"),
                                         drift=offline_a.drift)
    rec = simulate_live(dataclasses.replace(base, seed=12))
    return payload, rec, offline_fit(rec)


def offline_fit(rec):
    """``ftcal payload --bias-drift random-walk`` on the recording's static holds."""
    keep = rec.holding
    recording = PayloadRecording(rec.wrench[keep], Kinematics(rec.gravity[keep]), np.zeros(keep.sum(), int),
                                 rec.time[keep], None)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return identify_recording(recording, bias_drift="random-walk", time_column="time", cross_validate=False)


def test_online_bias_tracks_drift_nearly_as_well_as_the_offline_smoother(drifting):
    payload, rec, offline = drifting
    live = LiveCalibrator(tools={"tool": payload}, tool="tool")
    live.retare()  # a new session: the bias is unknown
    out = run_blocks(live, rec)
    # Compared from the first static sample on: before it the bias is unknown (and its std says so).
    known = np.arange(rec.time.size) >= np.argmax(out["updated"])
    assert known.mean() > 0.99 and out["bias_std"][~known].min() > 100 * NOISE.max()
    online_rms = np.sqrt(np.mean((out["bias"] - rec.bias)[known] ** 2, axis=0))
    knots = offline.drift
    smoothed = np.column_stack([np.interp(rec.time, knots.knot_times, knots.knot_bias[:, j]) for j in range(6)])
    smoother_rms = np.sqrt(np.mean((smoothed - rec.bias)[known] ** 2, axis=0))
    untracked = rec.bias - rec.bias[known][0]  # the bias held at a perfect tare on the same sample
    untracked_rms = np.sqrt(np.mean(untracked[known] ** 2, axis=0))
    assert np.all(online_rms <= 1.5 * smoother_rms), (online_rms, smoother_rms)
    assert np.all(untracked_rms >= 5.0 * online_rms), (untracked_rms, online_rms)


def test_a_held_contact_is_flagged_and_not_absorbed():
    s = LiveScenario(duration=120.0, rate=500.0, hold_s=12.0, move_s=2.0, contacts=((44.0, 5.0, 10.0),), seed=5)
    rec = simulate_live(s)  # the contact lies inside the hold from 42 s to 54 s
    assert rec.holding[(rec.time >= 44.0) & (rec.time < 49.0)].all()
    live = LiveCalibrator(tools={"gripper": tool_payload(s.tools["gripper"])}, tool="gripper",
                          walk_std=[3, 3, 3, .3, .3, .3])
    live.retare()
    out = run_blocks(live, rec)
    from ftcal.live.health import BIT

    pressing = np.linalg.norm(rec.contact[:, :3], axis=1) >= 5.0
    assert pressing.sum() >= 0.9 * 5.0 * s.rate
    assert np.mean(out["flags"][pressing] & BIT["contact"] != 0) > 0.99
    assert np.mean(out["flags"][pressing] & BIT["unexplained"] != 0) > 0.85  # after its 0.5 s
    window = (rec.time >= 43.9) & (rec.time <= 49.1)
    moved = np.linalg.norm(out["bias"][window, :3] - out["bias"][window][0, :3], axis=1).max()
    true_moved = np.linalg.norm(rec.bias[window, :3] - rec.bias[window][0, :3], axis=1).max()
    assert moved - true_moved < 0.1 * 10.0
    raised = [e for e in out["events"] if e[1] == "contact" and e[2] == "raised" and 43.9 <= e[0] <= 44.2]
    assert raised and "chi2" in raised[0][3]


def test_retare_keeps_the_tool_in_every_pose():
    s = LiveScenario(duration=80.0, rate=250.0, hold_s=4.0, move_s=1.0, walk=(0.0, 0.0), ramp=(0.0, 0.0), seed=7)
    rec = simulate_live(s)
    at = int(np.searchsorted(rec.time, 6.0))  # in the second hold
    kept = LiveCalibrator(tools={"gripper": tool_payload(s.tools["gripper"])}, tool="gripper",
                          initial_bias=np.zeros(6), initial_bias_std=np.r_[np.full(3, 1e-3), np.full(3, 1e-4)])
    out = run_blocks(kept, rec, events={at: LiveCalibrator.retare})
    naive = LiveCalibrator(noise_std=NOISE, initial_bias=np.zeros(6), walk_std=np.zeros(6),
                           initial_bias_std=np.r_[np.full(3, 1e-3), np.full(3, 1e-4)])  # a tare without the tool
    plain = run_blocks(naive, rec, events={at: LiveCalibrator.retare})
    later = rec.holding & (rec.time > 10.0) & out["static"]
    ratios, naive_ratios = [], []
    for pose in np.unique(rec.pose[later]):
        rows = later & (rec.pose == pose)
        ratios.append(np.sqrt(np.mean(out["compensated"][rows] ** 2, axis=0)) / NOISE)
        naive_ratios.append(np.sqrt(np.mean(plain["compensated"][rows] ** 2, axis=0)) / NOISE)
    assert len(ratios) >= 10
    assert np.max(ratios) < 1.3  # noise level: the RMS of the compensated wrench is the noise's
    assert np.max(naive_ratios) > 20.0  # what a tare that forgets the tool leaves


def test_a_tool_identified_in_place_matches_batch_payload(tmp_path):
    s = LiveScenario(duration=60.0, rate=200.0, hold_s=3.0, move_s=1.5, walk=(0.0, 0.0), ramp=(0.0, 0.0),
                     tools={"drill": Tool(2.1, (0.02, 0.01, 0.09))}, seed=9)
    rec = simulate_live(s)
    live = LiveCalibrator(noise_std=NOISE)
    live.start_identification("drill")
    run_blocks(live, rec)
    payload = live.finish_identification(save_to=tmp_path / "drill.json")
    assert live.tool == "drill"
    table = tmp_path / "rec.parquet"
    rec.frame().to_parquet(table)
    batch_path = tmp_path / "batch.json"
    subprocess.run([sys.executable, "-m", "ftcal", "payload", str(table), "--orientation", "qx,qy,qz,qw",
                    "--inputs", "Fx,Fy,Fz,Tx,Ty,Tz", "-o", str(batch_path)], check=True, capture_output=True)
    batch = json.loads(batch_path.read_text())
    assert abs(payload.mass - batch["mass"]) <= batch["stderr"]["mass"]
    assert np.all(np.abs(payload.com - batch["com"]) <= np.asarray(batch["stderr"]["com"]))
    assert abs(payload.mass - 2.1) <= 3.0 * payload.stderr["mass"]
    assert np.all(np.abs(payload.com - [0.02, 0.01, 0.09]) <= 3.0 * payload.stderr["com"])
    saved = json.loads((tmp_path / "drill.json").read_text())
    assert saved["mass"] == payload.mass


def test_state_resumes_after_a_restart(tmp_path):
    s = LiveScenario(duration=30.0, rate=200.0, seed=4)
    rec = simulate_live(s)
    half = rec.time.size // 2
    tools = {"gripper": tool_payload(s.tools["gripper"])}
    whole = LiveCalibrator(tools=tools, tool="gripper")
    ref = run_blocks(whole, rec)
    state = tmp_path / "state.json"
    first = LiveCalibrator(tools=tools, tool="gripper", state_path=state)
    first.run(rec.time[:half], wrench=rec.wrench[:half], quaternion=rec.quaternion[:half])
    first.save_state()
    second = LiveCalibrator(tools=tools, state_path=state)  # mounts the saved tool
    assert second.tool == "gripper" and second.counters["samples"] == half
    np.testing.assert_array_equal(second.bias, first.bias)
    with pytest.raises(FtcalError, match="increasing"):
        second.run(rec.time[:1], wrench=rec.wrench[:1], quaternion=rec.quaternion[:1])
    rest = second.run(rec.time[half:], wrench=rec.wrench[half:], quaternion=rec.quaternion[half:])
    # The motion test restarts without history, so the first samples are not static; the bias agrees soon after.
    np.testing.assert_allclose(rest.bias[-1], ref["bias"][-1], atol=1e-3)


def test_switching_tools_is_instant_and_logged():
    s = LiveScenario(duration=40.0, rate=200.0, hold_s=4.0, move_s=1.0, swaps=((21.0, "drill"),), seed=8)
    rec = simulate_live(s)  # the swap happens 1 s into the hold from 20 s to 24 s
    tools = {name: tool_payload(tool) for name, tool in s.tools.items()}
    live = LiveCalibrator(tools=tools, tool="gripper", walk_std=[3, 3, 3, .3, .3, .3])
    at = int(np.searchsorted(rec.time, 21.0))
    out = run_blocks(live, rec, events={at: lambda c: c.switch_tool("drill")})
    assert any(e[1] == "tool" and "'gripper' -> 'drill'" in e[3] for e in live.events)
    after = slice(at, at + 100)
    assert np.sqrt(np.mean(out["compensated"][after, :3] ** 2)) < 3 * NOISE[0]
    assert not np.any(out["flags"][after])


def test_stuck_channel_and_bad_input_are_reported():
    s = LiveScenario(duration=20.0, rate=200.0, seed=2)
    rec = simulate_live(s)
    wrench = rec.wrench.copy()
    wrench[1000:1500, 2] = wrench[1000, 2]  # Fz freezes for 2.5 s while the others move
    live = LiveCalibrator(tools={"gripper": tool_payload(s.tools["gripper"])}, tool="gripper")
    r = live.run(rec.time, wrench=wrench, quaternion=rec.quaternion)
    from ftcal.live.health import BIT

    stuck = (r.flags & BIT["stuck"]) != 0
    assert stuck[1199:1500].all() and not stuck[:1199].any() and not stuck[1500:].any()
    assert any(e[1] == "stuck" and "Fz" in e[3] for e in r.events)
    with pytest.raises(FtcalError, match="non-finite"):
        live.run(rec.time[-1:] + 1.0, wrench=np.full((1, 6), np.nan), quaternion=rec.quaternion[-1:])
    with pytest.raises(FtcalError, match="exactly one"):
        live.run(rec.time[-1:] + 1.0, wrench=rec.wrench[-1:])


def test_raw_channels_through_a_model_and_its_temperature_range():
    from ftcal.core.dataset import Dataset
    from ftcal.core.model import CalibrationModel
    from ftcal.live.health import BIT

    rng = np.random.default_rng(21)
    mix = np.eye(6) + 0.05 * rng.normal(size=(6, 6))  # the gauges see a mix of the six axes
    wrench = rng.uniform(-20, 20, size=(3000, 6))
    temperature = rng.uniform(25.0, 40.0, size=3000)
    raw = np.column_stack([wrench @ mix.T + 0.01 * (temperature[:, None] - 30.0), temperature])
    model = CalibrationModel(degree=1).fit(Dataset.from_arrays(raw, wrench))
    s = LiveScenario(duration=10.0, rate=200.0, seed=3)
    rec = simulate_live(s)
    hot = np.where(rec.time < 6.0, 30.0, 50.0)  # beyond the 25-40 °C the model saw, from 6 s on
    u = np.column_stack([rec.wrench @ mix.T + 0.01 * (hot[:, None] - 30.0), hot])
    live = LiveCalibrator(model, tools={"gripper": tool_payload(s.tools["gripper"])}, tool="gripper")
    r = live.run(rec.time, raw=u, quaternion=rec.quaternion)
    # Inside its range the affine model recovers the wrench exactly (the simulation is affine in the raw channels).
    np.testing.assert_allclose(r.calibrated[rec.time < 6.0], rec.wrench[rec.time < 6.0], atol=1e-6)
    flagged = (r.flags & BIT["temperature"]) != 0
    assert flagged[rec.time >= 6.0].all() and not flagged[rec.time < 6.0].any()
    assert any(e[1] == "temperature" and "50" in e[3] for e in r.events)


def test_the_docstring_example_runs():
    import doctest

    import ftcal.live.calibrator as module

    result = doctest.testmod(module, optionflags=doctest.NORMALIZE_WHITESPACE)
    assert result.attempted > 0 and result.failed == 0


def _affine_model_and_raw(rec, seed=21):
    """A degree-1 model of 6 mixed gauges + temperature, and the raw channels of ``rec`` through that mix."""
    from ftcal.core.dataset import Dataset
    from ftcal.core.model import CalibrationModel

    rng = np.random.default_rng(seed)
    mix = np.eye(6) + 0.05 * rng.normal(size=(6, 6))
    wrench = rng.uniform(-20, 20, size=(3000, 6))
    temperature = rng.uniform(25.0, 40.0, size=3000)
    model = CalibrationModel(degree=1).fit(Dataset.from_arrays(
        np.column_stack([wrench @ mix.T + 0.01 * (temperature[:, None] - 30.0), temperature]), wrench))
    hot = np.where(rec.time < 6.0, 30.0, 50.0)
    return model, np.column_stack([rec.wrench @ mix.T + 0.01 * (hot[:, None] - 30.0), hot])


@pytest.mark.parametrize("source", ["gravity", "imu", "gravity+joints"])
def test_single_samples_take_the_same_path_as_blocks_with_a_model_and_bad_channels(source):
    """The per-sample path (plain floats) against the block path (prefix scans): a model with a temperature
    input that leaves its range, a gauge that freezes, every gravity source, and step() and run() mixed."""
    from ftcal.live.health import names_of

    s = LiveScenario(duration=10.0, rate=200.0, hold_s=1.5, move_s=0.5, contacts=((3.2, 0.6, 10.0),), seed=6)
    rec = simulate_live(s)
    model, raw = _affine_model_and_raw(rec)
    raw[900:1400, 1] = raw[900, 1]  # one gauge freezes for 2.5 s while the others move
    joints = np.cumsum(np.abs(np.diff(rec.quaternion, axis=0, prepend=rec.quaternion[:1])), axis=0)
    if source == "gravity":
        kw = {"gravity": rec.gravity}
    elif source == "imu":
        kw = {"imu": -rec.gravity}
    else:
        kw = {"gravity": rec.gravity, "joints": joints}
    tools = {"gripper": tool_payload(s.tools["gripper"])}
    make = lambda: LiveCalibrator(model, tools=tools, tool="gripper", walk_std=[3, 3, 3, .3, .3, .3])  # noqa: E731
    block = make().run(rec.time, raw=raw, **kw)
    live = make()
    steps, k = [], 0
    while k < rec.time.size:  # single samples, with a block of 37 now and then
        if k % 500 == 250:
            r = live.run(rec.time[k:k + 37], raw=raw[k:k + 37], **{n: v[k:k + 37] for n, v in kw.items()})
            steps += [(r.bias[i], r.bias_std[i], r.compensated[i], r.calibrated[i], bool(r.updated[i]),
                       bool(r.static[i]), set(names_of(int(r.flags[i])))) for i in range(r.n_samples)]
            k += 37
            continue
        one = live.step(rec.time[k], raw=raw[k], **{n: v[k] for n, v in kw.items()})
        steps.append((one.bias, one.bias_std, one.compensated, one.calibrated, one.updated, one.static,
                      set(one.flags)))
        k += 1
    flags = [set(names_of(int(f))) for f in block.flags]
    assert any("stuck" in f for f in flags) and any("temperature" in f for f in flags)
    assert block.updated.any() and not block.updated.all()
    np.testing.assert_array_equal(block.static, [x[5] for x in steps])
    np.testing.assert_array_equal(block.updated, [x[4] for x in steps])
    np.testing.assert_allclose(block.calibrated, [x[3] for x in steps], rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(block.bias, [x[0] for x in steps], rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(block.bias_std, [x[1] for x in steps], rtol=1e-9)
    np.testing.assert_allclose(block.compensated, [x[2] for x in steps], rtol=1e-9, atol=1e-9)
    assert flags == [x[6] for x in steps]
    ref = make()
    ref.run(rec.time, raw=raw, **kw)
    assert live.counters == ref.counters


def test_single_samples_reject_bad_input_like_blocks():
    live = LiveCalibrator(noise_std=NOISE)
    live.step(0.0, wrench=np.zeros(6), gravity=[0, 0, -9.81])
    with pytest.raises(FtcalError, match="non-finite"):
        live.step(0.1, wrench=[0, 0, np.inf, 0, 0, 0], gravity=[0, 0, -9.81])
    with pytest.raises(FtcalError, match="unit length"):
        live.step(0.1, wrench=np.zeros(6), quaternion=[0, 0, 0, 2.0])
    with pytest.raises(FtcalError, match="increasing"):
        live.step(0.0, wrench=np.zeros(6), gravity=[0, 0, -9.81])
    with pytest.raises(FtcalError, match="shape"):
        live.step(0.1, wrench=np.zeros(5), gravity=[0, 0, -9.81])
    assert live.counters["samples"] == 1 and live.last_time == 0.0


def test_the_walk_and_noise_that_payload_identifies_reach_the_live_tracker(tmp_path):
    """Offline ``payload --bias-drift random-walk`` on a recording whose walk and noise are known (the simulation's):
    the payload file stores the variances it identified, and a live calibrator built from that file uses them."""
    from ftcal.files.payload_json import load_payload, save_payload

    s = LiveScenario(duration=1800.0, rate=20.0, hold_s=8.0, move_s=2.0, walk=(3.0, 0.3), ramp=(0.0, 0.0), seed=17)
    rec = simulate_live(s)
    fit = offline_fit(rec)
    payload = PayloadParameters.from_fit(fit.fit, gravity=9.81, frame=None, reaction=False,
                                         wrench_columns=("Fx", "Fy", "Fz", "Tx", "Ty", "Tz"), drift=fit.drift)
    save_payload(payload, tmp_path / "tool.json")
    doc = json.loads((tmp_path / "tool.json").read_text())
    walk = np.sqrt(doc["drift"]["random_walk"]["walk_variance"])  # per √h
    noise = np.sqrt(doc["drift"]["random_walk"]["noise_variance"])  # per sample
    truth_walk, truth_noise = np.repeat(s.walk, 3), np.repeat(s.noise, 3)
    assert np.all((walk > truth_walk / 2) & (walk < 2 * truth_walk)), walk
    # Per block (1.4 s) the walk moves the bias about 6x the noise of a block mean: the noise is identified
    # far less precisely than the walk.
    assert np.all((noise > truth_noise / 2) & (noise < 2 * truth_noise)), noise
    np.testing.assert_allclose(walk ** 2, fit.drift.walk_variance, rtol=1e-12)  # what the identification returned
    live = LiveCalibrator(tools={"tool": load_payload(tmp_path / "tool.json")}, tool="tool")
    # The tracker's walk: the stored one less the share a fitted wander explains (white noise here: a little).
    tracked = np.sqrt(live.walk_variance * 3600.0)
    assert np.all(tracked <= walk * (1 + 1e-12)) and np.all((tracked > truth_walk / 2) & (tracked < 2 * truth_walk))
    # The tracker's noise is what the data show per sample within the holds (the variogram's white + wander;
    # here white noise, the walk within a hold fitted apart).
    sample = np.sqrt(doc["drift"]["random_walk"]["sample_variance"])
    assert np.all((sample > 0.75 * truth_noise) & (sample < 1.33 * truth_noise)), sample
    np.testing.assert_allclose(live.noise_std, sample, rtol=1e-12)
    overridden = LiveCalibrator(tools={"tool": load_payload(tmp_path / "tool.json")}, tool="tool",
                                walk_std=np.full(6, 2.0), noise_std=np.full(6, 0.1))
    np.testing.assert_allclose(overridden.walk_variance * 3600.0, 4.0)
    np.testing.assert_allclose(overridden.noise_std, 0.1)
