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
from .features import MonomialBasis, RegressorLayout
from .model import CalibrationModel, model_from_fitted
from .normalization import normalization_from_range
from .progress import progress_bar
from .solvers.base import ScaledProblem
from .solvers.lasso import Lasso
from .solvers.least_squares import LeastSquares, Ridge
from .statistics import layout_statistics, sum_statistics

__all__ = ["Candidate", "CrossValidationResult", "PAPER_LAMBDAS", "cross_validate", "default_candidates",
           "fit_best", "fit_candidates", "grouped_folds"]

PAPER_LAMBDAS = (0.5, 1.0, 10.0, 50.0, 100.0, 200.0)
TIE_TOLERANCE = 0.01  # candidates within 1% of the best score count as tied


@dataclass(frozen=True)
class Candidate:
    degree: int
    penalty: str  # "none", "ridge" or "lasso"
    lam: float | None

    @property
    def label(self) -> str:
        return f"np{self.degree}" if self.penalty == "none" else f"np{self.degree} {self.penalty} λ={self.lam:g}"

    def solver(self):
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
    """Validation masks: each fold is a set of whole groups, folds balanced by sample count."""
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
    """Least squares at every degree, plus ``penalty`` at every (degree, λ) when given."""
    out = [Candidate(d, "none", None) for d in degrees]
    if penalty is not None:
        out += [Candidate(d, penalty, float(lam)) for d in degrees for lam in lams]
    return out


def _score(y: np.ndarray, prediction: np.ndarray, output_names: Sequence[str]) -> tuple[float, str]:
    forces, _ = metrics.force_torque_columns(output_names)
    if forces is not None:
        return metrics.norm_rmse(y[:, forces], prediction[:, forces]), "force-norm RMSE"
    return float(np.mean(metrics.rmse(y, prediction))), "mean RMSE"


def cross_validate(data: Dataset, candidates: Sequence[Candidate], *, n_folds: int = 5,
                   normalization: str = "center", na: int = 0, nb: int = 0,
                   seed: int = 0) -> CrossValidationResult:
    """Score every candidate by grouped K-fold validation; pick the best.

    The score is the validation force-norm RMSE (mean RMSE over outputs when
    the outputs are not a wrench); ties within 1% go to fewer nonzero
    coefficients. Input normalization uses the ranges of all the data.
    """
    if data.outputs is None:
        raise FtcalError("Cross-validation needs reference outputs in the data.")
    if not candidates:
        raise FtcalError("No candidate models to cross-validate.")
    folds = grouped_folds(data.groups, n_folds, seed)
    u, y = data.inputs, data.outputs
    in_norm = normalization_from_range(u.min(axis=0), u.max(axis=0), normalization)
    out_norm = normalization_from_range(y.min(axis=0), y.max(axis=0), "center")
    top = max(c.degree for c in candidates)
    top_layout = RegressorLayout(MonomialBasis(u.shape[1], top), y.shape[1], na, nb)
    by_degree = {d: RegressorLayout(MonomialBasis(u.shape[1], d), y.shape[1], na, nb)
                 for d in sorted({c.degree for c in candidates})}

    fold_stats = _fold_statistics(data, folds, top_layout, by_degree, in_norm, out_norm)
    scores = {c: CandidateScore(c) for c in candidates}
    metric = ""
    with progress_bar("cross-validating", len(folds) * len(by_degree)) as advance:
        for f, val_mask in enumerate(folds):
            train = {d: sum_statistics([fold_stats[g][d] for g in range(len(folds)) if g != f])
                     for d in fold_stats[0]}
            val, fit_part = data.subset(val_mask), data.subset(~val_mask)
            for degree, layout in by_degree.items():
                stats = (train[degree] if degree in train
                         else train[top].restrict(layout.basis.index_in(top_layout.basis)))
                problem = ScaledProblem.from_statistics(stats)
                group = [c for c in candidates if c.degree == degree]
                for candidate, result in _solve_group(problem, group):
                    model = model_from_fitted(
                        degree=degree, na=na, nb=nb, normalization=normalization,
                        coef=result.coef / problem.column_scale[:, None],
                        input_normalization=in_norm, output_normalization=out_norm,
                        input_names=data.input_names, output_names=data.output_names,
                        input_range=np.c_[u.min(axis=0), u.max(axis=0)],
                        output_range=np.c_[y.min(axis=0), y.max(axis=0)])
                    val_score, metric = _score(val.outputs, model.predict(val, warn_out_of_range=False),
                                               data.output_names)
                    train_score, _ = _score(fit_part.outputs, model.predict(fit_part, warn_out_of_range=False),
                                            data.output_names)
                    entry = scores[candidate]
                    entry.fold_scores.append(val_score)
                    entry.fold_train_scores.append(train_score)
                    entry.n_nonzero.append(int(np.count_nonzero(result.coef)))
                advance(1)
    ordered = [scores[c] for c in candidates]
    best_value = min(s.score for s in ordered)
    tied = [s for s in ordered if s.score <= best_value * (1 + TIE_TOLERANCE)]
    best = min(tied, key=lambda s: (s.nonzero, s.score)).candidate
    return CrossValidationResult(ordered, best, metric, len(folds))


