"""The payload-side steps take data, not only paths: a DataFrame, a list or dict of them, the result of
``build_dataset`` (a bag's table, straight from Python) or a Dataset give every number the same tables give
from Parquet files, and the text and errors name what the caller gave.

The data: a ROS 2 bag (written with rosbags' own writer, no ftcal code) of a 0.8 kg tool held still in 6
orientations with slerped moves between them; the truth (mass, centre of mass, bias) is known.
"""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest
from bag_data import Bag
from scipy.spatial.transform import Rotation, Slerp

import ftcal
from ftcal.workflow.checking import check_sensor
from ftcal.workflow.compensation import compensate
from ftcal.workflow.datasets import build_dataset, expected
from ftcal.workflow.payload import identify_payload, retare

T0 = 1_700_000_000 * 10**9
RATE = 100.0
MASS, COM = 0.8, np.array([-0.015, 0.01, 0.07])
BIAS = np.array([-0.4, 0.2, 0.6, 0.015, -0.02, 0.01])
NOISE = np.array([0.01, 0.01, 0.01, 0.001, 0.001, 0.001])
HOLD_S, MOVE_S, N_POSES = 2.0, 0.8, 6
QUATERNION = ("qx", "qy", "qz", "qw")


def schedule():
    """Orientation (sensor -> world, gravity -z) at each sample."""
    poses = Rotation.random(N_POSES, random_state=5)
    rotations = []
    for k in range(N_POSES):
        rotations += [poses[k]] * int(HOLD_S * RATE)
        if k + 1 < N_POSES:
            n_move = int(MOVE_S * RATE)
            slerp = Slerp([0.0, 1.0], Rotation.concatenate([poses[k], poses[k + 1]]))
            rotations += list(slerp(np.arange(1, n_move + 1) / (n_move + 1)))
    return Rotation.concatenate(rotations)


@pytest.fixture(scope="module")
def bag_dataset(tmp_path_factory):
    """The bag's dataset built from Python (no file), and the same table written to Parquet."""
    folder = tmp_path_factory.mktemp("data")
    rotation = schedule()
    weight = MASS * rotation.inv().apply([0.0, 0.0, -9.81])
    wrench = BIAS + np.c_[weight, np.cross(COM, weight)]
    wrench += np.random.default_rng(8).normal(size=wrench.shape) * NOISE
    bag = Bag("mcap")
    for k, (w, q) in enumerate(zip(wrench, rotation.as_quat())):
        stamp = T0 + int(round(k * 1e9 / RATE))
        bag.wrench("/ft", stamp, w)
        bag.imu("/imu", stamp, q, (0.0, 0.0, 0.0), (0.0, 0.0, 9.81))
    result = build_dataset(bag.write(folder / "arm"), wrench_topic="/ft", imu_topic="/imu", no_filter=True)
    path = folder / "arm.parquet"
    result.save(path)
    return {"result": result, "path": path, "folder": folder}


FIT_KEYS = ("mass", "com", "force_bias", "torque_bias")


def assert_same_fit(a, b):
    """Every number of two payload fits: parameters and standard errors to 1e-12, and the rest of to_dict."""
    for key in FIT_KEYS:
        np.testing.assert_allclose(getattr(a.fit, key), getattr(b.fit, key), rtol=0, atol=1e-12)
        np.testing.assert_allclose(a.fit.stderr[key], b.fit.stderr[key], rtol=0, atol=1e-12)
    left, right = a.to_dict(), b.to_dict()
    for key in ("notes", "sources"):
        left.pop(key), right.pop(key)
    assert json.dumps(left, sort_keys=True) == json.dumps(right, sort_keys=True)


