"""``ftcal fit``: dropped rows split ARX segments; force-only outputs and repeated λ are no traceback;
MLP weights stored as strings are refused (issue 28)."""

import json

import numpy as np
import pandas as pd
import pytest

from ftcal.cli import main
from ftcal.files.model_json import digest


def arx_table(path, gap_row=None):
    """y(k) = 0.8 y(k−1) + 2 u(k) exactly: a fit that keeps lags inside segments has no residual."""
    rng = np.random.default_rng(0)
    u = rng.normal(size=400)
    y = np.zeros(400)
    for k in range(1, 400):
        y[k] = 0.8 * y[k - 1] + 2.0 * u[k]
    frame = pd.DataFrame({"u1": u, "Fx": y})
    if gap_row is not None:
        frame.loc[gap_row, "u1"] = np.nan  # one empty cell: the row is dropped
    frame.to_csv(path, index=False)
    return path


def test_drop_incomplete_does_not_bridge_the_gap_with_arx_lags(tmp_path, capsys):
    data = arx_table(tmp_path / "arx.csv", gap_row=200)
    assert main(["fit", str(data), "--inputs", "u1", "--outputs", "Fx", "--degree", "1", "--na", "1",
                 "--drop-incomplete", "-o", str(tmp_path / "m.json")]) == 0
    doc = json.loads((tmp_path / "m.json").read_text())
    rmse = doc["fit"]["metrics"]["rmse"][0]
    # Bridging would pair y(201) with y(199) once: a residual of 0.8 (y(200) − y(199)), RMS ~0.05 over 397 rows.
    assert rmse < 1e-8, rmse


def test_force_only_outputs_fit_and_describe(tmp_path, capsys):
    rng = np.random.default_rng(1)
    u = rng.normal(size=(300, 3))
    frame = pd.DataFrame(np.c_[u, u @ np.diag([2.0, 3.0, 4.0])], columns=["u1", "u2", "u3", "Fx", "Fy", "Fz"])
    frame.to_csv(tmp_path / "f.csv", index=False)
    assert main(["fit", str(tmp_path / "f.csv"), "--inputs", "u1,u2,u3", "--outputs", "Fx,Fy,Fz", "--degree", "1",
                 "-o", str(tmp_path / "m.json")]) == 0
    assert "force-norm RMSE" in capsys.readouterr().out
    assert main(["info", str(tmp_path / "m.json")]) == 0
    assert "torque-norm" not in capsys.readouterr().out


def test_a_repeated_lambda_is_refused_in_one_line(tmp_path, capsys):
    data = arx_table(tmp_path / "t.csv")
    with pytest.raises(SystemExit) as exit_:
        main(["fit", str(data), "--inputs", "u1", "--outputs", "Fx", "--degree", "auto", "--lambdas", "1,1",
              "-o", str(tmp_path / "m.json")])
    assert exit_.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--lambdas" in err[0]


