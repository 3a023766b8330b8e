"""Candidate poses: random joint configurations within limits, pins and a minimum sensor height.

Only the joints on the kinematic chain from the base to the sensor move the
sensor frame; they are sampled uniformly within their (narrowed) limits. Every
other movable joint stays at 0 unless pinned with a value. A minimum height
keeps the sensor origin above the base's xy-plane; it is the only safety
check: ftcal does no collision checking.

Every configuration is paired with every load, and the expected wrench of all
of them comes from one batched iDynTree pass per load.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from ..robot.expected import expected_wrenches
from ..robot.kinematics import sensor_poses
from ..robot.model import RobotModel
from ..robot.payloads import Payload
from ..runtime.errors import FtcalError, ParameterError

GRAVITY = (0.0, 0.0, -9.81)
# Draw at most this many batches of configurations while looking for ones above the minimum height.
MAX_DRAWS = 20


@dataclass(frozen=True)
class JointSpace:
    """Which joints move and where.

    Attributes
    ----------
    joint_names : all movable joints of the model, in its order
    free : names of the sampled joints (the chain to the sensor, minus pinned ones)
    lower, upper : ndarray of shape (n_free,), rad, the sampling box
    fixed : pinned joint values (rad) by name; every other joint is 0
    """

    joint_names: tuple[str, ...]
    free: tuple[str, ...]
    lower: np.ndarray
    upper: np.ndarray
    fixed: Mapping[str, float]

    @property
    def columns(self) -> tuple[str, ...]:
        """Joints a plan lists: the free ones then the pinned ones, in the model's order."""
        used = set(self.free) | set(self.fixed)
        return tuple(n for n in self.joint_names if n in used)

    def sample(self, n: int, rng: np.random.Generator) -> np.ndarray:
        """``n`` configurations, ndarray of shape (n, n_dofs) in the order of :attr:`joint_names`."""
        q = np.zeros((n, len(self.joint_names)))
        index = {name: i for i, name in enumerate(self.joint_names)}
        for name, value in self.fixed.items():
            q[:, index[name]] = value
        cols = [index[name] for name in self.free]
        q[:, cols] = rng.uniform(self.lower, self.upper, size=(n, len(cols)))
        return q

    def free_values(self, q: np.ndarray) -> np.ndarray:
        """The free joints' columns of ``q`` (n, n_dofs) → (n, n_free)."""
        index = {name: i for i, name in enumerate(self.joint_names)}
        return q[:, [index[name] for name in self.free]]


def chain_joints(robot: RobotModel, sensor: str, base: str | None = None) -> tuple[str, ...]:
    """Movable joints on the path from the base frame's link to the sensor's parent link.

    Returns
    -------
    tuple of joint names, in the model's joint order
    """
    m = robot.model
    ft = robot.sensor(sensor)
    start = m.getFrameLink(robot.base_frame(base)[0])
    goal = m.getLinkIndex(ft.parent_link)
    came_from: dict[int, tuple[int, int]] = {start: (-1, -1)}
    frontier = [start]
    while frontier and goal not in came_from:
        nxt = []
        for link in frontier:
            for j in range(m.getNrOfJoints()):
                joint = m.getJoint(j)
                a, b = joint.getFirstAttachedLink(), joint.getSecondAttachedLink()
                other = b if a == link else a if b == link else None
                if other is not None and other not in came_from:
                    came_from[other] = (link, j)
                    nxt.append(other)
        frontier = nxt
    on_path = set()
    link = goal
    while link != start and link in came_from:
        link, j = came_from[link]
        on_path.add(m.getJointName(j))
    return tuple(n for n in robot.joint_names if n in on_path)


def joint_limits(robot: RobotModel, name: str) -> tuple[float, float]:
    """URDF position limits of a movable joint (rad); (−π, π) for a joint without limits."""
    m = robot.model
    joint = m.getJoint(m.getJointIndex(name))
    if joint.hasPosLimits():
        return float(joint.getMinPosLimit(0)), float(joint.getMaxPosLimit(0))
    return -math.pi, math.pi


