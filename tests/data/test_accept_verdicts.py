"""``ftcal check --accept`` never passes what it cannot judge, and does not call a quiet channel broken.

Issue 28 (wrong verdicts) and issue 27 ("a 10-bit channel constant through a still hold called
dead, a channel at its own maximum of 436 of 1023 called saturated"). The sensor is simulated:
raw counts u = round(M w + o + e), a 10-bit converter (0..1023) for the quantised cases, with a
known mixing matrix M; the calibration is an affine model fitted on separate training data.
"""

import numpy as np
import pandas as pd
import pytest

from ftcal import CalibrationModel, Dataset, save_model
from ftcal.check.accept import Thresholds, acceptance_test
from ftcal.cli import main

RNG = np.random.default_rng(11)
M = np.eye(6) * 4.0 + 0.4 * RNG.standard_normal((6, 6))  # counts per N or N·m
O = np.full(6, 512.0)
AXES = ["Fx", "Fy", "Fz", "Tx", "Ty", "Tz"]
U = [f"u{i}" for i in range(1, 7)]
PER_POSE = 300
LOADS = np.array([[0, 0, 0, 0, 0, 0], [40, -10, 30, 1, 2, -1], [-50, 20, -5, -3, 1, 2],
                  [10, 50, -40, 2, -2, 0.5], [-20, -30, 50, -1, -3, 3]], dtype=float)


def counts(w, rng, noise_counts):
    """10-bit readings of wrenches ``w``: noise in counts per channel, then rounding."""
    return np.round(w @ M.T + O + rng.normal(size=w.shape) * noise_counts)


@pytest.fixture(scope="module")
def model_path(tmp_path_factory):
    rng = np.random.default_rng(0)
    w = rng.uniform(-1.0, 1.0, (4000, 6)) * [60, 60, 60, 4, 4, 4]
    u = w @ M.T + O + rng.normal(size=w.shape) * 0.3  # unrounded training data: the fit sees the true gain
    model = CalibrationModel(degree=1).fit(Dataset.from_arrays(u, w, input_names=U, output_names=AXES))
    path = tmp_path_factory.mktemp("verdicts") / "affine.json"
    save_model(model, path)
    return path


def recording(rng, noise_counts, loads=LOADS):
    w = np.repeat(loads, PER_POSE, axis=0)
    frame = pd.DataFrame(np.c_[counts(w, rng, noise_counts), w], columns=U + AXES)
    frame["pose"] = np.repeat([f"p{k}" for k in range(len(loads))], PER_POSE)
    return frame


def accept(capsys, model_path, data, *extra):
    code = main(["check", "--accept", str(model_path), str(data), "--group-by", "pose", *map(str, extra)])
    captured = capsys.readouterr()
    return code, captured.out, captured.err


# Quiet channels (noise 0.02 counts: constant through every still hold) next to flickering ones (0.6 counts).
QUIET = np.array([0.02, 0.6, 0.02, 0.6, 0.02, 0.6])


def test_a_quantised_channel_resting_through_still_holds_is_not_a_fault(capsys, tmp_path, model_path):
    frame = recording(np.random.default_rng(1), QUIET)
    for c in ("u1", "u3", "u5"):  # the quiet channels really rest on one count per pose
        assert all(g.nunique() <= 2 for _, g in frame.groupby("pose")[c])
    path = tmp_path / "quantised.csv"
    frame.to_csv(path, index=False)
    code, out, err = accept(capsys, model_path, path, "--max-force-error", 1e3, "--max-torque-error", 1e3)
    assert code == 0 and not any(line.startswith(("channel:", "unusable:")) for line in out.splitlines()), out + err
    # The channel whose own maximum (far below 1023) is held through a pose is not saturated either.
    assert frame["u1"].max() < 1023


def test_a_channel_that_does_not_follow_a_load_change_is_stuck_even_if_quantised(capsys, tmp_path, model_path):
    frame = recording(np.random.default_rng(2), QUIET)
    frame.loc[PER_POSE:3 * PER_POSE - 1, "u3"] = frame.loc[PER_POSE, "u3"]  # frozen across poses p1 and p2
    path = tmp_path / "stuck.csv"
    frame.to_csv(path, index=False)
    code, out, _ = accept(capsys, model_path, path, "--max-force-error", 1e3, "--max-torque-error", 1e3)
    assert code == 1 and any(line.startswith("channel:") and "u3" in line and "stuck" in line
                             for line in out.splitlines()), out


