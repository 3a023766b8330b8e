"""Payload files for the robot's controllers: ros2_controllers' ``admittance_controller``, control_toolbox's
``GravityCompensation`` filter, and a Universal Robots arm's own payload setting (URScript ``set_payload``, the UR
ROS 2 driver's ``set_payload`` service).

Each file carries the tool's mass and centre of gravity as the upstream parameter definitions name them:

* ``admittance-controller``: ros2_controllers ``admittance_controller/src/admittance_controller_parameters.yaml``
  (ros-controls/ros2_controllers at 94e74de35f9d04f313aca8f29df66c3a76004aa7): ``gravity_compensation.frame.id``
  (the frame the CoG is given in, normally the F/T sensor's), ``gravity_compensation.CoG.pos`` (3 values) and
  ``gravity_compensation.CoG.force`` ("the weight of the end effector, e.g mass * 9.81"). Its
  ``admittance_rule_impl.hpp`` subtracts ``(0, 0, -force)`` in the base frame and ``(R pos) × (0, 0, -force)``: a
  sensor that reads +m·g, ftcal's convention.
* ``gravity-compensation-filter``: control_toolbox
  ``control_toolbox/src/control_filters/gravity_compensation_filter_parameters.yaml`` (ros-controls/control_toolbox at
  e274281b41eb1c3f4817b2226c4ddbc6863b5d66): ``world_frame``, ``sensor_frame``, ``tool.CoG`` (3, sensor frame),
  ``tool.mass`` (kg), ``tool.gravity_field`` (world frame, m/s², default [0, 0, -9.81]); its
  ``gravity_compensation.cpp`` subtracts mass·gravity_field rotated into the sensor frame and CoG × that force: again
  +m·g.
* ``ur-payload``: ros-industrial/ur_msgs ``srv/SetPayload.srv`` (at 7f73065036ea8acbf3a0551f480cc57493341f22):
  ``float32 mass``, ``geometry_msgs/Vector3 center_of_gravity``; URScript ``set_payload(m, cog)``. The robot wants the
  CoG in its tool flange frame: the file is right when the sensor frame is the flange's (a UR e-series' own sensor,
  or a sensor mounted without offset or rotation); otherwise move the CoG first.

Neither controller has a bias parameter: the sensor's bias drifts (tare it, or run ``ftcal live``, which tracks it).
Payloads identified with ``--reaction`` (the sensor reads −m·g) are refused: these files cannot say so.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..payload.parameters import PayloadParameters
from ..runtime.atomic import write_text_atomic
from ..runtime.errors import FtcalError, ParameterError
from .ros_yaml import _float, _list, _string
from .targets import ConvertOptions, Written

ADMITTANCE_SOURCE = ("ros-controls/ros2_controllers admittance_controller/src/admittance_controller_parameters.yaml "
                     "at 94e74de3")
FILTER_SOURCE = ("ros-controls/control_toolbox control_toolbox/src/control_filters/"
                 "gravity_compensation_filter_parameters.yaml at e274281b")
UR_SOURCE = "ros-industrial/ur_msgs srv/SetPayload.srv at 7f73065, URScript set_payload"
DEFAULT_WORLD_FRAME = "world"


def _checked(payload: PayloadParameters, target: str, frame: str | None = None, need_frame: bool = True) -> str:
    if payload.reaction:
        raise ParameterError(('to', 'reaction'), f"{{to}} {target} expects a sensor that reads +m·g (ftcal's convention); this payload was "
                         "identified with {reaction}, which its parameters cannot represent.")
    if not np.isfinite(payload.mass) or payload.mass <= 0:
        raise ParameterError('to', f"{{to}} {target}: the tool's mass must be > 0; the payload has {payload.mass} kg.")
    frame = frame or payload.frame
    if need_frame and not frame:
        raise ParameterError(('to', 'frame'), f"{{to}} {target} needs the sensor frame's name: identify with {{frame}} NAME or give {{frame}}.")
    return frame or ""


def admittance_text(payload: PayloadParameters, frame: str | None = None) -> str:
    """The ``gravity_compensation`` parameters of ros2_controllers' admittance_controller."""
    frame = _checked(payload, "admittance-controller", frame)
    return (f"# ftcal payload: the tool's weight and centre of gravity for admittance_controller\n"
            f"# (parameters of {ADMITTANCE_SOURCE}); rename the controller to yours\n"
            "admittance_controller:\n"
            "  ros__parameters:\n"
            "    gravity_compensation:\n"
            "      frame:\n"
            f"        id: {_string(frame)}\n"
            "      CoG:\n"
            f"        pos: {_list(payload.com)}\n"
            f"        force: {_float(payload.mass * payload.gravity)}\n")


def gravity_filter_text(payload: PayloadParameters, frame: str | None = None,
                        world_frame: str = DEFAULT_WORLD_FRAME) -> str:
    """The parameters of control_toolbox's GravityCompensation filter."""
    frame = _checked(payload, "gravity-compensation-filter", frame)
    return (f"# ftcal payload: the tool for control_toolbox's GravityCompensation filter\n"
            f"# (parameters of {FILTER_SOURCE}); in a filter chain they go under the filter's params\n"
            "/**:\n"
            "  ros__parameters:\n"
            f"    world_frame: {_string(world_frame)}\n"
            f"    sensor_frame: {_string(frame)}\n"
            "    tool:\n"
            f"      CoG: {_list(payload.com)}\n"
            f"      mass: {_float(payload.mass)}\n"
            f"      gravity_field: {_list([0.0, 0.0, -payload.gravity])}\n")


def ur_payload_text(payload: PayloadParameters) -> str:
    """URScript ``set_payload`` and the UR ROS 2 driver's ``set_payload`` service call (comment), for the tool."""
    _checked(payload, "ur-payload", need_frame=False)
    m, (x, y, z) = _float(payload.mass), (_float(v) for v in payload.com)
    return (f"# ftcal payload: mass (kg) and centre of gravity (m, tool flange frame: right when the sensor frame\n"
            f"# is the flange's) for the robot's payload setting ({UR_SOURCE})\n"
            f"# ros2 service call /io_and_status_controller/set_payload ur_msgs/srv/SetPayload "
            f"\"{{mass: {m}, center_of_gravity: {{x: {x}, y: {y}, z: {z}}}}}\"\n"
            f"set_payload({m}, [{x}, {y}, {z}])\n")


def _notes(source: PayloadParameters) -> tuple[str, ...]:
    from .payload_formats import _notes as undetermined

    return (*undetermined(source), "no bias parameter there: tare the sensor, or track it with ftcal live")


def write_admittance(source: PayloadParameters, output: Path, options: ConvertOptions) -> Written:
    write_text_atomic(output, admittance_text(source, options.get("frame")))
    return Written((Path(output),), _notes(source))


def write_gravity_filter(source: PayloadParameters, output: Path, options: ConvertOptions) -> Written:
    write_text_atomic(output, gravity_filter_text(source, options.get("frame"),
                                                  options.get("world_frame", DEFAULT_WORLD_FRAME)))
    return Written((Path(output),), _notes(source))


def write_ur_payload(source: PayloadParameters, output: Path, options: ConvertOptions) -> Written:
    write_text_atomic(output, ur_payload_text(source))
    return Written((Path(output),), (*_notes(source), "the centre of gravity is in the sensor frame: the robot "
                                     "wants the tool flange's"))
