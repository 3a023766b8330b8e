"""Selection per output and per block, judged on force and torque; relative λ; cost; saturation; incomplete rows."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from ftcal.core.dataset import Dataset
from ftcal.core.model import CalibrationModel
from ftcal.core.select import (
    SaturationWarning,
    SelectionLossWarning,
    estimate_cost,
    fit_selection,
    select_model,
)

OUTPUTS = ("Fx", "Fy", "Fz", "Tx", "Ty", "Tz")


def sensor(rng, n_groups=24, per_group=30, group_offset=0.0, torque_noise=0.02, spread=0.08):
    """Three channels held at ``n_groups`` poses (small variation within a pose).

    Forces are cubic in the channels (degree 3 needed), torques affine plus sample
    noise and, with ``group_offset``, an error constant over each load case (a
    mis-measured load): polynomials of higher degree can only fit those offsets.
    """
    base = rng.uniform(-1.0, 1.0, (n_groups, 1, 3))
    u = (base + spread * rng.standard_normal((n_groups, per_group, 3))).reshape(-1, 3)
    forces = 10.0 * np.c_[u[:, 0] + 0.8 * u[:, 0] ** 3 + 0.5 * u[:, 1] * u[:, 2] ** 2,
                          u[:, 1] - 0.7 * u[:, 1] ** 3 + 0.4 * u[:, 0] ** 2 * u[:, 2],
                          u[:, 2] + 0.6 * u[:, 2] ** 3 - 0.5 * u[:, 0] * u[:, 1] * u[:, 2]]
    torques = u @ np.array([[0.5, 0.1, 0.0], [0.0, 0.4, -0.2], [0.1, 0.0, 0.3]]) + 0.05
    torques = torques + torque_noise * rng.standard_normal(torques.shape)
    torques += group_offset * np.repeat(rng.standard_normal((n_groups, 3)), per_group, axis=0)
    forces += 0.02 * rng.standard_normal(forces.shape)
    groups = np.repeat([f"case{g}" for g in range(n_groups)], per_group)
    return Dataset.from_arrays(u * 100.0 + 500.0, np.c_[forces, torques], input_names=("a", "b", "c"),
                               output_names=OUTPUTS, groups=groups)


def quiet(function, *args, **kwargs):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return function(*args, **kwargs)


def test_per_output_selection_recovers_cubic_forces_and_affine_torques(rng):
    data = sensor(rng)
    # Degree 2 may not improve an odd function: try every degree.
    result = quiet(select_model, data, degrees=(1, 2, 3), penalties=(), select_per="output", stop_early=False)
    assert [c.degree for c in result.candidate_of_output()] == [3, 3, 3, 1, 1, 1]
    # One model at the largest degree; each output predicts exactly as its own candidate fitted alone.
    model = fit_selection(result)
    assert model.layout_.basis.degree == 3
    cubic, affine = CalibrationModel(3).fit(data), CalibrationModel(1).fit(data)
    fresh = sensor(np.random.default_rng(7)).inputs
    expected = np.c_[cubic.predict(fresh, warn_out_of_range=False)[:, :3],
                     affine.predict(fresh, warn_out_of_range=False)[:, 3:]]
    got = model.predict(fresh, warn_out_of_range=False)
    np.testing.assert_allclose(got, expected, rtol=0, atol=1e-9 * np.abs(expected).max())
    # The torque columns hold exact zeros for every term above degree 1.
    high = [i for i, combo in enumerate(model.layout_.basis.combinations) if len(combo) > 1]
    assert np.all(model.coef_[high, 3:] == 0.0) and np.all(model.coef_[high, :3] != 0.0)
    assert model.solver_info_["name"] == "per-output selection"


def test_mixed_penalties_embed_exactly_through_a_change_of_basis(rng, tmp_path):
    from ftcal.files.model_files import load_model, save_model

    data = sensor(rng)
    result = quiet(select_model, data, degrees=(1, 2, 3), penalties=("ridge",), select_per="output")
    chosen = result.candidate_of_output()
    model = fit_selection(result)
    fresh = sensor(np.random.default_rng(8)).inputs
    for j, candidate in enumerate(chosen):
        alone = quiet(CalibrationModel(candidate.degree, solver=candidate.solver()).fit, data)
        expected = alone.predict(fresh, warn_out_of_range=False)[:, j]
        np.testing.assert_allclose(model.predict(fresh, warn_out_of_range=False)[:, j], expected, rtol=0,
                                   atol=1e-8 * np.abs(expected).max())
    model.training_metrics_ = model.metrics(data, warn_out_of_range=False)
    save_model(model, tmp_path / "m.json")
    np.testing.assert_array_equal(load_model(tmp_path / "m.json").predict(fresh, warn_out_of_range=False),
                                  model.predict(fresh, warn_out_of_range=False))


def test_force_and_torque_side_by_side_and_a_model_that_loses_on_torque_is_flagged():
    # Torque is affine with a per-load-case error: a cubic fits those errors and loses on new load cases.
    data = sensor(np.random.default_rng(0), n_groups=14, group_offset=0.2, spread=0.03)
    with pytest.warns(SelectionLossWarning, match="torque"):
        result = quiet_except(SelectionLossWarning, select_model, data, degrees=(1, 2, 3), penalties=(),
                              select_per="model", objective="force", stop_early=False)
    assert result.best.degree == 3 and result.losses() == ["torque"]
    assert "torque" in result.verdict() and "WORSE than np1" in result.verdict()
    summary = result.summary()
    assert "val force N" in summary and "val torque N·m" in summary
    # Independent check of the flag: the fold-by-fold torque error-norm RMSE of np3 and np1 from numpy.
    from ftcal.core.select import grouped_folds

    def torque_rmse(degree, mask):
        model = CalibrationModel(degree).fit(data.subset(~mask))
        error = model.predict(data.subset(mask), warn_out_of_range=False)[:, 3:] - data.outputs[mask, 3:]
        return np.sqrt(np.mean(np.sum(error ** 2, axis=1)))

    difference = np.array([torque_rmse(1, m) - torque_rmse(3, m) for m in grouped_folds(data.groups, 5)])
    assert difference.mean() < -2 * difference.std(ddof=1) / np.sqrt(difference.size)
    assert result.block_comparisons()["torque"].margin == pytest.approx(difference.mean(), rel=1e-6)
    # Chosen per block, torque stays affine and nothing is lost.
    per_block = quiet(select_model, data, degrees=(1, 2, 3), penalties=(), select_per="block", stop_early=False)
    assert per_block.losses() == [] and [c.degree for c in per_block.candidate_of_output()][3:] == [1, 1, 1]


def quiet_except(kind, function, *args, **kwargs):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        warnings.simplefilter("always", kind)
        return function(*args, **kwargs)


def test_relative_lambda_grid_selects_the_same_relative_lambda_for_replicated_data(rng):
    data = sensor(rng, n_groups=10, per_group=20, group_offset=0.05)
    index = np.tile(np.arange(data.n_samples), 4)
    four = Dataset.from_arrays(data.inputs[index], data.outputs[index], input_names=data.input_names,
                               output_names=OUTPUTS, groups=np.asarray(data.groups)[index])
    once = quiet(select_model, data, degrees=(1, 2), penalties=("lasso", "ridge"), select_per="output")
    again = quiet(select_model, four, degrees=(1, 2), penalties=("lasso", "ridge"), select_per="output")
    a, b = once.candidate_of_output(), again.candidate_of_output()
    assert [(c.degree, c.penalty) for c in a] == [(c.degree, c.penalty) for c in b]
    # The best λ of each penalty and degree, per output (whether or not it then beats affine by the margin).
    for j in range(len(OUTPUTS)):
        for degree in (1, 2):
            for penalty in ("lasso", "ridge"):
                x, y = (min((s for s in r.scores if (s.candidate.degree, s.candidate.penalty) == (degree, penalty)),
                            key=lambda s: np.mean(np.asarray(s.fold_mse)[:, j])).candidate for r in (once, again))
                assert y.relative_lam == pytest.approx(x.relative_lam, rel=1e-9)
                assert y.lam == pytest.approx(4 * x.lam, rel=1e-6)  # absolute λ scales with N; relative does not


def test_cost_estimate_is_within_a_factor_three_of_the_counted_work(rng):
    data = sensor(rng, n_groups=15, per_group=40)
    result = quiet(select_model, data, degrees=(1, 2, 3, 4), select_per="output")
    tried = sorted({s.candidate.degree for s in result.scores})
    # 15 load cases in 5 folds: nested cross-validation's pair fits are counted when the estimate knows the groups.
    estimate = estimate_cost(data.n_samples, 3, 6, tried, result.n_folds, n_groups=15)
    counted = result.search.work
    assert 1 / 3 <= estimate.total_units / (counted["statistics"] + counted["solve"]) <= 3
    # The statistics part counts the same passes (two bases per degree) and rows.
    assert sum(u[0] for u in estimate.units) == counted["statistics"]
    kept, note = estimate.within(budget_seconds=0.0, memory_bytes=1e12)
    assert kept == (tried[0],) and "--budget" in note and "--max-degree" in note


def test_saturation_warns_for_30_poses_and_28_coefficients(tmp_path, capsys):
    import pandas as pd

    from ftcal.cli import main

    rng = np.random.default_rng(0)
    poses = rng.uniform(-1, 1, (30, 6))
    u = np.repeat(poses, 4, axis=0) + 1e-4 * rng.standard_normal((120, 6))
    table = pd.DataFrame(u, columns=[f"s{i}" for i in range(6)])
    table[list(OUTPUTS)] = u @ rng.standard_normal((6, 6))
    table["case"] = np.repeat(np.arange(30), 4)
    table.to_csv(tmp_path / "bench.csv", index=False)
    common = ["fit", str(tmp_path / "bench.csv"), "--inputs", ",".join(table.columns[:6]), "--group-by", "case"]
    from ftcal.runtime.errors import FtcalWarning

    with warnings.catch_warnings():
        # The CLI prints them on stderr; the ridge fit of an exactly affine map also validates worse than
        # affine on the load cases (issue 44), and says so.
        warnings.simplefilter("always", FtcalWarning)
        warnings.simplefilter("always", SaturationWarning)
        # Degree 2 over 6 inputs: 28 coefficients per output, for 30 poses (120 samples).
        assert main([*common, "--degree", "2", "-o", str(tmp_path / "np2.json")]) == 0
        assert "28 coefficients per output for 30 distinct poses" in capsys.readouterr().err
        assert main([*common, "-o", str(tmp_path / "np1.json")]) == 0  # 7 coefficients: fine
        assert main([*common, "--degree", "2", "--ridge", "1", "-o", str(tmp_path / "r2.json")]) == 0  # penalized
        assert "saturation" not in capsys.readouterr().err
    # The library warns with its class.
    from ftcal.core.select import warn_if_saturated

    with pytest.warns(SaturationWarning):
        assert warn_if_saturated(28, 30, 30)


@pytest.mark.slow
def test_no_saturation_warning_on_the_demo(quick_demo, tmp_path, capsys):
    """On the session's quick demo (conftest.py builds it once per run; read only here)."""
    from ftcal.cli import main

    capsys.readouterr()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        warnings.simplefilter("always", SaturationWarning)
        for degree in ("1", "4"):  # least squares up to 330 coefficients per output, on the demo's trajectories
            assert main(["fit", str(quick_demo / "ftcal-demo" / "train.parquet"), "--group-by", "load", "--degree",
                         degree, "-o", str(tmp_path / f"np{degree}.json")]) == 0
    assert "saturation" not in capsys.readouterr().err


