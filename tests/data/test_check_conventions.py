"""``ftcal check DATA``: each convention error injected into a simulated recording is found, with the right fix.

The recordings are simulated here, independently of ftcal: random sensor orientations held
still (with slerp motion between them), a tool of known mass and centre of mass, a known bias
and noise, in ftcal's sign convention (a mass m at rest reads m·g in the sensor frame). Each
error is then injected as the physical mistake it stands for, and the expected fix is worked
out by hand from that mistake.
"""

import math
import re
import warnings

import numpy as np
import pandas as pd
import pytest
from scipy.spatial.transform import Rotation, Slerp

from ftcal.check.conventions import check_conventions, rotation_from_rpy
from ftcal.data.holds import find_holds, hold_averages
from ftcal.cli import main
from ftcal.runtime.errors import FtcalError, FtcalWarning

G = 9.81
MASS = 1.2
COM = np.array([0.01, -0.02, 0.08])
BIAS = np.array([3.0, -2.0, 5.0, 0.2, -0.1, 0.05])
NOISE = np.array([0.2, 0.2, 0.2, 0.01, 0.01, 0.01])
PER_HOLD, MOVE = 150, 25


def recording(seed=0, n_holds=8):
    """Readings (n, 6), sensor-to-world rotations (n, 3, 3) and hold index (-1 while moving)."""
    rng = np.random.default_rng(seed)
    rots = Rotation.random(n_holds, random_state=seed + 100)
    mats, hold = [], []
    for k in range(n_holds):
        mats += [rots[k].as_matrix()] * PER_HOLD
        hold += [k] * PER_HOLD
        if k + 1 < n_holds:
            path = Slerp([0.0, 1.0], Rotation.concatenate([rots[k], rots[k + 1]]))
            mats += list(path(np.linspace(0.0, 1.0, MOVE + 2)[1:-1]).as_matrix())
            hold += [-1] * MOVE
    rotation = np.array(mats)
    gravity = np.einsum("nji,j->ni", rotation, [0.0, 0.0, -G])  # Rᵀ (0, 0, −g)
    clean = np.c_[MASS * gravity + BIAS[:3], np.cross(COM, MASS * gravity) + BIAS[3:]]
    return clean + rng.normal(size=clean.shape) * NOISE, rotation, np.array(hold)


def gravity_of(rotation):
    return np.einsum("nji,j->ni", rotation, [0.0, 0.0, -G])


def averages(wrench, rotation):
    """Per-hold means, the holds found from the gravity direction (rows 10 ms apart)."""
    gravity = gravity_of(rotation)
    holds = find_holds(np.arange(len(wrench)) * 0.01, gravity=gravity)
    return hold_averages(holds, wrench, gravity, rotation)


def findings(wrench, rotation, **kwargs):
    return check_conventions(averages(wrench, rotation), **kwargs).findings


def both(matrix, wrench):
    """The same 3 × 3 map applied to force and torque."""
    return np.c_[wrench[:, :3] @ matrix.T, wrench[:, 3:] @ matrix.T]


@pytest.mark.parametrize("seed", range(12))
def test_a_correct_recording_has_no_finding(seed):
    wrench, rotation, _ = recording(seed, n_holds=4 + seed % 6)
    assert findings(wrench, rotation) == []


def test_holds_are_the_still_stretches():
    wrench, rotation, hold = recording(3)
    holds = averages(wrench, rotation)
    assert holds.n_holds == 8
    for k in range(8):
        rows = np.flatnonzero(hold == k)
        assert holds.start[k] == rows[0] and holds.stop[k] == rows[-1] + 1


def test_reaction_sign_is_found_and_fixed_by_reaction():
    wrench, rotation, _ = recording(1)
    (f,) = findings(-wrench, rotation)
    assert f.kind == "sign" and f.fix == "--reaction" and f.reaction and f.confidence > 0.999


