"""``FitResult`` renders its model lines from the fitted model's numbers (issue #43), not from stored text.

The numbers the report prints are checked against an independent computation (numpy's least squares on
the same table), and a result whose model is swapped for another renders the other model's lines: the
text follows the typed fields.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pandas as pd

import ftcal
from ftcal.workflow.fitting import model_report


def _table(seed: int, n: int = 60) -> pd.DataFrame:
    # An affine truth plus a cubic the affine fit cannot follow and noise: a nonzero training error.
    rng = np.random.default_rng(seed)
    u = rng.uniform(-1.0, 1.0, size=n)
    return pd.DataFrame({"u1": u, "Fx": 3.0 * u + 1.0 + 0.4 * u ** 3 + 0.05 * rng.normal(size=n)})


def test_the_training_line_is_the_least_squares_rmse_of_the_table():
    frame = _table(0)
    result = ftcal.fit(frame, inputs=["u1"], outputs=["Fx"])
    # numpy's least squares of Fx on [1, u1], independent of ftcal's solver.
    design = np.c_[np.ones(len(frame)), frame["u1"]]
    coef, *_ = np.linalg.lstsq(design, frame["Fx"].to_numpy(), rcond=None)
    rmse = float(np.sqrt(np.mean((frame["Fx"].to_numpy() - design @ coef) ** 2)))
    assert result.lines[-1] == f"training RMSE per output: Fx {rmse:.4g}"  # one output: no wrench block, no unit
    assert result.lines[-1] not in result.preamble  # rendered from the model, not stored
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


def test_the_selection_text_is_rendered_from_the_selection():
    # Four load cases of a cubic sensor: degree="auto" runs the grouped search; its verdict is printed.
    frame = pd.concat([_table(seed, n=40).assign(load=f"L{seed}") for seed in range(4)], ignore_index=True)
    result = ftcal.fit(frame, inputs=["u1"], outputs=["Fx"], degree="auto", group_by="load", max_degree=3)
    verdict = result.selection.verdict()
    assert verdict in result.summary() and not any(verdict in line for line in result.preamble)
    # A selection that chose otherwise renders its own verdict in the same place.
    other = replace(result.selection, best=result.selection.scores[-1].candidate, selection=[])
    assert replace(result, selection=other).summary().count(other.verdict()) == 1
