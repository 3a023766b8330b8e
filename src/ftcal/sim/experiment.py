"""The paper's in-situ experiment, simulated end to end into robot-logger files.

For every load on the right forearm support (the paper's 0, 1, 2, 5, 7, 9, 10 kg; the
support itself is always there), every start temperature and every trajectory (grid,
weight lifting):

    joint trajectory (``ftcal.sim.trajectories``)
      → true wrench at the right-arm F/T sensor (``ftcal.robot``, iDynTree; with the
        joint velocities and accelerations unless ``dynamic=False``)
      → simulated sensor (``ftcal.sim.sensor``) at a slowly drifting temperature
      → ``<folder>/l0kg-r<load>kg/<trajectory>_<temperature>C.mat`` (``ftcal.sim.logger_mat``)

Streams have their own clocks, as on the robot: F/T at ``ft_rate``, joints at
``joint_rate`` shifted by ``joint_delay``, temperature at ``temperature_rate``. A
``manifest.json`` in ``folder`` lists every recording with its payloads (in the
``FRAME:MASS@X,Y,Z`` syntax of :func:`ftcal.robot.payloads.parse_payload_spec`) and its
temperatures.
"""

from __future__ import annotations

import dataclasses
import json
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..runtime.atomic import write_text_atomic
from ..runtime.checks import check_choice, check_float
from ..runtime.errors import FtcalError
from ..runtime.progress import track
from .logger_mat import RobotLog, Stream, write_robot_log
from .sensor import StrainGaugeSensor, temperature_drift
from .trajectories import (
    ARM_JOINTS,
    JointTrajectory,
    grid_trajectory,
    joint_limits,
    load_idyntree,
    weight_lifting_trajectory,
)

PAPER_LOADS = (0.0, 1.0, 2.0, 5.0, 7.0, 9.0, 10.0)
TRAJECTORIES = ("grid", "lifting")
# The logger's joint order (not iDynTree's): readers must map joints by name.
LOGGED_JOINTS = ("torso_pitch", "torso_roll", "torso_yaw", "neck_pitch", "neck_roll", "neck_yaw",
                 "l_shoulder_pitch", "l_shoulder_roll", "l_shoulder_yaw", "l_elbow",
                 "l_wrist_prosup", "l_wrist_pitch", "l_wrist_yaw", *ARM_JOINTS,
                 "l_hip_pitch", "l_hip_roll", "l_hip_yaw", "l_knee", "l_ankle_pitch", "l_ankle_roll",
                 "r_hip_pitch", "r_hip_roll", "r_hip_yaw", "r_knee", "r_ankle_pitch", "r_ankle_roll")
START_EPOCH = 1.7e9  # s, a plausible YARP clock value


@dataclass(frozen=True)
class ExperimentConfig:
    """What to simulate.

    robot : icub-models name (its URDF gives kinematics, inertias and joint limits)
    sensor : F/T sensor name, also the name of its streams in the files
    loads_kg : plate masses on the support, one folder each
    support_kg, load_frame, load_com : the support's mass, and the link and centre of
        mass (m, in that link's frame) of the support and of the plates
    temperatures : start temperature (°C) of each repetition; each recording then drifts
        up by 1–3 °C towards the motors' heat (``temperature_time_constant`` s)
    trajectories : any of ``"grid"``, ``"lifting"``
    ft_rate, joint_rate, temperature_rate : Hz; ``joint_delay`` s between the clocks
    dynamic : true wrench with joint velocities and accelerations (else static)
    version, layout : see :func:`ftcal.sim.logger_mat.write_robot_log`
    seed : sensor draw and all randomness
    """

    robot: str = "iCubGenova11"
    sensor: str = "r_arm_ft"
    loads_kg: tuple[float, ...] = PAPER_LOADS
    support_kg: float = 0.6
    load_frame: str = "r_forearm"
    load_com: tuple[float, float, float] = (-0.09, 0.0, 0.03)
    temperatures: tuple[float, ...] = (25.0, 33.0, 40.0)
    temperature_time_constant: float = 600.0
    trajectories: tuple[str, ...] = TRAJECTORIES
    ft_rate: float = 100.0
    joint_rate: float = 100.0
    joint_delay: float = 0.003
    temperature_rate: float = 10.0
    dynamic: bool = True
    version: str = "7.3"
    layout: str = "channels_first"
    seed: int = 0

    def __post_init__(self) -> None:
        for name in ("ft_rate", "joint_rate", "temperature_rate", "support_kg",
                     "temperature_time_constant"):
            check_float(getattr(self, name), name, "ExperimentConfig", 0.0, low_inclusive=False)
        for load in self.loads_kg:
            check_float(load, "loads_kg", "ExperimentConfig", 0.0)
        for name in self.trajectories:
            check_choice(name, "trajectories", "ExperimentConfig", TRAJECTORIES)
        if not self.loads_kg or not self.temperatures or not self.trajectories:
            raise FtcalError("ExperimentConfig needs at least one load, temperature and trajectory.")


