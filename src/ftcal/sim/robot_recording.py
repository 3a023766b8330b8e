"""``ftcal simulate``: what a calibration run on *your* robot would record, from its URDF and a plan.

The robot visits the plan's poses in order (an ``ftcal plan`` CSV or any table of joint
waypoints, one column per URDF joint, rad; an optional ``load`` column indexes the loads):
a hold of ``hold_s`` at each pose, then a minimum-jerk move to the next, its duration set
so that no joint exceeds ``speed`` × its URDF velocity limit. Waypoints outside the URDF
position limits are refused, and a minimum-jerk move stays between its end points, so the
whole motion is within the limits.

Each run of consecutive poses with the same load is one recording (the loads are mounted
in between, ``mount_s`` later). The true wrench at the sensor comes from iDynTree
(:func:`ftcal.robot.expected_wrenches`, with the joint velocities and accelerations), for
the robot with its tool (``--payload``) and the load of that run; the sensor is a
:class:`ftcal.sim.sensor_model.SensorModel` at a temperature that moves linearly from
``temperature_start`` to ``temperature_end`` over the whole session, with a bias that ramps
and random-walks across recordings.

Written per recording (``formats``):

* ``bag``: a ROS 2 bag folder with ``/joint_states`` (sensor_msgs/JointState),
  ``/tf`` (base → sensor frame), ``/imu`` (sensor_msgs/Imu on the sensor frame),
  ``/ft_sensor/wrench`` (the driver's factory-calibrated wrench) or ``/ft_sensor/raw``
  (the ADC counts packed in a WrenchStamped) and ``/ft_sensor/temperature``;
* ``table``: a robot-log table (Parquet, docs/formats.md: ``time``, ``<sensor>_u1..u6``,
  ``<sensor>_T``, joint positions and ``.vel``/``.acc``) on the F/T clock;

plus ``loads.toml`` (the load of each recording, for ``ftcal dataset --payload-file``) and
``truth.json``: the sensor (true and factory matrices, every coefficient), the drift (bias
per hold), the tool and loads, the holds' times, the seed and settings. The same seed
writes the same bytes.
"""

from __future__ import annotations

import json
import math
import os
import shutil
import tempfile
import xml.etree.ElementTree as ET
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from ..core.limits import MAX_SIMULATED_SAMPLES

MIN_HOLD_SAMPLES = 2  # F/T samples a simulated hold must hold: its mean bias is written to the truth file
from ..core.limits import SIMULATE_FORMATS as FORMATS
from ..robot.model import RobotModel
from ..robot.payloads import Payload
from ..runtime.atomic import write_text_atomic
from ..runtime.errors import FtcalError, ParameterError
from .arm_bag import START_NS, TEMPERATURE_RATE
from .sensor_model import CHANNELS, SensorModel

LOAD_COLUMN = "load"
TRUTH_FORMAT = "ftcal-simulation-truth"
TRUTH_VERSION = 1
RAW_TOPIC = "/ft_sensor/raw"
DEFAULT_VELOCITY = 1.0  # rad/s, for joints whose URDF gives no velocity limit