def test_drop_incomplete_counts_the_rows_it_drops(tmp_path, capsys):
    from ftcal.cli import main
    from ftcal.files.model_files import load_model

    rng = np.random.default_rng(1)
    u = rng.uniform(-1, 1, (50, 2))
    lines = ["a,b,note," + ",".join(OUTPUTS)]
    # outputs vary in all six directions (noise beside the two-input response), so no excitation warning
    for i, row in enumerate(np.c_[u, u @ rng.standard_normal((2, 6)) + rng.standard_normal((50, 6))]):
        cells = [f"{v:.6f}" for v in row]
        if i in (3, 17):
            cells[0] = ""            # an empty input
        if i in (17, 40):
            cells[2 + 3] = ""        # an empty output (Fz)
        note = "" if i == 9 else "x"  # an empty cell in a column the fit does not use
        lines.append(",".join(cells[:2] + [note] + cells[2:]))
    path = tmp_path / "holes.csv"
    path.write_text("\n".join(lines) + "\n")
    common = ["fit", str(path), "--inputs", "a,b"]
    assert main([*common, "-o", str(tmp_path / "x.json")]) == 2
    assert "--drop-incomplete" in capsys.readouterr().err
    assert main([*common, "--drop-incomplete", "-o", str(tmp_path / "m.json")]) == 0
    assert "dropped 3 row(s)" in capsys.readouterr().err  # rows 3, 17 and 40; row 9's hole is not used
    assert load_model(tmp_path / "m.json").n_samples_fit_ == 47


