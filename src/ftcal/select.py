"""Grouped cross-validation over degree and λ.

Folds are made of whole groups (load cases or recordings), never of random
samples: consecutive samples of one recording are near-duplicates, so a random
split would validate on data the model has effectively seen.

Statistics are accumulated once per group at the highest degree; a lower
degree's statistics are a sub-block of them and a fold's training statistics
are a sum over its groups, so the whole grid costs one pass over the data
plus the validation predictions.
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from . import metrics
from ._checks import check_int
from .dataset import Dataset
from .errors import FtcalError, IllPosedFitWarning
from .limits import PAPER_LAMBDAS
from .model import CalibrationModel, FitFrame
from .progress import progress_bar
from .solvers.base import ScaledProblem, Solver
from .solvers.lasso import Lasso
from .solvers.least_squares import LeastSquares, Ridge
from .statistics import SufficientStatistics, sum_statistics

__all__ = ["Candidate", "CrossValidationResult", "PAPER_LAMBDAS", "cross_validate", "default_candidates",
           "fit_best", "fit_candidates", "grouped_folds"]

TIE_TOLERANCE = 0.01  # candidates within 1% of the best score count as tied


@dataclass(frozen=True)
class Candidate:
    """One point of the selection grid.

    Parameters
    ----------
    degree : int
        Polynomial degree.
    penalty : {"none", "ridge", "lasso"}
        One of :data:`ftcal.limits.PENALTIES`.
    lam : float or None
        The penalty weight λ (None for least squares).

    Examples
    --------
    >>> Candidate(3, "lasso", 50.0).label
    'np3 lasso λ=50'
    """

    degree: int
    penalty: str
    lam: float | None

    @property
    def label(self) -> str:
        return f"np{self.degree}" if self.penalty == "none" else f"np{self.degree} {self.penalty} λ={self.lam:g}"

    def solver(self) -> Solver:
        """A solver for this candidate's penalty and λ."""
        if self.penalty == "lasso":
            return Lasso(self.lam)
        if self.penalty == "ridge":
            return Ridge(self.lam)
        return LeastSquares()


@dataclass
class CandidateScore:
    candidate: Candidate
    fold_scores: list[float] = field(default_factory=list)
    fold_train_scores: list[float] = field(default_factory=list)
    n_nonzero: list[int] = field(default_factory=list)

    @property
    def score(self) -> float:
        return float(np.mean(self.fold_scores))

    @property
    def train_score(self) -> float:
        return float(np.mean(self.fold_train_scores))

    @property
    def nonzero(self) -> float:
        return float(np.mean(self.n_nonzero))

    def as_dict(self) -> dict:
        return {"degree": self.candidate.degree, "penalty": self.candidate.penalty,
                "lambda": self.candidate.lam, "validation_score": self.score,
                "train_score": self.train_score, "fold_scores": self.fold_scores,
                "n_nonzero": self.nonzero}


@dataclass
class CrossValidationResult:
    scores: list[CandidateScore]
    best: Candidate
    metric: str
    n_folds: int

    def table(self) -> str:
        """The validation curve as aligned text, best marked with '*'."""
        lines = [f"{'model':<24} {'train':>10} {'validation':>11} {'nonzero':>9}   ({self.metric}, {self.n_folds} folds)"]
        for s in self.scores:
            mark = "*" if s.candidate == self.best else " "
            lines.append(f"{mark}{s.candidate.label:<23} {s.train_score:>10.4f} {s.score:>11.4f} {s.nonzero:>9.0f}")
        return "\n".join(lines)


def grouped_folds(groups: np.ndarray, n_folds: int = 5, seed: int = 0) -> list[np.ndarray]:
    """Validation masks: each fold is a set of whole groups, folds balanced by sample count.

    Parameters
    ----------
    groups : ndarray of shape (n_samples,)
        Group label per sample (load case or recording).
    n_folds : int >= 2
        At most the number of groups.
    seed : int
        Order among groups of equal size.

    Returns
    -------
    list of ndarray of bool, shape (n_samples,)
        One validation mask per fold; every sample is in exactly one.

    Examples
    --------
    >>> folds = grouped_folds(np.array(["a", "a", "b", "c"]), n_folds=2)
    >>> sorted(int(m.sum()) for m in folds)
    [2, 2]
    """
    labels, counts = np.unique(np.asarray(groups, dtype=str), return_counts=True)
    if labels.size < 2:
        raise FtcalError("Cross-validation needs at least 2 groups (recordings or load cases); "
                         "the data has 1. Pass more files or name a group column with --group-by.")
    n_folds = check_int(n_folds, "n_folds", "cross_validate", 2)
    n_folds = min(n_folds, labels.size)
    order = np.random.default_rng(seed).permutation(labels.size)
    # Largest groups first, each to the currently lightest fold.
    order = order[np.argsort(-counts[order], kind="stable")]
    load = np.zeros(n_folds)
    fold_of = np.empty(labels.size, dtype=np.int64)
    for g in order:
        f = int(np.argmin(load))
        fold_of[g] = f
        load[f] += counts[g]
    group_fold = dict(zip(labels, fold_of))
    sample_fold = np.array([group_fold[g] for g in np.asarray(groups, dtype=str)])
    return [sample_fold == f for f in range(n_folds)]


