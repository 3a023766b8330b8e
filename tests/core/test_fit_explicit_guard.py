"""Explicit fits that cannot silently lose (issue 44): more least-squares coefficients per output than
distinct poses is refused with the numbers and what to do; an explicit degree or LASSO fit on grouped data
is cross-validated beside affine least squares on whole load cases, with a warning when it is worse beyond
the fold noise.

Truth: simulated sensors (:func:`benchmarks.load_cases.make_paper_sensor`, an affine or a nonlinear
sensor with a load-case reference error) and counted monomials (C(n + d, d) per output).
"""

from __future__ import annotations

import warnings
from math import comb

import numpy as np
import pandas as pd

from benchmarks.load_cases import make_paper_sensor
from ftcal.cli import main

OUTPUTS = ["Fx", "Fy", "Fz", "Tx", "Ty", "Tz"]


def table(path, seed, n_groups, per_group=20, nonlinearity=0.0, case_error=0.02):
    u, y, groups, _ = make_paper_sensor(seed, n_groups=n_groups, per_group=per_group, nonlinearity=nonlinearity,
                                        case_error=case_error)
    frame = pd.DataFrame(u, columns=[f"s{i + 1}" for i in range(6)])
    frame[OUTPUTS] = y
    frame["load"] = groups
    frame.to_csv(path, index=False)
    return path


def run(capsys, *args):
    with warnings.catch_warnings():
        warnings.simplefilter("always")
        code = main(["fit", *map(str, args)])
    out = capsys.readouterr()
    return code, out.out, out.err


def test_more_coefficients_than_poses_is_refused_with_the_numbers(tmp_path, capsys):
    # 12 load cases held still: 12 distinct poses; degree 2 over 6 inputs has C(8, 2) = 28 per output.
    data = table(tmp_path / "few.csv", 0, n_groups=12)
    rng = np.random.default_rng(0)
    frame = pd.read_csv(data)
    for g, rows in frame.groupby("load").groups.items():  # one pose per load case (no motion within it)
        frame.loc[rows, [f"s{i + 1}" for i in range(6)]] = frame.loc[rows[0], [f"s{i + 1}" for i in range(6)]].values \
            + 1e-6 * rng.standard_normal((len(rows), 6))
    frame.to_csv(data, index=False)
    code, _, err = run(capsys, data, "--inputs", ",".join(f"s{i + 1}" for i in range(6)), "--degree", "2",
                       "-o", tmp_path / "m.json")
    assert code == 2, err
    err = err.strip().splitlines()
    assert len(err) == 1, err
    assert f"{comb(8, 2)} coefficients per output for 12 distinct poses" in err[0]
    assert "--degree 1" in err[0] and "--lasso" in err[0]
    assert not (tmp_path / "m.json").exists()


def test_an_explicit_degree_that_overfits_load_cases_is_named(tmp_path, capsys):
    # Affine truth, 16 load cases with a mis-measured reference each: degree 3 (84 coefficients per output)
    # chases the load cases' errors and validates far worse than affine on whole held-out load cases.
    data = table(tmp_path / "affine.csv", 1, n_groups=16, per_group=25)
    code, out, err = run(capsys, data, "--inputs", ",".join(f"s{i + 1}" for i in range(6)), "--degree", "3",
                         "-o", tmp_path / "np3.json")
    assert code == 0
    line = next(l for l in out.splitlines() if l.startswith("grouped cross-validation of np3"))
    ratio = float(line.split("force ")[1].split("(")[1].split("x)")[0])
    assert ratio > 1.5, line
    assert "validates worse than the affine model beyond the fold noise" in err


def test_an_explicit_degree_that_helps_is_not_warned_about(tmp_path, capsys):
    data = table(tmp_path / "curved.csv", 2, n_groups=40, per_group=20, nonlinearity=1.0)
    code, out, err = run(capsys, data, "--inputs", ",".join(f"s{i + 1}" for i in range(6)), "--degree", "3",
                         "-o", tmp_path / "np3.json")
    assert code == 0
    line = next(l for l in out.splitlines() if l.startswith("grouped cross-validation of np3"))
    force = float(line.split("force ")[1].split("(")[1].split("x)")[0])
    assert force < 0.9, line  # the simulated sensor's degree-3 gain on new load cases is ~45 %
    assert "validates worse than the affine model" not in err


def test_the_library_fit_refuses_too_many_coefficients_read_whole_too(tmp_path, capsys):
    """The in-memory path (a Dataset given to workflow.fit) refuses as the streamed one does."""
    from ftcal.core.dataset import Dataset
    from ftcal.runtime.errors import FtcalError
    from ftcal.workflow.fitting import fit

    u, y, groups, _ = make_paper_sensor(3, n_groups=10, per_group=1)  # 10 samples, 10 poses
    data = Dataset.from_arrays(u, y, input_names=[f"s{i + 1}" for i in range(6)], output_names=OUTPUTS,
                               groups=groups)
    try:
        fit(data, degree=2)
    except FtcalError as error:
        assert f"{comb(8, 2)} coefficients per output for 10 distinct poses" in str(error)
    else:
        raise AssertionError("a degree-2 fit of 28 coefficients per output on 10 poses was not refused")
