"""``ftcal payload`` and ``ftcal compensate`` end to end, their payload file, and their error paths."""

import json
import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from scipy.spatial.transform import Rotation

from ftcal.cli import main
from ftcal.runtime.errors import FtcalWarning

FTCAL = str(Path(sys.executable).with_name("ftcal"))
G = 9.81
MASS = 0.85
COM = np.array([-0.004, 0.018, 0.062])
BIAS = np.array([-4.0, 2.5, 11.0, 0.3, -0.15, 0.08])
NOISE = np.array([0.2, 0.2, 0.2, 0.008, 0.008, 0.008])
N_POSES, PER_POSE = 16, 30


def poses_frame(seed=0, sign=1.0):
    """Static poses: quaternions (sensor to world), gravity columns and readings m g, c × m g, + bias + noise."""
    rng = np.random.default_rng(seed)
    rot = Rotation.random(N_POSES, random_state=seed + 1)
    q = np.repeat(rot.as_quat(), PER_POSE, axis=0)
    g = np.repeat(rot.inv().apply([0.0, 0.0, -G]), PER_POSE, axis=0)
    clean = np.c_[MASS * g, np.cross(COM, MASS * g)] + BIAS
    wrench = sign * clean + rng.normal(size=clean.shape) * NOISE
    frame = pd.DataFrame(np.c_[q, g, wrench], columns=["qx", "qy", "qz", "qw", "gx", "gy", "gz",
                                                      "u1", "u2", "u3", "u4", "u5", "u6"])
    frame.insert(0, "pose", np.repeat(np.arange(N_POSES), PER_POSE))
    frame["time"] = np.arange(len(frame)) * 0.01
    return frame


@pytest.fixture(scope="module")
def data(tmp_path_factory):
    root = tmp_path_factory.mktemp("payload")
    path = root / "poses.csv"
    poses_frame().to_csv(path, index=False)
    return root, path


def run(capsys, argv):
    with warnings.catch_warnings():
        warnings.simplefilter("error", FtcalWarning)
        code = main([str(a) for a in argv])
    captured = capsys.readouterr()
    assert code == 0, captured.err
    return captured.out, captured.err


def fails(capsys, argv, fragment, output):
    code = main([str(a) for a in argv])
    captured = capsys.readouterr()
    lines = captured.err.strip().splitlines()
    assert code == 2 and len(lines) == 1 and fragment in lines[0], captured.err
    assert not Path(output).exists()
    return lines[0]


def test_payload_recovers_mass_com_bias(capsys, data):
    root, path = data
    out_path = root / "payload.json"
    out, err = run(capsys, ["payload", path, "--orientation", "qx,qy,qz,qw", "--group-by", "pose",
                            "--frame", "ft_sensor", "-o", out_path])
    doc = json.loads(out_path.read_text())
    assert doc["format"] == "ftcal-payload" and doc["frame"] == "ft_sensor" and doc["reaction"] is False
    se = doc["stderr"]
    assert abs(doc["mass"] - MASS) < 4 * se["mass"]
    assert np.all(np.abs(np.array(doc["com"]) - COM) < 4 * np.array(se["com"]))
    assert np.all(np.abs(np.array(doc["force_bias"]) - BIAS[:3]) < 4 * np.array(se["force_bias"]))
    assert np.all(np.abs(np.array(doc["torque_bias"]) - BIAS[3:]) < 4 * np.array(se["torque_bias"]))
    np.testing.assert_allclose(doc["fit"]["residual_rms"], NOISE, rtol=0.15)
    assert "mass" in out and "±" in out and "residual RMS" in out and "cross-validated" in out
    assert "condition number" in out and f"payload from {N_POSES * PER_POSE} samples in {N_POSES} group(s)" in out


def test_gravity_columns_give_the_same_fit(capsys, data):
    root, path = data
    a, b = root / "a.json", root / "b.json"
    run(capsys, ["payload", path, "--orientation", "qx,qy,qz,qw", "-o", a])
    run(capsys, ["payload", path, "--gravity-columns", "gx,gy,gz", "-o", b])
    da, db = json.loads(a.read_text()), json.loads(b.read_text())
    for key in ("mass", "com", "force_bias", "torque_bias"):
        np.testing.assert_allclose(da[key], db[key], rtol=1e-9, atol=1e-12)


