"""The steps behind dataset, payload, compensate, check and convert: the command and its Python step give the
same numbers on the same generated data, and the old spellings of the renamed flags still work with a notice.

The data: a ROS 2 bag (written with rosbags' own writer) of a 1.2 kg tool held still in 8 orientations, with
slerped moves between them during which an acceleration along gravity adds 30 % to the weight. The truth is
known, so besides CLI == Python the tests check the numbers against it.
"""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from bag_data import Bag
from scipy.spatial.transform import Rotation, Slerp

import ftcal
from ftcal.cli import main

FTCAL = str(Path(sys.executable).with_name("ftcal"))
T0 = 1_700_000_000 * 10**9
RATE = 100.0
MASS, COM = 1.2, np.array([0.01, -0.02, 0.06])
BIAS = np.array([0.5, -0.3, 0.8, 0.02, -0.01, 0.005])
NOISE = np.array([0.01, 0.01, 0.01, 0.001, 0.001, 0.001])
HOLD_S, MOVE_S, N_POSES = 2.5, 1.0, 8
EXTRA_WHILE_MOVING = 0.3  # the moving samples weigh 30 % more (a vertical acceleration of 0.3 g)
QUATERNION = ["--orientation", "qx,qy,qz,qw"]


def schedule():
    """Orientation (sensor -> world, gravity -z) at each sample, and which samples move."""
    poses = Rotation.random(N_POSES, random_state=11)
    rotations, moving = [], []
    for k in range(N_POSES):
        n_hold = int(HOLD_S * RATE)
        rotations += [poses[k]] * n_hold
        moving += [False] * n_hold
        if k + 1 < N_POSES:
            n_move = int(MOVE_S * RATE)
            slerp = Slerp([0.0, 1.0], Rotation.concatenate([poses[k], poses[k + 1]]))
            rotations += list(slerp(np.arange(1, n_move + 1) / (n_move + 1)))
            moving += [True] * n_move
    return Rotation.concatenate(rotations), np.array(moving)


@pytest.fixture(scope="module")
def recorded(tmp_path_factory):
    """The bag, and the dataset the CLI made of it."""
    folder = tmp_path_factory.mktemp("workflow")
    rotation, moving = schedule()
    gravity = rotation.inv().apply([0.0, 0.0, -9.81])
    weight = MASS * gravity * np.where(moving, 1.0 + EXTRA_WHILE_MOVING, 1.0)[:, None]
    wrench = BIAS + np.c_[weight, np.cross(COM, weight)]
    wrench += np.random.default_rng(3).normal(size=wrench.shape) * NOISE
    bag = Bag("mcap")
    for k, (w, q) in enumerate(zip(wrench, rotation.as_quat())):
        stamp = T0 + int(round(k * 1e9 / RATE))
        bag.wrench("/ft", stamp, w)
        bag.imu("/imu", stamp, q, (0.0, 0.0, 0.0), (0.0, 0.0, 9.81))
    path = bag.write(folder / "arm")
    data = folder / "arm.parquet"
    done = run_cli(["dataset", path, "--wrench-topic", "/ft", "--imu-topic", "/imu", "--no-filter", "-o", data])
    return {"folder": folder, "bag": path, "data": data, "moving": moving, "dataset_stdout": done.stdout}


def run_cli(args, code=0):
    done = subprocess.run([FTCAL, *map(str, args)], capture_output=True, text=True)
    assert done.returncode == code, done.stderr
    return done


def numbers(value, path=""):
    """Every number of a JSON document by its path, leaving out when and by which ftcal it was written."""
    if isinstance(value, dict):
        out = {}
        for key, item in value.items():
            if key not in ("created", "sha256"):
                out.update(numbers(item, f"{path}/{key}"))
        return out
    if isinstance(value, list):
        out = {}
        for i, item in enumerate(value):
            out.update(numbers(item, f"{path}/{i}"))
        return out
    return {path: value}


