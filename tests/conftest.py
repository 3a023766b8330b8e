"""Shared fixtures for the fitting-engine tests: seeded data and independent references."""

import os

import numpy as np
import pytest
from sklearn.preprocessing import PolynomialFeatures


def reference_features(u, degree):
    """Monomials of degree 1..degree then the offset, built by scikit-learn (not ftcal)."""
    full = PolynomialFeatures(degree, include_bias=True).fit_transform(np.asarray(u, dtype=float))
    return np.roll(full, -1, axis=1)  # sklearn puts the bias first; the paper puts it last


def sensor_like_data(rng, n, n_channels=6):
    """Raw inputs like a real sensor: ADC counts ~5000 of mixed loads, temperature 25–44 °C.

    Outputs are the loads (N, Nm) with a mild non-polynomial response and a
    temperature effect, so no polynomial degree fits them exactly.
    """
    loads = rng.uniform(-1.0, 1.0, size=(n, n_channels))
    temperature = rng.uniform(25.0, 44.0, size=n)
    mixing = np.eye(n_channels) + 0.2 * np.random.default_rng(123).standard_normal((n_channels, n_channels))
    counts = 5000.0 + 800.0 * loads @ mixing.T + 3.0 * (temperature[:, None] - 35.0)
    wrench = loads * np.array([100.0, 100.0, 100.0, 10.0, 10.0, 10.0])[:n_channels]
    wrench = wrench + 5.0 * np.tanh(2.0 * loads[:, :1]) + 0.01 * (temperature[:, None] - 35.0) ** 2
    return np.c_[counts, temperature], wrench


@pytest.fixture(autouse=True, scope="session")
def private_cache_home(tmp_path_factory):
    """The expected-wrench cache of every test (and of the CLI it starts) goes to a temporary folder."""
    previous = os.environ.get("XDG_CACHE_HOME")
    os.environ["XDG_CACHE_HOME"] = str(tmp_path_factory.mktemp("xdg-cache"))
    yield
    if previous is None:
        os.environ.pop("XDG_CACHE_HOME", None)
    else:
        os.environ["XDG_CACHE_HOME"] = previous


def write_frame(frame, path):
    """CSV (full precision) or Parquet with 1000-row groups, by ``path``'s suffix: many chunks per file."""
    if str(path).endswith(".csv"):
        frame.to_csv(path, index=False, float_format="%.17g")
    else:
        frame.to_parquet(path, row_group_size=1000)
    return str(path)


@pytest.fixture
def rng():
    return np.random.default_rng(20240611)


@pytest.fixture
def ref_features():
    return reference_features


@pytest.fixture
def make_sensor_data():
    return sensor_like_data
