"""Sensor-frame kinematics from a URDF and joint data (iDynTree ``KinDynComputations``).

What a payload on the far side of an F/T sensor feels, per sample, in the
sensor frame: the gravity vector, the angular velocity and acceleration, and the
proper acceleration (what an accelerometer at the sensor origin would read,
``a - g``). :func:`sensor_kinematics` gives them for a sensor,
:func:`frame_kinematics` for any frame of the model, and
:func:`payload_regressor` the matrix that maps the inertial parameters of an
unknown payload on a link to its contribution to a sensor's expected wrench.

Kinematics follow :mod:`ftcal.robot.expected`: a fixed base (``base`` frame,
gravity given in its axes) by default; with a :class:`FloatingBase`, the IMU's
proper acceleration, angular velocity and angular acceleration drive the
kinematics (the IMU frame's link is the floating base), and the gravity vector
is the static estimate ``-proper acceleration`` of the IMU, rotated into each
frame (exact when the IMU does not accelerate linearly).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ..runtime.errors import FtcalError, ParameterError
from .expected import GRAVITY, FloatingBase, check_joints
from .model import RobotModel

# Mass and first moments: the only inertial parameters a static pose sees.
N_STATIC_PARAMETERS = 4


@dataclass(frozen=True)
class FrameKinematics:
    """Per-sample kinematics of one frame, all in that frame's axes.

    Attributes
    ----------
    gravity : ndarray of shape (n_samples, 3), m/s², the gravity vector
    angular_velocity : ndarray of shape (n_samples, 3), rad/s
    angular_acceleration : ndarray of shape (n_samples, 3), rad/s²
    proper_acceleration : ndarray of shape (n_samples, 3), m/s², acceleration of
        the frame origin minus gravity (an accelerometer's reading; ``-gravity`` at rest)
    """

    gravity: np.ndarray
    angular_velocity: np.ndarray
    angular_acceleration: np.ndarray
    proper_acceleration: np.ndarray


class _Kinematics:
    """One KinDynComputations set up for fixed- or floating-base sample-by-sample queries."""

    def __init__(self, robot: RobotModel, base: str | None, gravity: Sequence[float],
                 floating: FloatingBase | None) -> None:
        import idyntree.swig as idyn

        self.idyn = idyn
        model = robot.model
        if floating is not None:
            if not model.isFrameNameUsed(floating.frame):
                raise FtcalError(f"URDF {robot.source} has no frame named {floating.frame!r} (IMU frame).")
            anchor = int(model.getFrameIndex(floating.frame))
        else:
            anchor = robot.base_frame(base)[0]
        self.model = model
        self.floating = floating
        link = model.getFrameLink(anchor)
        self.kd = idyn.KinDynComputations()
        self.kd.loadRobotModel(model)
        self.kd.setFloatingBase(model.getLinkName(link))
        self.kd.setFrameVelocityRepresentation(idyn.MIXED_REPRESENTATION)
        # world = the anchor frame (base frame, or the IMU frame at that instant).
        link_H_anchor = model.getFrameTransform(anchor).asHomogeneousTransform().toNumPy()
        self.world_H_base = idyn.Transform(np.linalg.inv(link_H_anchor))
        self.anchor_rotation = link_H_anchor[:3, :3]
        self.anchor_origin = link_H_anchor[:3, 3]
        self.gravity = np.asarray(gravity, dtype=float)
        n = model.getNrOfDOFs()
        self.zeros = np.zeros(n)

    def frame_index(self, name: str, source: str) -> int:
        if not self.model.isFrameNameUsed(name):
            raise FtcalError(f"URDF {source} has no link or frame named {name!r}.")
        return int(self.model.getFrameIndex(name))

    def update(self, k: int, q, dq, ddq) -> None:
        """Set the state of sample ``k``; afterwards :meth:`frame` answers for any frame."""
        idyn = self.idyn
        qk = q[k]
        dqk = self.zeros if dq is None else dq[k]
        self.ddq = idyn.VectorDynSize.FromPython(self.zeros if ddq is None else ddq[k])
        twist = np.zeros(6)
        base_acc = np.zeros(6)
        gravity = self.gravity
        self.gravity_world = self.gravity
        if self.floating is not None:
            fb = self.floating
            # World axes = the IMU's axes at this instant; the IMU's link is the base.
            omega = fb.angular_velocity[k]
            alpha = np.zeros(3) if fb.angular_acceleration is None else fb.angular_acceleration[k]
            r = self.anchor_rotation.T @ self.anchor_origin  # base origin -> IMU origin, world axes
            # Proper acceleration of the base origin from the IMU's; computing with zero gravity
            # then gives every frame its proper acceleration (a uniform field shifts all alike).
            twist[3:] = omega
            base_acc[:3] = fb.proper_acceleration[k] - np.cross(alpha, r) - np.cross(omega, np.cross(omega, r))
            base_acc[3:] = alpha
            gravity = np.zeros(3)
            self.gravity_world = -fb.proper_acceleration[k]
        ok = self.kd.setRobotState(self.world_H_base, idyn.VectorDynSize.FromPython(qk), idyn.Twist.FromPython(twist),
                                   idyn.VectorDynSize.FromPython(dqk), idyn.Vector3.FromPython(gravity))
        if not ok:
            raise FtcalError(f"iDynTree could not set the robot state at sample {k}.")
        self.base_acc = idyn.Vector6.FromPython(base_acc)

    def frame(self, index: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """world_R_frame, world position, then ω, α and proper acceleration in world axes."""
        h = self.kd.getWorldTransform(index).asHomogeneousTransform().toNumPy()
        vel = self.kd.getFrameVel(index).toNumPy()
        acc = self.kd.getFrameAcc(index, self.base_acc, self.ddq).toNumPy()
        proper = acc[:3] - (0.0 if self.floating is not None else self.gravity)
        return h[:3, :3], h[:3, 3], vel[3:], acc[3:], proper


def _prepare(robot: RobotModel, q, dq, ddq, floating):
    q = check_joints(robot, q, "joint positions")
    dq = None if dq is None else check_joints(robot, dq, "joint velocities", q.shape[0])
    ddq = None if ddq is None else check_joints(robot, ddq, "joint accelerations", q.shape[0])
    return q, dq, ddq


def require_chain_joints(robot: RobotModel, given: Sequence[str], base: str, sensor: str, where: str,
                         parameters: Sequence[str] = ()) -> None:
    """Refuse data that lack a joint on the chain from ``base`` to F/T ``sensor``.

    A joint without data is held at 0 rad (:meth:`RobotModel.joint_matrix`): off that chain that
    only moves other limbs, but on it it turns gravity in the sensor frame, silently.

    Raises
    ------
    FtcalError
        Naming ``where``, the missing joints, the base and the sensor; a :class:`ParameterError` of
        ``parameters`` when they are given (``where`` then writes them as ``{name}``).
    """
    chain = robot.chain_joints(base, _sensor_frame(robot, sensor)[0])
    missing = [j for j in chain if j not in set(given)]
    if missing:
        _refuse(parameters, f"{where}: no data for joint(s) {', '.join(map(repr, missing))}, on the chain from base "
                f"{base!r} to sensor {sensor!r}: gravity in the sensor frame depends on them, and a joint "
                "without data would be held at 0 rad (joints off that chain may be left out).")


def require_wrench_joints(robot: RobotModel, given: Sequence[str], base: str, sensors: Sequence[str], where: str,
                          hint: str = "", parameters: Sequence[str] = ()) -> None:
    """Refuse data that lack a joint the expected wrench of any of ``sensors`` depends on.

    That is every joint on the chain from ``base`` to the sensor (it turns gravity in the sensor frame) and
    every joint beyond the sensor (it moves the mass the sensor carries); a joint without data would be
    held at 0 rad by :meth:`RobotModel.joint_matrix`, silently.

    Parameters
    ----------
    robot : the model
    given : names of the joints the data hold
    base : fixed base frame
    sensors : F/T sensor (or sensor joint) names
    where : the data's name in the message
    hint : what the user can do instead, appended to the message
    parameters : the caller's parameters that ``where`` and ``hint`` write as ``{name}`` (a
        :class:`ParameterError`), or none

    Raises
    ------
    FtcalError
        Naming ``where``, the missing joints and the sensors they matter for.
    """
    given_set = set(given)
    missing: list[str] = []
    for name in sensors:
        ft = robot.sensor(name)
        needed = (*robot.chain_joints(base, _sensor_frame(robot, ft.name)[0]), *robot.joints_beyond(ft, base))
        missing += [j for j in needed if j not in given_set and j not in missing]
    if missing:
        shown = ", ".join(map(repr, missing[:8])) + (f" and {len(missing) - 8} more" if len(missing) > 8 else "")
        _refuse(parameters, f"{where}: no data for joint(s) {shown}; the expected wrench of sensor(s) "
                f"{', '.join(sensors)} depends on them (they turn gravity in the sensor frame or move the "
                f"mass beyond it), and a joint without data would be held at 0 rad{hint}.")


def _refuse(parameters: Sequence[str], message: str):
    """Raise ``message``: naming ``parameters`` (as ``{name}``) when there are any."""
    raise ParameterError(tuple(parameters), message) if parameters else FtcalError(message)


def _sensor_frame(robot: RobotModel, sensor: str) -> tuple[str, np.ndarray]:
    """Name of the link the sensor's frame is fixed to, and link_H_sensor (4, 4)."""
    import idyntree.swig as idyn

    ft = robot.sensor(sensor)
    native = robot.sensors.getSixAxisForceTorqueSensor(ft.index)
    link = robot.model.getLinkIndex(ft.parent_link)
    transform = idyn.Transform()
    if not native.getLinkSensorTransform(link, transform):
        raise FtcalError(f"iDynTree has no transform from link {ft.parent_link!r} to F/T sensor {ft.name!r}.")
    return ft.parent_link, transform.asHomogeneousTransform().toNumPy()


