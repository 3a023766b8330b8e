"""In-situ datasets: raw F/T readings against the wrenches the robot model expects.

For one F/T sensor and a list of recordings, :func:`recordings_dataset` reads each
recording, puts its streams on the sensor's clock, smooths the raw channels
and the temperature (Savitzky–Golay, optional), computes the expected wrench
with the recording's load case attached (:mod:`ftcal.robot`) and returns a
:class:`~ftcal.core.dataset.Dataset`:

* inputs ``u1..u6`` (the six raw channels) and ``T`` (temperature);
* outputs ``Fx Fy Fz Tx Ty Tz``, the expected wrench (convention in
  :mod:`ftcal.robot.expected`);
* one segment per recording (ARX lags never cross recordings);
* group = the recording's load case name, else the recording's file stem.

:func:`build_log_table` returns the same dataset with the columns a fit does not
take beside it (what ``ftcal dataset`` writes):

* ``time``, s, each recording's own clock;
* the logged joint positions, rad, one column per joint (named as the joint;
  the joints every recording logs), for ``ftcal payload --urdf``;
* ``static`` (1 still, 0 moving) and ``hold`` (the still pose's number over all
  recordings, -1 while moving), from the logged joint positions over the log's
  time stamps (:func:`ftcal.data.holds.find_holds`), as for ROS bags.

:func:`write_dataset` stores it as Parquet or CSV with those columns plus
``segment`` and ``load`` (the load case), which ``ftcal fit DATA`` uses by default
(or ``--group-by hold``: one cross-validation group per pose).
"""

from __future__ import annotations

import dataclasses
import functools
import warnings
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..core.columns import LOAD_COLUMN, SEGMENT_COLUMN
from ..core.dataset import DEFAULT_INPUTS, DEFAULT_OUTPUTS, Dataset, concatenate
from ..data.alignment import Aligned, align
from ..data.holds import Holds, find_holds, number_across
from ..data.logs import read_recording
from ..data.recording import sensor_aliases
from ..data.signals import channel_issues, smooth
from ..robot.cache import cache_key, cached
from ..robot.expected import GRAVITY, FloatingBase, expected_wrenches, warn_if_zero_reference
from ..robot.kinematics import require_wrench_joints
from ..robot.loadcases import LoadCase, LoadCaseConfig
from ..robot.model import RobotModel
from ..robot.payloads import Payload
from ..runtime.errors import FtcalError, ParameterError, FtcalWarning
from ..runtime.deprecation import deprecated_alias


@dataclass(frozen=True)
class InsituOptions:
    """How recordings become a dataset.

    base, gravity : fixed-base frame and gravity in its axes (see ftcal.robot.expected)
    savgol_frame, savgol_order : Savitzky–Golay smoothing of the raw channels and
        temperature; ``savgol_frame=None`` turns it off
    rate : Hz of a uniform clock, or None for the sensor's own timestamps
    temperature : include the temperature input ``T`` (needs a temperature stream)
    derivatives : use logged joint velocities/accelerations (else static)
    imu, imu_frame : accelerometer/gyro stream name and its URDF frame, for floating-base kinematics
    align_first_sample : the paper's dataset offset: shift each recording's raw
        channels so its first sample equals the expected wrench there
    joint_units : "rad" or "deg" (joint data in the logs)
    adc_limits : (low, high) raw values that mean the ADC saturated, or None
    cache : reuse expected wrenches from the cache (see ftcal.robot.cache)
    cache_dir : folder of the cache, or None for the user cache folder (~/.cache/ftcal)
    workers : processes for the expected wrenches
    payload_link : link of an unknown payload to estimate later with the calibration
        (``ftcal fit --estimate-payload``): the dataset then also holds its regressor
        columns ``Y_<link>_<output>_<parameter>`` (4 parameters m, mcx, mcy, mcz for static
        data; all 10 with ``derivatives`` or an IMU), see :mod:`ftcal.payload.unknown_load`
    """

    base: str | None = None
    gravity: tuple[float, float, float] = GRAVITY
    savgol_frame: int | None = 101
    savgol_order: int = 3
    rate: float | None = None
    temperature: bool = True
    derivatives: bool = False
    imu: str | None = None
    imu_frame: str | None = None
    align_first_sample: bool = False
    joint_units: str = "rad"
    adc_limits: tuple[float, float] | None = None
    cache: bool = True
    cache_dir: str | Path | None = None
    workers: int = 2
    payload_link: str | None = None


