"""The default weighting of payload fits is chosen by held-out blocks, and never loses to OLS there."""

import numpy as np
from scipy.spatial.transform import Rotation

from ftcal.payload.accumulate import payload_statistics
from ftcal.payload.identify import identify_from_statistics
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
    return identify_from_statistics({"all": total}, clusters=blocks, weighting=weighting)


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


# ---------------------------------------------------------------- a drifting axis: weights must not lose the norm
def regressor(g):
    """Stacked rows (6N, 10) of F = m g + b_F, T = (m c) × g + b_T for θ = [m, m c, b_F, b_T], by hand."""
    n = len(g)
    x = np.zeros((n, 6, 10))
    gx, gy, gz = g.T
    for j in range(3):
        x[:, j, 0] = g[:, j]
        x[:, j, 4 + j] = 1.0
        x[:, 3 + j, 7 + j] = 1.0
    x[:, 3, 2], x[:, 3, 3] = gz, -gy  # Tx = mcy gz − mcz gy
    x[:, 4, 3], x[:, 4, 1] = gx, -gz  # Ty = mcz gx − mcx gz
    x[:, 5, 1], x[:, 5, 2] = gy, -gx  # Tz = mcx gy − mcy gx
    return x


def held_out_force_norms(g, w, n_blocks=20):
    """Held-out force SSE of OLS and per-axis WLS over contiguous blocks, with numpy's lstsq on all rows."""
    x = regressor(g)
    sse = {"ols": 0.0, "wls": 0.0}
    for rows in np.array_split(np.arange(len(g)), n_blocks):
        train = np.setdiff1d(np.arange(len(g)), rows)
        xt, yt = x[train], w[train]
        theta = np.linalg.lstsq(xt.reshape(-1, 10), yt.reshape(-1), rcond=None)[0]
        weights = 1.0 / np.mean((yt - xt @ theta) ** 2, axis=0)
        root = np.sqrt(weights)
        theta_w = np.linalg.lstsq((xt * root[None, :, None]).reshape(-1, 10), (yt * root).reshape(-1), rcond=None)[0]
        for name, t in (("ols", theta), ("wls", theta_w)):
            sse[name] += float(np.sum((w[rows, :3] - x[rows, :3] @ t) ** 2))
    return sse["wls"] / sse["ols"]


def test_weights_that_lose_the_held_out_force_norm_are_not_kept():
    # Fz drifts (a random walk): its residual is large, per-axis weights down-weight it and the mass is read from
    # Fx, Fy. The mean of the per-axis held-out ratios can then favour the weights while the force error norm,
    # which the drifting axis dominates, loses: the earlier rule kept such weights (seed 2: forces 0.64x on the
    # per-axis mean, 1.04x on the norm).
    noise = np.array([0.05, 0.05, 0.05, 0.002, 0.002, 0.002])
    kept_ols_against_the_mean = 0
    for seed in range(8):
        rng = np.random.default_rng(seed)
        g = np.repeat(Rotation.random(40, random_state=seed).inv().apply([0.0, 0.0, -G]), 25, axis=0)
        w = np.c_[MASS * g, np.cross(COM, MASS * g)] + BIAS + rng.normal(size=(len(g), 6)) * noise
        w[:, 2] += np.cumsum(rng.normal(size=len(g))) * 0.1
        blocks = [payload_statistics(w[i], Kinematics(g[i])) for i in np.array_split(np.arange(len(g)), 20)]
        result = identify_from_statistics({"all": payload_statistics(w, Kinematics(g))}, clusters=blocks)
        norm = held_out_force_norms(g, w)
        if result.weighting == "wls":  # kept weights never lose the held-out force norm (numpy's own refits)
            assert norm <= 1.02, (seed, norm, result.weighting_evidence)
        elif norm > 1.02:
            kept_ols_against_the_mean += "forces 0." in result.weighting_evidence
    assert kept_ols_against_the_mean >= 1