def frame_kinematics(robot: RobotModel, frame: str, q: np.ndarray, dq: np.ndarray | None = None,
                     ddq: np.ndarray | None = None, *, base: str | None = None,
                     gravity: Sequence[float] = GRAVITY, floating: FloatingBase | None = None,
                     frame_H_point: np.ndarray | None = None) -> FrameKinematics:
    """Kinematics of a model frame (link or additional frame), per sample, in its own axes.

    Parameters
    ----------
    robot : the model
    frame : link or frame name
    q, dq, ddq : ndarray of shape (n_samples, n_dofs), order of ``robot.joint_names``
        (rad, rad/s, rad/s²); ``dq``/``ddq`` None mean zero (static)
    base : fixed base frame (default as :meth:`RobotModel.base_frame`); ignored with ``floating``
    gravity : gravity in base-frame axes, m/s²
    floating : IMU data for a floating base (see module docstring)
    frame_H_point : optional (4, 4) pose of a point frame rigidly fixed to ``frame``; the
        result is then that point frame's kinematics

    Returns
    -------
    FrameKinematics

    Raises
    ------
    FtcalError : unknown frame, bad joint arrays, iDynTree failure.
    """
    q, dq, ddq = _prepare(robot, q, dq, ddq, floating)
    kin = _Kinematics(robot, base, gravity, floating)
    index = kin.frame_index(frame, robot.source)
    offset = np.eye(4) if frame_H_point is None else np.asarray(frame_H_point, dtype=float)
    rot_fp, r_fp = offset[:3, :3], offset[:3, 3]
    n = q.shape[0]
    out = np.empty((4, n, 3))
    for k in range(n):
        kin.update(k, q, dq, ddq)
        rot, _, omega, alpha, proper = kin.frame(index)
        r = rot @ r_fp
        proper = proper + np.cross(alpha, r) + np.cross(omega, np.cross(omega, r))
        to_point = (rot @ rot_fp).T
        out[:, k] = (to_point @ kin.gravity_world, to_point @ omega, to_point @ alpha, to_point @ proper)
    return FrameKinematics(*out)


