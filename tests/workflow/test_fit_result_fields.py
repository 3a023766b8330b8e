"""``FitResult`` holds numbers and renders its report from them (issue #43), not from stored text.

Each typed field is checked twice: its numbers against an independent computation on the same table
(numpy's least squares and SVD, pandas' min and max, the network's weight count by hand, a simulated
payload with known mass), and a result whose field holds another value renders that other value's text
(the expected text derived from the changed numbers, not written out).
"""

from __future__ import annotations

import warnings
from dataclasses import replace

import numpy as np
import pandas as pd
import pytest

import ftcal
from ftcal.core.columns import DEFAULT_OUTPUTS
from ftcal.payload.unknown_load import payload_column
from ftcal.workflow.fit_report import SearchCost
from ftcal.workflow.fitting import model_report


def _table(seed: int, n: int = 60) -> pd.DataFrame:
    # An affine truth plus a cubic the affine fit cannot follow and noise: a nonzero training error.
    rng = np.random.default_rng(seed)
    u = rng.uniform(-1.0, 1.0, size=n)
    return pd.DataFrame({"u1": u, "Fx": 3.0 * u + 1.0 + 0.4 * u ** 3 + 0.05 * rng.normal(size=n)})


def _load_cases(n_cases: int = 5, n: int = 40) -> pd.DataFrame:
    """Load cases of a cubic sensor, each its own group (``load``), the i-th loaded further than the last."""
    parts = []
    for k in range(n_cases):
        part = _table(k, n)
        part["u1"] *= 0.5 + 0.25 * k
        part["Fx"] = 3.0 * part["u1"] + 1.0 + 0.4 * part["u1"] ** 3 + 0.05 * np.random.default_rng(10 + k).normal(size=n)
        parts.append(part.assign(load=f"L{k}"))
    return pd.concat(parts, ignore_index=True)


def test_the_training_line_is_the_least_squares_rmse_of_the_table():
    frame = _table(0)
    result = ftcal.fit(frame, inputs=["u1"], outputs=["Fx"])
    # numpy's least squares of Fx on [1, u1], independent of ftcal's solver.
    design = np.c_[np.ones(len(frame)), frame["u1"]]
    coef, *_ = np.linalg.lstsq(design, frame["Fx"].to_numpy(), rcond=None)
    rmse = float(np.sqrt(np.mean((frame["Fx"].to_numpy() - design @ coef) ** 2)))
    assert result.lines[-1] == f"training RMSE per output: Fx {rmse:.4g}"  # one output: no wrench block, no unit
    assert result.lines[-1] not in result.preamble  # rendered from the model
    assert result.summary() == "\n".join([*result.preamble, *model_report(result.model)])


def test_the_text_follows_the_model_field():
    first = ftcal.fit(_table(0), inputs=["u1"], outputs=["Fx"])
    other = ftcal.fit(_table(1, n=80), inputs=["u1"], outputs=["Fx"])
    swapped = replace(first, model=other.model)
    assert "samples: 80" in swapped.summary() and "samples: 60" in first.summary()
    assert swapped.lines[-1] == other.lines[-1] != first.lines[-1]


def test_the_written_line_comes_from_output(tmp_path):
    target = tmp_path / "m.json"
    result = ftcal.fit(_table(0), inputs=["u1"], outputs=["Fx"], output=target)
    assert result.lines[-1] == f"wrote {target}" and result.lines[:-1] == replace(result, output=None).lines


def test_the_excitation_line_holds_the_singular_values_of_the_centred_outputs():
    rng = np.random.default_rng(3)
    u = rng.uniform(-1.0, 1.0, size=(200, 2))
    frame = pd.DataFrame({"u1": u[:, 0], "u2": u[:, 1], "Fx": 5.0 * u[:, 0], "Fy": 2.0 * u[:, 1] + 0.3 * u[:, 0]})
    result = ftcal.fit(frame, inputs=["u1", "u2"], outputs=["Fx", "Fy"])
    centred = frame[["Fx", "Fy"]].to_numpy() - frame[["Fx", "Fy"]].to_numpy().mean(axis=0)
    sv = np.linalg.svd(centred, compute_uv=False)  # both forces: scaled alike, so the plain SVD
    np.testing.assert_allclose(result.excitation.singular_values, sv / sv[0], atol=1e-3)
    assert result.excitation.n_excited == 2 and result.lines[0] == result.excitation.summary()
    # Another excitation (the second direction hardly excited) renders its own numbers.
    weak = replace(result.excitation, singular_values=np.array([1.0, sv[1] / sv[0] / 1000]), n_excited=1)
    text = replace(result, excitation=weak).lines[0]
    assert "span 1 of 2 directions" in text and f"{sv[1] / sv[0] / 1000:.2g}" in text
    assert result.to_dict()["excitation"]["n_excited"] == 2


