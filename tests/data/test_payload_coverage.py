"""Honest standard errors: 95 % intervals for the mass contain the truth >= 90 % of the time.

Each scenario simulates 200 recordings with known mass, centre of mass and bias, a systematic
pose order (gravity sweeps the sensor's axes in time order, as robots are usually programmed)
and time-correlated noise (AR(1), correlation time ~2 samples at 10 Hz, 25 s per pose), with and without a
drifting bias, and fits them through ``identify_recording`` (what ``ftcal payload`` runs).
The simulation is sensor-frame statics (F = m g + b, T = c × m g + b), independent of ftcal's
regressor code.
"""

import numpy as np
import pytest
from scipy.signal import lfilter

from ftcal.payload.identify import identify_from_statistics
from ftcal.payload.accumulate import payload_statistics
from ftcal.payload.kinematics import Kinematics
from ftcal.payload.tables import PayloadRecording, identify_recording

# 600 fits, about a minute. Warnings about a fit are not what is tested (a recording in a few hundred may say
# its error grows with the blocks' length: the error stated is then the largest, which coverage checks).
pytestmark = [pytest.mark.slow, pytest.mark.filterwarnings("ignore::ftcal.runtime.errors.IllPosedFitWarning")]

G = 9.81
MASS = 1.3
COM = np.array([0.012, -0.025, 0.071])
BIAS = np.array([3.0, -2.0, 5.0, 0.1, -0.2, 0.05])
NOISE = np.array([0.3, 0.3, 0.3, 0.01, 0.01, 0.01])
RECORDINGS = 200
RATE_HZ = 10.0


def simulate(seed: int, drift: str, n_poses: int = 20, per_pose: int = 250, rho: float = 0.6):
    """Gravity (N, 3), time (N,) s and readings (R, N, 6) of RECORDINGS recordings."""
    rng = np.random.default_rng(seed)
    tilt = np.linspace(0.1, 2.6, n_poses)  # systematic order: tilt and azimuth grow with time
    azimuth = np.linspace(0.0, 3 * np.pi, n_poses)
    g = G * np.c_[np.sin(tilt) * np.cos(azimuth), np.sin(tilt) * np.sin(azimuth), -np.cos(tilt)]
    g = np.repeat(g, per_pose, axis=0)
    n = len(g)
    time = np.arange(n) / RATE_HZ
    noise = lfilter([np.sqrt(1 - rho ** 2)], [1.0, -rho], rng.normal(size=(RECORDINGS, n, 6)), axis=1) * NOISE
    wrench = np.c_[MASS * g, np.cross(COM, MASS * g)] + BIAS + noise
    if drift == "random-walk":
        wrench += np.cumsum(rng.normal(size=(RECORDINGS, n, 6)), axis=1) * NOISE * 0.1
    elif drift == "linear":
        wrench += rng.normal(size=(RECORDINGS, 1, 6)) * NOISE * 5 * (time / time[-1])[None, :, None]
    return g, time, wrench


def fit_all(drift: str, model: str, seed: int):
    g, time, wrench = simulate(seed, drift)
    labels = np.full(len(g), "run", dtype=object)
    results = [identify_recording(PayloadRecording(w, Kinematics(g), labels, time, None), bias_drift=model,
                                  time_column="time", cross_validate=False) for w in wrench]
    return g, wrench, results


def coverage(results) -> float:
    return float(np.mean([abs(r.fit.mass - MASS) <= 1.96 * r.fit.stderr["mass"] for r in results]))


def test_no_drift_correlated_noise_auto_keeps_constant_bias_and_covers():
    g, wrench, results = fit_all("none", "auto", seed=1)
    chosen = [r.drift.model for r in results]
    assert chosen.count("none") >= 0.9 * RECORDINGS  # the simpler model when there is no drift
    assert coverage(results) >= 0.90
    # The scenario is hard: textbook (independent-noise) standard errors cover far less often.
    textbook = [identify_from_statistics({"run": payload_statistics(w, Kinematics(g))}, weighting="ols") for w in wrench]
    assert np.mean([abs(f.mass - MASS) <= 1.96 * f.stderr["mass"] for f in textbook]) < 0.8


def test_linear_drift_linear_model_covers():
    _, _, results = fit_all("linear", "linear", seed=2)
    assert coverage(results) >= 0.90


def test_random_walk_drift_state_space_model_covers():
    _, _, results = fit_all("random-walk", "random-walk", seed=3)
    assert coverage(results) >= 0.90
    # A constant bias on the same recordings takes part of the walk into the mass. Its intervals missed far
    # more often (< 60 %) with the 20-block jackknife alone; the coarser jackknives see the walk move
    # neighbouring blocks together and widen them until they cover, at the price of a larger error.
    constant = [type(r)(r.constant, r.constant, None, "", None, 0.0, None) for r in results]
    assert coverage(constant) >= 0.85
    assert np.median([r.constant.stderr["mass"] for r in results]) > np.median([r.fit.stderr["mass"] for r in results])
