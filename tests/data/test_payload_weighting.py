"""The default weighting of payload fits is chosen by held-out blocks, and never loses to OLS there."""

import numpy as np
from scipy.spatial.transform import Rotation

from ftcal.payload.accumulate import payload_statistics
from ftcal.payload.identify import identify_payload
from ftcal.payload.kinematics import Kinematics

G = 9.81
MASS = 1.3
COM = np.array([0.012, -0.025, 0.071])
BIAS = np.array([3.0, -2.0, 5.0, 0.1, -0.2, 0.05])


def fit(noise, seed, weighting="auto"):
    rng = np.random.default_rng(seed)
    g = np.repeat(Rotation.random(40, random_state=seed).inv().apply([0.0, 0.0, -G]), 25, axis=0)
    w = np.c_[MASS * g, np.cross(COM, MASS * g)] + BIAS + rng.normal(size=(len(g), 6)) * noise
    blocks = [payload_statistics(w[i], Kinematics(g[i])) for i in np.array_split(np.arange(len(g)), 20)]
    total = payload_statistics(w, Kinematics(g))
    return identify_payload({"all": total}, clusters=blocks, weighting=weighting)


def test_equal_noise_keeps_plain_least_squares():
    result = fit(np.array([0.3, 0.3, 0.3, 0.01, 0.01, 0.01]), seed=1)
    assert result.weighting == "ols" and "plain least squares kept" in result.weighting_evidence


def test_very_unequal_force_noise_keeps_the_weighting_and_it_helps():
    # Fz 50x noisier than Fx, Fy: the mass is far better read from Fx, Fy (inverse-variance weighting).
    noise = np.array([0.02, 0.02, 1.0, 0.01, 0.01, 0.01])
    chosen = [fit(noise, seed) for seed in range(10)]
    assert sum(r.weighting == "wls" for r in chosen) >= 8  # held-out evidence is noisy too
    ols = [fit(noise, seed, weighting="ols") for seed in range(10)]
    # Over these recordings the weighted mass is closer to the truth than the OLS mass.
    assert np.mean([(r.mass - MASS) ** 2 for r in chosen]) < 0.5 * np.mean([(r.mass - MASS) ** 2 for r in ols])