def test_a_channel_at_the_converters_full_scale_is_saturated(capsys, tmp_path, model_path):
    frame = recording(np.random.default_rng(3), QUIET)
    frame["u2"] = frame["u2"].clip(upper=1023)
    frame.loc[4 * PER_POSE:, "u2"] = 1023.0  # the last pose drives channel 2 to the rail of a 10-bit ADC
    path = tmp_path / "rail.csv"
    frame.to_csv(path, index=False)
    code, out, _ = accept(capsys, model_path, path, "--max-force-error", 1e3, "--max-torque-error", 1e3)
    assert code == 1 and any(line.startswith("channel:") and "u2" in line and "saturated" in line
                             and "1023" in line for line in out.splitlines()), out


@pytest.mark.parametrize("noise", [0.0, 0.6])
def test_a_dead_sensor_fails_even_with_huge_thresholds(capsys, tmp_path, model_path, noise):
    """Every channel reads the unloaded value (plus noise) while the reference load changes by tens of N."""
    frame = recording(np.random.default_rng(4), QUIET)
    rng = np.random.default_rng(5)
    frame[U] = np.round(O + rng.normal(size=(len(frame), 6)) * noise)
    path = tmp_path / "dead.csv"
    frame.to_csv(path, index=False)
    code, out, _ = accept(capsys, model_path, path, "--max-force-error", 1e6, "--max-torque-error", 1e6)
    assert code == 1 and "dead" in out and "FAIL" in out, out


def test_a_reference_of_zero_everywhere_is_unusable(capsys, tmp_path, model_path):
    """A table whose Fx..Tz are ~0 (a forgotten load case) cannot pass a loaded sensor."""
    frame = recording(np.random.default_rng(6), QUIET)
    frame[AXES] = 1e-12
    path = tmp_path / "zero-ref.csv"
    frame.to_csv(path, index=False)
    code, out, _ = accept(capsys, model_path, path, "--max-force-error", 1e6, "--max-torque-error", 1e6)
    assert code == 1 and any(line.startswith("unusable:") and "zero" in line for line in out.splitlines()), out


def test_a_model_without_training_range_gives_no_infinite_percent_threshold(capsys, tmp_path, model_path):
    """Paper XML carries no range: --max-error-percent must not become an infinite threshold."""
    xml = tmp_path / "model.xml"
    assert main(["convert", str(model_path), "--to", "paper-xml", "-o", str(xml)]) == 0
    frame = recording(np.random.default_rng(7), QUIET)
    frame["Fx"] += 50.0  # a calibration 50 N off on Fx
    path = tmp_path / "off.csv"
    frame.to_csv(path, index=False)
    capsys.readouterr()
    code, out, err = accept(capsys, xml, path, "--max-error-percent", 2)
    assert code == 2 and "--rated-force" in err and len(err.strip().splitlines()) == 1, out + err
    code, out, err = accept(capsys, xml, path, "--max-error-percent", 2, "--rated-force", 200)
    assert code == 2 and "--rated-torque" in err, out + err
    code, out, _ = accept(capsys, xml, path, "--max-error-percent", 2, "--rated-force", 200, "--rated-torque", 10)
    assert code == 1 and "thresholds 4 N, 0.2 N·m" in out  # 2 % of 200 N and of 10 N·m


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_a_non_finite_error_never_passes(bad):
    rng = np.random.default_rng(8)
    error = rng.normal(scale=0.01, size=(100, 6))
    labels = np.repeat(["a", "b"], 50)
    error[rng.integers(100), rng.integers(6)] = bad
    result = acceptance_test(error, labels, AXES, Thresholds())
    assert not result.passed and any("non-finite" in p for p in result.problems)
    clean = acceptance_test(np.zeros((100, 6)), labels, AXES, Thresholds())
    assert clean.passed


@pytest.mark.parametrize("limit", [np.nan, np.inf, 0.0])
def test_a_threshold_that_is_not_finite_and_positive_never_passes(limit):
    result = acceptance_test(np.zeros((10, 6)), np.zeros(10), AXES, Thresholds(limit, 0.1))
    assert not result.passed and any("threshold" in p for p in result.problems)