LOG_COLUMNS = ("time", "static", "hold")  # beside the joints, in a LogTable's columns


@dataclass(frozen=True)
class LogTable:
    """A dataset from robot logs and the columns beside it that a fit does not take.

    dataset : inputs u1..u6 (and T), outputs Fx..Tz, one segment per recording
    columns : column name → ndarray of shape (n_samples,), in writing order: ``time``, the joint
        positions, ``static`` and ``hold`` (see the module docstring)
    notes : one line per recording: its holds
    """

    dataset: Dataset
    columns: dict[str, np.ndarray]
    notes: tuple[str, ...]


def recordings_dataset(recordings: Sequence[str | Path], robot: RobotModel, sensor: str, *,
                  payloads: Sequence[Payload] = (), load_cases: LoadCaseConfig | None = None,
                  options: InsituOptions = InsituOptions(), executor=None) -> Dataset:
    """One dataset for F/T ``sensor`` from all ``recordings`` (one segment each).

    The dataset of :func:`build_log_table`; the parameters are its.

    Returns
    -------
    Dataset with inputs u1..u6 (and T), outputs Fx..Tz, one segment per recording.
    """
    return build_log_table(recordings, robot, sensor, payloads=payloads, load_cases=load_cases,
                           options=options, executor=executor).dataset


def build_log_table(recordings: Sequence[str | Path], robot: RobotModel, sensor: str, *,
                    payloads: Sequence[Payload] = (), load_cases: LoadCaseConfig | None = None,
                    options: InsituOptions = InsituOptions(), executor=None) -> LogTable:
    """One dataset for F/T ``sensor`` from all ``recordings`` (one segment each), with time, joints and holds.

    Parameters
    ----------
    recordings : paths of the recordings, one segment each, in this order
    robot : the robot without the recordings' payloads
    sensor : F/T sensor (sensor or joint name)
    payloads : payloads attached in every recording
    load_cases : payloads and load-case names per recording
    options : how recordings become a dataset
    executor : None to work here, or an executor of :mod:`ftcal.runtime.executors`
        (e.g. a Dask cluster): one task per recording; the workers rebuild the
        robot from its URDF text and compute expected wrenches in one process
        each; their warnings are re-emitted here, recording by recording.

    Returns
    -------
    LogTable: the dataset (inputs u1..u6 and T, outputs Fx..Tz, one segment per recording) and its
    ``time``, joint, ``static`` and ``hold`` columns, the holds numbered over all recordings.

    Raises
    ------
    FtcalError
        No recordings, an unknown sensor or base, a recording that cannot be used, or a joint
        named like another column.
    """
    if not recordings:
        raise FtcalError("No recordings given.")
    if (options.imu is None) != (options.imu_frame is None):
        raise ParameterError(('imu', 'imu_frame'), "Give both {imu} (stream name) and {imu_frame} (URDF frame), or neither.")
    ft_sensor = robot.sensor(sensor)  # fail early on an unknown sensor
    robot.base_frame(options.base)
    config = load_cases or LoadCaseConfig()
    models: dict[tuple[Payload, ...], RobotModel] = {}
    parts = []
    tasks = []
    for segment, path in enumerate(recordings):
        case = config.resolve(path, tuple(payloads))
        if executor is not None:
            description = (robot.urdf_text, robot.source, (*robot.payloads, *case.payloads), robot.declared)
            tasks.append((path, description, ft_sensor.name, case, segment))
            continue
        if case.payloads not in models:
            models[case.payloads] = robot.with_payloads(case.payloads)
        parts.append(recording_table(path, models[case.payloads], ft_sensor.name, case, segment, options))
    if executor is not None:
        # One process per task on the workers: a Dask worker must not start its own process pool.
        results = executor.map(_recording_task, tasks, dataclasses.replace(options, workers=1),
                               description="recordings")
        for part, caught in results:
            for message, category in caught:
                warnings.warn(message, category, stacklevel=2)
            parts.append(part)
    return _join(parts)


def _join(parts: Sequence[LogTable]) -> LogTable:
    """One table from the recordings' tables: the joints they all log, holds numbered across them."""
    dataset = concatenate([p.dataset for p in parts])
    joints = [name for name in parts[0].columns if name not in LOG_COLUMNS
              and all(name in p.columns for p in parts)]
    columns = {name: np.concatenate([p.columns[name] for p in parts]) for name in ("time", *joints, "static")}
    columns["hold"] = number_across([p.columns["hold"] for p in parts])
    return LogTable(dataset, columns, tuple(line for p in parts for line in p.notes))


