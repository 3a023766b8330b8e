"""`ftcal demo`: the simulated paper experiment, end to end through the real readers and iDynTree."""

from __future__ import annotations

import json
import warnings
from math import comb

import numpy as np
import pandas as pd
import pytest

from ftcal.cli import main
from ftcal.files.model_files import load_model
from ftcal.runtime.errors import FtcalWarning

FORCES = ["Fx", "Fy", "Fz"]


def paper_count(degree: int, n_inputs: int = 7, n_outputs: int = 6) -> int:
    return n_outputs * (1 + sum(comb(n_inputs + p - 1, p) for p in range(1, degree + 1)))


@pytest.fixture(scope="module")
def quick_demo(quick_demo, tmp_path_factory):
    """A copy of the session's quick demo (conftest.py builds it once per run): its folder and summary."""
    import shutil

    out = tmp_path_factory.mktemp("demo") / "ftcal-demo"
    shutil.copytree(quick_demo / "ftcal-demo", out)
    return out, json.loads((out / "summary.json").read_text())


def test_summary_lists_every_model_with_the_paper_counts(quick_demo):
    _, summary = quick_demo
    rows = summary["models"]
    assert [(r["degree"], r["lambda"]) for r in rows] == (
        [(d, None) for d in range(1, 6)] + [(4, lam) for lam in (0.5, 1.0, 10.0, 50.0, 100.0, 200.0)])
    for row in rows:
        assert row["n_coefficients"] == paper_count(row["degree"])
        assert 0 < row["n_nonzero"] <= row["n_coefficients"]
        for part in ("train", "validation"):
            assert set(row[part]) >= {"rmse", "best_fit", "max_abs_error", "force_norm_rmse",
                                      "torque_norm_rmse", "n_samples", "n_out_of_range"}


def test_validation_metrics_match_a_recomputation_from_the_saved_files(quick_demo):
    out, summary = quick_demo
    validation = pd.read_parquet(out / "validation.parquet")
    truth = validation[FORCES].to_numpy()
    for row in summary["models"]:
        name = f"np{row['degree']}" + (f"-lasso{row['lambda']:g}" if row["lambda"] is not None else "")
        model = load_model(out / "models" / f"{name}.json")
        predicted = model.predict(validation[list(model.input_names_)].to_numpy(), warn_out_of_range=False)
        # The paper's "RMSE of force norm", by hand.
        diff = np.linalg.norm(truth, axis=1) - np.linalg.norm(predicted[:, :3], axis=1)
        assert row["validation"]["force_norm_rmse"] == pytest.approx(np.sqrt(np.mean(diff ** 2)), rel=1e-9)
        assert row["validation"]["n_samples"] == len(validation)


def test_every_load_case_is_in_both_training_and_validation(quick_demo):
    out, _ = quick_demo
    train = pd.read_parquet(out / "train.parquet")
    validation = pd.read_parquet(out / "validation.parquet")
    assert set(train["load"]) == set(validation["load"]) == {"l0kg-r0kg", "l0kg-r5kg", "l0kg-r10kg"}
    # Recordings are whole: no segment is split between the two sets.
    assert not set(train["segment"]) & set(validation["segment"])


def test_report_shows_every_model(quick_demo):
    out, summary = quick_demo
    html = (out / "report.html").read_text()
    for row in summary["models"]:
        label = f"np{row['degree']}" + (f" lasso λ={row['lambda']:g}" if row["lambda"] is not None else "")
        assert label in html
    assert "http://" not in html and "https://" not in html


@pytest.mark.slow
def test_full_demo_shows_what_the_paper_shows(tmp_path):
    """The paper's qualitative findings, on the default simulated experiment."""
    assert main(["demo", "--out", str(tmp_path)]) == 0
    rows = json.loads((tmp_path / "summary.json").read_text())["models"]
    plain = {r["degree"]: r for r in rows if r["lambda"] is None}
    lasso = [r for r in rows if r["lambda"] is not None]
    val = {d: r["validation"]["force_norm_rmse"] for d, r in plain.items()}
    train = {d: r["train"]["force_norm_rmse"] for d, r in plain.items()}
    # Higher degrees cut the affine model's validation error (paper: 4.58 N -> 2.09 N) ...
    assert min(val[3], val[4]) < 0.6 * val[1]
    # ... training error keeps falling with degree, but degree 5 overfits (Table II).
    assert all(train[d + 1] < train[d] for d in range(1, 5))
    assert val[5] > val[4]
    # LASSO at degree 4 beats plain least squares at degree 4 for some lambda (Table III).
    assert min(r["validation"]["force_norm_rmse"] for r in lasso) < val[4]


