"""A drifting bias: linear and random-walk models recovered, auto's choice, temperature,
compensation along the trajectory, re-taring, and one-line errors.

Truth comes from hand statics in the sensor frame (F = m g + b(t), T = c × m g + b(t)) with a
known bias path; nothing is taken from ftcal's own output.
"""

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from scipy.spatial.transform import Rotation

from ftcal.payload.kinematics import Kinematics
from ftcal.payload.tables import PayloadRecording, identify_recording

FTCAL = str(Path(sys.executable).with_name("ftcal"))
G = 9.81
MASS = 1.3
COM = np.array([0.012, -0.025, 0.071])
BIAS = np.array([3.0, -2.0, 5.0, 0.1, -0.2, 0.05])
NOISE = np.array([0.3, 0.3, 0.3, 0.01, 0.01, 0.01])
SLOPE = np.array([2.0, -1.0, 3.0, 0.05, 0.02, -0.03])  # per hour
WALK = NOISE * 0.05  # random-walk step per sample
RATE_HZ = 10.0


def statics(g):
    return np.c_[MASS * g, np.cross(COM, MASS * g)]


def simulate(drift: str, seed: int = 0, n_poses: int = 30, per_pose: int = 200, start: float = 0.0):
    """Gravity, time (s), true bias path and readings; poses in random order, 10 Hz."""
    rng = np.random.default_rng(seed)
    g = np.repeat(Rotation.random(n_poses, random_state=seed + 1).inv().apply([0.0, 0.0, -G]), per_pose, axis=0)
    n = len(g)
    time = start + np.arange(n) / RATE_HZ
    hours = (time - time[0]) / 3600.0
    if drift == "none":
        path = np.broadcast_to(BIAS, (n, 6)).copy()
    elif drift == "linear":
        path = BIAS + hours[:, None] * SLOPE * 20  # 20× the slope: clear in a 10-min recording
    else:
        path = BIAS + np.cumsum(rng.normal(size=(n, 6)), axis=0) * WALK
    wrench = statics(g) + path + rng.normal(size=(n, 6)) * NOISE
    return g, time, path, wrench


def recording(g, time, wrench, temperature=None):
    return PayloadRecording(wrench, Kinematics(g), np.full(len(g), "run", dtype=object), time, temperature)


def write_table(path, g, time, wrench, temperature=None):
    frame = pd.DataFrame(np.c_[time, g, wrench], columns=["time", "gx", "gy", "gz", "u1", "u2", "u3", "u4", "u5", "u6"])
    if temperature is not None:
        frame["temp"] = temperature
    frame.to_parquet(path)
    return path


def ftcal(*args):
    return subprocess.run([FTCAL, *map(str, args)], capture_output=True, text=True, timeout=300)


# ---------------------------------------------------------------- library: each drift kind recovered
def test_linear_drift_slopes_and_mass_recovered():
    g, time, _, wrench = simulate("linear", seed=1)
    result = identify_recording(recording(g, time, wrench), bias_drift="linear", time_column="time")
    slope, se = result.fit.covariates["time"]
    assert np.all(np.abs(slope - 20 * SLOPE) < 4 * se)
    assert np.all(np.abs(20 * SLOPE) > 10 * se)  # the slope is resolved, not just within noise
    assert abs(result.fit.mass - MASS) < 4 * result.fit.stderr["mass"]
    # The bias stored is the one at the end of the recording.
    end = BIAS + 20 * SLOPE * (time[-1] - time[0]) / 3600.0
    got = np.r_[result.fit.force_bias, result.fit.torque_bias]
    se_end = np.r_[result.fit.stderr["force_bias"], result.fit.stderr["torque_bias"]]
    assert np.all(np.abs(got - end) < 4 * se_end)
    np.testing.assert_allclose(result.drift.knot_times, time[[0, -1]])


def test_random_walk_trajectory_variance_and_mass_recovered():
    g, time, path, wrench = simulate("random-walk", seed=2)
    result = identify_recording(recording(g, time, wrench), bias_drift="random-walk", time_column="time")
    fit = result.fit
    assert abs(fit.mass - MASS) < 4 * fit.stderr["mass"]
    assert np.all(np.abs(fit.com - COM) < 4 * fit.stderr["com"])
    # Walk standard deviation per √h: step σ × √(samples per hour).
    truth = WALK * np.sqrt(RATE_HZ * 3600.0)
    np.testing.assert_allclose(result.walk_std, truth, rtol=0.3)
    # The smoothed trajectory follows the true bias path far better than any constant does.
    knots = result.drift.knot_times
    estimated = np.column_stack([np.interp(time, knots, result.drift.knot_bias[:, j]) for j in range(6)])
    error = np.sqrt(np.mean((estimated - path) ** 2, axis=0))
    spread = np.std(path, axis=0)
    assert np.all(error < 0.3 * spread)


