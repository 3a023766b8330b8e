"""The data the benchmarks share: the synthetic sensor table (make_data) and the load cases of the
model-selection and MLP benchmarks (a module of its own, so cases import it
without importing each other)."""

from __future__ import annotations

import numpy as np

N_OUTPUTS = 6


def make_data(n: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    scale = np.array([120.0, 120.0, 110.0, 25.0, 25.0, 12.0])
    raw = rng.uniform(-1.0, 1.0, (n, 6)) * scale
    temperature = rng.uniform(25.0, 44.0, (n, 1))
    u = np.hstack([raw, temperature])
    x = raw / scale
    t = (temperature[:, 0] - 34.5) / 9.5
    y = np.column_stack([
        scale[i] * (x[:, i] + 0.05 * np.tanh(2 * x[:, (i + 1) % 6]) + 0.02 * t * x[:, i] + 0.01 * x[:, i] ** 3)
        for i in range(N_OUTPUTS)]) + rng.normal(0.0, 0.3, (n, N_OUTPUTS))
    return u, y


def make_load_cases(n: int, n_groups: int = 60, n_channels: int = 8, seed: int = 0):
    """A third-party-like sensor: ``n_channels`` strain channels, ``n_groups`` load cases (one file each).

    Each load case holds a base wrench with small slow variations; the channels are an
    affine map of the wrench plus quadratic cross-talk, offsets of ~1000 counts and noise,
    so the inverse map (channels -> wrench) is mildly nonlinear.
    Returns inputs (n, n_channels), outputs (n, 6) and group labels (n,).
    """
    rng = np.random.default_rng(seed)
    full_scale = np.array([100.0, 100.0, 150.0, 8.0, 8.0, 5.0])
    per = -(-n // n_groups)
    base = rng.uniform(-1.0, 1.0, (n_groups, 6))
    drift = np.cumsum(rng.normal(0.0, 0.004, (n_groups, per, 6)), axis=1)
    x = (base[:, None, :] + drift).reshape(-1, 6)[:n]
    mixing = rng.normal(0.0, 1.0, (n_channels, 6))
    quadratic = rng.normal(0.0, 0.08, (n_channels, 6, 6))
    counts = 1000.0 + 400.0 * (x @ mixing.T + np.einsum("cij,ni,nj->nc", quadratic, x, x))
    counts += rng.normal(0.0, 0.5, counts.shape)
    groups = np.repeat([f"case{g:02d}" for g in range(n_groups)], per)[:n]
    return counts, x * full_scale, groups


def make_paper_sensor(seed: int, n_groups: int = 40, per_group: int = 30, nonlinearity: float = 1.0,
                      case_error: float = 0.01, noise: float = 0.002, n_channels: int = 6):
    """A strain-gauge sensor like the paper's, calibrated on grouped load cases with a known truth.

    Each load case is a wrench held while the pose moves a little (``per_group`` samples
    within ±4 % of full scale around its base); the channels are an affine map of the wrench
    plus ``nonlinearity`` × quadratic and cubic cross-talk (1.0: a degree-3/4 fit removes
    about half the affine model's error on new load cases, the paper's 4.58 N -> 2.09 N);
    0 makes the inverse map exactly affine. ``case_error`` (fraction of full scale) is a
    reference wrench mis-measured by a constant over each load case, the error that makes
    whole load cases disagree and that a richer model can chase; ``noise`` is per sample.
    Returns inputs (n, n_channels), reference wrenches (n, 6), group labels (n,) and the
    true wrench without the load-case error (n, 6).
    """
    rng = np.random.default_rng(seed)
    law = np.random.default_rng(12345)  # the sensor itself is the same for every seed
    full_scale = np.array([100.0, 100.0, 150.0, 8.0, 8.0, 5.0])
    mixing = np.eye(6)[:n_channels] + law.normal(0.0, 0.25, (n_channels, 6))
    quadratic = law.normal(0.0, 0.06, (n_channels, 6, 6))
    cubic = law.normal(0.0, 0.05, (n_channels, 6))
    base = rng.uniform(-1.0, 1.0, (n_groups, 6))
    x = (base[:, None, :] + rng.uniform(-0.04, 0.04, (n_groups, per_group, 6))).reshape(-1, 6)
    strain = x @ mixing.T + nonlinearity * (np.einsum("cij,ni,nj->nc", quadratic, x, x) + (x ** 3) @ cubic.T)
    counts = 2000.0 + 1000.0 * (strain + rng.normal(0.0, noise, strain.shape))
    reference = x + case_error * np.repeat(rng.standard_normal((n_groups, 6)), per_group, axis=0)
    groups = np.repeat([f"case{g:02d}" for g in range(n_groups)], per_group)
    return counts, reference * full_scale, groups, x * full_scale
