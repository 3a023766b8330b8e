"""The sensors / expected / dataset commands, including their error paths."""

import warnings

import h5py
import numpy as np
import pandas as pd
import pytest
from test_insitu import expected_at, make_recording
from test_logs_mat import logger_tree, write_v5, write_v73
from test_robot_expected import FOREARM, static_wrench
from test_robot_model import TINY_URDF

from ftcal.cli import main

WRENCH = ("Fx", "Fy", "Fz", "Tx", "Ty", "Tz")


@pytest.fixture
def urdf(tmp_path):
    path = tmp_path / "tiny.urdf"
    path.write_text(TINY_URDF)
    return str(path)


def fails(capfd, argv, message):
    """The command exits 2 with exactly one stderr line naming the problem, and no traceback."""
    assert main(argv) == 2
    err = capfd.readouterr().err
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith(f"ftcal {argv[0]}: error: ")
    assert message in lines[0], lines[0]


def test_sensors(capfd, urdf):
    assert main(["sensors", "--urdf", urdf, "--payload", "tool:2@0.1,0,0"]) == 0
    out = capfd.readouterr().out
    line = next(l for l in out.splitlines() if l.strip().startswith("arm_ft"))
    assert line.split() == ["arm_ft", "arm_ft_sensor", "upper", "forearm", "1", "3.5000"]
    assert "joints (1): shoulder" in out
    assert main(["sensors", "--model", "iCubGenova04"]) == 0
    out = capfd.readouterr().out
    assert "F/T sensors (6)" in out and "r_arm_ft_sensor" in out


def test_sensors_errors(capfd, tmp_path):
    bad = tmp_path / "bad.urdf"
    bad.write_text("<robot name='x'><link name='a'/><joint")
    fails(capfd, ["sensors", "--urdf", str(bad)], "bad.urdf does not parse")  # iDynTree's chatter is silenced
    fails(capfd, ["sensors", "--model", "iCubNowhere"], "Unknown robot model 'iCubNowhere'")
    fails(capfd, ["sensors", "--urdf", str(tmp_path / "none.urdf")], "no such file")


@pytest.mark.parametrize("suffix", [".csv", ".parquet"])
def test_expected(capfd, tmp_path, urdf, suffix):
    theta = np.array([0.0, 0.3, -0.8, 1.7])
    joints = tmp_path / "joints.csv"
    pd.DataFrame({"time": np.arange(4.0), "shoulder": theta}).to_csv(joints, index=False)
    out = tmp_path / f"wrench{suffix}"
    assert main(["expected", "--urdf", urdf, "--joints", str(joints), "--sensor", "arm_ft_sensor",
                 "-o", str(out)]) == 0
    frame = pd.read_csv(out) if suffix == ".csv" else pd.read_parquet(out)
    assert list(frame.columns) == ["time", *(f"arm_ft_sensor_{a}" for a in WRENCH)]
    want = np.array([static_wrench([FOREARM], t) for t in theta])
    np.testing.assert_allclose(frame.iloc[:, 1:].to_numpy(), want, atol=1e-9)
    # degrees, all sensors by default, a payload
    pd.DataFrame({"shoulder": np.rad2deg(theta)}).to_parquet(tmp_path / "deg.parquet")
    assert main(["expected", "--urdf", urdf, "--joints", str(tmp_path / "deg.parquet"), "--degrees",
                 "--payload", "forearm:1@0.2,0,0", "-o", str(out)]) == 0
    frame = pd.read_csv(out) if suffix == ".csv" else pd.read_parquet(out)
    np.testing.assert_allclose(frame.to_numpy(), want * 2.5 / 1.5, atol=1e-9)


def test_expected_errors(capfd, tmp_path, urdf):
    joints = tmp_path / "joints.csv"
    out = tmp_path / "out.csv"
    pd.DataFrame({"shoulder": [0.0, 0.1], "wrist": [0.0, 0.0]}).to_csv(joints, index=False)
    fails(capfd, ["expected", "--urdf", urdf, "--joints", str(joints), "-o", str(out)], "'wrist' not in URDF")
    pd.DataFrame({"shoulder": [0.0, np.nan]}).to_csv(joints, index=False)
    fails(capfd, ["expected", "--urdf", urdf, "--joints", str(joints), "-o", str(out)],
          "column 'shoulder' has 1 empty, NaN or infinite cell(s), first at line 3")
    pd.DataFrame({"shoulder": [0.0]}).to_csv(joints, index=False)
    fails(capfd, ["expected", "--urdf", urdf, "--joints", str(joints), "--sensor", "l_arm_ft", "-o", str(out)],
          "no F/T sensor matching 'l_arm_ft'")
    fails(capfd, ["expected", "--urdf", urdf, "--joints", str(joints), "--base", "root_link", "-o", str(out)],
          "no link or frame named 'root_link'")
    fails(capfd, ["expected", "--urdf", urdf, "--joints", str(tmp_path / "nope.csv"), "-o", str(out)],
          "nope.csv: no such file")
    assert not out.exists()


