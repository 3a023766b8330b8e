"""Out-of-range inputs: said once per command, with the channels, how far, and the error there.

Every expected number is computed here with numpy from the arrays written to disk: the
excursion in training spans by hand, the in/out force-norm RMSE from the norms.
"""

from __future__ import annotations

import json
import warnings

import cli_data as cd
import numpy as np
import pytest

from ftcal import CalibrationModel, Dataset, save_model
from ftcal.cli import main
from ftcal.core.ranges import excursions
from ftcal.runtime.errors import FtcalWarning, OutOfRangeWarning

N_TRAIN, N_NEW = 400, 300


@pytest.fixture(scope="module")
def work(tmp_path_factory):
    """A degree-1 model of the synthetic sensor; new data with T pushed beyond its training range in 7 rows."""
    rng = np.random.default_rng(11)
    root = tmp_path_factory.mktemp("oor")
    train = cd.training_frame(rng, N_TRAIN)
    u = train[list(cd.INPUTS)].to_numpy()
    model = CalibrationModel(degree=1).fit(Dataset.from_arrays(u, train[list(cd.OUTPUTS)].to_numpy(),
                                                               input_names=cd.INPUTS, output_names=cd.OUTPUTS))
    save_model(model, root / "m.json")
    new = cd.random_inputs(rng, N_NEW, shrink=0.9)
    low, high = u[:, 6].min(), u[:, 6].max()
    new[:7, 6] = high + (high - low) * np.array([0.5, 0.1, 0.1, 0.2, 0.05, 0.3, 0.25])  # 50 % beyond at most
    y_new = cd.truth(new)
    cd.frame(new, y_new).to_csv(root / "new.csv", index=False)
    cd.frame(new[:150], y_new[:150]).to_csv(root / "a.csv", index=False)
    cd.frame(new[150:], y_new[150:]).to_csv(root / "b.csv", index=False)
    return root, model, new, y_new, (low, high)


def warning_lines(err: str) -> list[str]:
    return [line for line in err.splitlines() if "outside the training range" in line]


def test_excursions_are_in_training_spans():
    span = np.array([[10.0, 30.0]])  # a 20-wide range
    got = excursions(np.array([[5.0], [20.0], [36.0], [30.0]]), span).ravel()
    assert got.tolist() == [0.25, 0.0, 0.3, 0.0]


def test_predict_warns_once_naming_the_channel_and_how_far(work, capsys, tmp_path):
    root, *_ = work
    with warnings.catch_warnings():
        warnings.simplefilter("always", FtcalWarning)
        # two input files: still one warning for the one cause, with the total count
        assert main(["predict", str(root / "m.json"), str(root / "a.csv"), str(root / "b.csv"),
                     "-o", str(tmp_path / "w.csv")]) == 0
    err = capsys.readouterr().err
    lines = warning_lines(err)
    assert len(lines) == 1, err
    assert lines[0].startswith(f"warning: 7 of {N_NEW} samples have inputs outside the training range: ")
    assert "T up to 50 % of its training span beyond it (7 samples)" in lines[0]
    assert "u1" not in lines[0]


def test_one_sample_is_singular(work, capsys, tmp_path):
    root, _, new, y_new, _ = work
    one = tmp_path / "one.csv"
    cd.frame(new[6:20], y_new[6:20]).to_csv(one, index=False)  # row 6 is the only one outside
    with warnings.catch_warnings():
        warnings.simplefilter("always", FtcalWarning)
        assert main(["predict", str(root / "m.json"), str(one), "-o", str(tmp_path / "w.csv")]) == 0
    (line,) = warning_lines(capsys.readouterr().err)
    assert "1 of 14 samples has inputs" in line and "(1 sample)" in line and "1 samples" not in line


def test_evaluate_says_it_once_with_the_error_inside_and_outside(work, capsys):
    root, model, new, y_new, _ = work
    prediction = model.predict(new, warn_out_of_range=False)
    forces = [0, 1, 2]
    d = np.linalg.norm(y_new[:, forces], axis=1) - np.linalg.norm(prediction[:, forces], axis=1)
    want_out, want_in = np.sqrt(np.mean(d[:7] ** 2)), np.sqrt(np.mean(d[7:] ** 2))
    with warnings.catch_warnings():
        warnings.simplefilter("always", FtcalWarning)
        assert main(["evaluate", str(root / "m.json"), str(root / "new.csv"), "--json"]) == 0
    out, err = capsys.readouterr()
    detail = json.loads(out)["out_of_range"]
    assert detail["n_out_of_range"] == 7 and list(detail["inputs"]) == ["T"]
    assert detail["inputs"]["T"]["max_excursion"] == pytest.approx(0.5, rel=1e-12)
    assert detail["force_norm_rmse_out_of_range"] == pytest.approx(want_out, rel=1e-10)
    assert detail["force_norm_rmse_in_range"] == pytest.approx(want_in, rel=1e-10)
    assert warning_lines(err) == []  # the JSON holds it; no warning line besides
    with warnings.catch_warnings():
        warnings.simplefilter("always", FtcalWarning)
        assert main(["evaluate", str(root / "m.json"), str(root / "new.csv")]) == 0
    out, err = capsys.readouterr()
    assert "outside the training range" not in err
    assert f"{N_NEW} samples, 7 outside the training input range" in out
    assert f"force-norm RMSE {want_out:.4g} N on them vs {want_in:.4g} N on the {N_NEW - 7} inside" in out
    assert sum("T up to" in line for line in out.splitlines()) == 1


