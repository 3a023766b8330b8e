"""Right-arm joint trajectories like the paper's calibration motions (Section IV-A).

* ``grid``: the shoulder visits a boustrophedon grid of pitch × roll angles (with the yaw
  alternating between rows), so gravity sweeps about a quarter of a sphere in the arm
  sensor's frame; minimum-jerk moves with holds at each node.
* ``weight lifting``: from a rest pose the arm lifts the load as high as it can (the
  load then pulls along the sensor's z axis), moves around that lifted pose, and comes
  back down.

Angles are radians; every waypoint is clipped into the URDF joint limits (read with
iDynTree) minus a margin, and minimum-jerk blends between waypoints stay between them,
so the whole trajectory respects the limits.
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from pathlib import Path
from typing import NamedTuple

import numpy as np

from ..runtime.checks import check_float, check_int
from ..runtime.errors import FtcalError
from .synthetic import SAMPLE_RATE, smooth_path

ARM_JOINTS = ("r_shoulder_pitch", "r_shoulder_roll", "r_shoulder_yaw", "r_elbow",
              "r_wrist_prosup", "r_wrist_pitch", "r_wrist_yaw")
LIMIT_MARGIN = np.deg2rad(3.0)  # keep clear of the hardware end stops
REST = np.deg2rad([-10.0, 25.0, 0.0, 50.0, 0.0, 0.0, 0.0])
GRID_PITCH = np.deg2rad([-85.0, 0.0])
GRID_ROLL = np.deg2rad([15.0, 100.0])
GRID_YAW = np.deg2rad([0.0, 45.0])
LIFTED = np.deg2rad([-40.0, 140.0, 10.0, 25.0, 0.0, 0.0, 0.0])
LIFT_WANDER = np.deg2rad([15.0, 15.0, 25.0, 15.0, 30.0, 15.0, 10.0])


class JointTrajectory(NamedTuple):
    """Sampled joint positions.

    time : ndarray of shape (n_samples,), s from 0
    joint_names : names of the columns of ``positions``
    positions : ndarray of shape (n_samples, n_joints), rad
    """

    time: np.ndarray
    joint_names: tuple[str, ...]
    positions: np.ndarray


def load_idyntree():
    """Import ``idyntree.swig`` with its import-time DeprecationWarnings silenced.

    SWIG's module init warns; under ``-W error`` (our pytest setting) the warning becomes
    an exception inside the C extension's init and the interpreter crashes.
    """
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        import idyntree.swig as idyn
    return idyn


def joint_limits(urdf: str | Path, joints: Sequence[str] = ARM_JOINTS) -> np.ndarray:
    """Position limits of ``joints`` from a URDF, ndarray of shape (n_joints, 2), rad."""
    idyn = load_idyntree()
    loader = idyn.ModelLoader()
    if not loader.loadReducedModelFromFile(str(urdf), list(joints)):
        raise FtcalError(f"URDF {urdf}: iDynTree cannot load the joints {', '.join(joints)}.")
    model = loader.model()
    limits = np.empty((len(joints), 2))
    for i, name in enumerate(joints):
        joint = model.getJoint(model.getJointIndex(name))
        if not joint.hasPosLimits():
            raise FtcalError(f"URDF {urdf}: joint {name!r} has no position limits.")
        limits[i] = joint.getMinPosLimit(0), joint.getMaxPosLimit(0)
    return limits


def grid_trajectory(limits: np.ndarray, rows: int = 4, columns: int = 4, move_s: float = 3.0,
                    hold_s: float = 1.5, sample_rate: float = SAMPLE_RATE,
                    rng: np.random.Generator | None = None) -> JointTrajectory:
    """The grid trajectory of the right arm (``rows · columns`` nodes, plus rest at both ends).

    Parameters
    ----------
    limits : ndarray of shape (7, 2), limits of :data:`ARM_JOINTS` (see :func:`joint_limits`)
    rng : jitters every node by up to 3° per joint, so repeated recordings differ

    Returns
    -------
    JointTrajectory over :data:`ARM_JOINTS`, ``(rows · columns + 1) · (move_s + hold_s)`` s long
    """
    n_rows = check_int(rows, "rows", "grid_trajectory", 1)
    n_cols = check_int(columns, "columns", "grid_trajectory", 1)
    nodes = [REST]
    for r, pitch in enumerate(np.linspace(*GRID_PITCH, n_rows)):
        rolls = np.linspace(*GRID_ROLL, n_cols)
        for roll in rolls if r % 2 == 0 else rolls[::-1]:
            node = REST.copy()
            node[:3] = pitch, roll, GRID_YAW[r % 2]
            nodes.append(node)
    nodes.append(REST)
    return _sample(np.array(nodes), limits, move_s, hold_s, sample_rate, rng)


def weight_lifting_trajectory(limits: np.ndarray, wanders: int = 8, move_s: float = 3.0,
                              hold_s: float = 1.0, sample_rate: float = SAMPLE_RATE,
                              rng: np.random.Generator | None = None) -> JointTrajectory:
    """The weight-lifting trajectory: rest → lifted → ``wanders`` poses near it → rest.

    The wander poses are spread deterministically around the lifted pose (a jittered
    version with ``rng``), within :data:`LIFT_WANDER` of it per joint.

    Returns
    -------
    JointTrajectory over :data:`ARM_JOINTS`, ``(wanders + 3) · (move_s + hold_s)`` s long
    """
    n = check_int(wanders, "wanders", "weight_lifting_trajectory", 0)
    # Signs from a fixed pattern: every joint swings both ways during the wander.
    phase = np.arange(n)[:, None] * (1 + np.arange(7))[None, :]
    around = LIFTED + LIFT_WANDER * np.sin(2.0 * np.pi * phase / max(n, 1) + 0.7)
    nodes = np.vstack([REST, LIFTED, around, LIFTED, REST])
    return _sample(nodes, limits, move_s, hold_s, sample_rate, rng)


def _sample(nodes: np.ndarray, limits: np.ndarray, move_s: float, hold_s: float,
            sample_rate: float, rng: np.random.Generator | None) -> JointTrajectory:
    lim = np.asarray(limits, dtype=np.float64)
    if lim.shape != (len(ARM_JOINTS), 2) or np.any(lim[:, 1] - lim[:, 0] <= 2 * LIMIT_MARGIN):
        raise FtcalError(f"limits must have shape ({len(ARM_JOINTS)}, 2) with min < max "
                         f"(one row per joint of {', '.join(ARM_JOINTS)}).")
    move = check_float(move_s, "move_s", "trajectory", 0.0, low_inclusive=False)
    hold = check_float(hold_s, "hold_s", "trajectory", 0.0)
    rate = check_float(sample_rate, "sample_rate", "trajectory", 0.0, low_inclusive=False)
    if rng is not None:
        nodes = nodes + rng.uniform(-1, 1, size=nodes.shape) * np.deg2rad(3.0)
    nodes = np.clip(nodes, lim[:, 0] + LIMIT_MARGIN, lim[:, 1] - LIMIT_MARGIN)
    # Each node but the last gets a move towards the next and a hold there.
    n_samples = int(round((len(nodes) - 1) * (move + hold) * rate))
    positions = smooth_path(nodes, n_samples, move, hold, rate)
    return JointTrajectory(np.arange(n_samples) / rate, ARM_JOINTS, positions)
