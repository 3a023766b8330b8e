"""The live step: the live calibrator built from a model, a tool library and a gravity source, run over a
recording (:func:`replay_live`), over Zenoh (:func:`serve_zenoh`) or as a ROS 2 node (:func:`serve_ros2`).

`ftcal live` parses its options into a :class:`LiveSetup` and calls one of these; Python users and the
demos call the same functions. Messages name the parameters (``tools``, ``walk_std``); the CLI writes
them as its flags.
"""

from __future__ import annotations

import dataclasses
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

from ..runtime.errors import FtcalError, ParameterError
from .result import StepResult

DEFAULT_WRENCH = ("u1", "u2", "u3", "u4", "u5", "u6")


def _six(values, name: str):
    """Two values (force, torque) or six, as an array of six; None stays None."""
    import numpy as np

    if values is None:
        return None
    if len(values) == 2:
        return np.r_[np.full(3, values[0]), np.full(3, values[1])]
    if len(values) == 6:
        return np.asarray(values, dtype=float)
    raise ParameterError(name, f"{{{name}}}: give two values (force, torque) or six; got {len(values)}.")


@dataclass(frozen=True)
class LiveSetup:
    """What the live calibrator is built from: the options the replay, Zenoh and ROS 2 share.

    Parameters
    ----------
    model : CalibrationModel, path of a model file, or None (the signal is the wrench)
    tools : mapping or sequence of (name, payload) pairs; a payload is a
        :class:`~ftcal.payload.parameters.PayloadParameters` or a payload file
    mount : the tool mounted at the start (default: the first tool, else ``"none"``)
    walk_std, noise_std : bias random-walk std per sqrt(h) and per-sample noise std: (force, torque) or six
        values (default: the identified ones, see :class:`~ftcal.live.LiveCalibrator`)
    bias : six initial bias values, N and N m (default: the first static samples set it)
    g : gravity magnitude, m/s²
    state : state file, resumed from when it exists and saved at the end
    urdf, sensor, ft_joint, ft_frame, base, degrees : gravity from the joints of this robot model
    """

    model: Any = None
    tools: Any = ()
    mount: str | None = None
    walk_std: Sequence[float] | None = None
    noise_std: Sequence[float] | None = None
    bias: Sequence[float] | None = None
    g: float = 9.81
    state: str | os.PathLike | None = None
    urdf: str | os.PathLike | None = None
    sensor: str | None = None
    ft_joint: str | None = None
    ft_frame: str | None = None
    base: str | None = None
    degrees: bool = False

    def tool_items(self) -> list[tuple[str, Any]]:
        return list(self.tools.items() if isinstance(self.tools, Mapping) else self.tools)

    def robot_gravity(self, joint_names: Sequence[str] | None = None, where: str = "the joints"):
        """The joints-to-gravity source (:class:`~ftcal.robot.kinematics.SensorGravity`) over the joints among
        ``joint_names`` (None: all the robot's), built as the payload step builds its URDF source; None
        without ``urdf``."""
        from ..robot.kinematics import SensorGravity, kinematics_source

        if self.urdf is None:
            for name in ("sensor", "ft_joint", "ft_frame", "base"):
                if getattr(self, name) is not None:
                    raise ParameterError((name, "urdf"), f"{{{name}}} goes with {{urdf}} (gravity from the joints).")
            return None
        source = kinematics_source(urdf=str(self.urdf), sensor=self.sensor, ft_joint=self.ft_joint,
                                   ft_frame=self.ft_frame, base=self.base, g=self.g, degrees=self.degrees,
                                   robot_parameters=("urdf",))
        known = set(source.robot.joint_names)
        names = source.robot.joint_names if joint_names is None else [n for n in joint_names if n in known]
        if not names:
            raise FtcalError(f"{where}: nothing named like a joint of URDF {source.robot.source} "
                             f"(e.g. {', '.join(source.robot.joint_names[:4])}).")
        return SensorGravity(source.robot, source.sensor, names, base=source.base, g=source.g,
                             degrees=source.degrees, source=where)

    def calibrator(self, robot=None):
        """The :class:`~ftcal.live.LiveCalibrator` of this setup (``robot``: a joints-to-gravity source)."""
        return live_calibrator(self.model, self.tool_items(), mount=self.mount, walk_std=self.walk_std,
                               noise_std=self.noise_std, bias=self.bias, g=self.g, state=self.state, robot=robot)


