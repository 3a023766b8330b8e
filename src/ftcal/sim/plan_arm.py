"""The simulated arm of ``ftcal demo --scenario plan``: four joints, a wrist F/T sensor, a hand.

Shoulder and elbow pitch, wrist roll (about the forearm) and wrist pitch: the roll
joint lets the wrist point gravity along every sensor axis, so both the calibration
and the payload identification are identifiable. The sensor sits between the wrist
and the hand (0.6 kg); loads are mounted on the ``tool`` flange 8 cm beyond it.
"""

from __future__ import annotations

HAND_MASS = 0.6  # kg, beyond the sensor
HAND_COM = (0.01, 0.0, 0.045)  # m, sensor frame
TOOL_OFFSET = (0.0, 0.0, 0.08)  # m, the tool flange in the sensor frame (same axes)
BASE_FRAME, SENSOR = "base_link", "wrist_ft"

ARM_URDF = """<?xml version="1.0"?>
<robot name="plan_arm">
  <link name="base_link">
    <inertial><origin xyz="0 0 0.1"/><mass value="8.0"/>
      <inertia ixx="0.1" ixy="0" ixz="0" iyy="0.1" iyz="0" izz="0.1"/></inertial>
  </link>
  <link name="upper_arm">
    <inertial><origin xyz="0 0 0.17"/><mass value="2.0"/>
      <inertia ixx="0.02" ixy="0" ixz="0" iyy="0.02" iyz="0" izz="0.004"/></inertial>
  </link>
  <link name="forearm">
    <inertial><origin xyz="0 0 0.15"/><mass value="1.2"/>
      <inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.002"/></inertial>
  </link>
  <link name="wrist">
    <inertial><origin xyz="0 0 0.01"/><mass value="0.4"/>
      <inertia ixx="0.001" ixy="0" ixz="0" iyy="0.001" iyz="0" izz="0.001"/></inertial>
  </link>
  <link name="wrist_pitch_link">
    <inertial><origin xyz="0 0 0.02"/><mass value="0.3"/>
      <inertia ixx="0.0005" ixy="0" ixz="0" iyy="0.0005" iyz="0" izz="0.0005"/></inertial>
  </link>
  <link name="hand">
    <inertial><origin xyz="{hand_com}"/><mass value="{hand_mass}"/>
      <inertia ixx="0.001" ixy="0" ixz="0" iyy="0.001" iyz="0" izz="0.0008"/></inertial>
  </link>
  <link name="tool"/>
  <joint name="shoulder_pitch" type="revolute">
    <parent link="base_link"/><child link="upper_arm"/><origin xyz="0 0 0.4" rpy="0 0 0"/><axis xyz="0 1 0"/>
    <limit lower="-2.0" upper="2.0" effort="50" velocity="1"/>
  </joint>
  <joint name="elbow_pitch" type="revolute">
    <parent link="upper_arm"/><child link="forearm"/><origin xyz="0 0 0.35" rpy="0 0 0"/><axis xyz="0 1 0"/>
    <limit lower="-2.5" upper="2.5" effort="30" velocity="1"/>
  </joint>
  <joint name="wrist_roll" type="revolute">
    <parent link="forearm"/><child link="wrist"/><origin xyz="0 0 0.3" rpy="0 0 0"/><axis xyz="0 0 1"/>
    <limit lower="-3.1" upper="3.1" effort="10" velocity="1"/>
  </joint>
  <joint name="wrist_pitch" type="revolute">
    <parent link="wrist"/><child link="wrist_pitch_link"/><origin xyz="0 0 0.03" rpy="0 0 0"/><axis xyz="0 1 0"/>
    <limit lower="-2.0" upper="2.0" effort="10" velocity="1"/>
  </joint>
  <joint name="wrist_ft_sensor" type="fixed">
    <parent link="wrist_pitch_link"/><child link="hand"/><origin xyz="0 0 0.04" rpy="0 0 0"/>
  </joint>
  <joint name="tool_flange" type="fixed">
    <parent link="hand"/><child link="tool"/><origin xyz="{tool}" rpy="0 0 0"/>
  </joint>
  <sensor name="wrist_ft" type="force_torque">
    <parent joint="wrist_ft_sensor"/>
    <force_torque><frame>sensor</frame><measure_direction>child_to_parent</measure_direction></force_torque>
    <origin rpy="0 0 0" xyz="0 0 0"/>
  </sensor>
</robot>
""".format(hand_com=" ".join(map(str, HAND_COM)), hand_mass=HAND_MASS, tool=" ".join(map(str, TOOL_OFFSET)))
