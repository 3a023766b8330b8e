"""A wrist sensor while the robot runs, with known truth: drifting bias, poses, moves, contacts, tool swaps.

The sensor reads ``bias(t) + tool gravity wrench + contact + noise`` (ftcal's sign convention). The
bias is a random walk plus a ramp (the UR wrist sensor that drifts 0 → 4 N in 5 minutes); the
sensor holds random orientations and moves between them (smooth, slow enough that the tool's
inertial wrench stays below the noise); a contact is a force (and its torque about a point on
the tool) held in one pose; tools are swapped at given times while the robot holds still.
The truth (bias, tool wrench, contact) is returned beside the readings, for tests and the demo.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

AXES = ("Fx", "Fy", "Fz", "Tx", "Ty", "Tz")


@dataclass(frozen=True)
class Tool:
    """A rigid tool: mass (kg) and centre of mass (m, sensor frame)."""

    mass: float
    com: tuple[float, float, float]


@dataclass(frozen=True)
class LiveScenario:
    """What happens during the recording.

    Attributes
    ----------
    duration : s
    rate : Hz
    hold_s, move_s : s per static hold and per move between holds
    noise : per-sample noise std, force (N) and torque (N·m)
    walk : random-walk std per √h, force and torque
    ramp : bias slope per hour, force and torque (one direction per axis, drawn)
    tools : name → Tool; the first is mounted at the start
    swaps : (time s, tool name) tool changes (the robot holds still for the swap)
    contacts : (start s, duration s, force N) contacts along a drawn direction, at 5 cm on the tool
    seed : random seed
    """

    duration: float = 300.0
    rate: float = 500.0
    hold_s: float = 4.0
    move_s: float = 2.0
    noise: tuple[float, float] = (0.05, 0.004)
    walk: tuple[float, float] = (3.0, 0.3)
    ramp: tuple[float, float] = (20.0, 1.0)
    tools: dict = field(default_factory=lambda: {"gripper": Tool(1.2, (0.004, -0.003, 0.06)),
                                                 "drill": Tool(2.1, (0.02, 0.01, 0.09))})
    swaps: tuple = ()
    contacts: tuple = ()
    seed: int = 0


@dataclass
class LiveRecording:
    """Readings and truth, one row per sample (ftcal's sign convention)."""

    time: np.ndarray  # (n,)
    quaternion: np.ndarray  # (n, 4) sensor to world, x y z w
    gravity: np.ndarray  # (n, 3) in sensor axes
    wrench: np.ndarray  # (n, 6) what the sensor reads
    bias: np.ndarray  # (n, 6) true bias
    tool_wrench: np.ndarray  # (n, 6) true gravity wrench of the mounted tool
    contact: np.ndarray  # (n, 6) true contact wrench
    tool: np.ndarray  # (n,) object, mounted tool's name
    holding: np.ndarray  # (n,) bool, the robot holds a pose
    pose: np.ndarray  # (n,) int, pose number (-1 while moving)

    def frame(self):
        """The readings as a table (``time``, ``qx..qw``, ``Fx..Tz``, ``tool``), as a recorder would write it."""
        import pandas as pd

        cols = {"time": self.time}
        cols.update({c: self.quaternion[:, i] for i, c in enumerate(("qx", "qy", "qz", "qw"))})
        cols.update({c: self.wrench[:, i] for i, c in enumerate(AXES)})
        return pd.DataFrame(cols)


def simulate_live(s: LiveScenario = LiveScenario()) -> LiveRecording:
    """Simulate the scenario.

    Returns
    -------
    LiveRecording
    """
    from scipy.spatial.transform import Rotation, Slerp

    rng = np.random.default_rng(s.seed)
    n = int(round(s.duration * s.rate))
    t = np.arange(n) / s.rate
    period = s.hold_s + s.move_s
    n_poses = int(np.ceil(s.duration / period)) + 1
    # Orientations spread over the sphere of gravity directions, tool never far above the horizon.
    poses = Rotation.from_quat(_unit(rng.normal(size=(n_poses, 4))))
    k = np.minimum((t // period).astype(int), n_poses - 2)
    phase = t - k * period
    holding = phase < s.hold_s
    blend = np.clip((phase - s.hold_s) / s.move_s, 0.0, 1.0)
    blend = blend * blend * (3.0 - 2.0 * blend)  # smooth start and stop
    q = np.empty((n, 4))
    for pose in np.unique(k):
        rows = k == pose
        slerp = Slerp([0.0, 1.0], Rotation.concatenate([poses[pose], poses[pose + 1]]))
        q[rows] = slerp(blend[rows]).as_quat()
    gravity = Rotation.from_quat(q).inv().apply([0.0, 0.0, -9.81])
    # Bias: random walk + ramp, starting from a drawn offset.
    sigma = np.r_[np.full(3, s.walk[0]), np.full(3, s.walk[1])] / np.sqrt(3600.0)
    steps = rng.normal(size=(n, 6)) * sigma * np.sqrt(1.0 / s.rate)
    steps[0] = 0.0
    slope = np.r_[np.full(3, s.ramp[0]), np.full(3, s.ramp[1])] / 3600.0 * rng.choice([-1.0, 1.0], 6)
    bias = rng.normal(size=6) * np.r_[np.full(3, 2.0), np.full(3, 0.2)] + np.cumsum(steps, axis=0) + np.outer(t, slope)
    # Tools: swaps switch the mounted one.
    names = list(s.tools)
    tool = np.full(n, names[0], dtype=object)
    for when, name in sorted(s.swaps):
        tool[t >= when] = name
    tool_wrench = np.zeros((n, 6))
    for name, spec in s.tools.items():
        rows = tool == name
        mc = spec.mass * np.asarray(spec.com)
        tool_wrench[rows, :3] = spec.mass * gravity[rows]
        tool_wrench[rows, 3:] = np.cross(mc, gravity[rows])
    contact = np.zeros((n, 6))
    for start, length, force in s.contacts:
        rows = (t >= start) & (t < start + length)
        direction = _unit(rng.normal(size=(1, 3)))[0]
        ramp = np.clip(np.minimum(t[rows] - start, start + length - t[rows]) / 0.05, 0.0, 1.0)  # 50 ms edges
        f = force * direction * ramp[:, None]
        contact[rows, :3] = f
        contact[rows, 3:] = np.cross([0.0, 0.0, 0.05], f)
    noise = rng.normal(size=(n, 6)) * np.r_[np.full(3, s.noise[0]), np.full(3, s.noise[1])]
    wrench = bias + tool_wrench + contact + noise
    return LiveRecording(t, q, gravity, wrench, bias, tool_wrench, contact, tool, holding,
                         np.where(holding, k, -1))


def _unit(x: np.ndarray) -> np.ndarray:
    return x / np.linalg.norm(x, axis=1, keepdims=True)
