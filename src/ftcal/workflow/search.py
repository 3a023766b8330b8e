"""A model search as an estimator (scikit-learn's ``GridSearchCV``/``LassoCV``): ``ModelSearch(...).fit(data)``.

The search is today's ``degree="auto"`` selection (grouped cross-validation over degree, penalty and λ,
:func:`ftcal.core.select.select_model`); this class only names its options once and keeps what it found,
``best_estimator_`` (the refitted model) and ``cv_results_`` (every candidate's scores), so that
:func:`ftcal.fit` can take it as its ``model``.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..core.limits import SELECTION_BUDGET_SECONDS
from ..runtime.errors import NotFittedError
from .result import StepResult


class ModelSearch:
    """Grouped cross-validation over polynomial degree and penalty, then a refit of the best on all the data.

    Parameters
    ----------
    max_degree : int
        Degrees 1..max_degree are tried (a degree is skipped when a lower one already did better).
    penalties : sequence of {"lasso", "ridge"}
        Penalized bases tried beside least squares.
    lambdas : sequence of float, optional
        λ grid (default: relative to each candidate's λ_max; the paper's grid is absolute).
    folds : int
        Number of grouped folds.
    select_per : {"block", "output", "model"}
        Choose one candidate for forces and one for torques, one per output, or one for all.
    objective : {"both", "force", "torque"}
        What the single best candidate is ranked by.
    budget : float
        CPU seconds the search may spend (degrees beyond it are dropped, said so).
    verbose : bool
        Report every candidate's scores, not only the summary.
    lasso, ridge : float, optional
        Search degree only, at this fixed penalty.

    Attributes
    ----------
    best_estimator_ : CalibrationModel
        The selected model, refitted on all the data.
    cv_results_ : dict of lists
        One entry per candidate tried: ``degree``, ``penalty``, ``lambda``, ``mean_test_score``,
        ``mean_train_score``, ``mean_nonzero`` (coefficients), ``split_test_scores`` (score units: ``metric_``).
    best_params_ : dict
        The best single candidate's ``degree``, ``penalty`` and ``lambda``.
    metric_ : str
        What the scores measure.
    selection_ : CrossValidationResult
        The whole search (selection per part, comparison with affine, notes).
    result_ : FitResult
        What :func:`ftcal.fit` returned.

    Examples
    --------
    >>> import numpy as np, pandas as pd
    >>> import ftcal
    >>> from ftcal.workflow.search import ModelSearch
    >>> rng = np.random.default_rng(0)
    >>> u = rng.uniform(-1, 1, (400, 1))
    >>> frame = pd.DataFrame({"u1": u[:, 0], "Fx": 2 * u[:, 0] + u[:, 0] ** 2 + 0.01 * rng.normal(size=400),
    ...                       "load": np.repeat(np.arange(4), 100)})
    >>> search = ModelSearch(max_degree=3, penalties=(), folds=4).fit(frame, inputs=["u1"], outputs=["Fx"],
    ...                                                               group_by="load")
    >>> search.best_params_["degree"] >= 2, len(search.cv_results_["degree"]) >= 2
    (True, True)
    """

    def __init__(self, max_degree: int = 5, *, penalties: Sequence[str] = ("lasso", "ridge"),
                 lambdas: Sequence[float] | None = None, folds: int = 5, select_per: str = "block",
                 objective: str = "both", budget: float = SELECTION_BUDGET_SECONDS, verbose: bool = False,
                 lasso: float | None = None, ridge: float | None = None):
        self.max_degree = max_degree
        self.penalties = penalties
        self.lambdas = lambdas
        self.folds = folds
        self.select_per = select_per
        self.objective = objective
        self.budget = budget
        self.verbose = verbose
        self.lasso = lasso
        self.ridge = ridge

    def get_params(self) -> dict[str, Any]:
        """The search's options, as :func:`ftcal.fit` takes them with ``degree="auto"``."""
        return {"max_degree": self.max_degree, "penalties": tuple(self.penalties),
                "lambdas": None if self.lambdas is None else tuple(self.lambdas), "folds": self.folds,
                "select_per": self.select_per, "objective": self.objective, "budget": self.budget,
                "verbose": self.verbose, "lasso": self.lasso, "ridge": self.ridge}

    def search_keywords(self) -> dict[str, Any]:
        """The keywords of :func:`ftcal.fit` this search stands for: ``degree="auto"`` and its options."""
        return {"degree": "auto", **self.get_params()}

    def fit(self, data, **keywords) -> ModelSearch:
        """Run the search on ``data`` (what :func:`ftcal.fit` takes; ``keywords``: its other keywords)."""
        from .fitting import fit

        fit(data, self, **keywords)  # fit() calls _found() with what it found
        return self

    def _found(self, result) -> None:
        """Keep what :func:`ftcal.fit` found (called by it)."""
        selection = result.selection
        self.result_, self.selection_, self.best_estimator_ = result, selection, result.model
        scores = selection.scores
        self.metric_ = selection.metric
        self.cv_results_ = {"degree": [s.candidate.degree for s in scores],
                            "penalty": [s.candidate.penalty for s in scores],
                            "lambda": [s.candidate.lam for s in scores],
                            "mean_test_score": [s.score for s in scores],
                            "mean_train_score": [s.train_score for s in scores],
                            "mean_nonzero": [s.nonzero for s in scores],
                            "split_test_scores": [s.fold_scores for s in scores]}
        best = selection.best
        self.best_params_ = {"degree": best.degree, "penalty": best.penalty, "lambda": best.lam}

    def to_frame(self):
        """:attr:`cv_results_` as a :class:`pandas.DataFrame`, one row per candidate (fold scores in lists)."""
        import pandas as pd

        self._check_fitted()
        return pd.DataFrame(self.cv_results_)

    def _check_fitted(self) -> None:
        if not hasattr(self, "best_estimator_"):
            raise NotFittedError("This ModelSearch is not fitted yet: call fit(data) first.")

    def predict(self, u, **keywords):
        """The best model's prediction (:meth:`CalibrationModel.predict`)."""
        self._check_fitted()
        return self.best_estimator_.predict(u, **keywords)

    def __repr__(self) -> str:
        given = {k: v for k, v in self.get_params().items() if v != ModelSearch().get_params()[k]}
        return f"ModelSearch({', '.join(f'{k}={v!r}' for k, v in given.items())})"