@pytest.fixture
def logs(tmp_path):
    a, b = tmp_path / "l0kg-r0kg" / "a.mat", tmp_path / "l0kg-r1kg" / "b.mat"
    make_recording(a, write_v73)
    make_recording(b, write_v5, payload=(1.0, np.array([0.2, 0.0, 0.0])), layout="channels_first")
    toml = tmp_path / "loads.toml"
    toml.write_text('[convention.right]\nframe = "forearm"\ncom = [0.2, 0.0, 0.0]\n')
    return a, b, toml


def test_dataset_then_fit(capfd, tmp_path, urdf, logs):
    a, b, toml = logs
    out = tmp_path / "data.parquet"
    assert main(["dataset", str(a), str(b), "--urdf", urdf, "--sensor", "arm_ft", "--payload-file", str(toml),
                 "--no-filter", "-o", str(out)]) == 0
    assert "load case(s) l0kg-r0kg, l0kg-r1kg" in capfd.readouterr().out
    frame = pd.read_parquet(out)
    assert list(frame.columns) == ["u1", "u2", "u3", "u4", "u5", "u6", "T", *WRENCH, "time", "shoulder", "static",
                                   "hold", "segment", "load"]
    # the logged joint on the F/T clock (it turns at 0.5 rad/s from t = 0, so never holds still)
    np.testing.assert_allclose(frame["shoulder"], 0.5 * frame["time"], atol=1e-12)
    assert frame["static"].eq(0).all() and frame["hold"].eq(-1).all()
    second = frame[frame["segment"] == 1]
    np.testing.assert_allclose(np.linalg.norm(second[["Fx", "Fy", "Fz"]].to_numpy(), axis=1), 2.5 * 9.81)
    # raw = 100 + 3 · wrench in both recordings, the second one with 1 kg more at the forearm COM
    np.testing.assert_allclose(second[["u1", "u2", "u3", "u4", "u5", "u6"]].to_numpy(),
                               100 + 3 * second[list(WRENCH)].to_numpy(), atol=1e-3)
    pytest.importorskip("ftcal.cli.cmd_fit")
    model = tmp_path / "model.json"
    with warnings.catch_warnings():
        warnings.simplefilter("always")
        assert main(["fit", str(out), "--segment-by", "segment", "--group-by", "load", "-o", str(model)]) == 0
    assert model.is_file()
    # one joint turning the forearm: the reference wrenches span 2 of the 6 directions, which fit says
    assert "warning: reference wrenches span 2 of 6 directions" in capfd.readouterr().err


def test_dataset_smoothing_flags(capfd, tmp_path, urdf, logs):
    a, _, _ = logs
    out = tmp_path / "data.csv"
    assert main(["dataset", str(a), "--urdf", urdf, "--sensor", "arm_ft_sensor", "--savgol-frame", "21",
                 "--no-temperature", "--gravity", "0", "0", "-9.81", "-o", str(out)]) == 0
    frame = pd.read_csv(out)
    assert "T" not in frame.columns and len(frame) > 100
    fails(capfd, ["dataset", str(a), "--urdf", urdf, "--sensor", "arm_ft", "--savgol-frame", "20",
                  "-o", str(out)], "must be odd")


