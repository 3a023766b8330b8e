"""In-situ datasets: raw F/T readings against the wrenches the robot model expects.

For one F/T sensor and a list of recordings, :func:`build_dataset` reads each
recording, puts its streams on the sensor's clock, smooths the raw channels
and the temperature (Savitzky–Golay, optional), computes the expected wrench
with the recording's load case attached (:mod:`ftcal.robot`) and returns a
:class:`~ftcal.dataset.Dataset`:

* inputs ``u1..u6`` (the six raw channels) and ``T`` (temperature);
* outputs ``Fx Fy Fz Tx Ty Tz``, the expected wrench (convention in
  :mod:`ftcal.robot.expected`);
* one segment per recording (ARX lags never cross recordings);
* group = the recording's load case name, else the recording's file stem.

:func:`write_dataset` stores it as Parquet or CSV with those columns plus
``segment`` and ``group``, ready for ``ftcal fit DATA --segment-by segment
--group-by group``.
"""

from __future__ import annotations

import dataclasses
import warnings
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .dataset import DEFAULT_INPUTS, DEFAULT_OUTPUTS, Dataset, concatenate
from .errors import FtcalError, FtcalWarning
from .io.logs import read_recording, sensor_aliases
from .io.logs_quality import channel_issues, smooth
from .io.logs_sync import Aligned, align
from .robot.cache import cache_key, cached
from .robot.expected import GRAVITY, FloatingBase, expected_wrenches
from .robot.loadcases import LoadCase, LoadCaseConfig
from .robot.model import RobotModel
from .robot.payloads import Payload


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


def build_dataset(recordings: Sequence[str | Path], robot: RobotModel, sensor: str, *,
                  payloads: Sequence[Payload] = (), load_cases: LoadCaseConfig | None = None,
                  options: InsituOptions = InsituOptions()) -> Dataset:
    """One dataset for F/T ``sensor`` from all ``recordings`` (one segment each)."""
    if not recordings:
        raise FtcalError("No recordings given.")
    if (options.imu is None) != (options.imu_frame is None):
        raise FtcalError("Give both --imu (stream name) and --imu-frame (URDF frame), or neither.")
    ft_sensor = robot.sensor(sensor)  # fail early on an unknown sensor
    robot.base_frame(options.base)
    config = load_cases or LoadCaseConfig()
    models: dict[tuple[Payload, ...], RobotModel] = {}
    parts = []
    for segment, path in enumerate(recordings):
        case = config.resolve(path, tuple(payloads))
        if case.payloads not in models:
            models[case.payloads] = robot.with_payloads(case.payloads)
        parts.append(recording_dataset(path, models[case.payloads], ft_sensor.name, case, segment, options))
    return concatenate(parts)


def recording_dataset(path: str | Path, robot: RobotModel, sensor: str, case: LoadCase, segment: int,
                      options: InsituOptions = InsituOptions()) -> Dataset:
    """The dataset of one recording; ``robot`` already carries the load case's payloads."""
    path = Path(path)
    ft_sensor = robot.sensor(sensor)
    recording = read_recording(path, options.joint_units)
    aliases = sensor_aliases(ft_sensor.name, ft_sensor.joint)
    for issue in channel_issues(recording.ft_stream(*aliases), options.adc_limits):
        warnings.warn(str(issue), FtcalWarning, stacklevel=2)
    data = align(recording, aliases, temperature=options.temperature, derivatives=options.derivatives,
                 imu=options.imu, rate=options.rate)
    expected = _expected(path, robot, data, options)[:, ft_sensor.index, :]
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
    ds = Dataset.from_arrays(inputs, expected, input_names=names, output_names=DEFAULT_OUTPUTS,
                             segments=np.full(n, segment), groups=np.full(n, case.name, dtype=object))
    return dataclasses.replace(ds, sources=(str(path),))


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


def write_dataset(dataset: Dataset, path: str | Path) -> None:
    """Write ``dataset`` as Parquet or CSV (by extension), atomically.

    Columns: the input names, the output names, ``segment`` and ``group``.
    """
    import pandas as pd

    from .io.tables import write_table

    if dataset.outputs is None:
        raise FtcalError("The dataset has no outputs to write.")
    columns = {name: dataset.inputs[:, i] for i, name in enumerate(dataset.input_names)}
    columns.update({name: dataset.outputs[:, i] for i, name in enumerate(dataset.output_names)})
    columns["segment"] = dataset.segments
    columns["group"] = np.asarray(dataset.groups).astype(str)
    write_table(pd.DataFrame(columns), path)
