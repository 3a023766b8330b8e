"""Fit-ready tables from ROS bags: the F/T stream's clock, the other topics on it.

For each bag, :func:`bag_columns` reads the topics of a
:class:`~ftcal.data.bags.BagTopics`, checks the F/T channels (non-finite values,
gaps, saturated or stuck channels), puts every stream on the F/T stream's
clock (:func:`ftcal.data.alignment.align_streams`: linear interpolation, slerp for
orientations), smooths the F/T channels and temperature (Savitzky–Golay, as
for ``.mat`` logs) and returns named columns (project-wide names):

=================  =============================================================
``time``           s, the F/T stream's stamps
``u1..u6``         the measured wrench (Fx, Fy, Fz, Tx, Ty, Tz as the sensor reports it)
``T``              °C, only when a temperature topic is given
``qx,qy,qz,qw``    orientation of the sensor in a gravity-aligned world (from ``--tf BASE:SENSOR``,
                   BASE assumed gravity-aligned with gravity along −z, else from the IMU)
``wx..wz, ax..az`` IMU angular velocity (rad/s) and linear acceleration (m/s², with gravity)
joint names        positions, rad, from the joints topic (with a URDF: its joints only; without:
                   every joint whose positions are all finite), for ``ftcal payload --urdf``
``Fx..Tz``         expected wrench from the robot model (only with a URDF and a joints topic)
``static``         1 on the still samples (:func:`ftcal.data.holds.find_holds`: from the orientation,
                   else the joints, else the wrench's variation), 0 while moving
``hold``           the still pose's number, counted over all bags (one cross-validation group per
                   pose with ``--group-by hold``), -1 while moving
``segment``        one per bag; ``load``: the bag's load case, else its stem
=================  =============================================================
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from ..core.columns import LOAD_COLUMN, SEGMENT_COLUMN
from ..core.dataset import DEFAULT_OUTPUTS
from ..data.alignment import align_streams
from ..data.bags import BagTopics, tf_key
from ..data.holds import number_across
from ..data.recording import Stream
from ..data.signals import channel_issues, smooth
from ..robot.expected import warn_if_zero_reference
from ..robot.kinematics import require_chain_joints
from ..robot.loadcases import LoadCaseConfig
from ..robot.payloads import Payload
from ..runtime.errors import FtcalError, ParameterError, FtcalWarning
from .recordings import InsituOptions


@dataclass(frozen=True)
class BagTable:
    """One table built from bags.

    columns : column name → ndarray of shape (n_samples,), in writing order
    notes : one line per bag saying which streams and clocks were used
    """

    columns: dict[str, np.ndarray]
    notes: tuple[str, ...]

    @property
    def n_samples(self) -> int:
        return int(next(iter(self.columns.values())).shape[0])


def build_bag_table(bags: Sequence[str | Path], topics: BagTopics, *, robot=None, sensor: str | None = None,
                    payloads: Sequence[Payload] = (), load_cases: LoadCaseConfig | None = None,
                    options: InsituOptions = InsituOptions(), executor=None) -> BagTable:
    """One table from all ``bags`` (one segment each).

    Parameters
    ----------
    bags : sequence of path
        ROS 1 ``.bag`` files, ROS 2 bag folders, ``.db3`` or ``.mcap`` files.
    topics : BagTopics
        Topics to read (the same in every bag).
    robot : RobotModel or None
        With ``sensor`` and ``topics.joints``: add the expected wrench ``Fx..Tz``. The joint
        columns are kept with or without it.
    sensor : str or None
        F/T sensor of ``robot``.
    payloads, load_cases : as for :func:`ftcal.insitu.recordings.recordings_dataset`
    options : InsituOptions
        ``savgol_frame``/``savgol_order``, ``rate``, ``adc_limits``, ``base``, ``gravity``, ``workers``.
    executor : None to work here, or an executor of :mod:`ftcal.runtime.executors` (e.g. a Dask
        cluster): one task per bag, as :func:`ftcal.insitu.recordings.recordings_dataset` does for logs.

    Returns
    -------
    BagTable

    Raises
    ------
    FtcalError
        Any bad input (missing topic, wrong type, no overlap, non-finite values, bad quaternions,
        disconnected tf chain), naming the bag and topic.
    """
    if not bags:
        raise FtcalError("No bags given.")
    unsupported = {("dynamic",): ("{dynamic}", options.derivatives),
                   ("imu", "imu_frame", "imu_topic"): ("{imu}/{imu_frame} (YARP logs; use {imu_topic})", options.imu),
                   ("align_first_sample", "urdf", "robot"): ("{align_first_sample} without {urdf}/{robot}",
                                                             options.align_first_sample and robot is None)}
    for parameters, (what, given) in unsupported.items():
        if given:
            raise ParameterError(parameters, f"{what} is not available for ROS bags.")
    if robot is not None:
        if sensor is None:
            raise ParameterError(('sensor', 'urdf', 'robot'), "{sensor} is required with {urdf}/{robot}.")
        if topics.joints is None:
            raise ParameterError(('joints_topic', 'urdf', 'robot'), "{joints_topic} is required with {urdf}/{robot} (the expected wrench needs the joints).")
        robot.sensor(sensor)
        robot.base_frame(options.base)
    config = load_cases or LoadCaseConfig()
    cases = [config.resolve(path, tuple(payloads)) for path in bags]  # group: the load case, else the bag's stem
    if executor is None:
        models: dict = {}
        parts = []
        for segment, (path, case) in enumerate(zip(bags, cases)):
            model = None
            if robot is not None:
                if case.payloads not in models:
                    models[case.payloads] = robot.with_payloads(case.payloads)
                model = models[case.payloads]
            parts.append(bag_columns(Path(path), topics, segment, case.name, model, sensor, options))
    else:
        tasks = [(str(path), None if robot is None else
                  (robot.urdf_text, robot.source, (*robot.payloads, *case.payloads), robot.declared),
                  segment, case.name) for segment, (path, case) in enumerate(zip(bags, cases))]
        # One process per task on the workers: a Dask worker must not start its own process pool.
        results = executor.map(_bag_task, tasks, topics, sensor, replace(options, workers=1),
                               description="bags")
        parts = []
        for part, caught in results:
            for message, category in caught:
                warnings.warn(message, category, stacklevel=2)
            parts.append(part)
    for path, part in zip(bags, parts):
        if list(part.columns) != list(parts[0].columns):
            raise FtcalError(f"Bag {path}: gives columns {','.join(part.columns)} but {bags[0]} gives "
                             f"{','.join(parts[0].columns)} (an IMU without orientation in one of them?).")
    columns = {name: np.concatenate([p.columns[name] for p in parts]) for name in parts[0].columns}
    columns["hold"] = number_across([p.columns["hold"] for p in parts])
    return BagTable(columns, tuple(line for p in parts for line in p.notes))


def _bag_task(path: str, description: tuple | None, segment: int, group: str, topics: BagTopics,
              sensor: str | None, options: InsituOptions) -> tuple[BagTable, list[tuple[str, type]]]:
    """:func:`bag_columns` as a worker runs it: the table and its FtcalWarnings (text, class), in order.

    ``description``: the robot's (:func:`ftcal.insitu.recordings.robot_from_description`), or None without a robot.
    """
    from .recordings import robot_from_description

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        robot = None if description is None else robot_from_description(*description)
        table = bag_columns(Path(path), topics, segment, group, robot, sensor, options)
    return table, [(str(w.message), w.category) for w in caught if issubclass(w.category, FtcalWarning)]


def bag_columns(path: Path, topics: BagTopics, segment: int, group: str, robot=None, sensor: str | None = None,
                options: InsituOptions = InsituOptions()) -> BagTable:
    """The table of one bag (see the module docstring).

    Parameters
    ----------
    path : Path
        The bag.
    topics : BagTopics
    segment : int
        Segment id of its samples.
    group : str
        Group label of its samples.
    robot : RobotModel or None
        Already carrying the bag's load-case payloads; with ``sensor``, adds ``Fx..Tz``.
    sensor : str or None
    options : InsituOptions

    Returns
    -------
    BagTable
    """
    from ..data.logs import read_recording

    recording = read_recording(path, options.joint_units, topics=topics)
    ft = recording.ft[topics.wrench]
    for issue in channel_issues(ft, options.adc_limits):
        warnings.warn(str(issue), FtcalWarning, stacklevel=2)
    streams: dict[str, Stream] = {"ft": ft}
    if topics.temperature is not None:
        streams["T"] = recording.temperature[topics.temperature]
    if topics.joints is not None:
        joints = recording.joints
        streams["q"] = _urdf_joints(path, joints, robot) if robot is not None else _finite_joints(path, joints)
        if robot is not None:
            require_chain_joints(robot, streams["q"].columns, robot.base_frame(options.base)[1], sensor,
                                 f"Bag {path}: {joints.name}")
    orientation_source = None
    if topics.tf is not None:
        orientation_source = tf_key(topics.tf)
    elif topics.imu is not None and topics.imu in recording.orientations:
        orientation_source = topics.imu
    if orientation_source is not None:
        streams["orientation"] = recording.orientations[orientation_source]
    if topics.imu is not None:
        streams["gyro"] = recording.gyros[topics.imu]
        streams["acc"] = recording.accelerometers[topics.imu]
    clock, on_clock, trimmed, _ = align_streams(streams, "ft", rate=options.rate, where=f"Bag {path}")
    raw, temp = on_clock["ft"], on_clock.get("T")
    if options.savgol_frame is not None:
        raw = smooth(raw, options.savgol_frame, options.savgol_order, where=f"Bag {path} {topics.wrench}")
        if temp is not None:
            temp = smooth(temp, options.savgol_frame, options.savgol_order, where=f"Bag {path} {topics.temperature}")
    columns: dict[str, np.ndarray] = {"time": clock}
    columns.update({f"u{i + 1}": raw[:, i] for i in range(6)})
    if temp is not None:
        columns["T"] = temp[:, 0]
    for key, names in (("orientation", ("qx", "qy", "qz", "qw")), ("gyro", ("wx", "wy", "wz")),
                       ("acc", ("ax", "ay", "az"))):
        if key in on_clock:
            columns.update({name: on_clock[key][:, i] for i, name in enumerate(names)})
    if "q" in on_clock:
        later = (*DEFAULT_OUTPUTS, "static", "hold", SEGMENT_COLUMN, LOAD_COLUMN)
        taken = [name for name in streams["q"].columns if name in columns or name in later]
        if taken:
            raise FtcalError(f"Bag {path}: {topics.joints} has a joint named {taken[0]!r}, like a column of the "
                             "table; rename the joint.")
        columns.update({name: on_clock["q"][:, i] for i, name in enumerate(streams["q"].columns)})
    if robot is not None:
        expected = _expected(path, robot, sensor, streams["q"].columns, on_clock["q"], options)
        warn_if_zero_reference(expected, f"Bag {path}", sensor, group)
        if options.align_first_sample:
            raw = raw - (raw[0] - expected[0])
        columns.update({f"u{i + 1}": raw[:, i] for i in range(6)})
        columns.update({name: expected[:, i] for i, name in enumerate(DEFAULT_OUTPUTS)})
    holds = _holds(clock, on_clock, raw, path)
    columns["static"] = holds.static.astype(np.int64)
    columns["hold"] = holds.hold
    n = clock.size
    columns[SEGMENT_COLUMN] = np.full(n, segment)
    columns[LOAD_COLUMN] = np.full(n, group, dtype=object)
    notes = [f"{path}: {topics.wrench} {ft.n_samples} messages ({ft.clock}"
             + (f", frame {ft.frame}" if ft.frame else "") + f"), {n} samples kept"
             + (f" ({trimmed[0]} cut at the start, {trimmed[1]} at the end to overlap the other topics)"
                if any(trimmed) else "")]
    # One line per topic: an IMU gives its gyro, accelerometer (and orientation) as separate streams.
    for stream in {s.name: s for key, s in streams.items() if key != "ft"}.values():
        notes.append(f"  {stream.name}: {stream.n_samples} samples ({stream.clock})")
    return BagTable(columns, tuple(notes))


def _holds(clock: np.ndarray, on_clock: dict, raw: np.ndarray, path: Path):
    """Static holds of one bag: from the orientation, else the joints, else the wrench's variation."""
    from ..data.holds import find_holds

    if "orientation" in on_clock:
        return find_holds(clock, orientation=on_clock["orientation"], where=f"Bag {path}")
    if "q" in on_clock:
        return find_holds(clock, joints=on_clock["q"], where=f"Bag {path}")
    return find_holds(clock, wrench=raw, where=f"Bag {path}")


