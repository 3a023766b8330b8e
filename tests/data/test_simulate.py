"""`ftcal simulate` on a robot that is not a demo's: plan → simulate → dataset → fit → payload → check (UR5).

Known truth: the simulation's own tool and sensor (truth.json); the UR5 from example-robot-data
with a sensor declared on its flange joint. Same seed → the same bytes.
"""

import filecmp
import json
import sys
import warnings
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from ftcal.cli import main
from ftcal.runtime.errors import IllPosedFitWarning

ROBOTS = Path(sys.prefix) / "lib" / f"python{sys.version_info.major}.{sys.version_info.minor}" / \
    "site-packages" / "cmeel.prefix" / "share" / "example-robot-data" / "robots"
UR5 = ROBOTS / "ur_description" / "urdf" / "ur5_robot.urdf"
ROBOT = ["--urdf", str(UR5), "--ft-joint", "ee_fixed_joint", "--base", "base_link"]
TOOL_MASS, TOOL_COM = 0.8, (0.01, 0.0, 0.05)
TOOL = f"ee_link:{TOOL_MASS}@{','.join(map(str, TOOL_COM))}"
LOAD = "ee_link:2.0@0,0.02,0.08"
LOAD2 = "ee_link:1.0@0.07,-0.03,0.02"  # another lever arm: torque varies apart from force
LOADS = ["--load", "none", "--load", LOAD, "--load", LOAD2]

pytestmark = [pytest.mark.skipif(not UR5.is_file(), reason="example-robot-data is not installed"),
              pytest.mark.slow]


@pytest.fixture(scope="module")
def session(tmp_path_factory):
    root = tmp_path_factory.mktemp("simulate")
    plan = root / "plan.csv"
    assert main(["plan", *ROBOT, *LOADS, "--poses", "9", "--candidates", "400",
                 "--seed", "1", "-o", str(plan)]) == 0
    # The planner may put every pose on one load; three blocks of poses, one per load, excite every
    # direction of the wrench (torque apart from force), which a calibration needs.
    table = pd.read_csv(plan)
    table["load"] = np.arange(len(table)) * 3 // len(table)
    table.to_csv(plan, index=False)
    for name in ("a", "b"):
        assert main(["simulate", str(plan), *ROBOT, "--payload", TOOL, *LOADS, "--speed", "0.6",
                     "--hold", "1.5", "--format", "both", "--seed", "7", "-o", str(root / name)]) == 0
    return root


def test_same_seed_gives_the_same_bytes(session):
    a, b = session / "a", session / "b"
    files = sorted(p.relative_to(a) for p in a.rglob("*") if p.is_file())
    assert any(f.suffix == ".mcap" for f in files) and any(f.suffix == ".parquet" for f in files)
    assert sorted(p.relative_to(b) for p in b.rglob("*") if p.is_file()) == files
    for f in files:
        assert filecmp.cmp(a / f, b / f, shallow=False), f


def test_truth_file_records_the_tool_loads_and_a_sensor_that_reproduces_the_channels(session):
    from ftcal.sim.robot_recording import read_truth

    truth, sensor = read_truth(session / "a" / "truth.json")
    assert truth["tool"] == [{"frame": "ee_link", "mass": TOOL_MASS, "com": list(TOOL_COM), "inertia": [0.0] * 6}]
    assert truth["loads"][0] is None and truth["loads"][1]["mass"] == 2.0
    np.testing.assert_allclose(np.array(truth["sensor"]["true_matrix"]), sensor.true_matrix, rtol=0, atol=0)
    # Every hold's samples are still: the joints of the table do not move inside a hold.
    rec = truth["recordings"][0]
    table = pd.read_parquet(session / "a" / f"{rec['name']}.parquet")
    joints = truth["robot"]["joints"]
    for start, end in rec["holds"]:
        inside = table[(table.time >= start) & (table.time <= end)]
        assert len(inside) > 100 and np.ptp(inside[joints].to_numpy(), axis=0).max() == 0.0


def test_motion_stays_within_the_urdf_limits(session):
    from ftcal.robot import RobotModel, SensorDeclaration
    from ftcal.sim.robot_recording import joint_bounds

    robot = RobotModel.load(UR5, declared=[SensorDeclaration("ee_fixed_joint")])
    position, velocity = joint_bounds(robot)
    for path in (session / "a").glob("*.parquet"):
        table = pd.read_parquet(path)
        q = table[list(robot.joint_names)].to_numpy()
        assert np.all(q >= position[:, 0]) and np.all(q <= position[:, 1])
        dq = table[[f"{n}.vel" for n in robot.joint_names]].to_numpy()
        assert np.all(np.abs(dq) <= 0.6 * velocity + 1e-9)  # --speed 0.6 of the URDF limits (3.15 rad/s)


