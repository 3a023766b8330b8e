"""Right-arm calibration trajectories: URDF limits, timing, smoothness."""

import xml.etree.ElementTree as ET

import icub_models
import numpy as np
import pytest

from ftcal.runtime.errors import FtcalError
from ftcal.sim.trajectories import ARM_JOINTS, grid_trajectory, joint_limits, weight_lifting_trajectory

URDF = icub_models.get_model_file("iCubGenova11")


@pytest.fixture(scope="module")
def limits():
    return joint_limits(URDF)


def test_limits_are_the_urdf_limits(limits):
    root = ET.parse(URDF).getroot()
    for name, (low, high) in zip(ARM_JOINTS, limits):
        tag = root.find(f"joint[@name='{name}']/limit")
        assert low == pytest.approx(float(tag.get("lower")))
        assert high == pytest.approx(float(tag.get("upper")))


@pytest.mark.parametrize("make", [grid_trajectory, weight_lifting_trajectory])
def test_trajectories_respect_limits_and_run_at_100_hz(limits, make):
    traj = make(limits, rng=np.random.default_rng(0))
    assert traj.joint_names == ARM_JOINTS
    assert traj.positions.shape == (len(traj.time), 7)
    assert np.allclose(np.diff(traj.time), 0.01)
    assert 30.0 <= traj.time[-1] <= 90.0
    assert np.all(traj.positions >= limits[:, 0]) and np.all(traj.positions <= limits[:, 1])
    # Smooth: no jump bigger than a fast joint (3 rad/s) covers in one sample.
    assert np.abs(np.diff(traj.positions, axis=0)).max() < 0.03


def test_grid_duration_counts_its_nodes(limits):
    traj = grid_trajectory(limits, rows=3, columns=2, move_s=2.0, hold_s=1.0)
    # 3 * 2 grid nodes + rest at both ends: 7 moves of 3 s.
    assert len(traj.time) == 7 * 3 * 100


def test_grid_sweeps_shoulder_pitch_and_roll(limits):
    traj = grid_trajectory(limits)
    span = np.rad2deg(np.ptp(traj.positions, axis=0))
    assert span[0] > 80 and span[1] > 80  # shoulder pitch and roll


def test_weight_lifting_raises_the_arm_above_the_grid(limits):
    lift = weight_lifting_trajectory(limits)
    grid = grid_trajectory(limits)
    assert lift.positions[:, 1].max() > grid.positions[:, 1].max() + np.deg2rad(20)


def test_bad_limits_are_rejected():
    with pytest.raises(FtcalError, match="limits must have shape"):
        grid_trajectory(np.zeros((3, 2)))