def test_cli_refuses_contradictory_selection_options(tmp_path, capsys):
    from ftcal.cli import main

    path = tmp_path / "t.csv"
    path.write_text("a,Fx,Fy,Fz,Tx,Ty,Tz\n" + "".join(f"{i},{i},1,2,3,4,5\n" for i in range(6)))
    common = ["fit", str(path), "--inputs", "a", "--degree", "auto", "-o", str(tmp_path / "m.json")]
    assert main([*common, "--objective", "force"]) == 2
    assert "--select-per model" in capsys.readouterr().err
    assert main([*common, "--max-degree", "11"]) == 2
    assert "--max-degree" in capsys.readouterr().err


# float64 cell keys (20**7 cells < 2**53), integer keys (20**13 < 2**63), bytes keys (20**16 ≥ 2**63)
@pytest.mark.parametrize("n_inputs", [7, 13, 16])
def test_pose_cells_count_the_distinct_grid_cells(n_inputs):
    """Against numpy's unique rows of the grid indices, computed here by hand; chunks unite."""
    from ftcal.core.select import pose_cells

    rng = np.random.default_rng(n_inputs)
    u = np.round(rng.normal(size=(3000, n_inputs)), 1)  # repeated values: shared cells
    span = np.c_[u.min(axis=0), u.max(axis=0)]
    grid = np.minimum(np.floor((u - span[:, 0]) / (span[:, 1] - span[:, 0]) * 20), 19)
    expected = len(np.unique(grid, axis=0))
    assert len(pose_cells(u, span)) == expected
    assert len(pose_cells(u[:1000], span) | pose_cells(u[1000:], span)) == expected