def sensor_kinematics(robot: RobotModel, sensor: str, q: np.ndarray, dq: np.ndarray | None = None,
                      ddq: np.ndarray | None = None, *, base: str | None = None,
                      gravity: Sequence[float] = GRAVITY,
                      floating: FloatingBase | None = None) -> FrameKinematics:
    """Kinematics of an F/T sensor's frame (the frame its wrench is expressed in), per sample.

    Parameters and returns as :func:`frame_kinematics`; ``sensor`` is a sensor or
    joint name. ``gravity`` of the result is what the payload tools need for a
    static pose: a tool of mass m at rest adds ``m * gravity`` to the sensor's force.
    """
    link, link_H_sensor = _sensor_frame(robot, sensor)
    return frame_kinematics(robot, link, q, dq, ddq, base=base, gravity=gravity, floating=floating,
                            frame_H_point=link_H_sensor)


def sensor_poses(robot: RobotModel, sensor: str, q: np.ndarray, *, base: str | None = None) -> np.ndarray:
    """Pose of an F/T sensor's frame in the fixed ``base`` frame, per sample (positions only, no motion).

    Parameters
    ----------
    robot : the model
    sensor : sensor or joint name
    q : ndarray of shape (n_samples, n_dofs), order of ``robot.joint_names`` (rad)
    base : fixed base frame (default as :meth:`RobotModel.base_frame`)

    Returns
    -------
    ndarray of shape (n_samples, 4, 4)
        ``base_H_sensor``: rotation (sensor axes in base axes) and origin (m). The
        gravity vector ``g`` of the base frame reads ``R.T @ g`` in sensor axes.
    """
    import idyntree.swig as idyn

    q = check_joints(robot, q, "joint positions")
    link, link_H_sensor = _sensor_frame(robot, sensor)
    model = robot.model
    anchor = robot.base_frame(base)[0]
    kd = idyn.KinDynComputations()
    kd.loadRobotModel(model)
    kd.setFloatingBase(model.getLinkName(model.getFrameLink(anchor)))
    base_H_link = model.getFrameTransform(anchor).asHomogeneousTransform().toNumPy()
    kd.setWorldBaseTransform(idyn.Transform(np.linalg.inv(base_H_link)))
    index = int(model.getFrameIndex(link))
    out = np.empty((q.shape[0], 4, 4))
    for k in range(q.shape[0]):
        if not kd.setJointPos(idyn.VectorDynSize.FromPython(q[k])):
            raise FtcalError(f"iDynTree could not set the joint positions at sample {k}.")
        out[k] = kd.getWorldTransform(index).asHomogeneousTransform().toNumPy()
    return out @ link_H_sensor


