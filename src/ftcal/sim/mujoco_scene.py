"""A MuJoCo scene built from the same URDF ftcal reads with iDynTree: arm, wrist F/T site, tool, table.

MuJoCo (``mujoco`` from PyPI) loads URDF itself; before it does, :func:`mujoco_urdf` removes
what it cannot or need not load here, and says so:

* ``<visual>`` and ``<collision>`` elements (meshes included): only the links' ``<inertial>``
  elements matter for the wrench at the sensor, so meshes are replaced by their inertias; the
  only contact geometry is the tool tip and the table this module adds;
* ``<gazebo>``, ``<transmission>``, ``<sensor>`` and ``ros2_control`` elements (not rigid-body data);
* fixed joints are kept as bodies (``fusestatic="false"``), so the sensor's child link stays a body
  and MuJoCo's force/torque sensors can measure the wrench across the sensor joint.

Sign convention: MuJoCo's ``force``/``torque`` sensors on a site of the child body report the
wrench the parent applies on the child's subtree; ftcal (iDynTree, ``child_to_parent``) reports
the wrench the child applies on the parent, so :func:`sensor_wrench` negates them. At a static pose
the two engines agree (tests/e2e/test_closed_loop.py checks it to a relative 1e-6).
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from dataclasses import dataclass

import numpy as np

from ..robot.model import RobotModel
from ..runtime.errors import FtcalError

REMOVED = ("visual", "collision")
TOP_LEVEL_REMOVED = ("gazebo", "transmission", "sensor", "ros2_control")
SITE, TIP_SITE, TOOL_BODY, TABLE = "ftcal_ft", "ftcal_tip", "ftcal_tool", "ftcal_table"


@dataclass(frozen=True)
class Tool:
    """A tool on the sensor: rigid body in the sensor frame, and a spherical tip for contact.

    mass : kg; com : m; inertia : (ixx, iyy, izz) kg m² about the COM, sensor axes;
    tip : tip centre (m, sensor frame); radius : tip radius, m
    """

    mass: float = 1.0
    com: tuple[float, float, float] = (0.0, 0.01, 0.06)
    inertia: tuple[float, float, float] = (0.004, 0.004, 0.001)
    tip: tuple[float, float, float] = (0.0, 0.0, 0.14)
    radius: float = 0.01


@dataclass
class Scene:
    """A compiled MuJoCo model and data with the names ftcal added."""

    model: object
    data: object
    joint_names: tuple[str, ...]
    qpos_index: np.ndarray
    dof_index: np.ndarray
    site: int
    tip: int | None
    table_geom: int | None
    tip_geom: int | None
    tool_body: int | None
    notes: tuple[str, ...]


def mujoco_urdf(urdf_text: str, source: str = "<urdf>") -> tuple[str, list[str]]:
    """URDF text MuJoCo loads with every link kept as a body, and what was removed (for the report)."""
    try:
        root = ET.fromstring(urdf_text)
    except ET.ParseError as exc:
        raise FtcalError(f"URDF {source} is not valid XML ({exc}).") from None
    counts: dict[str, int] = {}
    meshes = 0
    for link in root.findall("link"):
        for tag in REMOVED:
            for element in link.findall(tag):
                meshes += len(element.findall(".//mesh"))
                link.remove(element)
                counts[tag] = counts.get(tag, 0) + 1
    for tag in TOP_LEVEL_REMOVED:
        for element in root.findall(tag):
            root.remove(element)
            counts[tag] = counts.get(tag, 0) + 1
    for element in root.findall("mujoco"):
        root.remove(element)
    extension = ET.SubElement(root, "mujoco")
    ET.SubElement(extension, "compiler", discardvisual="true", fusestatic="false", balanceinertia="false",
                  strippath="true")
    notes = [f"removed {n} <{tag}> element(s)" for tag, n in sorted(counts.items())]
    if meshes:
        notes.append(f"{meshes} mesh(es) replaced by their links' inertias (no geometry is needed for the wrench)")
    return ET.tostring(root, encoding="unicode"), notes


def build_scene(robot: RobotModel, sensor: str, tool: Tool | None = None, *, table_height: float | None = None,
                table_center: tuple[float, float] = (0.5, 0.0), timestep: float = 0.002,
                friction: float = 0.3, joint_damping: float = 0.5) -> Scene:
    """Compile the arm of ``robot`` with a force/torque site at ``sensor``, optionally a tool and a table.

    Parameters
    ----------
    robot : the robot (payloads are not transferred: pass the tool as ``tool``)
    sensor : F/T sensor or joint name
    tool : rigid tool on the sensor frame, with a contact tip
    table_height : top of a table (m, base z) under the tool; None: no table
    """
    try:
        import mujoco
    except ImportError:
        raise FtcalError("the closed-loop scenario needs MuJoCo: pip install 'ftcal[mujoco]'.") from None

    ft = robot.sensor(sensor)
    text, notes = mujoco_urdf(robot.urdf_text, robot.source)
    try:
        spec = mujoco.MjSpec.from_string(text)
    except Exception as exc:  # mujoco raises ValueError with its own message
        raise FtcalError(f"URDF {robot.source}: MuJoCo cannot load it ({str(exc).splitlines()[0]}).") from None
    spec.option.timestep = timestep
    parent_H_sensor = _parent_H_sensor(robot, ft)
    model = spec.compile()
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    world_H_parent = _body_pose(model, data, ft.parent_link)
    world_H_child = _body_pose(model, data, ft.child_link)
    child_H_sensor = np.linalg.inv(world_H_child) @ world_H_parent @ parent_H_sensor
    child = spec.body(ft.child_link)
    quat = _quat(child_H_sensor[:3, :3])
    child.add_site(name=SITE, pos=child_H_sensor[:3, 3], quat=quat, size=[0.01, 0.01, 0.01])
    spec.add_sensor(name="ftcal_force", type=mujoco.mjtSensor.mjSENS_FORCE, objtype=mujoco.mjtObj.mjOBJ_SITE,
                    objname=SITE)
    spec.add_sensor(name="ftcal_torque", type=mujoco.mjtSensor.mjSENS_TORQUE, objtype=mujoco.mjtObj.mjOBJ_SITE,
                    objname=SITE)
    for j in spec.joints:
        j.damping = [joint_damping, 0.0, 0.0]
    if tool is not None:
        body = child.add_body(name=TOOL_BODY, pos=child_H_sensor[:3, 3], quat=quat)
        body.explicitinertial = True
        body.mass = tool.mass
        body.ipos = list(tool.com)
        body.inertia = list(tool.inertia)
        body.add_geom(name=TOOL_BODY + "_tip", type=mujoco.mjtGeom.mjGEOM_SPHERE, size=[tool.radius, 0, 0],
                      pos=list(tool.tip), density=0.0, friction=[friction, 0.005, 0.0001], condim=3,
                      solref=[0.01, 1.0])
        body.add_site(name=TIP_SITE, pos=list(tool.tip))
    if table_height is not None:
        spec.worldbody.add_geom(name=TABLE, type=mujoco.mjtGeom.mjGEOM_BOX, size=[0.3, 0.3, 0.1],
                                pos=[table_center[0], table_center[1], table_height - 0.1],
                                friction=[friction, 0.005, 0.0001], solref=[0.01, 1.0])
    model = spec.compile()
    data = mujoco.MjData(model)
    names = tuple(n for n in robot.joint_names)
    qpos_index, dof_index = [], []
    for n in names:
        jid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, n)
        if jid < 0:
            raise FtcalError(f"URDF {robot.source}: MuJoCo has no joint {n!r} (continuous or planar joints are "
                             "not supported here).")
        qpos_index.append(model.jnt_qposadr[jid])
        dof_index.append(model.jnt_dofadr[jid])
    site = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, SITE)
    tip = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, TIP_SITE) if tool is not None else None
    table_geom = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, TABLE) if table_height is not None else None
    tip_geom = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, TOOL_BODY + "_tip") if tool is not None else None
    tool_body = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, TOOL_BODY) if tool is not None else None
    return Scene(model, data, names, np.array(qpos_index), np.array(dof_index), site, tip, table_geom, tip_geom,
                 tool_body, tuple(notes))


def sensor_wrench(scene: Scene) -> np.ndarray:
    """The wrench at the sensor in ftcal's convention (child on parent, sensor frame), from the last forward pass."""
    return -np.asarray(scene.data.sensordata[:6], dtype=np.float64).copy()


