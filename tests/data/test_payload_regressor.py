"""The payload regressors against iDynTree (random kinematic states) and hand statics."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from ftcal.payload.regressor import (
    DYNAMIC_PARAMETERS,
    STATIC_PARAMETERS,
    dynamic_regressor,
    inertia_about_com,
    inertia_matrix,
    inertial_regressor,
    skew,
    static_regressor,
)

G = 9.81
# A tool hanging from a fixed F/T joint; sensor, mount and tool frames coincide (identity joint origin),
# the tool's inertial frame is offset and rotated so that every inertial parameter is non-zero.
MASS = 1.7
COM = np.array([0.03, -0.02, 0.08])
RPY = (0.3, -0.2, 0.5)
IXX, IXY, IXZ, IYY, IYZ, IZZ = 0.012, 0.001, -0.002, 0.018, 0.0015, 0.009
ONE_LINK_URDF = f"""<?xml version="1.0"?>
<robot name="one_link">
  <link name="mount">
    <inertial><origin xyz="0 0 0"/><mass value="0.4"/>
      <inertia ixx="0.001" ixy="0" ixz="0" iyy="0.001" iyz="0" izz="0.001"/></inertial>
  </link>
  <link name="tool">
    <inertial><origin xyz="{COM[0]} {COM[1]} {COM[2]}" rpy="{RPY[0]} {RPY[1]} {RPY[2]}"/><mass value="{MASS}"/>
      <inertia ixx="{IXX}" ixy="{IXY}" ixz="{IXZ}" iyy="{IYY}" iyz="{IYZ}" izz="{IZZ}"/></inertial>
  </link>
  <joint name="ft_joint" type="fixed">
    <parent link="mount"/><child link="tool"/><origin xyz="0 0 0" rpy="0 0 0"/>
  </joint>
  <sensor name="ft" type="force_torque">
    <parent joint="ft_joint"/>
    <force_torque><frame>sensor</frame><measure_direction>child_to_parent</measure_direction></force_torque>
    <origin rpy="0 0 0" xyz="0 0 0"/>
  </sensor>
</robot>
"""


def urdf_parameters():
    """π = [m, m c, I about the origin] from the URDF's inertial block, by the parallel-axis theorem."""
    rot = Rotation.from_euler("xyz", RPY).as_matrix()  # URDF rpy: fixed-axis roll, pitch, yaw
    inertia_com = rot @ inertia_matrix([IXX, IXY, IXZ, IYY, IYZ, IZZ]) @ rot.T
    inertia_origin = inertia_com + MASS * (COM @ COM * np.eye(3) - np.outer(COM, COM))
    i = inertia_origin
    return np.r_[MASS, MASS * COM, i[0, 0], i[0, 1], i[0, 2], i[1, 1], i[1, 2], i[2, 2]]


def idyntree_measurements(path, proper_acc, omega, alpha):
    """The F/T reading iDynTree predicts with the mount as floating base, state by state."""
    import idyntree.swig as idyn

    est = idyn.ExtWrenchesAndJointTorquesEstimator()
    assert est.loadModelAndSensorsFromFile(str(path))
    model, sensors = est.model(), est.sensors()
    frame = model.getFrameIndex("mount")
    unknowns = idyn.LinkUnknownWrenchContacts(model)
    unknowns.addNewUnknownFullWrenchInFrameOrigin(model, frame)
    meas, contacts = idyn.SensorsMeasurements(sensors), idyn.LinkContactWrenches(model)
    tau = idyn.JointDOFsDoubleArray(model)
    q = idyn.JointPosDoubleArray(model)
    dq = idyn.JointDOFsDoubleArray(model)
    q.zero()
    dq.zero()
    wrench = idyn.Wrench()
    out = np.zeros((len(proper_acc), 6))
    for k in range(len(proper_acc)):
        assert est.updateKinematicsFromFloatingBase(
            q, dq, dq, frame, idyn.Vector3.FromPython(proper_acc[k]),
            idyn.Vector3.FromPython(omega[k]), idyn.Vector3.FromPython(alpha[k]))
        assert est.computeExpectedFTSensorsMeasurements(unknowns, meas, contacts, tau)
        meas.getMeasurement(idyn.SIX_AXIS_FORCE_TORQUE, 0, wrench)
        out[k] = wrench.toNumPy()
    return out