def test_score_warns_once_with_the_error_split(work):
    _, model, new, y_new, _ = work
    data = Dataset.from_arrays(new, y_new, input_names=cd.INPUTS, output_names=cd.OUTPUTS)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        model.metrics(data)
    messages = [str(w.message) for w in caught if issubclass(w.category, OutOfRangeWarning)]
    assert len(messages) == 1 and "force-norm RMSE" in messages[0] and "on them vs" in messages[0]


def test_evaluate_prints_every_metric_with_its_unit(work, capsys):
    root, *_ = work
    assert main(["evaluate", str(root / "m.json"), str(root / "new.csv")]) == 0
    out = capsys.readouterr().out
    for name, unit in (("force-norm RMSE", "N"), ("torque-norm RMSE", "N·m"),
                       ("RMSE of the force error norm", "N"), ("RMSE of the torque error norm", "N·m")):
        line = next(line for line in out.splitlines() if line.startswith(f"{name}: "))
        assert line.endswith(f" {unit}"), line
    rows = {line.split()[0]: line.split()[-1] for line in out.splitlines() if line.split()[:1] in
            [[n] for n in cd.OUTPUTS]}
    assert rows == {"Fx": "N", "Fy": "N", "Fz": "N", "Tx": "N·m", "Ty": "N·m", "Tz": "N·m"}
    assert "resid. acf(1) = lag-1 autocorrelation" in out


def test_range_and_span_told_apart_text_and_json_agree(tmp_path, capsys):
    """Issue 27: 'N outside the training input range' must count only inputs beyond their own min/max.

    Training inputs lie on the line u2 = u1 (± 1e-3); 40 new rows lie on u2 = −u1 inside both
    ranges (outside the span, by construction), 9 push u1 beyond its maximum (outside the range).
    Before the fix evaluate printed the 49 as "outside the training input range" with an empty
    channel list, and the JSON's count disagreed with the text's split.
    """
    import pandas as pd

    rng = np.random.default_rng(27)
    t = rng.uniform(-1, 1, 500)
    train = pd.DataFrame({"u1": t, "u2": t + 1e-3 * rng.normal(size=500)})
    train["Fx"] = 2 * train.u1 + train.u2 + 0.01 * rng.normal(size=500)
    train.to_csv(tmp_path / "train.csv", index=False)
    assert main(["fit", str(tmp_path / "train.csv"), "--inputs", "u1,u2", "--outputs", "Fx", "--degree", "1",
                 "-o", str(tmp_path / "m.json")]) == 0
    s = rng.uniform(-0.8, 0.8, 40)
    span = pd.DataFrame({"u1": s, "u2": -s})
    inside = pd.DataFrame({"u1": t[:100] * 0.9, "u2": t[:100] * 0.9})
    beyond = pd.DataFrame({"u1": np.full(9, train.u1.max() + 0.5), "u2": np.full(9, train.u2.max() * 0.5)})
    new = pd.concat([span, inside, beyond], ignore_index=True)
    new["Fx"] = 2 * new.u1 + new.u2
    new.to_csv(tmp_path / "new.csv", index=False)
    capsys.readouterr()
    assert main(["evaluate", str(tmp_path / "m.json"), str(tmp_path / "new.csv")]) == 0
    text = capsys.readouterr().out
    assert "149 samples, 9 outside the training input range" in text
    assert "40 more inside every input's range but outside the training span" in text
    assert "outside: u1 up to" in text and "u2 up to" not in text
    assert main(["evaluate", str(tmp_path / "m.json"), str(tmp_path / "new.csv"), "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert (doc["n_outside_range"], doc["n_outside_span"], doc["n_out_of_range"]) == (9, 40, 49)
    with warnings.catch_warnings():  # predict (and compensate, score): the same split, one warning
        warnings.simplefilter("always", FtcalWarning)
        assert main(["predict", str(tmp_path / "m.json"), str(tmp_path / "new.csv"), "-o",
                     str(tmp_path / "p.csv")]) == 0
    lines = warning_lines(capsys.readouterr().err)
    assert len(lines) == 1 and "9 of 149 samples have inputs outside the training range: u1" in lines[0]
    assert "40 of 149 sample(s) inside the training range lie outside the span" in lines[0]
