"""ROS payload exports, parsed back with PyYAML (a YAML 1.1 reader, like rosparam).

Field names, from the packages' own repositories:
- kth-ros-pkg/force_torque_tools: ``force_torque_sensor_calib/src/ft_calib_node.cpp`` (saveCalibData)
  sets ``/ft_calib/bias``, ``gripper_mass``, ``gripper_com_frame_id``, ``gripper_com_child_frame_id``
  and ``gripper_com_pose`` (x, y, z, roll, pitch, yaw), dumped with ``rosparam dump``;
  ``gravity_compensation/config/ft_calib_data_example.yaml`` is such a file.
- tpoignonec/ft_tools_ros2: ``ft_tools/config/calibration.yaml`` and ``FtParameters::from_yaml`` in
  ``ft_tools/src/ft_parameters.cpp`` read ``mass``, ``sensor_frame_to_com``, ``force_offset``,
  ``torque_offset`` (3-vectors).
"""

import numpy as np
import pytest

from ftcal.files.ros_yaml import write_ft_tools_ros2, write_ros_yaml
from ftcal.payload.parameters import PayloadParameters
from ftcal.runtime.errors import FtcalError

yaml = pytest.importorskip("yaml")

PAYLOAD = PayloadParameters(mass=1.6954823452240575, com=np.array([0.0023920647465803537, 1e-05, 0.0791345548713843]),
                            force_bias=np.array([0.33, -11.6, 4.4]), torque_bias=np.array([-0.24, -0.33, -1e-07]),
                            gravity=9.81, frame="/left_arm_ft_sensor")


def test_force_torque_tools_ft_calib(tmp_path):
    path = write_ros_yaml(PAYLOAD, tmp_path / "ft_calib.yaml", com_frame="gripper_com")
    doc = yaml.safe_load(path.read_text())
    assert set(doc) == {"bias", "gripper_mass", "gripper_com_frame_id", "gripper_com_child_frame_id",
                        "gripper_com_pose"}
    assert doc["bias"] == [0.33, -11.6, 4.4, -0.24, -0.33, -1e-07]  # 1e-07 parsed as a float, not a string
    assert doc["gripper_mass"] == 1.6954823452240575
    assert doc["gripper_com_frame_id"] == "/left_arm_ft_sensor"
    assert doc["gripper_com_child_frame_id"] == "gripper_com"
    assert doc["gripper_com_pose"] == [0.0023920647465803537, 1e-05, 0.0791345548713843, 0.0, 0.0, 0.0]


def test_gravity_compensation_formula_on_the_export_zeroes_the_load(tmp_path):
    # gravity_compensation.cpp: zeroed = raw − bias; weight = mass · g; torque = r × weight; out = zeroed − wrench.
    doc = yaml.safe_load(write_ros_yaml(PAYLOAD, tmp_path / "f.yaml").read_text())
    g = np.array([3.0, -4.0, -8.0]) * 9.81 / np.linalg.norm([3.0, -4.0, -8.0])
    raw = np.r_[PAYLOAD.mass * g, np.cross(PAYLOAD.com, PAYLOAD.mass * g)] + PAYLOAD.bias
    weight = doc["gripper_mass"] * g
    out = raw - np.array(doc["bias"]) - np.r_[weight, np.cross(doc["gripper_com_pose"][:3], weight)]
    np.testing.assert_allclose(out, 0.0, atol=1e-12)


def test_ft_tools_ros2_calibration(tmp_path):
    doc = yaml.safe_load(write_ft_tools_ros2(PAYLOAD, tmp_path / "calibration.yaml").read_text())
    assert set(doc) == {"mass", "sensor_frame_to_com", "force_offset", "torque_offset"}
    assert doc["mass"] == PAYLOAD.mass
    assert doc["sensor_frame_to_com"] == PAYLOAD.com.tolist()
    assert doc["force_offset"] == PAYLOAD.force_bias.tolist()
    assert doc["torque_offset"] == PAYLOAD.torque_bias.tolist()


def test_reaction_payloads(tmp_path):
    reaction = PayloadParameters(PAYLOAD.mass, PAYLOAD.com, PAYLOAD.force_bias, PAYLOAD.torque_bias, 9.81,
                                 "ft", reaction=True)
    doc = yaml.safe_load(write_ros_yaml(reaction, tmp_path / "r.yaml").read_text())
    assert doc["bias"] == (-PAYLOAD.bias).tolist()  # in the sign of the sensor's own readings
    with pytest.raises(FtcalError, match="ft_tools_ros2 expects the sensor to read"):
        write_ft_tools_ros2(reaction, tmp_path / "c.yaml")
    assert not (tmp_path / "c.yaml").exists()


def test_ft_calib_needs_a_frame(tmp_path):
    nameless = PayloadParameters(1.0, np.zeros(3), np.zeros(3), np.zeros(3), 9.81)
    with pytest.raises(FtcalError, match="needs the sensor frame name"):
        write_ros_yaml(nameless, tmp_path / "f.yaml")
    write_ros_yaml(nameless, tmp_path / "f.yaml", frame="tool0")
    assert yaml.safe_load((tmp_path / "f.yaml").read_text())["gripper_com_frame_id"] == "tool0"
