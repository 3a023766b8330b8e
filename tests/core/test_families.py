"""Model families as plug-ins: the protocol, the registry, model files with and without ``family``.

The proof that a new family is one module plus one registry line: :class:`LinearFamily` below is a
whole family (least squares on normalized inputs) that becomes loadable, predictable and evaluable
by ``ftcal`` through one ``FAMILIES`` entry, and that ``ftcal convert`` refuses where it does not export.
"""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

from ftcal.cli import main
from ftcal.core import families
from ftcal.core.dataset import Dataset
from ftcal.core.families import FAMILIES, ModelFamily, family_class
from ftcal.core.limits import FAMILY_NAMES
from ftcal.core.mlp import MLPModel
from ftcal.core.model import CalibrationModel
from ftcal.core.normalization import normalization_from_range, variables_normalization, variables_range
from ftcal.files.model_files import load_model
from ftcal.files.model_files import load_model, save_model
from ftcal.files.model_json import digest, format_document, model_document
from ftcal.runtime.errors import FtcalError

INPUTS = ("u1", "u2", "u3")
OUTPUTS = ("Fx", "Fy", "Fz", "Tx", "Ty", "Tz")


class LinearFamily:
    """A whole model family in one class: y = offset + scale · ([x, 1] @ M), M by least squares."""

    family = "test-linear"
    exports = frozenset({"json"})
    streams = False
    is_static = True

    def fit(self, data, outputs=None):
        u, y = data.inputs, data.outputs
        self.input_normalization_ = normalization_from_range(u.min(0), u.max(0))
        self.output_normalization_ = normalization_from_range(y.min(0), y.max(0))
        x = np.c_[self.input_normalization_.apply(u), np.ones(len(u))]
        self.matrix_ = np.linalg.lstsq(x, self.output_normalization_.apply(y), rcond=None)[0]
        self.input_names_, self.output_names_ = tuple(data.input_names), tuple(data.output_names)
        self.input_range_, self.output_range_ = np.c_[u.min(0), u.max(0)], np.c_[y.min(0), y.max(0)]
        self.n_samples_fit_ = len(u)
        self.solver_info_ = {"name": "lstsq", "lambda": None}
        self.training_metrics_ = self.metrics(data)
        return self

    def predict(self, data, *, mode="free-run", start="zeros", warn_out_of_range=True):
        u = data.select_inputs(self.input_names_) if isinstance(data, Dataset) else np.asarray(data)
        x = np.c_[self.input_normalization_.apply(u), np.ones(len(u))]
        return self.output_normalization_.offset + self.output_normalization_.scale * (x @ self.matrix_)

    def metrics(self, data, *, mode="one-step", start="zeros", warmup="drop", warn_out_of_range=True):
        from ftcal.core.metrics import summarize

        summary = summarize(data.outputs, self.predict(data), self.output_names_)
        summary["n_out_of_range"] = int(self.out_of_range(data.inputs).sum())
        return summary

    def out_of_range(self, inputs):
        return np.any((inputs < self.input_range_[:, 0]) | (inputs > self.input_range_[:, 1]), axis=1)

    def describe(self):
        return {"degree": 1, "na": 0, "nb": 0, "n_inputs": len(self.input_names_),
                "n_outputs": len(self.output_names_), "n_coefficients": int(self.matrix_.size),
                "n_nonzero": int(np.count_nonzero(self.matrix_))}

    def label(self):
        return "linear"

    def to_document(self):
        return {"parameters": {"matrix": self.matrix_.tolist()}}

    @classmethod
    def from_document(cls, doc, source):
        model = cls()
        model.matrix_ = np.array(doc["parameters"]["matrix"], dtype=np.float64)
        ins, outs = doc["inputs"], doc["outputs"]
        model.input_normalization_, model.output_normalization_ = variables_normalization(ins), variables_normalization(outs)
        model.input_range_, model.output_range_ = variables_range(ins), variables_range(outs)
        model.input_names_ = tuple(v["name"] for v in ins)
        model.output_names_ = tuple(v["name"] for v in outs)
        model.n_samples_fit_ = doc["fit"]["n_samples"]
        model.solver_info_ = doc["fit"]["solver"]
        model.training_metrics_ = doc["fit"]["metrics"]
        return model


