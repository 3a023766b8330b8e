"""A robot model: URDF text, the iDynTree model and its six-axis F/T sensors.

Load a URDF from any path or an iCub by name (via the ``icub-models``
package); attach payloads in memory; look F/T sensors up by sensor name
(``r_arm_ft``) or joint name (``r_arm_ft_sensor``); find the links (and mass)
on the far side of a sensor as seen from the base frame. Sensors come from
iDynTree sensor tags, Gazebo force_torque tags, or declarations on fixed
joints (:mod:`ftcal.robot.declare`).

Joint positions handed to iDynTree follow :attr:`RobotModel.joint_names`: the
one-degree-of-freedom joints of the URDF, in iDynTree's DOF order.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from ..core.limits import MAX_TEXT_FILE_BYTES
from ..runtime.errors import FtcalError, ParameterError
from ..runtime.inputs import check_input_file
from ._quiet import captured_stderr
from .declare import SensorDeclaration, no_sensor_hint, prepare_urdf
from .payloads import Payload
from .urdf_checks import check_urdf

DEFAULT_BASE = "root_link"


@dataclass(frozen=True)
class FTSensor:
    """One six-axis F/T sensor of the model.

    ``index`` is its position among iDynTree's SIX_AXIS_FORCE_TORQUE sensors;
    ``parent_link`` is the link on which the measured wrench is applied and
    ``child_link`` the link that applies it (URDF ``child_to_parent``).
    """

    name: str
    joint: str
    parent_link: str
    child_link: str
    index: int

    def matches(self, name: str) -> bool:
        """True for the sensor name or joint name, with or without a ``_sensor`` suffix."""
        stem = name.removesuffix("_sensor")
        return stem in (self.name.removesuffix("_sensor"), self.joint.removesuffix("_sensor"))


class RobotModel:
    """An iDynTree model with its sensors, built from URDF text.

    Use :meth:`load` (path or iCub name) or :meth:`from_text`. Instances are
    immutable in spirit: :meth:`with_payloads` returns a new model.

    F/T sensors come from iDynTree sensor elements, Gazebo force_torque tags
    and ``declared`` sensors on fixed joints (:mod:`ftcal.robot.declare`).
    ``urdf_text``, ``payloads`` and ``declared`` together describe the model:
    worker processes rebuild it from them.
    """

    def __init__(self, urdf_text: str, source: str, payloads: Sequence[Payload] = (),
                 declared: Sequence[SensorDeclaration] = ()) -> None:
        import idyntree.swig as idyn

        self.urdf_text = urdf_text
        self.source = source
        self.payloads = tuple(payloads)
        self.declared = tuple(declared)
        check_urdf(urdf_text, source)
        loader = idyn.ModelLoader()
        parsed_text = prepare_urdf(urdf_text, source, self.declared)
        with captured_stderr() as chatter:
            ok = loader.loadModelFromString(parsed_text)
        # iDynTree can report success with an empty model after its own errors (e.g. an unsupported element).
        if not ok or loader.model().getNrOfLinks() == 0:
            detail = next((line for line in chatter if "ERROR" in line), chatter[0] if chatter else "")
            raise FtcalError(f"URDF {source} does not parse"
                             + (f": {detail.replace('[ERROR] ', '')}" if detail else "."))
        # Copies: the loader owns what model() and sensors() return, and it dies with this scope.
        self.model = idyn.Model(loader.model())
        self.sensors = idyn.SensorsList(loader.sensors())
        for payload in self.payloads:
            _attach(self.model, payload, source)
        self.joint_names = _dof_joint_names(self.model)
        self.ft_sensors = _ft_sensors(self.model, self.sensors)

    @classmethod
    def from_text(cls, urdf_text: str, source: str = "<string>",
                  declared: Sequence[SensorDeclaration] = ()) -> "RobotModel":
        return cls(urdf_text, source, declared=declared)

    @classmethod
    def load(cls, urdf: str | Path | None = None, name: str | None = None,
             declared: Sequence[SensorDeclaration] = ()) -> "RobotModel":
        """Load from a URDF path, or an iCub model by name (``icub-models``), with ``declared`` F/T sensors."""
        if (urdf is None) == (name is None):
            raise ParameterError(('urdf', 'robot'), "Give exactly one of a URDF path ({urdf}) or a robot model name ({robot}).")
        path = Path(urdf) if urdf is not None else icub_model_path(str(name))
        check_input_file(path, "URDF", max_bytes=MAX_TEXT_FILE_BYTES)
        try:
            text = path.read_text(encoding="utf-8")
        except FileNotFoundError:
            raise FtcalError(f"URDF {path}: no such file.") from None
        except (OSError, UnicodeDecodeError) as exc:
            raise FtcalError(f"URDF {path}: cannot read it ({exc}).") from None
        return cls(text, str(path), declared=declared)

    def with_payloads(self, payloads: Sequence[Payload]) -> "RobotModel":
        """A new model with ``payloads`` added to the ones already attached (declared sensors kept)."""
        return RobotModel(self.urdf_text, self.source, (*self.payloads, *payloads), self.declared)

    def require_ft_sensors(self) -> None:
        """Raise FtcalError, naming the fixed joints to declare one on, if the model has no F/T sensor."""
        if not self.ft_sensors:
            raise ParameterError(("ft_joint", "ft_frame"),
                                 f"URDF {self.source} has no six-axis F/T sensor; {no_sensor_hint(self.urdf_text)}.")

    def sensor(self, name: str) -> FTSensor:
        """The F/T sensor called ``name`` (sensor or joint name)."""
        self.require_ft_sensors()
        found = [s for s in self.ft_sensors if s.matches(name)]
        if len(found) != 1:
            known = ", ".join(s.name for s in self.ft_sensors) or "none"
            what = "no" if not found else "more than one"
            raise FtcalError(f"URDF {self.source} has {what} F/T sensor matching {name!r}; "
                             f"its F/T sensors are: {known}.")
        return found[0]

    def base_frame(self, name: str | None = None) -> tuple[int, str]:
        """Index and name of the base frame: ``name``, else ``root_link`` if present, else the default base link."""
        if name is None:
            name = DEFAULT_BASE if self.model.isFrameNameUsed(DEFAULT_BASE) else \
                self.model.getLinkName(self.model.getDefaultBaseLink())
        if not self.model.isFrameNameUsed(name):
            raise FtcalError(f"URDF {self.source} has no link or frame named {name!r} (base frame).")
        return int(self.model.getFrameIndex(name)), name

    def links_beyond(self, sensor: FTSensor, base: str | None = None) -> tuple[str, ...]:
        """Links on the far side of the sensor's joint, seen from the base frame."""
        m = self.model
        base_link = m.getFrameLink(self.base_frame(base)[0])
        cut = m.getJointIndex(sensor.joint)
        neighbours: dict[int, list[int]] = {i: [] for i in range(m.getNrOfLinks())}
        for j in range(m.getNrOfJoints()):
            if j == cut:
                continue
            joint = m.getJoint(j)
            a, b = joint.getFirstAttachedLink(), joint.getSecondAttachedLink()
            neighbours[a].append(b)
            neighbours[b].append(a)
        reached = {base_link}
        queue = deque([base_link])
        while queue:
            for nxt in neighbours[queue.popleft()]:
                if nxt not in reached:
                    reached.add(nxt)
                    queue.append(nxt)
        return tuple(m.getLinkName(i) for i in range(m.getNrOfLinks()) if i not in reached)

    def joints_beyond(self, sensor: FTSensor, base: str | None = None) -> tuple[str, ...]:
        """The movable joints between two :meth:`links_beyond`: they move the mass the sensor carries."""
        m = self.model
        beyond = set(self.links_beyond(sensor, base))
        movable = set(self.joint_names)
        names = []
        for j in range(m.getNrOfJoints()):
            joint = m.getJoint(j)
            links = (m.getLinkName(joint.getFirstAttachedLink()), m.getLinkName(joint.getSecondAttachedLink()))
            if m.getJointName(j) in movable and all(link in beyond for link in links):
                names.append(m.getJointName(j))
        return tuple(names)

    def mass_beyond(self, sensor: FTSensor, base: str | None = None) -> float:
        """Total mass (kg, payloads included) of :meth:`links_beyond`."""
        m = self.model
        return float(sum(m.getLink(m.getLinkIndex(n)).getInertia().getMass()
                         for n in self.links_beyond(sensor, base)))

    def chain_joints(self, frame_a: str, frame_b: str) -> tuple[str, ...]:
        """The movable joints on the kinematic path between two frames (links or additional frames).

        The rotation between the two frames depends on these joints only: a table that lacks one of
        them cannot give the gravity direction in one frame from the other.
        """
        import idyntree.swig as idyn

        model = self.model
        links = [int(model.getFrameLink(model.getFrameIndex(f))) for f in (frame_a, frame_b)]
        traversal = idyn.Traversal()
        model.computeFullTreeTraversal(traversal, links[0])  # rooted at frame_a's link
        found = []
        link = links[1]
        while link != links[0]:
            joint = traversal.getParentJointFromLinkIndex(link)
            if joint is None:
                break
            if joint.getNrOfDOFs() > 0:
                found.append(model.getJointName(joint.getIndex()))
            link = traversal.getParentLinkFromLinkIndex(link).getIndex()
        movable = set(self.joint_names)
        return tuple(name for name in reversed(found) if name in movable)

    def joint_matrix(self, names: Sequence[str], values, where: str):
        """Place columns named ``names`` into the model's joint order; joints not given are 0.

        Callers whose result depends on a joint check it is given first
        (:func:`ftcal.robot.kinematics.require_chain_joints`, :func:`ftcal.robot.kinematics.require_wrench_joints`).

        values : array of shape (n_samples, len(names)); returns (n_samples, n_dofs).
        ``where`` names the source in error messages (file and stream).
        """
        import numpy as np

        index = {n: i for i, n in enumerate(self.joint_names)}
        unknown = [n for n in names if n not in index]
        if unknown:
            raise FtcalError(f"{where}: joint(s) {', '.join(map(repr, unknown[:5]))} not in URDF {self.source} "
                             f"(it has {len(self.joint_names)} movable joints, e.g. "
                             f"{', '.join(self.joint_names[:4])}).")
        if len(set(names)) != len(names):
            raise FtcalError(f"{where}: a joint name appears more than once.")
        values = np.asarray(values, dtype=np.float64)
        self.check_joint_limits(names, values, where)
        out = np.zeros((values.shape[0], len(self.joint_names)))
        out[:, [index[n] for n in names]] = values
        return out

    def check_joint_limits(self, names: Sequence[str], values, where: str) -> None:
        """Refuse joint values more than a full turn beyond their URDF limits (degrees read as radians, or
        another robot's log); values just beyond them are kept (encoders and simulators overshoot).

        values : array of shape (n_samples, len(names)), rad (m for prismatic joints).
        """
        import numpy as np

        from ..core.limits import JOINT_LIMIT_SLACK

        m = self.model
        for k, name in enumerate(names):
            joint = m.getJoint(m.getJointIndex(name))
            if not joint.hasPosLimits() or values.shape[0] == 0:
                continue
            low, high = float(joint.getMinPosLimit(0)), float(joint.getMaxPosLimit(0))
            column = values[:, k]
            beyond = np.maximum(low - column, column - high)
            j = int(np.argmax(beyond))
            if beyond[j] > JOINT_LIMIT_SLACK:
                raise ParameterError('degrees', f"{where}: joint {name!r} holds {column[j]:g}, {beyond[j]:g} beyond its URDF limits "
                                 f"[{low:g}, {high:g}] (radians expected: are the joints in degrees? give "
                                 "{degrees}).")

    def total_mass(self) -> float:
        m = self.model
        return float(sum(m.getLink(i).getInertia().getMass() for i in range(m.getNrOfLinks())))


