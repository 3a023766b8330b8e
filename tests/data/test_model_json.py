"""Native JSON model file: lossless round trip, digest, schema and consistency errors."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ftcal.core.dataset import Dataset
from ftcal.core.features import MonomialBasis, RegressorLayout
from ftcal.core.model import CalibrationModel, model_from_fitted
from ftcal.core.normalization import Normalization
from ftcal.core.solvers.lasso import Lasso
from ftcal.files.model_files import load_model, load_model_file, save_model
from ftcal.files.model_json import digest, format_document, model_document, parse_model
from ftcal.runtime.errors import FtcalError


def fitted(degree=2, na=0, nb=0, solver=None, seed=0):
    rng = np.random.default_rng(seed)
    u = rng.uniform([4000, -200, 25], [6000, 300, 45], (400, 3))
    y = np.c_[0.01 * u[:, 0] + 1e-6 * u[:, 1] ** 2, 0.02 * u[:, 1] - 0.3 * u[:, 2]]
    y += rng.normal(0, 0.01, y.shape)
    data = Dataset.from_arrays(u, y, input_names=["s1", "s2", "T"], output_names=["Fx", "Tz"])
    return CalibrationModel(degree, na=na, nb=nb, solver=solver).fit(data), u


def resign(doc):
    doc["sha256"] = digest(doc)
    return format_document(doc)


def test_static_round_trip_is_bit_identical(tmp_path):
    model, u = fitted(solver=Lasso(0.5))
    path = tmp_path / "m.json"
    save_model(model, path, sources=["run1.mat", "run2.mat"], input_units=["count", "count", "degC"],
               output_units=["N", "Nm"])
    loaded_file = load_model_file(path)
    loaded = loaded_file.model
    np.testing.assert_array_equal(loaded.predict(u), model.predict(u))
    np.testing.assert_array_equal(loaded.coef_, model.coef_)
    assert loaded.input_names_ == ("s1", "s2", "T") and loaded.output_names_ == ("Fx", "Tz")
    np.testing.assert_array_equal(loaded.input_range_, model.input_range_)
    # A LASSO fit is stored in the paper's basis by default (issue 9, item 1).
    assert (loaded.degree, loaded.na, loaded.nb, loaded.normalization_) == (2, 0, 0, "maxabs")
    assert loaded.solver_info_["name"] == "lasso" and loaded.solver_info_["lambda"] == 0.5
    assert loaded.n_samples_fit_ == 400 and loaded.rank_ == model.rank_
    assert loaded.condition_number_ == model.condition_number_
    assert loaded.training_metrics_["rmse"] == list(model.training_metrics_["rmse"])
    assert loaded_file.input_units == ("count", "count", "degC")
    assert loaded_file.sources == ("run1.mat", "run2.mat")


def test_arx_round_trip_is_bit_identical(tmp_path):
    model, u = fitted(degree=1, na=1, nb=1)
    path = tmp_path / "arx.json"
    save_model(model, path)
    np.testing.assert_array_equal(load_model(path).predict(u), model.predict(u))


def test_file_is_readable_and_lists_terms(tmp_path):
    model, _ = fitted()
    path = tmp_path / "m.json"
    save_model(model, path)
    doc = json.loads(path.read_text())
    assert doc["format"] == "ftcal-model" and doc["format_version"] == "1.0"
    # Degree 2 in (s1, s2, T): 3 linear, 6 quadratic terms and the offset, in the paper's order.
    assert doc["terms"]["names"] == ["s1", "s2", "T", "s1^2", "s1·s2", "s1·T", "s2^2", "s2·T", "T^2", "1"]
    assert doc["terms"]["exponents"][4] == [1, 1, 0]
    assert len(doc["sha256"]) == 64


@st.composite
def random_models(draw):
    nu, ny = draw(st.integers(1, 3)), draw(st.integers(1, 3))
    degree = draw(st.integers(1, 3))
    na, nb = draw(st.sampled_from([(0, 0), (1, 0), (0, 1), (2, 1)]))
    n = RegressorLayout(MonomialBasis(nu, degree), ny, na, nb).n_features
    # Any float text (subnormals, -0.0, 17-digit mantissas), within magnitudes a fitted model's
    # prediction stays finite at: loading refuses a model that overflows inside its own range (issue 27).
    finite = st.floats(min_value=-1e100, max_value=1e100)
    positive = st.floats(min_value=1e-100, max_value=1e100)
    coef = draw(st.lists(finite, min_size=n * ny, max_size=n * ny))
    offsets = draw(st.lists(finite, min_size=nu + ny, max_size=nu + ny))
    scales = draw(st.lists(positive, min_size=nu + ny, max_size=nu + ny))
    return model_from_fitted(
        degree=degree, na=na, nb=nb, normalization="maxabs", coef=np.reshape(coef, (n, ny)),
        input_normalization=Normalization(np.array(offsets[:nu]), np.array(scales[:nu])),
        output_normalization=Normalization(np.array(offsets[nu:]), np.array(scales[nu:])),
        input_names=[f"in{i}" for i in range(nu)], output_names=[f"out{i}" for i in range(ny)],
        input_range=np.tile([-np.inf, np.inf], (nu, 1)), output_range=np.tile([-np.inf, 2.5], (ny, 1)),
        training_metrics={"rmse": [float("nan")] * ny})


@settings(max_examples=60, deadline=None)
@given(random_models())
def test_random_models_round_trip_exactly(model):
    loaded = parse_model(format_document(model_document(model))).model
    # Bitwise equality (also keeps −0.0 apart from 0.0).
    assert loaded.coef_.tobytes() == model.coef_.tobytes()
    for a, b in ((loaded.input_normalization_, model.input_normalization_),
                 (loaded.output_normalization_, model.output_normalization_)):
        assert a.offset.tobytes() == b.offset.tobytes() and a.scale.tobytes() == b.scale.tobytes()
    np.testing.assert_array_equal(loaded.input_range_, model.input_range_)
    np.testing.assert_array_equal(loaded.output_range_, model.output_range_)
    assert loaded.training_metrics_ == {"rmse": [None] * len(model.output_names_)}
    assert math.isnan(loaded.condition_number_)


def test_nan_is_written_as_null():
    model, _ = fitted(degree=1)
    model.training_metrics_ = {"best_fit": [float("nan"), 0.5]}
    text = format_document(model_document(model))
    assert "NaN" not in text
    assert json.loads(text)["fit"]["metrics"]["best_fit"] == [None, 0.5]


@pytest.fixture(scope="module")
def saved_text():
    model, _ = fitted(degree=1)
    return format_document(model_document(model))


def test_truncated_file_reports_line_and_column(saved_text):
    with pytest.raises(FtcalError, match=r"m\.json: not valid JSON: .* line \d+, column \d+"):
        parse_model(saved_text[: len(saved_text) // 2], "m.json")


def test_tampered_coefficient_fails_the_digest(saved_text):
    doc = json.loads(saved_text)
    doc["coefficients"][1][0] = 2 * doc["coefficients"][1][0] + 1
    with pytest.raises(FtcalError, match="modified after it was written"):
        parse_model(format_document(doc), "m.json")


def test_schema_violation_names_the_field(saved_text):
    doc = json.loads(saved_text)
    doc["inputs"][1]["scale"] = -2.0
    with pytest.raises(FtcalError, match=r"m\.json: invalid model file at \$\.inputs\[1\]\.scale: "):
        parse_model(format_document(doc), "m.json")
    doc = json.loads(saved_text)
    doc["coefficients"][0][1] = "3.5"
    with pytest.raises(FtcalError, match=r"\$\.coefficients\[0\]\[1\]: '3\.5' is not of type 'number'"):
        parse_model(format_document(doc), "m.json")


def test_digest_covers_content_not_layout(saved_text):
    relaid = json.dumps(json.loads(saved_text), indent=7)
    assert relaid != saved_text
    parse_model(relaid, "m.json")


def test_newer_format_version_asks_for_an_upgrade(saved_text):
    doc = json.loads(saved_text)
    doc["format_version"] = "2.0"
    with pytest.raises(FtcalError, match="newer .* upgrade ftcal"):
        parse_model(resign(doc), "m.json")


def test_exponent_table_must_match_the_model_class(saved_text):
    doc = json.loads(saved_text)
    doc["terms"]["exponents"][0], doc["terms"]["exponents"][1] = doc["terms"]["exponents"][1], \
        doc["terms"]["exponents"][0]
    with pytest.raises(FtcalError, match=r"terms\.exponents\[0\] is \[0, 1, 0\]; degree 1.* \[1, 0, 0\]"):
        parse_model(resign(doc), "m.json")


def test_coefficient_shape_must_match(saved_text):
    doc = json.loads(saved_text)
    doc["coefficients"][2].append(1.0)
    with pytest.raises(FtcalError, match=r"coefficients\[2\] has 3 values; the model has 2 outputs"):
        parse_model(resign(doc), "m.json")
    doc = json.loads(saved_text)
    doc["coefficients"].pop()
    with pytest.raises(FtcalError, match="coefficients has 3 entries; degree 1, na=0, nb=0 with 3 inputs and 2 outputs has 4 terms"):
        parse_model(resign(doc), "m.json")


def test_other_documents_are_not_model_files(saved_text):
    with pytest.raises(FtcalError, match="not an ftcal model file"):
        parse_model('{"format": "something-else"}', "m.json")
    with pytest.raises(FtcalError, match="NaN is not valid JSON"):
        parse_model(saved_text.replace('"condition_number": ', '"condition_number": NaN, "x": '), "m.json")


def test_read_model_dispatches_on_content(tmp_path):
    model, u = fitted(degree=1)
    json_path = save_model(model, tmp_path / "model.any", "json", output_units=["N", "Nm"])
    xml_path = save_model(model, tmp_path / "model.other", "paper-xml")
    assert load_model_file(json_path).output_units == ("N", "Nm")
    np.testing.assert_array_equal(load_model(json_path).predict(u), model.predict(u))
    xml_model = load_model(xml_path)
    np.testing.assert_allclose(xml_model.predict(u), model.predict(u), rtol=1e-9)
    (tmp_path / "junk").write_text("hello")
    with pytest.raises(FtcalError, match="neither an ftcal JSON model file nor a paper XML"):
        load_model(tmp_path / "junk")
    with pytest.raises(FtcalError, match="is a directory; give the path of the json file"):
        save_model(model, tmp_path, "json")
    with pytest.raises(FtcalError, match="'fmt' parameter of save_model must be one of"):
        save_model(model, tmp_path / "x", "pickle")