def test_dataset_fit_payload_and_check_run_on_the_simulated_bags(session, tmp_path, capsys):
    out = session / "a"
    truth = json.loads((out / "truth.json").read_text())
    bags = [str(out / r["name"]) for r in truth["recordings"]]
    data = tmp_path / "data.parquet"
    assert main(["dataset", *bags, "--wrench-topic", "/ft_sensor/wrench", "--joints-topic", "/joint_states",
                 "--temperature-topic", "/ft_sensor/temperature", *ROBOT, "--sensor", "ee_fixed_joint",
                 "--payload", TOOL, "--payload-file", str(out / "loads.toml"), "--no-filter", "-o", str(data)]) == 0
    # The holds: the dataset's expected wrench is static, the simulated one has the moves' inertia too.
    table = pd.read_parquet(data)
    table = table[table["static"] == 1]
    assert table["hold"].nunique() >= 9
    table.to_parquet(data)
    u, f = table[[f"u{i}" for i in range(1, 7)]].to_numpy(), table[["Fx", "Fy", "Fz", "Tx", "Ty", "Tz"]].to_numpy()
    factory_error = np.sqrt(np.mean((u - f)[:, :3] ** 2))
    model = tmp_path / "affine.json"  # 9 poses: an affine model in u1..u6, T (the planner's degree-2 needs more)
    assert main(["fit", str(data), "--degree", "1", "-o", str(model)]) == 0
    metrics = json.loads(model.read_text())["fit"]["metrics"]
    fitted_error = np.sqrt(np.mean(np.square(_per_axis(metrics["rmse"])[:3])))
    # The in-situ fit sees bias, temperature and nonlinearity the factory matrix does not.
    assert fitted_error < 0.5 * factory_error

    # The tool: bias + mass + centre of mass from the recording without a load (joint columns + URDF).
    first = tmp_path / "first.parquet"
    assert main(["dataset", bags[0], "--wrench-topic", "/ft_sensor/wrench", "--joints-topic", "/joint_states",
                 "--no-filter", "-o", str(first)]) == 0
    payload = tmp_path / "payload.json"
    with warnings.catch_warnings():
        # simulate's bias drifts along the pose order of one recording: the payload's widened error may say that
        # the recording holds few independent pieces of evidence (a warning, which the test does not judge)
        warnings.filterwarnings("default", category=IllPosedFitWarning)
        assert main(["payload", str(first), *_robot_source(), "-o", str(payload)]) == 0
    fitted = json.loads(payload.read_text())
    found_mass = _field(fitted, "mass")
    assert abs(found_mass - TOOL_MASS) < 0.05 * TOOL_MASS
    np.testing.assert_allclose(_field(fitted, "com"), TOOL_COM, atol=0.01)
    capsys.readouterr()

    # No mounting mistake: check finds nothing to fix.
    code = main(["check", str(first), *_robot_source()])
    assert code == 0, capsys.readouterr().out


@pytest.mark.parametrize("mistake, finding", [("rotate-z:90", "rotation"), ("sign", "sign")])
def test_check_finds_the_mounting_mistake(session, tmp_path, capsys, mistake, finding):
    plan = session / "plan.csv"
    out = tmp_path / "sim"
    assert main(["simulate", str(plan), *ROBOT, "--payload", TOOL, *LOADS, "--hold", "1", "--speed", "0.6",
                 "--format", "table", "--mistake", mistake, "-o", str(out)]) == 0
    capsys.readouterr()
    table = sorted(out.glob("*-load0.parquet"))[0]
    wrench = ",".join(f"ee_fixed_joint_u{i}" for i in range(1, 7))
    assert main(["check", str(table), "--inputs", wrench, *_robot_source()]) == 1
    text = capsys.readouterr().out
    assert f"finding 1: {finding}" in text


def _robot_source():
    return ["--urdf", str(UR5), "--ft-joint", "ee_fixed_joint", "--base", "base_link"]


def _last_json(capsys):
    text = capsys.readouterr().out
    return text[text.index("{"):]


def _per_axis(values):
    return [values[k] for k in ("Fx", "Fy", "Fz", "Tx", "Ty", "Tz")] if isinstance(values, dict) else values


def _field(document, name):
    for key in ("parameters", "payload"):
        if isinstance(document.get(key), dict) and name in document[key]:
            value = document[key][name]
            return value["value"] if isinstance(value, dict) and "value" in value else value
    return document[name]


PENDULUM = """<?xml version="1.0"?>
<robot name="pendulum">
  <link name="base"><inertial><mass value="2.0"/><inertia ixx="0.1" ixy="0" ixz="0" iyy="0.1" iyz="0" izz="0.1"/>
  </inertial></link>
  <link name="arm"><inertial><origin xyz="0 0 -0.2"/><mass value="1.0"/>
    <inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.001"/></inertial></link>
  <link name="hand"><inertial><origin xyz="0.03 -0.02 -0.1"/><mass value="1.5"/>
    <inertia ixx="0.002" ixy="0" ixz="0" iyy="0.002" iyz="0" izz="0.002"/></inertial></link>
  <joint name="swing" type="revolute"><parent link="base"/><child link="arm"/><origin xyz="0 0 1.0"/>
    <axis xyz="0 1 0"/><limit lower="-2" upper="2" effort="10" velocity="2"/></joint>
  <joint name="wrist_fixed" type="fixed"><parent link="arm"/><child link="hand"/><origin xyz="0 0 -0.4"/></joint>
</robot>
"""


