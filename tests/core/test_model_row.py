"""One-sample paths of a fitted model (what the live calibrator calls per sample) equal the batch ones."""

import numpy as np
import pytest

from ftcal import CalibrationModel, Dataset


@pytest.fixture(scope="module")
def model():
    rng = np.random.default_rng(3)
    # Inputs on a tilted plane plus noise: an input span narrower than the input ranges.
    base = rng.uniform(-1.0, 1.0, size=(3000, 3))
    u = np.c_[base, base @ [0.5, -0.2, 0.1] + 0.01 * rng.normal(size=3000), rng.normal(size=(3000, 3))]
    y = np.c_[u[:, :6] * 2.0 + 0.05 * u[:, :6] ** 3]
    return CalibrationModel(3).fit(Dataset.from_arrays(u, y))


def test_row_predictor_is_predict_on_one_row(model):
    rows = np.random.default_rng(4).normal(size=(200, 7))
    one = model.row_predictor()
    expected = model.predict(rows, warn_out_of_range=False)
    assert np.array_equal(np.array([one(list(r)) for r in rows]), expected)


def test_row_range_test_is_out_of_range_on_one_row(model):
    rng = np.random.default_rng(5)
    inside = rng.uniform(-0.9, 0.9, size=(100, 7))
    inside[:, 3] = inside[:, :3] @ [0.5, -0.2, 0.1]
    off_plane = inside.copy()
    off_plane[:, 3] += 0.5  # inside every range, outside the span
    far = rng.uniform(-6.0, 6.0, size=(100, 7))
    rows = np.vstack([inside, off_plane, far])
    expected = model.out_of_range(rows)
    outside = model.row_range_test()
    assert [outside(list(r)) for r in rows] == expected.tolist()
    # The three kinds are all there, so the comparison covers both answers and the span's part.
    assert not expected[:100].any() and expected[100:200].all() and expected[200:].any()