def _fold_statistics(data, folds, top_layout, by_degree, in_norm, out_norm) -> list[dict]:
    """Per fold: {degree: statistics} (static models keep only the top degree)."""
    static = top_layout.is_static
    layouts = {top_layout.basis.degree: top_layout} if static else by_degree
    u_norm = in_norm.apply(data.inputs)
    y_norm = out_norm.apply(data.outputs)
    out = []
    with progress_bar("accumulating statistics", data.n_samples * len(layouts)) as advance:
        for mask in folds:
            part = data.subset(mask)
            idx = np.flatnonzero(mask)
            per_degree = {}
            for degree, layout in layouts.items():
                pieces = [layout_statistics(layout, u_norm[idx[a:b]], data.outputs[idx[a:b]],
                                            y_norm[idx[a:b]], advance=advance)
                          for a, b in part.segment_bounds()]
                per_degree[degree] = sum_statistics(pieces)
            out.append(per_degree)
    return out


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


def fit_best(data: Dataset, result: CrossValidationResult, *, normalization: str = "center",
             na: int = 0, nb: int = 0) -> CalibrationModel:
    """Refit the winning candidate on all the data."""
    best = result.best
    return CalibrationModel(best.degree, solver=best.solver(), na=na, nb=nb,
                            normalization=normalization).fit(data)




def fit_candidates(data: Dataset, candidates: Sequence[Candidate], *, normalization: str = "center",
                   advance=None) -> dict[Candidate, CalibrationModel]:
    """Fit every static candidate on all of ``data`` from one pass of statistics.

    The statistics are accumulated once at the highest degree; each degree's
    problem is a sub-block, and LASSO candidates of one degree run as one
    warm-started λ path. Equivalent to fitting each candidate separately.
    """
    if data.outputs is None:
        raise FtcalError("Fitting needs reference outputs in the data.")
    u, y = data.inputs, data.outputs
    in_norm = normalization_from_range(u.min(axis=0), u.max(axis=0), normalization)
    out_norm = normalization_from_range(y.min(axis=0), y.max(axis=0), "center")
    top = RegressorLayout(MonomialBasis(u.shape[1], max(c.degree for c in candidates)), y.shape[1])
    stats = CalibrationModel.statistics(data, top, in_norm, out_norm)
    models = {}
    for degree in sorted({c.degree for c in candidates}):
        layout = RegressorLayout(MonomialBasis(u.shape[1], degree), y.shape[1])
        problem = ScaledProblem.from_statistics(stats.restrict(layout.basis.index_in(top.basis)))
        group = [c for c in candidates if c.degree == degree]
        for candidate, result in _solve_group(problem, group):
            model = model_from_fitted(
                degree=degree, na=0, nb=0, normalization=normalization,
                coef=result.coef / problem.column_scale[:, None],
                input_normalization=in_norm, output_normalization=out_norm,
                input_names=data.input_names, output_names=data.output_names,
                input_range=np.c_[u.min(axis=0), u.max(axis=0)], output_range=np.c_[y.min(axis=0), y.max(axis=0)],
                n_samples_fit=data.n_samples, rank=result.rank, condition_number=result.condition_number,
                solver_info={"name": candidate.solver().name, "lambda": candidate.lam,
                             **{k: v for k, v in result.info.items() if k != "lambda"}},
                solver=candidate.solver())
            model.training_metrics_ = model.score(data, warn_out_of_range=False)
            models[candidate] = model
            if advance is not None:
                advance(1)
    return models
