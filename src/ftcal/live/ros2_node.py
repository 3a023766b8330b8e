"""The live calibrator as a ROS 2 node (rclpy): ``ftcal live --ros2``.

rclpy is imported only here, when the node starts: without a sourced ROS 2 (Humble or later) or the ROS 2 wheels
(``pip install ros-jazzy-rclpy ...``), :func:`import_rclpy` says so in one line.

* subscribes, with the sensor-data QoS (best effort: a reliable or a best-effort publisher matches; keep last
  :data:`INPUT_DEPTH`):
  ``ft/raw`` (``geometry_msgs/msg/WrenchStamped``), optionally ``sensor_msgs/msg/Imu`` (gravity from its
  orientation, else minus its acceleration), ``sensor_msgs/msg/JointState`` (with a robot model) and
  ``sensor_msgs/msg/Temperature``;
* publishes (reliable, as ros2_controllers' force_torque_sensor_broadcaster: any subscriber matches; keep last
  :data:`OUTPUT_DEPTH`)
  ``ft/calibrated`` and ``ft/compensated`` (``WrenchStamped``, the input's header) for every wrench; ``ft/bias`` and
  ``ft/bias_std`` (``WrenchStamped``: the tracked bias and its standard deviation, stamped with the last wrench's
  stamp) and ``/diagnostics`` (``diagnostic_msgs/msg/DiagnosticArray``) every second and at once when a flag changes,
  as ``diagnostic_updater`` paces them (:meth:`ftcal.live.node_core.NodeCore.run_loop`);
* services (``std_srvs/srv/Trigger``): ``ft/retare``, ``ft/identify/start`` (the tool is named by the
  ``identify_tool_name`` parameter) and ``ft/identify/finish``;
* parameters: every option of the node (:data:`PARAMETERS`), settable from a YAML file (``--ros-args --params-file
  FILE``) or ``-p NAME:=VALUE``; ``tool`` (the mounted tool) and ``identify_tool_name`` can be set while it runs
  (``ros2 param set /ftcal_live tool drill``: the parameter callback switches the tool, and refuses an unknown one).

Topics and services are relative names, so the node's namespace (``-r __ns:=/robot1``) prefixes them; the node name
(``-r __node:=NAME``) and remappings (``-r ft/raw:=/wrist/wrench``) work as in any ROS 2 node. rclpy's own signal
handlers are off: Ctrl-C and SIGTERM unwind through ftcal's command line, which saves the state.
"""

from __future__ import annotations

import math
import threading

from ..runtime.errors import FtcalError, ParameterError
from .health import names_of
from .node_core import NodeCore

