"""``PayloadResult`` and ``RebiasResult`` hold numbers and render their text from them (issue #43).

Truth: a tool of known mass and centre of mass on a sensor with a known bias, held still in random
orientations (gravity from the quaternion), then re-tared from new holds whose bias moved by a known
shift. The excitation's singular values are checked against numpy's SVD of the regressor built here by
hand; each field changed renders its own text, the expected text derived from the changed numbers.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pandas as pd
import pytest
from scipy.spatial.transform import Rotation

from ftcal.workflow.payload import identify_payload, retare

MASS, COM = 0.8, np.array([0.01, -0.02, 0.05])
BIAS = np.array([0.5, -0.3, 0.8, 0.02, -0.01, 0.005])
SHIFT = np.array([0.4, 0.0, -0.3, 0.0, 0.01, 0.0])
NOISE = np.array([0.01, 0.01, 0.01, 0.001, 0.001, 0.001])


def _holds(path, seed, bias, n_poses=12, per_pose=40):
    rng = np.random.default_rng(seed)
    rotations = Rotation.random(n_poses, random_state=seed)
    quat = np.repeat(rotations.as_quat(), per_pose, axis=0)
    g = Rotation.from_quat(quat).inv().apply([0.0, 0.0, -9.81])
    wrench = np.c_[MASS * g, np.cross(COM, MASS * g)] + bias + rng.normal(size=(len(g), 6)) * NOISE
    frame = pd.DataFrame(np.c_[quat, wrench], columns=["qx", "qy", "qz", "qw", "u1", "u2", "u3", "u4", "u5", "u6"])
    frame.to_csv(path, index=False)
    return g


@pytest.fixture(scope="module")
def identified(tmp_path_factory):
    folder = tmp_path_factory.mktemp("payload")
    g = _holds(folder / "first.csv", 1, BIAS)
    _holds(folder / "later.csv", 2, BIAS + SHIFT)
    result = identify_payload(str(folder / "first.csv"), orientation=("qx", "qy", "qz", "qw"),
                              output=folder / "p.json")
    return folder, g, result


def test_the_excitation_is_the_svd_of_the_payload_regressor(identified):
    _, g, result = identified
    # Force = m g + b_f, torque = (m c) × g + b_t: columns m, m·c, b_f, b_t (order and signs do not move the SVD).
    n = len(g)
    rows = np.zeros((n, 6, 10))
    rows[:, :3, 0] = g
    rows[:, 3:, 1:4] = -np.array([[[0, -z, y], [z, 0, -x], [-y, x, 0]] for x, y, z in g])  # (m c) × g
    rows[:, :, 4:] = np.eye(6)
    regressor = rows.reshape(6 * n, 10)
    regressor = regressor / np.linalg.norm(regressor, axis=0)
    sv = np.linalg.svd(regressor, compute_uv=False)
    excitation = result.excitation
    np.testing.assert_allclose(excitation.singular_values, sv / sv[0], atol=2e-3)
    assert excitation.n_determined == 10 and excitation.summary() in result.summary().splitlines()
    weaker = replace(excitation, singular_values=excitation.singular_values / [1, *[10.0] * 9], n_determined=9)
    text = replace(result, excitation=weaker).summary()
    assert "determine 9 of 10 parameter directions" in text
    assert f"{excitation.singular_values[1] / 10:.2g}" in text.splitlines()[-1]
    assert result.to_dict()["excitation"]["n_determined"] == 10


def test_the_retare_text_follows_its_numbers(identified):
    folder, _, _ = identified
    result = retare(folder / "p.json", str(folder / "later.csv"), orientation=("qx", "qy", "qz", "qw"))
    assert np.all(np.abs(result.change - SHIFT) < 5 * np.maximum(result.stderr, 1e-4) + 2e-3)
    text = result.summary()
    for axis, change in zip(("Fx", "Fz"), result.change[[0, 2]]):
        assert f"change since identification {change:+.4g} N" in text
    moved = [a for a, shift in zip(("Fx", "Fy", "Fz", "Tx", "Ty", "Tz"), SHIFT) if shift]  # far beyond the noise
    assert result.drifted == moved and f"on {', '.join(moved)}: the sensor drifted" in text
    assert "drift rate: unknown" in text and result.hours is None  # no time column
    # Other numbers, other text: half the change, within the noise; a drift rate over known hours.
    calm = replace(result, change=result.change / 2, z=np.zeros(6))
    assert f"change since identification {result.change[0] / 2:+.4g} N" in calm.summary()
    assert "within what the identification's uncertainty explains" in calm.summary() and calm.drifted == []
    hours = 2.5
    timed = replace(result, drift_rate=result.change / hours, hours=hours)
    line = next(line for line in timed.summary().splitlines() if "drift rate since" in line)
    assert line.startswith(f"  drift rate since identification ({hours:.3g} h): Fx {result.change[0] / hours:+.4g} N/h")
    assert result.to_dict()["drifted"] == moved