def test_dataset_step_equals_the_command(recorded, tmp_path):
    from ftcal.workflow.datasets import build_dataset

    result = build_dataset(recorded["bag"], wrench_topic="/ft", imu_topic="/imu", no_filter=True,
                           output=tmp_path / "py.parquet")
    cli, py = pd.read_parquet(recorded["data"]), pd.read_parquet(tmp_path / "py.parquet")
    pd.testing.assert_frame_equal(cli, py)
    pd.testing.assert_frame_equal(result.to_frame(), py, check_dtype=False)
    assert recorded["dataset_stdout"] == result.summary().replace(
        result.description, f"wrote {result.description}, to {recorded['data']}") + "\n"
    # the generated schedule, independently: one hold per pose, the moving samples marked
    assert result.n_samples == len(recorded["moving"]) and sorted(set(cli["hold"])) == [-1, *range(N_POSES)]
    assert np.mean((cli["static"] == 0) == recorded["moving"]) > 0.95


def test_payload_step_equals_the_command_and_drops_the_moving_samples(recorded, tmp_path):
    from ftcal.workflow.payload import identify_payload

    done = run_cli(["payload", recorded["data"], *QUATERNION, "-o", tmp_path / "cli.json"])
    result = identify_payload(recorded["data"], orientation=("qx", "qy", "qz", "qw"))
    assert done.stdout == result.summary() + "\n"
    result.save(tmp_path / "py.json")
    cli = numbers(json.loads((tmp_path / "cli.json").read_text()))
    assert cli == numbers(json.loads((tmp_path / "py.json").read_text())) and len(cli) > 20
    # against the truth: the still samples carry the tool's weight only
    assert result.mass == pytest.approx(MASS, abs=5 * result.fit.stderr["mass"] + 1e-3)
    np.testing.assert_allclose(result.com, COM, atol=2e-3)
    # the dataset's 'hold' column gives one cross-validation group per pose, and says so
    assert result.drift.n_groups == N_POSES and "groups: the tables' 'hold' column" in done.stdout
    # keeping the moving samples (30 % heavier) pulls the mass up: the default dropped them
    moving = identify_payload(recorded["data"], orientation=("qx", "qy", "qz", "qw"), keep_moving=True)
    assert abs(moving.mass - MASS) > 10 * abs(result.mass - MASS) and moving.mass > MASS
    assert result.to_dict()["mass"] == result.mass and json.loads(result.to_json())["n_groups"] == N_POSES
    assert repr(result).startswith("<PayloadResult: static samples: ") and "print() it" in repr(result)


@pytest.fixture(scope="module")
def payload_file(recorded):
    path = recorded["folder"] / "payload.json"
    run_cli(["payload", recorded["data"], *QUATERNION, "--frame", "ft_sensor", "-o", path])
    return path


def test_compensate_step_equals_the_command(recorded, payload_file, tmp_path):
    from ftcal.workflow.compensation import compensate

    run_cli(["compensate", payload_file, recorded["data"], *QUATERNION, "-o", tmp_path / "cli.parquet"])
    result = compensate(payload_file, recorded["data"], orientation=("qx", "qy", "qz", "qw"))
    pd.testing.assert_frame_equal(pd.read_parquet(tmp_path / "cli.parquet"), result.table)
    # no contact while still: what is left is the sensor noise
    still = result.contact[~recorded["moving"]]
    np.testing.assert_allclose(np.sqrt(np.mean(still ** 2, axis=0)), NOISE, rtol=0.25)
    assert result.to_dict()["n_samples"] == len(recorded["moving"])


def test_check_step_equals_the_command(recorded):
    from ftcal.workflow.checking import check_sensor

    done = run_cli(["check", recorded["data"], *QUATERNION])
    result = check_sensor(recorded["data"], orientation=("qx", "qy", "qz", "qw"))
    assert done.stdout == result.summary() + "\n" and result.exit_code == done.returncode == 0
    # the data are as declared: no finding, and the tool's mass from the holds
    assert result.passed and result.to_dict()["findings"] == []
    assert result.report.mass == pytest.approx(MASS, rel=0.01)


