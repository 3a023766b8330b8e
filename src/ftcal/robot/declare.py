"""F/T sensors on any URDF: declared by joint, or from Gazebo tags.

iDynTree's URDF parser reads only its own top-level sensor element::

    <sensor name="r_arm_ft" type="force_torque">
      <parent joint="r_arm_ft_sensor"/>
      <origin xyz="..." rpy="..."/>
      <force_torque><frame>sensor</frame><measure_direction>child_to_parent</measure_direction></force_torque>
    </sensor>

It ignores Gazebo's ``<gazebo reference="JOINT"><sensor type="force_torque">``
tags, and it turns a massless leaf link hanging from a fixed joint (UR's
``ee_link`` or ``tool0``, Panda's ``panda_hand_tcp``) into a plain frame, so
that joint vanishes from the model together with any sensor on it.

:func:`prepare_urdf` closes those gaps by rewriting the URDF text before
iDynTree reads it: every Gazebo force/torque tag (unless the joint already has
an iDynTree sensor) and every :class:`SensorDeclaration` (``--ft-joint``,
``--ft-frame``) becomes an iDynTree sensor element, and the child link of each
sensor joint is kept as a link (given :data:`KEEP_LINK_MASS` when massless).

Convention: Gazebo's and iDynTree's. ``measure_direction`` ``child_to_parent``
(the default, and the only one for declared sensors) means the sensor reports
the wrench the child link applies on the parent link; ``frame`` ``child`` is
the child link frame, ``parent`` the parent link frame, ``sensor`` the child
link frame moved by the tag's ``<pose>`` (Gazebo) or ``<origin>`` (iDynTree).
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from collections import deque
from dataclasses import dataclass

import numpy as np

from ..runtime.errors import FtcalError, ParameterError

# A massless child link would become a frame (and its joint disappear); this mass keeps it a
# link. Its weight, 1e-11 N, is far below any F/T sensor's resolution.
KEEP_LINK_MASS = 1e-12
FRAMES = ("child", "parent", "sensor")
DIRECTIONS = ("child_to_parent", "parent_to_child")


@dataclass(frozen=True)
class SensorDeclaration:
    """A six-axis F/T sensor on a fixed joint of a plain URDF.

    Attributes
    ----------
    joint : name of the fixed URDF joint the sensor sits on
    frame : link whose axes and origin are the sensor frame; None means the
        joint's child link (the URDF joint frame). It must be rigidly attached
        to the child link (only fixed joints in between).
    name : sensor name; None means the joint name
    """

    joint: str
    frame: str | None = None
    name: str | None = None

    @property
    def sensor_name(self) -> str:
        return self.name or self.joint

    def key(self) -> str:
        """A canonical text form, for cache keys."""
        return f"{self.sensor_name}@{self.joint}:{self.frame or ''}"


def prepare_urdf(text: str, source: str, declared: tuple[SensorDeclaration, ...] = ()) -> str:
    """URDF text with Gazebo and declared F/T sensors as iDynTree sensor elements.

    Parameters
    ----------
    text : URDF XML text
    source : file name for messages
    declared : sensors declared on fixed joints (``--ft-joint``/``--ft-frame``)

    Returns
    -------
    str : the text iDynTree should parse (``text`` itself when nothing changes)

    Raises
    ------
    FtcalError : unparsable XML, an unknown or non-fixed joint, a frame not
        rigidly attached to the joint's child link, a sensor declared twice.
    """
    if not declared and "force_torque" not in text:
        return text
    try:
        root = ET.fromstring(text)
    except ET.ParseError as exc:
        raise FtcalError(f"URDF {source} is not valid XML ({exc}).") from None
    joints = {j.get("name"): j for j in root.findall("joint")}
    native = {_parent_joint(s) for s in root.findall("sensor") if s.get("type") == "force_torque"}
    added: list[ET.Element] = []
    for gazebo in root.findall("gazebo"):
        joint = gazebo.get("reference")
        for tag in gazebo.findall("sensor"):
            if tag.get("type") == "force_torque" and joint not in native:
                _check_joint(joints, joint, source, f"Gazebo force_torque sensor {tag.get('name')!r}")
                added.append(_from_gazebo(tag, joint, source))
                native.add(joint)
    for decl in declared:
        _check_joint(joints, decl.joint, source, "{ft_joint}", "ft_joint")
        if decl.joint in native:
            raise ParameterError('ft_joint', f"URDF {source} already has an F/T sensor on joint {decl.joint!r}; "
                             f"use it by name instead of declaring one ({{ft_joint}}).")
        origin = None
        if decl.frame is not None:
            child = joints[decl.joint].find("child").get("link")
            origin = _rigid_transform(root, child, decl.frame, source, decl.joint)
        added.append(_sensor_element(decl.sensor_name, decl.joint, "sensor" if origin is not None else "child",
                                     "child_to_parent", origin))
        native.add(decl.joint)
    if not added and not _massless_children(root, joints, native):
        return text
    for element in added:
        root.append(element)
    links = {link.get("name"): link for link in root.findall("link")}
    for joint in native:
        if joint in joints:
            _keep_as_link(links.get(joints[joint].find("child").get("link")))
    return ET.tostring(root, encoding="unicode")


def fixed_joints(text: str) -> tuple[str, ...]:
    """Names of the URDF's fixed joints (where an F/T sensor can be declared), in file order."""
    try:
        root = ET.fromstring(text)
    except ET.ParseError:
        return ()
    return tuple(j.get("name") for j in root.findall("joint") if j.get("type") == "fixed")