@dataclass(frozen=True)
class SimulationConfig:
    """Timing, rates and conditions of a simulated session (s, Hz, °C)."""

    hold_s: float = 2.0
    speed: float = 0.3
    min_move_s: float = 1.0
    mount_s: float = 30.0
    rate: float = 250.0
    joint_rate: float = 100.0
    tf_rate: float = 100.0
    imu_rate: float = 100.0
    temperature_start: float = 28.0
    temperature_end: float = 34.0
    channels: str = "wrench"
    formats: tuple[str, ...] = ("bag",)
    seed: int = 0

    def __post_init__(self) -> None:
        for name in ("hold_s", "speed", "min_move_s", "rate", "joint_rate", "tf_rate", "imu_rate"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise FtcalError(f"{name} must be a finite number > 0; got {value!r}.")
        if not (math.isfinite(self.mount_s) and self.mount_s >= 0):
            raise FtcalError(f"mount_s must be a finite number >= 0; got {self.mount_s!r}.")
        if self.speed > 1:
            raise FtcalError(f"speed is a fraction of the URDF velocity limits, in (0, 1]; got {self.speed!r}.")
        if self.channels not in CHANNELS:
            raise FtcalError(f"channels must be one of {', '.join(CHANNELS)}; got {self.channels!r}.")
        if not self.formats or any(f not in FORMATS for f in self.formats):
            raise FtcalError(f"formats must be among {', '.join(FORMATS)}; got {', '.join(self.formats) or 'none'}.")


@dataclass(frozen=True)
class Waypoints:
    """Poses to visit: ``q`` of shape (n_poses, n_dofs) in ``robot.joint_names`` order, ``load`` indices (n_poses,)."""

    q: np.ndarray
    load: np.ndarray
    source: str = "<waypoints>"


@dataclass
class Session:
    """What :func:`simulate_session` wrote: recordings (name → files) and the truth document."""

    out_dir: Path
    recordings: list[dict] = field(default_factory=list)
    truth: dict = field(default_factory=dict)

    @property
    def files(self) -> list[str]:
        return [f for r in self.recordings for f in r["files"]] + [str(self.out_dir / "loads.toml"),
                                                                   str(self.out_dir / "truth.json")]


def read_waypoints(path: str | Path, robot: RobotModel, n_loads: int) -> Waypoints:
    """Joint waypoints from a CSV/Parquet table (an ``ftcal plan`` CSV or one column per joint).

    Joint columns are matched by URDF joint name; joints without a column stay at 0 (or at
    the nearer URDF limit when 0 is outside it). A
    ``load`` column (whole numbers in [0, n_loads)) picks each pose's load; other columns
    (``reference``, ``Fx``..``Tz``, ``time``) are ignored.

    Raises
    ------
    FtcalError
        No rows, no joint column, non-finite cells, a load out of range.
    """
    from ..data.tables import numeric_columns, read_table

    path = Path(path)
    frame = read_table(path)
    if frame.shape[0] == 0:
        raise FtcalError(f"plan {path}: the table has no rows.")
    joints = [c for c in frame.columns if c in robot.joint_names]
    if not joints:
        raise FtcalError(f"plan {path}: no column is a joint of URDF {robot.source} (its joints: "
                         f"{', '.join(robot.joint_names[:6])}{', ...' if len(robot.joint_names) > 6 else ''}).")
    q = robot.joint_matrix(joints, numeric_columns(frame, joints, path, "joint"), f"plan {path}")
    # Joints the table leaves out rest at 0, or at the nearer limit when 0 is outside.
    position, _ = joint_bounds(robot)
    absent = [i for i, n in enumerate(robot.joint_names) if n not in joints]
    q[:, absent] = np.clip(0.0, position[absent, 0], position[absent, 1])
    if LOAD_COLUMN in frame.columns:
        values = numeric_columns(frame, [LOAD_COLUMN], path, "load")[:, 0]
        bad = np.flatnonzero((values != np.round(values)) | (values < 0) | (values >= n_loads))
        if bad.size:
            raise ParameterError('load', f"plan {path}: column 'load' row {bad[0] + 1} is {values[bad[0]]:g}; it must be a whole "
                             f"number in [0, {n_loads}) indexing the {n_loads} {{load}} option(s) (default: none).")
        load = values.astype(np.int64)
    else:
        load = np.zeros(len(q), dtype=np.int64)
    return Waypoints(q, load, str(path))


def joint_bounds(robot: RobotModel) -> tuple[np.ndarray, np.ndarray]:
    """Position limits (n_dofs, 2) and velocity limits (n_dofs,) from the URDF (no limit: ±inf, 1 rad/s)."""
    position = np.tile([-np.inf, np.inf], (len(robot.joint_names), 1))
    velocity = np.full(len(robot.joint_names), DEFAULT_VELOCITY)
    model = robot.model
    for i, name in enumerate(robot.joint_names):
        joint = model.getJoint(model.getJointIndex(name))
        if joint.hasPosLimits():
            position[i] = joint.getMinPosLimit(0), joint.getMaxPosLimit(0)
    try:
        root = ET.fromstring(robot.urdf_text)
    except ET.ParseError:
        return position, velocity
    index = {n: i for i, n in enumerate(robot.joint_names)}
    for joint in root.iter("joint"):
        limit = joint.find("limit")
        if joint.get("name") in index and limit is not None:
            try:
                value = float(limit.get("velocity", "nan"))
            except ValueError:
                continue
            if math.isfinite(value) and value > 0:
                velocity[index[joint.get("name")]] = value
    return position, velocity


def check_within_limits(waypoints: Waypoints, robot: RobotModel, position: np.ndarray) -> None:
    """FtcalError naming the first pose and joint outside the URDF position limits."""
    below = waypoints.q < position[:, 0] - 1e-9
    above = waypoints.q > position[:, 1] + 1e-9
    bad = np.argwhere(below | above)
    if bad.size:
        row, col = bad[0]
        low, high = position[col]
        raise FtcalError(f"plan {waypoints.source}: row {row + 1}, joint {robot.joint_names[col]!r} = "
                         f"{waypoints.q[row, col]:.6g} rad is outside the URDF limits [{low:.6g}, {high:.6g}].")


class Motion:
    """Hold, minimum-jerk move, hold, ...: joint positions, velocities and accelerations at any time.

    Parameters
    ----------
    q : ndarray of shape (n_poses, n_dofs)
    velocity : ndarray of shape (n_dofs,), the speed each joint may reach, rad/s
    """

    def __init__(self, q: np.ndarray, velocity: np.ndarray, hold_s: float, min_move_s: float) -> None:
        self.q = np.asarray(q, dtype=np.float64)
        steps = np.abs(np.diff(self.q, axis=0))
        # A minimum-jerk move of length d in time T peaks at 1.875 d / T.
        moves = np.max(1.875 * steps / velocity, axis=1, initial=0.0) if len(steps) else np.zeros(0)
        self.moves = np.maximum(moves, min_move_s)
        self.hold_s = hold_s
        starts = [0.0]
        for m in self.moves:
            starts.append(starts[-1] + hold_s + m)
        self.starts = np.array(starts)  # start of each pose's hold
        self.duration = float(self.starts[-1] + hold_s)

    def holds(self) -> list[tuple[float, float]]:
        """(start, end) s of each pose's hold, from the recording's start."""
        return [(float(s), float(s + self.hold_s)) for s in self.starts]

    def __call__(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        t = np.asarray(t, dtype=np.float64)
        k = np.clip(np.searchsorted(self.starts, t, side="right") - 1, 0, len(self.starts) - 1)
        into = t - self.starts[k] - self.hold_s
        moving = (into > 0) & (k < len(self.moves))
        duration = np.append(self.moves, 1.0)[k]  # the last pose only holds
        tau = np.where(moving, np.clip(into / duration, 0.0, 1.0), 0.0)
        s = tau ** 3 * (10 - 15 * tau + 6 * tau ** 2)
        ds = np.where(moving, 30 * tau ** 2 * (1 - tau) ** 2 / duration, 0.0)
        dds = np.where(moving, 60 * tau * (1 - tau) * (1 - 2 * tau) / duration ** 2, 0.0)
        nxt = np.minimum(k + 1, len(self.q) - 1)
        delta = self.q[nxt] - self.q[k]
        return self.q[k] + s[:, None] * delta, ds[:, None] * delta, dds[:, None] * delta


def check_session_size(robot: RobotModel, waypoints: Waypoints, config: SimulationConfig) -> int:
    """The session's number of F/T samples; FtcalError when it exceeds :data:`~ftcal.core.limits.MAX_SIMULATED_SAMPLES`.

    Cheap (the motions' durations only), so callers check before they make any folder.
    """
    if config.hold_s * config.rate < MIN_HOLD_SAMPLES:  # a hold's bias and the truth file are means over it
        raise FtcalError(f"a hold of {config.hold_s:g} s at {config.rate:g} Hz has fewer than {MIN_HOLD_SAMPLES} F/T "
                         f"samples; raise the rate or the hold time (hold x rate >= {MIN_HOLD_SAMPLES}).")
    _, velocity = joint_bounds(robot)
    motions = [Motion(waypoints.q[a:b], config.speed * velocity, config.hold_s, config.min_move_s)
               for a, b, _ in _runs(waypoints.load)]
    duration = sum(m.duration for m in motions)
    samples = sum(int(math.floor(m.duration * config.rate)) + 1 for m in motions)
    if samples > MAX_SIMULATED_SAMPLES:
        raise FtcalError(f"rate {config.rate:g} Hz over {duration:.3g} s of motion makes {samples:.3g} F/T samples, "
                         f"more than the {MAX_SIMULATED_SAMPLES:,} a session may hold in memory (about 1.5 kB "
                         f"each); lower the rate (at most {MAX_SIMULATED_SAMPLES / duration:.4g} Hz here), "
                         "the hold time or the number of poses.")
    return samples


def simulate_session(robot: RobotModel, sensor_name: str, waypoints: Waypoints, sensor: SensorModel,
                     out_dir: str | Path, *, loads: Sequence[Payload | None] = (None,),
                     base: str | None = None, config: SimulationConfig = SimulationConfig()) -> Session:
    """Simulate the session and write its recordings, ``loads.toml`` and ``truth.json`` into ``out_dir``.

    Parameters
    ----------
    robot : the robot with its tool attached (``RobotModel.with_payloads``)
    sensor_name : its F/T sensor (sensor or joint name)
    waypoints : from :func:`read_waypoints`
    sensor : the simulated sensor
    out_dir : folder to write into (created; recordings of the same names are replaced)
    loads : what each ``load`` index mounts (None: nothing)
    base : fixed base frame, z up (default as :meth:`RobotModel.base_frame`)

    Returns
    -------
    Session

    Raises
    ------
    FtcalError
        Waypoints beyond the URDF's limits, or a session of more than
        :data:`~ftcal.core.limits.MAX_SIMULATED_SAMPLES` F/T samples (before anything is written).
    """
    ft = robot.sensor(sensor_name)
    _, base_name = robot.base_frame(base)
    position, velocity = joint_bounds(robot)
    check_within_limits(waypoints, robot, position)
    check_session_size(robot, waypoints, config)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    # Everything is written into a hidden staging folder first and moved in at the end, so that a failure
    # part-way (a bad load, a full disk, Ctrl-C) leaves no partial session beside the user's files.
    stage = Path(tempfile.mkdtemp(prefix=".simulate-", dir=out))
    try:
        truth, recordings = _simulate_into(stage, robot, ft, base_name, waypoints, sensor, loads, config)
        for item in sorted(stage.iterdir()):
            target = out / item.name
            if target.is_dir() and not target.is_symlink():
                shutil.rmtree(target)
            os.replace(item, target)
    finally:
        shutil.rmtree(stage, ignore_errors=True)
    for rec in recordings:
        rec["files"] = [str(out / Path(f).name) for f in rec["files"]]
    return Session(out, recordings, truth)


def _simulate_into(out: Path, robot: RobotModel, ft, base_name: str, waypoints: Waypoints, sensor: SensorModel,
                   loads: Sequence[Payload | None], config: SimulationConfig) -> tuple[dict, list[dict]]:
    """:func:`simulate_session`'s work, writing into ``out`` (the staging folder)."""
    from ..robot.expected import expected_wrenches

    position, velocity = joint_bounds(robot)
    rng = np.random.default_rng([config.seed, 31])
    runs = _runs(waypoints.load)
    motions = [Motion(waypoints.q[a:b], config.speed * velocity, config.hold_s, config.min_move_s) for a, b, _ in runs]
    starts = np.cumsum([0.0] + [m.duration + config.mount_s for m in motions])[:-1]
    total = float(starts[-1] + motions[-1].duration)
    clocks = [np.arange(int(math.floor(m.duration * config.rate)) + 1) / config.rate for m in motions]
    session_time = np.concatenate([s + c for s, c in zip(starts, clocks)])
    bias = sensor.bias(session_time, rng)  # one random walk across the session, mounting gaps included
    sizes = np.cumsum([0] + [len(c) for c in clocks])
    sensor_index = robot.ft_sensors.index(ft)
    recordings, truth_recordings = [], []
    for r, ((a, b, load_index), motion, start, t) in enumerate(zip(runs, motions, starts, clocks)):
        load = loads[load_index]
        loaded = robot.with_payloads([load]) if load is not None else robot
        q, dq, ddq = motion(t)
        wrench = expected_wrenches(loaded, q, dq=dq, ddq=ddq, base=base_name, workers=1,
                                   description=f"recording {r + 1}/{len(runs)}")[:, sensor_index]
        temperature = _temperature(config, start + t, total)
        run_bias = bias[sizes[r]:sizes[r + 1]]
        counts = sensor.counts(wrench, temperature, run_bias, rng)
        channels = sensor.factory_wrench(counts) if config.channels == "wrench" else counts
        name = f"run{r + 1:02d}-load{load_index}"
        files = []
        if "bag" in config.formats:
            files.append(_write_bag(out / name, robot, ft.name, base_name, motion, t, channels, start, total,
                                    config))
        if "table" in config.formats:
            files.append(_write_table(out / f"{name}.parquet", robot, ft.name, t, q, dq, ddq, channels,
                                      temperature, start))
        holds = motion.holds()
        scale = sensor.counts_per_full_scale
        hold_bias = [(scale * run_bias[(t >= h0) & (t <= h1)].mean(axis=0)) for h0, h1 in holds]
        recordings.append({"name": name, "files": [str(f) for f in files]})
        truth_recordings.append({
            "name": name, "files": [Path(f).name for f in files], "load": int(load_index),
            "payloads": [] if load is None else [_payload_dict(load)],
            "start_s": float(START_NS * 1e-9 + start), "duration_s": float(t[-1]), "n_samples": int(len(t)),
            "holds": [[float(START_NS * 1e-9 + start + h0), float(START_NS * 1e-9 + start + h1)] for h0, h1 in holds],
            "bias_counts_per_hold": [h.tolist() for h in hold_bias],
            "bias_wrench_per_hold": [(sensor.true_matrix @ h).tolist() for h in hold_bias],
            "temperature": [float(temperature[0]), float(temperature[-1])]})
    write_text_atomic(out / "loads.toml", _loads_toml(truth_recordings))
    truth = {
        "format": TRUTH_FORMAT, "version": TRUTH_VERSION, "seed": config.seed,
        "robot": {"urdf": robot.source, "sensor": ft.name, "sensor_joint": ft.joint, "base": base_name,
                  "joints": list(robot.joint_names)},
        "channels": config.channels, "config": asdict(config),
        "sensor": sensor.to_dict(),
        "drift": {"offset_counts": (sensor.offset * sensor.counts_per_full_scale).tolist(),
                  "ramp_counts_per_s": (sensor.ramp * sensor.counts_per_full_scale).tolist(),
                  "walk_counts_per_sqrt_s": sensor.spec.walk * sensor.counts_per_full_scale},
        "tool": [_payload_dict(p) for p in robot.payloads],
        "loads": [None if p is None else _payload_dict(p) for p in loads],
        "recordings": truth_recordings,
    }
    write_text_atomic(out / "truth.json", json.dumps(truth, indent=2, allow_nan=False) + "\n")
    return truth, recordings


def read_truth(path: str | Path) -> tuple[dict, SensorModel]:
    """A truth file and the sensor it describes (the same counts for the same inputs and noise)."""
    from ..core.limits import MAX_TEXT_FILE_BYTES
    from ..runtime.inputs import check_input_file

    # Like every file ftcal reads: a regular file of bounded size (a FIFO would hang the read).
    path = check_input_file(path, "truth file", max_bytes=MAX_TEXT_FILE_BYTES)
    try:
        document = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise FtcalError(f"truth file {path}: cannot read it as JSON ({exc}).") from None
    if not isinstance(document, dict) or document.get("format") != TRUTH_FORMAT:
        raise FtcalError(f"truth file {path}: not an ftcal simulation truth file (format {TRUTH_FORMAT!r}).")
    return document, SensorModel.from_dict(document.get("sensor", {}), f"truth file {path}: sensor")


def _runs(load: np.ndarray) -> list[tuple[int, int, int]]:
    """(first, end, load index) of each run of consecutive poses with the same load."""
    edges = np.flatnonzero(np.diff(load)) + 1
    bounds = np.concatenate([[0], edges, [len(load)]])
    return [(int(a), int(b), int(load[a])) for a, b in zip(bounds[:-1], bounds[1:])]


def _temperature(config: SimulationConfig, t: np.ndarray, total: float) -> np.ndarray:
    return config.temperature_start + (config.temperature_end - config.temperature_start) * t / max(total, 1e-9)


def _payload_dict(p: Payload) -> dict:
    return {"frame": p.frame, "mass": p.mass, "com": list(p.com), "inertia": list(p.inertia)}


def _loads_toml(recordings: list[dict]) -> str:
    lines = ["# The load of each simulated recording (ftcal dataset --payload-file; docs/formats.md).",
             "# The tool (--payload of ftcal simulate) is not listed: give it to ftcal dataset as --payload.", ""]
    for rec in recordings:
        lines += ["[[load]]", f"name = \"{rec['name']}\"", f"recordings = [\"{rec['name']}\"]"]
        for p in rec["payloads"]:
            com = ", ".join(repr(float(c)) for c in p["com"])
            inertia = ", ".join(repr(float(c)) for c in p["inertia"])
            lines += ["[[load.payload]]", f"frame = \"{p['frame']}\"", f"mass = {float(p['mass'])!r}",
                      f"com = [{com}]", f"inertia = [{inertia}]"]
        lines.append("")
    return "\n".join(lines)


def _write_bag(path: Path, robot: RobotModel, sensor: str, base: str, motion: Motion, t_ft: np.ndarray,
               channels: np.ndarray, start: float, total: float, config: SimulationConfig) -> Path:
    """One ROS 2 bag folder (mcap), written beside ``path`` and moved into place."""
    import shutil
    import tempfile

    from rosbags.rosbag2 import StoragePlugin, Writer
    from scipy.spatial.transform import Rotation

    from ..robot.kinematics import sensor_kinematics, sensor_poses
    from .arm_bag import BagMessages

    duration = float(t_ft[-1])
    t_q = np.arange(int(math.floor(duration * config.joint_rate)) + 1) / config.joint_rate
    t_tf = np.arange(int(math.floor(duration * config.tf_rate)) + 1) / config.tf_rate
    t_imu = np.arange(int(math.floor(duration * config.imu_rate)) + 1) / config.imu_rate
    t_temp = np.arange(int(math.floor(duration * TEMPERATURE_RATE)) + 1) / TEMPERATURE_RATE
    q_j, dq_j, _ = motion(t_q)
    poses = sensor_poses(robot, sensor, motion(t_tf)[0], base=base)
    q_i, dq_i, ddq_i = motion(t_imu)
    kin = sensor_kinematics(robot, sensor, q_i, dq_i, ddq_i, base=base)
    imu_orientation = Rotation.from_matrix(sensor_poses(robot, sensor, q_i, base=base)[:, :3, :3]).as_quat()
    tf_orientation = Rotation.from_matrix(poses[:, :3, :3]).as_quat()
    temperature = _temperature(config, start + t_temp, total)
    path.parent.mkdir(parents=True, exist_ok=True)
    staging = Path(tempfile.mkdtemp(prefix=f".{path.name}.", dir=path.parent))
    try:
        folder = staging / path.name
        topics = {"wrench": RAW_TOPIC} if config.channels == "raw" else None
        writer = Writer(folder, version=9, storage_plugin=StoragePlugin.MCAP)
        with writer:
            messages = BagMessages(writer, topics, frame=sensor)
            offset = start  # one session clock across recordings
            for k in range(len(t_ft)):
                messages.wrench(offset + t_ft[k], channels[k])
            names = list(robot.joint_names)
            for k in range(len(t_q)):
                messages.joint_state(offset + t_q[k], names, q_j[k], dq_j[k])
            for k in range(len(t_tf)):
                messages.tf(offset + t_tf[k], base, sensor, tf_orientation[k], static=False,
                            translation=poses[k, :3, 3])
            for k in range(len(t_imu)):
                messages.imu(offset + t_imu[k], imu_orientation[k], kin.angular_velocity[k],
                             kin.proper_acceleration[k])
            for k in range(len(t_temp)):
                messages.temperature(offset + t_temp[k], temperature[k])
            messages.flush()
        if path.exists():
            shutil.rmtree(path)
        folder.rename(path)
    finally:
        shutil.rmtree(staging, ignore_errors=True)
    return path


def _write_table(path: Path, robot: RobotModel, sensor: str, t: np.ndarray, q: np.ndarray, dq: np.ndarray,
                 ddq: np.ndarray, channels: np.ndarray, temperature: np.ndarray, start: float) -> Path:
    import pandas as pd

    from ..data.tables import write_table

    columns: dict[str, np.ndarray] = {"time": START_NS * 1e-9 + start + t}
    for i in range(6):
        columns[f"{sensor}_u{i + 1}"] = channels[:, i]
    columns[f"{sensor}_T"] = temperature
    for j, name in enumerate(robot.joint_names):
        columns[name] = q[:, j]
    for j, name in enumerate(robot.joint_names):
        columns[f"{name}.vel"] = dq[:, j]
    for j, name in enumerate(robot.joint_names):
        columns[f"{name}.acc"] = ddq[:, j]
    write_table(pd.DataFrame(columns), path)
    return path
