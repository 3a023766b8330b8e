"""Robot models: loading, F/T sensor lookup, mass beyond a sensor, payloads, load cases."""

import warnings
import xml.etree.ElementTree as ET

import pytest

from ftcal.robot import LoadCaseConfig, Payload, RobotModel, load_case_config, parse_payload_spec
from ftcal.robot.model import icub_model_path
from ftcal.runtime.errors import FtcalError

# base --shoulder (revolute about x, 0.3 m up)--> upper --arm_ft_sensor (fixed, 0.1 m down)--> forearm
# forearm: 1.5 kg, COM 0.2 m along x of the sensor frame; "tool" is a massless frame on the forearm,
# 0.3 m along x and turned 90° about z.
TINY_URDF = """<?xml version="1.0"?>
<robot name="tiny">
  <link name="base">
    <inertial><origin xyz="0 0 0"/><mass value="5.0"/>
      <inertia ixx="0.1" ixy="0" ixz="0" iyy="0.1" iyz="0" izz="0.1"/></inertial>
  </link>
  <link name="upper">
    <inertial><origin xyz="0 0 0"/><mass value="0.5"/>
      <inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/></inertial>
  </link>
  <link name="forearm">
    <inertial><origin xyz="0.2 0 0"/><mass value="1.5"/>
      <inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/></inertial>
  </link>
  <link name="tool"/>
  <joint name="shoulder" type="revolute">
    <parent link="base"/><child link="upper"/><origin xyz="0 0 0.3" rpy="0 0 0"/><axis xyz="1 0 0"/>
    <limit lower="-3" upper="3" effort="10" velocity="1"/>
  </joint>
  <joint name="arm_ft_sensor" type="fixed">
    <parent link="upper"/><child link="forearm"/><origin xyz="0 0 -0.1" rpy="0 0 0"/>
  </joint>
  <joint name="tool_fixed" type="fixed">
    <parent link="forearm"/><child link="tool"/><origin xyz="0.3 0 0" rpy="0 0 1.5707963267948966"/>
  </joint>
  <sensor name="arm_ft" type="force_torque">
    <parent joint="arm_ft_sensor"/>
    <force_torque><frame>sensor</frame><measure_direction>child_to_parent</measure_direction></force_torque>
    <origin rpy="0 0 0" xyz="0 0 0"/>
  </sensor>
</robot>
"""
FOREARM_MASS = 1.5


@pytest.fixture
def tiny_urdf(tmp_path):
    path = tmp_path / "tiny.urdf"
    path.write_text(TINY_URDF)
    return path


@pytest.fixture
def tiny(tiny_urdf):
    return RobotModel.load(urdf=tiny_urdf)


def test_sensor_by_sensor_or_joint_name(tiny):
    assert tiny.sensor("arm_ft").joint == "arm_ft_sensor"
    assert tiny.sensor("arm_ft_sensor").name == "arm_ft"
    s = tiny.sensor("arm_ft")
    assert (s.parent_link, s.child_link) == ("upper", "forearm")
    with pytest.raises(FtcalError, match="no F/T sensor matching 'l_arm_ft'.*arm_ft"):
        tiny.sensor("l_arm_ft")


def test_joints_and_base(tiny):
    assert tiny.joint_names == ("shoulder",)
    assert tiny.base_frame() == (0, "base")  # no root_link: the URDF's base link
    with pytest.raises(FtcalError, match="no link or frame named 'root_link'"):
        tiny.base_frame("root_link")


def test_mass_beyond_with_payloads(tiny):
    s = tiny.sensor("arm_ft")
    assert tiny.links_beyond(s) == ("forearm",)
    assert tiny.mass_beyond(s) == pytest.approx(FOREARM_MASS)
    loaded = tiny.with_payloads([Payload("tool", 2.0), Payload("forearm", 0.25)])
    assert loaded.mass_beyond(s) == pytest.approx(FOREARM_MASS + 2.25)
    assert tiny.mass_beyond(s) == pytest.approx(FOREARM_MASS)  # the original is untouched
    # seen from the forearm, everything else is beyond the sensor
    assert tiny.mass_beyond(s, base="forearm") == pytest.approx(5.5)


def test_payload_on_unknown_frame(tiny):
    with pytest.raises(FtcalError, match="no link or frame named 'hand'"):
        tiny.with_payloads([Payload("hand", 1.0)])


def test_bad_urdfs(tmp_path):
    with pytest.raises(FtcalError, match="no such file"):
        RobotModel.load(urdf=tmp_path / "missing.urdf")
    broken = tmp_path / "broken.urdf"
    broken.write_text("<robot name='x'><link name='a'/><joint")
    with pytest.raises(FtcalError, match="broken.urdf does not parse"):
        RobotModel.load(urdf=broken)
    with pytest.raises(FtcalError, match="Unknown robot model 'nope'"):
        RobotModel.load(name="nope")
    with pytest.raises(FtcalError, match="exactly one"):
        RobotModel.load()


def _subtree_mass_from_xml(path, joint_name):
    """Mass of the links below ``joint_name`` in the URDF tree, from the XML alone."""
    root = ET.parse(path).getroot()
    mass = {link.get("name"): float(link.find("inertial/mass").get("value")) if link.find("inertial") is not None
            else 0.0 for link in root.findall("link")}
    children = {}
    for j in root.findall("joint"):
        children.setdefault(j.find("parent").get("link"), []).append(j.find("child").get("link"))
    start = next(j.find("child").get("link") for j in root.findall("joint") if j.get("name") == joint_name)
    total, stack = 0.0, [start]
    while stack:
        link = stack.pop()
        total += mass[link]
        stack.extend(children.get(link, []))
    return total