def test_temperature_coefficients_recovered_without_time():
    rng = np.random.default_rng(5)
    g, time, _, wrench = simulate("none", seed=5)
    temperature = 30.0 + 5.0 * np.sin(np.arange(len(g)) / 500.0) + rng.normal(0, 0.1, len(g))
    per_kelvin = np.array([0.2, -0.1, 0.3, 0.004, -0.002, 0.001])
    wrench = wrench + np.outer(temperature - 30.0, per_kelvin)
    result = identify_recording(recording(g, None, wrench, temperature), bias_drift="auto",
                                temperature_column="temp")
    coefficients, se = result.fit.covariates["temperature"]
    assert np.all(np.abs(coefficients - per_kelvin) < 4 * se)
    assert result.drift.model == "none" and result.drift.temperature_column == "temp"


@pytest.mark.parametrize("drift", ["none", "linear", "random-walk"])
def test_auto_picks_the_generating_model(drift):
    g, time, _, wrench = simulate(drift, seed=7)
    result = identify_recording(recording(g, time, wrench), bias_drift="auto", time_column="time")
    assert result.drift.model == drift, result.selection


def test_auto_without_time_is_constant():
    g, _, _, wrench = simulate("none", seed=8)
    result = identify_recording(recording(g, None, wrench), bias_drift="auto")
    assert result.drift is None and result.fit is result.constant


# ---------------------------------------------------------------- CLI: file, printout, compensate
def test_cli_random_walk_file_printout_and_compensation(tmp_path):
    g, time, path, wrench = simulate("random-walk", seed=3)
    data = write_table(tmp_path / "run.parquet", g, time, wrench)
    done = ftcal("payload", data, "--gravity-columns", "gx,gy,gz", "--time", "time", "--bias-drift", "random-walk",
                 "-o", tmp_path / "p.json")
    assert done.returncode == 0, done.stderr
    assert "bias model: random-walk" in done.stdout and "N/h" in done.stdout and "vs a constant bias" in done.stdout
    doc = json.loads((tmp_path / "p.json").read_text())
    assert doc["drift"]["model"] == "random-walk" and doc["drift"]["time_column"] == "time"
    assert len(doc["drift"]["knots"]["time"]) >= 100
    done = ftcal("compensate", tmp_path / "p.json", data, "--gravity-columns", "gx,gy,gz", "-o", tmp_path / "c.parquet")
    assert done.returncode == 0, done.stderr
    assert "outside" not in done.stderr
    contact = pd.read_parquet(tmp_path / "c.parquet")[["Fx", "Fy", "Fz", "Tx", "Ty", "Tz"]].to_numpy()
    # Along the trajectory only the sensor noise is left; even the best constant bias leaves the wander.
    assert np.all(np.std(contact, axis=0) < 1.25 * NOISE)
    assert np.all(np.std(wrench - statics(g) - np.mean(path, axis=0), axis=0) > 1.1 * np.std(contact, axis=0))


def test_cli_compensate_beyond_recording_holds_last_bias_and_warns_once(tmp_path):
    g, time, _, wrench = simulate("linear", seed=4)
    data = write_table(tmp_path / "run.parquet", g, time, wrench)
    assert ftcal("payload", data, "--gravity-columns", "gx,gy,gz", "--time", "time", "--bias-drift", "linear",
                 "-o", tmp_path / "p.json").returncode == 0
    doc = json.loads((tmp_path / "p.json").read_text())
    later = write_table(tmp_path / "later.parquet", g[:50], time[-1] + 100.0 + np.arange(50), wrench[:50])
    done = ftcal("compensate", tmp_path / "p.json", later, "--gravity-columns", "gx,gy,gz", "-o", tmp_path / "c.csv")
    assert done.returncode == 0, done.stderr
    warnings = [line for line in done.stderr.splitlines() if "outside the identification recording" in line]
    assert len(warnings) == 1 and "50 sample(s)" in warnings[0]
    # Hand statics with the file's values and the last knot's bias.
    mass, com = doc["mass"], np.array(doc["com"])
    last = np.array(doc["drift"]["knots"]["bias"][-1])
    want = wrench[:50] - last - np.c_[mass * g[:50], np.cross(com, mass * g[:50])]
    got = pd.read_csv(tmp_path / "c.csv")[["Fx", "Fy", "Fz", "Tx", "Ty", "Tz"]].to_numpy()
    np.testing.assert_allclose(got, want, atol=1e-9)
    np.testing.assert_allclose(last, np.r_[doc["force_bias"], doc["torque_bias"]])


