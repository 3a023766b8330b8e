"""The load-case data the model-selection and MLP benchmarks share (a module of its own, so cases import it
without importing each other)."""

from __future__ import annotations

import numpy as np


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