NODE_NAME = "ftcal_live"
# The inputs' history: the sensor-data profile's best effort and volatility, but 100 samples deep, not 5: a callback
# that runs late (the executor's one thread, a slow step) loses none of a burst (with 5, 1 of 200 wrenches at 200 Hz
# was lost on this 2-core machine under load).
INPUT_DEPTH = 100
# The wrench outputs' history (reliable, keep last): a reliable writer drops what a late reader has not acknowledged
# once its history is full; 100 samples (50 ms at 2 kHz) give a reader under load that much slack.
OUTPUT_DEPTH = 100
# Parameter name -> (kind, description). The command line's option of the same name (dashes for underscores) gives
# the default; a params file or -p overrides it. "tools" is --tool NAME=PAYLOAD.json, "tool" is --mount.
PARAMETERS = {
    "wrench_topic": ("string", "raw geometry_msgs/msg/WrenchStamped"),
    "imu_topic": ("string", "sensor_msgs/msg/Imu, gravity from its orientation ('' : none)"),
    "joints_topic": ("string", "sensor_msgs/msg/JointState with urdf ('' : none)"),
    "temperature_topic": ("string", "sensor_msgs/msg/Temperature ('' : none)"),
    "prefix": ("string", "outputs PREFIX/calibrated, /compensated, /bias, /bias_std; services PREFIX/retare, "
                         "PREFIX/identify/start, PREFIX/identify/finish"),
    "tools": ("string_array", "the tool library, NAME=PAYLOAD.json each"),
    "tool": ("string", "the mounted tool (settable at run time: switches the tool)"),
    "identify_tool_name": ("string", "the name the next PREFIX/identify/start gives the tool it identifies"),
    "model": ("string", "calibration model file ('' : the wrench as given)"),
    "state": ("string", "state file, resumed from and saved on the way out ('' : none)"),
    "walk_std": ("double_array", "bias random-walk std per sqrt(h): force, torque or six values ([] : default)"),
    "noise_std": ("double_array", "per-sample noise std: force, torque or six values ([] : default)"),
    "bias": ("double_array", "initial bias, six values ([] : unknown)"),
    "g": ("double", "gravity magnitude, m/s^2"),
    "silence": ("double", "flag the input silent after this many seconds without a wrench"),
    "duration": ("double", "stop after this many seconds (0: run until stopped)"),
    "urdf": ("string", "robot model for gravity from the joint states ('' : none)"),
    "sensor": ("string", "the URDF's F/T sensor"), "ft_joint": ("string", "the URDF's F/T joint"),
    "ft_frame": ("string", "the URDF's F/T frame"), "base": ("string", "the URDF's gravity-aligned base link"),
    "degrees": ("bool", "joint positions in degrees"),
    "hardware_id": ("string", "the diagnostics' hardware_id (default: the wrench's frame id)"),
}
# The parameters that may change while the node runs; the others are read once, at start.
RUNTIME_PARAMETERS = ("tool", "identify_tool_name")
# diagnostic_msgs/msg/DiagnosticStatus levels (diagnostic_updater's OK, WARN, ERROR) by flag: a sensor that gives no
# usable data is an error, a reading to distrust a warning; a contact is what the sensor is for (OK, named).
ERROR_FLAGS = ("saturated", "dead", "silent")
WARN_FLAGS = ("stuck", "out_of_range", "temperature", "unexplained")
INSTALL_HINT = ("--ros2 needs rclpy and the ROS 2 message packages: source your ROS 2 setup (e.g. source "
                "/opt/ros/jazzy/setup.bash), or pip install ros-jazzy-rclpy ros-jazzy-rmw-fastrtps-cpp "
                "ros-jazzy-geometry-msgs ros-jazzy-sensor-msgs ros-jazzy-std-srvs ros-jazzy-diagnostic-msgs into "
                "this Python's environment (a venv of its own: their .pth re-executes Python)")


def import_rclpy():
    """rclpy, or :class:`FtcalError` saying what to source or install."""
    try:
        import rclpy  # noqa: F401
        from diagnostic_msgs.msg import DiagnosticArray  # noqa: F401
        from geometry_msgs.msg import WrenchStamped  # noqa: F401
        from sensor_msgs.msg import Imu, JointState, Temperature  # noqa: F401
        from std_srvs.srv import Trigger  # noqa: F401
    except ImportError as exc:
        raise FtcalError(f"{INSTALL_HINT}; missing: {exc.name or exc}.") from None
    import rclpy

    return rclpy


def level_of(flags) -> int:
    """The DiagnosticStatus level of a set of flag names: 2 (ERROR), 1 (WARN) or 0 (OK)."""
    if any(f in ERROR_FLAGS for f in flags):
        return 2
    return 1 if any(f in WARN_FLAGS for f in flags) else 0


def _ros_value(kind: str, value):
    if kind == "string":
        return "" if value is None else str(value)
    if kind == "double":
        return 0.0 if value is None else float(value)
    if kind == "bool":
        return bool(value)
    if kind == "double_array":
        return [] if value is None else [float(v) for v in value]
    return [] if value is None else [str(v) for v in value]


def _option_value(kind: str, value):
    """A parameter's value as the command line's option holds it ('' and [] are "not given")."""
    if kind in ("string", "string_array", "double_array") and len(value) == 0:
        return None
    return list(value) if kind.endswith("array") else value


