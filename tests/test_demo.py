"""`ftcal demo`: the simulated paper experiment, end to end through the real readers and iDynTree."""

from __future__ import annotations

import json
from math import comb

import numpy as np
import pandas as pd
import pytest

from ftcal.cli import main
from ftcal.io.model_json import load_model

FORCES = ["Fx", "Fy", "Fz"]


def paper_count(degree: int, n_inputs: int = 7, n_outputs: int = 6) -> int:
    return n_outputs * (1 + sum(comb(n_inputs + p - 1, p) for p in range(1, degree + 1)))


@pytest.fixture(scope="module")
def quick_demo(tmp_path_factory):
    out = tmp_path_factory.mktemp("demo")
    assert main(["demo", "--quick", "--out", str(out)]) == 0
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
    assert set(train["group"]) == set(validation["group"]) == {"l0kg-r0kg", "l0kg-r5kg", "l0kg-r10kg"}
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