def test_inertial_regressor_matches_idyntree(tmp_path):
    path = tmp_path / "one_link.urdf"
    path.write_text(ONE_LINK_URDF)
    rng = np.random.default_rng(7)
    n = 40
    proper_acc = rng.normal(0.0, 6.0, (n, 3))
    omega = rng.normal(0.0, 2.0, (n, 3))
    alpha = rng.normal(0.0, 5.0, (n, 3))
    want = idyntree_measurements(path, proper_acc, omega, alpha)
    got = inertial_regressor(proper_acc, omega, alpha) @ urdf_parameters()
    np.testing.assert_allclose(got, want, rtol=1e-10, atol=1e-10)


def test_inertial_regressor_at_rest_is_weight():
    g = Rotation.random(5, random_state=1).apply([0.0, 0.0, -G])
    got = inertial_regressor(-g) @ urdf_parameters()
    np.testing.assert_allclose(got[:, :3], MASS * g, atol=1e-12)
    np.testing.assert_allclose(got[:, 3:], np.cross(COM, MASS * g), atol=1e-12)


def test_static_regressor_hand_statics():
    # sensor z up: g = (0, 0, -g); 2 kg at (0.1, 0, 0): F = (0, 0, -2g), T = c × F = (0, 0.2g, 0)
    bias = np.array([1.0, -2.0, 3.0, 0.1, -0.2, 0.3])
    theta = np.r_[2.0, 2.0 * 0.1, 0.0, 0.0, bias]
    got = static_regressor(np.array([[0.0, 0.0, -G]]))[0] @ theta
    np.testing.assert_allclose(got, np.r_[0.0, 0.0, -2 * G, 0.0, 0.2 * G, 0.0] + bias, atol=1e-12)
    assert len(STATIC_PARAMETERS) == 10


def test_static_regressor_is_inertial_at_rest_plus_bias():
    g = Rotation.random(6, random_state=2).apply([0.0, 0.0, -G])
    y = static_regressor(g)
    np.testing.assert_allclose(y[:, :, :4], inertial_regressor(-g)[:, :, :4], atol=0.0)
    np.testing.assert_array_equal(y[:, :, 4:], np.broadcast_to(np.eye(6), (6, 6, 6)))
    dyn = dynamic_regressor(-g, np.zeros((6, 3)), np.zeros((6, 3)))
    assert dyn.shape == (6, 6, len(DYNAMIC_PARAMETERS))
    np.testing.assert_array_equal(dyn[:, :, 10:], y[:, :, 4:])


def test_skew_is_cross_product():
    rng = np.random.default_rng(0)
    v, w = rng.normal(size=(4, 3)), rng.normal(size=(4, 3))
    np.testing.assert_allclose(np.einsum("nij,nj->ni", skew(v), w), np.cross(v, w), atol=1e-15)


def test_inertia_about_com_undoes_parallel_axis():
    p = urdf_parameters()
    rot = Rotation.from_euler("xyz", RPY).as_matrix()
    want = rot @ inertia_matrix([IXX, IXY, IXZ, IYY, IYZ, IZZ]) @ rot.T
    got = inertia_about_com(MASS, COM, inertia_matrix(p[4:]))
    np.testing.assert_allclose(got, want, atol=1e-15)


@pytest.mark.parametrize("shape", [(3,), (1, 3)])
def test_single_sample_shapes(shape):
    assert inertial_regressor(np.ones(shape)).shape == (1, 6, 10)
    assert static_regressor(np.ones(shape)).shape == (1, 6, 10)
