"""F/T sensors on plain URDFs: declared by joint, or from Gazebo tags; checked on real public models.

References: forward kinematics composed by hand from the URDF joint origins with scipy's
rotations (UR5), iDynTree's KinDynComputations (Panda), iDynTree's own sensor-tag parser
(iCub), and the statics of a point mass: F = m g_s, T = c × m g_s.
"""

import re
import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import ftcal.robot.expected as expected_module
from ftcal.robot import Payload, RobotModel, SensorDeclaration
from ftcal.robot.expected import FloatingBase, expected_wrenches
from ftcal.runtime.errors import FtcalError

ROBOTS = Path(sys.prefix) / "lib" / f"python{sys.version_info.major}.{sys.version_info.minor}" / \
    "site-packages" / "cmeel.prefix" / "share" / "example-robot-data" / "robots"
UR5 = ROBOTS / "ur_description" / "urdf" / "ur5_robot.urdf"
PANDA = ROBOTS / "panda_description" / "urdf" / "panda.urdf"
G_BASE = np.array([0.0, 0.0, -9.81])
FTCAL = str(Path(sys.executable).with_name("ftcal"))

pytestmark = pytest.mark.skipif(not UR5.is_file(), reason="example-robot-data is not installed")


def ur5_chain_rotation(q, to_link):
    """base_link_R_<to_link> for the UR5, composed from the URDF's joint origins and axes by hand."""
    root = ET.parse(UR5).getroot()
    by_child = {j.find("child").get("link"): j for j in root.findall("joint")}
    chain = []
    link = to_link
    while link != "base_link":
        joint = by_child[link]
        chain.append(joint)
        link = joint.find("parent").get("link")
    names = ["shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint", "wrist_1_joint", "wrist_2_joint",
             "wrist_3_joint"]
    rotation, position = np.eye(3), np.zeros(3)
    for joint in reversed(chain):
        origin = joint.find("origin")
        rpy = [float(v) for v in origin.get("rpy", "0 0 0").split()]
        xyz = [float(v) for v in origin.get("xyz", "0 0 0").split()]
        position = position + rotation @ np.array(xyz)
        rotation = rotation @ Rotation.from_euler("xyz", rpy).as_matrix()  # URDF rpy: fixed axes x, y, z
        if joint.get("type") != "fixed":
            axis = np.array([float(v) for v in joint.find("axis").get("xyz").split()])
            rotation = rotation @ Rotation.from_rotvec(axis * q[names.index(joint.get("name"))]).as_matrix()
    return rotation, position


POSES = np.array([[0.0] * 6, [0.3, -1.2, 1.1, -0.4, 1.3, 0.7], [-2.0, 0.5, -1.9, 2.2, -0.6, 3.0]])


def test_ur5_declared_on_massless_end_effector_joint():
    # iDynTree alone would turn the massless ee_link into a frame and drop ee_fixed_joint.
    robot = RobotModel.load(UR5, declared=[SensorDeclaration("ee_fixed_joint")])
    (sensor,) = robot.ft_sensors
    assert (sensor.name, sensor.parent_link, sensor.child_link) == ("ee_fixed_joint", "wrist_3_link", "ee_link")
    mass, com = 1.7, np.array([0.02, -0.01, 0.12])
    loaded = robot.with_payloads([Payload("ee_link", mass, tuple(com))])
    w = expected_wrenches(loaded, POSES, base="base_link", workers=1)[:, 0]
    for k, q in enumerate(POSES):
        rotation, _ = ur5_chain_rotation(q, "ee_link")
        g_sensor = rotation.T @ G_BASE
        np.testing.assert_allclose(w[k, :3], mass * g_sensor, atol=1e-9)
        np.testing.assert_allclose(w[k, 3:], np.cross(com, mass * g_sensor), atol=1e-9)


