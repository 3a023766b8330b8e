"""Rank-deficient payload poses: estimate what they determine, report the rest as undetermined.

Known truth: readings are simulated by hand statics (F = m g + f_b, T = c × m g + t_b) from a
tool whose centre of mass is off the sensor axis in x, y and z. Poses that keep the sensor's z
axis vertical (tool down and tool up, turned about the vertical) never let the COM along z make
a torque: it cannot be identified, while mass, COM x/y and all biases can.
"""

import json
import warnings

import numpy as np
import pandas as pd
import pytest
from scipy.spatial.transform import Rotation

from ftcal.cli import main
from ftcal.files.model_json import digest
from ftcal.files.payload_json import load_payload, parse_payload
from ftcal.payload.accumulate import payload_statistics
from ftcal.payload.identify import identify_from_statistics
from ftcal.payload.kinematics import Kinematics
from ftcal.runtime.errors import FtcalError, FtcalWarning, UndeterminedWarning

G = 9.81
MASS = 1.3
COM = np.array([0.012, -0.025, 0.071])
BIAS = np.array([3.0, -2.0, 5.0, 0.1, -0.2, 0.05])
NOISE = np.array([0.3, 0.3, 0.3, 0.01, 0.01, 0.01])
PER_POSE = 40


def vertical_rotations(n_poses, seed):
    """Sensor-to-world rotations keeping the sensor's z axis vertical: turns about z, half of them tool up."""
    rng = np.random.default_rng(seed)
    turns = Rotation.from_euler("z", rng.uniform(-np.pi, np.pi, (n_poses, 1)))
    flip = Rotation.from_euler("x", np.where(np.arange(n_poses) % 2 == 0, 0.0, np.pi)[:, None])
    return turns * flip


def statics(gravity):
    """The wrench the tool and bias put on the sensor, noise-free."""
    return np.c_[MASS * gravity, np.cross(COM, MASS * gravity)] + BIAS


def frame_of(rotations, seed, per_pose=PER_POSE, contact=None):
    rng = np.random.default_rng(seed)
    q = np.repeat(rotations.as_quat(), per_pose, axis=0)
    gravity = np.repeat(rotations.inv().apply([0.0, 0.0, -G]), per_pose, axis=0)
    wrench = statics(gravity) + (0.0 if contact is None else contact)
    if seed is not None:
        wrench = wrench + rng.normal(size=wrench.shape) * NOISE
    frame = pd.DataFrame(np.c_[q, wrench], columns=["qx", "qy", "qz", "qw", "u1", "u2", "u3", "u4", "u5", "u6"])
    frame["pose"] = np.repeat(np.arange(len(rotations)), per_pose)
    frame["time"] = np.arange(len(frame)) * 0.05
    return frame, gravity


def fit_blocks(gravity, wrench, n_blocks=20):
    """identify_from_statistics as ftcal payload calls it: grouped jackknife over contiguous blocks."""
    edges = np.linspace(0, len(gravity), n_blocks + 1).astype(int)
    blocks = [payload_statistics(wrench[a:b], Kinematics(gravity[a:b])) for a, b in zip(edges[:-1], edges[1:])]
    total = blocks[0]
    for b in blocks[1:]:
        total = total + b
    return identify_from_statistics({"all": total}, clusters=blocks, cross_validate=False)


def run(capsys, argv, allowed=()):
    """Run the CLI with every FtcalWarning an error except ``allowed``; returns (stdout, stderr's warning lines)."""
    with warnings.catch_warnings():
        warnings.simplefilter("error", FtcalWarning)
        for kind in allowed:
            warnings.simplefilter("always", kind)
        code = main([str(a) for a in argv])
    out = capsys.readouterr()
    assert code == 0, out.err
    return out.out, [line for line in out.err.splitlines() if line.startswith("warning: ")]


