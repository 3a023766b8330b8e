"""A simulated robot arm whose wrist F/T sensor carries an unknown gripper, recorded into a ROS 2 bag.

The wrist visits ``n_poses`` random orientations (uniform over rotations),
slerping between them and holding each one still, as one does to identify a
tool's mass, centre of mass and the sensor's bias. The sensor reads, in its
own frame (ROS force_torque_tools convention: a tool at rest adds
``m · g_sensor``):

* force ``f = b_f(T) + m (g_s − a_c)`` and torque
  ``τ = b_τ + c × m (g_s − a_c) − I α − ω × I ω``, with ``g_s`` gravity (0, 0, −g) of the
  world in the sensor frame, ``c`` the gripper's centre of mass, ``a_c = α × c + ω × (ω × c)``
  its acceleration (the wrist rotates about the sensor origin), ``I`` its inertia about the COM;
* a force bias that drifts with temperature (``force_bias_tc`` N/°C from ``temperature_start``),
  plus Gaussian noise.

Topics (ROS 2, header stamps set, epoch time):

=================================  =============================  =======
``/ft_sensor/wrench``              geometry_msgs/WrenchStamped    ``rate``
``/tf``                            base_link → wrist_link         ``tf_rate``
``/tf_static``                     wrist_link → ft_sensor         once
``/imu``                           sensor_msgs/Imu on the sensor  ``imu_rate``
``/ft_sensor/temperature``         sensor_msgs/Temperature        10 Hz
=================================  =============================  =======

``base_link`` is gravity-aligned (z up), so ``ftcal dataset BAG --wrench-topic
/ft_sensor/wrench --tf base_link:ft_sensor`` gives the sensor orientation.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..runtime.errors import FtcalError

WRENCH_TOPIC = "/ft_sensor/wrench"
IMU_TOPIC = "/imu"
TEMPERATURE_TOPIC = "/ft_sensor/temperature"
JOINTS_TOPIC = "/joint_states"
BASE_FRAME, WRIST_FRAME, SENSOR_FRAME = "base_link", "wrist_link", "ft_sensor"
START_NS = 1_700_000_000 * 10**9
TEMPERATURE_RATE = 10.0  # Hz


@dataclass(frozen=True)
class ArmScenario:
    """The simulated gripper, sensor and motion (units: kg, m, N, N m, °C, s, Hz).

    ``mounting`` is the fixed rotation wrist_link → ft_sensor as a rotation vector (rad).
    """

    gripper_mass: float = 1.35
    gripper_com: tuple[float, float, float] = (0.012, -0.008, 0.085)
    gripper_inertia: tuple[float, float, float] = (0.004, 0.004, 0.002)
    force_bias: tuple[float, float, float] = (4.2, -3.1, 7.5)
    torque_bias: tuple[float, float, float] = (0.21, -0.12, 0.05)
    force_bias_tc: tuple[float, float, float] = (0.03, -0.02, 0.05)
    temperature_start: float = 28.0
    temperature_end: float = 34.0
    force_noise: float = 0.05
    torque_noise: float = 0.002
    gravity: float = 9.81
    n_poses: int = 24
    hold_s: float = 2.0
    move_s: float = 1.5
    rate: float = 500.0
    tf_rate: float = 100.0
    imu_rate: float = 200.0
    mounting: tuple[float, float, float] = (0.0, 0.0, np.pi / 4)
    seed: int = 0

    def __post_init__(self) -> None:
        if not (self.gripper_mass > 0 and self.n_poses >= 3 and self.hold_s > 0 and self.move_s > 0
                and min(self.rate, self.tf_rate, self.imu_rate) > 0):
            raise FtcalError("ArmScenario: mass, hold_s, move_s and rates must be > 0 and n_poses >= 3.")


@dataclass(frozen=True)
class ArmTruth:
    """What the simulation used: the values a payload identification should recover."""

    path: Path
    mass: float
    com: np.ndarray
    force_bias: np.ndarray
    torque_bias: np.ndarray
    force_bias_tc: np.ndarray
    temperature_reference: float
    gravity: float
    holds: list[tuple[float, float]] = field(default_factory=list)


def write_arm_bag(path: str | Path, scenario: ArmScenario = ArmScenario(), storage: str = "mcap") -> ArmTruth:
    """Simulate ``scenario`` and record it into a ROS 2 bag folder at ``path``.

    Parameters
    ----------
    path : str or Path
        The bag folder to create (must not exist).
    scenario : ArmScenario
    storage : {"mcap", "sqlite3"}

    Returns
    -------
    ArmTruth
        The true gripper and bias, and the (start, end) epoch seconds of each still hold.

    Raises
    ------
    FtcalError
        If ``path`` exists or ``storage`` is unknown.
    """
    from rosbags.rosbag2 import StoragePlugin, Writer
    from scipy.spatial.transform import Rotation

    path = Path(path)
    if path.exists():
        raise FtcalError(f"{path}: already exists; the arm bag is written into a new folder.")
    plugins = {"mcap": StoragePlugin.MCAP, "sqlite3": StoragePlugin.SQLITE3}
    if storage not in plugins:
        raise FtcalError(f"The 'storage' parameter must be 'mcap' or 'sqlite3'. Got {storage!r} instead.")
    s = scenario
    rng = np.random.default_rng(s.seed)
    poses = Rotation.from_quat(_unit(rng.normal(size=(s.n_poses, 4))))  # uniform over rotations
    period = s.hold_s + s.move_s
    duration = s.n_poses * period - s.move_s
    mounting = Rotation.from_rotvec(s.mounting)

    def wrist(t: np.ndarray) -> Rotation:
        """base_link → wrist_link: hold pose k, then a smooth (minimum-jerk) slerp to pose k + 1."""
        k = np.clip((t // period).astype(int), 0, s.n_poses - 1)
        phase = np.clip((t - k * period - s.hold_s) / s.move_s, 0.0, 1.0)
        blend = phase ** 3 * (10 - 15 * phase + 6 * phase ** 2)
        nxt = np.minimum(k + 1, s.n_poses - 1)
        delta = (poses[k].inv() * poses[nxt]).as_rotvec()
        return poses[k] * Rotation.from_rotvec(delta * blend[:, None])

    def sensor(t: np.ndarray) -> Rotation:
        return wrist(t) * mounting

    t_ft = np.arange(int(duration * s.rate) + 1) / s.rate
    temperature = s.temperature_start + (s.temperature_end - s.temperature_start) * t_ft / duration
    wrench = _sensor_wrench(s, sensor, t_ft, temperature)
    wrench[:, :3] += rng.normal(0.0, s.force_noise, (t_ft.size, 3))
    wrench[:, 3:] += rng.normal(0.0, s.torque_noise, (t_ft.size, 3))

    writer = Writer(path, version=9, storage_plugin=plugins[storage])
    with writer:
        messages = BagMessages(writer)
        for k, t in enumerate(t_ft):
            messages.wrench(t, wrench[k])
        t_tf = np.arange(int(duration * s.tf_rate) + 1) / s.tf_rate
        for t, q in zip(t_tf, wrist(t_tf).as_quat()):
            messages.tf(t, BASE_FRAME, WRIST_FRAME, q, static=False)
        messages.tf(0.0, WRIST_FRAME, SENSOR_FRAME, mounting.as_quat(), static=True)
        t_imu = np.arange(int(duration * s.imu_rate) + 1) / s.imu_rate
        omega, _, gravity_s = _motion(sensor, t_imu, s.gravity)
        for k, (t, q) in enumerate(zip(t_imu, sensor(t_imu).as_quat())):
            messages.imu(t, q, omega[k], -gravity_s[k])  # an accelerometer at rest reads −g
        t_temp = np.arange(int(duration * TEMPERATURE_RATE) + 1) / TEMPERATURE_RATE
        for t in t_temp:
            messages.temperature(t, s.temperature_start + (s.temperature_end - s.temperature_start) * t / duration)
        messages.flush()
    holds = [(START_NS * 1e-9 + k * period, START_NS * 1e-9 + k * period + s.hold_s) for k in range(s.n_poses)]
    return ArmTruth(path, s.gripper_mass, np.array(s.gripper_com), np.array(s.force_bias), np.array(s.torque_bias),
                    np.array(s.force_bias_tc), s.temperature_start, s.gravity, holds)


def _motion(sensor, t: np.ndarray, g: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Angular velocity and acceleration (sensor frame, by central differences) and gravity in the sensor frame."""
    h = 1e-4
    before, now, after = sensor(t - h), sensor(t), sensor(t + h)
    omega = (now.inv() * after).as_rotvec() / h  # body-frame angular velocity
    omega_before = (before.inv() * now).as_rotvec() / h
    alpha = (omega - omega_before) / h
    gravity_s = now.inv().apply(np.array([0.0, 0.0, -g]))
    return omega, alpha, gravity_s


