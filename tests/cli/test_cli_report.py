"""``ftcal report``: model files and data files in, one HTML page out; errors in one line."""

import re

import numpy as np
import pandas as pd
import pytest

from ftcal.cli import main
from ftcal.core.model import CalibrationModel
from ftcal.files.model_files import save_model
from ftcal.sim.synthetic import synthetic_recordings


def write_csv(data, path):
    frame = pd.DataFrame(np.c_[data.inputs, data.outputs], columns=[*data.input_names, *data.output_names])
    frame["group"] = np.asarray(data.groups, dtype=str)
    frame.to_csv(path, index=False)
    return path


def force_norm_rmse(y, y_hat):
    diff = np.linalg.norm(y[:, :3], axis=1) - np.linalg.norm(y_hat[:, :3], axis=1)
    return float(np.sqrt(np.mean(diff ** 2)))


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    folder = tmp_path_factory.mktemp("cli-report")
    full = synthetic_recordings(8, 250, seed=11, loads_kg=(0, 2, 5, 10))
    held_out = np.isin(full.segments, [5, 6])
    train, validation = full.subset(~held_out), full.subset(held_out)
    models = {}
    for degree in (1, 2):
        model = CalibrationModel(degree).fit(train)
        save_model(model, folder / f"np{degree}.json")
        models[f"np{degree}"] = model
    return {"dir": folder, "models": models, "train": train, "validation": validation,
            "train_csv": write_csv(train, folder / "train.csv"),
            "val_csv": write_csv(validation, folder / "validation.csv")}


def test_round_trip(files, capsys):
    d = files["dir"]
    out = d / "out" / "report.html"
    code = main(["report", str(d / "np1.json"), str(files["val_csv"]), str(d / "np2.json"),
                 "--group-by", "group", "--train", str(files["train_csv"]), "-o", str(out)])
    assert code == 0
    assert f"wrote {out}" in capsys.readouterr().out
    page = out.read_text(encoding="utf-8")
    validation, train = files["validation"], files["train"]
    for name, model in files["models"].items():
        assert f'<td class="name">{name}</td>' in page
        expected = force_norm_rmse(validation.outputs, model.predict(validation.inputs, warn_out_of_range=False))
        train_expected = force_norm_rmse(train.outputs, model.predict(train.inputs, warn_out_of_range=False))
        row = re.search(rf'<tr><td class="name">{name}</td>(.*?)</tr>', page).group(1)
        assert f"{expected:.4f}" in row and f"{train_expected:.4f}" in row
    # Groups came from the column, not the file name.
    assert "<td class=\"name\">l5kg</td>" in page and "l10kg" in page
    assert 'id="fig-validation-curve"' in page and 'id="fig-temperature"' in page
    assert not re.search(r"https?://", page)


def test_without_training_data(files, tmp_path):
    d = files["dir"]
    out = tmp_path / "r.html"
    assert main(["report", str(d / "np1.json"), str(files["val_csv"]), "-o", str(out)]) == 0
    page = out.read_text(encoding="utf-8")
    assert "Training data:" not in page
    assert 'id="fig-errors-least-squares"' in page


@pytest.mark.parametrize("files_arg, message", [
    (["val.csv"], "No model files given"),
    (["np1.json"], "No data files given"),
    (["np1.json", "val.csv", "notes.txt"], "notes.txt: unknown file type '.txt'"),
    (["np1.json", "README"], "README: unknown file type '(no extension)'"),
])
def test_bad_file_lists(files, tmp_path, capsys, files_arg, message):
    out = tmp_path / "r.html"
    names = {"val.csv": str(files["val_csv"]), "np1.json": str(files["dir"] / "np1.json")}
    code = main(["report", *[names.get(f, str(tmp_path / f)) for f in files_arg], "-o", str(out)])
    err = capsys.readouterr().err
    assert code == 2
    assert message in err and len(err.strip().splitlines()) == 1
    assert not out.exists()


def test_bad_output_and_missing_files(files, tmp_path, capsys):
    d = files["dir"]
    assert main(["report", str(d / "np1.json"), str(files["val_csv"]), "-o", str(tmp_path / "r.pdf")]) == 2
    assert "must end in .html" in capsys.readouterr().err
    assert main(["report", str(tmp_path / "absent.json"), str(files["val_csv"]), "-o", str(tmp_path / "r.html")]) == 2
    assert "absent.json" in capsys.readouterr().err
    assert main(["report", str(d / "np1.json"), str(tmp_path / "absent.csv"), "-o", str(tmp_path / "r.html")]) == 2
    assert "absent.csv: no such file" in capsys.readouterr().err
    assert main(["report", str(d / "np1.json"), str(files["val_csv"]), "--inputs", "u1,u2",
                 "-o", str(tmp_path / "r.html")]) == 2
    assert "no input column" in capsys.readouterr().err
    assert sorted(p.name for p in tmp_path.iterdir()) == []


def test_help_lists_report(capsys):
    with pytest.raises(SystemExit):
        main(["--help"])
    assert "report" in capsys.readouterr().out