# ---------------------------------------------------------------- (a) z axis always vertical
def test_vertical_z_recovers_mass_and_com_xy_within_their_standard_errors():
    # 100 simulated recordings: the 95 % intervals of what is determined must cover the truth.
    inside = {"mass": 0, "com x": 0, "com y": 0, "torque bias z": 0}
    n_runs = 100
    for seed in range(n_runs):
        rotations = vertical_rotations(10, seed)
        gravity = np.repeat(rotations.inv().apply([0.0, 0.0, -G]), PER_POSE, axis=0)
        wrench = statics(gravity) + np.random.default_rng(1000 + seed).normal(size=(len(gravity), 6)) * NOISE
        with pytest.warns(UndeterminedWarning):
            fit = fit_blocks(gravity, wrench)
        assert fit.undetermined.parameters == ("mcz",)
        assert np.isnan(fit.stderr["com"][2]) and fit.com[2] == 0.0  # held at the stated default, no error bar
        for key, est, se, truth in (("mass", fit.mass, fit.stderr["mass"], MASS),
                                    ("com x", fit.com[0], fit.stderr["com"][0], COM[0]),
                                    ("com y", fit.com[1], fit.stderr["com"][1], COM[1]),
                                    ("torque bias z", fit.torque_bias[2], fit.stderr["torque_bias"][2], BIAS[5])):
            assert se > 0
            inside[key] += abs(est - truth) <= 1.96 * se
    for key, count in inside.items():
        assert count / n_runs >= 0.88, (key, count)


def test_cli_names_the_undetermined_com_and_writes_it(tmp_path, capsys):
    frame, _ = frame_of(vertical_rotations(10, 0), seed=1)
    data, out = tmp_path / "vertical.csv", tmp_path / "p.json"
    frame.to_csv(data, index=False)
    stdout, texts = run(capsys, ["payload", data, "--orientation", "qx,qy,qz,qw", "--group-by", "pose",
                                 "-o", out], allowed=(UndeterminedWarning,))
    assert len(texts) == 1  # warned once
    assert "centre of mass along the sensor's z axis is not determined" in texts[0]
    assert "tilt" in texts[0] and "30°" in texts[0]
    assert "com z" in stdout and "undetermined" in stdout.split("com z")[1].splitlines()[0]
    doc = json.loads(out.read_text())
    assert doc["format_version"] == "1.1"
    assert doc["undetermined"]["parameters"] == ["mcz"] and doc["undetermined"]["held_at_zero"] == ["mcz"]
    assert doc["stderr"]["com"][2] is None and doc["com"][2] == 0.0
    payload = load_payload(out)
    assert payload.undetermined.parameters == ("mcz",)
    assert abs(payload.mass - MASS) < 4 * payload.stderr["mass"]


@pytest.mark.parametrize("drift", ["linear", "random-walk"])
def test_drift_models_hold_the_same_parameter(tmp_path, capsys, drift):
    frame, _ = frame_of(vertical_rotations(10, 2), seed=3)
    data, out = tmp_path / "vertical.csv", tmp_path / "p.json"
    frame.to_csv(data, index=False)
    run(capsys, ["payload", data, "--orientation", "qx,qy,qz,qw", "--time", "time", "--bias-drift", drift,
                 "-o", out], allowed=(UndeterminedWarning,))
    payload = load_payload(out)
    assert payload.drift.model == drift and payload.undetermined.held == ("mcz",)
    assert np.isnan(payload.stderr["com"][2])
    assert abs(payload.mass - MASS) < 4 * payload.stderr["mass"]
    np.testing.assert_array_less(np.abs(payload.com[:2] - COM[:2]), 4 * payload.stderr["com"][:2])


# ---------------------------------------------------------------- (b) one pose: nothing to identify
def test_a_single_pose_is_refused_naming_what_it_confounds(tmp_path, capsys):
    frame, _ = frame_of(vertical_rotations(1, 0), seed=4, per_pose=200)
    data, out = tmp_path / "one.csv", tmp_path / "p.json"
    frame.to_csv(data, index=False)
    code = main(["payload", str(data), "--orientation", "qx,qy,qz,qw", "-o", str(out)])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and not out.exists()
    assert "do not determine the mass" in err[0] and "tilt the sensor" in err[0]
    # Gravity along the sensor's z axis: the mass is confounded with the z force bias only; the
    # force biases across gravity are determined, so they are not named.
    assert "force bias z" in err[0] and "force bias x" not in err[0] and "force bias y" not in err[0]