def live_calibrator(model=None, tools: Mapping[str, Any] | Sequence[tuple[str, Any]] = (), *, mount: str | None = None,
                    walk_std: Sequence[float] | None = None, noise_std: Sequence[float] | None = None,
                    bias: Sequence[float] | None = None, g: float = 9.81, state: str | os.PathLike | None = None,
                    robot=None):
    """A :class:`~ftcal.live.LiveCalibrator` from a model and a tool library given as objects or files.

    Parameters are those of :class:`LiveSetup`; ``robot`` is a joints-to-gravity source
    (:meth:`LiveSetup.robot_gravity`) or None.

    Raises
    ------
    ParameterError
        A tool name given twice (or ``none``), an unknown ``mount``, a negative standard deviation, a bias
        that is not six values.
    """
    from ..files.model_files import load_model
    from ..files.payload_json import load_payload
    from ..live import LiveCalibrator

    library = {}
    for name, payload in (tools.items() if isinstance(tools, Mapping) else tools):
        if name in library or name == "none":
            raise ParameterError("tools", f"{{tools}} {name}={payload}: the name {name!r} is taken; give each "
                                          "tool its own name.")
        library[name] = load_payload(payload) if isinstance(payload, (str, os.PathLike)) else payload
    mount = mount if mount is not None else next(iter(library), "none")
    if mount not in library and mount != "none":
        raise ParameterError("mount", f"{{mount}} {mount}: no such tool ({', '.join(['none', *library])}).")
    model = load_model(model) if isinstance(model, (str, os.PathLike)) else model
    for name, values in (("walk_std", walk_std), ("noise_std", noise_std)):
        if values is not None and any(v < 0 for v in values):
            raise ParameterError(name, f"{{{name}}}: standard deviations must be >= 0.")
    if bias is not None and len(bias) != 6:
        raise ParameterError("bias", f"{{bias}}: give six values; got {len(bias)}.")
    return LiveCalibrator(model, library, tool=mount, walk_std=_six(walk_std, "walk_std"),
                          noise_std=_six(noise_std, "noise_std"), initial_bias=_six(bias, "bias"),
                          gravity_magnitude=g, state_path=None if state is None else str(state), robot=robot)


@dataclass(repr=False)
class LiveReplayResult(StepResult):
    """What :func:`replay_live` did.

    Attributes
    ----------
    replay : the replay's :class:`~ftcal.live.replay.ReplaySummary` (samples, time, flags, events)
    dropped : incomplete rows skipped (``drop_incomplete``)
    tracker : counts of the tracker's lock-outs, re-acquisitions, adaptations and rollbacks
    tracker_events : the first tracker events (time, kind, reason) other than adaptations
    bias, bias_std : the bias at the end and its standard deviation, N and N m
    tool : the tool mounted at the end
    output, state : the files written
    """

    replay: Any
    dropped: int
    tracker: dict
    tracker_events: list
    bias: list
    bias_std: list
    tool: str
    output: str
    state: str | None = None

    def summary(self) -> str:
        lines = [self.replay.line() + (f"; {self.dropped} incomplete row(s) dropped" if self.dropped else "")]
        events = self.replay.events
        lines += [f"  t={when:.3f} s  {flag}: {reason}" for when, flag, _, reason in events[:10]]
        if len(events) > 10:
            lines.append(f"  ... {len(events) - 10} more flag(s) raised (the table's flag_names column has them all)")
        if any(self.tracker.values()):
            lines.append("tracker: " + ", ".join(f"{n} {what}{'s' if n != 1 else ''}"
                                                 for what, n in self.tracker.items() if n))
            lines += [f"  t={when:.3f} s  {kind}: {reason}" for when, kind, reason in self.tracker_events]
        lines.append("bias now: " + ", ".join(f"{v:.4g} ± {s:.2g}" for v, s in zip(self.bias, self.bias_std))
                     + f" (tool {self.tool!r})")
        lines.append(f"wrote {self.output}" + (f" and {self.state}" if self.state else ""))
        return "\n".join(lines)

    def to_dict(self) -> dict:
        from .result import plain

        return plain({**{f.name: getattr(self, f.name) for f in dataclasses.fields(self) if f.name != "replay"},
                      "n_samples": self.replay.n_samples, "flag_samples": self.replay.flag_samples})


def _tracker(live) -> tuple[dict, list]:
    """The self-check's and the drift test's events (live.consistency, live.drift): a lock-out is never silent."""
    kinds = [(e[1], e[2]) for e in live.events]
    counts = {"lock-out": kinds.count(("tracker", "locked_out")),
              "re-acquisition": kinds.count(("tracker", "reacquired")),
              "adaptation of the noise": kinds.count(("tracker", "adapted")),
              "rollback": kinds.count(("bias", "rollback"))}
    shown = [(when, kind, reason) for when, what, kind, reason in live.events
             if what == "tracker" and kind != "adapted"][:5]
    return counts, shown