@dataclass(frozen=True)
class RecordingInfo:
    """One written recording, as listed in ``manifest.json`` (paths relative to the folder)."""

    file: str
    load_case: str
    trajectory: str
    load_kg: float
    payloads: tuple[str, ...]
    temperature_start: float
    temperature_end: float
    n_samples: int
    duration_s: float


def folder_name(left_kg: float, right_kg: float) -> str:
    """The paper's folder naming for the loads on the two arms, e.g. ``l0kg-r5kg``."""
    return f"l{left_kg:g}kg-r{right_kg:g}kg"


def run_experiment(folder: str | Path, config: ExperimentConfig | None = None,
                   sensor: StrainGaugeSensor | None = None) -> tuple[list[Path], list[RecordingInfo]]:
    """Simulate every (load, temperature, trajectory) recording into ``folder``.

    Parameters
    ----------
    sensor : the simulated sensor; default ``StrainGaugeSensor.create(seed=config.seed)``

    Returns
    -------
    files : paths written, in manifest order
    manifest : one :class:`RecordingInfo` per file (also written to ``folder/manifest.json``)
    """
    cfg = ExperimentConfig() if config is None else config
    load_idyntree()
    from ..robot.expected import expected_wrenches
    from ..robot.model import RobotModel
    from ..robot.payloads import Payload

    base = RobotModel.load(name=cfg.robot)
    sensor_index = base.ft_sensors.index(base.sensor(cfg.sensor))
    ft_sensor = sensor if sensor is not None else StrainGaugeSensor.create(seed=cfg.seed)
    limits = joint_limits(base.source, ARM_JOINTS)
    logged = tuple(j for j in LOGGED_JOINTS if j in base.joint_names)
    hold = _held_pose(base.source, logged)
    root = Path(folder)
    jobs = [(load, temp, traj) for load in cfg.loads_kg for temp in cfg.temperatures
            for traj in cfg.trajectories]
    rngs = np.random.default_rng(cfg.seed).spawn(len(jobs))
    files, manifest = [], []
    for (load, temp, traj), rng in track(list(zip(jobs, rngs)), "simulating recordings"):
        payloads = [Payload(cfg.load_frame, cfg.support_kg, cfg.load_com, name="support")]
        if load > 0:
            payloads.append(Payload(cfg.load_frame, load, cfg.load_com, name="plates"))
        robot = base.with_payloads(payloads)
        motion = _trajectory(traj, limits, rng)
        log, truth_temps = _simulate(cfg, robot, sensor_index, ft_sensor, motion, logged, hold,
                                     temp, rng, expected_wrenches)
        case = folder_name(0, load)
        relative = Path(case) / f"{traj}_{temp:g}C.mat"
        files.append(write_robot_log(root / relative, log, cfg.version, cfg.layout))
        manifest.append(RecordingInfo(
            file=relative.as_posix(), load_case=case, trajectory=traj, load_kg=float(load),
            payloads=tuple(_spec(p) for p in payloads),
            temperature_start=float(truth_temps[0]), temperature_end=float(truth_temps[-1]),
            n_samples=len(log.ft[cfg.sensor].timestamps), duration_s=float(motion.time[-1])))
    document = {"robot": cfg.robot, "sensor": cfg.sensor, "config": dataclasses.asdict(cfg),
                "recordings": [dataclasses.asdict(m) for m in manifest]}
    write_text_atomic(root / "manifest.json", json.dumps(document, indent=2) + "\n")
    return files, manifest


