"""The live state file's envelope and model digest have one home (``ftcal.files.state_json``), shared with
the model and payload files' canonical-JSON digest (issue #43).

What a digest must do, checked on models fitted here: the same model read back from its file resumes the
state (the digest survives the file's round trip, non-finite fields included: the OSQP solver states no
condition number, NaN), and a model that differs in one coefficient does not.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from ftcal.core.dataset import Dataset
from ftcal.core.model import CalibrationModel
from ftcal.core.solvers.osqp_qp import OsqpLeastSquares
from ftcal.files.model_files import load_model, save_model
from ftcal.files.state_json import STATE_FORMAT, check_state_envelope, model_digest
from ftcal.live import LiveCalibrator
from ftcal.runtime.errors import FtcalError

NOISE = [0.05] * 6
DOWN = [0.0, 0.0, -9.81]


def _model():
    rng = np.random.default_rng(4)
    raw = rng.uniform(-20, 20, size=(400, 6))
    wrench = raw @ (np.eye(6) + 0.05 * rng.normal(size=(6, 6))).T + 0.01 * raw ** 2
    return CalibrationModel(degree=2, solver=OsqpLeastSquares()).fit(Dataset.from_arrays(raw, wrench))


def test_a_state_resumes_with_the_model_read_back_from_its_file(tmp_path):
    model = _model()
    assert np.isnan(model.condition_number_)  # a non-finite field the digest must carry
    save_model(model, tmp_path / "m.json")
    first = LiveCalibrator(model, noise_std=NOISE)
    first.step(1.0, raw=[0.0] * 6, gravity=DOWN)
    first.save_state(tmp_path / "state.json")
    doc = json.loads((tmp_path / "state.json").read_text())
    assert doc["format"] == STATE_FORMAT and doc["model"] == model_digest(load_model(tmp_path / "m.json"))
    resumed = LiveCalibrator(load_model(tmp_path / "m.json"), noise_std=NOISE, state_path=tmp_path / "state.json")
    assert resumed.last_time == 1.0


def test_one_coefficient_changed_is_another_model(tmp_path):
    model = _model()
    other = load_model(save_model(model, tmp_path / "m.json"))
    other.coef_ = other.coef_.copy()
    other.coef_[0, 0] += 1e-9
    assert model_digest(other) != model_digest(model) and model_digest(None) is None
    LiveCalibrator(model, noise_std=NOISE).save_state(tmp_path / "state.json")
    with pytest.raises(FtcalError, match="written for another calibration model"):
        LiveCalibrator(other, noise_std=NOISE, state_path=tmp_path / "state.json")


@pytest.mark.parametrize("doc", [[], {"format": "ftcal-model", "format_version": "1.0"},
                                 {"format": STATE_FORMAT, "format_version": "9.9"}])
def test_what_is_not_a_state_file_of_this_version_is_one_line(doc):
    with pytest.raises(FtcalError, match=r"^s\.json: not a live state file \(ftcal-live-state 1\.1\)\.$"):
        check_state_envelope(doc, "s.json")


def test_a_state_file_of_the_earlier_digest_is_named_not_called_another_model(tmp_path):
    # A 1.0 file hashed its model with json.dumps(default=repr): its digest matches no model, so it is named as an
    # earlier file (one line) rather than refused as another model's.
    model = load_model(save_model(_model(), tmp_path / "m.json"))
    LiveCalibrator(model, noise_std=NOISE).save_state(tmp_path / "state.json")
    doc = json.loads((tmp_path / "state.json").read_text())
    doc["format_version"] = "1.0"
    (tmp_path / "state.json").write_text(json.dumps(doc))
    with pytest.raises(FtcalError, match=r"^\S*state\.json: a live state file of an earlier ftcal \(ftcal-live-state 1\.0\)[^\n]*$"):
        LiveCalibrator(model, noise_std=NOISE, state_path=tmp_path / "state.json")