def test_raw_channels_of_a_linear_sensor_invert_to_the_statics_with_the_true_matrix(tmp_path):
    """A URDF written here: a 1.5 kg hand below a sensor, swung about y. With nonlinearity, drift, noise and
    temperature effects off, the true matrix maps the recorded counts (minus the zero offset) back to
    F = m g_s, T = c × m g_s, g_s = R_y(q)ᵀ (0, 0, −9.81), within half a count per channel."""
    from scipy.spatial.transform import Rotation

    from ftcal.sim.robot_recording import read_truth

    urdf = tmp_path / "pendulum.urdf"
    urdf.write_text(PENDULUM)
    plan = tmp_path / "poses.csv"
    angles = np.array([-1.5, -0.6, 0.0, 0.7, 1.6])
    pd.DataFrame({"swing": angles}).to_csv(plan, index=False)
    out = tmp_path / "sim"
    assert main(["simulate", str(plan), "--urdf", str(urdf), "--ft-joint", "wrist_fixed", "--channels", "raw",
                 "--format", "table", "--nonlinearity", "0", "--drift", "0,0", "--noise", "0",
                 "--temperature", "25,25", "--hold", "0.5", "-o", str(out)]) == 0
    truth, sensor = read_truth(out / "truth.json")
    table = pd.read_parquet(out / f"{truth['recordings'][0]['name']}.parquet")
    counts = table[[f"wrist_fixed_u{i}" for i in range(1, 7)]].to_numpy()
    assert np.array_equal(counts, np.round(counts))  # ADC counts
    offset = np.array(truth["drift"]["offset_counts"])
    recovered = (counts - offset) @ np.array(truth["sensor"]["true_matrix"]).T
    bound = 0.5 * np.abs(sensor.true_matrix).sum(axis=1) + 1e-9
    mass, com = 1.5, np.array([0.03, -0.02, -0.1])
    for (start, end), q in zip(truth["recordings"][0]["holds"], angles):
        inside = (table["time"] >= start) & (table["time"] <= end)
        g = Rotation.from_euler("y", q).inv().apply([0.0, 0.0, -9.81])
        statics = np.concatenate([mass * g, np.cross(com, mass * g)])
        assert inside.sum() > 50
        assert np.all(np.abs(recovered[inside.to_numpy()] - statics) <= bound)


def test_a_session_that_fails_part_way_leaves_nothing_behind(tmp_path, monkeypatch, capsys):
    # The session's last file fails to write (a full disk, say): no recording, loads.toml or truth.json appears,
    # and files the user already had in the folder are untouched.
    from ftcal.sim import robot_recording
    from ftcal.sim.plan_arm import ARM_URDF

    urdf = tmp_path / "arm.urdf"
    urdf.write_text(ARM_URDF)
    plan = tmp_path / "plan.csv"
    assert main(["plan", "--urdf", str(urdf), "--poses", "4", "--candidates", "60", "--load", "none", "--load",
                 "tool:1@0.03,0,0.04", "-o", str(plan)]) == 0
    out = tmp_path / "sim"
    out.mkdir()
    (out / "mine.txt").write_text("keep")
    written = []
    original = robot_recording.write_text_atomic

    def failing(path, *args, **kwargs):  # the last file of the session, truth.json, cannot be written
        if Path(path).name == "truth.json":
            raise OSError(28, "No space left on device")
        written.append(Path(path).name)
        return original(path, *args, **kwargs)

    monkeypatch.setattr(robot_recording, "write_text_atomic", failing)
    code = main(["simulate", str(plan), "--urdf", str(urdf), "--load", "none", "--load", "tool:1@0.03,0,0.04",
                 "--hold", "0.2", "--rate", "50", "--format", "table", "-o", str(out)])
    assert code == 2 and "No space left on device" in capsys.readouterr().err
    assert written == ["loads.toml"]  # the recordings and loads.toml were written (staged) before the failure
    assert sorted(p.name for p in out.iterdir()) == ["mine.txt"]


def test_a_truth_file_that_is_a_fifo_is_refused_without_hanging(tmp_path):
    import os

    from ftcal.runtime.errors import FtcalError
    from ftcal.sim.robot_recording import read_truth

    fifo = tmp_path / "truth.json"
    os.mkfifo(fifo)
    with pytest.raises(FtcalError, match="truth file"):
        read_truth(fifo)