@dataclass(repr=False)
class CandidatesResult(StepResult):
    """What :func:`fit_candidates` fitted: one model per candidate, each on all of the data.

    Attributes
    ----------
    models : dict of Candidate (or the estimator template given) to fitted model
        In the order the candidates were given.
    n_samples : int
        Rows the models were fitted on.
    """

    models: dict
    n_samples: int
    _save: dict = field(default_factory=dict)  # what each model file records: the sources, their fingerprints

    def save(self, candidate, path: str | os.PathLike) -> Path:
        """Write ``candidate``'s model file (JSON, atomically) with the data's sources and training
        fingerprints, as :meth:`FitResult.save <ftcal.workflow.fitting.FitResult.save>` does."""
        from ..files.model_files import save_model

        return save_model(self.models[candidate], path, **self._save)

    def summary(self) -> str:
        from ..core.metrics import format_metric

        lines = [f"{len(self.models)} candidate(s) fitted on {self.n_samples} samples from one statistics pass "
                 "per degree"]
        for candidate, model in self.models.items():
            force = (model.training_metrics_ or {}).get("force_norm_rmse")
            lines.append(f"  {_label(candidate, model):<24} {model.describe()['n_coefficients']} coefficients"
                         + (f", training {format_metric('force_norm_rmse', force, 4)}" if force is not None else ""))
        return "\n".join(lines)

    def to_dict(self) -> dict:
        return {"n_samples": self.n_samples,
                "models": [{"label": _label(c, m), "family": m.family, "degree": getattr(c, "degree", None),
                            "penalty": getattr(c, "penalty", None), "lambda": getattr(c, "lam", None),
                            "n_coefficients": m.describe()["n_coefficients"]} for c, m in self.models.items()]}


def _label(candidate, model) -> str:
    """A polynomial candidate's label (``np4 lasso λ=50``), or the fitted estimator's own (``mlp 16 tanh``)."""
    from ..core.select import Candidate

    return candidate.label if isinstance(candidate, Candidate) else model.label()


def fit_candidates(data, candidates: Sequence, *, advance=None) -> CandidatesResult:
    """Fit several candidates on all of ``data``: the polynomials from one statistics pass per degree.

    The demos' step: where :func:`ftcal.fit` with each explicit degree would also run that degree's
    grouped comparison with affine (a second pass and a warning per candidate), this fits the given
    candidates only, the LASSO ones of a degree as one warm-started λ path
    (:func:`ftcal.core.select.fit_candidates`). A candidate that is an estimator (an
    :class:`~ftcal.core.mlp.MLPModel`, say) is a template: a clone of it is fitted as it stands, with its own
    ``fit(dataset)``, unlike :func:`ftcal.fit`, which sizes a network's training itself and may write the affine
    model instead.
    Scoring them is the caller's: held-out recordings, or :class:`ModelSearch` for grouped cross-validation.

    Parameters
    ----------
    data : Dataset, or what :func:`ftcal.fit` reads (paths, DataFrames), with reference outputs
    candidates : sequence of :class:`~ftcal.core.select.Candidate` (degree, penalty, λ) or estimators
        An estimator has ``clone()`` and ``fit(dataset) -> self``; its clone is fitted after the polynomials.
    advance : callable, optional
        Called with 1 after each candidate (a progress bar).

    Returns
    -------
    CandidatesResult

    Examples
    --------
    >>> import numpy as np
    >>> from ftcal import Dataset
    >>> from ftcal.core.mlp import MLPModel
    >>> from ftcal.core.select import Candidate
    >>> u = np.random.default_rng(0).normal(size=(200, 2))
    >>> data = Dataset.from_arrays(u, u @ [[1.0, 0.5], [0.0, 2.0]] + 0.1 * u ** 2)
    >>> network = MLPModel((4,), early_stopping=False, max_iter=20)
    >>> result = fit_candidates(data, [Candidate(1, "none", None), Candidate(2, "none", None), network])
    >>> [model.describe()["n_coefficients"] for model in result.models.values()]
    [6, 12, 22]
    >>> result.models[network] is not network  # the template stays unfitted
    True
    """
    from ..core.fingerprint import segment_fingerprints
    from ..core.select import Candidate, fit_candidates as fit_all
    from ..data.tables import load_dataset
    from .sources import tables_of

    polynomials = [c for c in candidates if isinstance(c, Candidate)]
    with tables_of(data) as (paths, dataset, names):
        dataset = dataset if dataset is not None else load_dataset(paths)
        models = fit_all(dataset, polynomials, advance=advance) if polynomials else {}
        for estimator in candidates:
            if not isinstance(estimator, Candidate):
                models[estimator] = estimator.clone().fit(dataset)
                if advance is not None:
                    advance(1)
        save = dict(sources=list(names) if paths else list(dataset.sources),
                    training_segments=segment_fingerprints(dataset))
    return CandidatesResult({c: models[c] for c in candidates}, dataset.n_samples, save)