def test_ur5_sensor_frame_on_another_link():
    # Sensor frame = tool0 (rigidly on wrist_3_link); payload at com in ee_link coordinates.
    robot = RobotModel.load(UR5, declared=[SensorDeclaration("ee_fixed_joint", "tool0")])
    mass, com_ee = 2.3, np.array([0.05, 0.0, 0.1])
    w = expected_wrenches(robot.with_payloads([Payload("ee_link", mass, tuple(com_ee))]), POSES,
                          base="base_link", workers=1)[:, 0]
    for k, q in enumerate(POSES):
        r_ee, p_ee = ur5_chain_rotation(q, "ee_link")
        r_tool, p_tool = ur5_chain_rotation(q, "tool0")
        com_tool = r_tool.T @ (p_ee + r_ee @ com_ee - p_tool)
        g_sensor = r_tool.T @ G_BASE
        np.testing.assert_allclose(w[k, :3], mass * g_sensor, atol=1e-9)
        np.testing.assert_allclose(w[k, 3:], np.cross(com_tool, mass * g_sensor), atol=1e-9)


def test_panda_hand_sensor_against_kindyn_forward_kinematics():
    import idyntree.swig as idyn

    robot = RobotModel.load(PANDA, declared=[SensorDeclaration("panda_hand_joint")])
    mass, com = 0.9, np.array([0.0, 0.03, 0.08])
    rng = np.random.default_rng(3)
    q = rng.uniform(-1.5, 1.5, (4, len(robot.joint_names)))
    q[:, -2:] = 0.02  # fingers
    bare = expected_wrenches(robot, q, workers=1)[:, 0]
    loaded = expected_wrenches(robot.with_payloads([Payload("panda_hand", mass, tuple(com))]), q, workers=1)[:, 0]
    loader = idyn.ModelLoader()
    assert loader.loadModelFromFile(str(PANDA))
    kd = idyn.KinDynComputations()
    kd.loadRobotModel(loader.model())
    for k in range(len(q)):
        kd.setJointPos(idyn.VectorDynSize.FromPython(q[k]))
        rotation = kd.getRelativeTransform("panda_link0", "panda_hand").getRotation().toNumPy()
        g_sensor = rotation.T @ G_BASE
        np.testing.assert_allclose(loaded[k, :3] - bare[k, :3], mass * g_sensor, atol=1e-9)
        np.testing.assert_allclose(loaded[k, 3:] - bare[k, 3:], np.cross(com, mass * g_sensor), atol=1e-9)
    # The hand and its fingers (0.73 + 2 x 0.015 kg in the URDF) hang beyond the sensor.
    assert robot.mass_beyond(robot.ft_sensors[0]) == pytest.approx(0.76)


def icub_text():
    import icub_models

    return Path(icub_models.get_model_file("iCubGenova04")).read_text()


def without_idyntree_sensors(text):
    return re.sub(r'\n  <sensor name="[^"]*" type="force_torque">.*?</sensor>', "", text, flags=re.S)


def test_icub_gazebo_tags_give_the_native_sensors_under_a_floating_base():
    native = RobotModel(icub_text(), "native")
    gazebo = RobotModel(without_idyntree_sensors(icub_text()), "gazebo only")
    assert [(s.name, s.joint, s.parent_link, s.child_link) for s in gazebo.ft_sensors] == \
        [(s.name, s.joint, s.parent_link, s.child_link) for s in native.ft_sensors]
    rng = np.random.default_rng(4)
    n = len(native.joint_names)
    q, dq, ddq = rng.uniform(-0.4, 0.4, (3, n)), rng.normal(size=(3, n)), rng.normal(size=(3, n))
    imu = FloatingBase("root_link", rng.normal(size=(3, 3)) + [0, 0, 9.81], rng.normal(size=(3, 3)))
    np.testing.assert_allclose(expected_wrenches(gazebo, q, dq=dq, ddq=ddq, floating=imu, workers=1),
                               expected_wrenches(native, q, dq=dq, ddq=ddq, floating=imu, workers=1), atol=1e-12)


