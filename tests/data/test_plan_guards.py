"""``ftcal plan`` refuses what it cannot plan for, bounds its work, and writes its outputs together (issue 28)."""

import numpy as np
import pandas as pd
import pytest

from ftcal.cli import main
from ftcal.plan import PlanRequest, design_experiment
from ftcal.robot import RobotModel, parse_payload_spec
from ftcal.runtime.errors import FtcalError
from ftcal.sim.plan_arm import ARM_URDF


@pytest.fixture(scope="module")
def arm(tmp_path_factory):
    path = tmp_path_factory.mktemp("plan") / "arm.urdf"
    path.write_text(ARM_URDF)
    return path


def plan(capsys, arm, *extra):
    code = main(["plan", "--urdf", str(arm), "--poses", "8", "--candidates", "200", *map(str, extra)])
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def test_a_load_upstream_of_the_sensor_is_refused(capsys, tmp_path, arm):
    """The arm's wrist sensor carries only the hand (and the tool frame on it): a load on the forearm is not felt."""
    robot = RobotModel.load(urdf=arm)
    assert "forearm" not in robot.links_beyond(robot.ft_sensors[0])
    code, _, err = plan(capsys, arm, "--load", "forearm:2@0,0,0.05", "-o", tmp_path / "p.csv")
    assert code == 2 and "forearm" in err and "base side" in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "p.csv").exists()
    code, _, err = plan(capsys, arm, "--load", "tool:2@0,0,0.05", "-o", tmp_path / "p.csv")
    assert code == 0, err


@pytest.mark.parametrize("spec", ["tool:1e7", "tool:1@0,0,1e5"])
def test_absurd_loads_are_refused(capsys, tmp_path, arm, spec):
    code, _, err = plan(capsys, arm, "--load", spec, "-o", tmp_path / "p.csv")
    assert code == 2 and len(err.strip().splitlines()) == 1 and not (tmp_path / "p.csv").exists()


def test_a_design_beyond_the_work_limit_is_refused_before_any_work():
    """Degree 10 over the 6 wrench axes: C(16, 6) = 8008 parameters; 8008³ alone is 5·10¹¹ operations."""
    robot = RobotModel.from_text(ARM_URDF)
    with pytest.raises(FtcalError, match="8008 parameters"):
        design_experiment(robot, PlanRequest((None,), 10, degree=10, n_candidates=100))


def test_a_recorded_table_with_absurd_wrenches_is_refused(capsys, tmp_path, arm):
    frame = pd.DataFrame(np.full((5, 6), 1e90), columns=["Fx", "Fy", "Fz", "Tx", "Ty", "Tz"])
    frame.to_csv(tmp_path / "rec.csv", index=False)
    code, _, err = plan(capsys, arm, "--from", tmp_path / "rec.csv", "-o", tmp_path / "p.csv")
    assert code == 2 and "rec.csv" in err and not (tmp_path / "p.csv").exists()


def test_a_failing_page_leaves_the_previous_plan_untouched(capsys, tmp_path, arm):
    out = tmp_path / "p.csv"
    out.write_text("the previous plan\n")
    (tmp_path / "page.html").mkdir()  # the page cannot be written: a folder is in the way
    code, _, err = plan(capsys, arm, "--html", tmp_path / "page.html", "-o", out)
    assert code == 2 and len(err.strip().splitlines()) == 1
    assert out.read_text() == "the previous plan\n"


def test_joints_a_turn_beyond_their_limits_are_refused():
    robot = RobotModel.from_text(ARM_URDF)
    name = robot.joint_names[0]
    m = robot.model
    high = m.getJoint(m.getJointIndex(name)).getMaxPosLimit(0)
    with pytest.raises(FtcalError, match="degrees"):
        robot.joint_matrix([name], np.array([[high + 7.0]]), "t.csv")  # 7 rad > 2π beyond the limit
    assert robot.joint_matrix([name], np.array([[high + 0.5]]), "t.csv").shape == (1, len(robot.joint_names))


def test_a_recorded_table_without_a_joint_on_the_chain_to_the_sensor_is_refused(capsys, tmp_path, arm):
    """A recorded pose table's missing shoulder would be held at 0 rad, turning gravity in the sensor frame."""
    robot = RobotModel.load(urdf=arm)
    given = robot.joint_names[1:]  # every joint but the first (shoulder_pitch, on the chain to the wrist sensor)
    pd.DataFrame(np.zeros((4, len(given))), columns=given).to_csv(tmp_path / "rec.csv", index=False)
    code, _, err = plan(capsys, arm, "--from", tmp_path / "rec.csv", "-o", tmp_path / "p.csv")
    assert code == 2 and len(err.strip().splitlines()) == 1 and not (tmp_path / "p.csv").exists()
    assert f"no data for joint(s) {robot.joint_names[0]!r}" in err and "rec.csv" in err