@pytest.mark.parametrize("sensor", ["r_arm_ft", "l_leg_ft"])
def test_icub_mass_beyond_matches_urdf_xml(sensor):
    path = icub_model_path("iCubGenova04")
    robot = RobotModel.load(name="iCubGenova04")
    s = robot.sensor(sensor)
    assert robot.mass_beyond(s) == pytest.approx(_subtree_mass_from_xml(path, s.joint), rel=1e-9)


def test_parse_payload_spec():
    p = parse_payload_spec("r_forearm:2.5@0.08,0,-0.01/1e-3,2e-3,3e-3")
    assert (p.frame, p.mass, p.com) == ("r_forearm", 2.5, (0.08, 0.0, -0.01))
    assert p.inertia == (1e-3, 2e-3, 3e-3, 0.0, 0.0, 0.0)
    assert parse_payload_spec("hand:1").com == (0.0, 0.0, 0.0)
    for bad, msg in [("hand", "must look like"), ("hand:-1", "mass must be"), ("hand:1@0,0", "must be 3 comma"),
                     ("hand:x", "MASS"), ("hand:1/1,2", "inertia")]:
        with pytest.raises(FtcalError, match=msg):
            parse_payload_spec(bad)


def test_load_cases_from_toml(tmp_path):
    toml = tmp_path / "loads.toml"
    toml.write_text("""
[[payload]]
frame = "forearm"
mass = 0.4

[[load]]
name = "heavy"
recordings = ["run7.mat"]
[[load.payload]]
frame = "tool"
mass = 5.0
com = [0.0, 0.0, 0.1]

[convention.right]
frame = "forearm"
com = [0.2, 0.0, 0.0]
""")
    config = load_case_config(toml)
    case = config.resolve(tmp_path / "x" / "run7.mat")
    assert case.name == "heavy" and [p.mass for p in case.payloads] == [0.4, 5.0]
    case = config.resolve(tmp_path / "heavy" / "a.mat")  # folder named after the case
    assert case.name == "heavy"
    case = config.resolve(tmp_path / "l0kg-r2.5kg" / "grid.mat")
    assert case.name == "l0kg-r2.5kg"
    assert [(p.frame, p.mass, p.com) for p in case.payloads] == [("forearm", 0.4, (0.0, 0.0, 0.0)),
                                                                ("forearm", 2.5, (0.2, 0.0, 0.0))]
    with pytest.raises(FtcalError, match=r"no \[convention.left\]"):
        config.resolve(tmp_path / "l1kg-r0kg" / "grid.mat")
    # issue 27: a recording the file's cases do not name is refused (no silent zero payload), nearest named
    with pytest.raises(FtcalError, match=r"matches no load case \(loads: 'heavy'.*nearest: 'heavy'"):
        config.resolve(tmp_path / "hevy" / "run8.mat")
    with pytest.raises(FtcalError, match=r"matches no load case.*nearest: 'run7.mat'"):
        config.resolve(tmp_path / "run8.mat")
    always = LoadCaseConfig(payloads=config.payloads)  # only [[payload]]: every recording, its own group
    plain = always.resolve(tmp_path / "other.mat", extra=(Payload("tool", 1.0),))
    assert plain.name == "other" and [p.mass for p in plain.payloads] == [0.4, 1.0]
    assert LoadCaseConfig().resolve("a/b.csv").name == "b"


def test_the_old_case_spelling_reads_the_same_load_cases_with_a_notice(tmp_path):
    """[[case]] / [[case.payload]] is the old spelling of [[load]] / [[load.payload]]."""
    body = '{key}]]\nname = "heavy"\nrecordings = ["run7.mat"]\n[[{key}.payload]]\nframe = "tool"\nmass = 5.0\n'
    new, old = tmp_path / "new.toml", tmp_path / "old.toml"
    new.write_text("[[" + body.format(key="load"))
    old.write_text("[[" + body.format(key="case"))
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # the new spelling: no notice
        expected = load_case_config(new).resolve(tmp_path / "run7.mat")
    with pytest.warns(FutureWarning, match=r"old.toml: \[\[case\]\] is now \[\[load\]\]"):
        case = load_case_config(old).resolve(tmp_path / "run7.mat")
    assert case == expected and case.name == "heavy" and [p.mass for p in case.payloads] == [5.0]
    both = tmp_path / "both.toml"
    both.write_text("[[" + body.format(key="load") + "[[" + body.format(key="case"))
    with pytest.raises(FtcalError, match=r"both.toml: both \[\[load\]\] and \[\[case\]\]"):
        load_case_config(both)


def test_load_case_file_errors(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text("[[payload]]\nframe = 'x'\nmass = 'heavy'\n")
    with pytest.raises(FtcalError, match="bad.toml: payload\\[0\\]"):
        load_case_config(bad)
    bad.write_text("[[payload]\n")
    with pytest.raises(FtcalError, match="cannot read it as TOML"):
        load_case_config(bad)
    bad.write_text("[weights]\nx = 1\n")
    with pytest.raises(FtcalError, match="unknown section"):
        load_case_config(bad)