def test_icub_declared_by_joint_matches_native_sensor():
    text = re.sub(r'<gazebo reference="r_arm_ft_sensor">.*?</gazebo>', "", without_idyntree_sensors(icub_text()),
                  flags=re.S)
    declared = RobotModel(text, "declared", declared=[SensorDeclaration("r_arm_ft_sensor", name="r_arm_ft")])
    assert "r_arm_ft" in [s.name for s in declared.ft_sensors]
    native = RobotModel(icub_text(), "native")
    q = np.random.default_rng(5).uniform(-0.5, 0.5, (3, len(native.joint_names)))
    got = expected_wrenches(declared, q, workers=1)[:, declared.sensor("r_arm_ft").index]
    want = expected_wrenches(native, q, workers=1)[:, native.sensor("r_arm_ft").index]
    np.testing.assert_allclose(got, want, atol=1e-12)


def gazebo_ur5(direction):
    tag = (f'<gazebo reference="ee_fixed_joint"><sensor name="wrist_ft" type="force_torque"><force_torque>'
           f'<frame>child</frame><measure_direction>{direction}</measure_direction></force_torque></sensor>'
           f'</gazebo></robot>')
    return RobotModel(UR5.read_text().replace("</robot>", tag), f"ur5+{direction}")


def test_gazebo_measure_direction_sets_the_sign():
    payload = [Payload("ee_link", 1.0, (0.0, 0.0, 0.1))]
    child = expected_wrenches(gazebo_ur5("child_to_parent").with_payloads(payload), POSES, base="base_link",
                              workers=1)
    parent = expected_wrenches(gazebo_ur5("parent_to_child").with_payloads(payload), POSES, base="base_link",
                               workers=1)
    assert gazebo_ur5("child_to_parent").ft_sensors[0].name == "wrist_ft"
    np.testing.assert_allclose(parent, -child, atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(child[:, 0, :3], axis=1), 9.81, rtol=1e-9)


def test_declared_sensor_survives_worker_processes(monkeypatch):
    robot = RobotModel.load(UR5, declared=[SensorDeclaration("ee_fixed_joint", "tool0")])
    robot = robot.with_payloads([Payload("ee_link", 1.2, (0.01, 0.02, 0.05))])
    q = np.random.default_rng(6).uniform(-3, 3, (40, 6))
    serial = expected_wrenches(robot, q, workers=1)
    monkeypatch.setattr(expected_module, "PARALLEL_MIN_SAMPLES", 10)
    monkeypatch.setattr(expected_module, "CHUNK", 10)
    parallel = expected_wrenches(robot, q, workers=2)
    np.testing.assert_array_equal(parallel, serial)
    assert np.abs(serial).max() > 1.0


def test_no_sensor_lists_the_fixed_joints():
    robot = RobotModel.load(PANDA)
    with pytest.raises(FtcalError, match=r"ft_joint JOINT.*panda_joint8, panda_hand_joint, panda_hand_tcp_joint"):
        robot.sensor("anything")
    with pytest.raises(FtcalError, match="no six-axis F/T sensor"):
        expected_wrenches(robot, np.zeros((1, len(robot.joint_names))))


@pytest.mark.parametrize("declaration, message", [
    (SensorDeclaration("elbow_joint"), "is revolute, not fixed"),
    (SensorDeclaration("no_such_joint"), "no joint named 'no_such_joint'.*ee_fixed_joint"),
    (SensorDeclaration("ee_fixed_joint", "forearm_link"), "not rigidly attached"),
    (SensorDeclaration("ee_fixed_joint", "nowhere"), "no link named 'nowhere'"),
])
def test_bad_declarations(declaration, message):
    with pytest.raises(FtcalError, match=message):
        RobotModel.load(UR5, declared=[declaration])


def run_cli(*args):
    return subprocess.run([FTCAL, *args], capture_output=True, text=True)