def payload_regressor(robot: RobotModel, sensor: str, link: str, q: np.ndarray, dq: np.ndarray | None = None,
                      ddq: np.ndarray | None = None, *, base: str | None = None,
                      gravity: Sequence[float] = GRAVITY, floating: FloatingBase | None = None,
                      static: bool = False) -> np.ndarray:
    """Per-sample matrix Y with ``wrench = Y @ pi`` for an unknown payload on ``link``.

    ``pi`` are the payload's inertial parameters in ``link`` coordinates, in the
    order of :data:`ftcal.payload.regressor.INERTIAL_PARAMETERS` (m kg; m·c kg m; inertia about the link
    origin, link axes, kg m²), and ``wrench`` (Fx..Tz, N and N m) is what the
    payload adds to ``sensor``'s expected wrench, with the convention of
    :mod:`ftcal.robot.expected`. ``link`` must be on the far side of the sensor
    as seen from the base.

    Returns
    -------
    ndarray of shape (n_samples, 6, 10), or (n_samples, 6, 4) with ``static``
    (mass and first moments only: the inertia columns vanish without motion).

    Raises
    ------
    FtcalError : unknown sensor or link, a link on the base side of the sensor.
    """
    from ..payload.regressor import INERTIAL_PARAMETERS, inertial_regressor

    q, dq, ddq = _prepare(robot, q, dq, ddq, floating)
    ft = robot.sensor(sensor)
    beyond = robot.links_beyond(ft, None if floating is not None else base)
    if link not in beyond:
        raise FtcalError(f"Payload link {link!r}: not on the far side of F/T sensor {ft.name!r}, so the "
                         f"sensor does not feel it; links beyond it: {', '.join(beyond) or 'none'}.")
    sensor_link, link_H_sensor = _sensor_frame(robot, sensor)
    kin = _Kinematics(robot, base, gravity, floating)
    sensor_index = kin.frame_index(sensor_link, robot.source)
    link_index = kin.frame_index(link, robot.source)
    n = q.shape[0]
    sensor_R_link = np.empty((n, 3, 3))
    lever = np.empty((n, 3))
    motion = np.empty((3, n, 3))
    for k in range(n):
        kin.update(k, q, dq, ddq)
        rot_l, p_l, omega, alpha, proper = kin.frame(link_index)
        rot_s, p_s, *_ = kin.frame(sensor_index)
        world_R_sensor = rot_s @ link_H_sensor[:3, :3]
        sensor_R_link[k] = world_R_sensor.T @ rot_l
        lever[k] = world_R_sensor.T @ (p_l - rot_s @ link_H_sensor[:3, 3] - p_s)
        motion[:, k] = (rot_l.T @ proper, rot_l.T @ omega, rot_l.T @ alpha)
    # Wrench the payload applies at the link origin, link axes; then rotate it into the sensor
    # frame and take the torque about the sensor origin.
    y_link = inertial_regressor(*motion)
    width = N_STATIC_PARAMETERS if static else len(INERTIAL_PARAMETERS)
    force = np.einsum("nij,njk->nik", sensor_R_link, y_link[:, :3, :width])
    torque = np.einsum("nij,njk->nik", sensor_R_link, y_link[:, 3:, :width]) + np.cross(lever[:, :, None], force, axis=1)
    return np.concatenate([force, torque], axis=1)


