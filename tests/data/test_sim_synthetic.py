"""Synthetic recordings: physics of the hanging load, labels, seeding."""

import numpy as np
import pytest

from ftcal.core.dataset import DEFAULT_INPUTS, DEFAULT_OUTPUTS
from ftcal.runtime.errors import FtcalError
from ftcal.sim.synthetic import ARM_MASS, GRAVITY, smooth_path, synthetic_recordings

LOADS = (0, 1, 2, 5, 7, 9, 10)


@pytest.fixture(scope="module")
def data():
    return synthetic_recordings(n_recordings=14, samples_per_recording=1500, seed=3)


def test_layout_segments_and_groups(data):
    assert data.n_samples == 14 * 1500
    assert data.input_names == DEFAULT_INPUTS and data.output_names == DEFAULT_OUTPUTS
    assert [b - a for a, b in data.segment_bounds()] == [1500] * 14
    labels = [data.groups[a] for a, _ in data.segment_bounds()]
    assert labels == [f"l{m}kg" for m in LOADS] * 2
    assert len(data.sources) == 14


def test_force_norm_is_the_weight_of_arm_and_load(data):
    for (a, b), load in zip(data.segment_bounds(), LOADS * 2):
        norm = np.linalg.norm(data.outputs[a:b, :3], axis=1)
        assert np.allclose(norm, (ARM_MASS + load) * GRAVITY)


def test_torque_is_perpendicular_to_a_gravity_force(data):
    # Every force is parallel to gravity, so tau = (sum m_i c_i) x g is orthogonal to f.
    f, tau = data.outputs[:, :3], data.outputs[:, 3:]
    assert np.allclose(np.einsum("ij,ij->i", f, tau), 0.0, atol=1e-9)


def test_raw_channels_are_roughly_in_wrench_units(data):
    true = np.linalg.norm(data.outputs[:, :3], axis=1)
    raw = np.linalg.norm(data.inputs[:, :3], axis=1)
    assert np.median(np.abs(raw - true) / true) < 0.2


def test_temperatures_start_at_the_requested_values(data):
    starts = [data.inputs[a, 6] for a, _ in data.segment_bounds()]
    assert starts == [25.0] * 7 + [32.0] * 7


def test_same_seed_same_data_other_seed_other_data(data):
    again = synthetic_recordings(n_recordings=14, samples_per_recording=1500, seed=3)
    other = synthetic_recordings(n_recordings=14, samples_per_recording=1500, seed=4)
    assert np.array_equal(data.inputs, again.inputs)
    assert np.array_equal(data.outputs, again.outputs)
    assert not np.array_equal(data.inputs, other.inputs)


def test_smooth_path_moves_with_minimum_jerk_and_holds():
    wp = np.array([[0.0], [1.0], [3.0]])
    path = smooth_path(wp, n_samples=600, move_s=2.0, hold_s=1.0, sample_rate=100.0)
    assert path[0, 0] == 0.0
    assert path[100, 0] == pytest.approx(0.5)  # s = 1/2: 10/8 - 15/16 + 6/32 = 1/2
    assert np.all(path[200:300, 0] == 1.0)     # hold on the second waypoint
    assert path[599, 0] == pytest.approx(3.0)
    assert np.all(np.diff(path[:, 0]) >= 0)


def test_bad_arguments_are_rejected():
    with pytest.raises(FtcalError, match="'n_recordings' parameter"):
        synthetic_recordings(n_recordings=0)
    with pytest.raises(FtcalError, match="'loads_kg' parameter"):
        synthetic_recordings(n_recordings=1, samples_per_recording=10, loads_kg=(-1,))