def no_sensor_hint(text: str, name_of=lambda name: "{" + name + "}") -> str:
    """How to declare an F/T sensor on this URDF, naming its fixed joints; the parameters ``ft_joint`` and
    ``ft_frame`` are written ``name_of(name)`` (``{name}`` for a :class:`ParameterError`, a flag in the CLI)."""
    candidates = fixed_joints(text)
    listed = ", ".join(candidates[:12]) + (", ..." if len(candidates) > 12 else "") if candidates else "none"
    return (f"declare one with {name_of('ft_joint')} JOINT (optionally {name_of('ft_frame')} LINK) on a fixed joint "
            f"(this URDF's fixed joints: {listed}), or add a Gazebo <sensor type=\"force_torque\"> tag")


def _parent_joint(sensor: ET.Element) -> str | None:
    parent = sensor.find("parent")
    return None if parent is None else parent.get("joint")


def _check_joint(joints: dict, name: str | None, source: str, what: str, parameter: str | None = None) -> None:
    """Refuse a sensor joint that is not a fixed joint of the URDF; naming ``parameter`` (as ``{name}`` in
    ``what``) when the caller's parameter gave it."""
    def refuse(message):
        raise ParameterError(parameter, message) if parameter else FtcalError(message)

    if name not in joints:
        refuse(f"{what}: URDF {source} has no joint named {name!r}; its fixed joints are: "
                         f"{', '.join(n for n, j in joints.items() if j.get('type') == 'fixed') or 'none'}.")
    if joints[name].get("type") != "fixed":
        refuse(f"{what}: joint {name!r} of URDF {source} is {joints[name].get('type')}, not fixed; "
                         f"a six-axis F/T sensor sits on a fixed joint.")


def _from_gazebo(tag: ET.Element, joint: str, source: str) -> ET.Element:
    where = f"URDF {source}: Gazebo sensor {tag.get('name')!r}"
    frame = (tag.findtext("force_torque/frame") or "child").strip()
    direction = (tag.findtext("force_torque/measure_direction") or "child_to_parent").strip()
    if frame not in FRAMES:
        raise FtcalError(f"{where}: <frame> must be one of {', '.join(FRAMES)}; got {frame!r}.")
    if direction not in DIRECTIONS:
        raise FtcalError(f"{where}: <measure_direction> must be one of {', '.join(DIRECTIONS)}; got {direction!r}.")
    origin = None
    pose = tag.findtext("pose")
    if frame == "sensor" and pose and pose.strip():
        try:
            values = [float(v) for v in pose.split()]
        except ValueError:
            values = []
        if len(values) != 6:
            raise FtcalError(f"{where}: <pose> must be six numbers (x y z roll pitch yaw); got {pose.strip()!r}.")
        origin = (values[:3], values[3:])
    return _sensor_element(tag.get("name") or joint, joint, frame, direction, origin)


def _sensor_element(name: str, joint: str, frame: str, direction: str, origin) -> ET.Element:
    sensor = ET.Element("sensor", name=name, type="force_torque")
    ET.SubElement(sensor, "parent", joint=joint)
    if origin is not None:
        xyz, rpy = origin
        ET.SubElement(sensor, "origin", xyz=" ".join(map(repr, map(float, xyz))),
                      rpy=" ".join(map(repr, map(float, rpy))))
    ft = ET.SubElement(sensor, "force_torque")
    ET.SubElement(ft, "frame").text = frame
    ET.SubElement(ft, "measure_direction").text = direction
    return sensor