def test_cli_rebias_recovers_a_shifted_bias_and_its_rate(tmp_path):
    g, time, _, wrench = simulate("none", seed=6)
    first = write_table(tmp_path / "first.parquet", g, time, wrench)
    assert ftcal("payload", first, "--gravity-columns", "gx,gy,gz", "--time", "time", "--bias-drift", "none",
                 "-o", tmp_path / "p.json").returncode == 0
    shift = np.array([1.5, -0.8, 0.0, 0.03, 0.0, -0.02])
    hours_later = 2.0
    g2, time2, _, wrench2 = simulate("none", seed=9, n_poses=5, start=time[-1] + hours_later * 3600.0)
    second = write_table(tmp_path / "second.parquet", g2, time2, wrench2 + shift)
    done = ftcal("payload", "--rebias", tmp_path / "p.json", second, "--gravity-columns", "gx,gy,gz",
                 "--time", "time", "-o", tmp_path / "q.json")
    assert done.returncode == 0, done.stderr
    doc = json.loads((tmp_path / "q.json").read_text())
    bias = np.r_[doc["force_bias"], doc["torque_bias"]]
    se = np.r_[doc["stderr"]["force_bias"], doc["stderr"]["torque_bias"]]
    assert np.all(np.abs(bias - (BIAS + shift)) < 4 * se + 4 * np.r_[json.loads(
        (tmp_path / "p.json").read_text())["stderr"]["force_bias"], [0, 0, 0]] * 0 + 1e-12)
    assert doc["mass"] == json.loads((tmp_path / "p.json").read_text())["mass"]
    assert "more than the identification's uncertainty explains" in done.stdout
    assert "Fx" in done.stdout.split("explains")[1] and "Fz" not in done.stdout.split("explains")[1]
    # The rate line: 1.5 N over ~2 h (from the end of the first recording to the middle of the second).
    rate_line = next(line for line in done.stdout.splitlines() if "drift rate since identification" in line)
    hours = (time2.mean() - time[-1]) / 3600.0
    fx_rate = float(rate_line.split("Fx ")[1].split()[0])
    assert abs(fx_rate - shift[0] / hours) < 4 * se[0] / hours + 0.05


def test_cli_rebias_without_shift_is_within_uncertainty(tmp_path):
    g, time, _, wrench = simulate("none", seed=10)
    first = write_table(tmp_path / "first.parquet", g, time, wrench)
    assert ftcal("payload", first, "--gravity-columns", "gx,gy,gz", "-o", tmp_path / "p.json").returncode == 0
    g2, time2, _, wrench2 = simulate("none", seed=11, n_poses=5)
    second = write_table(tmp_path / "second.parquet", g2, time2, wrench2)
    done = ftcal("payload", "--rebias", tmp_path / "p.json", second, "--gravity-columns", "gx,gy,gz",
                 "-o", tmp_path / "q.json")
    assert done.returncode == 0, done.stderr
    assert "within what the identification's uncertainty explains" in done.stdout
    assert "drift rate: unknown" in done.stdout