def test_left_handed_frame_is_a_mirror_fixed_by_reaction_and_a_half_turn():
    wrench, rotation, _ = recording(2)
    mirror = np.diag([1.0, -1.0, 1.0])  # the sensor's y axis points the other way
    (f,) = findings(both(mirror, wrench), rotation)
    assert f.kind == "handedness" and f.reaction and "--reaction" in f.fix
    # −diag(1, −1, 1) = diag(−1, 1, −1): a half turn about y.
    np.testing.assert_allclose(rotation_from_rpy(f.rpy), np.diag([-1.0, 1.0, -1.0]), atol=1e-9)
    assert "y axis is reversed" in f.message
    assert f.before[0] > 1.0 and f.after[0] < 0.05


def test_permuted_columns_are_found_and_fixed_by_reordering_the_wrench_columns():
    wrench, rotation, _ = recording(4)
    swap = np.eye(3)[[1, 0, 2]]  # the column named Fx holds Fy and vice versa (and the torques)
    (f,) = findings(both(swap, wrench), rotation, wrench_columns=("Fx", "Fy", "Fz", "Tx", "Ty", "Tz"))
    assert f.kind == "permutation" and f.wrench == ("Fy", "Fx", "Fz", "Ty", "Tx", "Tz")
    assert f.fix == "--inputs Fy,Fx,Fz,Ty,Tx,Tz"


@pytest.mark.parametrize("axis, degrees", [("x", 2.0), ("z", -2.0), ("z", 90.0), ("y", -90.0)])
def test_a_sensor_turned_on_its_flange_is_found_with_the_rotation_to_declare(axis, degrees):
    wrench, rotation, _ = recording(5)
    # The real sensor frame S' is the declared S turned by `degrees` about `axis`: a vector's
    # S' coordinates are R(θ)ᵀ times its S coordinates, so the readings are R(θ)ᵀ w.
    turn = Rotation.from_euler(axis, degrees, degrees=True).as_matrix()
    (f,) = findings(both(turn.T, wrench), rotation)
    assert f.kind == "rotation" and f.confidence > 0.999
    error = Rotation.from_matrix(rotation_from_rpy(f.rpy) @ turn.T).magnitude()
    assert math.degrees(error) < 0.1
    assert f.after[0] < 0.05 < f.before[0]


def test_a_quarter_degree_is_within_mounting_tolerance():
    wrench, rotation, _ = recording(6)
    turn = Rotation.from_euler("x", 0.25, degrees=True).as_matrix()
    assert findings(both(turn.T, wrench), rotation) == []


def test_a_wrench_in_the_base_frame_is_found():
    wrench, rotation, _ = recording(7)
    based = np.c_[np.einsum("nij,nj->ni", rotation, wrench[:, :3]), np.einsum("nij,nj->ni", rotation, wrench[:, 3:])]
    (f,) = findings(based, rotation)
    assert f.kind == "base-frame" and "F_sensor = Rᵀ F_base" in f.fix
    assert f.after[0] < 0.05 < 1.0 < f.before[0]


def test_a_pre_tared_gravity_compensated_stream_is_found():
    wrench, rotation, _ = recording(8)
    g = gravity_of(rotation)
    contact = wrench - np.c_[MASS * g + BIAS[:3], np.cross(COM, MASS * g) + BIAS[3:]]  # what the driver outputs
    (f,) = findings(contact, rotation)
    assert f.kind == "compensated" and "tared" in f.message and f.confidence > 0.999


def test_a_compensated_stream_with_bias_left_is_told_apart_from_a_tared_one():
    wrench, rotation, _ = recording(9)
    g = gravity_of(rotation)
    (f,) = findings(wrench - np.c_[MASS * g, np.cross(COM, MASS * g)], rotation)
    assert f.kind == "compensated" and "constant offset" in f.message


def test_a_stream_zeroed_with_the_tool_on_is_found():
    wrench, rotation, hold = recording(10)
    (f,) = findings(wrench - wrench[hold == 2].mean(axis=0), rotation)
    assert f.kind == "zeroed" and "hold 3" in f.message