def static_sensor_wrench(scene: Scene, q: np.ndarray) -> np.ndarray:
    """The wrench at joint positions ``q`` (robot.joint_names order) with the arm held still (zero velocity
    and acceleration, by inverse dynamics), shape (6,)."""
    import mujoco

    m, d = scene.model, scene.data
    d.qpos[:] = m.qpos0
    d.qpos[scene.qpos_index] = q
    d.qvel[:] = 0.0
    d.qacc[:] = 0.0
    mujoco.mj_inverse(m, d)
    return sensor_wrench(scene)


def _parent_H_sensor(robot: RobotModel, ft) -> np.ndarray:
    import idyntree.swig as idyn

    native = robot.sensors.getSixAxisForceTorqueSensor(ft.index)
    transform = idyn.Transform()
    if not native.getLinkSensorTransform(robot.model.getLinkIndex(ft.parent_link), transform):
        raise FtcalError(f"iDynTree has no transform from link {ft.parent_link!r} to F/T sensor {ft.name!r}.")
    return transform.asHomogeneousTransform().toNumPy()


def _body_pose(model, data, name: str) -> np.ndarray:
    import mujoco

    bid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, name)
    if bid < 0:
        raise FtcalError(f"MuJoCo has no body {name!r} (the link was merged or renamed).")
    out = np.eye(4)
    out[:3, :3] = data.xmat[bid].reshape(3, 3)
    out[:3, 3] = data.xpos[bid]
    return out


def _quat(rotation: np.ndarray) -> list[float]:
    """MuJoCo's (w, x, y, z) quaternion of a rotation matrix."""
    from scipy.spatial.transform import Rotation

    x, y, z, w = Rotation.from_matrix(rotation).as_quat()
    return [w, x, y, z]