# ---------------------------------------------------------------- bad input: one line, exit 2
@pytest.fixture(scope="module")
def table(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("bad")
    g, time, _, wrench = simulate("none", seed=12, n_poses=10, per_pose=20)
    write_table(tmp / "ok.parquet", g, time, wrench, temperature=np.full(len(g), 25.0))
    backwards = time.copy()
    backwards[57] = backwards[56]
    write_table(tmp / "backwards.parquet", g, backwards, wrench)
    pd.read_parquet(tmp / "ok.parquet").drop(columns="time").to_parquet(tmp / "notime.parquet")
    return tmp


@pytest.mark.parametrize("args, message", [
    (["notime.parquet", "--bias-drift", "linear"], "--bias-drift linear needs the time column and"),
    (["notime.parquet", "--bias-drift", "random-walk"], "has none named 'time': give --time COL."),
    (["backwards.parquet", "--time", "time", "--bias-drift", "linear"],
     "backwards.parquet: time column 'time' does not increase at row 57"),
    (["ok.parquet", "--temperature", "temp"], "--temperature temp: the column is constant (25)"),
    (["ok.parquet", "--time", "time", "--bias-drift", "random-walk", "--dynamic"],
     "--bias-drift random-walk works with static poses only"),
    (["ok.parquet", "--time", "clock", "--bias-drift", "linear"], "missing time column(s) 'clock'"),
])
def test_bad_drift_input_is_one_line_exit_2(table, args, message):
    args = [table / a if a.endswith(".parquet") else a for a in args]
    done = ftcal("payload", *args, "--gravity-columns", "gx,gy,gz", "-o", table / "out.json")
    assert done.returncode == 2
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and message in lines[0] and "Traceback" not in done.stderr
    assert not (table / "out.json").exists()


def test_the_time_column_defaults_to_time_as_the_help_says(table):
    # --time's help: "default: the column 'time' where there is one"; the drift models then need no --time.
    done = ftcal("payload", table / "ok.parquet", "--bias-drift", "linear", "--gravity-columns", "gx,gy,gz",
                 "-o", table / "default-time.json")
    assert done.returncode == 0, done.stderr
    assert json.loads((table / "default-time.json").read_text())["drift"]["time_column"] == "time"


# ---------------------------------------------------------------- payload file
def test_payload_file_round_trips_the_drift_and_old_files_stay_constant(tmp_path):
    from ftcal.files.payload_json import load_payload, save_payload
    from ftcal.payload.drift import BiasDrift
    from ftcal.payload.parameters import PayloadParameters

    stderr = {"mass": 0.01, "com": np.full(3, 1e-3), "force_bias": np.full(3, 0.1), "torque_bias": np.full(3, 0.01)}
    fit = {"n_samples": 10, "residual_rms": np.ones(6), "condition_number": 1.0, "wrench_columns": list("abcdef")}
    drift = BiasDrift("linear", "time", 0.0, 3600.0, np.array([0.0, 3600.0]), np.vstack([BIAS, BIAS + SLOPE]),
                      "temp", 30.0, np.arange(6.0))
    payload = PayloadParameters(MASS, COM, BIAS[:3] + SLOPE[:3], BIAS[3:] + SLOPE[3:], G, None, False, None,
                                stderr, fit, drift)
    save_payload(payload, tmp_path / "p.json")
    back = load_payload(tmp_path / "p.json").drift
    assert back.model == "linear" and back.temperature_column == "temp" and back.temperature_reference == 30.0
    np.testing.assert_array_equal(back.knot_bias, drift.knot_bias)
    # Half-way through the hour at 31 degrees: half the slope plus one degree of the coefficients.
    got = back.bias(BIAS, np.array([1800.0]), np.array([31.0]))
    np.testing.assert_allclose(got[0], BIAS + SLOPE / 2 + np.arange(6.0))
    doc = json.loads((tmp_path / "p.json").read_text())
    save_payload(PayloadParameters(MASS, COM, BIAS[:3], BIAS[3:], G, stderr=stderr, fit=fit), tmp_path / "old.json")
    assert "drift" not in json.loads((tmp_path / "old.json").read_text()) and "drift" in doc
    old = load_payload(tmp_path / "old.json")
    assert old.drift is None and np.array_equal(old.bias_of(None, None, 2), np.tile(BIAS, (2, 1)))


def test_the_wander_fits_moments_are_the_gauss_markov_integrals():
    """The hold-mean variance of a unit first-order Gauss-Markov process (``within_hold_noise``'s V(T)) against the
    double integral of its autocorrelation exp(-|t - s| / τ) by the midpoint rule, and the χ² quantile of the
    wander test (Wilson-Hilferty) against SciPy's."""
    from scipy.stats import chi2

    from ftcal.payload.drift import _chi2_quantile, _mean_variance

    for length, tau in ((5.0, 2.0), (0.5, 3.0), (20.0, 0.5)):
        t = (np.arange(2000) + 0.5) * length / 2000
        numeric = np.mean(np.exp(-np.abs(t[:, None] - t[None]) / tau))
        assert abs(_mean_variance(np.array([length]), tau)[0] - numeric) < 5e-3 * numeric
    for dof in (10, 16, 30, 60):
        assert abs(_chi2_quantile(0.999, dof) / chi2.ppf(0.999, dof) - 1.0) < 0.01