def test_compensate_removes_payload_to_noise(capsys, data):
    root, path = data
    payload, out_path = root / "p.json", root / "contact.parquet"
    run(capsys, ["payload", path, "--orientation", "qx,qy,qz,qw", "-o", payload])
    run(capsys, ["compensate", payload, path, "--orientation", "qx,qy,qz,qw", "-o", out_path])
    table = pd.read_parquet(out_path)
    original = pd.read_csv(path)
    assert list(table.columns) == list(original.columns) + ["Fx", "Fy", "Fz", "Tx", "Ty", "Tz"]
    pd.testing.assert_frame_equal(table[original.columns], original)
    contact = table[["Fx", "Fy", "Fz", "Tx", "Ty", "Tz"]].to_numpy()
    np.testing.assert_allclose(np.sqrt(np.mean(contact ** 2, axis=0)), NOISE, rtol=0.15)
    before = np.sqrt(np.mean(original[["u1", "u2", "u3", "u4", "u5", "u6"]].to_numpy() ** 2, axis=0))
    assert np.all(before > 5 * NOISE)


def test_compensate_through_a_calibration_model(capsys, tmp_path):
    from ftcal.core.dataset import Dataset
    from ftcal.core.model import CalibrationModel
    from ftcal.files.model_files import save_model

    # Raw channels r = M⁻¹ (w − o): an affine calibration model maps them back to the wrench.
    frame = poses_frame(seed=3)
    mixing = np.eye(6) + 0.1 * np.random.default_rng(5).standard_normal((6, 6))
    offset = np.array([50.0, -20.0, 10.0, 1.0, 2.0, -3.0])
    wrench = frame[["u1", "u2", "u3", "u4", "u5", "u6"]].to_numpy()
    raw = np.linalg.solve(mixing, (wrench - offset).T).T
    names = ["r1", "r2", "r3", "r4", "r5", "r6"]
    calib = pd.DataFrame(raw, columns=names)
    model = CalibrationModel(1).fit(Dataset.from_arrays(raw, wrench, input_names=tuple(names)))
    save_model(model, tmp_path / "cal.json")
    data_path = tmp_path / "raw.csv"
    pd.concat([frame[["qx", "qy", "qz", "qw"]], calib], axis=1).to_csv(data_path, index=False)
    payload = tmp_path / "p.json"
    frame.to_csv(tmp_path / "poses.csv", index=False)
    run(capsys, ["payload", tmp_path / "poses.csv", "--orientation", "qx,qy,qz,qw", "-o", payload])
    run(capsys, ["compensate", payload, data_path, "--model", tmp_path / "cal.json",
                 "--orientation", "qx,qy,qz,qw", "-o", tmp_path / "out.csv"])
    contact = pd.read_csv(tmp_path / "out.csv")[["Fx", "Fy", "Fz", "Tx", "Ty", "Tz"]].to_numpy()
    np.testing.assert_allclose(np.sqrt(np.mean(contact ** 2, axis=0)), NOISE, rtol=0.15)


def test_negative_mass_offers_reaction(capsys, tmp_path):
    path = tmp_path / "reaction.csv"
    poses_frame(seed=1, sign=-1.0).to_csv(path, index=False)
    out = tmp_path / "p.json"
    line = fails(capsys, ["payload", path, "--orientation", "qx,qy,qz,qw", "-o", out], "--reaction", out)
    assert "negative" in line and "opposite sign convention" in line
    run(capsys, ["payload", path, "--orientation", "qx,qy,qz,qw", "--reaction", "-o", out])
    doc = json.loads(out.read_text())
    assert doc["reaction"] is True and abs(doc["mass"] - MASS) < 4 * doc["stderr"]["mass"]
    # Compensation keeps the readings' sign: what is left is the (negated) noise.
    run(capsys, ["compensate", out, path, "--orientation", "qx,qy,qz,qw", "-o", tmp_path / "c.csv"])
    contact = pd.read_csv(tmp_path / "c.csv")[["Fx", "Fy", "Fz", "Tx", "Ty", "Tz"]].to_numpy()
    np.testing.assert_allclose(np.sqrt(np.mean(contact ** 2, axis=0)), NOISE, rtol=0.15)