def test_a_bags_dataset_goes_straight_into_identify_payload(bag_dataset):
    result = bag_dataset["result"]
    direct = identify_payload(result, orientation=QUATERNION)             # no Parquet file
    from_file = identify_payload(bag_dataset["path"], orientation=QUATERNION)
    assert_same_fit(direct, from_file)
    # the same text, naming the DataFrame where the file route names the file
    assert direct.summary() == from_file.summary().replace(str(bag_dataset["path"]), "DataFrame")
    assert direct.sources == ["DataFrame"] and "ftcal-frame-" not in direct.summary()
    # against the truth of the simulation
    assert direct.mass == pytest.approx(MASS, abs=5 * direct.fit.stderr["mass"] + 1e-3)
    np.testing.assert_allclose(direct.com, COM, atol=2e-3)
    np.testing.assert_allclose(np.r_[direct.fit.force_bias, direct.fit.torque_bias], BIAS, atol=10 * NOISE.max())
    # the DataFrame itself, and the payload file written from it
    frame = identify_payload(result.to_frame(), orientation=QUATERNION)
    assert_same_fit(frame, from_file)


def test_a_dict_of_dataframes_is_a_list_of_named_recordings(bag_dataset, tmp_path):
    table = pd.read_parquet(bag_dataset["path"])
    half = int(np.flatnonzero(table["hold"].to_numpy() == N_POSES // 2)[0])
    parts = {"first": table.iloc[:half], "second": table.iloc[half:]}
    paths = []
    for name, part in parts.items():
        paths.append(tmp_path / f"{name}.parquet")
        part.to_parquet(paths[-1], index=False)
    # one cross-validation group per recording: the groups are the dict's names, the files' paths
    by_name = identify_payload(parts, orientation=QUATERNION, group_by=None, keep_moving=True)
    by_path = identify_payload(paths, orientation=QUATERNION, group_by=None, keep_moving=True)
    assert_same_fit(by_name, by_path)
    assert sorted(g.group for g in by_name.fit.cross_validation) == ["first", "second"]
    assert sorted(g.group for g in by_path.fit.cross_validation) == sorted(map(str, paths))
    assert by_name.sources == ["first", "second"]
    # a plain list is numbered
    listed = identify_payload(list(parts.values()), orientation=QUATERNION, keep_moving=True)
    assert listed.sources == ["DataFrame 1", "DataFrame 2"]
    by_name.save(tmp_path / "named.json")
    by_path.save(tmp_path / "paths.json")
    named, pathed = (json.loads((tmp_path / f).read_text()) for f in ("named.json", "paths.json"))
    for key in FIT_KEYS:
        np.testing.assert_allclose(named[key], pathed[key], rtol=0, atol=1e-12)


def test_compensate_rebias_and_check_take_a_dataframe(bag_dataset, tmp_path):
    table, path = bag_dataset["result"].to_frame(), bag_dataset["path"]
    payload = tmp_path / "tool.json"
    identify_payload(path, orientation=QUATERNION, output=payload)
    from_frame = compensate(payload, table, orientation=QUATERNION)
    from_file = compensate(payload, path, orientation=QUATERNION)
    pd.testing.assert_frame_equal(from_frame.table, from_file.table)
    assert from_frame.sources == ["DataFrame"]
    # no contact anywhere still: the contact is the sensor noise on the static samples
    still = from_frame.contact[table["static"].to_numpy() == 1]
    np.testing.assert_allclose(np.sqrt(np.mean(still ** 2, axis=0)), NOISE, rtol=0.3)

    rebias_frame = retare(payload, table, orientation=QUATERNION)
    rebias_file = retare(payload, path, orientation=QUATERNION)
    for key in ("bias", "stderr", "change", "z"):
        np.testing.assert_allclose(getattr(rebias_frame, key), getattr(rebias_file, key), rtol=0, atol=1e-12)
    assert rebias_frame.summary() == rebias_file.summary().replace(str(path), "DataFrame")

    check_frame = check_sensor(table, orientation=QUATERNION)
    check_file = check_sensor(path, orientation=QUATERNION)
    assert check_frame.summary() == check_file.summary().replace(str(path), "DataFrame")
    assert check_frame.passed and check_frame.report.mass == pytest.approx(MASS, rel=0.01)


def test_a_dataset_is_one_table_per_segment_of_its_columns(tmp_path):
    rotations = Rotation.random(12, random_state=9)
    gravity = rotations.inv().apply([0.0, 0.0, -9.81])
    wrench = BIAS + np.c_[MASS * gravity, np.cross(COM, MASS * gravity)]
    names = ("u1", "u2", "u3", "u4", "u5", "u6")
    dataset = ftcal.Dataset.from_arrays(wrench, gravity, input_names=names, output_names=("gx", "gy", "gz"),
                                        segments=np.repeat([0, 1], 6))
    frame = pd.DataFrame(np.c_[wrench, gravity], columns=[*names, "gx", "gy", "gz"])
    paths = [tmp_path / "a.parquet", tmp_path / "b.parquet"]
    frame.iloc[:6].to_parquet(paths[0], index=False)
    frame.iloc[6:].to_parquet(paths[1], index=False)
    from_dataset = identify_payload(dataset, gravity_columns=("gx", "gy", "gz"))
    from_files = identify_payload(paths, gravity_columns=("gx", "gy", "gz"))
    assert_same_fit(from_dataset, from_files)
    assert len(from_dataset.sources) == 2
    # exact data: the truth to rounding
    assert from_dataset.mass == pytest.approx(MASS, rel=1e-9)
    np.testing.assert_allclose(from_dataset.com, COM, atol=1e-9)


def test_expected_takes_the_joint_table_as_a_dataframe(tmp_path):
    from ftcal.robot import RobotModel
    from ftcal.sim.plan_arm import ARM_URDF

    urdf = tmp_path / "arm.urdf"
    urdf.write_text(ARM_URDF)
    joints = pd.DataFrame(np.random.default_rng(2).uniform(-1.0, 1.0, size=(5, 4)),
                          columns=["shoulder_pitch", "elbow_pitch", "wrist_roll", "wrist_pitch"])
    joints.to_parquet(tmp_path / "joints.parquet", index=False)
    from_frame = expected(joints, urdf=urdf, no_cache=True)
    from_file = expected(tmp_path / "joints.parquet", urdf=urdf, no_cache=True)
    pd.testing.assert_frame_equal(from_frame.table, from_file.table)
    # the force's norm is the weight beyond the sensor in every pose (a physical invariant)
    robot = RobotModel.load(urdf=str(urdf))
    weight = robot.mass_beyond(robot.sensor("wrist_ft"), robot.base_frame(None)[1]) * 9.81
    force = from_frame.table[["wrist_ft_Fx", "wrist_ft_Fy", "wrist_ft_Fz"]].to_numpy()
    np.testing.assert_allclose(np.linalg.norm(force, axis=1), weight, rtol=1e-9)


def test_bad_data_is_one_line_naming_what_was_given(bag_dataset):
    table = bag_dataset["result"].to_frame()
    with pytest.raises(ftcal.FtcalError) as caught:
        identify_payload({"run7": table.drop(columns=["u3"])}, orientation=QUATERNION)
    message = str(caught.value)
    assert "run7" in message and "u3" in message and "ftcal-frame-" not in message and "\n" not in message
    with pytest.raises(ftcal.FtcalError, match="DATA DataFrame: cannot be written as a table"):
        identify_payload(pd.DataFrame({"u1": [object()]}), orientation=QUATERNION)  # not a table's cell
    with pytest.raises(ftcal.FtcalError, match="DATA: no table given"):
        compensate("tool.json", {}, orientation=QUATERNION)
    with pytest.raises(ftcal.FtcalError, match="DATA: expected a file name"):
        check_sensor(42, orientation=QUATERNION)
    with pytest.raises(ftcal.FtcalError, match="LOG: a Dataset is already built"):
        build_dataset(ftcal.Dataset.from_arrays(np.zeros((2, 7)), np.zeros((2, 6))))
    with pytest.raises(ftcal.FtcalError, match="^joints: one joint table, not 2"):
        expected([table, table], robot="iCubGenova11")
