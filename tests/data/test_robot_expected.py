"""Expected F/T wrenches against hand-computed physics and a direct iDynTree loop."""

import numpy as np
import pytest
from test_robot_model import FOREARM_MASS, TINY_URDF

from ftcal.robot import FloatingBase, Payload, RobotModel, expected_wrenches
from ftcal.robot import expected as expected_module
from ftcal.runtime.errors import FtcalError

G = 9.81


@pytest.fixture
def tiny():
    return RobotModel.from_text(TINY_URDF, "tiny.urdf")


def gravity_in_sensor(theta):
    """(0, 0, -g) of the base, in the sensor frame after rotating the shoulder by theta about x."""
    return np.array([0.0, -G * np.sin(theta), -G * np.cos(theta)])


def static_wrench(bodies, theta):
    """Σ m g and Σ c × m g over (mass, com in sensor frame) — the weight hanging beyond the sensor."""
    g = gravity_in_sensor(theta)
    force = sum(m * g for m, _ in bodies)
    torque = sum(np.cross(c, m * g) for m, c in bodies)
    return np.r_[force, torque]


FOREARM = (FOREARM_MASS, np.array([0.2, 0.0, 0.0]))


@pytest.mark.parametrize("theta", [0.0, 0.5, -1.2, 2.0])
def test_static_forearm_weight(tiny, theta):
    w = expected_wrenches(tiny, np.array([[theta]]))[0, 0]
    np.testing.assert_allclose(w, static_wrench([FOREARM], theta), atol=1e-9)
    assert np.linalg.norm(w[:3]) == pytest.approx(FOREARM_MASS * G)


def test_point_mass_payload_on_rotated_frame(tiny):
    # 2 kg at (0.1, 0, 0) of "tool"; tool sits at (0.3, 0, 0) of the forearm turned 90° about z,
    # so the mass is at (0.3, 0.1, 0) in the sensor (= forearm) frame.
    loaded = tiny.with_payloads([Payload("tool", 2.0, (0.1, 0.0, 0.0))])
    thetas = np.array([[0.0], [0.7]])
    w = expected_wrenches(loaded, thetas)[:, 0]
    for k, theta in enumerate(thetas[:, 0]):
        want = static_wrench([FOREARM, (2.0, np.array([0.3, 0.1, 0.0]))], theta)
        np.testing.assert_allclose(w[k], want, atol=1e-9)
    # at theta = 0 by hand: T = (0.1·(-2g), 0.2·1.5g + 0.3·2g, 0)
    np.testing.assert_allclose(w[0, 3:], [-0.2 * G, 0.9 * G, 0.0], atol=1e-9)


def test_spinning_shoulder_with_inertial_payload(tiny):
    # Shoulder turning at w about x through q = 0. Every point beyond the sensor sits 0.1 m
    # below the axis, so it accelerates by w² · 0.1 upwards (centripetal). The payload's
    # inertia, given in the tool axes (90° about z from the forearm), adds the gyroscopic
    # torque w × I w. Measured (child on parent) = -(parent on child).
    w = 2.0
    ixx, iyy, izz, ixy, ixz, iyz = 0.01, 0.02, 0.03, 0.004, 0.005, 0.0
    inertia_tool = np.array([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]])
    rz = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    inertia = rz @ inertia_tool @ rz.T
    loaded = tiny.with_payloads([Payload("tool", 2.0, (0.0, 0.0, 0.0), (ixx, iyy, izz, ixy, ixz, iyz))])
    got = expected_wrenches(loaded, np.zeros((1, 1)), dq=np.array([[w]]))[0, 0]
    g_minus_a = np.array([0.0, 0.0, -G - 0.1 * w**2])
    omega = np.array([w, 0.0, 0.0])
    bodies = [FOREARM, (2.0, np.array([0.3, 0.0, 0.0]))]
    force = sum(m * g_minus_a for m, _ in bodies)
    torque = sum(np.cross(c, m * g_minus_a) for m, c in bodies) - np.cross(omega, inertia @ omega)
    np.testing.assert_allclose(got, np.r_[force, torque], atol=1e-9)


