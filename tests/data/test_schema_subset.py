"""The packaged schemas' validity without jsonschema (issue 43, item 5: ``ftcal info`` imports no jsonschema).

Reference: jsonschema itself (Draft 2020-12 with ftcal's strict integers, the validator the model files used
before), on valid documents of each kind and on Hypothesis mutations of them (a key removed, added or given
another JSON value, at any depth): the subset validator must agree with it on every document.
"""

import copy
import json
import warnings

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from ftcal.core.dataset import Dataset
from ftcal.core.mlp import MLPModel
from ftcal.core.model import CalibrationModel
from ftcal.files import model_json
from ftcal.files.model_json import model_document
from ftcal.files.payload_json import payload_document
from ftcal.files.schema_subset import Unsupported, is_valid
from ftcal.payload.parameters import PayloadParameters

RESOURCES = {"model": "schemas/model-1.json", "payload": "schemas/payload-1.json"}


def documents():
    rng = np.random.default_rng(2)
    u = rng.normal(size=(300, 3))
    data = Dataset.from_arrays(u, u ** 2 + u, input_names=["a", "b", "c"], output_names=["Fx", "Fy", "Fz"])
    grip = PayloadParameters(1.2, np.array([0.004, -0.003, 0.06]), np.zeros(3), np.zeros(3), 9.81,
                             stderr={"mass": 1e-3, "com": np.full(3, 1e-4), "force_bias": np.full(3, .01),
                                     "torque_bias": np.full(3, 1e-3)},
                             fit={"n_samples": 100, "residual_rms": [0.01] * 6, "condition_number": 1.0,
                                  "wrench_columns": ["Fx", "Fy", "Fz", "Tx", "Ty", "Tz"]})
    from ftcal.core.solvers.least_squares import Ridge

    with warnings.catch_warnings():  # independent rows: the lags are near collinear, any fitted ARX will do
        warnings.simplefilter("ignore")
        arx = CalibrationModel(1, na=1, nb=1, solver=Ridge(1e-3)).fit(data)
    return {"polynomial": ("model", model_document(CalibrationModel(2).fit(data))),
            "arx": ("model", model_document(arx)),
            "mlp": ("model", model_document(MLPModel(hidden=(3,), max_iter=20, early_stopping=False).fit(data))),
            "payload": ("payload", json.loads(json.dumps(payload_document(grip))))}


DOCUMENTS = documents()
JSON = st.recursive(st.one_of(st.none(), st.booleans(), st.integers(-3, 3), st.floats(-1e3, 1e3), st.just(2.0),
                              st.text(max_size=6), st.sampled_from(["Fx", "polynomial", "center", "ftcal-model"])),
                    lambda inner: st.one_of(st.lists(inner, max_size=3),
                                            st.dictionaries(st.text(max_size=5), inner, max_size=3)), max_leaves=6)


def jsonschema_valid(kind, doc):
    return not any(True for _ in model_json._validator(RESOURCES[kind]).iter_errors(doc))


@pytest.mark.parametrize("name", sorted(DOCUMENTS))
def test_written_documents_are_valid_for_both(name):
    kind, doc = DOCUMENTS[name]
    assert jsonschema_valid(kind, doc)
    assert is_valid(model_json._schema(RESOURCES[kind]), doc)


def paths(value, prefix=()):
    """Every (path, container) position of a JSON value."""
    yield prefix
    if isinstance(value, dict):
        for key, item in value.items():
            yield from paths(item, (*prefix, key))
    elif isinstance(value, list):
        for index, item in enumerate(value):
            yield from paths(item, (*prefix, index))


@settings(max_examples=400, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(name=st.sampled_from(sorted(DOCUMENTS)), data=st.data())
def test_the_subset_agrees_with_jsonschema_on_mutated_documents(name, data):
    kind, original = DOCUMENTS[name]
    doc = copy.deepcopy(original)
    for _ in range(data.draw(st.integers(1, 3))):
        where = data.draw(st.sampled_from(list(paths(doc))))
        if not where:
            continue
        parent = doc
        for step in where[:-1]:
            parent = parent[step]
        action = data.draw(st.sampled_from(["replace", "delete", "add"]))
        if action == "replace":
            parent[where[-1]] = data.draw(JSON)
        elif action == "delete":
            del parent[where[-1]]
        elif isinstance(parent, dict):
            parent[data.draw(st.text(max_size=8))] = data.draw(JSON)
        else:
            parent.append(data.draw(JSON))
    try:
        fast = is_valid(model_json._schema(RESOURCES[kind]), doc)
    except Unsupported:
        return  # jsonschema decides those documents in check_document
    assert fast == jsonschema_valid(kind, doc)
