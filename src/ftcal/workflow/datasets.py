"""Robot logs or ROS bags to a fit-ready dataset (``ftcal dataset``); expected wrenches of joint tables
(``ftcal expected``)."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

from ..runtime.errors import single_line
from ..runtime.errors import FtcalError, ParameterError
from .result import StepResult
from .sources import reads_tables, robot_model

WRENCH = ("Fx", "Fy", "Fz", "Tx", "Ty", "Tz")
BAG_OPTIONS = ("wrench_topic", "joints_topic", "temperature_topic", "imu_topic", "tf", "receive_time")


@dataclass(repr=False)
class DatasetResult(StepResult):
    """A dataset built from recordings: its columns, and what was noticed on the way.

    Attributes
    ----------
    table : LogTable (robot logs) or BagTable (ROS bags); ``save`` writes it
    kind : {"logs", "bags"}
    n_recordings : int, the recordings (robot logs or bags) read
    notes : list of str, one line per thing noticed (printed first)

    Examples
    --------
    >>> import numpy as np
    >>> from ftcal.insitu.bags import BagTable
    >>> table = BagTable({"time": np.arange(3.0), "u1": np.zeros(3)}, ())
    >>> result = DatasetResult(table, "bags", 1)
    >>> result.n_samples, result.columns, result.description
    (3, ['time', 'u1'], '3 samples from 1 bag(s), columns time,u1')
    """

    table: object
    kind: str
    n_recordings: int
    notes: list[str] = field(default_factory=list)

    @property
    def n_samples(self) -> int:
        """Rows of the dataset."""
        return self.table.dataset.n_samples if self.kind == "logs" else self.table.n_samples

    @property
    def columns(self) -> list[str]:
        """The dataset's column names, in file order."""
        return list(self.table.columns)

    def to_frame(self):
        """The dataset as a pandas DataFrame (the table ``save`` writes)."""
        import pandas as pd

        if self.kind == "bags":
            return pd.DataFrame(dict(self.table.columns))
        from ..insitu.recordings import dataset_frame

        return dataset_frame(self.table)

    @property
    def load_cases(self) -> list[str]:
        """The load cases of a dataset from robot logs, sorted (none from bags)."""
        return sorted(set(map(str, self.table.dataset.groups))) if self.kind == "logs" else []

    @property
    def n_holds(self) -> int:
        """The static holds of a dataset from robot logs (0 from bags)."""
        if self.kind != "logs" or not self.n_samples:
            return 0
        return int(self.table.columns["hold"].max()) + 1

    @property
    def description(self) -> str:
        """What the table holds, in one line (the last of :meth:`summary`)."""
        if self.kind == "bags":
            return (f"{self.n_samples} samples from {self.n_recordings} bag(s), columns "
                    f"{single_line(','.join(self.table.columns))}")
        return (f"{self.n_samples} samples from {self.n_recordings} recording(s), "
                f"load case(s) {', '.join(self.load_cases)}, {self.n_holds} static hold(s)")

    def summary(self) -> str:
        return "\n".join([*self.notes, self.description])

    def to_dict(self) -> dict:
        from .result import plain

        return plain({"kind": self.kind, "n_samples": self.n_samples, "columns": self.columns,
                      "n_recordings": self.n_recordings, "load_cases": self.load_cases, "n_holds": self.n_holds,
                      "description": self.description, "notes": self.notes})

    def save(self, path) -> None:
        """Write the dataset (.parquet or .csv, atomically)."""
        if self.kind == "bags":
            from ..insitu.bags import write_bag_table

            write_bag_table(self.table, Path(path))
        else:
            from ..insitu.recordings import write_dataset

            write_dataset(self.table, Path(path))