def test_a_sensor_that_reads_nothing_is_a_finding_not_a_pass(capsys, tmp_path):
    # An unpowered sensor or a driver publishing a default message: all zeros, or one value, in every sample.
    # Before: "no finding" and exit 0 for all zeros (the mass test only said "too noisy").
    _, rotation, _ = recording(12)
    for reading in (np.zeros(6), np.array([1.5, -2.0, 3.0, 0.0, 0.0, 0.0])):
        (f,) = findings(np.tile(reading, (len(rotation), 1)), rotation)
        assert f.kind == "no-signal" and "not measuring" in f.message
        code, out, _ = check(capsys, write(tmp_path, np.tile(reading, (len(rotation), 1)), rotation))
        assert code == 1 and "no-signal" in out and "no finding" not in out
    # a live force stream with dead torque channels (a force-only sensor's zero columns) is no such finding
    wrench, rotation, _ = recording(12)
    wrench[:, 3:] = 0.0
    assert all(f.kind != "no-signal" for f in findings(wrench, rotation))


def test_torques_about_another_point_give_an_implausible_com():
    wrench, rotation, _ = recording(11)
    point = np.array([0.0, 0.0, 0.5])  # e.g. a tool centre point 0.5 m out
    moved = np.c_[wrench[:, :3], wrench[:, 3:] - np.cross(point, wrench[:, :3])]
    (f,) = findings(moved, rotation)
    assert f.kind == "lever"
    # T_p = (c − p) × m g + ...: the apparent centre of mass is c − p.
    shown = re.search(r"comes out at \(([^)]*)\) m", f.message).group(1)
    np.testing.assert_allclose([float(v) for v in shown.split(",")], COM - point, atol=2e-3)


def test_too_few_or_too_similar_holds_are_refused():
    wrench, rotation, hold = recording(12, n_holds=2)
    with pytest.raises(FtcalError, match="2 static hold"):
        check_conventions(averages(wrench, rotation))
    still = np.repeat(rotation[:1], len(rotation), axis=0)
    with pytest.raises(FtcalError, match="no static hold|1 static hold"):
        check_conventions(averages(wrench, still))


# ---------------------------------------------------------------- the command line

def write(tmp_path, wrench, rotation, name="rec.csv"):
    frame = pd.DataFrame(np.c_[Rotation.from_matrix(rotation).as_quat(), wrench],
                         columns=["qx", "qy", "qz", "qw", "Fx", "Fy", "Fz", "Tx", "Ty", "Tz"])
    path = tmp_path / name
    frame.to_csv(path, index=False)
    return path


def check(capsys, path, *extra):
    with warnings.catch_warnings():
        warnings.simplefilter("error", FtcalWarning)
        code = main(["check", str(path), "--inputs", "Fx,Fy,Fz,Tx,Ty,Tz", "--orientation", "qx,qy,qz,qw",
                     *map(str, extra)])
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def test_cli_exit_codes_and_the_printed_fix_works(capsys, tmp_path):
    wrench, rotation, _ = recording(13)
    good = write(tmp_path, wrench, rotation, "good.csv")
    assert check(capsys, good)[0] == 0
    swapped = write(tmp_path, both(np.eye(3)[[1, 0, 2]], wrench), rotation, "swapped.csv")
    code, out, _ = check(capsys, swapped)
    assert code == 1 and "fix: --inputs Fy,Fx,Fz,Ty,Tx,Tz" in out
    # The printed fix, applied, leaves nothing to report.
    with warnings.catch_warnings():
        warnings.simplefilter("error", FtcalWarning)
        assert main(["check", str(swapped), "--inputs", "Fy,Fx,Fz,Ty,Tx,Tz", "--orientation", "qx,qy,qz,qw"]) == 0
    reaction = write(tmp_path, -wrench, rotation, "reaction.csv")
    code, out, _ = check(capsys, reaction)
    assert code == 1 and "fix: --reaction" in out
    assert check(capsys, reaction, "--reaction")[0] == 0
    code, out, _ = check(capsys, good, "--reaction")
    assert code == 1 and "fix: leave out --reaction" in out


def test_cli_html_page(capsys, tmp_path):
    wrench, rotation, _ = recording(14)
    path = write(tmp_path, both(Rotation.from_euler("z", 90, degrees=True).as_matrix(), wrench), rotation)
    page = tmp_path / "check.html"
    code, out, err = check(capsys, path, "--html", page)
    assert code == 1 and "finding 1: rotation" in out and f"wrote {page}" in err
    text = page.read_text()
    assert "rotation" in text and "<img" in text and "Residuals by hold" in text


