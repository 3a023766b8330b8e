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


def planar_sensor(tmp_path, rng):
    """A fitted model (degree ≤ 2) of an affine sensor trained on planar loads (Fz never loaded); its gains and
    the training load cases (one row each)."""
    import warnings

    wrench, groups = planar_loads(rng)
    gains = np.eye(6) * 100 + rng.normal(size=(6, 6)) * 5
    frame = pd.DataFrame(np.c_[wrench @ gains.T + rng.normal(size=wrench.shape) * 0.5, wrench],
                         columns=[f"u{i}" for i in range(1, 7)] + NAMES)
    frame["case"] = groups
    frame.to_csv(tmp_path / "train.csv", index=False)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the unexcited Fz is warned about; not what is tested here
        assert main(["fit", str(tmp_path / "train.csv"), "--inputs", "u1,u2,u3,u4,u5,u6", "--group-by", "case",
                     "--degree", "auto", "--max-degree", "2", "--folds", "4", "-o", str(tmp_path / "m.json")]) == 0
    return gains, wrench[::20]


def write_loads(path, rng, gains, wrench):
    raw = wrench @ gains.T + rng.normal(size=wrench.shape) * 0.5
    pd.DataFrame(np.c_[raw, wrench], columns=[f"u{i}" for i in range(1, 7)] + NAMES).to_csv(path, index=False)
    return str(path)


def test_evaluate_and_predict_say_when_the_data_load_an_axis_training_never_loaded(tmp_path, capsys):
    """The failure: the fit's CV error is small, the error on data loading the new axis Fz is far larger;
    evaluate and predict say so in one line (and evaluate in its JSON), and say nothing on in-span data."""
    import json
    import warnings

    from ftcal.runtime.errors import FtcalWarning

    rng = np.random.default_rng(2)
    gains, cases = planar_sensor(tmp_path, rng)
    fit_text = capsys.readouterr().out
    # new load cases of the same kind: midpoints of two training cases (inside the training loads' span)
    pairs = np.random.default_rng(3).choice(len(cases), size=(4, 2), replace=False)
    inside = np.repeat(cases[pairs].mean(axis=1), 20, axis=0) + rng.normal(size=(80, 6)) * 0.01
    inside[:, 2] = rng.normal(size=80) * 0.01
    new_axis = inside.copy()
    new_axis[:, 2] = np.repeat([-20.0, -10.0, 10.0, 20.0], 20)  # Fz, as large as the training Fx and Fy
    files = {"inside": write_loads(tmp_path / "inside.csv", rng, gains, inside),
             "new_axis": write_loads(tmp_path / "new_axis.csv", rng, gains, new_axis)}
    docs = {}
    for name, path in files.items():
        assert main(["evaluate", str(tmp_path / "m.json"), path]) == 0
        text = capsys.readouterr().out
        assert main(["evaluate", str(tmp_path / "m.json"), path, "--json"]) == 0
        docs[name] = json.loads(capsys.readouterr().out)
        with warnings.catch_warnings():
            warnings.simplefilter("always", FtcalWarning)
            assert main(["predict", str(tmp_path / "m.json"), path, "-o", str(tmp_path / f"{name}.pred.csv")]) == 0
        said = [line for line in text.splitlines() if "beyond the training loads" in line]
        predicted = [line for line in capsys.readouterr().err.splitlines() if "beyond the training loads" in line]
        loads = docs[name]["loads_beyond_training"]
        if name == "inside":
            assert said == [] and predicted == [] and loads["n_beyond"] == 0 and loads["outputs"] == {}
        else:
            # every sample loads Fz at 10 N or more: beyond 5 % of the widest training force span (about 2 N)
            assert len(said) == 1 and "the reference loads go beyond the training loads on Fz" in said[0]
            assert "does not forecast" in said[0] and "Fx" not in said[0]
            assert loads["n_beyond"] == len(new_axis) and set(loads["outputs"]) == {"Fz"}
            assert loads["outputs"]["Fz"]["samples"] == len(new_axis)
            assert loads["outputs"]["Fz"]["low"] == -20.0 and loads["outputs"]["Fz"]["high"] == 20.0
            # one warning line: the inputs outside the range, then the loads (the prediction along the new axis)
            assert len(predicted) == 1 and predicted[0].startswith("warning: 80 of 80 samples have inputs outside")
            assert "the predicted loads go beyond the training loads on Fz" in predicted[0]
    # the failure the warning is about: on the new axis the error is far beyond the in-span error
    assert "cross-validated error:" in fit_text
    assert docs["new_axis"]["force_norm_rmse"] > 10 * docs["inside"]["force_norm_rmse"]