def test_convert_step_equals_the_command(payload_file, tmp_path):
    from ftcal.workflow.export import convert

    done = run_cli(["convert", payload_file, "--to", "ros-yaml", "-o", tmp_path / "cli.yaml"])
    result = convert(payload_file, "ros-yaml", tmp_path / "py.yaml")
    assert (tmp_path / "cli.yaml").read_text() == (tmp_path / "py.yaml").read_text()
    assert done.stdout == result.summary().replace(str(tmp_path / "py.yaml"), str(tmp_path / "cli.yaml")) + "\n"
    mass = json.loads(payload_file.read_text())["mass"]
    assert f"{mass}" in (tmp_path / "py.yaml").read_text() or f"{mass:.17g}" in (tmp_path / "py.yaml").read_text()


def test_the_steps_are_reachable_from_ftcal():
    from ftcal import workflow

    for name in ("build_dataset", "identify_payload", "compensate", "check_sensor", "plan_experiment", "convert",
                 "DatasetResult", "PayloadResult", "CompensationResult", "CheckResult", "PlanResult",
                 "ConvertResult"):
        assert name in ftcal.__all__ and name in dir(ftcal)
        assert getattr(ftcal, name) is getattr(workflow, name)
        assert issubclass(getattr(ftcal, name), workflow.StepResult) if name.endswith("Result") else True


def test_bad_step_input_is_one_line():
    with pytest.raises(ftcal.FtcalError, match="unknown keyword 'orientations'"):
        ftcal.identify_payload("x.csv", orientations=("qx", "qy", "qz", "qw"))
    with pytest.raises(ftcal.FtcalError, match="bias_drift 'sometimes'"):
        ftcal.identify_payload("x.csv", bias_drift="sometimes")


# --- one vocabulary: the new spellings, and the old ones with a notice ---

def identity_model(path):
    """A calibration whose outputs Fx..Tz are its inputs u1..u6 (fitted on exact data)."""
    raw = np.random.default_rng(0).normal(size=(200, 6))
    model = ftcal.CalibrationModel(1).fit(ftcal.Dataset.from_arrays(
        raw, raw, input_names=tuple(f"u{i}" for i in range(1, 7)),
        output_names=("Fx", "Fy", "Fz", "Tx", "Ty", "Tz")))
    ftcal.save_model(model, path)
    return path


def test_compensate_calibration_flag_and_its_old_spelling(recorded, payload_file, tmp_path):
    model = identity_model(tmp_path / "identity.json")
    new = run_cli(["compensate", payload_file, recorded["data"], *QUATERNION, "--calibration", model,
                   "-o", tmp_path / "new.parquet"])
    old = run_cli(["compensate", payload_file, recorded["data"], *QUATERNION, "--model", model,
                   "-o", tmp_path / "old.parquet"])
    assert "notice:" not in new.stderr
    notices = [line for line in old.stderr.splitlines() if line.startswith("notice:")]
    assert len(notices) == 1 and "--calibration CAL.json" in notices[0]
    pd.testing.assert_frame_equal(pd.read_parquet(tmp_path / "new.parquet"), pd.read_parquet(tmp_path / "old.parquet"))
    # an identity calibration predicts the readings: the same contact as without it
    run_cli(["compensate", payload_file, recorded["data"], *QUATERNION, "-o", tmp_path / "plain.parquet"])
    np.testing.assert_allclose(pd.read_parquet(tmp_path / "new.parquet")[["Fx", "Tz"]],
                               pd.read_parquet(tmp_path / "plain.parquet")[["Fx", "Tz"]], atol=1e-9)
    # --model NAME is a robot model in compensate as in every other command
    refused = run_cli(["compensate", payload_file, recorded["data"], "--model", "NoSuchRobot", "--sensor", "s",
                       "-o", tmp_path / "robot.parquet"], code=2)
    assert "NoSuchRobot" in refused.stderr and not (tmp_path / "robot.parquet").exists()