def default_candidates(degrees: Sequence[int] = (1, 2, 3, 4, 5), lams: Sequence[float] = PAPER_LAMBDAS,
                       penalty: str | None = "lasso") -> list[Candidate]:
    """Least squares at every degree, plus ``penalty`` at every (degree, λ) when given.

    Parameters
    ----------
    degrees : sequence of int
    lams : sequence of float
    penalty : {"ridge", "lasso"} or None

    Returns
    -------
    list of Candidate

    Examples
    --------
    >>> [c.label for c in default_candidates((1, 2), lams=(10.0,))]
    ['np1', 'np2', 'np1 lasso λ=10', 'np2 lasso λ=10']
    """
    out = [Candidate(d, "none", None) for d in degrees]
    if penalty is not None:
        out += [Candidate(d, penalty, float(lam)) for d in degrees for lam in lams]
    return out


def _score(y: np.ndarray, prediction: np.ndarray, output_names: Sequence[str]) -> tuple[float, str]:
    forces, _ = metrics.force_torque_columns(output_names)
    if forces is not None:
        return metrics.norm_rmse(y[:, forces], prediction[:, forces]), "force-norm RMSE"
    return float(np.mean(metrics.rmse(y, prediction))), "mean RMSE"


def cross_validate(data: Dataset, candidates: Sequence[Candidate], *, template: CalibrationModel | None = None,
                   n_folds: int = 5, seed: int = 0) -> CrossValidationResult:
    """Score every candidate by grouped K-fold validation; pick the best.

    Parameters
    ----------
    data : Dataset
        With reference outputs and at least two groups.
    candidates : sequence of Candidate
        Degrees and penalties to try.
    template : CalibrationModel, optional
        Unfitted model whose other parameters (ARX orders, basis, prior) every
        candidate shares; each candidate is ``template.clone(degree=..., solver=...)``.
    n_folds : int
    seed : int
        Fold assignment seed (see :func:`grouped_folds`).

    Returns
    -------
    CrossValidationResult

    Notes
    -----
    The score is the validation force-norm RMSE (mean RMSE over outputs when
    the outputs are not a wrench); ties within 1% go to fewer nonzero
    coefficients. Input normalization uses the ranges of all the data.
    """
    if data.outputs is None:
        raise FtcalError("Cross-validation needs reference outputs in the data.")
    if not candidates:
        raise FtcalError("No candidate models to cross-validate.")
    template = template if template is not None else CalibrationModel()
    folds = grouped_folds(data.groups, n_folds, seed)
    plan = _Plan(data, template, candidates)
    fold_stats = [plan.statistics(data.subset(mask)) for mask in folds]
    scores = {c: CandidateScore(c) for c in candidates}
    metric = ""
    with progress_bar("cross-validating", len(folds) * len(plan.groups)) as advance:
        for f, val_mask in enumerate(folds):
            train = {key: sum_statistics([fold_stats[g][key] for g in range(len(folds)) if g != f])
                     for key in fold_stats[0]}
            val, fit_part = data.subset(val_mask), data.subset(~val_mask)
            for key, group in plan.groups.items():
                for candidate, model in plan.solve(key, group, train):
                    val_score, metric = _score(val.outputs, model.predict(val, warn_out_of_range=False),
                                               data.output_names)
                    train_score, _ = _score(fit_part.outputs, model.predict(fit_part, warn_out_of_range=False),
                                            data.output_names)
                    entry = scores[candidate]
                    entry.fold_scores.append(val_score)
                    entry.fold_train_scores.append(train_score)
                    entry.n_nonzero.append(int(np.count_nonzero(model.coef_)))
                advance(1)
    ordered = [scores[c] for c in candidates]
    best_value = min(s.score for s in ordered)
    tied = [s for s in ordered if s.score <= best_value * (1 + TIE_TOLERANCE)]
    best = min(tied, key=lambda s: (s.nonzero, s.score)).candidate
    return CrossValidationResult(ordered, best, metric, len(folds))