@dataclass(frozen=True)
class JointColumnsSource:
    """Sensor-frame gravity from joint-position columns and a URDF: a kinematics source for ``ftcal payload``.

    Implements :class:`ftcal.payload.kinematics.KinematicsSource`: called with a
    table, it reads every column named like a movable joint of ``robot`` (rad, or
    degrees with ``degrees``; joints without a column are 0) and returns the
    gravity vector ``(0, 0, -g)`` of the fixed ``base`` frame expressed in the
    frame of F/T ``sensor``, per row (static poses).
    """

    robot: RobotModel
    sensor: str
    base: str | None = None
    g: float = 9.81
    degrees: bool = False

    @property
    def columns(self) -> tuple[str, ...]:
        return self.robot.joint_names

    def __call__(self, frame, source: str):
        from ..payload.kinematics import Kinematics

        known = set(self.robot.joint_names)
        names = [str(c) for c in frame.columns if c in known]
        if not names:
            raise FtcalError(f"{source}: no column is named like a joint of URDF {self.robot.source} "
                             f"(e.g. {', '.join(self.robot.joint_names[:4])}).")
        non_numeric = [c for c in names if not np.issubdtype(frame[c].dtype, np.number)]
        if non_numeric:
            raise FtcalError(f"{source}: joint column {non_numeric[0]!r} is not numeric.")
        require_chain_joints(self.robot, names, self.robot.base_frame(self.base)[1], self.sensor, source)
        values = frame[names].to_numpy(np.float64)
        if self.degrees:
            values = np.deg2rad(values)
        q = self.robot.joint_matrix(names, values, source)
        kinematics = sensor_kinematics(self.robot, self.sensor, q, base=self.base, gravity=(0.0, 0.0, -self.g))
        return Kinematics(kinematics.gravity)


