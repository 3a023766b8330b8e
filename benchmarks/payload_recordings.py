"""Simulated payload recordings with a known mass, for the honesty of payload standard errors.

Hand statics (F = m g + b(t), T = c × m g + b(t)) with a known mass, independent of ftcal's regressor code;
tests/data/test_payload_uncertainty.py and benchmarks/bench_payload_errors.py read the same recordings.
"""

from __future__ import annotations

import numpy as np
from scipy.signal import lfilter
from scipy.spatial.transform import Rotation

G = 9.81
MASS = 1.3
COM = np.array([0.012, -0.025, 0.071])
BIAS = np.array([3.0, -2.0, 5.0, 0.1, -0.2, 0.05])
NOISE = np.array([0.3, 0.3, 0.3, 0.01, 0.01, 0.01])
RATE_HZ = 10.0


def statics(g):
    return np.c_[MASS * g, np.cross(COM, MASS * g)]


def simulate(scenario: str, seed: int, n_poses: int = 30, per_pose: int = 60, move: int = 30):
    """Gravity (N, 3), time (s) and readings (N, 6) of one recording.

    ``sweep``: one averaged row for each of 100 poses in a systematic order (tilt and azimuth grow with
    time) with a random-walk bias, so the drift follows the pose order. ``holds``: still poses; a random-walk bias, AR(1) noise (correlated over ~1 s) and an error
    constant over each hold (hysteresis, a cable's pull). ``moves``: the same with the sensor
    turning between holds, its reading lagging the gravity wrench by a first-order filter
    (time constant about a sample: a sensor filter or a clock offset). ``per-pose``: one averaged
    row per pose, 10 s apart, with a drifting bias.
    """
    rng = np.random.default_rng(seed)
    directions = Rotation.random(n_poses, random_state=seed + 1).inv().apply([0.0, 0.0, -G])
    if scenario == "sweep":  # 100 poses, one row each, in a systematic order: the drift follows the pose order
        tilt, azimuth = np.linspace(0.1, 2.8, 100), np.linspace(0.0, 4 * np.pi, 100)
        g = G * np.c_[np.sin(tilt) * np.cos(azimuth), np.sin(tilt) * np.sin(azimuth), -np.cos(tilt)]
        path = BIAS + np.cumsum(rng.normal(size=(100, 6)), axis=0) * NOISE * 0.3
        return g, np.arange(100) * 10.0, statics(g) + path + rng.normal(size=(100, 6)) * NOISE
    if scenario == "per-pose":
        time = np.arange(n_poses) * 10.0
        path = BIAS + np.cumsum(rng.normal(size=(n_poses, 6)), axis=0) * NOISE * 0.3
        return directions, time, statics(directions) + path + rng.normal(size=(n_poses, 6)) * NOISE
    pieces = []
    for i in range(n_poses):
        pieces.append(np.repeat(directions[i][None], per_pose, axis=0))
        if scenario == "moves" and i + 1 < n_poses:
            s = np.linspace(0.0, 1.0, move + 2)[1:-1, None]
            turn = directions[i] * (1 - s) + directions[i + 1] * s
            pieces.append(G * turn / np.linalg.norm(turn, axis=1, keepdims=True))
    g = np.concatenate(pieces)
    n = len(g)
    wrench = statics(g)
    if scenario == "moves":
        wrench = lfilter([0.5], [1.0, -0.5], wrench, axis=0, zi=0.5 * wrench[:1])[0]
    hold = np.cumsum(np.r_[0, np.any(np.diff(g, axis=0) != 0, axis=1)])
    wrench += rng.normal(size=(hold[-1] + 1, 6))[hold] * NOISE * 0.3
    wrench += BIAS + np.cumsum(rng.normal(size=(n, 6)), axis=0) * NOISE * 0.03
    wrench += lfilter([np.sqrt(1 - 0.9 ** 2)], [1.0, -0.9], rng.normal(size=(n, 6)), axis=0) * NOISE
    return g, np.arange(n) / RATE_HZ, wrench



def breaking(scenario: str, seed: int):
    """A ``holds`` recording (20 poses of 40 samples) with one more assumption broken."""
    g, time, wrench = simulate("holds", seed, n_poses=20, per_pose=40)
    rng = np.random.default_rng(seed + 77)
    n = len(g)
    if scenario == "wander":  # slow coloured wander (AR(1), τ ≈ 60 s) at 3x the white noise
        wrench = wrench + lfilter([np.sqrt(1 - 0.9983 ** 2)], [1.0, -0.9983], rng.normal(size=(n, 6)), axis=0) \
            * NOISE * 3
    elif scenario == "speed-up":  # the walk runs 5x faster in the second half
        steps = rng.normal(size=(n, 6)) * NOISE * 0.15 * (np.arange(n) > n // 2)[:, None]
        wrench = wrench + np.cumsum(steps, axis=0)
    elif scenario == "10-bit":  # a 10-bit converter over ±1.2x the largest reading
        lsb = 2.4 * np.abs(wrench).max(axis=0) / 1024
        wrench = np.round(wrench / lsb) * lsb
    elif scenario == "gain":  # per-axis gain errors of ±1.5 % and 1 % cross-talk from Fx into Fy
        force = wrench[:, :3].copy()
        wrench = wrench.copy()
        wrench[:, 0], wrench[:, 1] = 1.015 * force[:, 0], 0.985 * force[:, 1] + 0.01 * force[:, 0]
    return g, time, wrench