def test_check_payload_json_flag_and_its_old_spelling(recorded, payload_file, tmp_path):
    model = identity_model(tmp_path / "identity.json")
    base = ["check", "--accept", model, recorded["data"], *QUATERNION]
    new = subprocess.run([FTCAL, *map(str, base), "--payload-json", str(payload_file)], capture_output=True, text=True)
    old = subprocess.run([FTCAL, *map(str, base), "--payload", str(payload_file)], capture_output=True, text=True)
    assert new.returncode == old.returncode in (0, 1) and new.stdout == old.stdout
    assert "notice:" not in new.stderr
    assert [line for line in old.stderr.splitlines() if line.startswith("notice:")] == [
        "notice: --payload PAYLOAD.json is now --payload-json PAYLOAD.json (in the robot commands, --payload is a "
        "mass/COM spec)"]
    # the reference is the payload's bias + weight: the identity calibration's error is the contact, ~ the noise
    # on the still samples; the moving ones carry 30 % of the weight more
    assert new.stdout.startswith(f"acceptance of {model} on {len(recorded['moving'])} samples")


def test_dataset_sensor_is_implied_by_one_declared_sensor(tmp_path, capsys):
    from ftcal.sim.plan_arm import ARM_URDF

    urdf = tmp_path / "arm.urdf"
    urdf.write_text(ARM_URDF)
    bag = Bag("mcap")
    joints = ["shoulder_pitch", "elbow_pitch", "wrist_roll", "wrist_pitch"]
    for k in range(300):
        stamp = T0 + k * 10**7
        bag.wrench("/ft", stamp, np.arange(6.0))
        bag.joints("/joint_states", stamp, joints, [0.1, 0.2, 0.3, 0.4])
    path = bag.write(tmp_path / "arm")
    base = ["dataset", str(path), "--urdf", str(urdf), "--wrench-topic", "/ft", "--joints-topic", "/joint_states",
            "--no-filter"]
    assert main([*base, "--sensor", "wrist_ft", "-o", str(tmp_path / "named.parquet")]) == 0
    capsys.readouterr()
    assert main([*base, "-o", str(tmp_path / "implied.parquet")]) == 0
    out = capsys.readouterr().out
    assert "sensor: wrist_ft, the robot model's only F/T sensor" in out
    named, implied = pd.read_parquet(tmp_path / "named.parquet"), pd.read_parquet(tmp_path / "implied.parquet")
    pd.testing.assert_frame_equal(named, implied)
    # the expected wrench of a still arm: its norm is the weight beyond the sensor (a physical invariant)
    from ftcal.robot import RobotModel

    robot = RobotModel.load(urdf=str(urdf))
    weight = robot.mass_beyond(robot.sensor("wrist_ft"), robot.base_frame(None)[1]) * 9.81
    np.testing.assert_allclose(np.linalg.norm(implied[["Fx", "Fy", "Fz"]].to_numpy(), axis=1), weight, rtol=1e-9)
    assert math.isfinite(weight) and weight > 0


def test_rebias_step_equals_the_command(recorded, payload_file, tmp_path):
    from ftcal.workflow.payload import retare

    done = run_cli(["payload", recorded["data"], *QUATERNION, "--rebias", payload_file, "-o", tmp_path / "cli.json"])
    result = retare(payload_file, recorded["data"], orientation=("qx", "qy", "qz", "qw"),
                    output=tmp_path / "py.json")
    assert done.stdout == result.summary() + "\n"
    assert numbers(json.loads((tmp_path / "cli.json").read_text())) == numbers(
        json.loads((tmp_path / "py.json").read_text()))
    # re-tared on the identification's own still samples: the same bias within its errors, and the true one
    assert np.all(np.abs(result.z) < 3.0)
    assert np.all(np.abs(result.bias - BIAS) < 10 * NOISE)