def kinematics_source(*, orientation: Sequence[str] | None = None, gravity_columns: Sequence[str] | None = None,
                      g: float = 9.81, urdf: str | None = None, robot_name: str | None = None,
                      sensor: str | None = None, ft_joint: str | None = None, ft_frame: str | None = None,
                      base: str | None = None, degrees: bool = False, dynamic: bool = False,
                      angular_velocity: Sequence[str] | None = ("wx", "wy", "wz"),
                      linear_acceleration: Sequence[str] | None = ("ax", "ay", "az"),
                      angular_acceleration: Sequence[str] | None = None, time: str | None = None,
                      robot_parameters: Sequence[str] = ("urdf", "robot")):
    """The gravity (and motion) source of ``ftcal payload``, ``check`` and ``compensate``.

    Exactly one of: quaternion ``orientation`` columns (x, y, z, w), ``gravity_columns`` (sensor
    frame, m/s²), or a robot model (``urdf`` or ``robot_name``, with ``sensor`` or a sensor declared
    on the fixed joint ``ft_joint``) and its joint columns. With ``dynamic`` the source also gives
    the motion columns (:class:`~ftcal.payload.kinematics.MotionSource`).

    Parameters
    ----------
    robot_parameters : the caller's parameters that give the robot model, for messages (``robot`` is
        ``robot_name``: the steps' name for it)

    Returns
    -------
    KinematicsSource

    Raises
    ------
    FtcalError
        No source or two sources, wrong column counts, an unknown sensor or a URDF error.
    """
    from ..payload.kinematics import GravityColumnsSource, MotionSource, OrientationSource
    from .declare import SensorDeclaration

    # Messages name the step's parameters ({name}, ParameterError): the CLI shows them as its flags.
    robot_text = " or ".join("{" + n + "}" + {"urdf": " PATH", "robot": " NAME"}.get(n, "") for n in robot_parameters)
    if urdf is not None or robot_name is not None:
        if orientation is not None or gravity_columns is not None:
            raise ParameterError((*robot_parameters, "orientation", "gravity_columns"),
                                 f"give one gravity source: a robot model ({robot_text}), {{orientation}} or "
                                 "{gravity_columns}.")
        if ft_joint is None and ft_frame is not None:
            raise ParameterError(("ft_frame", "ft_joint"),
                                 "{ft_frame} needs {ft_joint} (the fixed joint the sensor sits on).")
        declared = () if ft_joint is None else (SensorDeclaration(ft_joint, ft_frame),)
        robot = RobotModel.load(urdf=urdf, name=robot_name, declared=declared)
        robot.require_ft_sensors()
        if sensor is None and len(robot.ft_sensors) > 1:
            raise ParameterError("sensor", f"{{sensor}}: URDF {robot.source} has {len(robot.ft_sensors)} F/T "
                                 f"sensors; name one of {', '.join(s.name for s in robot.ft_sensors)}.")
        chosen = robot.sensor(sensor) if sensor is not None else robot.ft_sensors[0]
        source = JointColumnsSource(robot, chosen.name, base, g, degrees)
    elif orientation is not None or gravity_columns is not None:
        if orientation is not None and gravity_columns is not None:
            raise ParameterError(("orientation", "gravity_columns"),
                                 "give one gravity source: {orientation} or {gravity_columns}, not both.")
        # The robot model's options mean nothing to a column source: refused, not ignored.
        given = [name for name, value in (("sensor", sensor), ("ft_joint", ft_joint), ("ft_frame", ft_frame),
                                          ("base", base), ("degrees", degrees or None)) if value is not None]
        if given:
            raise ParameterError((*given, *robot_parameters),
                                 f"{', '.join('{' + n + '}' for n in given)} {'go' if len(given) > 1 else 'goes'} "
                                 f"with a robot model ({robot_text}) and its joint columns; "
                                 "the gravity here comes from columns.")
        if orientation is not None:
            if len(orientation) != 4:
                raise ParameterError("orientation", f"{{orientation}} needs 4 columns qx,qy,qz,qw; "
                                     f"got {','.join(orientation)}.")
            source = OrientationSource(tuple(orientation), g)
        else:
            if len(gravity_columns) != 3:
                raise ParameterError("gravity_columns", f"{{gravity_columns}} needs 3 columns; "
                                     f"got {','.join(gravity_columns)}.")
            source = GravityColumnsSource(tuple(gravity_columns), g)
    else:
        raise ParameterError(("orientation", "gravity_columns", *robot_parameters, "sensor"),
                             "give the sensor's orientation: {orientation} qx,qy,qz,qw, {gravity_columns} gx,gy,gz, "
                             f"or a robot model ({robot_text}) with {{sensor}}.")
    if not dynamic:
        given = [name for name, value, default in (
            ("angular_velocity", angular_velocity, ("wx", "wy", "wz")),
            ("linear_acceleration", linear_acceleration, ("ax", "ay", "az")),
            ("angular_acceleration", angular_acceleration, None)) if _as_tuple(value) != default]
        if given:
            raise ParameterError((*given, "dynamic"),
                                 f"{', '.join('{' + n + '}' for n in given)} {'go' if len(given) > 1 else 'goes'} "
                                 "with {dynamic} (the motion columns of the inertia fit); "
                                 "a static fit does not read them.")
        return source
    for name, cols in (("angular_velocity", angular_velocity), ("linear_acceleration", linear_acceleration),
                       ("angular_acceleration", angular_acceleration)):
        if cols is not None and len(cols) != 3:
            raise ParameterError(name, f"{{{name}}} needs 3 columns; got {','.join(cols)}.")
    return MotionSource(source, angular_velocity, linear_acceleration, angular_acceleration, time or "time")


