"""The MuJoCo scene and the closed loop: the two engines agree, and the calibration's effect in the loop.

References: iDynTree's expected wrench (another engine) for the same URDF, joints and tool; the
simulation's known truth (MuJoCo's own contact force, not the sensor) for the ordering targets of
issue 31: (b) ftcal contact-force RMSE at least 2x lower than (a) factory + tare and within 1.5x of
(d) the true wrench; phantom force in free motion at most 1/3 of (a)'s.
"""

import sys
from pathlib import Path

import numpy as np
import pytest

from ftcal.robot import Payload, RobotModel, SensorDeclaration
from ftcal.robot.expected import expected_wrenches
from ftcal.sim.mujoco_scene import Tool, build_scene, mujoco_urdf, static_sensor_wrench
from ftcal.sim.plan_arm import ARM_URDF

pytest.importorskip("mujoco")

ROBOTS = Path(sys.prefix) / "lib" / f"python{sys.version_info.major}.{sys.version_info.minor}" / \
    "site-packages" / "cmeel.prefix" / "share" / "example-robot-data" / "robots"
UR5 = ROBOTS / "ur_description" / "urdf" / "ur5_robot.urdf"
TOOL = Tool(mass=1.3, com=(0.02, -0.01, 0.07), inertia=(0.003, 0.004, 0.002))


def cases():
    yield RobotModel(ARM_URDF, "plan_arm.urdf"), "wrist_ft", "hand"
    if UR5.is_file():
        yield RobotModel.load(UR5, declared=[SensorDeclaration("ee_fixed_joint")]), "ee_fixed_joint", "ee_link"


@pytest.mark.parametrize("tool", [None, TOOL])
def test_mujoco_sensor_wrench_equals_idyntree_expected_wrench_at_static_poses(tool):
    for robot, sensor, frame in cases():
        if tool is None and robot.mass_beyond(robot.sensor(sensor)) < 1e-6:
            continue  # the bare UR5 has nothing beyond its flange sensor
        scene = build_scene(robot, sensor, tool)
        loaded = robot if tool is None else robot.with_payloads(
            [Payload(frame, tool.mass, tool.com, (*tool.inertia, 0.0, 0.0, 0.0))])
        q = np.random.default_rng(3).uniform(-1.5, 1.5, (6, len(robot.joint_names)))
        reference = expected_wrenches(loaded, q, workers=1)[:, 0]
        mujoco_wrench = np.array([static_sensor_wrench(scene, qk) for qk in q])
        scale = np.abs(reference).max()
        assert scale > 1.0  # the poses load the sensor
        np.testing.assert_allclose(mujoco_wrench, reference, rtol=0, atol=1e-6 * scale)


@pytest.mark.skipif(not UR5.is_file(), reason="example-robot-data is not installed")
def test_meshes_are_replaced_by_inertias_and_said_so():
    text, notes = mujoco_urdf(UR5.read_text())
    assert "<mesh" not in text and "<visual" not in text and "<collision" not in text
    assert any("mesh" in n for n in notes) and any("gazebo" in n for n in notes)


@pytest.mark.slow
def test_closed_loop_meets_the_ordering_targets(tmp_path):
    import json

    from ftcal.sim.closed_loop import CLOSED_LOOP_QUICK, ClosedLoopConfig, run_closed_loop

    summary = run_closed_loop(ClosedLoopConfig(out_dir=tmp_path, **CLOSED_LOOP_QUICK))
    rows = {r["condition"]: r for r in summary["conditions"]}
    a, b, d = rows["factory"], rows["ftcal"], rows["true"]
    assert b["contact_rmse"] * 2 <= a["contact_rmse"]
    assert b["contact_rmse"] <= 1.5 * d["contact_rmse"]
    assert b["phantom_rms"] * 3 <= a["phantom_rms"]
    # free motion is free: MuJoCo saw no contact there, so whatever a condition perceives is phantom
    assert all(r["true_contact_in_free_motion"] == 0.0 for r in (a, b, d))
    live = rows["ftcal + live"]
    if live["available"]:  # ftcal.live is installed: the same targets as (b)
        assert live["contact_rmse"] * 2 <= a["contact_rmse"] and live["contact_rmse"] <= 1.5 * d["contact_rmse"]
        assert live["phantom_rms"] * 3 <= a["phantom_rms"]
    else:
        assert "ftcal.live" in live["reason"]
    assert json.loads((tmp_path / "summary.json").read_text())["ratios"] == summary["ratios"]
    assert "<img" in (tmp_path / "report.html").read_text()