def _recording_task(path: str | Path, description: tuple, sensor: str, case: LoadCase, segment: int,
                    options: InsituOptions) -> tuple[LogTable, list[tuple[str, type]]]:
    """:func:`recording_table` as a worker runs it: the table and its FtcalWarnings (text, class), in order.

    Other warnings (e.g. deprecation notes of the worker's first iDynTree import) stay on the worker.
    """
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        part = recording_table(path, robot_from_description(*description), sensor, case, segment, options)
    return part, [(str(w.message), w.category) for w in caught if issubclass(w.category, FtcalWarning)]


@functools.lru_cache(maxsize=8)
def robot_from_description(urdf_text: str, source: str, payloads: tuple[Payload, ...],
                           declared: tuple) -> RobotModel:
    """A RobotModel rebuilt from its picklable description, once per worker process and description.

    Parameters
    ----------
    urdf_text, source, payloads, declared : a RobotModel's URDF text, source, payloads and declared sensors

    Returns
    -------
    RobotModel
    """
    return RobotModel(urdf_text, source, payloads, declared)


def recording_table(path: str | Path, robot: RobotModel, sensor: str, case: LoadCase, segment: int,
                    options: InsituOptions = InsituOptions()) -> LogTable:
    """The table of one recording (holds counted from 0); ``robot`` already carries the load case's payloads."""
    path = Path(path)
    ft_sensor = robot.sensor(sensor)
    recording = read_recording(path, options.joint_units)
    aliases = sensor_aliases(ft_sensor.name, ft_sensor.joint)
    for issue in channel_issues(recording.ft_stream(*aliases), options.adc_limits):
        warnings.warn(str(issue), FtcalWarning, stacklevel=2)
    data = align(recording, aliases, temperature=options.temperature, derivatives=options.derivatives,
                 imu=options.imu, rate=options.rate)
    if set(data.joint_names) <= set(robot.joint_names):  # else joint_matrix names the joints the URDF lacks
        require_wrench_joints(robot, data.joint_names, options.imu_frame or robot.base_frame(options.base)[1],
                              [ft_sensor.name], f"Recording {path}", " (joints off the chain to the sensor and "
                              "off the links beyond it may be left out)")
    expected = _expected(path, robot, data, options)[:, ft_sensor.index, :]
    warn_if_zero_reference(expected, f"Recording {path}", ft_sensor.name, case.name)
    raw, temp = data.ft, data.temperature
    if options.savgol_frame is not None:
        raw = smooth(raw, options.savgol_frame, options.savgol_order, where=f"Recording {path}")
        temp = None if temp is None else smooth(temp, options.savgol_frame, options.savgol_order,
                                                where=f"Recording {path}")
    if options.align_first_sample:
        raw = raw - (raw[0] - expected[0])
    names = DEFAULT_INPUTS if temp is not None else DEFAULT_INPUTS[:6]
    inputs = raw if temp is None else np.column_stack([raw, temp])
    n = inputs.shape[0]
    outputs, output_names = expected, DEFAULT_OUTPUTS
    if options.payload_link is not None:
        columns, regressor = _payload_regressor(path, robot, ft_sensor.name, data, options)
        outputs = np.column_stack([expected, regressor.reshape(n, -1)])
        output_names = DEFAULT_OUTPUTS + columns
    ds = Dataset.from_arrays(inputs, outputs, input_names=names, output_names=output_names,
                             segments=np.full(n, segment), groups=np.full(n, case.name, dtype=object))
    taken = set(names) | set(output_names) | set(LOG_COLUMNS) | {SEGMENT_COLUMN, LOAD_COLUMN}
    clash = [name for name in data.joint_names if name in taken]
    if clash:
        raise FtcalError(f"Recording {path}: a joint is named {clash[0]!r}, like a column of the dataset; "
                         "rename the joint.")
    holds = _holds(path, data, raw)
    columns = {"time": data.time, **{name: data.q[:, j] for j, name in enumerate(data.joint_names)},
               "static": holds.static.astype(np.int64), "hold": holds.hold}
    return LogTable(dataclasses.replace(ds, sources=(str(path),)), columns, (f"{path}: {holds.describe(data.time)}",))


