"""``ftcal info``'s numpy-free reading of a model file (:mod:`ftcal.files.model_info`, issue 43 item 5).

Reference: the full loader (:func:`ftcal.files.model_files.load_model_file`, numpy, scipy's sparse
substitution for the raw coefficients, numpy's argsort and eigvalsh) and the text ``info`` printed from
it before the light path existed (:func:`ftcal.files.model_info.loaded_facts`, unchanged). On written model files
the light path must be taken and print the same bytes; on mutated, re-signed documents (so that the
digest passes and the loader's later checks are reached) it must give up on every file the loader
refuses, and otherwise print what the loader's path prints.
"""

import copy
import json

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from ftcal.workflow.info import report
from ftcal.core.dataset import Dataset
from ftcal.core.model import CalibrationModel
from ftcal.core.solvers.lasso import Lasso
from ftcal.files.model_info import covariance_acceptable, jacobi_eigenvalues, light_facts, loaded_facts
from ftcal.files.model_json import digest, format_document, model_document
from ftcal.runtime.errors import FtcalError


def _data(rng, n_inputs=3, spread=1.0, centre=0.0):
    u = rng.normal(size=(400, n_inputs)) * spread + centre
    y = np.column_stack([u[:, 0] + 0.3 * u[:, 1] ** 2, u[:, 1] - 0.2 * u[:, 0] * u[:, -1], u[:, 2] ** 3 * 0.01])
    names = ["a", "b", "c", "T"][:n_inputs]
    return Dataset.from_arrays(u, y + 0.01 * rng.normal(size=y.shape), input_names=names,
                               output_names=["Fx", "Fy", "Fz"])


def models():
    rng = np.random.default_rng(7)
    data = _data(rng)
    found = {f"degree {d}": CalibrationModel(d).fit(data) for d in (1, 2, 3, 4)}
    found["temperature"] = CalibrationModel(2).fit(_data(rng, 4, spread=50.0, centre=20.0))
    found["lasso"] = CalibrationModel(3, solver=Lasso(1e-3)).fit(data)
    return found


MODELS = models()
DOCUMENTS = {name: model_document(model) for name, model in MODELS.items()}


def write(tmp_path, doc, name="model.json"):
    path = tmp_path / name
    path.write_text(format_document(doc), encoding="utf-8")
    return path


def full_text(path, terms=10):
    return report(str(path), loaded_facts(str(path), terms))


@pytest.mark.parametrize("name", sorted(DOCUMENTS))
@pytest.mark.parametrize("terms", [10, 3, 0, 1000])
def test_the_light_path_is_taken_and_prints_the_loaders_text(tmp_path, name, terms):
    path = write(tmp_path, DOCUMENTS[name])
    light = light_facts(path, terms)
    assert light is not None
    assert report(str(path), light) == full_text(path, terms)


def _perturbed(doc, rng):
    """Every float of the document times 1 + 1e-12·N(0, 1), re-signed."""
    def walk(value):
        if isinstance(value, dict):
            return {k: walk(v) for k, v in value.items()}
        if isinstance(value, list):
            return [walk(v) for v in value]
        if isinstance(value, float):
            return value * (1.0 + 1e-12 * rng.normal())
        return value

    out = walk({k: v for k, v in doc.items() if k not in ("created", "sha256")})
    out["created"] = doc["created"]
    out["sha256"] = digest(out)
    return out


@pytest.mark.parametrize("name", sorted(DOCUMENTS))
def test_a_1e_12_perturbation_prints_the_same_text(tmp_path, name):
    rng = np.random.default_rng(3)
    path = write(tmp_path, DOCUMENTS[name])
    moved = write(tmp_path, _perturbed(DOCUMENTS[name], rng), "moved.json")
    light, light_moved = light_facts(path, 10), light_facts(moved, 10)
    assert light is not None and light_moved is not None
    assert report("m", light) == report("m", light_moved) == report("m", loaded_facts(str(moved), 10))


@pytest.mark.parametrize("degree", [1, 3])
def test_fitting_inputs_perturbed_by_1e_12_prints_the_same_text(tmp_path, degree):
    rng = np.random.default_rng(11)
    data = _data(rng)
    u, y = data.inputs, data.outputs
    moved = Dataset.from_arrays(u * (1.0 + 1e-12 * rng.normal(size=u.shape)), y, input_names=data.input_names,
                                output_names=data.output_names)
    texts = []
    for which in (data, moved):
        doc = model_document(CalibrationModel(degree).fit(which))
        doc["created"] = DOCUMENTS["degree 1"]["created"]
        doc["sha256"] = digest(doc)
        light = light_facts(write(tmp_path, doc), 10)
        assert light is not None
        texts.append(report("m", light))
    assert texts[0] == texts[1]


