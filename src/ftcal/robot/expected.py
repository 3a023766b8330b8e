"""Expected F/T sensor wrenches from joint data, with iDynTree.

For every sample, :class:`WrenchPredictor` hands the joint positions (and
optionally velocities, accelerations, floating-base IMU data) to iDynTree's
``ExtWrenchesAndJointTorquesEstimator`` and reads back
``computeExpectedFTSensorsMeasurements``: the wrench each F/T sensor should
measure if the only external wrench acts on the base frame (the robot is held
at its base, e.g. on a pole).

Output convention
-----------------
``(Fx, Fy, Fz, Tx, Ty, Tz)`` in N and N m is the wrench that the sensor's
child link (URDF ``child_to_parent``; :attr:`FTSensor.child_link`) applies on
its parent link (:attr:`FTSensor.parent_link`), expressed in the sensor frame,
torque about the sensor frame origin. With a static robot fixed at a base on
the parent side (the iCub arms and legs seen from ``root_link``), the force is
the weight of everything beyond the sensor: ``F = M · g`` with ``g`` the
gravity vector in sensor axes and ``M`` the mass beyond the sensor, and
``T = Σ m_i c_i × g`` with ``c_i`` the centres of mass relative to the sensor.
This is iDynTree's and Gazebo's ``child_to_parent`` measure direction, the one
of sensors declared with ``--ft-joint`` (:mod:`ftcal.robot.declare`) and the
ROS force_torque_tools convention; a Gazebo tag saying ``parent_to_child``
gets the opposite sign, as that simulated sensor reports.

Kinematics
----------
* fixed base (default): the base frame (default ``root_link``) does not
  accelerate; ``gravity`` is given in base-frame axes (default (0, 0, -9.81));
  joint velocities/accelerations are zero unless given (static assumption);
* floating base: per-sample proper acceleration (accelerometer reading, m/s²),
  angular velocity (gyroscope, rad/s) and optionally angular acceleration of
  an IMU frame, all in that frame's axes; gravity is then implied by the
  accelerometer.

Joint positions are radians (metres for prismatic joints), in the order of
:attr:`RobotModel.joint_names`.

Throughput: one estimator per process; large jobs are split across worker
processes (:func:`expected_wrenches`), each building its own estimator from the
URDF text and payloads.
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ..core.limits import ZERO_REFERENCE_WRENCH
from ..runtime.checks import check_int
from ..runtime.errors import FtcalError, FtcalWarning, ParameterWarning
from ..runtime.processes import WorkerProcesses
from ..runtime.progress import progress_bar
from .declare import SensorDeclaration
from .model import RobotModel
from .payloads import Payload

GRAVITY = (0.0, 0.0, -9.81)
# Below this many samples, starting worker processes costs more than it saves.
PARALLEL_MIN_SAMPLES = 20_000
CHUNK = 5_000


@dataclass(frozen=True)
class FloatingBase:
    """IMU data for floating-base kinematics (all in ``frame`` axes).

    proper_acceleration : ndarray of shape (n_samples, 3), m/s² (accelerometer)
    angular_velocity : ndarray of shape (n_samples, 3), rad/s (gyroscope)
    angular_acceleration : ndarray of shape (n_samples, 3), rad/s², or None (zero)
    """

    frame: str
    proper_acceleration: np.ndarray
    angular_velocity: np.ndarray
    angular_acceleration: np.ndarray | None = None

    def rows(self, start: int, stop: int) -> "FloatingBase":
        acc = None if self.angular_acceleration is None else self.angular_acceleration[start:stop]
        return FloatingBase(self.frame, self.proper_acceleration[start:stop],
                            self.angular_velocity[start:stop], acc)


class WrenchPredictor:
    """One iDynTree estimator, ready to predict all F/T sensors sample by sample."""

    def __init__(self, robot: RobotModel, base: str | None = None,
                 gravity: Sequence[float] = GRAVITY) -> None:
        import idyntree.swig as idyn

        self._idyn = idyn
        self.robot = robot
        model = robot.model
        self.n_dofs = model.getNrOfDOFs()
        self.n_sensors = len(robot.ft_sensors)
        robot.require_ft_sensors()
        # Only the F/T sensors: iDynTree would otherwise also predict every IMU of the model.
        only_ft = idyn.SensorsList()
        for s in robot.ft_sensors:
            only_ft.addSensor(robot.sensors.getSixAxisForceTorqueSensor(s.index))
        self.base_index, self.base = robot.base_frame(base)
        gravity = np.asarray(gravity, dtype=float)
        if gravity.shape != (3,) or not np.isfinite(gravity).all():
            raise FtcalError(f"gravity must be three finite numbers (m/s², base-frame axes); got {gravity.tolist()}.")
        self.estimator = idyn.ExtWrenchesAndJointTorquesEstimator()
        if not self.estimator.setModelAndSensors(model, only_ft):
            raise FtcalError(f"iDynTree could not set up the estimator for URDF {robot.source}.")
        self.gravity = idyn.Vector3.FromPython(np.asarray(gravity, dtype=float))
        self.unknowns = idyn.LinkUnknownWrenchContacts(model)
        self.unknowns.addNewUnknownFullWrenchInFrameOrigin(model, self.base_index)
        self.measurements = idyn.SensorsMeasurements(only_ft)
        self.contacts = idyn.LinkContactWrenches(model)
        self.torques = idyn.JointDOFsDoubleArray(model)
        self.zeros = idyn.VectorDynSize.FromPython(np.zeros(self.n_dofs))
        self.buffer = idyn.VectorDynSize(6 * self.n_sensors)

    def compute(self, q: np.ndarray, dq: np.ndarray | None = None, ddq: np.ndarray | None = None,
                floating: FloatingBase | None = None) -> np.ndarray:
        """Expected wrenches, ndarray of shape (n_samples, n_sensors, 6).

        q, dq, ddq : ndarray of shape (n_samples, n_dofs); dq/ddq None means zero.
        """
        idyn = self._idyn
        vec = idyn.VectorDynSize.FromPython
        est, g, zeros = self.estimator, self.gravity, self.zeros
        q = np.ascontiguousarray(q, dtype=np.float64)
        n = q.shape[0]
        out = np.empty((n, 6 * self.n_sensors))
        if floating is not None:
            frame = self.robot.model.getFrameIndex(floating.frame)
            zero3 = np.zeros(3)
        for k in range(n):
            qk = vec(q[k])
            dqk = zeros if dq is None else vec(dq[k])
            ddqk = zeros if ddq is None else vec(ddq[k])
            if floating is None:
                ok = est.updateKinematicsFromFixedBase(qk, dqk, ddqk, self.base_index, g)
            else:
                alpha = zero3 if floating.angular_acceleration is None else floating.angular_acceleration[k]
                ok = est.updateKinematicsFromFloatingBase(
                    qk, dqk, ddqk, frame, idyn.Vector3.FromPython(floating.proper_acceleration[k]),
                    idyn.Vector3.FromPython(floating.angular_velocity[k]), idyn.Vector3.FromPython(alpha))
            ok = ok and est.computeExpectedFTSensorsMeasurements(self.unknowns, self.measurements,
                                                                 self.contacts, self.torques)
            if not ok:
                raise FtcalError(f"iDynTree failed to compute the expected F/T wrenches at sample {k}.")
            self.measurements.toVector(self.buffer)
            out[k] = self.buffer.toNumPy()
        return out.reshape(n, self.n_sensors, 6)


def expected_wrenches(robot: RobotModel, q: np.ndarray, *, dq: np.ndarray | None = None,
                      ddq: np.ndarray | None = None, floating: FloatingBase | None = None,
                      base: str | None = None, gravity: Sequence[float] = GRAVITY,
                      workers: int = 2, description: str = "expected wrenches") -> np.ndarray:
    """Expected wrenches of all F/T sensors, ndarray of shape (n_samples, n_sensors, 6).

    Sensors are in the order of ``robot.ft_sensors``. ``q``/``dq``/``ddq`` are
    ndarrays of shape (n_samples, n_dofs) in the order of ``robot.joint_names``.
    Inputs of ``PARALLEL_MIN_SAMPLES`` or more are split across ``workers``
    processes (started with ``spawn``: a script that calls this at its top level without the usual
    ``if __name__ == "__main__":`` guard gets the work done in its own process, with a warning saying
    so, :func:`ftcal.runtime.processes.spawn_reruns_main`); a progress bar shows the samples done.
    """
    workers = check_int(workers, "workers", "expected_wrenches", 1, 64)
    q = check_joints(robot, q, "joint positions")
    dq = None if dq is None else check_joints(robot, dq, "joint velocities", q.shape[0])
    ddq = None if ddq is None else check_joints(robot, ddq, "joint accelerations", q.shape[0])
    if floating is not None and not robot.model.isFrameNameUsed(floating.frame):
        raise FtcalError(f"URDF {robot.source} has no frame named {floating.frame!r} (IMU frame).")
    n = q.shape[0]
    bounds = [(a, min(a + CHUNK, n)) for a in range(0, n, CHUNK)]
    predictor = WrenchPredictor(robot, base, gravity)  # also validates base and sensors up front
    out = np.empty((n, predictor.n_sensors, 6))

    def job(a: int, b: int) -> tuple:
        return (q[a:b], None if dq is None else dq[a:b], None if ddq is None else ddq[a:b],
                None if floating is None else floating.rows(a, b))

    with progress_bar(description, n) as advance:
        if workers <= 1 or n < PARALLEL_MIN_SAMPLES:
            for a, b in bounds:
                out[a:b] = predictor.compute(*job(a, b))
                advance(b - a)
            return out
        # Worker processes with a pipe each: a Ctrl-C, a signal or a worker's error kills them at once.
        init = (robot.urdf_text, robot.source, robot.payloads, robot.declared, predictor.base, tuple(gravity))
        with WorkerProcesses(workers, _init_worker, init) as processes:
            for (a, b), chunk in zip(bounds, processes.map(_work, (job(a, b) for a, b in bounds))):
                out[a:b] = chunk
                advance(b - a)
    return out


def warn_if_zero_reference(expected: np.ndarray, where: str, sensor: str, case: str) -> None:
    """Warn when the expected wrench of a whole recording is ~0: the fit would learn a sensor that reads zero.

    The robot model then has no mass beyond ``sensor`` and the load case ``case`` attaches none, which is
    almost always a forgotten payload (``--payload``, ``--payload-file``) or a sensor declared at the tip.
    """
    size = float(np.abs(expected).max(initial=0.0)) if expected.size else 0.0
    if size < ZERO_REFERENCE_WRENCH:
        warnings.warn(ParameterWarning(("payload", "payload_file"), f"{where}: the reference wrench is zero in every "
                                       f"sample (max |Fx..Tz| = {size:.2g}): nothing hangs beyond sensor {sensor!r} in "
                                       f"the robot model and load case {case!r} attaches no payload; a fit on it "
                                       "learns a sensor that reads zero. Give the load with {payload} or "
                                       "{payload_file}."), stacklevel=3)


def check_joints(robot: RobotModel, values: np.ndarray, what: str, n: int | None = None) -> np.ndarray:
    """``values`` as a float array of shape (n_samples, n_dofs), finite, with ``n`` rows if given."""
    arr = np.asarray(values, dtype=np.float64)
    if arr.ndim != 2 or arr.shape[1] != len(robot.joint_names):
        raise FtcalError(f"{what} must have shape (n_samples, {len(robot.joint_names)}) for URDF "
                         f"{robot.source}; got {arr.shape}.")
    if n is not None and arr.shape[0] != n:
        raise FtcalError(f"{what} have {arr.shape[0]} samples but joint positions have {n}.")
    bad = ~np.isfinite(arr)
    if bad.any():
        row, col = np.argwhere(bad)[0]
        raise FtcalError(f"{what}: non-finite value for joint {robot.joint_names[col]!r} at sample {row}.")
    return arr


_PREDICTOR: WrenchPredictor | None = None


def _init_worker(urdf_text: str, source: str, payloads: tuple[Payload, ...],
                 declared: tuple[SensorDeclaration, ...], base: str, gravity: tuple[float, float, float]) -> None:
    global _PREDICTOR
    _PREDICTOR = WrenchPredictor(RobotModel(urdf_text, source, payloads, declared), base, gravity)


def _work(job: tuple) -> np.ndarray:
    assert _PREDICTOR is not None
    return _PREDICTOR.compute(*job)