@reads_tables("logs", "LOG", dataset="refuse")
def build_dataset(logs, *, urdf=None, robot: str | None = None, sensor: str | None = None,
                  ft_joint: str | None = None, ft_frame: str | None = None, payload: Sequence[str] = (),
                  base: str | None = None, wrench_topic: str | None = None, joints_topic: str | None = None,
                  temperature_topic: str | None = None, imu_topic: str | None = None, receive_time: bool = False,
                  tf: tuple[str, str | None] | None = None, payload_file=None,
                  gravity: Sequence[float] = (0.0, 0.0, -9.81), savgol_frame: int = 101, savgol_order: int = 3,
                  no_filter: bool = False, rate: float | None = None, no_temperature: bool = False,
                  degrees: bool = False, dynamic: bool = False, imu: str | None = None, imu_frame: str | None = None,
                  align_first_sample: bool = False, adc_limits: tuple[float, float] | None = None,
                  estimate_payload: str | None = None, workers: int = 2, no_cache: bool = False, cache_dir=None,
                  executor=None, output=None) -> DatasetResult:
    """Robot logs (.mat/.csv/.parquet) or ROS bags to a fit-ready dataset for one F/T sensor: ``ftcal dataset``.

    Every keyword is the command's flag of the same name (``ftcal dataset --help``); ``robot`` is
    ``--model NAME``. ``sensor`` may be left out when the robot model has one F/T sensor (e.g. the one
    ``ft_joint`` declares on a plain URDF): that one is used, and a note says so.

    Parameters
    ----------
    logs : path or list of paths, all robot logs or all ROS bags; or robot-log tables in memory (a
        DataFrame, a list of them, or a dict name -> DataFrame), read as the same tables in Parquet files
    executor : an executor of :mod:`ftcal.runtime.executors` (e.g. Dask) for the per-file work, or None
    output : path or None; when given, the dataset is written there

    Returns
    -------
    DatasetResult

    Raises
    ------
    FtcalError
        Bad input: a mix of bags and logs, a bag option for logs, no robot model for logs, an
        ambiguous sensor, or any problem of the recordings (naming file and column).

    Examples
    --------
    >>> build_dataset([])
    Traceback (most recent call last):
    ...
    ftcal.runtime.errors.FtcalError: LOG: no file given.
    """
    from ..data.logs import is_bag as bag
    from ..insitu.recordings import InsituOptions, build_log_table
    from ..robot import load_case_config, parse_payload_spec

    paths = logs.paths
    is_bag = [bag(p) for p in paths]
    if any(is_bag) and not all(is_bag):
        raise FtcalError(f"LOG {paths[is_bag.index(False)]}: mix of ROS bags and other logs; "
                         "build one dataset per kind.")
    given = {"wrench_topic": wrench_topic, "joints_topic": joints_topic, "temperature_topic": temperature_topic,
             "imu_topic": imu_topic, "tf": tf, "receive_time": receive_time}
    if not any(is_bag):
        named = [o for o in BAG_OPTIONS if given[o] not in (None, False)]
        if named:
            raise ParameterError(named[0], f"{{{named[0]}}} applies to ROS bags only; {paths[0]} is not a bag.")
        if urdf is None and robot is None:
            raise ParameterError(('urdf', 'robot'), "{urdf} or {robot} is required for .mat/.csv/.parquet logs.")
    if any(is_bag) and estimate_payload:
        raise ParameterError('estimate_payload',
                             "{estimate_payload} applies to .mat/.csv/.parquet logs; for a bag, identify "
                         "the tool with `ftcal payload` on the bag's dataset.")
    model = (robot_model(urdf=urdf, robot=robot, ft_joint=ft_joint, ft_frame=ft_frame)
             if urdf is not None or robot is not None else None)
    notes = []
    if model is not None and sensor is None:
        sensors = model.ft_sensors
        if len(sensors) != 1:
            raise ParameterError(('sensor', 'ft_joint'), "{sensor} is required: the robot model has "
                             + (f"{len(sensors)} F/T sensors ({', '.join(s.name for s in sensors)})."
                                if sensors else "no F/T sensor (declare one with {ft_joint} JOINT)."))
        sensor = sensors[0].name
        notes.append(f"sensor: {single_line(sensor)}, the robot model's only F/T sensor")
    payloads = [parse_payload_spec(spec) for spec in payload]
    config = load_case_config(payload_file) if payload_file else None
    options = InsituOptions(
        base=base, gravity=tuple(gravity), savgol_frame=None if no_filter else savgol_frame,
        savgol_order=savgol_order, rate=rate, temperature=not no_temperature, derivatives=dynamic,
        imu=imu, imu_frame=imu_frame, align_first_sample=align_first_sample,
        joint_units="deg" if degrees else "rad", adc_limits=tuple(adc_limits) if adc_limits else None,
        cache=not no_cache, cache_dir=cache_dir, workers=workers, payload_link=estimate_payload)
    if all(is_bag):
        from ..data.bags import BagTopics
        from ..insitu.bags import build_bag_table

        if wrench_topic is None:
            raise ParameterError('wrench_topic', f"Bag {paths[0]}: {{wrench_topic}} is required (list the topics with "
                             f"'ftcal topics {paths[0]}').")
        topics = BagTopics(wrench_topic, joints_topic, temperature_topic, imu_topic, tf, receive_time=receive_time)
        table = build_bag_table(paths, topics, robot=model, sensor=sensor, payloads=payloads, load_cases=config,
                                options=options, executor=executor)
        result = DatasetResult(table, "bags", len(paths), notes + [single_line(n) for n in table.notes])
    else:
        table = build_log_table(paths, model, sensor, payloads=payloads, load_cases=config, options=options,
                                executor=executor)
        result = DatasetResult(table, "logs", len(paths), notes + [single_line(n) for n in table.notes])
    if output is not None:
        result.save(output)
    return result