# ---------------------------------------------------------------- (c) compensation
def test_compensation_is_right_in_determined_poses_and_warns_outside(tmp_path, capsys):
    frame, _ = frame_of(vertical_rotations(10, 5), seed=6)
    data, out = tmp_path / "vertical.csv", tmp_path / "p.json"
    frame.to_csv(data, index=False)
    run(capsys, ["payload", data, "--orientation", "qx,qy,qz,qw", "-o", out], allowed=(UndeterminedWarning,))
    push = np.array([2.0, -1.0, 4.0, 0.3, 0.1, -0.2])  # the contact wrench to recover
    # New samples, noise-free, in poses the identification did not visit but in its span (z vertical).
    inside, _ = frame_of(vertical_rotations(6, 77), seed=None, per_pose=1, contact=push)
    inside_path, inside_out = tmp_path / "inside.csv", tmp_path / "inside-c.csv"
    inside.to_csv(inside_path, index=False)
    run(capsys, ["compensate", out, inside_path, "--orientation", "qx,qy,qz,qw", "-o", inside_out])  # no warning
    contact = pd.read_csv(inside_out)[["Fx", "Fy", "Fz", "Tx", "Ty", "Tz"]].to_numpy()
    np.testing.assert_allclose(contact[:, :3], np.broadcast_to(push[:3], (6, 3)), atol=0.05)
    np.testing.assert_allclose(contact[:, 3:], np.broadcast_to(push[3:], (6, 3)), atol=0.005)
    # Tilted 45°: the held COM z (0 instead of 0.071 m) now makes a torque; the command must say so.
    tilted = Rotation.from_euler("x", [[45.0], [-45.0]], degrees=True)
    outside, _ = frame_of(tilted, seed=None, per_pose=1, contact=push)
    outside_path, outside_out = tmp_path / "outside.csv", tmp_path / "outside-c.csv"
    outside.to_csv(outside_path, index=False)
    _, texts = run(capsys, ["compensate", out, inside_path, outside_path, "--orientation", "qx,qy,qz,qw",
                            "-o", outside_out], allowed=(UndeterminedWarning,))
    assert len(texts) == 1 and "2 of 8 sample(s) lie outside the span" in texts[0] and "(com z)" in texts[0]
    wrong = pd.read_csv(outside_out)[["Tx", "Ty", "Tz"]].to_numpy()[6:]
    expected_error = MASS * G * COM[2] * np.sin(np.pi / 4)  # (0, 0, c_z) × m g at 45°: the torque left over
    assert np.all(np.abs(np.linalg.norm(wrong - push[3:], axis=1) - expected_error) < 0.02)


def test_rebias_keeps_the_undetermined_field(tmp_path, capsys):
    frame, _ = frame_of(vertical_rotations(10, 8), seed=9)
    data, out, retared = tmp_path / "vertical.csv", tmp_path / "p.json", tmp_path / "r.json"
    frame.to_csv(data, index=False)
    run(capsys, ["payload", data, "--orientation", "qx,qy,qz,qw", "-o", out], allowed=(UndeterminedWarning,))
    later, _ = frame_of(vertical_rotations(4, 10), seed=11)
    later[["u1", "u2", "u3"]] += [0.5, 0.0, -0.5]  # the force bias moved by a known amount
    later_path = tmp_path / "later.csv"
    later.to_csv(later_path, index=False)
    run(capsys, ["payload", "--rebias", out, later_path, "--orientation", "qx,qy,qz,qw", "-o", retared])
    old, new = load_payload(out), load_payload(retared)
    assert new.undetermined.parameters == ("mcz",)
    np.testing.assert_allclose(new.force_bias - old.force_bias, [0.5, 0.0, -0.5], atol=0.1)
    # Re-taring from tilted poses: the held COM z leaks into the torque bias; the command says so.
    tilted, _ = frame_of(Rotation.from_euler("y", [[40.0], [-60.0]], degrees=True), seed=15)
    tilted_path = tmp_path / "tilted.csv"
    tilted.to_csv(tilted_path, index=False)
    _, texts = run(capsys, ["payload", "--rebias", out, tilted_path, "--orientation", "qx,qy,qz,qw",
                            "-o", tmp_path / "r2.json"], allowed=(UndeterminedWarning,))
    assert len(texts) == 1 and "the re-tare data: 80 of 80 sample(s) lie outside the span" in texts[0]