def test_the_comparison_with_affine_is_leave_one_group_out_least_squares():
    frame = _load_cases()
    result = ftcal.fit(frame, inputs=["u1"], outputs=["Fx"], degree=3, group_by="load")
    versus = result.versus_affine
    assert versus.candidate == "np3" and versus.n_folds == 5 and versus.n_groups == 5
    # Five groups in five folds: each fold holds out one load case. numpy's least squares per fold.
    def held_out_rmse(degree):
        scores = []
        for label, held in frame.groupby("load"):
            rest = frame[frame["load"] != label]
            coef = np.polyfit(rest["u1"], rest["Fx"], degree)
            scores.append(np.sqrt(np.mean((np.polyval(coef, held["u1"]) - held["Fx"]) ** 2)))
        return float(np.mean(scores))

    (block,) = versus.blocks
    assert block.error == pytest.approx(held_out_rmse(3), rel=1e-6)
    assert block.affine_error == pytest.approx(held_out_rmse(1), rel=1e-6)
    line = next(line for line in result.lines if line.startswith("grouped cross-validation of np3"))
    assert f"{block.error:.4g}" in line and f"({block.error / block.affine_error:.3g}x)" in line
    # Another comparison (twice the error) renders its own error and ratio.
    worse = replace(versus, blocks=(replace(block, error=2 * block.error),))
    text = replace(result, versus_affine=worse).summary()
    assert f"{2 * block.error:.4g}" in text and f"({2 * block.error / block.affine_error:.3g}x)" in text
    assert line not in text
    frame_of = versus.to_frame()
    assert frame_of.loc[block.name, "ratio"] == pytest.approx(block.error / block.affine_error)
    assert result.to_dict()["versus_affine"]["blocks"][0]["error"] == pytest.approx(block.error)


def test_the_search_renders_its_cost_selection_and_span_from_its_fields():
    frame = _load_cases(4)
    result = ftcal.fit(frame, inputs=["u1"], outputs=["Fx"], degree="auto", group_by="load", max_degree=3, folds=4)
    verdict = result.selection.verdict()
    assert result.summary().count(verdict) == 1
    # A selection that chose otherwise renders its own verdict in the same place.
    other = replace(result.selection, best=result.selection.scores[-1].candidate, selection=[])
    assert replace(result, selection=other).summary().count(other.verdict()) == 1
    # The span: the loads' min and max (pandas), and another span renders its own.
    span = result.span
    low, high = frame["Fx"].min(), frame["Fx"].max()
    assert span.low[0] == pytest.approx(low) and span.high[0] == pytest.approx(high)
    assert f"Fx {low:.3g}..{high:.3g}" in result.summary()
    inside = replace(span, probed=(), high=span.high * 2)
    text = replace(result, span=inside).summary()
    assert "measured inside the training loads' span" in text and f"..{2 * high:.3g}" in text
    # The cost: the budget it was held to, and a budget only degree 1 fits drops the rest, by name.
    cost = result.search_cost
    assert isinstance(cost, SearchCost) and cost.degrees == (1, 2, 3)
    estimate = cost.estimate
    first_only = estimate.spent_seconds + estimate.seconds[0] + estimate.final_seconds[0] + 1e-9
    tight = replace(result, search_cost=replace(cost, budget=first_only))
    dropped = ", ".join(map(str, estimate.degrees[1:]))
    assert f"(--budget {first_only:g} s)" in tight.summary()
    assert any(line.startswith(f"degrees {dropped} not tried") for line in tight.lines)
    assert not any("not tried: estimated" in line for line in result.lines)
    assert result.search_cost.to_frame()["searched"].tolist() == [True, True, True]
    assert tight.search_cost.to_frame()["searched"].tolist() == [True, False, False]
    assert result.to_dict()["search_cost"]["degrees"] == [1, 2, 3]
    # The model file records the search's notes followed by the span and the estimate (as before).
    notes = result.model.solver_info_["cross_validation"]["notes"]
    assert notes[-2:] == [str(span), cost.planned.describe()]


