"""Payload files for ROS users: force_torque_tools ``ft_calib`` YAML and ft_tools_ros2 ``calibration.yaml``.

force_torque_tools (kth-ros-pkg, ROS 1): ``force_torque_sensor_calib`` dumps
and ``gravity_compensation`` loads

* ``bias``: 6 values fx, fy, fz, tx, ty, tz, subtracted from the raw reading;
* ``gripper_mass``: kg (the node rejects a mass <= 0);
* ``gripper_com_frame_id``: the frame the COM pose is expressed in (the F/T
  sensor frame) and ``gripper_com_child_frame_id``: the name of the COM frame;
* ``gripper_com_pose``: x, y, z, roll, pitch, yaw of the COM (m, rad).

``gravity_compensation`` computes ``(raw − bias) − mass·g`` and the torque
``com × mass·g``, ``g`` being the vector its gravity topic gives in the sensor
frame. For a sensor in ftcal's convention (no ``--reaction``) feed it the
gravity vector (pointing down); an accelerometer's reading (pointing up)
matches sensors that needed ``--reaction``. The bias is written in the sign of
the sensor's own readings.

ft_tools_ros2 (tpoignonec, ROS 2) reads ``mass``, ``sensor_frame_to_com``,
``force_offset`` and ``torque_offset`` and computes ``raw − m·g_s − com × m·g_s
− offsets`` with gravity pointing down: ftcal's convention exactly.

Numbers are written with full precision and always with a decimal point, so
that YAML 1.1 readers (PyYAML, rosparam) parse ``1e-05`` as a float too.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..payload.parameters import PayloadParameters
from ..runtime.atomic import write_text_atomic
from ..runtime.errors import FtcalError, ParameterError

DEFAULT_COM_FRAME = "gripper_com"


def _float(value: float) -> str:
    value = float(value)
    if not np.isfinite(value):
        raise FtcalError(f"cannot write the non-finite value {value} to a ROS YAML file.")
    text = repr(value)
    mantissa, e, exponent = text.partition("e")
    if "." not in mantissa:
        mantissa += ".0"
    return mantissa + (e + ("+" + exponent if exponent[:1] not in "+-" else exponent) if e else "")


def _list(values) -> str:
    return "[" + ", ".join(_float(v) for v in np.ravel(values)) + "]"


def _string(text: str) -> str:
    """A YAML double-quoted scalar of ``text``: printable ASCII as itself, every other character escaped.

    Frame names come from payload files: a raw newline, NEL or U+2028 (line
    breaks to YAML 1.1), a quote or a control character must not end the
    scalar or start a new key.
    """
    out = []
    for ch in str(text):
        code = ord(ch)
        if " " <= ch <= "~" and ch not in '"\\':
            out.append(ch)
        elif ch in '"\\':
            out.append("\\" + ch)
        elif 0xD800 <= code <= 0xDFFF:
            raise FtcalError(f"the frame name {text!r} holds a lone surrogate (U+{code:04X}), which YAML cannot carry.")
        else:
            out.append(f"\\x{code:02X}" if code < 0x100 else f"\\u{code:04X}" if code < 0x10000 else f"\\U{code:08X}")
    return '"' + "".join(out) + '"'


def ros_yaml_text(payload: PayloadParameters, *, frame: str | None = None,
                  com_frame: str = DEFAULT_COM_FRAME) -> str:
    """The force_torque_tools ``ft_calib`` YAML for ``payload``.

    Parameters
    ----------
    payload : PayloadParameters
    frame : str or None
        ``gripper_com_frame_id``, the F/T sensor frame; default the payload's ``frame``.
    com_frame : str
        ``gripper_com_child_frame_id``, the name given to the COM frame.

    Returns
    -------
    str

    Raises
    ------
    FtcalError
        Without a sensor frame name, or for a non-positive mass.
    """
    frame = frame or payload.frame
    if not frame:
        raise ParameterError('frame', "the ft_calib YAML needs the sensor frame name (gripper_com_frame_id): "
                         "identify with {frame} NAME or give the frame when converting.")
    if payload.mass <= 0:
        raise FtcalError(f"gripper_mass must be > 0 for gravity_compensation; the payload has {payload.mass} kg.")
    sign = -1.0 if payload.reaction else 1.0
    # rosparam dump order: keys sorted.
    return (f"bias: {_list(sign * payload.bias)}\n"
            f"gripper_com_child_frame_id: {_string(com_frame)}\n"
            f"gripper_com_frame_id: {_string(frame)}\n"
            f"gripper_com_pose: {_list(np.r_[payload.com, 0.0, 0.0, 0.0])}\n"
            f"gripper_mass: {_float(payload.mass)}\n")


def ft_tools_ros2_text(payload: PayloadParameters) -> str:
    """The ft_tools_ros2 ``calibration.yaml`` for ``payload``.

    Raises
    ------
    FtcalError
        For payloads identified with ``--reaction``: ft_tools_ros2 assumes
        readings in ftcal's sign convention and a positive mass.
    """
    if payload.reaction:
        raise ParameterError('reaction', "ft_tools_ros2 expects the sensor to read +m·g (ftcal's convention); this payload "
                         "was identified with {reaction}, which that package cannot represent.")
    return (f"mass: {_float(payload.mass)}\n"
            f"sensor_frame_to_com: {_list(payload.com)}\n"
            f"force_offset: {_list(payload.force_bias)}\n"
            f"torque_offset: {_list(payload.torque_bias)}\n")


def write_ros_yaml(payload: PayloadParameters, path: str | Path, *, frame: str | None = None,
                   com_frame: str = DEFAULT_COM_FRAME) -> Path:
    """Write :func:`ros_yaml_text` to ``path`` atomically; returns the path."""
    write_text_atomic(path, ros_yaml_text(payload, frame=frame, com_frame=com_frame))
    return Path(path)


def write_ft_tools_ros2(payload: PayloadParameters, path: str | Path) -> Path:
    """Write :func:`ft_tools_ros2_text` to ``path`` atomically; returns the path."""
    write_text_atomic(path, ft_tools_ros2_text(payload))
    return Path(path)