# ---------------------------------------------------------------- (d) well excited: nothing changes
def test_well_excited_poses_get_no_warning_and_a_version_1_0_file(tmp_path, capsys):
    frame, _ = frame_of(Rotation.random(12, random_state=3), seed=12)
    data, out = tmp_path / "spread.csv", tmp_path / "p.json"
    frame.to_csv(data, index=False)
    stdout, _ = run(capsys, ["payload", data, "--orientation", "qx,qy,qz,qw", "-o", out])  # warnings are errors
    assert "undetermined" not in stdout
    doc = json.loads(out.read_text())
    assert doc["format_version"] == "1.0" and "undetermined" not in doc
    payload = load_payload(out)
    assert payload.undetermined is None
    np.testing.assert_array_less(np.abs(payload.com - COM), 4 * payload.stderr["com"])


def test_null_standard_errors_need_the_undetermined_field(tmp_path, capsys):
    frame, _ = frame_of(Rotation.random(12, random_state=3), seed=12)
    data, out = tmp_path / "spread.csv", tmp_path / "p.json"
    frame.to_csv(data, index=False)
    run(capsys, ["payload", data, "--orientation", "qx,qy,qz,qw", "-o", out])
    doc = json.loads(out.read_text())
    doc["stderr"]["com"][2] = None
    doc.pop("sha256")
    doc["sha256"] = digest(doc)
    with pytest.raises(FtcalError, match=r"stderr has null entries but no undetermined field"):
        parse_payload(json.dumps(doc), "edited.json")
    doc["format_version"] = "1.1"
    doc.pop("sha256")
    doc["sha256"] = digest(doc)
    with pytest.raises(FtcalError, match=r"1.1 goes with the undetermined field"):
        parse_payload(json.dumps(doc), "edited.json")


def test_convert_says_what_the_target_file_cannot(tmp_path, capsys):
    frame, _ = frame_of(vertical_rotations(10, 13), seed=14)
    data, out, yaml = tmp_path / "vertical.csv", tmp_path / "p.json", tmp_path / "calibration.yaml"
    frame.to_csv(data, index=False)
    run(capsys, ["payload", data, "--orientation", "qx,qy,qz,qw", "-o", out], allowed=(UndeterminedWarning,))
    stdout, _ = run(capsys, ["convert", out, "--to", "ft-tools-ros2", "-o", yaml])
    assert "com z not determined by the identification poses" in stdout


def test_two_gravity_directions_confound_com_along_their_difference_with_a_torque_bias():
    # Tool down (g = −z) and on its side (g = −x) only: gravity changes along (1, 0, −1)/√2, so a first
    # moment along that direction plus a torque bias −(m c) × g₁ reproduces every reading (worked by hand:
    # (1, 0, −1) × (0, 0, −g) = (0, g, 0), a torque bias along y).
    gravity = np.repeat([[0.0, 0.0, -G], [-G, 0.0, 0.0]] * 5, PER_POSE, axis=0)
    wrench = statics(gravity) + np.random.default_rng(21).normal(size=(len(gravity), 6)) * NOISE
    with pytest.warns(UndeterminedWarning, match=r"along the sensor direction \(0\.71, 0\.00, -0\.71\) is "
                                                 r"confounded with the torque bias y"):
        fit = fit_blocks(gravity, wrench)
    assert set(fit.undetermined.parameters) == {"mcx", "mcz", "Ty_bias"} and len(fit.undetermined.held) == 1
    assert np.isnan(fit.stderr["com"][[0, 2]]).all() and np.isnan(fit.stderr["torque_bias"][1])
    # Determined: mass, com y, the force biases and torque biases x, z.
    assert abs(fit.mass - MASS) < 4 * fit.stderr["mass"]
    assert abs(fit.com[1] - COM[1]) < 4 * fit.stderr["com"][1]
    np.testing.assert_array_less(np.abs(fit.force_bias - BIAS[:3]), 4 * fit.stderr["force_bias"])
    np.testing.assert_array_less(np.abs(fit.torque_bias[[0, 2]] - BIAS[[3, 5]]), 4 * fit.stderr["torque_bias"][[0, 2]])
    # The undetermined combination the poses do see is still right: (m c)·(1, 0, 1) and the y torque at g = −z.
    first = fit.mass * fit.com
    assert abs((first[0] + first[2]) - MASS * (COM[0] + COM[2])) < 0.01
    predicted = np.cross(first, [0.0, 0.0, -G])[1] + fit.torque_bias[1]
    assert abs(predicted - (np.cross(MASS * COM, [0.0, 0.0, -G])[1] + BIAS[4])) < 0.01