@dataclass
class _Source:
    """The table to replay (a ROS bag becomes a temporary Parquet table through the dataset step's reader,
    unsmoothed), its default wrench columns and its column names (for the joints)."""

    path: str
    default_signal: tuple[str, ...] | None
    columns: tuple[str, ...]
    orientation: tuple[str, ...] | None = None
    tmp: Any = field(default=None, repr=False)


def replays_a_bag(data: str | os.PathLike) -> bool:
    """Whether :func:`replay_live` reads ``data`` as a ROS bag (by its topics), else as a table (by its columns)."""
    from ..data.logs import is_bag

    return is_bag(data)


def _open_source(data, *, wrench_topic, joints_topic, imu_topic, tf, receive_time, base, gravity_given) -> _Source:
    import tempfile
    from pathlib import Path

    from ..data.tables import table_columns

    path = Path(data)
    if not replays_a_bag(path):
        return _Source(str(data), None, tuple(table_columns(str(data))))
    from ..data.bags import BagTopics
    from ..insitu.bags import build_bag_table, write_bag_table
    from ..insitu.recordings import InsituOptions

    topics = BagTopics(wrench=wrench_topic, joints=joints_topic, imu=imu_topic, tf=tf, receive_time=receive_time)
    table = build_bag_table([path], topics, options=InsituOptions(savgol_frame=None, temperature=False, base=base))
    _check_magnitudes(data, table, wrench_topic, imu_topic or joints_topic or "/tf")
    tmp = tempfile.TemporaryDirectory(prefix="ftcal-live-bag-")
    out = Path(tmp.name) / "bag.parquet"
    write_bag_table(table, out)
    quaternion = ("qx", "qy", "qz", "qw")
    orientation = quaternion if all(c in table.columns for c in quaternion) and not gravity_given else None
    return _Source(str(out), DEFAULT_WRENCH, tuple(table.columns), orientation, tmp)


def _check_magnitudes(data, table, wrench_topic: str, other_topic: str) -> None:
    """Refuse a bag value beyond :data:`~ftcal.core.limits.MAX_CELL_MAGNITUDE` naming the bag, its topic and time
    (the temporary table the bag becomes would name itself instead)."""
    import numpy as np

    from ..core.limits import MAX_CELL_MAGNITUDE

    wrench = {f"u{j + 1}": axis for j, axis in enumerate(("Fx", "Fy", "Fz", "Tx", "Ty", "Tz"))}
    for column, values in table.columns.items():
        values = np.asarray(values)
        if values.dtype.kind != "f":
            continue
        huge = np.abs(values) > MAX_CELL_MAGNITUDE
        if huge.any():
            k = int(np.flatnonzero(huge)[0])
            what = (f"the wrench on {wrench_topic} ({wrench[column]})" if column in wrench else
                    f"{column!r} (from {other_topic})")
            raise FtcalError(f"{data}: {what} holds {values[k]:g} at t={table.columns['time'][k]:.6f} s, beyond "
                             f"{MAX_CELL_MAGNITUDE:g} in magnitude: no sensor reads that.")


def replay_columns(setup_model, tools, robot, *, time="time", inputs=None, default_signal=None, orientation=None,
                   gravity_columns=None, imu_columns=None, temperature=None):
    """Which columns of the replayed table feed the calibrator (:class:`~ftcal.live.replay.ReplayColumns`)."""
    from ..live.replay import ReplayColumns

    if setup_model is not None:
        names = tuple(setup_model.input_names_)
        signal, raw = tuple(inputs or names), True
        if len(signal) != len(names):
            raise ParameterError("inputs", f"{{inputs}} {','.join(signal)}: the model reads {len(names)} raw "
                                           f"input(s) ({','.join(names)}); name one column for each, in that order.")
    else:
        first = next((p for p in tools.values() if p is not None), None)
        signal = tuple(inputs or default_signal or (first.fit.get("wrench_columns") if first else None)
                       or DEFAULT_WRENCH)
        if len(signal) != 6:
            raise ParameterError(("inputs", "model"), f"{{inputs}} needs 6 wrench columns without {{model}}; got "
                                                      f"{','.join(signal)}.")
        raw = False
    if robot is not None:
        return ReplayColumns(time, signal, raw, "joints", tuple(robot.joints), temperature)
    given = [(kind, name, cols, need) for kind, name, cols, need in (
        ("quaternion", "orientation", orientation, 4), ("gravity", "gravity_columns", gravity_columns, 3),
        ("imu", "imu_columns", imu_columns, 3)) if cols is not None]
    if not given:
        raise ParameterError(("orientation", "gravity_columns", "imu_columns", "urdf"),
                             "give the sensor's orientation: {orientation} qx,qy,qz,qw, {gravity_columns} gx,gy,gz, "
                             "{imu_columns} ax,ay,az, or {urdf} with the robot's joint columns.")
    kind, name, cols, need = given[0]
    if len(cols) != need:
        raise ParameterError(name, f"{{{name}}} needs {need} columns; got {','.join(cols)}.")
    return ReplayColumns(time, signal, raw, kind, tuple(cols), temperature)