@dataclass(repr=False)
class ExpectedResult(StepResult):
    """Expected F/T wrenches for a joint table: ``table`` has ``time`` (when given) and ``SENSOR_Fx..Tz``."""

    table: object
    sensors: list[str] = field(default_factory=list)

    def summary(self) -> str:
        return f"{len(self.table)} samples x {len(self.sensors)} sensor(s)"

    def to_dict(self) -> dict:
        from .result import plain

        return plain({"n_samples": len(self.table), "sensors": self.sensors,
                      "columns": {str(c): self.table[c].to_numpy() for c in self.table.columns}})

    def save(self, path) -> None:
        """Write the table (CSV or Parquet by suffix, atomically)."""
        from ..data.tables import write_table

        write_table(self.table, Path(path))


@reads_tables("joints", "joints", dataset="refuse")
def expected(joints, *, urdf=None, robot: str | None = None, ft_joint: str | None = None,
             ft_frame: str | None = None, payload: Sequence[str] = (), base: str | None = None,
             sensor: Sequence[str] = (), gravity: Sequence[float] = (0.0, 0.0, -9.81), degrees: bool = False,
             workers: int = 2, no_cache: bool = False, cache_dir=None, missing_joints: str = "refuse",
             executor=None, output=None) -> ExpectedResult:
    """The wrench each F/T sensor should measure for every row of a joint table: ``ftcal expected``.

    Parameters
    ----------
    joints : path of a CSV/Parquet table, one column per joint (rad, or degrees with ``degrees``), or that
        table as a pandas DataFrame (written to a temporary Parquet file for the step; with an executor,
        its workers must see this machine's temporary folder, as ``local:N`` does)
    urdf, robot, ft_joint, ft_frame, payload, base : the robot model (as ``ftcal expected``)
    sensor : sensor names (default: every F/T sensor)
    gravity : gravity in base-frame axes, m/s²
    missing_joints : ``"refuse"`` (default) a table that lacks a joint the sensors' wrench depends on (on
        the chain from the base, or beyond the sensor), or ``"zero"``: the caller says it is at 0 rad
    executor : an executor of :mod:`ftcal.runtime.executors`: the joints file is one task there; or None
    output : path or None; when given, the table is written there

    Returns
    -------
    ExpectedResult

    Raises
    ------
    FtcalError
        Bad robot options, an unknown sensor or joint, a non-numeric joint column.
    """
    import pandas as pd

    if len(joints.paths) != 1:
        raise ParameterError('joints', f"{{joints}}: one joint table, not {len(joints.paths)}.")
    [path] = joints.paths
    model = robot_model(urdf=urdf, robot=robot, ft_joint=ft_joint, ft_frame=ft_frame, payload=payload)
    names = [sensor] if isinstance(sensor, str) else list(sensor)
    sensors = [model.sensor(name) for name in names] or list(model.ft_sensors)
    labels = names or [s.name for s in sensors]
    _, base_frame = model.base_frame(base)
    from ..core.limits import MISSING_JOINTS

    if missing_joints not in MISSING_JOINTS:
        raise ParameterError('missing_joints',
                             f"{{missing_joints}} {missing_joints!r}: must be one of {', '.join(MISSING_JOINTS)}.")
    settings = (base_frame, tuple(gravity), degrees, not no_cache, cache_dir, tuple(s.name for s in sensors),
                missing_joints)
    if executor is not None:
        description = (model.urdf_text, model.source, model.payloads, model.declared)
        [(time, wrenches)] = executor.map(_remote_wrenches, [(path, description)], 1, *settings,
                                          description="joints files")
    else:
        time, wrenches = joints_file_wrenches(path, model, workers, *settings)
    columns = {"time": time} if time is not None else {}
    for label, s in zip(labels, sensors):
        for axis, name in enumerate(WRENCH):
            columns[f"{label}_{name}"] = wrenches[:, s.index, axis]
    result = ExpectedResult(pd.DataFrame(columns), labels)
    if output is not None:
        result.save(output)
    return result


