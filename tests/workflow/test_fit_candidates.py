"""The fit_candidates step: several candidates from one statistics pass, each as if fitted alone."""

from __future__ import annotations

import numpy as np
import pandas as pd

from ftcal import CalibrationModel, Dataset
from ftcal.core.select import Candidate
from ftcal.core.solvers.lasso import Lasso
from ftcal.workflow import fit_candidates

INPUTS = tuple(f"u{i}" for i in range(1, 7))
OUTPUTS = ("Fx", "Fy", "Fz", "Tx", "Ty", "Tz")


def _sensor(n=400, seed=3):
    """A quadratic sensor without noise: degree 2 holds it exactly (truth known)."""
    rng = np.random.default_rng(seed)
    u = rng.uniform(-2.0, 2.0, size=(n, 6))
    gain = np.eye(6) + 0.05 * rng.normal(size=(6, 6))
    wrench = u @ gain.T + 0.02 * u[:, [0]] * u[:, [1]] - 0.01 * u ** 2
    return Dataset.from_arrays(u, wrench, input_names=INPUTS, output_names=OUTPUTS), u, wrench


def test_each_candidate_is_the_model_fitted_on_its_own():
    data, u, wrench = _sensor()
    wanted = [Candidate(1, "none", None), Candidate(2, "none", None), Candidate(2, "lasso", 0.5)]
    result = fit_candidates(data, wanted)
    assert list(result.models) == wanted and result.n_samples == 400
    alone = {wanted[0]: CalibrationModel(degree=1).fit(data), wanted[1]: CalibrationModel(degree=2).fit(data),
             wanted[2]: CalibrationModel(degree=2, solver=Lasso(0.5)).fit(data)}
    probe = np.random.default_rng(9).uniform(-2.0, 2.0, size=(50, 6))
    for candidate, model in result.models.items():
        np.testing.assert_allclose(model.predict(probe), alone[candidate].predict(probe), rtol=0, atol=1e-8)
    # Degree 2 holds the quadratic sensor: its error on the training rows is rounding only; affine's is not.
    assert np.abs(result.models[wanted[1]].predict(u) - wrench).max() < 1e-9
    assert np.abs(result.models[wanted[0]].predict(u) - wrench).max() > 1e-3


def test_tables_in_memory_read_as_ftcal_fit_reads_them():
    data, u, wrench = _sensor(seed=5)
    frame = pd.DataFrame(np.c_[u, wrench], columns=[*INPUTS, *OUTPUTS])
    from_frame = fit_candidates(frame, [Candidate(2, "none", None)]).models[Candidate(2, "none", None)]
    from_data = fit_candidates(data, [Candidate(2, "none", None)]).models[Candidate(2, "none", None)]
    np.testing.assert_allclose(from_frame.predict(u), from_data.predict(u), rtol=0, atol=1e-9)
    assert "1 candidate(s) fitted on 400 samples" in fit_candidates(frame, [Candidate(1, "none", None)]).summary()


def test_an_estimator_candidate_is_fitted_as_it_stands():
    """A network among the candidates is a template: its clone, fitted as its own fit does (the step sizes nothing)."""
    from ftcal.core.mlp import MLPModel

    _, u, wrench = _sensor(n=300, seed=7)
    data = Dataset.from_arrays(u, wrench, input_names=INPUTS, output_names=OUTPUTS,
                               groups=np.repeat(np.arange(3), 100))
    options = {"max_iter": 30, "max_samples": 200, "seed": 4}
    network = MLPModel((5,), **options)
    result = fit_candidates(data, [network, Candidate(1, "none", None)])
    assert list(result.models) == [network, Candidate(1, "none", None)] and not hasattr(network, "weights_")
    alone = MLPModel((5,), **options).fit(data)
    np.testing.assert_array_equal(result.models[network].predict(u), alone.predict(u))
    assert result.models[network].n_iter_ == alone.n_iter_
    assert "mlp 5 tanh" in result.summary() and result.to_dict()["models"][0]["family"] == "mlp"