def test_icub_arm_force_norm_is_weight_beyond_sensor():
    robot = RobotModel.load(name="iCubGenova04").with_payloads([Payload("r_hand", 3.0, (0.0, 0.05, 0.0))])
    sensor = robot.sensor("r_arm_ft_sensor")
    mass = robot.mass_beyond(sensor)
    q = np.random.default_rng(3).uniform(-1.0, 1.0, (50, len(robot.joint_names)))
    w = expected_wrenches(robot, q)[:, sensor.index]
    np.testing.assert_allclose(np.linalg.norm(w[:, :3], axis=1), mass * G, rtol=1e-9)
    # gravity of any direction in the base frame gives the same norm
    w = expected_wrenches(robot, q[:5], gravity=(3.0, -4.0, 0.0))[:, sensor.index]
    np.testing.assert_allclose(np.linalg.norm(w[:, :3], axis=1), mass * 5.0, rtol=1e-9)


def direct_idyntree(urdf_path, q, base):
    """A plain per-sample iDynTree loop, written independently of ftcal's predictor."""
    import idyntree.swig as idyn

    est = idyn.ExtWrenchesAndJointTorquesEstimator()
    assert est.loadModelAndSensorsFromFile(str(urdf_path))
    model, sensors = est.model(), est.sensors()
    n_ft = sensors.getNrOfSensors(idyn.SIX_AXIS_FORCE_TORQUE)
    names = [sensors.getSensor(idyn.SIX_AXIS_FORCE_TORQUE, i).getName() for i in range(n_ft)]
    base_index = model.getFrameIndex(base)
    unknowns = idyn.LinkUnknownWrenchContacts(model)
    unknowns.addNewUnknownFullWrenchInFrameOrigin(model, base_index)
    meas, contacts = idyn.SensorsMeasurements(sensors), idyn.LinkContactWrenches(model)
    tau = idyn.JointDOFsDoubleArray(model)
    zero = idyn.JointDOFsDoubleArray(model)
    zero.zero()
    gravity = idyn.Vector3()
    gravity.zero()
    gravity.setVal(2, -G)
    out = np.zeros((len(q), n_ft, 6))
    wrench = idyn.Wrench()
    for k, row in enumerate(q):
        qj = idyn.JointPosDoubleArray(model)
        for j, v in enumerate(row):
            qj.setVal(j, float(v))
        assert est.updateKinematicsFromFixedBase(qj, zero, zero, base_index, gravity)
        assert est.computeExpectedFTSensorsMeasurements(unknowns, meas, contacts, tau)
        for i in range(n_ft):
            meas.getMeasurement(idyn.SIX_AXIS_FORCE_TORQUE, i, wrench)
            out[k, i] = wrench.toNumPy()
    return names, out


def test_parallel_path_matches_direct_loop(monkeypatch):
    from ftcal.robot.model import icub_model_path

    robot = RobotModel.load(name="iCubGenova04")
    q = np.random.default_rng(7).uniform(-1.5, 1.5, (400, len(robot.joint_names)))
    names, want = direct_idyntree(icub_model_path("iCubGenova04"), q, "root_link")
    # Force the worker-process path on a small input, in several chunks.
    monkeypatch.setattr(expected_module, "PARALLEL_MIN_SAMPLES", 100)
    monkeypatch.setattr(expected_module, "CHUNK", 150)
    got = expected_wrenches(robot, q, workers=2)
    assert [s.name for s in robot.ft_sensors] == names
    np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-12)


def test_floating_base_imu_at_rest_equals_fixed_base():
    robot = RobotModel.load(name="iCubGenova04")
    q = np.random.default_rng(11).uniform(-1.0, 1.0, (20, len(robot.joint_names)))
    # An accelerometer at rest reads the opposite of gravity: +9.81 up in the base frame.
    imu = FloatingBase("root_link", np.tile([0.0, 0.0, G], (20, 1)), np.zeros((20, 3)))
    np.testing.assert_allclose(expected_wrenches(robot, q, floating=imu), expected_wrenches(robot, q),
                               atol=1e-9)


def test_bad_joint_arrays(tiny):
    with pytest.raises(FtcalError, match=r"shape \(n_samples, 1\)"):
        expected_wrenches(tiny, np.zeros((3, 2)))
    with pytest.raises(FtcalError, match="non-finite value for joint 'shoulder' at sample 1"):
        expected_wrenches(tiny, np.array([[0.0], [np.nan]]))
    with pytest.raises(FtcalError, match="velocities have 2 samples"):
        expected_wrenches(tiny, np.zeros((3, 1)), dq=np.zeros((2, 1)))
    with pytest.raises(FtcalError, match="unknown_joint"):
        tiny.joint_matrix(["shoulder", "unknown_joint"], np.zeros((1, 2)), "joints.csv")