def test_reader_rejects_tampered_and_invalid_files(capsys, data, tmp_path):
    from ftcal.files.model_json import digest
    from ftcal.files.payload_json import load_payload
    from ftcal.runtime.errors import FtcalError

    root, path = data
    good = tmp_path / "p.json"
    run(capsys, ["payload", path, "--orientation", "qx,qy,qz,qw", "-o", good])
    doc = json.loads(good.read_text())
    assert load_payload(good).mass == pytest.approx(doc["mass"], rel=0, abs=0)
    tampered = dict(doc, mass=doc["mass"] * 1.1)
    (tmp_path / "t.json").write_text(json.dumps(tampered))
    with pytest.raises(FtcalError, match=r"t.json: the sha256 digest does not match"):
        load_payload(tmp_path / "t.json")
    invalid = {k: v for k, v in doc.items() if k != "com"}
    invalid["sha256"] = digest(invalid)
    (tmp_path / "i.json").write_text(json.dumps(invalid))
    with pytest.raises(FtcalError, match=r"i.json: invalid payload file at \$: 'com' is a required property"):
        load_payload(tmp_path / "i.json")
    (tmp_path / "m.json").write_text(json.dumps({"format": "ftcal-model"}))
    with pytest.raises(FtcalError, match=r"not an ftcal payload file"):
        load_payload(tmp_path / "m.json")
    out = tmp_path / "c.csv"
    fails(capsys, ["compensate", tmp_path / "t.json", path, "--orientation", "qx,qy,qz,qw", "-o", out],
          "sha256 digest does not match", out)


def bad_tables(tmp_path):
    frame = poses_frame(seed=2)
    cases = {}
    missing = frame.drop(columns=["u5"])
    cases["missing"] = (missing, "missing wrench column(s) 'u5'")
    nonunit = frame.copy()
    nonunit.loc[37, "qw"] += 0.05
    cases["nonunit"] = (nonunit, "quaternion columns qx,qy,qz,qw are not unit length at row 37")
    nan = frame.copy()
    nan.loc[5, "u2"] = np.nan
    cases["nan"] = (nan, "column 'u2' has 1 empty, NaN or infinite cell(s), first at line 7")
    fixed = frame.copy()
    fixed[["qx", "qy", "qz", "qw"]] = [0.0, 0.0, 0.0, 1.0]  # one orientation: nothing separates m from bias
    cases["degenerate"] = (fixed, "the poses do not determine the mass")
    cases["too_few"] = (frame.iloc[:1], "1 sample(s) give 6 equations for 10 unknowns")
    paths = {}
    for name, (table, fragment) in cases.items():
        path = tmp_path / f"{name}.csv"
        table.to_csv(path, index=False)
        paths[name] = (path, fragment)
    return paths


def test_bad_input_is_one_line_exit_2_nothing_written(capsys, tmp_path):
    out = tmp_path / "p.json"
    for name, (path, fragment) in bad_tables(tmp_path).items():
        fails(capsys, ["payload", path, "--orientation", "qx,qy,qz,qw", "-o", out], fragment, out)
    good = tmp_path / "good.csv"
    poses_frame().to_csv(good, index=False)
    fails(capsys, ["payload", good, "-o", out], "give the sensor's orientation", out)
    fails(capsys, ["payload", good, "--orientation", "qx,qy,qz", "-o", out], "--orientation needs 4 columns", out)
    fails(capsys, ["payload", good, "--orientation", "qx,qy,qz,qw", "-o", tmp_path / "p.yaml"],
          "must end in .json", tmp_path / "p.yaml")
    fails(capsys, ["payload", tmp_path / "nothere.csv", "--orientation", "qx,qy,qz,qw", "-o", out],
          "no such file", out)
    fails(capsys, ["payload", good, "--gravity-columns", "gx,gy,gz", "--group-by", "nope", "-o", out],
          "no group column 'nope'", out)


def test_output_never_overwrites_an_input(capsys, data, tmp_path):
    root, path = data
    copy = tmp_path / "in.json"
    copy.write_text("{}")
    code = main(["payload", str(copy), "--orientation", "qx,qy,qz,qw", "-o", str(copy)])
    err = capsys.readouterr().err
    assert code == 2 and "is also an input" in err and copy.read_text() == "{}"


