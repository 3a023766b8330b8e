"""The cross-validated error says what it measured: loads inside the training span, or beyond the other
folds' loads; an axis the data hardly load is named (its error was never measured).

Truth: a simulated affine sensor loaded only along Fx and Fy (Fz, torques: noise), whose evaluation on
loads along Fz errs far beyond the cross-validated error (cross-talk the fit could not see).
"""

import numpy as np
import pandas as pd

from ftcal.cli import main
from ftcal.core.excitation import group_output_ranges, held_out_span

NAMES = ["Fx", "Fy", "Fz", "Tx", "Ty", "Tz"]


def planar_loads(rng, n_cases=12, per_case=20):
    cases = np.zeros((n_cases, 6))
    cases[:, :2] = rng.uniform(-20, 20, (n_cases, 2))
    cases[:, 3:] = rng.uniform(-1, 1, (n_cases, 3))
    wrench = np.repeat(cases, per_case, axis=0) + rng.normal(size=(n_cases * per_case, 6)) * 0.01
    return wrench, np.repeat([f"case{k}" for k in range(n_cases)], per_case)


def test_an_axis_the_data_never_load_is_named_and_the_span_stated():
    wrench, groups = planar_loads(np.random.default_rng(0))
    fold_of = {f"case{k}": k % 4 for k in range(12)}
    text = held_out_span(group_output_ranges(wrench, groups), fold_of, NAMES)
    assert "hardly load Fz" in text
    assert "Fx" in text.split("beyond the other folds' loads on")[1].split(";")[0]


def test_folds_that_only_interpolate_say_so():
    # Every fold holds the same two extreme cases' twins: none reaches beyond the others.
    base = np.array([[-10.0, 0, 0, 0, 0, 0], [10.0, 0, 0, 0, 0, 0], [0.0, 5, 0, 0, 0, 0]])
    outputs = np.vstack([base + 0.001 * k for k in range(4)])
    outputs[:, 2:] = np.tile([-1.0, 1.0, 0.0], 4)[:, None] * [1, 0.1, 0.1, 0.1]  # small, but loaded
    groups = np.array([f"g{k}" for k in range(12)])
    fold_of = {f"g{k}": k // 3 for k in range(12)}
    text = held_out_span(group_output_ranges(outputs, groups), fold_of, NAMES)
    assert text.startswith("cross-validated error: measured inside the training loads' span")


def test_fit_prints_the_span_its_cross_validated_error_was_measured_in(tmp_path, capsys):
    rng = np.random.default_rng(1)
    wrench, groups = planar_loads(rng)
    gains = np.eye(6) * 100 + rng.normal(size=(6, 6)) * 5
    raw = wrench @ gains.T + rng.normal(size=wrench.shape) * 0.5
    frame = pd.DataFrame(np.c_[raw, wrench], columns=[f"u{i}" for i in range(1, 7)] + NAMES)
    frame["case"] = groups
    frame.to_csv(tmp_path / "train.csv", index=False)
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the unexcited Fz is warned about too; not what is tested here
        assert main(["fit", str(tmp_path / "train.csv"), "--inputs", "u1,u2,u3,u4,u5,u6", "--group-by", "case",
                     "--degree", "auto", "--max-degree", "2", "--folds", "4", "-o", str(tmp_path / "m.json")]) == 0
    out = capsys.readouterr().out
    assert "cross-validated error:" in out and "hardly load Fz" in out