class Ros2Node:
    """The calibrator behind rclpy subscriptions, publishers, services and parameters (see the module docstring).

    Parameters
    ----------
    settings : dict, the command line's values by parameter name (:data:`PARAMETERS`)
    build : callable(settings) -> (LiveCalibrator, SensorGravity or None), the calibrator those settings describe
    ros_args : list of str, what followed ``--ros-args``
    """

    def __init__(self, settings: dict, build, ros_args=(), echo=print) -> None:
        rclpy = import_rclpy()
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.signals import SignalHandlerOptions

        self.rclpy, self.echo = rclpy, echo
        self.context = rclpy.Context()
        try:
            rclpy.init(args=["ftcal", "--ros-args", *ros_args] if ros_args else ["ftcal"], context=self.context,
                       signal_handler_options=SignalHandlerOptions.NO)
        except Exception as exc:  # rcl's error on a bad --ros-args (an unknown rule, a missing params file)
            raise ParameterError("ros_args", f"{{ros_args}}: {str(exc).splitlines()[0]}") from None
        try:
            self.node = rclpy.create_node(NODE_NAME, context=self.context)
            self.settings = self._declare(settings)
            live, robot = build(self.settings)
            self.core = NodeCore(live, robot=robot, echo=echo, source=self.node.resolve_topic_name(
                self.settings["wrench_topic"]), what="--ros2")
            self.last_header = None
            self._create_interfaces()
        except BaseException:
            self._shutdown()
            raise
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)

    # ----- parameters --------------------------------------------------------------------------------------
    def _declare(self, settings: dict) -> dict:
        from rcl_interfaces.msg import ParameterDescriptor
        from rclpy.parameter import Parameter

        values = {}
        for name, (kind, description) in PARAMETERS.items():
            descriptor = ParameterDescriptor(description=description, read_only=name not in RUNTIME_PARAMETERS)
            default = _ros_value(kind, settings.get(name))
            if isinstance(default, list) and not default:  # an empty list has no type of its own (rclpy: bytes)
                default = Parameter.Type.DOUBLE_ARRAY if kind == "double_array" else Parameter.Type.STRING_ARRAY
            try:
                value = self.node.declare_parameter(name, default, descriptor).value
            except Exception as exc:  # rclpy's InvalidParameterTypeException and kin: a params file's wrong type
                raise FtcalError(f"parameter {name}: {str(exc).splitlines()[0]}") from None
            values[name] = _option_value(kind, [] if value is None else value)
        for name in ("silence", "g"):
            if not (math.isfinite(values[name]) and values[name] > 0):
                raise FtcalError(f"parameter {name}: must be a positive number; got {values[name]!r}.")
        duration = values["duration"]
        if not (math.isfinite(duration) and duration >= 0):
            raise FtcalError(f"parameter duration: must be >= 0 (0: until stopped); got {duration!r}.")
        values["duration"] = duration or None
        if values["wrench_topic"] is None or values["prefix"] is None:
            raise FtcalError("parameters wrench_topic and prefix must not be empty.")
        self.node.add_on_set_parameters_callback(self._on_parameters)
        return values

    def _on_parameters(self, parameters):
        from rcl_interfaces.msg import SetParametersResult

        for parameter in parameters:
            if parameter.name == "tool" and str(parameter.value) != self.core.live.tool:  # not a switch to itself
                done = self.core.command("switch_tool", str(parameter.value))
                if not done["ok"]:
                    return SetParametersResult(successful=False, reason=done["error"])
            elif parameter.name == "identify_tool_name" and not str(parameter.value).strip():
                return SetParametersResult(successful=False, reason="identify_tool_name must not be empty")
        return SetParametersResult(successful=True)

    # ----- topics and services ------------------------------------------------------------------------------
    def _create_interfaces(self) -> None:
        from diagnostic_msgs.msg import DiagnosticArray
        from geometry_msgs.msg import WrenchStamped
        from rclpy.qos import QoSProfile, qos_profile_sensor_data
        from sensor_msgs.msg import Imu, JointState, Temperature
        from std_srvs.srv import Trigger

        node, s, prefix = self.node, self.settings, self.settings["prefix"].rstrip("/")
        sensor_data = QoSProfile(**{**_qos_fields(qos_profile_sensor_data), "depth": INPUT_DEPTH})
        self.publishers = {name: node.create_publisher(WrenchStamped, f"{prefix}/{name}", OUTPUT_DEPTH)
                           for name in ("calibrated", "compensated", "bias", "bias_std")}
        self.publishers["diagnostics"] = node.create_publisher(DiagnosticArray, "/diagnostics", 10)
        if (self.core.robot is None) != (s["joints_topic"] is None):
            raise FtcalError("parameters joints_topic and urdf go together: gravity from the joint states and the "
                             "robot model.")
        if s["joints_topic"] and s["imu_topic"]:
            raise FtcalError("give one gravity source: imu_topic, or joints_topic with urdf.")
        node.create_subscription(WrenchStamped, s["wrench_topic"], self._on_wrench, sensor_data)
        if s["imu_topic"]:
            node.create_subscription(Imu, s["imu_topic"], self._on_imu, sensor_data)
        if s["joints_topic"]:
            node.create_subscription(JointState, s["joints_topic"], self._on_joints, sensor_data)
        if s["temperature_topic"]:
            node.create_subscription(Temperature, s["temperature_topic"],
                                     lambda m: self.core.take_temperature(m.temperature), sensor_data)
        node.create_service(Trigger, f"{prefix}/retare", lambda req, res: self._trigger(res, "retare", ""))
        node.create_service(Trigger, f"{prefix}/identify/start", lambda req, res: self._trigger(
            res, "identify_tool", "start " + str(node.get_parameter("identify_tool_name").value)))
        node.create_service(Trigger, f"{prefix}/identify/finish",
                            lambda req, res: self._trigger(res, "identify_tool", "finish"))

    def _trigger(self, response, name: str, text: str):
        """A Trigger service: success and one line (the warning, the identified mass, or the error)."""
        import json

        done = self.core.command(name, text)
        response.success = bool(done["ok"])
        if not done["ok"]:
            response.message = done["error"]
        elif "warning" in done:
            response.message = done["warning"]
        elif "mass" in done:
            response.message = json.dumps({k: done[k] for k in ("mass", "mass_stderr", "com")})
            self._mounted(done["status"]["tool"])
        else:
            response.message = f"{name}: done (tool {done['status']['tool']!r})"
        return response

    def _mounted(self, tool: str) -> None:
        """The tool identified in place is mounted: the ``tool`` parameter says so (its callback finds it mounted)."""
        from rclpy.parameter import Parameter

        self.node.set_parameters([Parameter("tool", Parameter.Type.STRING, tool)])

    def _on_wrench(self, msg) -> None:
        f, t = msg.wrench.force, msg.wrench.torque
        stamp_ns = msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec
        done = self.core.process_wrench(stamp_ns, (f.x, f.y, f.z, t.x, t.y, t.z))
        if done is None:
            return
        result = done[0]
        self.last_header = msg.header
        if not self.core.closing:
            self.publishers["calibrated"].publish(self._wrench(msg.header, result.calibrated))
            self.publishers["compensated"].publish(self._wrench(msg.header, result.compensated))
        self.core.announce(stamp_ns * 1e-9, *done)

    def _on_imu(self, msg) -> None:
        o, a = msg.orientation, msg.linear_acceleration
        self.core.take_imu((o.x, o.y, o.z, o.w), float(msg.orientation_covariance[0]), (a.x, a.y, a.z))

    def _on_joints(self, msg) -> None:
        stamp = msg.header.stamp.sec + 1e-9 * msg.header.stamp.nanosec
        self.core.take_joints(list(msg.name), list(msg.position), stamp, self.node.resolve_topic_name(
            self.settings["joints_topic"]))

    @staticmethod
    def _wrench(header, values):
        from geometry_msgs.msg import WrenchStamped

        out = WrenchStamped(header=header)
        v = [float(x) for x in values]
        out.wrench.force.x, out.wrench.force.y, out.wrench.force.z = v[0], v[1], v[2]
        out.wrench.torque.x, out.wrench.torque.y, out.wrench.torque.z = v[3], v[4], v[5]
        return out

    # ----- diagnostics --------------------------------------------------------------------------------------
    def _diagnostics(self) -> int:
        """Publish /diagnostics and the bias; returns the flag bits reported."""
        from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
        from std_msgs.msg import Header

        with self.core.lock:
            flags = self.core.live.flags_now
            doc = self.core.diagnostics_status()
        names = names_of(flags)
        status = DiagnosticStatus(level=bytes([level_of(names)]), name=f"{self.node.get_name()}: force/torque "
                                  "calibration")
        status.message = "; ".join(f"{k}: {doc['reasons'][k]}" for k in names) if names else "OK"
        header = self.last_header
        status.hardware_id = self.settings["hardware_id"] or (header.frame_id if header is not None else "")
        pairs = [("tool", doc["tool"]), ("flags", ",".join(names)), ("raised", ",".join(doc["raised"]))]
        pairs += [(f"bias_{axis}", f"{b:.6g}") for axis, b in zip(AXES, doc["bias"])]
        pairs += [(f"bias_std_{axis}", f"{b:.3g}") for axis, b in zip(AXES, doc["bias_std"])]
        pairs += [(name, str(value)) for name, value in doc["counters"].items()]
        pairs += [(name, str(doc[name])) for name in ("bad_messages", "stale_samples", "stamp_jumps",
                                                       "waiting_for_joints", "stale_joints")]
        pairs += [("identifying", doc["identifying"] or ""), ("holds_collected", str(doc["holds_collected"]))]
        status.values = [KeyValue(key=k, value=str(v)) for k, v in pairs]
        array = DiagnosticArray(header=Header(stamp=self.node.get_clock().now().to_msg()), status=[status])
        if self.core.closing:
            return flags
        self.publishers["diagnostics"].publish(array)
        if header is not None:
            self.publishers["bias"].publish(self._wrench(header, doc["bias"]))
            self.publishers["bias_std"].publish(self._wrench(header, doc["bias_std"]))
        return flags

    # ----- running ----------------------------------------------------------------------------------------
    def serve(self) -> int:
        """Spin the node's callbacks on a thread of their own while this thread watches for silence and publishes
        the diagnostics, until ``duration`` (or Ctrl-C / SIGTERM); the state is saved on the way out."""
        spinner = threading.Thread(target=self._spin, name="ftcal-ros2-executor", daemon=True)
        spinner.start()
        s = self.settings
        inputs = [self.node.resolve_topic_name(s[k]) for k in ("wrench_topic", "imu_topic", "joints_topic",
                                                               "temperature_topic") if s[k]]
        self.echo(f"ftcal live: ROS 2 node {self.node.get_fully_qualified_name()} listening on {', '.join(inputs)}; "
                  f"publishing {self.node.resolve_topic_name(s['prefix'].rstrip('/') + '/compensated')} and "
                  "/diagnostics", flush=True)
        try:
            self.core.run_loop(s["duration"], s["silence"], self._diagnostics)
        finally:
            self.core.closing = True
            self._shutdown()
            spinner.join(timeout=5.0)
            self.core.save_on_exit()
        return 0

    def _spin(self) -> None:
        try:
            self.executor.spin()
        except Exception:  # the context shut down under it on the way out
            if not self.core.closing:
                raise

    def _shutdown(self) -> None:
        executor = getattr(self, "executor", None)
        if executor is not None:
            executor.shutdown(timeout_sec=2.0)
        node = getattr(self, "node", None)
        if node is not None:
            node.destroy_node()
        if self.context.ok():
            self.rclpy.shutdown(context=self.context)


AXES = ("Fx", "Fy", "Fz", "Tx", "Ty", "Tz")


def _qos_fields(profile) -> dict:
    return {"history": profile.history, "reliability": profile.reliability, "durability": profile.durability}


def serve(settings: dict, build, ros_args=()) -> int:
    """Run ``ftcal live --ros2``: a :class:`Ros2Node` from the command line's ``settings`` until it is stopped."""
    return Ros2Node(settings, build, ros_args).serve()