def test_dynamic_needs_motion_columns(capsys, data, tmp_path):
    root, path = data
    out = tmp_path / "p.json"
    fails(capsys, ["payload", path, "--orientation", "qx,qy,qz,qw", "--dynamic", "-o", out],
          "missing angular velocity column(s) 'wx', 'wy', 'wz'", out)


def test_real_process_error_is_one_line(tmp_path):
    out = tmp_path / "p.json"
    done = subprocess.run([FTCAL, "payload", str(tmp_path / "nothere.csv"), "--orientation", "qx,qy,qz,qw",
                           "-o", str(out)], capture_output=True, text=True, timeout=120)
    assert done.returncode == 2 and "Traceback" not in done.stderr
    assert done.stderr.strip().splitlines() == [f"ftcal payload: error: {tmp_path / 'nothere.csv'}: no such file."]
    assert not out.exists()


def test_poorly_excited_poses_warn_and_still_write(capsys, tmp_path):
    # The sensor only turns about its own z axis, tilted 3° from the vertical.
    frame = poses_frame(seed=4)
    phi = np.repeat(np.linspace(0.0, 2 * np.pi, N_POSES, endpoint=False), PER_POSE)
    rot = Rotation.from_euler("x", 3.0, degrees=True) * Rotation.from_euler("z", phi[:, None])
    g = rot.inv().apply([0.0, 0.0, -G])
    wrench = np.c_[MASS * g, np.cross(COM, MASS * g)] + BIAS
    frame[["qx", "qy", "qz", "qw"]] = rot.as_quat()
    frame[["u1", "u2", "u3", "u4", "u5", "u6"]] = wrench + np.random.default_rng(0).normal(size=wrench.shape) * NOISE
    path, out = tmp_path / "cone.csv", tmp_path / "p.json"
    frame.to_csv(path, index=False)
    with warnings.catch_warnings():
        warnings.simplefilter("always", FtcalWarning)
        assert main(["payload", str(path), "--orientation", "qx,qy,qz,qw", "-o", str(out)]) == 0
    captured = capsys.readouterr()
    lines = [l for l in captured.err.splitlines() if l.startswith("warning: the poses hardly excite mass")]
    assert lines and "tilt the sensor" in lines[0]
    assert "poorly excited: m," in captured.out and out.exists()


def test_convert_payload_to_ros_files(capsys, data):
    yaml = pytest.importorskip("yaml")
    root, path = data
    payload = root / "for-ros.json"
    run(capsys, ["payload", path, "--orientation", "qx,qy,qz,qw", "--frame", "ft_sensor", "-o", payload])
    doc = json.loads(payload.read_text())
    run(capsys, ["convert", payload, "--to", "ros-yaml", "--com-frame", "tool_com", "-o", root / "ft_calib.yaml"])
    ros1 = yaml.safe_load((root / "ft_calib.yaml").read_text())
    # force_torque_tools keys (ft_calib_node.cpp saveCalibData); values are the payload file's own.
    assert ros1["gripper_mass"] == doc["mass"] and ros1["bias"] == doc["force_bias"] + doc["torque_bias"]
    assert ros1["gripper_com_frame_id"] == "ft_sensor" and ros1["gripper_com_child_frame_id"] == "tool_com"
    assert ros1["gripper_com_pose"] == doc["com"] + [0.0, 0.0, 0.0]
    run(capsys, ["convert", payload, "--to", "ft-tools-ros2", "-o", root / "calibration.yaml"])
    ros2 = yaml.safe_load((root / "calibration.yaml").read_text())
    # ft_tools_ros2 keys (FtParameters::from_yaml).
    assert ros2 == {"mass": doc["mass"], "sensor_frame_to_com": doc["com"],
                    "force_offset": doc["force_bias"], "torque_offset": doc["torque_bias"]}
    fails(capsys, ["convert", payload, "--to", "onnx", "-o", root / "p.onnx"], "ftcal-payload file", root / "p.onnx")
    fails(capsys, ["convert", payload, "--to", "ros-yaml", "-o", root / "p.txt"], "must end in .yaml",
          root / "p.txt")