def _holds(path: Path, data: Aligned, raw: np.ndarray) -> Holds:
    """Static holds of one recording: from the logged joint positions, else the wrench's variation."""
    if data.q.shape[1]:
        return find_holds(data.time, joints=data.q, where=f"Recording {path}")
    return find_holds(data.time, wrench=raw, where=f"Recording {path}")


def _payload_regressor(path: Path, robot: RobotModel, sensor: str, data: Aligned,
                       options: InsituOptions) -> tuple[tuple[str, ...], np.ndarray]:
    """Column names and (n_samples, 6, k) regressor of the unknown payload on ``options.payload_link``."""
    from ..payload.regressor import INERTIAL_PARAMETERS
    from ..payload.unknown_load import payload_column
    from ..robot.kinematics import N_STATIC_PARAMETERS, payload_regressor

    where = f"Recording {path} joints_state"
    q = robot.joint_matrix(data.joint_names, data.q, where)
    dq = None if data.dq is None else robot.joint_matrix(data.joint_names, data.dq, where)
    ddq = None if data.ddq is None else robot.joint_matrix(data.joint_names, data.ddq, where)
    floating = None if options.imu_frame is None else FloatingBase(options.imu_frame, data.accelerometer, data.gyro)
    static = dq is None and ddq is None and floating is None
    regressor = payload_regressor(robot, sensor, options.payload_link, q, dq, ddq, base=options.base,
                                  gravity=options.gravity, floating=floating, static=static)
    parameters = INERTIAL_PARAMETERS[:N_STATIC_PARAMETERS] if static else INERTIAL_PARAMETERS
    columns = tuple(payload_column(options.payload_link, o, p) for o in DEFAULT_OUTPUTS for p in parameters)
    return columns, regressor


def _expected(path: Path, robot: RobotModel, data: Aligned, options: InsituOptions) -> np.ndarray:
    """Expected wrenches of all sensors, (n_samples, n_sensors, 6), cached (see ftcal.robot.cache)."""
    where = f"Recording {path} joints_state"
    q = robot.joint_matrix(data.joint_names, data.q, where)
    dq = None if data.dq is None else robot.joint_matrix(data.joint_names, data.dq, where)
    ddq = None if data.ddq is None else robot.joint_matrix(data.joint_names, data.ddq, where)
    floating = None
    if options.imu_frame is not None:
        floating = FloatingBase(options.imu_frame, data.accelerometer, data.gyro)
    base = robot.base_frame(options.base)[1]
    arrays = [q, dq, ddq, None if floating is None else floating.proper_acceleration,
              None if floating is None else floating.angular_velocity]

    def compute() -> np.ndarray:
        return expected_wrenches(robot, q, dq=dq, ddq=ddq, floating=floating, base=base,
                                 gravity=options.gravity, workers=options.workers,
                                 description=f"expected wrenches {path.name}")

    if not options.cache:
        return compute()
    key = cache_key(robot, arrays, (base, tuple(options.gravity), options.imu_frame))
    return cached(key, [s.name for s in robot.ft_sensors], q.shape[0], compute, options.cache_dir)


def write_dataset(dataset: Dataset | LogTable, path: str | Path) -> None:
    """Write ``dataset`` as Parquet or CSV (by extension), atomically.

    Columns: the input names, the output names, for a :class:`LogTable` its columns
    (``time``, the joints, ``static``, ``hold``), then ``segment`` and ``group``.
    """
    from ..data.tables import write_table

    write_table(dataset_frame(dataset), path)


def dataset_frame(dataset: Dataset | LogTable):
    """The columns :func:`write_dataset` writes, as a pandas DataFrame."""
    import pandas as pd

    extra: dict[str, np.ndarray] = {}
    if isinstance(dataset, LogTable):
        dataset, extra = dataset.dataset, dataset.columns
    if dataset.outputs is None:
        raise FtcalError("The dataset has no outputs to write.")
    columns = {name: dataset.inputs[:, i] for i, name in enumerate(dataset.input_names)}
    columns.update({name: dataset.outputs[:, i] for i, name in enumerate(dataset.output_names)})
    columns.update(extra)
    columns[SEGMENT_COLUMN] = dataset.segments
    columns[LOAD_COLUMN] = np.asarray(dataset.groups).astype(str)
    return pd.DataFrame(columns)


# The old name, shadowed by the dataset step (ftcal.build_dataset, another signature).
build_dataset = deprecated_alias(recordings_dataset, "ftcal.insitu.recordings.build_dataset",
                                 "ftcal.insitu.recordings.recordings_dataset")