def icub_model_path(name: str) -> Path:
    """The URDF of an iCub model shipped by ``icub-models``."""
    import icub_models

    try:
        return Path(icub_models.get_model_file(name))
    except FileNotFoundError:
        known = ", ".join(sorted(icub_models.get_robot_names()))
        raise ParameterError('robot', f"Unknown robot model {name!r} ({{robot}}); icub-models has: {known}.") from None


def _dof_joint_names(model) -> tuple[str, ...]:
    names = [""] * model.getNrOfDOFs()
    for j in range(model.getNrOfJoints()):
        joint = model.getJoint(j)
        if joint.getNrOfDOFs() == 1:
            names[joint.getDOFsOffset()] = model.getJointName(j)
    return tuple(names)


def _ft_sensors(model, sensors) -> tuple[FTSensor, ...]:
    import idyntree.swig as idyn

    found = []
    for i in range(sensors.getNrOfSensors(idyn.SIX_AXIS_FORCE_TORQUE)):
        ft = sensors.getSixAxisForceTorqueSensor(i)
        applied = ft.getAppliedWrenchLink()
        first, second = ft.getFirstLinkIndex(), ft.getSecondLinkIndex()
        other = second if applied == first else first
        found.append(FTSensor(ft.getName(), ft.getParentJoint(), model.getLinkName(applied),
                              model.getLinkName(other), i))
    return tuple(found)