def replay_live(data: str | os.PathLike, setup: LiveSetup, *, output: str | os.PathLike, time: str = "time",
                inputs: Sequence[str] | None = None, orientation: Sequence[str] | None = None,
                gravity_columns: Sequence[str] | None = None, imu_columns: Sequence[str] | None = None,
                temperature: str | None = None, retare_at: Sequence[float] = (),
                switch_tool: Sequence[tuple[float, str]] = (), realtime: bool = False, drop_incomplete: bool = False,
                wrench_topic: str = "/ft/raw", joints_topic: str | None = None, imu_topic: str | None = None,
                tf: tuple[str, str | None] | None = None, receive_time: bool = False) -> LiveReplayResult:
    """Run the live calibrator of ``setup`` over a recording and write each sample's results to ``output``.

    Parameters
    ----------
    data : CSV or Parquet table, or a ROS bag (with ``wrench_topic`` and ``joints_topic`` or ``tf``)
    setup : the calibrator's model, tools, noise, bias, state file and robot model
    output : the results table (.parquet or .csv), written atomically
    time, inputs, temperature : the table's time column, signal columns (the model's raw inputs, else six wrench
        columns) and temperature column
    orientation, gravity_columns, imu_columns : gravity from a quaternion (x, y, z, w), a gravity vector or an
        accelerometer in the sensor frame (else from the joints and ``setup.urdf``)
    retare_at, switch_tool : scripted re-tares (times, s) and tool switches ((time, tool) pairs)
    realtime : replay at the recording's speed
    drop_incomplete : skip rows with an empty or NaN cell in the columns used (counted)
    wrench_topic, joints_topic, imu_topic, tf, receive_time : how a bag is read (as the dataset step reads it)

    Returns
    -------
    LiveReplayResult

    Raises
    ------
    ParameterError
        A bag with ``setup.model`` or ``drop_incomplete``.
    FtcalError
        Unreadable inputs, wrong columns, a tool or gravity source that does not fit. The state file is
        saved on Ctrl-C or SIGTERM (what was processed), and left as it was on bad input.
    """
    from contextlib import nullcontext

    from ..data.tables import drop_incomplete as dropping
    from ..live.replay import ScriptedEvent, replay_table

    if replays_a_bag(data):
        if setup.model is not None:
            raise ParameterError("model", "{model} with a bag: the bag's wrench topic is the wrench; replay a table of "
                                          "raw channels with {model} instead.")
        if drop_incomplete:
            raise ParameterError("drop_incomplete", "{drop_incomplete} applies to tables; a bag's reader refuses its "
                                                    "NaN stretches, naming them.")
    events = [ScriptedEvent(t, "retare") for t in retare_at] + [ScriptedEvent(t, "switch", n) for t, n in switch_tool]
    gravity_given = any(v is not None for v in (orientation, gravity_columns, imu_columns, setup.urdf))
    source = _open_source(data, wrench_topic=wrench_topic, joints_topic=joints_topic, imu_topic=imu_topic, tf=tf,
                          receive_time=receive_time, base=setup.base, gravity_given=gravity_given)
    try:
        if source.orientation is not None:
            orientation = source.orientation
        if setup.urdf is not None and any(v is not None for v in (orientation, gravity_columns, imu_columns)):
            raise ParameterError(("urdf", "orientation", "gravity_columns", "imu_columns"),
                                 "give one gravity source: {urdf} (with the joints), {orientation}, "
                                 "{gravity_columns} or {imu_columns}.")
        robot = setup.robot_gravity(source.columns, str(data))
        live = setup.calibrator(robot)
        columns = replay_columns(live.model, live.tools, robot, time=time, inputs=inputs,
                                 default_signal=source.default_signal, orientation=orientation,
                                 gravity_columns=gravity_columns, imu_columns=imu_columns, temperature=temperature)
        try:
            # The state is saved before the output is renamed into place: a state that cannot be written leaves
            # no output.
            with dropping() if drop_incomplete else nullcontext() as dropped:
                summary = replay_table(source.path, live, columns, output, events=events, realtime=realtime,
                                       before_commit=live.save_state if setup.state else None)
        except FtcalError:
            raise  # bad input: no output, and the state file is left as it was
        except BaseException:  # Ctrl-C, SIGTERM: keep what was processed
            if setup.state and live.last_time is not None:
                live.save_state()
            raise
    finally:
        if source.tmp is not None:
            source.tmp.cleanup()
    summary.dropped = sum(dropped.values()) if dropped else 0
    counts, shown = _tracker(live)
    status = live.status()
    return LiveReplayResult(summary, summary.dropped, counts, shown, list(status["bias"]), list(status["bias_std"]),
                            status["tool"], str(output), None if setup.state is None else str(setup.state))