def test_cli_sensors_with_declared_joint():
    done = run_cli("sensors", "--urdf", str(UR5), "--ft-joint", "ee_fixed_joint", "--payload", "ee_link:2.0")
    assert done.returncode == 0, done.stderr
    line = next(row for row in done.stdout.splitlines() if row.strip().startswith("ee_fixed_joint"))
    assert line.split()[-1] == "2.0000"  # 2 kg payload + 1e-12 kg kept-link mass


def test_cli_without_sensor_says_how_to_declare_one(tmp_path):
    (tmp_path / "q.csv").write_text("panda_joint1\n0.1\n")
    done = run_cli("expected", "--urdf", str(PANDA), "--joints", str(tmp_path / "q.csv"), "-o", str(tmp_path / "o.csv"))
    assert done.returncode == 2
    assert len(done.stderr.strip().splitlines()) == 1
    assert "--ft-joint" in done.stderr and "panda_hand_joint" in done.stderr
    assert not (tmp_path / "o.csv").exists()
    done = run_cli("sensors", "--urdf", str(PANDA), "--ft-frame", "panda_hand")
    assert done.returncode == 2 and "--ft-frame needs --ft-joint" in done.stderr


def test_cli_expected_with_declared_sensor(tmp_path):
    import pandas as pd

    q = POSES[1]
    pd.DataFrame([dict(zip(["shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint", "wrist_1_joint",
                            "wrist_2_joint", "wrist_3_joint"], q))]).to_csv(tmp_path / "q.csv", index=False)
    done = run_cli("expected", "--urdf", str(UR5), "--ft-joint", "ee_fixed_joint", "--base", "base_link",
                   "--payload", "ee_link:3.0", "--joints", str(tmp_path / "q.csv"), "-o", str(tmp_path / "w.csv"))
    assert done.returncode == 0, done.stderr
    out = pd.read_csv(tmp_path / "w.csv")
    rotation, _ = ur5_chain_rotation(q, "ee_link")
    force = out[[f"ee_fixed_joint_{a}" for a in ("Fx", "Fy", "Fz")]].to_numpy()[0]
    np.testing.assert_allclose(force, 3.0 * rotation.T @ G_BASE, atol=1e-6)


SLIDER_ARM = """<robot name="slider">
  <link name="base"><inertial><mass value="1"/><inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <link name="slider"><inertial><mass value="1"/><inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <link name="hand"><inertial><mass value="1.5"/><inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <joint name="glide" type="{kind}"><parent link="base"/><child link="slider"/><axis xyz="0 0 1"/>
    <limit lower="-1" upper="1" effort="10" velocity="1"/></joint>
  <joint name="wrist_ft" type="fixed"><parent link="slider"/><child link="hand"/><origin xyz="0 0 -0.3"/></joint>
</robot>"""


@pytest.mark.parametrize("kind, way", [("planar", "two prismatic joints and a revolute one"),
                                       ("floating", "so that 'slider' is the root link")])
def test_a_planar_or_floating_joint_is_named_not_taken_for_a_missing_sensor(tmp_path, kind, way):
    # Before: iDynTree dropped the whole model, and --ft-joint wrist_ft got "has no six-axis F/T sensor".
    urdf = tmp_path / f"{kind}.urdf"
    urdf.write_text(SLIDER_ARM.format(kind=kind))
    done = run_cli("sensors", "--urdf", str(urdf), "--ft-joint", "wrist_ft")
    assert done.returncode == 2 and len(done.stderr.strip().splitlines()) == 1
    assert f"joint 'glide' (from link 'base' to 'slider') has type '{kind}'" in done.stderr and way in done.stderr
    assert "no six-axis F/T sensor" not in done.stderr
    # the same chain with a joint iDynTree models has the declared sensor
    assert RobotModel.from_text(SLIDER_ARM.format(kind="prismatic"), declared=[SensorDeclaration("wrist_ft")]) \
        .sensor("wrist_ft").child_link == "hand"