def test_jacobi_eigenvalues_match_numpy():
    rng = np.random.default_rng(5)
    for n in (1, 2, 3, 7):
        a = rng.normal(size=(n, n))
        a = a + a.T
        got = sorted(jacobi_eigenvalues(a.tolist()))
        assert np.allclose(got, np.linalg.eigvalsh(a), rtol=0, atol=1e-12 * np.abs(a).max() * n)


def test_covariance_near_and_beyond_the_bound():
    # diag(1, -d): the loader refuses below -1e-9 * 1 * 2; the light check accepts only clearly above it.
    assert covariance_acceptable([[1.0, 0.0], [0.0, 0.0]])
    assert covariance_acceptable([[1.0, 0.0], [0.0, -1e-9]])
    assert not covariance_acceptable([[1.0, 0.0], [0.0, -2.1e-9]])
    assert not covariance_acceptable([[1.0, 2.0], [2.0, 1.0]])  # eigenvalues 3 and -1
    assert not covariance_acceptable([[1.0, 1e-6], [0.0, 1.0]])  # not symmetric


# Values that keep a document schema-valid but may break the loader's later checks.
NUMBERS = st.one_of(st.sampled_from([0.0, -0.0, 1.0, -1.0, 1e-320, 2.2250738585072014e-308, 1e-300, 1e300,
                                     1.7e308, -1.7e308, 1e-9, 1.0000000001e-9, 3.0, 0.5]),
                    st.floats(-1e6, 1e6, allow_nan=False), st.integers(-3, 12))
ANY = st.one_of(NUMBERS, st.none(), st.booleans(), st.text(max_size=4), st.sampled_from(["a", "Fx", "T"]),
                st.lists(st.integers(0, 3), max_size=4), st.lists(NUMBERS, max_size=4))


def positions(value, prefix=()):
    yield prefix
    if isinstance(value, dict):
        for key, item in value.items():
            yield from positions(item, (*prefix, key))
    elif isinstance(value, list):
        for index, item in enumerate(value):
            yield from positions(item, (*prefix, index))


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow,
                                                                   HealthCheck.function_scoped_fixture])
@given(name=st.sampled_from(sorted(DOCUMENTS)), data=st.data())
def test_the_light_path_never_accepts_what_the_loader_refuses(tmp_path, name, data):
    doc = copy.deepcopy(DOCUMENTS[name])
    for _ in range(data.draw(st.integers(1, 3))):
        where = data.draw(st.sampled_from([p for p in positions(doc) if p and p[0] not in ("sha256", "created")]))
        parent = doc
        for step in where[:-1]:
            parent = parent[step]
        action = data.draw(st.sampled_from(["number", "number", "any", "delete", "swap"]))
        if action == "number":
            parent[where[-1]] = data.draw(NUMBERS)
        elif action == "any":
            parent[where[-1]] = data.draw(ANY)
        elif action == "delete":
            del parent[where[-1]]
        elif isinstance(parent, list) and len(parent) > 1:
            i = data.draw(st.integers(0, len(parent) - 1))
            parent[i], parent[where[-1]] = parent[where[-1]], parent[i]
    doc["sha256"] = digest(doc)
    path = tmp_path / "mutated.json"
    path.write_text(json.dumps(doc), encoding="utf-8")
    light = light_facts(path, 10)
    try:
        expected = full_text(path)
    except FtcalError:
        assert light is None
        return
    if light is not None:
        assert report(str(path), light) == expected


@pytest.mark.parametrize("edit, message", [
    (lambda d: d["inputs"][0].update(scale=1e-320), "is too small to divide by"),
    (lambda d: d["inputs"][1].update(range=[2.0, 1.0]), "has min > max"),
    (lambda d: d["fit"]["input_spread"]["covariance"][0].__setitem__(1, 5.0), "is not symmetric"),
    (lambda d: d["fit"]["input_spread"].update(covariance=[[1.0, 2.0, 0.0], [2.0, 1.0, 0.0], [0.0, 0.0, 1.0]]),
     "not positive semi-definite"),
    (lambda d: d["inputs"][0].update(scale=1e-300), "prediction overflows"),  # a^2 of 1e300
    (lambda d: d["terms"]["exponents"].reverse(), "the paper's column order"),
])
def test_ftcal_info_refuses_what_the_loader_refuses_with_its_message(tmp_path, capsys, edit, message):
    from ftcal.cli import main

    doc = copy.deepcopy(DOCUMENTS["degree 2"])
    assert doc["fit"].get("input_spread") is not None
    edit(doc)
    doc["sha256"] = digest(doc)
    path = write(tmp_path, doc)
    with pytest.raises(FtcalError) as loader:
        loaded_facts(str(path), 10)
    assert message in str(loader.value)
    assert light_facts(path, 10) is None
    assert main(["info", str(path)]) == 2
    err = capsys.readouterr().err
    assert str(loader.value) in err and "Traceback" not in err