def serve_zenoh(setup: LiveSetup, **options) -> int:
    """Serve the live calibrator of ``setup`` over Zenoh until ``duration`` or Ctrl-C.

    Parameters
    ----------
    setup : the calibrator's model, tools, noise, bias, state file and robot model
    **options : the fields of :class:`~ftcal.live.zenoh_node.ZenohOptions` (``listen``, ``connect``, ``wrench_topic``,
        ``imu_topic``, ``joints_topic``, ``temperature_topic``, ``prefix``, ``silence``, ``duration``, ``keys``,
        ``domain_id``, ``rt_priority``, ``low_latency``); gravity from ``joints_topic`` with ``setup.urdf``

    Returns
    -------
    int
        The exit code (0).

    Raises
    ------
    ParameterError
        ``joints_topic`` without ``setup.urdf`` or the other way round, and the values
        :class:`~ftcal.live.zenoh_node.ZenohOptions` refuses; checked before anything is loaded or opened.
    """
    from ..live.zenoh_node import ZenohOptions, serve

    if (options.get("joints_topic") is None) != (setup.urdf is None):
        raise ParameterError(("joints_topic", "urdf"), "{joints_topic} and {urdf} go together: gravity from the joint "
                                                       "states and the robot model.")
    checked = ZenohOptions(**options)
    robot = setup.robot_gravity(None, f"urdf {setup.urdf}")
    return serve(setup.calibrator(), checked, robot=robot)


# ROS parameter -> the setup's field where the names differ.
_ROS2_FIELDS = {"tool": "mount"}
_ROS2_SETUP = ("walk_std", "noise_std", "bias", "g", "degrees", "model", "state", "sensor", "ft_joint", "ft_frame",
               "base", "tool", "urdf")


def serve_ros2(setup: LiveSetup, node: Mapping[str, Any], ros_args: Sequence[str] = ()) -> int:
    """Run the live calibrator as a ROS 2 node (ftcal.live.ros2_node).

    ``setup`` and ``node`` (the node's other parameters: topics, prefix, silence, duration, ...) are the
    parameters' defaults; a params file or ``-p`` in ``ros_args`` may override them, so the calibrator is
    built from the parameters' values."""
    from ..live.ros2_node import PARAMETERS, serve

    settings = {name: None for name in PARAMETERS}
    settings.update({name: getattr(setup, _ROS2_FIELDS.get(name, name)) for name in _ROS2_SETUP})
    settings.update(node)
    items = setup.tool_items()
    settings["tools"] = [f"{name}={path}" for name, path in items]
    settings["identify_tool_name"] = "identified_tool"
    settings["tool"] = setup.mount if setup.mount is not None else next((name for name, _ in items), "none")

    def build(values: dict):
        changes = {}
        for name, value in values.items():
            if name == "tools":
                changes["tools"] = [_tool_spec(text) for text in value or ()]
            elif name in _ROS2_SETUP:
                changes[_ROS2_FIELDS.get(name, name)] = value
        built = dataclasses.replace(setup, **changes)
        return built.calibrator(), built.robot_gravity(None, f"urdf {built.urdf}")  # the robot: the node's gravity source

    return serve(settings, build, tuple(ros_args))


def _tool_spec(text: str) -> tuple[str, str]:
    """``NAME=PAYLOAD.json`` of the ROS parameter ``tools``."""
    name, sep, path = str(text).partition("=")
    if not sep or not name or not path:
        raise FtcalError(f"parameter tools: expected NAME=PAYLOAD.json, got {text!r}")
    return name, path