def joints_file_wrenches(joints, robot, workers, base, gravity, degrees, cache, cache_dir, sensors=(),
                         missing_joints="refuse"):
    """The ``time`` column (or None) and the (n_samples, n_sensors, 6) expected wrenches of a joints file.

    A joint that the wrench of one of ``sensors`` depends on and that the file lacks is refused unless
    ``missing_joints`` is ``"zero"`` (the user says it is at 0 rad).
    """
    import numpy as np

    from ..data.tables import numeric_columns, read_table
    from ..robot.cache import cache_key, cached
    from ..robot.expected import expected_wrenches
    from ..robot.kinematics import require_wrench_joints

    table = read_table(Path(joints))
    joint_cols = [c for c in table.columns if c != "time"]
    if missing_joints != "zero" and set(joint_cols) <= set(robot.joint_names):  # else joint_matrix names them
        require_wrench_joints(robot, joint_cols, base, sensors, f"{{joints}} {joints}",
                              " (give their columns, or {missing_joints} zero if they are at 0 rad)",
                              parameters=("joints", "missing_joints"))
    values = numeric_columns(table, joint_cols, Path(joints), "joint")
    if degrees:
        values = np.deg2rad(values)
    q = robot.joint_matrix(joint_cols, values, str(joints))

    def compute() -> np.ndarray:
        return expected_wrenches(robot, q, base=base, gravity=gravity, workers=workers)

    if not cache:
        wrenches = compute()
    else:
        key = cache_key(robot, [q], (base, tuple(gravity), None))
        wrenches = cached(key, [s.name for s in robot.ft_sensors], q.shape[0], compute, cache_dir)
    return (table["time"].to_numpy() if "time" in table.columns else None), wrenches


def _remote_wrenches(joints, description, workers, *settings):
    """:func:`joints_file_wrenches` on a Dask worker: the robot rebuilt from its picklable description."""
    from ..insitu.recordings import robot_from_description

    return joints_file_wrenches(joints, robot_from_description(*description), workers, *settings)