def _massless_children(root: ET.Element, joints: dict, sensor_joints: set) -> bool:
    links = {link.get("name"): link for link in root.findall("link")}
    return any(_mass(links.get(joints[j].find("child").get("link"))) == 0.0
               for j in sensor_joints if j in joints)


def _mass(link: ET.Element | None) -> float:
    if link is None:
        return 1.0
    mass = link.find("inertial/mass")
    try:
        return 0.0 if mass is None else float(mass.get("value", "0"))
    except ValueError:
        return 1.0  # iDynTree reports the malformed value itself


def _keep_as_link(link: ET.Element | None) -> None:
    if link is None or _mass(link) != 0.0:
        return
    inertial = link.find("inertial")
    if inertial is None:
        inertial = ET.SubElement(link, "inertial")
        ET.SubElement(inertial, "origin", xyz="0 0 0", rpy="0 0 0")
        ET.SubElement(inertial, "inertia", ixx="0", ixy="0", ixz="0", iyy="0", iyz="0", izz="0")
    mass = inertial.find("mass")
    if mass is None:
        mass = ET.SubElement(inertial, "mass")
    mass.set("value", repr(KEEP_LINK_MASS))


def rpy_matrix(roll: float, pitch: float, yaw: float) -> np.ndarray:
    """URDF's fixed-axis roll-pitch-yaw rotation, Rz(yaw) · Ry(pitch) · Rx(roll), shape (3, 3)."""
    cr, sr, cp, sp, cy, sy = np.cos(roll), np.sin(roll), np.cos(pitch), np.sin(pitch), np.cos(yaw), np.sin(yaw)
    rx = np.array([[1, 0, 0], [0, cr, -sr], [0, sr, cr]])
    ry = np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]])
    rz = np.array([[cy, -sy, 0], [sy, cy, 0], [0, 0, 1]])
    return rz @ ry @ rx


def _matrix_rpy(rotation: np.ndarray) -> tuple[float, float, float]:
    pitch = float(np.arcsin(np.clip(-rotation[2, 0], -1.0, 1.0)))
    if abs(rotation[2, 0]) < 1 - 1e-12:
        return float(np.arctan2(rotation[2, 1], rotation[2, 2])), pitch, float(np.arctan2(rotation[1, 0], rotation[0, 0]))
    # Gimbal lock: only roll - yaw (or roll + yaw) is defined; put it all in roll.
    return float(np.arctan2(-rotation[1, 2], rotation[1, 1])), pitch, 0.0


def _origin(joint: ET.Element) -> np.ndarray:
    origin = joint.find("origin")
    xyz = [float(v) for v in (origin.get("xyz", "0 0 0") if origin is not None else "0 0 0").split()]
    rpy = [float(v) for v in (origin.get("rpy", "0 0 0") if origin is not None else "0 0 0").split()]
    out = np.eye(4)
    out[:3, :3] = rpy_matrix(*rpy)
    out[:3, 3] = xyz
    return out


def _rigid_transform(root: ET.Element, child: str, frame: str, source: str, joint: str):
    """child_H_frame through fixed joints only, as (xyz, rpy); error if not rigidly attached."""
    edges: dict[str, list[tuple[str, np.ndarray]]] = {}
    for j in root.findall("joint"):
        if j.get("type") != "fixed":
            continue
        a, b, h = j.find("parent").get("link"), j.find("child").get("link"), _origin(j)
        edges.setdefault(a, []).append((b, h))
        edges.setdefault(b, []).append((a, np.linalg.inv(h)))
    seen = {child: np.eye(4)}
    queue = deque([child])
    while queue:
        link = queue.popleft()
        for nxt, h in edges.get(link, ()):
            if nxt not in seen:
                seen[nxt] = seen[link] @ h
                queue.append(nxt)
    if frame not in seen:
        if frame not in {link.get("name") for link in root.findall("link")}:
            raise ParameterError('ft_frame', f"{{ft_frame}} {frame!r}: URDF {source} has no link named {frame!r}.")
        raise ParameterError(('ft_frame', 'ft_joint'), f"{{ft_frame}} {frame!r} is not rigidly attached (through fixed joints only) to "
                         f"{child!r}, the child link of {{ft_joint}} {joint!r} in URDF {source}.")
    h = seen[frame]
    return h[:3, 3], _matrix_rpy(h[:3, :3])