def test_dataset_errors(capfd, tmp_path, urdf, logs):
    a, _, _ = logs
    out = tmp_path / "data.parquet"
    base = ["--urdf", urdf, "-o", str(out)]
    fails(capfd, ["dataset", str(a), *base, "--sensor", "l_arm_ft"], "no F/T sensor matching 'l_arm_ft'")
    truncated = tmp_path / "trunc.mat"
    truncated.write_bytes(a.read_bytes()[:3000])
    fails(capfd, ["dataset", str(truncated), *base, "--sensor", "arm_ft"], "trunc.mat: cannot read")
    t = np.arange(200) * 0.01
    raw = 100 + 3 * expected_at(t) + np.random.default_rng(2).normal(size=(200, 6))
    tree = logger_tree(raw, np.full(200, 30.0), np.c_[0.5 * t], t, t, names=("arm_ft",), joints=["shoulder"])
    del tree["temperatures"]
    fails(capfd, ["dataset", str(write_v73(tmp_path / "notemp.mat", tree)), *base, "--sensor", "arm_ft"],
          "no temperature stream for sensor 'arm_ft'")
    tree = logger_tree(raw, np.full(200, 30.0), np.c_[0.5 * t], t, t, names=("arm_ft",), joints=["shoulder"])
    tree["joints_state"]["positions"]["data"][50:60] = np.nan
    fails(capfd, ["dataset", str(write_v5(tmp_path / "nan.mat", tree)), *base, "--sensor", "arm_ft"],
          "NaN stretch in column 'shoulder' from t=0.500 to t=0.590 s")
    short = logger_tree(raw, np.full(200, 30.0), np.c_[0.5 * t], t, t[:150], names=("arm_ft",), joints=["shoulder"])
    fails(capfd, ["dataset", str(write_v73(tmp_path / "short.mat", short)), *base, "--sensor", "arm_ft"],
          "joints_state.positions.data has shape")
    with h5py.File(tmp_path / "empty.mat", "w") as f:
        f.create_group("robot_logger_device")
    fails(capfd, ["dataset", str(tmp_path / "empty.mat"), *base, "--sensor", "arm_ft"], "no F/T streams")
    bad = tmp_path / "bad.urdf"
    bad.write_text("<robot")
    fails(capfd, ["dataset", str(a), "--urdf", str(bad), "-o", str(out), "--sensor", "arm_ft"], "does not parse")
    fails(capfd, ["dataset", str(a), *base, "--sensor", "arm_ft", "--payload", "forearm:-2"], "mass must be")
    assert not out.exists()


def test_a_recording_the_load_cases_do_not_name_is_refused_with_the_nearest(capfd, tmp_path, urdf):
    """Issue 27: a forgotten or mistyped load case gave the recording no payload, silently."""
    run = tmp_path / "hevy" / "a.mat"  # the case is 'heavy'
    make_recording(run, write_v73)
    toml = tmp_path / "loads.toml"
    toml.write_text('[[load]]\nname = "heavy"\n[[load.payload]]\nframe = "forearm"\nmass = 2.0\n')
    out = tmp_path / "d.parquet"
    fails(capfd, ["dataset", str(run), "--urdf", urdf, "--sensor", "arm_ft", "--payload-file", str(toml),
                  "--no-filter", "-o", str(out)], "matches no load case (loads: 'heavy'; nearest: 'heavy')")
    assert not out.exists()
    typo = tmp_path / "l0kg-r1kgg" / "a.mat"  # the folder convention, mistyped
    make_recording(typo, write_v73)
    toml.write_text('[convention.right]\nframe = "forearm"\n')
    fails(capfd, ["dataset", str(typo), "--urdf", urdf, "--sensor", "arm_ft", "--payload-file", str(toml),
                  "--no-filter", "-o", str(out)], "'l0kg-r1kgg' is not of the form l<x>kg-r<y>kg")
    assert not out.exists()


def test_the_old_case_spelling_builds_the_same_dataset_with_one_notice(capfd, tmp_path, urdf, logs):
    """[[case]] / [[case.payload]] (the old spelling of [[load]]) names the same load case: same table."""
    a, _, _ = logs
    tables = {}
    for key in ("load", "case"):
        toml = tmp_path / f"{key}.toml"
        toml.write_text(f'[[{key}]]\nname = "heavy"\nrecordings = ["a.mat"]\n[[{key}.payload]]\n'
                        'frame = "forearm"\nmass = 2.0\n')
        out = tmp_path / f"{key}.parquet"
        assert main(["dataset", str(a), "--urdf", urdf, "--sensor", "arm_ft", "--payload-file", str(toml),
                     "--no-filter", "-o", str(out)]) == 0
        notices = [line for line in capfd.readouterr().err.splitlines() if line.startswith("notice:")]
        assert len(notices) == (key == "case"), notices
        tables[key] = pd.read_parquet(out)
    assert "[[case]] is now [[load]]" in notices[0]
    assert set(tables["case"]["load"]) == {"heavy"}
    pd.testing.assert_frame_equal(tables["case"], tables["load"])


