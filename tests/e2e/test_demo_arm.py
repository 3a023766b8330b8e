"""`ftcal demo --scenario arm`: bag → dataset → payload → compensate recovers the simulator's gripper.

The true values come from the ArmScenario the simulator ran (an independent source);
the noise levels the residuals must reach are the scenario's declared noise.
"""

import dataclasses
import json
import re

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from ftcal.cli import main
from ftcal.data.bags import BagTopics, read_bag
from ftcal.files.payload_json import load_payload
from ftcal.runtime.errors import FtcalError
from ftcal.sim.arm_bag import WRENCH_TOPIC, ArmScenario
from ftcal.sim.demo_arm import ArmDemoConfig, run_arm_demo, write_demo_bag

SMALL = ArmScenario(n_poses=8, hold_s=1.0, move_s=1.0, rate=200.0, tf_rate=50.0, imu_rate=100.0,
                    force_bias_tc=(0.0, 0.0, 0.0), seed=5)


@pytest.fixture(scope="module")
def demo(tmp_path_factory):
    out = tmp_path_factory.mktemp("arm-demo")
    return out, run_arm_demo(ArmDemoConfig(out_dir=out, scenario=SMALL))


def test_recovers_the_simulated_gripper_and_bias(demo):
    out, summary = demo
    rows = {r["name"]: r for r in summary["parameters"]}
    true = {"mass": SMALL.gripper_mass,
            **{f"com {a}": v for a, v in zip("xyz", SMALL.gripper_com)},
            **{f"force bias {a}": v for a, v in zip("xyz", SMALL.force_bias)},
            **{f"torque bias {a}": v for a, v in zip("xyz", SMALL.torque_bias)},
            **{f"inertia {a}{a}": v for a, v in zip("xyz", SMALL.gripper_inertia)}}
    assert set(rows) == set(true)
    for name, value in true.items():
        assert rows[name]["true"] == pytest.approx(value)
        # within 4 standard errors, and the standard errors are small (a meaningful check)
        assert abs(rows[name]["identified"] - value) < 4 * rows[name]["stderr"], name
    assert rows["mass"]["stderr"] < 1e-3 * SMALL.gripper_mass
    payload = load_payload(out / "payload.json")
    np.testing.assert_allclose(payload.com, SMALL.gripper_com, atol=1e-4)
    assert payload.frame == "ft_sensor"


def test_compensation_leaves_the_declared_noise(demo):
    out, summary = demo
    for axis in ("Fx", "Fy", "Fz", "Tx", "Ty", "Tz"):
        sigma = SMALL.force_noise if axis.startswith("F") else SMALL.torque_noise
        assert summary["residual_rms_after"][axis] == pytest.approx(sigma, rel=0.1), axis
        assert summary["residual_rms_before"][axis] > 10 * sigma


def test_residual_before_is_the_gripper_weight(demo):
    """Before compensation the force RMS is that of b_f + m·g_s, computed from the dataset's quaternions."""
    import pandas as pd

    out, summary = demo
    table = pd.read_parquet(out / "arm.parquet")
    g_s = Rotation.from_quat(table[["qx", "qy", "qz", "qw"]].to_numpy()).inv().apply([0.0, 0.0, -SMALL.gravity])
    static = np.asarray(SMALL.force_bias) + SMALL.gripper_mass * g_s
    # moves add the gripper's inertial force, so compare loosely with the static weight
    np.testing.assert_allclose([summary["residual_rms_before"][a] for a in ("Fx", "Fy", "Fz")],
                               np.sqrt(np.mean(static ** 2, axis=0)), rtol=0.05)


def test_report_and_files(demo):
    out, summary = demo
    page = (out / "report.html").read_text(encoding="utf-8")
    assert "True vs identified parameters" in page
    for name in ("mass", "com z", "force bias x", "torque bias z", "inertia zz"):
        assert f'<td class="name">{name}</td>' in page
    assert re.search(r'<img src="data:image/png;base64,', page)
    assert json.loads((out / "summary.json").read_text())["parameters"] == summary["parameters"]
    ros = (out / "ft_calib.yaml").read_text()
    # force_torque_tools ft_calib field names
    for field in ("bias:", "gripper_mass:", "gripper_com_frame_id:", "gripper_com_pose:"):
        assert field in ros
    assert (out / "arm" / "metadata.yaml").is_file() and (out / "contact.parquet").is_file()


def test_rerun_replaces_the_bag_and_spares_other_folders(tmp_path):
    tiny = ArmScenario(n_poses=3, hold_s=0.5, move_s=0.5, rate=100.0)
    write_demo_bag(tmp_path / "arm", tiny)
    truth = write_demo_bag(tmp_path / "arm", dataclasses.replace(tiny, n_poses=4))  # a re-run of the demo
    assert truth.path == tmp_path / "arm" and len(truth.holds) == 4
    stream = read_bag(truth.path, BagTopics(WRENCH_TOPIC)).ft[WRENCH_TOPIC]
    assert stream.n_samples == 351  # 4 holds and 3 moves of 0.5 s at 100 Hz, both ends included
    assert [p.name for p in tmp_path.iterdir()] == ["arm"]  # no scratch folder left behind
    (tmp_path / "mine").mkdir()
    with pytest.raises(FtcalError, match="mine: exists and is not a ROS 2 bag folder"):
        write_demo_bag(tmp_path / "mine", tiny)


def test_unknown_scenario_is_one_line(tmp_path, capsys):
    assert main(["demo", "--scenario", "ur5", "--out", str(tmp_path / "x")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "--scenario ur5" in err and "paper, arm" in err
    assert not (tmp_path / "x").exists()


def test_cli_arm_scenario_prints_the_table(tmp_path, capsys):
    assert main(["demo", "--scenario", "arm", "--quick", "--out", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert re.search(r"^mass\s+kg\s+1\.35\s", out, re.MULTILINE)  # the simulator's default gripper mass
    assert "Residual RMS" in out and (tmp_path / "report.html").is_file() and (tmp_path / "ft_calib.yaml").is_file()