def _attach(model, payload: Payload, source: str) -> None:
    """Add the payload's spatial inertia to the link that carries its frame."""
    import idyntree.swig as idyn
    import numpy as np

    if not model.isFrameNameUsed(payload.frame):
        raise FtcalError(f"Payload {payload.name or payload.frame!r}: URDF {source} has no link or frame "
                         f"named {payload.frame!r}.")
    frame = model.getFrameIndex(payload.frame)
    link_H_frame = model.getFrameTransform(frame).asHomogeneousTransform().toNumPy()
    rotation, origin = link_H_frame[:3, :3], link_H_frame[:3, 3]
    ixx, iyy, izz, ixy, ixz, iyz = payload.inertia
    inertia_frame = np.array([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]])
    # Move the payload into link coordinates: COM by the frame pose, inertia by rotation only
    # (it stays about the COM, so no parallel-axis term here; iDynTree adds it when combining).
    com_link = rotation @ np.asarray(payload.com) + origin
    inertia_link = rotation @ inertia_frame @ rotation.T
    added = idyn.SpatialInertia()
    added.fromRotationalInertiaWrtCenterOfMass(payload.mass, idyn.Position(*com_link),
                                               idyn.RotationalInertia(inertia_link))
    link = model.getLink(model.getFrameLink(frame))
    link.setInertia(link.getInertia() + added)