def _sensor_wrench(s: ArmScenario, sensor, t: np.ndarray, temperature: np.ndarray) -> np.ndarray:
    omega, alpha, gravity_s = _motion(sensor, t, s.gravity)
    c = np.asarray(s.gripper_com)
    inertia = np.asarray(s.gripper_inertia)
    a_com = np.cross(alpha, c) + np.cross(omega, np.cross(omega, c))
    force = s.gripper_mass * (gravity_s - a_com)
    torque = np.cross(c, force) - alpha * inertia - np.cross(omega, omega * inertia)
    drift = np.outer(temperature - s.temperature_start, s.force_bias_tc)
    return np.hstack([force + np.asarray(s.force_bias) + drift, torque + np.asarray(s.torque_bias)])


class BagMessages:
    """Serializes messages with rosbags' ROS 2 types and writes them in time order.

    ``topics`` overrides the topic names of the arm scenario (keys ``wrench``, ``imu``,
    ``temperature``, ``joints``); ``frame`` is the header frame of the sensor's messages.
    """

    def __init__(self, writer, topics: dict[str, str] | None = None, frame: str = SENSOR_FRAME) -> None:
        from rosbags.typesys import Stores, get_typestore

        self.ts = get_typestore(Stores.ROS2_HUMBLE)
        self.types = self.ts.types
        self.writer = writer
        self.topics = {"wrench": WRENCH_TOPIC, "imu": IMU_TOPIC, "temperature": TEMPERATURE_TOPIC,
                       "joints": JOINTS_TOPIC, **(topics or {})}
        self.frame = frame
        self.pending: list[tuple[int, str, object, str]] = []
        self.connections: dict[str, object] = {}

    def _header(self, t: float, frame: str):
        ns = START_NS + int(round(t * 1e9))
        stamp = self.types["builtin_interfaces/msg/Time"](ns // 10**9, ns % 10**9)
        return ns, self.types["std_msgs/msg/Header"](stamp, frame)

    def _vec(self, v):
        return self.types["geometry_msgs/msg/Vector3"](*map(float, v))

    def _add(self, ns: int, topic: str, msg, msgtype: str) -> None:
        self.pending.append((ns, topic, msg, msgtype))

    def wrench(self, t: float, w: np.ndarray) -> None:
        ns, header = self._header(t, self.frame)
        msg = self.types["geometry_msgs/msg/WrenchStamped"](
            header, self.types["geometry_msgs/msg/Wrench"](self._vec(w[:3]), self._vec(w[3:])))
        self._add(ns, self.topics["wrench"], msg, "geometry_msgs/msg/WrenchStamped")

    def tf(self, t: float, parent: str, child: str, q: np.ndarray, static: bool,
           translation: np.ndarray | None = None) -> None:
        ns, header = self._header(t, parent)
        if translation is None:
            translation = (0.0, 0.0, 0.0) if static else (0.4, 0.1, 0.6)
        transform = self.types["geometry_msgs/msg/Transform"](
            self._vec(translation), self.types["geometry_msgs/msg/Quaternion"](*map(float, q)))
        msg = self.types["tf2_msgs/msg/TFMessage"]([self.types["geometry_msgs/msg/TransformStamped"](
            header, child, transform)])
        self._add(ns, "/tf_static" if static else "/tf", msg, "tf2_msgs/msg/TFMessage")

    def imu(self, t: float, q: np.ndarray, omega: np.ndarray, accel: np.ndarray) -> None:
        ns, header = self._header(t, self.frame)
        zeros = np.zeros(9)
        msg = self.types["sensor_msgs/msg/Imu"](header, self.types["geometry_msgs/msg/Quaternion"](*map(float, q)),
                                                zeros, self._vec(omega), zeros, self._vec(accel), zeros)
        self._add(ns, self.topics["imu"], msg, "sensor_msgs/msg/Imu")

    def temperature(self, t: float, value: float) -> None:
        ns, header = self._header(t, self.frame)
        self._add(ns, self.topics["temperature"], self.types["sensor_msgs/msg/Temperature"](header, float(value), 0.01),
                  "sensor_msgs/msg/Temperature")

    def joint_state(self, t: float, names: list[str], position: np.ndarray, velocity: np.ndarray) -> None:
        ns, header = self._header(t, "")
        msg = self.types["sensor_msgs/msg/JointState"](header, list(names), np.asarray(position, dtype=np.float64),
                                                       np.asarray(velocity, dtype=np.float64), np.zeros(0))
        self._add(ns, self.topics["joints"], msg, "sensor_msgs/msg/JointState")

    def flush(self) -> None:
        """Write everything in receive-time order (receive time = header stamp here; ties keep the call order)."""
        for ns, topic, msg, msgtype in sorted(self.pending, key=lambda m: m[0]):
            if topic not in self.connections:
                self.connections[topic] = self.writer.add_connection(topic, msgtype, typestore=self.ts)
            self.writer.write(self.connections[topic], ns, self.ts.serialize_cdr(msg, msgtype))


def _unit(x: np.ndarray) -> np.ndarray:
    return x / np.linalg.norm(x, axis=1, keepdims=True)
