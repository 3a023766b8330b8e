"""``ftcal simulate`` refuses a session too large for memory in one line, before it makes any folder.

Truth: a one-pose plan holds for exactly ``--hold`` seconds (no moves), so it has floor(hold × rate) + 1
F/T samples, by hand; the limit is the declared one.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from ftcal.cli import main
from ftcal.core.limits import MAX_SIMULATED_SAMPLES
from ftcal.runtime.errors import FtcalError
from ftcal.sim.plan_arm import ARM_URDF


@pytest.fixture
def arm(tmp_path):
    urdf = tmp_path / "arm.urdf"
    urdf.write_text(ARM_URDF)
    return urdf


def test_a_billion_hertz_is_one_line_and_leaves_no_folder(tmp_path, arm, capsys):
    from ftcal.robot.model import RobotModel

    plan = tmp_path / "plan.csv"
    joints = RobotModel.load(arm).joint_names
    pd.DataFrame([[0.0] * len(joints), [0.4] * len(joints)], columns=joints).to_csv(plan, index=False)
    out = tmp_path / "sim"
    code = main(["simulate", str(plan), "--urdf", str(arm), "--rate", "1e9", "--format", "table", "-o", str(out)])
    err = capsys.readouterr().err.strip()
    assert code == 2 and len(err.splitlines()) == 1 and "Traceback" not in err
    assert "rate 1e+09 Hz" in err and f"{MAX_SIMULATED_SAMPLES:,}" in err
    assert not out.exists()  # before: an empty folder, after trying to allocate 77 GiB


def test_the_limit_counts_the_samples_of_the_session(arm):
    from ftcal.robot.model import RobotModel
    from ftcal.sim.robot_recording import SimulationConfig, Waypoints, check_session_size

    robot = RobotModel.load(arm)
    one_pose = Waypoints(np.zeros((1, len(robot.joint_names))), np.zeros(1, dtype=int))
    hold = 1.0
    # floor(hold × rate) + 1 samples: MAX_SIMULATED_SAMPLES exactly at rate MAX − 1, one more at rate MAX
    assert check_session_size(robot, one_pose, SimulationConfig(hold_s=hold, rate=MAX_SIMULATED_SAMPLES - 1.0)) \
        == MAX_SIMULATED_SAMPLES
    with pytest.raises(FtcalError, match="more than the 2,000,000"):
        check_session_size(robot, one_pose, SimulationConfig(hold_s=hold, rate=float(MAX_SIMULATED_SAMPLES)))


@pytest.mark.parametrize("hold, rate", [("0.2", "1"), ("0.2", "1e-320"), ("1e-320", "50"), ("0.2", "9")])
def test_a_hold_without_two_samples_is_one_line_and_leaves_no_folder(tmp_path, arm, capsys, hold, rate):
    """A hold's bias in truth.json is the mean over its samples: a hold × rate below 2 (0.2 s × 9 Hz = 1.8)
    was a traceback (NaN refused by the JSON writer) after the folder was made."""
    from ftcal.robot.model import RobotModel

    plan = tmp_path / "plan.csv"
    joints = RobotModel.load(arm).joint_names
    pd.DataFrame([[0.0] * len(joints), [0.4] * len(joints)], columns=joints).to_csv(plan, index=False)
    out = tmp_path / "sim"
    code = main(["simulate", str(plan), "--urdf", str(arm), "--hold", hold, "--rate", rate, "--format", "table",
                 "-o", str(out)])
    err = capsys.readouterr().err.strip()
    assert code == 2 and len(err.splitlines()) == 1 and "Traceback" not in err and "fewer than 2" in err, err
    assert not out.exists()


def test_a_hold_of_two_samples_runs(tmp_path, arm):
    from ftcal.robot.model import RobotModel

    plan = tmp_path / "plan.csv"
    joints = RobotModel.load(arm).joint_names
    pd.DataFrame([[0.0] * len(joints), [0.4] * len(joints)], columns=joints).to_csv(plan, index=False)
    assert main(["simulate", str(plan), "--urdf", str(arm), "--hold", "0.2", "--rate", "10", "--format", "table",
                 "-o", str(tmp_path / "sim")]) == 0
    assert (tmp_path / "sim" / "truth.json").exists()