def _as_tuple(columns):
    return None if columns is None else tuple(columns)


class SensorGravity:
    """Gravity in an F/T sensor's frame from joint positions, one sample or a block at a time (static poses).

    The live calibrator's robot source: it keeps one iDynTree ``KinDynComputations`` (set up once), and
    per sample sets the joint positions and reads the sensor frame's orientation ``base_R_sensor``;
    gravity ``(0, 0, −g)`` of the fixed ``base`` frame then reads ``base_R_sensorᵀ (0, 0, −g)`` (what
    :class:`JointColumnsSource` gives ``ftcal payload`` through :func:`sensor_kinematics`).

    Parameters
    ----------
    robot : RobotModel
    sensor : F/T sensor (sensor or joint name)
    joints : names of the joint values given, in their order (each a movable joint of ``robot``; the
        joints on the chain from ``base`` to the sensor must be among them; the others are held at 0)
    base : fixed base frame (default as :meth:`RobotModel.base_frame`), gravity along its −z
    g : gravity magnitude, m/s²
    degrees : joint values are in degrees
    """

    def __init__(self, robot: RobotModel, sensor: str, joints: Sequence[str], *, base: str | None = None,
                 g: float = 9.81, degrees: bool = False, source: str = "joints") -> None:
        import idyntree.swig as idyn

        self.idyn, self.robot, self.joints, self.g, self.degrees = idyn, robot, tuple(joints), float(g), degrees
        self.base = base
        ft = robot.sensor(sensor)
        self.sensor = ft.name
        anchor, base_name = robot.base_frame(base)
        robot.joint_matrix(self.joints, np.zeros((1, len(self.joints))), source)  # unknown names: one line
        require_chain_joints(robot, self.joints, base_name, ft.name, source)
        index = {n: i for i, n in enumerate(robot.joint_names)}
        self._order = [index[n] for n in self.joints]
        self._q = np.zeros(len(robot.joint_names))
        link, link_H_sensor = _sensor_frame(robot, ft.name)
        model = robot.model
        self.kd = idyn.KinDynComputations()
        self.kd.loadRobotModel(model)
        self.kd.setFloatingBase(model.getLinkName(model.getFrameLink(anchor)))
        base_H_link = model.getFrameTransform(anchor).asHomogeneousTransform().toNumPy()
        self.kd.setWorldBaseTransform(idyn.Transform(np.linalg.inv(base_H_link)))
        self._frame = int(model.getFrameIndex(link))
        self._link_R_sensor = link_H_sensor[:3, :3]

    def with_joints(self, joints: Sequence[str], source: str = "joints") -> "SensorGravity":
        """The same robot, sensor, base and gravity over other joint names (e.g. a JointState message's)."""
        return SensorGravity(self.robot, self.sensor, joints, base=self.base, g=self.g, degrees=self.degrees,
                             source=source)

    def one(self, positions) -> tuple[float, float, float]:
        """Gravity (m/s², sensor axes) for one sample of joint positions (in the order of ``joints``)."""
        q = self._q
        values = np.asarray(positions, dtype=float)
        q[self._order] = np.deg2rad(values) if self.degrees else values
        if not self.kd.setJointPos(self.idyn.VectorDynSize.FromPython(q)):
            raise FtcalError("iDynTree could not set the joint positions.")
        rotation = self.kd.getWorldTransform(self._frame).getRotation().toNumPy() @ self._link_R_sensor
        # Third row of base_R_sensor is the base z axis in sensor axes.
        return tuple((-self.g * rotation[2]).tolist())

    def __call__(self, positions: np.ndarray) -> np.ndarray:
        """Gravity (n, 3), m/s², sensor axes, for joint positions of shape (n, len(joints))."""
        positions = np.asarray(positions, dtype=float)
        return np.array([self.one(row) for row in positions]).reshape(-1, 3)