def _finite_joints(path: Path, joints: Stream) -> Stream:
    """The joints of a JointState stream with a finite position throughout (a gripper's may be NaN)."""
    keep = [c for c in range(len(joints.columns)) if np.all(np.isfinite(joints.data[:, c]))]
    if not keep:
        raise FtcalError(f"Bag {path}: {joints.name} has no joint with finite positions throughout.")
    if len(keep) < len(joints.columns):
        dropped = [joints.columns[c] for c in range(len(joints.columns)) if c not in keep]
        warnings.warn(f"Bag {path}: {joints.name}: joint(s) {', '.join(dropped[:5])} have non-finite positions; "
                      "left out of the table.", FtcalWarning, stacklevel=3)
    return replace(joints, data=joints.data[:, keep], columns=tuple(joints.columns[c] for c in keep))


def _urdf_joints(path: Path, joints: Stream, robot) -> Stream:
    """The URDF's joints of a JointState stream; others (a gripper's, say) are dropped with a warning."""
    known = set(robot.joint_names)
    keep = [c for c, name in enumerate(joints.columns) if name in known]
    if not keep:
        raise FtcalError(f"Bag {path}: {joints.name} has none of the URDF's joints (it has "
                         f"{', '.join(joints.columns[:5]) or 'no names'}; the URDF has "
                         f"{', '.join(robot.joint_names[:5])}, ...).")
    if len(keep) < len(joints.columns):
        dropped = [name for name in joints.columns if name not in known]
        warnings.warn(f"Bag {path}: {joints.name}: joint(s) {', '.join(dropped[:5])} are not in the URDF; "
                      f"ignored.", FtcalWarning, stacklevel=3)
    for c in keep:
        absent = ~np.isfinite(joints.data[:, c])
        if absent.any():
            where = np.flatnonzero(absent)
            raise FtcalError(f"Bag {path}: {joints.name}: URDF joint {joints.columns[c]!r} has no position from "
                             f"t={float(joints.time[where[0]]):.3f} to t={float(joints.time[where[-1]]):.3f} s "
                             f"({where.size} of {absent.size} samples; it is not in every JointState message); "
                             "cut the bag to where it is published (or remove the joint from the URDF).")
    missing = [name for name in robot.joint_names if name not in joints.columns]
    if missing:
        warnings.warn(f"Bag {path}: {joints.name} lacks URDF joint(s) {', '.join(missing[:5])}; they are held "
                      f"at 0 rad.", FtcalWarning, stacklevel=3)
    return replace(joints, data=joints.data[:, keep], columns=tuple(joints.columns[c] for c in keep))