class _Plan:
    """Candidates grouped by (degree, solve basis): one set of statistics per basis, at the top degree.

    A lower degree's statistics are a sub-block of the top degree's; LASSO
    candidates of one group run as one warm-started λ path.
    """

    def __init__(self, data: Dataset, template: CalibrationModel, candidates: Sequence[Candidate]):
        self.models = {c: template.clone(degree=c.degree, solver=c.solver()) for c in candidates}
        with warnings.catch_warnings():
            # Ill-posedness is judged per fold by the validation score.
            warnings.simplefilter("ignore", IllPosedFitWarning)
            self.frames: dict[Candidate, FitFrame] = {c: m.frame(data) for c, m in self.models.items()}
        self.groups: dict[tuple[int, str], list[Candidate]] = {}
        for c in candidates:
            self.groups.setdefault((c.degree, self._basis_key(c)), []).append(c)
        top = {}
        for c in candidates:
            key = self._basis_key(c)
            if key not in top or c.degree > top[key].degree:
                top[key] = c
        self.top = {key: self.frames[c] for key, c in top.items()}

    def _basis_key(self, c: Candidate) -> str:
        frame = self.frames[c]
        return frame.normalization if frame.solves_in_stored_basis else "solve:" + frame.normalization

    def statistics(self, part: Dataset) -> dict[str, SufficientStatistics]:
        """Statistics of ``part`` at the top degree of each solve basis."""
        return {key: CalibrationModel.statistics(part, frame.layout, frame.solve_input_normalization,
                                                 frame.solve_output_normalization)
                for key, frame in self.top.items()}

    def solve(self, key: tuple[int, str], group: list[Candidate], stats: dict[str, SufficientStatistics]):
        """Yield (candidate, fitted model) for one group from the summed ``stats``."""
        degree, basis = key
        top = self.top[basis]
        frame = self.frames[group[0]]
        columns = _columns_in(frame, top)
        problem = ScaledProblem.from_statistics(stats[basis].restrict(columns))
        for candidate, result in _solve_group(problem, group):
            model = self.models[candidate].clone()
            yield candidate, model.adopt(self.frames[candidate], problem, result)


def _columns_in(frame: FitFrame, top: FitFrame) -> np.ndarray:
    """Columns of ``top``'s regressor that make ``frame``'s (a lower degree, same lags)."""
    return frame.layout.index_in(top.layout)


def _solve_group(problem: ScaledProblem, candidates: list[Candidate]):
    """Yield (candidate, SolverResult), running each LASSO λ path warm-started."""
    with warnings.catch_warnings():
        # Fold fits of high degrees on few groups are often ill-posed; the
        # validation score already says how much that matters.
        warnings.simplefilter("ignore", IllPosedFitWarning)
        lasso = [c for c in candidates if c.penalty == "lasso"]
        if lasso:
            results = Lasso(lasso[0].lam).fit_path(problem, [c.lam for c in lasso])
            yield from zip(lasso, results)
        for c in candidates:
            if c.penalty != "lasso":
                yield c, c.solver().fit(problem)


def fit_best(data: Dataset, result: CrossValidationResult, *,
             template: CalibrationModel | None = None) -> CalibrationModel:
    """Refit the winning candidate of ``result`` on all of ``data``.

    Parameters
    ----------
    data : Dataset
    result : CrossValidationResult
    template : CalibrationModel, optional
        The template ``result`` was computed with.

    Returns
    -------
    CalibrationModel
    """
    template = template if template is not None else CalibrationModel()
    return template.clone(degree=result.best.degree, solver=result.best.solver()).fit(data)


def fit_candidates(data: Dataset, candidates: Sequence[Candidate], *, template: CalibrationModel | None = None,
                   advance=None) -> dict[Candidate, CalibrationModel]:
    """Fit every candidate on all of ``data`` from one pass of statistics per basis.

    Equivalent to fitting each candidate separately (``template.clone(...).fit(data)``).

    Parameters
    ----------
    data : Dataset
    candidates : sequence of Candidate
    template : CalibrationModel, optional
    advance : callable, optional
        Called with 1 after each candidate (progress).

    Returns
    -------
    dict of Candidate to fitted CalibrationModel
    """
    if data.outputs is None:
        raise FtcalError("Fitting needs reference outputs in the data.")
    plan = _Plan(data, template if template is not None else CalibrationModel(), candidates)
    stats = plan.statistics(data)
    models = {}
    for key, group in sorted(plan.groups.items()):
        for candidate, model in plan.solve(key, group, stats):
            model.training_metrics_ = model.score(data, warn_out_of_range=False)
            models[candidate] = model
            if advance is not None:
                advance(1)
    return models
