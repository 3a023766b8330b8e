"""The noise the live tracker takes from a payload file is the noise it will see, and every path takes it alike.

Own truth generator (not ftcal's simulation): a sensor held still in twelve orientations, 20 s each at 100 Hz,
whose reading is the tool's gravity wrench + a constant bias + a slow walk + a first-order Gauss-Markov wander
(0.25 N, τ 2 s: what real gauges show) + white noise (0.02 N), quantised to 0.02 N. The random-walk identification
(``payload --bias-drift random-walk``) resolves the bias to 1-s blocks; its block-mean noise, scaled to one sample
as for white noise, is not what the gate will see per sample; the within-hold variogram is.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from ftcal.live import LiveCalibrator
from ftcal.live.c_runtime import runtime_parameters
from ftcal.payload.kinematics import Kinematics
from ftcal.payload.parameters import PayloadParameters
from ftcal.payload.tables import PayloadRecording, identify_recording

RATE, HOLD_S, HOLDS = 100.0, 20.0, 12
WANDER, TAU, WHITE, LSB = 0.25, 2.0, 0.02, 0.02
MASS, COM = 1.2, np.array([0.004, -0.003, 0.06])


def gauss_markov(rng, n, sigma, tau, dt):
    """Exact discretisation of a first-order Gauss-Markov process, stationary from the first sample."""
    phi = np.exp(-dt / tau)
    x = np.empty((n, 6))
    x[0] = rng.normal(size=6) * sigma
    kick = rng.normal(size=(n, 6)) * sigma * np.sqrt(1.0 - phi * phi)
    for k in range(1, n):
        x[k] = phi * x[k - 1] + kick[k]
    return x


def still_recording(seed=3, wander=WANDER):
    rng = np.random.default_rng(seed)
    per = int(HOLD_S * RATE)
    n = per * HOLDS
    directions = rng.normal(size=(HOLDS, 3))
    directions /= np.linalg.norm(directions, axis=1, keepdims=True)
    gravity = np.repeat(9.81 * directions, per, axis=0)
    time = np.arange(n) / RATE + np.repeat(np.arange(HOLDS) * 3.0, per)  # 3 s moves between holds, not recorded
    wrench = np.zeros((n, 6))
    wrench[:, :3] = MASS * gravity
    wrench[:, 3:] = np.cross(MASS * COM, gravity)
    scale = np.r_[np.ones(3), np.full(3, 0.1)]  # torques a tenth (N·m)
    walk = np.cumsum(rng.normal(size=(n, 6)) * 0.5 / np.sqrt(3600.0 * RATE), axis=0)  # 0.5 N/√h
    wrench += np.r_[1.0, -2.0, 0.5, 0.1, 0.05, -0.1] + scale * walk
    wrench += scale * (gauss_markov(rng, n, wander, TAU, 1.0 / RATE) + rng.normal(size=(n, 6)) * WHITE)
    wrench = np.round(wrench / (LSB * scale)) * (LSB * scale)
    return time, gravity, wrench


def identify(time, gravity, wrench):
    recording = PayloadRecording(wrench, Kinematics(gravity), np.zeros(len(time), int), time, None)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        fit = identify_recording(recording, bias_drift="random-walk", time_column="time", cross_validate=False)
    return PayloadParameters.from_fit(fit.fit, gravity=9.81, frame=None, reaction=False,
                                      wrench_columns=("Fx", "Fy", "Fz", "Tx", "Ty", "Tz"), drift=fit.drift)


@pytest.fixture(scope="module")
def identified():
    return identify(*still_recording())


def test_the_wander_is_told_from_the_walk(identified):
    """The walk between the holds' means grows with the gap, the wander's share stops after a few τ: the wander's
    low-frequency density 2 s² τ (what the tracker's update takes) comes out near the truth's, and the walk
    fitted beside it near the true 0.5 N/√h, while the block-level walk takes the wander for a walk."""
    drift = identified.drift
    scale = np.r_[np.ones(3), np.full(3, 0.1)]
    wander = np.sqrt(drift.wander_variance) / scale
    assert np.all((wander > 0.6 * WANDER) & (wander < 1.5 * WANDER)), wander
    density = 2.0 * drift.wander_variance * drift.wander_tau / scale ** 2
    truth = 2.0 * WANDER ** 2 * TAU
    assert np.all((density > truth / 4) & (density < 4 * truth)), density
    beside = np.sqrt(drift.hold_walk_variance) / scale
    assert np.all(beside < 3 * 0.5) and np.all(np.sqrt(drift.walk_variance) / scale > 3 * 0.5), beside
    live = LiveCalibrator(tools={"tool": identified}, tool="tool")
    np.testing.assert_allclose(live.wander_density, 2.0 * drift.wander_variance * drift.wander_tau, rtol=1e-12)


def test_white_noise_has_no_wander():
    """Without a wander the fit keeps white noise and the walk (χ² test at 0.999): no density, the plain filter."""
    drift = identify(*still_recording(wander=0.0)).drift
    assert np.all(drift.wander_variance == 0.0) and np.all(drift.wander_tau == 0.0), drift.wander_variance
    floor = WHITE ** 2 + LSB ** 2 / 12.0
    np.testing.assert_allclose(drift.sample_variance[:3], floor, rtol=0.25)


def test_a_file_without_the_walk_beside_the_wander_loads(identified, tmp_path):
    import json

    from ftcal.files.model_json import digest
    from ftcal.files.payload_json import load_payload, save_payload

    save_payload(identified, tmp_path / "new.json")
    doc = json.loads((tmp_path / "new.json").read_text())
    assert len(doc["drift"]["random_walk"]["hold_walk_variance"]) == 6
    del doc["drift"]["random_walk"]["hold_walk_variance"]
    doc["sha256"] = digest(doc)  # as a file written before the field
    (tmp_path / "old.json").write_text(json.dumps(doc))
    old = load_payload(tmp_path / "old.json")
    assert old.drift.hold_walk_variance is None
    # the older rule: the block-level walk less what the wander fakes over a block, floored at a hundredth
    drift = old.drift
    block, tau = drift.block_seconds, drift.wander_tau
    fake = np.where(tau > 0, 2.0 * drift.wander_variance * -np.expm1(-block / np.where(tau > 0, tau, 1.0)) / block, 0)
    expected = np.maximum(drift.walk_variance / 3600.0 - fake, 0.01 * drift.walk_variance / 3600.0)
    np.testing.assert_allclose(LiveCalibrator(tools={"tool": old}, tool="tool").walk_variance, expected, rtol=1e-12)


def test_the_stored_noise_holds_the_wander_within_a_hold(identified):
    drift = identified.drift
    truth = WANDER ** 2 + WHITE ** 2 + LSB ** 2 / 12.0  # per-sample variance of the reading about the bias
    force = np.sqrt(drift.sample_variance[:3])
    assert np.all(force > np.sqrt(0.6 * truth)) and np.all(force < np.sqrt(1.5 * truth)), force
    assert np.all((drift.wander_tau[:3] > TAU / 2.5) & (drift.wander_tau[:3] < 2.5 * TAU)), drift.wander_tau
    # The block-mean noise times the block's samples (exact for white noise; what the tracker used before) is
    # not the per-sample variance under a wander: 1-s blocks average a τ = 2 s wander only in part.
    assert np.any(np.abs(np.log(drift.noise_variance[:3] / truth)) > np.log(2.0)), drift.noise_variance
    assert drift.block_seconds == pytest.approx(1.0, rel=0.05)
    assert 0.5 * HOLD_S < drift.hold_seconds <= HOLD_S  # the blocks beside a move are left out
    live = LiveCalibrator(tools={"tool": identified}, tool="tool")
    np.testing.assert_allclose(live.noise_std ** 2, drift.sample_variance, rtol=1e-12)  # a square root and back


def test_the_c_runtime_starts_from_the_same_noise_and_walk(identified):
    """One rule for both: ``convert --to c-runtime`` used to take the residual RMS and the knots (noise 0.065 vs
    0.236 N, walk 1.50 vs 2.93 N/√h on a new user's files) while LiveCalibrator took the stored variances."""
    old_style = PayloadParameters(identified.mass, identified.com, identified.force_bias, identified.torque_bias,
                                  9.81, fit={"residual_rms": [0.5] * 6})
    for tools in ({"tool": identified}, {"plain": old_style, "tool": identified}, {"plain": old_style}, {}):
        live = LiveCalibrator(tools=tools, tool=next(iter(tools), "none"))
        params = runtime_parameters(tools)
        np.testing.assert_array_equal(params["noise_variance"], live.noise_std ** 2)
        np.testing.assert_array_equal(params["walk_variance"], live.walk_variance)
        np.testing.assert_array_equal(params["wander_density"], live.wander_density)
    # The wander looks like a walk to the 1-s blocks (the stored walk is far above the true 0.5 N/√h); the tracker
    # takes out the share a Gauss-Markov wander explains (else it walks with the wander and takes touches in).
    stored = np.sqrt(identified.drift.walk_variance[:3])
    tracked = np.sqrt(runtime_parameters({"tool": identified})["walk_variance"][:3] * 3600.0)
    assert np.all(stored > 3 * 0.5) and np.all(tracked < 0.5 * stored), (stored, tracked)


def test_the_variogram_fit_is_scipys_non_negative_least_squares():
    # payload imports no SciPy (test_payload_one_pass), so the three-column NNLS is ftcal's own: SciPy is the reference
    from scipy.optimize import nnls

    from ftcal.payload.drift import _nonnegative_least_squares

    rng = np.random.default_rng(3)
    for _ in range(300):
        a, b = rng.normal(size=(9, 3)), rng.normal(size=9)
        x_ref, norm_ref = nnls(a, b)
        x, norm = _nonnegative_least_squares(a, b)
        np.testing.assert_allclose(x, x_ref, atol=1e-10)
        assert abs(norm - norm_ref) <= 1e-10


def test_the_default_chain_on_a_coloured_recording_without_contact(tmp_path):
    """Issue 40: ``payload --time`` (auto: the random walk), then ``live --replay`` with that file, on the coloured,
    quantised recording above (no contact): <= 1 % of static samples flagged, and the compensated force within
    1.5x of ``compensate``'s (the offline smoother's bias at each sample)."""
    import subprocess
    import sys

    import pandas as pd

    time, gravity, wrench = still_recording()
    table = pd.DataFrame(wrench, columns=[f"u{j}" for j in range(1, 7)])
    table.insert(0, "time", time)
    table[["gx", "gy", "gz"]] = gravity
    data = tmp_path / "rec.csv"
    table.to_csv(data, index=False)
    ftcal = [sys.executable, "-m", "ftcal"]
    common = ["--gravity-columns", "gx,gy,gz"]
    for args in (["payload", str(data), *common, "--time", "time", "-o", str(tmp_path / "p.json")],
                 ["live", "--replay", str(data), *common, "--inputs", "u1,u2,u3,u4,u5,u6",
                  "--tool", f"t={tmp_path / 'p.json'}", "-o", str(tmp_path / "live.csv")],
                 ["compensate", str(tmp_path / "p.json"), str(data), *common, "--time", "time",
                  "-o", str(tmp_path / "comp.csv")]):
        done = subprocess.run([*ftcal, *args], capture_output=True, text=True)
        assert done.returncode == 0, done.stderr
    live, offline = pd.read_csv(tmp_path / "live.csv"), pd.read_csv(tmp_path / "comp.csv")
    static = live["static"].astype(bool).to_numpy()
    assert static.mean() > 0.9
    from ftcal.live.health import BIT

    flagged = (live["flags"].to_numpy().astype(int) & (BIT["contact"] | BIT["unexplained"])) != 0
    assert flagged[static].mean() <= 0.01
    force = ["Fx", "Fy", "Fz"]
    ratio = np.sqrt(np.mean(live.loc[static, force].to_numpy() ** 2) / np.mean(offline.loc[static, force].to_numpy() ** 2))
    assert ratio <= 1.5, ratio