def test_cli_bad_input_is_one_line(capsys, tmp_path):
    wrench, rotation, _ = recording(15, n_holds=2)
    path = write(tmp_path, wrench, rotation)
    code, _, err = check(capsys, path)
    assert code == 2 and len(err.strip().splitlines()) == 1 and "at least 3" in err
    assert main(["check", str(path), "--inputs", "Fx,Fy,Fz,Tx,Ty,Nope", "--orientation", "qx,qy,qz,qw"]) == 2
    assert "Nope" in capsys.readouterr().err


def test_payload_warns_on_base_frame_data_and_not_on_good_data(capsys, tmp_path):
    wrench, rotation, _ = recording(16)
    good = write(tmp_path, wrench, rotation, "good.csv")
    args = ["--inputs", "Fx,Fy,Fz,Tx,Ty,Tz", "--orientation", "qx,qy,qz,qw"]
    with warnings.catch_warnings():
        warnings.simplefilter("error", FtcalWarning)
        assert main(["payload", str(good), *args, "-o", str(tmp_path / "p.json")]) == 0
    capsys.readouterr()
    based = np.c_[np.einsum("nij,nj->ni", rotation, wrench[:, :3]), np.einsum("nij,nj->ni", rotation, wrench[:, 3:])]
    path = write(tmp_path, based, rotation, "based.csv")
    with warnings.catch_warnings():
        warnings.simplefilter("always", FtcalWarning)
        main(["payload", str(path), *args, "-o", str(tmp_path / "q.json")])  # may also refuse a negative mass
    err = capsys.readouterr().err
    assert "warning: the data look base-frame-wrong" in err


@pytest.mark.slow
def test_joints_and_urdf_route_finds_a_sensor_turned_on_the_flange(capsys, tmp_path):
    """UR5 joints + --urdf/--ft-joint; gravity composed by hand from the URDF (tests/data/test_robot_declare.py)."""
    from test_robot_declare import UR5, ur5_chain_rotation

    if not UR5.is_file():
        pytest.skip("example-robot-data is not installed")
    rng = np.random.default_rng(17)
    names = ["shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint", "wrist_1_joint", "wrist_2_joint",
             "wrist_3_joint"]
    q = rng.uniform(-2.5, 2.5, (7, 6))
    g = np.array([ur5_chain_rotation(qk, "ee_link")[0].T @ [0.0, 0.0, -G] for qk in q])
    clean = np.c_[MASS * g + BIAS[:3], np.cross(COM, MASS * g) + BIAS[3:]]
    turn = Rotation.from_euler("z", 90, degrees=True).as_matrix()  # mounted a quarter turn off the URDF
    rows = np.repeat(np.arange(len(q)), 40)
    wrench = both(turn.T, clean[rows]) + rng.normal(size=(len(rows), 6)) * NOISE
    frame = pd.DataFrame(np.c_[q[rows], wrench], columns=names + ["Fx", "Fy", "Fz", "Tx", "Ty", "Tz"])
    frame["pose"] = rows
    path = tmp_path / "joints.csv"
    frame.to_csv(path, index=False)
    args = ["check", str(path), "--inputs", "Fx,Fy,Fz,Tx,Ty,Tz", "--urdf", str(UR5), "--ft-joint", "ee_fixed_joint",
            "--base", "base_link", "--group-by", "pose"]
    assert main(args) == 1
    out = capsys.readouterr().out
    assert "rotation" in out and 'rpy="0 0 1.5708"' in out and "--ft-frame" in out
    assert "base-frame readings not tested" in out


@pytest.mark.parametrize("dof", [1, 2, 3, 4, 7])
def test_chi2_in_closed_form_matches_scipy_stats(dof):
    # The convention check's χ² without importing scipy.stats (most of a second): the library is the reference.
    from scipy.stats import chi2

    from ftcal.check.conventions import chi2_cdf, chi2_quantile

    for x in (1e-3, 0.5, 3.84, 11.3, 60.0):
        assert chi2_cdf(x, dof) == pytest.approx(chi2.cdf(x, dof), abs=1e-12)
    for probability in (0.5, 0.95, 0.999):
        assert chi2_quantile(probability, dof) == pytest.approx(chi2.ppf(probability, dof), rel=1e-9)