def test_drift_confounded_with_the_pose_order_is_refused():
    # Gravity's x component grows exactly linearly with time: a bias slope in time along Fx is the same
    # column as (m gx) minus a constant, so the drift cannot be told from the weight; nothing sensible to hold.
    t = np.linspace(0.0, 1.0, 400)
    gx = -5.0 + 8.0 * t
    gravity = np.c_[gx, np.ones_like(t), -np.sqrt(G ** 2 - gx ** 2 - 1.0)]
    wrench = statics(gravity) + np.random.default_rng(0).normal(size=(len(t), 6)) * NOISE
    stats = payload_statistics(wrench, Kinematics(gravity), extra=t[:, None])
    with pytest.raises(FtcalError, match=r"leave the bias's time coefficients undetermined .*revisit early poses"):
        identify_from_statistics({"a": stats}, covariates=("time",))


def test_only_undetermined_parameters_may_lack_a_standard_error(tmp_path, capsys):
    from dataclasses import replace

    from ftcal.files.payload_json import save_payload

    frame, _ = frame_of(vertical_rotations(10, 16), seed=17)
    data, out = tmp_path / "vertical.csv", tmp_path / "p.json"
    frame.to_csv(data, index=False)
    run(capsys, ["payload", data, "--orientation", "qx,qy,qz,qw", "-o", out], allowed=(UndeterminedWarning,))
    payload = load_payload(out)
    broken = replace(payload, stderr=dict(payload.stderr, com=np.array([np.nan, 1e-4, np.nan])))  # com x is determined
    with pytest.raises(FtcalError, match=r"non-finite values"):
        save_payload(broken, tmp_path / "broken.json")
    assert not (tmp_path / "broken.json").exists()


@pytest.mark.parametrize("lapack", ["flipped", "rounds-toward-com-x", "rounds-toward-com-z"])
def test_the_undetermined_report_does_not_depend_on_the_lapack_build(monkeypatch, lapack):
    # Another LAPACK (OpenBLAS core type, thread count) may return either sign for a null vector, and rounds
    # its components differently in the last digits. Emulate both on a null direction whose COM x and z
    # components are equal in exact arithmetic: the held parameter, directions and text must not move.
    from ftcal.payload import identify

    gravity = np.repeat([[0.0, 0.0, -G], [-G, 0.0, 0.0]] * 5, PER_POSE, axis=0)
    wrench = statics(gravity) + np.random.default_rng(21).normal(size=(len(gravity), 6)) * NOISE
    with pytest.warns(UndeterminedWarning):
        reference = fit_blocks(gravity, wrench).undetermined

    eigh = np.linalg.eigh

    def other_build(matrix):
        values, vectors = eigh(matrix)
        vectors = vectors.copy()
        null = values <= values[-1] * 1e-12
        if lapack == "flipped":
            vectors[:, null] *= -1.0
        else:  # parameters are (m, mcx, mcy, mcz, biases...): nudge one COM component by 1e-13
            vectors[1 if lapack.endswith("x") else 3, null] *= 1.0 + 1e-13
        return values, vectors

    monkeypatch.setattr(identify.np.linalg, "eigh", other_build)
    with pytest.warns(UndeterminedWarning):
        other = fit_blocks(gravity, wrench).undetermined
    assert other.held == reference.held and other.parameters == reference.parameters
    assert other.message == reference.message
    np.testing.assert_allclose(other.directions, reference.directions, atol=1e-9)


@pytest.mark.parametrize("vector, expected", [((-0.7071067811865476, 0.0, 0.7071067811865475), (1, 0, -1)),
                                              ((0.7071067811865475, 0.0, -0.7071067811865476), (1, 0, -1)),
                                              ((1e-12, -0.6, 0.8), (0, 1, -1))])
def test_a_reported_direction_has_one_sign(vector, expected):
    # The rule, by hand: the first component within 1e-6 of the largest magnitude is made positive.
    from ftcal.core.directions import canonical_sign

    assert tuple(np.sign(np.round(canonical_sign(np.array(vector)), 9)).astype(int)) == expected