def _expected(path: Path, robot, sensor: str, joint_names: tuple[str, ...], q: np.ndarray,
              options: InsituOptions) -> np.ndarray:
    """Expected wrench of ``sensor`` at each sample, (n_samples, 6), static (joint positions only)."""
    from ..robot.expected import expected_wrenches

    from ..robot.kinematics import require_wrench_joints

    ft_sensor = robot.sensor(sensor)
    base = robot.base_frame(options.base)[1]
    require_wrench_joints(robot, joint_names, base, [ft_sensor.name], f"Bag {path} joints",
                          " (joints off the chain to the sensor and off the links beyond it may be left out)")
    matrix = robot.joint_matrix(joint_names, q, f"Bag {path} joints")
    wrenches = expected_wrenches(robot, matrix, base=base, gravity=options.gravity, workers=options.workers,
                                 description=f"expected wrenches {path.name}")
    return wrenches[:, ft_sensor.index, :]


def write_bag_table(table: BagTable, path: str | Path) -> None:
    """Write ``table`` as CSV or Parquet (by suffix), atomically; refuses non-finite values.

    Raises
    ------
    FtcalError
        If a numeric column holds NaN or inf (nothing is written).
    """
    import pandas as pd

    from ..data.tables import write_table

    for name, values in table.columns.items():
        if values.dtype.kind == "f" and not np.all(np.isfinite(values)):
            raise FtcalError(f"{path}: column {name!r} would hold non-finite values; nothing written.")
    frame = pd.DataFrame({name: (v.astype(str) if v.dtype == object else v) for name, v in table.columns.items()})
    write_table(frame, path)