def test_a_zero_reference_wrench_is_said_and_refused_by_fit(capfd, tmp_path):
    """Nothing beyond the sensor (a massless forearm) and no payload: the reference is 0 everywhere."""
    massless = tmp_path / "massless.urdf"
    massless.write_text(TINY_URDF.replace('<origin xyz="0.2 0 0"/><mass value="1.5"/>',
                                          '<origin xyz="0.2 0 0"/><mass value="0.0"/>'))
    run = tmp_path / "run" / "a.mat"
    make_recording(run, write_v73)
    out = tmp_path / "d.parquet"
    with warnings.catch_warnings():
        warnings.simplefilter("always")
        assert main(["dataset", str(run), "--urdf", str(massless), "--sensor", "arm_ft", "--no-filter",
                     "-o", str(out)]) == 0
    assert "the reference wrench is zero in every sample" in capfd.readouterr().err
    assert np.abs(pd.read_parquet(out)[["Fx", "Fy", "Fz", "Tx", "Ty", "Tz"]].to_numpy()).max() < 1e-6
    fails(capfd, ["fit", str(out), "--degree", "1", "-o", str(tmp_path / "m.json")], "are constant and ~0")
    assert not (tmp_path / "m.json").exists()


# TINY_URDF with a movable wrist beyond the sensor (1 kg 0.1 m along the tool's x) and a neck off the arm.
WRIST_URDF = TINY_URDF.replace(
    '<joint name="tool_fixed" type="fixed">', '<joint name="wrist" type="revolute">').replace(
    '<origin xyz="0.3 0 0" rpy="0 0 1.5707963267948966"/>',
    '<origin xyz="0.3 0 0" rpy="0 0 1.5707963267948966"/><axis xyz="0 0 1"/>'
    '<limit lower="-3" upper="3" effort="10" velocity="1"/>').replace(
    '<link name="tool"/>',
    '<link name="tool"><inertial><origin xyz="0.1 0 0"/><mass value="1.0"/>'
    '<inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/></inertial></link>'
    '<link name="head"/><joint name="neck" type="revolute"><parent link="base"/><child link="head"/>'
    '<axis xyz="0 0 1"/><limit lower="-3" upper="3" effort="10" velocity="1"/></joint>')


def tool_in_sensor(wrist):
    """The tool mass's position in the sensor (= forearm) frame, by hand: (0.3, 0, 0) + Rz(π/2 + wrist)·(0.1, 0, 0)."""
    return np.array([0.3 - 0.1 * np.sin(wrist), 0.1 * np.cos(wrist), 0.0])


def test_expected_refuses_a_missing_joint_the_wrench_depends_on(capfd, tmp_path):
    urdf = tmp_path / "wrist.urdf"
    urdf.write_text(WRIST_URDF)
    theta, wrist = np.array([0.3, -0.8]), np.array([0.5, -1.1])
    joints, out = tmp_path / "joints.csv", tmp_path / "out.csv"
    argv = ["expected", "--urdf", str(urdf), "--joints", str(joints), "--no-cache", "-o", str(out)]
    # the wrist (beyond the sensor) moves the tool's mass: without its column, refused
    pd.DataFrame({"shoulder": theta}).to_csv(joints, index=False)
    fails(capfd, argv, "no data for joint(s) 'wrist'")
    assert not out.exists()
    # the shoulder (between base and sensor) turns gravity: refused too, and the hint names the option
    pd.DataFrame({"wrist": wrist}).to_csv(joints, index=False)
    fails(capfd, argv, "--missing-joints zero")
    # the user says the wrist is at 0 rad: the tool hangs at (0.3, 0.1, 0)
    pd.DataFrame({"shoulder": theta}).to_csv(joints, index=False)
    assert main([*argv, "--missing-joints", "zero"]) == 0
    want = [static_wrench([FOREARM, (1.0, tool_in_sensor(0.0))], t) for t in theta]
    np.testing.assert_allclose(pd.read_csv(out).to_numpy(), want, atol=1e-9)
    # every joint that matters given, the neck (off the arm) left out: accepted, wrist where the table says
    pd.DataFrame({"shoulder": theta, "wrist": wrist}).to_csv(joints, index=False)
    assert main(argv) == 0
    want = [static_wrench([FOREARM, (1.0, tool_in_sensor(w))], t) for t, w in zip(theta, wrist)]
    np.testing.assert_allclose(pd.read_csv(out).to_numpy(), want, atol=1e-9)
