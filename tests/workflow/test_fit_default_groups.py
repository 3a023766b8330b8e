"""fit uses the load-case column `ftcal dataset` writes as its validation groups by default, and says so."""

import subprocess

import numpy as np
import pandas as pd
import pytest

import ftcal

FTCAL = "/work/main/.venv/bin/ftcal"


def write_tables(folder, with_group: bool, column: str = "load"):
    """Two files, each holding 4 load cases (so one group per file would be 2 folds, per load case 8);
    ``column`` names them ("group": the old spelling of "load")."""
    rng = np.random.default_rng(11)
    paths = []
    for k in range(2):
        u = rng.uniform(-1.0, 1.0, size=(800, 3))
        frame = pd.DataFrame(u, columns=["u1", "u2", "u3"])
        frame["Fx"] = 2.0 * u[:, 0] + 0.3 * u[:, 1] ** 2 + 0.01 * rng.normal(size=800)
        if with_group:
            frame[column] = [f"load{4 * k + i // 200}" for i in range(800)]
        path = folder / f"part{k}.parquet"
        frame.to_parquet(path)
        paths.append(str(path))
    return paths


def test_degree_auto_groups_by_the_dataset_column_when_every_file_has_it(tmp_path):
    paths = write_tables(tmp_path, with_group=True)
    default = ftcal.fit(paths, inputs=["u1", "u2", "u3"], outputs=["Fx"], degree="auto", max_degree=2)
    named = ftcal.fit(paths, inputs=["u1", "u2", "u3"], outputs=["Fx"], degree="auto", max_degree=2,
                      group_by="load")
    assert any("'load' column" in note for note in default.notes)
    assert not any("'load' column" in note for note in named.notes)
    # The same folds, so the same search table and the same model.
    # (its notes hold the CPU seconds already spent, which differ between two runs)
    a, b = default.selection.as_dict(), named.selection.as_dict()
    assert {k: v for k, v in a.items() if k != "notes"} == {k: v for k, v in b.items() if k != "notes"}
    assert np.array_equal(default.model.coef_, named.model.coef_)
    # 8 load cases: 5 folds (the default), where one group per file would allow 2 at most.
    assert default.selection.as_dict()["n_folds"] == 5


def test_without_the_column_each_file_stays_a_group(tmp_path):
    paths = write_tables(tmp_path, with_group=False)
    result = ftcal.fit(paths, inputs=["u1", "u2", "u3"], outputs=["Fx"], degree="auto", max_degree=2, folds=2)
    assert not any("'load' column" in note for note in result.notes)
    assert result.selection.as_dict()["n_folds"] == 2


def test_the_command_says_which_groups_it_used(tmp_path):
    paths = write_tables(tmp_path, with_group=True)
    run = subprocess.run([FTCAL, "fit", *paths, "--inputs", "u1,u2,u3", "--outputs", "Fx", "--degree", "auto",
                          "--max-degree", "2", "-o", str(tmp_path / "m.json")], capture_output=True, text=True)
    assert run.returncode == 0, run.stderr
    assert "groups: the tables' 'load' column" in run.stderr
    assert "notice" not in run.stderr


def test_an_affine_fit_is_not_regrouped(tmp_path):
    paths = write_tables(tmp_path, with_group=True)
    result = ftcal.fit(paths, inputs=["u1", "u2", "u3"], outputs=["Fx"], degree=1)
    assert not any("'load' column" in note for note in result.notes)


def test_a_fixed_degree_is_compared_with_affine_on_the_load_cases(tmp_path):
    """Issue 44: an explicit degree above 1 is cross-validated beside affine on whole load cases."""
    paths = write_tables(tmp_path, with_group=True)
    result = ftcal.fit(paths, inputs=["u1", "u2", "u3"], outputs=["Fx"], degree=2)
    assert any("'load' column" in note for note in result.notes)
    assert any(line.startswith("grouped cross-validation of np2 against affine") for line in result.lines)


def test_the_mlp_guard_scores_outputs_without_a_force_block(tmp_path):
    """With groups, the MLP is compared with the affine model on its own score: here the mean RMSE (Fx alone
    is no force block); the comparison used to demand a force block and refused the fit."""
    paths = write_tables(tmp_path, with_group=True)
    result = ftcal.fit(paths, inputs=["u1", "u2", "u3"], outputs=["Fx"], family="mlp", hidden=[4], max_iter=50,
                       seed=0)
    assert any("'load' column" in note for note in result.notes)
    # The cross-validation table: the MLP beside the affine model (np1), both by the mean RMSE over 5 load-case folds.
    assert "(mean RMSE, 5 grouped folds)" in result.summary() and " np1 " in result.summary()


def test_an_older_table_s_group_column_is_read_as_load_with_a_notice(tmp_path):
    """Tables written before the load case had one name hold it as 'group': the same 8 load cases, the same
    5 folds and the same model as the 'load' spelling, and a FutureWarning naming both spellings."""
    (tmp_path / "new").mkdir()
    (tmp_path / "old").mkdir()
    new = write_tables(tmp_path / "new", with_group=True)
    old = write_tables(tmp_path / "old", with_group=True, column="group")
    kwargs = dict(inputs=["u1", "u2", "u3"], outputs=["Fx"], degree="auto", max_degree=2)
    expected = ftcal.fit(new, **kwargs)
    for group_by in (None, "load"):  # by default, and when 'load' is named
        with pytest.warns(FutureWarning, match="'group'.*is now 'load'"):
            result = ftcal.fit(old, group_by=group_by, **kwargs)
        assert result.selection.as_dict()["n_folds"] == 5
        assert np.array_equal(result.model.coef_, expected.model.coef_)


def test_the_command_prints_one_notice_for_the_old_group_column(tmp_path):
    paths = write_tables(tmp_path, with_group=True, column="group")
    run = subprocess.run([FTCAL, "fit", *paths, "--inputs", "u1,u2,u3", "--outputs", "Fx", "--degree", "auto",
                          "--max-degree", "2", "-o", str(tmp_path / "m.json")], capture_output=True, text=True)
    assert run.returncode == 0, run.stderr
    notices = [line for line in run.stderr.splitlines() if line.startswith("notice:")]
    assert len(notices) == 1 and "'group'" in notices[0] and "'load'" in notices[0], run.stderr