def test_oversized_payload_file_is_refused_before_reading(capsys, data, tmp_path):
    from ftcal.core.limits import MAX_MODEL_BYTES

    huge = tmp_path / "huge.json"
    with open(huge, "wb") as fh:
        fh.truncate(MAX_MODEL_BYTES + 1)  # sparse: no 100 MB written
    fails(capsys, ["compensate", huge, data[1], "--orientation", "qx,qy,qz,qw", "-o", tmp_path / "c.parquet"],
          "too large for a payload file", tmp_path / "c.parquet")


def _compensate_beyond_training(capsys, tmp_path, quantile: float):
    """Compensate two files with a calibration model trained on r1 up to its ``quantile``.

    The raw channels are the recorded wrench minus 3 (an offset wrench, so the model's wrench is the
    recorded one); the two files are the halves of one table, so both hold rows beyond the training
    range. Returns the command's stderr, the wrench, the training rows and the table's length.
    """
    from ftcal.core.dataset import Dataset
    from ftcal.core.model import CalibrationModel
    from ftcal.files.model_files import save_model

    frame = poses_frame(seed=4)
    wrench = frame[["u1", "u2", "u3", "u4", "u5", "u6"]].to_numpy()
    names = ["r1", "r2", "r3", "r4", "r5", "r6"]
    raw = wrench - 3.0
    inside = raw[:, 0] <= np.quantile(raw[:, 0], quantile)
    save_model(CalibrationModel(1).fit(Dataset.from_arrays(raw[inside], wrench[inside], input_names=tuple(names))),
               tmp_path / "cal.json")
    frame.to_csv(tmp_path / "poses.csv", index=False)
    payload = tmp_path / "p.json"
    run(capsys, ["payload", tmp_path / "poses.csv", "--orientation", "qx,qy,qz,qw", "-o", payload])
    table = pd.concat([frame[["qx", "qy", "qz", "qw"]], pd.DataFrame(raw, columns=names)], axis=1)
    half = len(table) // 2
    table.iloc[:half].to_csv(tmp_path / "a.csv", index=False)
    table.iloc[half:].to_csv(tmp_path / "b.csv", index=False)
    assert np.sum(~inside[:half]) and np.sum(~inside[half:])  # both files hold some
    with warnings.catch_warnings():
        warnings.simplefilter("always", FtcalWarning)
        assert main(["compensate", str(payload), str(tmp_path / "a.csv"), str(tmp_path / "b.csv"), "--model",
                     str(tmp_path / "cal.json"), "--orientation", "qx,qy,qz,qw", "-o", str(tmp_path / "out.csv")]) == 0
    return capsys.readouterr().err, wrench, inside, len(table)


def test_compensate_warns_once_for_all_files_about_inputs_out_of_range(capsys, tmp_path):
    """A calibration model trained on the lower 80 % of r1: both files hold rows beyond it, one warning."""
    err, _, inside, n_rows = _compensate_beyond_training(capsys, tmp_path, 0.8)
    lines = [line for line in err.splitlines() if "outside the training range" in line]
    assert len(lines) == 1, err
    assert lines[0].startswith(f"warning: {np.sum(~inside)} of {n_rows} samples have inputs outside")
    assert "r1 up to" in lines[0]


def test_compensate_names_the_axes_its_model_drives_beyond_the_training_loads(capsys, tmp_path):
    """A calibration model trained on the lower half of r1 (so of Fx): the compensated files load Fx far beyond
    it; the one warning names Fx, the largest predicted load and the training loads' edge."""
    err, wrench, inside, _ = _compensate_beyond_training(capsys, tmp_path, 0.5)
    lines = [line for line in err.splitlines() if "beyond the training loads" in line]
    assert len(lines) == 1, err  # one warning for both files, beside the inputs outside their range
    assert "outside the training range" in lines[0]
    loads = lines[0][lines[0].index("the predicted loads go beyond the training loads on"):]
    top, edge = wrench[:, 0].max(), wrench[inside, 0].max()
    assert f"Fx ({wrench[:, 0].min():.3g}..{top:.3g} against " in loads and f"..{edge:.3g} in training" in loads