def _simulate(cfg: ExperimentConfig, robot, sensor_index: int, ft_sensor: StrainGaugeSensor,
              motion: JointTrajectory, logged: Sequence[str], hold: np.ndarray, start_temp: float,
              rng: np.random.Generator, expected_wrenches) -> tuple[RobotLog, np.ndarray]:
    t0 = START_EPOCH + rng.uniform(0, 1e5)
    duration = motion.time[-1]
    t_ft = np.arange(0.0, duration, 1.0 / cfg.ft_rate)
    t_q = np.arange(0.0, duration - cfg.joint_delay, 1.0 / cfg.joint_rate) + cfg.joint_delay
    t_temp = np.arange(0.0, duration, 1.0 / cfg.temperature_rate)

    def arm_at(times: np.ndarray) -> np.ndarray:
        return np.column_stack([np.interp(times, motion.time, q) for q in motion.positions.T])

    # True wrench on the F/T clock, with derivatives of the smooth motion.
    q_arm = arm_at(t_ft)
    full = np.zeros((len(t_ft), len(robot.joint_names)))
    for name, value in zip(logged, hold):
        full[:, robot.joint_names.index(name)] = value
    cols = [robot.joint_names.index(j) for j in ARM_JOINTS]
    full[:, cols] = q_arm
    dq = ddq = None
    if cfg.dynamic:
        dq = np.zeros_like(full)
        dq[:, cols] = np.gradient(q_arm, t_ft, axis=0)
        ddq = np.zeros_like(full)
        ddq[:, cols] = np.gradient(dq[:, cols], t_ft, axis=0)
    wrench = expected_wrenches(robot, full, dq=dq, ddq=ddq, workers=1,
                               description="expected wrenches")[:, sensor_index]
    target = start_temp + rng.uniform(1.0, 3.0)
    temps = temperature_drift(t_ft, start_temp, target, cfg.temperature_time_constant)
    raw = ft_sensor.measure(wrench, temps, rng, cfg.ft_rate)

    # Joint streams on their own clock, in the logger's joint order.
    q_log = np.tile(hold, (len(t_q), 1))
    arm_cols = [logged.index(j) for j in ARM_JOINTS]
    q_log[:, arm_cols] = arm_at(t_q)
    dq_log = np.zeros_like(q_log)
    dq_log[:, arm_cols] = np.gradient(q_log[:, arm_cols], t_q, axis=0)
    ddq_log = np.zeros_like(q_log)
    ddq_log[:, arm_cols] = np.gradient(dq_log[:, arm_cols], t_q, axis=0)
    temp_log = temperature_drift(t_temp, start_temp, target, cfg.temperature_time_constant)
    log = RobotLog(ft={cfg.sensor: Stream(t0 + t_ft, raw)},
                   temperatures={cfg.sensor: Stream(t0 + t_temp, temp_log)},
                   joint_names=tuple(logged),
                   positions=Stream(t0 + t_q, q_log), velocities=Stream(t0 + t_q, dq_log),
                   accelerations=Stream(t0 + t_q, ddq_log), robot_name=cfg.robot)
    return log, temps


def _trajectory(name: str, limits: np.ndarray, rng: np.random.Generator) -> JointTrajectory:
    if name == "grid":
        return grid_trajectory(limits, rng=rng)
    return weight_lifting_trajectory(limits, rng=rng)


def _held_pose(urdf: str, joints: Sequence[str]) -> np.ndarray:
    # Joints that do not move sit at zero, or at the nearest limit when zero is outside.
    return np.clip(0.0, *joint_limits(urdf, joints).T)


def _spec(payload) -> str:
    x, y, z = payload.com
    return f"{payload.frame}:{payload.mass:g}@{x:g},{y:g},{z:g}"