@dataclass(repr=False)
class SensorsResult(StepResult):
    """A robot model's six-axis F/T sensors, the mass beyond each seen from the base frame, and its joints.

    Attributes
    ----------
    robot : RobotModel, with its payloads
    base : str, the base frame the masses beyond the sensors are seen from

    Examples
    --------
    >>> result = robot_sensors(robot="iCubGenova04")
    >>> result.sensors[0]["name"], result.summary().splitlines()[0].startswith("model: ")
    ('l_leg_ft', True)
    """

    robot: object
    base: str

    @property
    def sensors(self) -> list[dict]:
        """One dict per sensor: name, joint, parent and child link, links beyond it and their mass (kg)."""
        robot, base = self.robot, self.base
        return [{"name": s.name, "joint": s.joint, "parent_link": s.parent_link, "child_link": s.child_link,
                 "links_beyond": len(robot.links_beyond(s, base)), "mass_beyond": float(robot.mass_beyond(s, base))}
                for s in robot.ft_sensors]

    def lines(self, name_of=str) -> list[str]:
        """The text, line by line; ``name_of`` names the parameters of the hint given without a sensor (the
        parameter itself by default; the CLI passes its flag names)."""
        from ..robot.declare import no_sensor_hint

        robot = self.robot
        lines = [f"model: {robot.source}", f"base frame: {self.base}; total mass {robot.total_mass():.4f} kg"]
        if robot.payloads:
            lines.append("payloads: " + "; ".join(f"{p.mass:g} kg on {p.frame}" for p in robot.payloads))
        rows = [("sensor", "joint", "parent link", "child link", "links beyond", "mass beyond [kg]")]
        rows += [(s["name"], s["joint"], s["parent_link"], s["child_link"], str(s["links_beyond"]),
                  f"{s['mass_beyond']:.4f}") for s in self.sensors]
        if len(rows) == 1:
            lines.append(f"F/T sensors: none; {no_sensor_hint(robot.urdf_text, name_of)}")
        else:
            lines.append(f"F/T sensors ({len(rows) - 1}):")
            widths = [max(len(r[i]) for r in rows) for i in range(len(rows[0]))]
            lines += ["  " + "  ".join(c.ljust(w) for c, w in zip(r, widths)).rstrip() for r in rows]
        lines.append(f"joints ({len(robot.joint_names)}): " + ", ".join(robot.joint_names))
        return lines

    def summary(self) -> str:
        return "\n".join(self.lines())

    def to_dict(self) -> dict:
        from .result import plain

        robot = self.robot
        return plain({"model": robot.source, "base": self.base, "total_mass": robot.total_mass(),
                      "payloads": [{"frame": p.frame, "mass": p.mass} for p in robot.payloads],
                      "sensors": self.sensors, "joints": list(robot.joint_names)})


def robot_sensors(*, urdf=None, robot: str | None = None, ft_joint: str | None = None, ft_frame: str | None = None,
                  payload: Sequence[str] = (), base: str | None = None) -> SensorsResult:
    """A robot model's F/T sensors, joints and the mass beyond each sensor: ``ftcal sensors``.

    Parameters
    ----------
    urdf, robot, ft_joint, ft_frame, payload : the robot model (:func:`ftcal.workflow.sources.robot_model`)
    base : the base frame (default ``root_link``, else the model's default base link)

    Returns
    -------
    SensorsResult

    Raises
    ------
    FtcalError
        No robot model, a URDF that does not parse, an unknown base frame.
    """
    model = robot_model(urdf=urdf, robot=robot, ft_joint=ft_joint, ft_frame=ft_frame, payload=payload)
    _, name = model.base_frame(base)
    return SensorsResult(model, name)


@dataclass(repr=False)
class TopicsResult(StepResult):
    """A ROS bag's topics: what :func:`bag_topics` read.

    Attributes
    ----------
    bag : str, the bag as given
    topics : list of TopicSummary (name, msgtype, count, rate in Hz or None), sorted by name
    """

    bag: str
    topics: list

    def summary(self) -> str:
        rows = [("topic", "type", "count", "rate [Hz]")]
        rows += [(single_line(s.name), single_line(s.msgtype), str(s.count),
                  "-" if s.rate is None else f"{s.rate:.6g}") for s in self.topics]
        widths = [max(len(r[i]) for r in rows) for i in range(4)]
        lines = [f"{single_line(self.bag)}: {len(self.topics)} topic(s)"]
        lines += ["  " + "  ".join([r[0].ljust(widths[0]), r[1].ljust(widths[1]), r[2].rjust(widths[2]),
                                    r[3].rjust(widths[3])]).rstrip() for r in rows]
        return "\n".join(lines)

    def to_dict(self) -> dict:
        from .result import plain

        return plain({"bag": self.bag, "topics": [{"name": s.name, "msgtype": s.msgtype, "count": s.count,
                                                   "rate": s.rate} for s in self.topics]})


def bag_topics(bag: str | Path) -> TopicsResult:
    """The topics of a ROS 1 .bag, a ROS 2 bag folder, a .db3 or an .mcap file: ``ftcal topics``.

    Parameters
    ----------
    bag : path
        The bag; its topics' message type, count and mean receive rate are read
        (:func:`ftcal.data.bags.list_topics`).

    Returns
    -------
    TopicsResult

    Raises
    ------
    FtcalError
        If the bag cannot be opened.
    """
    from ..data.bags import list_topics

    return TopicsResult(str(bag), list_topics(bag))