def _payload_table(path, mass=1.5, mc=(0.03, -0.02, 0.05), n=400, seed=0):
    """A linear sensor reading the known wrench plus a payload's: Y (the payload regressor) drawn at random,
    so the wrench it adds is Y @ (m, m·c)."""
    rng = np.random.default_rng(seed)
    known = rng.normal(size=(n, 6)) * [20, 20, 20, 2, 2, 2]
    regressor = rng.normal(size=(n, 6, 4)) * [[10], [10], [10], [1], [1], [1]]
    true = known + regressor @ np.array([mass, *mc])
    gains = np.eye(6) * 100 + np.random.default_rng(1).normal(size=(6, 6))
    raw = true @ gains.T + rng.normal(size=(n, 6)) * 0.5
    table = pd.DataFrame(raw, columns=[f"u{i}" for i in range(1, 7)])
    for i, axis in enumerate(DEFAULT_OUTPUTS):
        table[axis] = known[:, i]
        for k, parameter in enumerate(("m", "mcx", "mcy", "mcz")):
            table[payload_column("tool", axis, parameter)] = regressor[:, i, k]
    table.to_parquet(path)
    return path


def test_the_payload_lines_are_rendered_from_the_estimate(tmp_path):
    path = _payload_table(tmp_path / "payload.parquet")
    result = ftcal.fit(str(path), inputs=[f"u{i}" for i in range(1, 7)], estimate_payload="tool")
    estimate = result.payload
    assert abs(estimate.mass - 1.5) < 4 * estimate.stderr[0]  # the simulated payload, within its error
    assert result.lines[:len(estimate.lines())] == estimate.lines()
    heavier = replace(estimate, values=estimate.values * 2)
    text = replace(result, payload=heavier).summary()
    assert f"  m    {2 * estimate.mass: .6g}" in text and f"  m    {estimate.mass: .6g}" not in text
    assert result.to_dict()["payload"]["values"][0] == pytest.approx(estimate.mass)


def test_the_mlp_lines_are_rendered_from_its_size_and_folds():
    frame = _load_cases(4, n=50)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the network is large for these rows, and may lose to affine: said apart
        result = ftcal.fit(frame, inputs=["u1"], outputs=["Fx"], family="mlp", group_by="load", max_iter=20,
                           folds=4)
    network, validation = result.mlp.network, result.mlp.validation
    sizes = (1, *network.hidden, 1)
    assert network.n_weights == sum(a * b + b for a, b in zip(sizes[:-1], sizes[1:]))  # weights and biases
    assert network.n_rows == len(frame) and result.lines[0] == network.line()
    assert validation.n_folds == 4 and len(validation.affine_fold_scores) == 4
    mean = np.mean(validation.fold_scores)
    assert validation.to_frame()["mlp"].mean() == pytest.approx(mean)
    assert f"{mean:>11.4f}" in result.summary()
    # Other fold scores (twice the error) render their own mean; a smaller network its own size.
    doubled = replace(validation, fold_scores=tuple(2 * v for v in validation.fold_scores))
    assert f"{2 * mean:>11.4f}" in replace(result, mlp=replace(result.mlp, validation=doubled)).summary()
    smaller = replace(network, hidden=(2,), n_weights=(1 * 2 + 2) + (2 * 1 + 1))
    assert replace(result, mlp=replace(result.mlp, network=smaller)).lines[0].startswith("network 1-2-1: 7 weights")
    written_affine = any(line.startswith("written: the affine model") for line in result.lines)
    assert written_affine == bool(validation.lost)
    assert result.to_dict()["mlp"]["network"]["n_weights"] == network.n_weights