@pytest.mark.parametrize("value", ['"nan"', '"1e999"', "true", "null"])
def test_mlp_weights_that_are_not_numbers_are_refused(tmp_path, capsys, value):
    rng = np.random.default_rng(2)
    u = rng.normal(size=(200, 3))
    frame = pd.DataFrame(np.c_[u, np.tanh(u)], columns=["u1", "u2", "u3", "Fx", "Fy", "Fz"])
    frame["g"] = np.repeat(["a", "b"], 100)
    frame.to_csv(tmp_path / "d.csv", index=False)
    assert main(["fit", str(tmp_path / "d.csv"), "--inputs", "u1,u2,u3", "--outputs", "Fx,Fy,Fz", "--family", "mlp",
                 "--hidden", "3", "--max-iter", "20", "--group-by", "g", "-o", str(tmp_path / "m.json")]) == 0
    doc = json.loads((tmp_path / "m.json").read_text())
    doc["parameters"]["layers"][0]["weights"][0][0] = json.loads(value)
    doc["sha256"] = digest(doc)
    (tmp_path / "bad.json").write_text(json.dumps(doc))
    capsys.readouterr()
    assert main(["info", str(tmp_path / "bad.json")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "layers[0]" in err[0], err


@pytest.mark.parametrize("max_iter", ["1", "5"])
def test_mlp_max_iter_below_one_checkpoint_is_no_traceback(tmp_path, capsys, max_iter):
    rng = np.random.default_rng(3)
    u = rng.normal(size=(150, 3))
    frame = pd.DataFrame(np.c_[u, np.tanh(u)], columns=["u1", "u2", "u3", "Fx", "Fy", "Fz"])
    frame["g"] = np.repeat(["a", "b", "c"], 50)
    frame.to_csv(tmp_path / "d.csv", index=False)
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("always")  # main() prints ftcal's warnings as one stderr line each
        code = main(["fit", str(tmp_path / "d.csv"), "--inputs", "u1,u2,u3", "--outputs", "Fx,Fy,Fz", "--family",
                     "mlp", "--hidden", "3", "--max-iter", max_iter, "--group-by", "g", "-o", str(tmp_path / "m.json")])
    assert code == 0
    # A network stopped after 1 or 5 iterations may validate worse than affine: then the guard writes the affine
    # model and says so; either way a model file is written and nothing ends in a traceback.
    lost = "validates worse than the affine model" in capsys.readouterr().err
    family = json.loads((tmp_path / "m.json").read_text()).get("family", "polynomial")
    assert family == ("polynomial" if lost else "mlp")


def test_an_empty_option_value_is_refused_in_one_line(tmp_path, capsys):
    data = arx_table(tmp_path / "t.csv")
    assert main(["fit", str(data), "--inputs", "u1", "--outputs", "Fx", "--degree", "1", "--group-by", "",
                 "-o", str(tmp_path / "m.json")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--group-by" in err[0] and not (tmp_path / "m.json").exists()


@pytest.mark.parametrize("extra", [["--folds", "3"], ["--max-degree", "2"], ["--select-per", "model"],
                                   ["--budget", "5"], ["--verbose"], ["--lambdas", "1,0.1"],
                                   ["--penalties", "ridge"]])
def test_search_options_with_a_fixed_degree_are_refused_not_ignored(tmp_path, capsys, extra):
    data = arx_table(tmp_path / "t.csv")
    assert main(["fit", str(data), "--inputs", "u1", "--outputs", "Fx", "--degree", "1", *extra,
                 "-o", str(tmp_path / "m.json")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and extra[0] in err[0] and "--degree auto" in err[0]


@pytest.mark.parametrize("degree", ["1", "auto"])
def test_drop_incomplete_arx_counts_and_fingerprints_the_two_segments(tmp_path, capsys, degree):
    """The dropped row splits the file in two segments: each loses its own warm-up sample (400 − 1 dropped − 2)
    and the model's training fingerprints are the two segments, as a table holding them as two labelled segments
    gives (was one segment of 399 rows and 398 samples: the streamed summary bridged the gap)."""
    data = arx_table(tmp_path / "arx.csv", gap_row=200)
    frame = pd.read_csv(data)
    frame["load"] = np.repeat(["a", "b"], 200)
    frame.to_csv(data, index=False)
    split = frame.drop(index=200).assign(seg=lambda f: np.where(f.index < 200, "s1", "s2"))
    split.to_csv(tmp_path / "split.csv", index=False)
    common = ["--inputs", "u1", "--outputs", "Fx", "--degree", degree, "--na", "1",
              *(["--max-degree", "2", "--group-by", "load"] if degree == "auto" else [])]
    assert main(["fit", str(data), *common, "--drop-incomplete", "-o", str(tmp_path / "m.json")]) == 0
    assert main(["fit", str(tmp_path / "split.csv"), *common, "--segment-by", "seg",
                 "-o", str(tmp_path / "s.json")]) == 0
    got, want = (json.loads((tmp_path / n).read_text())["fit"] for n in ("m.json", "s.json"))
    assert got["n_samples"] == want["n_samples"] == 400 - 1 - 2
    assert [s["rows"] for s in got["training_segments"]] == [200, 199]
    assert got["training_segments"] == want["training_segments"]