def joint_space(robot: RobotModel, sensor: str, base: str | None = None, *,
                ranges: Mapping[str, tuple[float, float]] | None = None,
                fixed: Mapping[str, float] | None = None) -> JointSpace:
    """The sampling box: URDF limits of the chain joints, narrowed by ``ranges``, minus ``fixed`` joints.

    Parameters
    ----------
    robot, sensor, base : the model, its F/T sensor, the fixed base frame
    ranges : joint name → (low, high) in rad, narrowing the URDF limits (``--joint-range``)
    fixed : joint name → value in rad (``--fixed``); any movable joint

    Raises
    ------
    FtcalError
        Unknown joint, a range on a joint off the chain, an empty range, a pin
        outside the joint's limits, or no free joint left.
    """
    ranges = dict(ranges or {})
    fixed = {k: float(v) for k, v in (fixed or {}).items()}
    known = set(robot.joint_names)
    chain = chain_joints(robot, sensor, base)
    for parameter, names in (("joint_range", ranges), ("fixed", fixed)):
        for name in names:
            if name not in known:
                raise ParameterError(parameter, f"{{{parameter}}} {name}: no movable joint of that name in URDF {robot.source} "
                                 f"(its joints: {', '.join(robot.joint_names[:8])}"
                                 f"{', ...' if len(robot.joint_names) > 8 else ''}).")
    for name in ranges:
        if name not in chain:
            raise ParameterError('joint_range', f"{{joint_range}} {name}: the joint is not on the chain from the base to the sensor, "
                             f"so it does not move the sensor (chain: {', '.join(chain) or 'none'}).")
        if name in fixed:
            raise ParameterError(('joint_range', 'fixed'), f"{{joint_range}} {name}: the joint is also pinned with {{fixed}}; give one of them.")
    for name, value in fixed.items():
        lo, hi = joint_limits(robot, name)
        if not lo <= value <= hi:
            raise ParameterError('fixed', f"{{fixed}} {name}={value:g}: outside the joint's URDF limits [{lo:g}, {hi:g}] rad.")
    free = tuple(n for n in chain if n not in fixed)
    if not free:
        raise FtcalError(f"no joint left to move the sensor: the chain from the base to the sensor "
                         f"({', '.join(chain) or 'no movable joint'}) is all pinned.")
    lower, upper = np.empty(len(free)), np.empty(len(free))
    for i, name in enumerate(free):
        lo, hi = joint_limits(robot, name)
        if name in ranges:
            lo, hi = max(lo, ranges[name][0]), min(hi, ranges[name][1])
            if not lo < hi:
                raise ParameterError('joint_range', f"{{joint_range}} {name}:{ranges[name][0]:g}:{ranges[name][1]:g}: empty within "
                                 f"the URDF limits {joint_limits(robot, name)} rad.")
        lower[i], upper[i] = lo, hi
    return JointSpace(robot.joint_names, free, lower, upper, fixed)


@dataclass(frozen=True)
class Candidates:
    """Configurations to choose from, each under every load.

    Attributes
    ----------
    q : ndarray of shape (n_configurations, n_dofs), rad
    height : ndarray of shape (n_configurations,), m, sensor origin above the base's xy-plane
    gravity : ndarray of shape (n_configurations, 3), m/s², gravity in sensor axes
    wrench : ndarray of shape (n_configurations, n_loads, 6), expected Fx..Tz (N, N m)
    """

    q: np.ndarray
    height: np.ndarray
    gravity: np.ndarray
    wrench: np.ndarray

    @property
    def n_configurations(self) -> int:
        return self.q.shape[0]

    @property
    def n_loads(self) -> int:
        return self.wrench.shape[1]


def reachable_configurations(robot: RobotModel, sensor: str, space: JointSpace, n: int,
                             rng: np.random.Generator, *, base: str | None = None,
                             min_height: float | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``n`` random configurations whose sensor origin is at least ``min_height`` above the base plane.

    Returns
    -------
    q : ndarray of shape (n_found, n_dofs)
    height : ndarray of shape (n_found,), m
    gravity : ndarray of shape (n_found, 3), gravity in sensor axes, m/s²

    ``n_found`` is below ``n`` only when :data:`MAX_DRAWS` batches of ``n``
    draws did not give enough configurations above ``min_height``.
    """
    kept: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []
    found = 0
    for _ in range(MAX_DRAWS):
        q = space.sample(n, rng)
        poses = sensor_poses(robot, sensor, q, base=base)
        height = poses[:, 2, 3]
        ok = np.ones(n, dtype=bool) if min_height is None else height >= min_height
        gravity = np.einsum("nji,j->ni", poses[:, :3, :3], np.asarray(GRAVITY))
        kept.append((q[ok], height[ok], gravity[ok]))
        found += int(ok.sum())
        if found >= n:
            break
    q, height, gravity = (np.concatenate(parts)[:n] for parts in zip(*kept))
    return q, height, gravity


def candidate_poses(robot: RobotModel, sensor: str, space: JointSpace, loads: Sequence[Payload | None],
                    n: int, rng: np.random.Generator, *, base: str | None = None,
                    min_height: float | None = None) -> Candidates:
    """Draw ``n`` configurations (see :func:`reachable_configurations`) and their expected wrenches per load.

    Parameters
    ----------
    loads : the loads, None for nothing mounted
    """
    q, height, gravity = reachable_configurations(robot, sensor, space, n, rng, base=base, min_height=min_height)
    index = robot.sensor(sensor).index
    wrench = np.empty((q.shape[0], len(loads), 6))
    for k, load in enumerate(loads):
        loaded = robot if load is None else robot.with_payloads([load])
        wrench[:, k] = expected_wrenches(loaded, q, base=base, gravity=GRAVITY, workers=1,
                                         description=f"expected wrenches, load {k}")[:, index]
    return Candidates(q, height, gravity, wrench)
