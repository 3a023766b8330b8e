"""What a report is made of: one :class:`ModelRun` per evaluated model.

A run carries the metrics and the validation prediction, so the report never
refits or re-predicts; :func:`evaluate` makes a run from a fitted model.
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ..core.dataset import Dataset
from ..core.families import ModelFamily
from ..runtime.errors import FtcalError
from ..runtime.deprecation import deprecated_alias

LASSO_SOLVERS = ("lasso", "osqp-lasso")
RIDGE_SOLVERS = ("ridge",)
_TEMPERATURE = re.compile(r"(^|[_\W])(t|temp|temperature)$", re.IGNORECASE)


@dataclass
class ModelRun:
    """One model evaluated on the validation set (and optionally the training set).

    Attributes
    ----------
    name : label in tables and legends, e.g. ``"np4"`` or ``"np4 λ=50"``
    model : a fitted model of any family (:class:`~ftcal.core.families.ModelFamily`)
    train_metrics : ``model.metrics(train)`` style dict, or None
    validation_metrics : ``model.metrics(validation)`` style dict
    validation_prediction : ndarray of shape (n_validation, n_outputs), columns in
        ``model.output_names_`` order
    """

    name: str
    model: ModelFamily
    train_metrics: dict | None
    validation_metrics: dict
    validation_prediction: np.ndarray

    @property
    def family(self) -> str:
        """"least squares", "LASSO", "ridge" (the paper's experiments) or, beyond polynomials, the model family."""
        if self.model.family != "polynomial":
            return self.model.family.upper() if self.model.family == "mlp" else self.model.family
        solver = str(self.model.solver_info_.get("name") or "")
        if solver in LASSO_SOLVERS:
            return "LASSO"
        if solver in RIDGE_SOLVERS:
            return "ridge"
        return "least squares"

    @property
    def lam(self) -> float | None:
        lam = self.model.solver_info_.get("lambda")
        return None if lam is None else float(lam)


def default_name(model: ModelFamily) -> str:
    """``np4``, ``np4 lasso λ=50``, ``np2 na=1 nb=1``, ``mlp 32,32 tanh``: the family's label."""
    return model.label()


def evaluate_run(model: ModelFamily, validation: Dataset, *, name: str | None = None,
             train: Dataset | None = None) -> ModelRun:
    """Score ``model`` on ``validation`` (and ``train``) and keep its validation prediction.

    Samples outside the training range are counted (``n_out_of_range`` in the
    metrics, a column of the report) instead of warned about.
    """
    validation_metrics = model.metrics(validation, warn_out_of_range=False)
    # The prediction the metrics score: one-step for ARX models (the paper's evaluation).
    prediction = model.predict(validation, mode="one-step", warn_out_of_range=False)
    train_metrics = None if train is None else model.metrics(train, warn_out_of_range=False)
    return ModelRun(name or default_name(model), model, train_metrics, validation_metrics, prediction)


def expected_outputs(run: ModelRun, data: Dataset) -> np.ndarray:
    """The reference outputs of ``data`` in the order of the run's prediction columns."""
    if data.outputs is None:
        raise FtcalError("The report needs reference outputs (the expected wrench) in the validation data.")
    index = {n: i for i, n in enumerate(data.output_names)}
    missing = [n for n in run.model.output_names_ if n not in index]
    if missing:
        raise FtcalError(f"Model {run.name!r} predicts {', '.join(missing)}, which the validation data lacks.")
    return data.outputs[:, [index[n] for n in run.model.output_names_]]


def temperature_column(names: Sequence[str]) -> int | None:
    """Index of the temperature input (``T``, ``temp``, ``r_arm_ft_T``...), or None."""
    for i, name in enumerate(names):
        if _TEMPERATURE.search(name):
            return i
    return None


def natural_key(label) -> tuple:
    """Sort ``l2kg`` before ``l10kg``: digit runs compare as numbers."""
    parts = re.split(r"(\d+(?:\.\d+)?)", str(label))
    return tuple(float(p) if i % 2 else p for i, p in enumerate(parts))


# The old name, shadowed by the evaluate step (ftcal.evaluate, another signature).
evaluate = deprecated_alias(evaluate_run, "ftcal.report.evaluate", "ftcal.report.evaluate_run")