def linear_data(n=400, seed=0, groups=4):
    """Outputs exactly affine in the inputs: y = u @ A + b (the truth the family must recover)."""
    rng = np.random.default_rng(seed)
    u = rng.uniform(-2.0, 3.0, (n, len(INPUTS)))
    a = rng.normal(size=(len(INPUTS), len(OUTPUTS)))
    b = rng.normal(size=len(OUTPUTS))
    return Dataset.from_arrays(u, u @ a + b, input_names=INPUTS, output_names=OUTPUTS,
                               groups=np.repeat(np.arange(groups), n // groups)), a, b


def test_both_shipped_families_follow_the_protocol_and_are_registered():
    assert tuple(FAMILIES) == FAMILY_NAMES
    assert family_class("polynomial") is CalibrationModel and family_class("mlp") is MLPModel
    for model in (CalibrationModel(2), CalibrationModel(1, na=1), MLPModel((4,))):
        assert isinstance(model, ModelFamily)
    assert CalibrationModel(1).is_static and not CalibrationModel(1, na=1).is_static and MLPModel().is_static
    assert not isinstance(object(), ModelFamily)


def test_unknown_family_in_a_file_is_one_clear_error(tmp_path):
    data, _, _ = linear_data()
    doc = model_document(MLPModel((3,), max_iter=5, early_stopping=False).fit(data))
    doc["family"] = "forest"
    doc["sha256"] = digest(doc)
    path = tmp_path / "forest.json"
    path.write_text(format_document(doc))
    with pytest.raises(FtcalError, match=r"forest\.json: unknown model family 'forest'; this ftcal knows polynomial, mlp"):
        load_model(path)


def test_a_new_family_is_one_class_plus_one_registry_line(tmp_path, monkeypatch, capsys):
    monkeypatch.setitem(FAMILIES, "test-linear", f"{__name__}:LinearFamily")
    data, a, b = linear_data()
    model = LinearFamily().fit(data)
    assert isinstance(model, ModelFamily)
    path = tmp_path / "linear.json"
    save_model(model, path)
    doc = json.loads(path.read_text())
    assert doc["family"] == "test-linear" and "coefficients" not in doc
    loaded = load_model(path)
    assert type(loaded).__name__ == "LinearFamily"
    u_new = np.array([[0.5, -1.0, 2.5], [1.5, 0.2, -1.5]])  # inside the training box
    np.testing.assert_allclose(loaded.predict(u_new), u_new @ a + b, rtol=1e-10, atol=1e-10)  # the truth
    # predict and evaluate reach it through the registry alone.
    table = tmp_path / "new.csv"
    pd.DataFrame(np.c_[u_new, u_new @ a + b], columns=INPUTS + OUTPUTS).to_csv(table, index=False,
                                                                               float_format="%.17g")
    assert main(["predict", str(path), str(table), "-o", str(tmp_path / "p.csv")]) == 0
    np.testing.assert_allclose(pd.read_csv(tmp_path / "p.csv")[list(OUTPUTS)].to_numpy(), u_new @ a + b,
                               rtol=1e-10, atol=1e-10)
    capsys.readouterr()
    assert main(["evaluate", str(path), str(table), "--json"]) == 0
    assert max(json.loads(capsys.readouterr().out)["rmse"]) < 1e-9
    # A target the family does not export: one line, exit 2, nothing written.
    assert main(["convert", str(path), "--to", "c", "-o", str(tmp_path / "c")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == ["ftcal convert: error: --to c: the test-linear family cannot be exported there; it exports json."]
    assert not (tmp_path / "c").exists()


def test_a_registered_class_that_breaks_the_protocol_is_refused(monkeypatch):
    monkeypatch.setitem(FAMILIES, "broken", "ftcal.core.dataset:Dataset")
    with pytest.raises(FtcalError, match="does not follow ModelFamily: it lacks family"):
        families.family_class("broken")


def test_an_old_model_file_without_family_still_loads(tmp_path):
    """A file as ftcal wrote them before families: no ``family`` field (its digest made without one)."""
    data, a, b = linear_data()
    model = CalibrationModel(1).fit(data)
    doc = model_document(model)
    del doc["family"]
    doc["sha256"] = digest(doc)
    path = tmp_path / "old.json"
    path.write_text(format_document(doc))
    loaded = load_model(path)
    assert isinstance(loaded, CalibrationModel) and loaded.family == "polynomial"
    u = data.inputs[:50]
    assert np.array_equal(loaded.predict(u), model.predict(u))
    np.testing.assert_allclose(loaded.predict(u), u @ a + b, rtol=1e-9, atol=1e-9)


def test_new_polynomial_files_name_their_family_and_mixed_fields_are_refused(tmp_path):
    data, _, _ = linear_data()
    doc = model_document(CalibrationModel(2).fit(data))
    assert doc["family"] == "polynomial"
    doc["parameters"] = {"weights": []}  # a polynomial holds no family parameters
    doc["sha256"] = digest(doc)
    path = tmp_path / "mixed.json"
    path.write_text(format_document(doc))
    with pytest.raises(FtcalError, match=r"mixed\.json: invalid model file"):
        load_model(path)