def test_adc_datasets_reach_the_firmware_matrix(quick_demo, tmp_path, capsys):
    """README's firmware path: affine on the demo's ADC counts → matrix file → the board's arithmetic."""
    out, _ = quick_demo
    train = pd.read_parquet(out / "train.parquet")
    train_adc = pd.read_parquet(out / "train-adc.parquet")
    channels = [f"u{i}" for i in range(1, 7)]
    counts = train_adc[channels].to_numpy()
    assert counts.min() >= -32768 and counts.max() <= 32767  # signed 16-bit ADC
    assert train_adc[FORCES].equals(train[FORCES]) and train_adc["T"].equals(train["T"])
    # Counts are an affine image of the logged channels, so affine least squares on either predicts the same.
    design = np.column_stack([train[channels].to_numpy(), np.ones(len(train))])
    design_adc = np.column_stack([counts, np.ones(len(train))])
    y = train[FORCES].to_numpy()
    same = design @ np.linalg.lstsq(design, y, rcond=None)[0]
    np.testing.assert_allclose(design_adc @ np.linalg.lstsq(design_adc, y, rcond=None)[0], same,
                               rtol=0, atol=1e-7 * np.abs(y).max())
    model_path, board = tmp_path / "affine-adc.json", tmp_path / "firmware"
    assert main(["fit", str(out / "train-adc.parquet"), "--inputs", ",".join(channels), "-o", str(model_path)]) == 0
    board.mkdir()
    capsys.readouterr()
    with warnings.catch_warnings():  # the CLI prints its warnings itself
        warnings.simplefilter("always", FtcalWarning)
        assert main(["convert", str(model_path), "--to", "icub-firmware", "--serial", "SN001", "-o", str(board)]) == 0
    assert "warning: The iCub firmware calibration matrix has no offset term" in capsys.readouterr().err
    lines = (board / "matrix_SN001.txt").read_text().split()
    q15 = np.array([int(h, 16) - (0x10000 if int(h, 16) >= 0x8000 else 0) for h in lines[:36]]).reshape(6, 6)
    full_scale = np.array([int(v) for v in lines[37:43]])
    # The board: wrench_i = FS_i · Σ_j (q_ij / 32768) · raw_j / 32767, plus the tare the matrix cannot hold.
    model = load_model(model_path)
    board_wrench = counts @ (full_scale[:, None] * q15 / 32768 / 32767).T
    tare = model.predict(np.zeros((1, 6)), warn_out_of_range=False)[0]
    half_step = full_scale / 32767 / 32768 / 2
    bound = np.abs(counts).sum(axis=1, keepdims=True) * half_step
    assert np.all(np.abs(board_wrench + tare - model.predict(counts, warn_out_of_range=False)) <= bound * 1.001)


def test_firmware_refusal_for_the_wrench_model_says_what_to_fit(quick_demo, tmp_path, capsys):
    out, _ = quick_demo
    model_path = tmp_path / "affine.json"
    assert main(["fit", str(out / "train.parquet"), "-o", str(model_path)]) == 0
    capsys.readouterr()
    assert main(["convert", str(model_path), "--to", "icub-firmware", "-o", str(tmp_path / "m.txt")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "ADC-count channels" in err[0] and "train-adc.parquet" in err[0], err
    assert not (tmp_path / "m.txt").exists()


def test_the_paper_demo_also_records_the_arm_bag(quick_demo):
    """README's ROS example reads ftcal-demo/arm after `make demo`: the arm scenario's ROS 2 bag."""
    from ftcal.data.bags import BagTopics, read_bag
    from ftcal.sim.demo_arm import ARM_DEMO_SCENARIO as s

    out, _ = quick_demo
    stream = read_bag(out / "arm", BagTopics("/ft_sensor/wrench")).ft["/ft_sensor/wrench"]
    # n_poses holds and n_poses - 1 moves at `rate`, both ends included
    assert stream.n_samples == round((s.n_poses * (s.hold_s + s.move_s) - s.move_s) * s.rate) + 1
    assert stream.frame == "ft_sensor"


def test_the_demo_data_are_well_excited(quick_demo, capsys):
    """Several load cases over many poses: every wrench direction excited, no warning from fit, the
    validation recordings inside the training inputs' span, and the arm's payload determines all ten
    parameter directions from its static holds."""
    out, _ = quick_demo
    capsys.readouterr()
    with warnings.catch_warnings():
        warnings.simplefilter("error", FtcalWarning)
        assert main(["fit", str(out / "train.parquet"), "--segment-by", "segment", "--group-by", "load",
                     "-o", str(out / "excited.json")]) == 0
        assert "excitation: reference wrenches span 6 of 6 directions" in capsys.readouterr().out
        assert main(["evaluate", str(out / "excited.json"), str(out / "validation.parquet"), "--json"]) == 0
        # the samples out of range are those outside the training box: none is added by the span check
        inputs = ["u1", "u2", "u3", "u4", "u5", "u6", "T"]
        train, validation = (pd.read_parquet(out / name)[inputs] for name in ("train.parquet", "validation.parquet"))
        outside = ((validation < train.min()) | (validation > train.max())).any(axis=1).sum()
        assert json.loads(capsys.readouterr().out)["n_out_of_range"] == outside
        assert main(["dataset", str(out / "arm"), "--wrench-topic", "/ft_sensor/wrench", "--tf", "base_link",
                     "--no-filter", "-o", str(out / "arm-static.parquet")]) == 0
        assert main(["payload", str(out / "arm-static.parquet"), "--orientation", "qx,qy,qz,qw",
                     "-o", str(out / "arm-static.json")]) == 0
    printed = capsys.readouterr().out
    assert "excluded" in printed and "the poses determine 10 of 10 parameter directions" in printed
