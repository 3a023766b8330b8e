"""Grouped cross-validation over degree, penalty and λ.

Folds are made of whole groups (load cases or recordings), never of random
samples: consecutive samples of one recording are near-duplicates, so a random
split would validate on data the model has effectively seen.

Everything is scored from sufficient statistics: each fold's statistics are
accumulated once per degree (the sum of its groups'), a training set's are the
sum of the other folds', and a candidate's validation error is exact algebra on
the held-out fold's statistics, ‖Aθ − y‖² = θᵀGθ − 2θᵀc + ‖y‖², so no
candidate is ever evaluated sample by sample. The score is therefore the RMSE of
the force error norm ‖f − f̂‖ (mean RMSE over outputs when the outputs are not a
wrench); for ARX models it is the one-step error on rows past the warm-up, the
paper's evaluation.

:func:`select_model` builds the grid from the data: for each degree, LASSO λ
from λ_max (the smallest λ that zeroes every non-offset coefficient) down three
decades and ridge λ over six decades below trace(G)/p, extended when the best λ
sits at an edge. Degrees are tried in increasing order and the search stops at
the first degree that is worse than a lower one.
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

from ..runtime.checks import check_int
from ..runtime.errors import FtcalError, FtcalWarning, IllPosedFitWarning
from ..runtime.progress import progress_bar
from ..runtime.threads import single_threaded_blas, worker_count
from . import metrics
from .dataset import Dataset
from .limits import PAPER_LAMBDAS
from .model import CalibrationModel, FitFrame
from .solvers.base import ScaledProblem, Solver
from .solvers.lasso import Lasso
from .solvers.least_squares import LeastSquares, Ridge
from .statistics import SufficientStatistics, sum_statistics

__all__ = ["Candidate", "CrossValidationResult", "DatasetStatistics", "GroupedStatistics", "PAPER_LAMBDAS",
           "best_model", "cross_validate", "default_candidates", "fit_best", "fit_candidates", "fold_of_groups",
           "grouped_folds", "select_model"]

TIE_TOLERANCE = 0.01  # candidates within 1% of the best score count as tied
DEFAULT_DEGREES = (1, 2, 3, 4, 5)
DEFAULT_PENALTIES = ("lasso", "ridge")
LASSO_POINTS, LASSO_DECADES = 10, 3.0
RIDGE_POINTS, RIDGE_DECADES = 13, 6.0
MAX_EXTENSIONS = 2  # times the grid grows past an edge where the best λ sits


@dataclass(frozen=True)
class Candidate:
    """One point of the selection grid.

    Parameters
    ----------
    degree : int
        Polynomial degree.
    penalty : {"none", "ridge", "lasso"}
        One of :data:`ftcal.core.limits.PENALTIES`.
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
    """A candidate's scores, one per fold (validation and training), and its nonzero counts."""

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


@dataclass(frozen=True)
class Comparison:
    """The winner against the affine model, fold by fold.

    Attributes
    ----------
    reference : Candidate
        Least squares at the lowest degree scored (affine), or the best candidate of that degree.
    margin : float
        Mean over folds of (reference score − winner score); positive when the winner is better.
    spread : float
        Standard deviation of that difference over folds.
    standard_error : float
        ``spread / sqrt(n_folds)``.
    """

    reference: Candidate
    margin: float
    spread: float
    standard_error: float

    @property
    def within_noise(self) -> bool:
        """The winner's advantage is under two standard errors of the fold-to-fold differences."""
        return self.margin < 2.0 * self.standard_error


@dataclass
class CrossValidationResult:
    """Scores of every candidate tried, the winner and how it compares with the affine model.

    Attributes
    ----------
    scores : list of CandidateScore, in the order tried
    best : Candidate
    metric : str
        What the scores measure (``"force error-norm RMSE"`` or ``"mean RMSE"``).
    n_folds : int
    skipped_degrees : tuple of int
        Degrees not tried because a lower degree already did better.
    """

    scores: list[CandidateScore]
    best: Candidate
    metric: str
    n_folds: int
    skipped_degrees: tuple[int, ...] = ()

    def score_of(self, candidate: Candidate) -> CandidateScore:
        return next(s for s in self.scores if s.candidate == candidate)

    def comparison(self) -> Comparison:
        """The winner's margin over the affine model with its fold-to-fold spread."""
        lowest = min(s.candidate.degree for s in self.scores)
        plain = [s for s in self.scores if s.candidate == Candidate(lowest, "none", None)]
        pool = plain or [s for s in self.scores if s.candidate.degree == lowest]
        reference = min(pool, key=lambda s: s.score)
        difference = np.asarray(reference.fold_scores) - np.asarray(self.score_of(self.best).fold_scores)
        spread = float(np.std(difference, ddof=1)) if difference.size > 1 else 0.0
        return Comparison(reference.candidate, float(difference.mean()), spread,
                          spread / np.sqrt(difference.size))

    def table(self) -> str:
        """The validation curve as aligned text, best marked with '*', then the verdict."""
        lines = [f"{'model':<24} {'train':>10} {'validation':>11} {'nonzero':>9}   ({self.metric}, {self.n_folds} folds)"]
        for s in self.scores:
            mark = "*" if s.candidate == self.best else " "
            lines.append(f"{mark}{s.candidate.label:<23} {s.train_score:>10.4f} {s.score:>11.4f} {s.nonzero:>9.0f}")
        if self.skipped_degrees:
            lines.append(f"degrees {', '.join(map(str, self.skipped_degrees))} not tried: a lower degree already "
                         "validated better")
        lines.append(self.verdict())
        return "\n".join(lines)

    def verdict(self) -> str:
        """One sentence: the winner, its margin over affine and the fold-to-fold spread."""
        best = self.score_of(self.best)
        c = self.comparison()
        if c.reference == self.best:
            return f"selected {self.best.label} ({self.metric} {best.score:.4g})"
        text = (f"selected {self.best.label}: {self.metric} {best.score:.4g}, "
                f"margin over {c.reference.label} {c.margin:+.3g} on average over {self.n_folds} folds "
                f"(fold-to-fold spread {c.spread:.3g}, standard error {c.standard_error:.3g})")
        if c.within_noise and self.best.degree > c.reference.degree:
            text += "; within the fold noise"
        return text


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
    group_fold = fold_of_groups(dict(zip(labels, counts)), n_folds, seed)
    sample_fold = np.array([group_fold[g] for g in np.asarray(groups, dtype=str)])
    return [sample_fold == f for f in range(max(group_fold.values()) + 1)]


def fold_of_groups(sizes: dict[str, int], n_folds: int = 5, seed: int = 0) -> dict[str, int]:
    """The fold of each group, from the groups' sample counts alone (see :func:`grouped_folds`).

    Parameters
    ----------
    sizes : dict of group label (str) -> number of samples
    n_folds, seed : int

    Returns
    -------
    dict of group label -> fold index in 0 .. min(n_folds, number of groups) - 1
    """
    labels = np.array(sorted(sizes), dtype=str)
    counts = np.array([sizes[g] for g in labels])
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
    return {str(g): int(f) for g, f in zip(labels, fold_of)}


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


def cross_validate(data: "Dataset | GroupedStatistics", candidates: Sequence[Candidate], *,
                   template: CalibrationModel | None = None,
                   n_folds: int = 5, seed: int = 0) -> CrossValidationResult:
    """Score every candidate by grouped K-fold validation; pick the best.

    Parameters
    ----------
    data : Dataset or GroupedStatistics (e.g. streamed files)
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
    Candidates whose mean score is within 1% or one (paired, fold-to-fold)
    standard error of the best count as tied; ties go to fewer nonzero
    coefficients. Input normalization uses the ranges of all the data.
    """
    if not candidates:
        raise FtcalError("No candidate models to cross-validate.")
    search = _Search(data, template, n_folds, seed)
    for degree in sorted({c.degree for c in candidates}):
        search.score([c for c in candidates if c.degree == degree])
    return search.result([search.scores[c] for c in candidates])


def select_model(data: "Dataset | GroupedStatistics", *, template: CalibrationModel | None = None,
                 degrees: Sequence[int] = DEFAULT_DEGREES, penalties: Sequence[str] = DEFAULT_PENALTIES,
                 lambdas: Sequence[float] | None = None, n_folds: int = 5, seed: int = 0,
                 stop_early: bool = True) -> CrossValidationResult:
    """Grouped cross-validation over degrees, penalties and a data-driven λ grid.

    Parameters
    ----------
    data : Dataset or GroupedStatistics (e.g. streamed files)
    template : CalibrationModel, optional
        Shared parameters (ARX orders, basis, prior), as in :func:`cross_validate`.
    degrees : sequence of int
        Tried in increasing order.
    penalties : sequence of {"lasso", "ridge"}
        Penalized candidates beside least squares at every degree.
    lambdas : sequence of float, optional
        A fixed λ grid for every degree and penalty (e.g. :data:`PAPER_LAMBDAS`);
        by default the grid comes from the data (see the module docstring).
    n_folds, seed : int
    stop_early : bool
        Stop at the first degree whose best score is worse than a lower degree's.

    Returns
    -------
    CrossValidationResult
        Emits a :class:`~ftcal.runtime.errors.FtcalWarning` when a winner of higher degree
        beats the affine model by less than two standard errors of the fold-to-fold
        differences.
    """
    penalties = tuple(penalties)
    for penalty in penalties:
        if penalty not in ("lasso", "ridge"):
            raise FtcalError(f"Unknown penalty {penalty!r}; choose from 'lasso', 'ridge'.")
    degrees = sorted({check_int(d, "degrees", "select_model", 1) for d in degrees})
    if not degrees:
        raise FtcalError("No degrees to select from.")
    search = _Search(data, template, n_folds, seed)
    best_so_far = np.inf
    skipped: tuple[int, ...] = ()
    for i, degree in enumerate(degrees):
        search.score([Candidate(degree, "none", None)])
        for penalty in penalties:
            grid = list(lambdas) if lambdas is not None else search.lambda_grid(degree, penalty)
            search.score([Candidate(degree, penalty, float(lam)) for lam in grid])
            if lambdas is None:
                search.extend_at_edges(degree, penalty)
        best_here = min(s.score for c, s in search.scores.items() if c.degree == degree)
        if stop_early and best_here > best_so_far and i + 1 < len(degrees):
            skipped = tuple(degrees[i + 1:])
            break
        best_so_far = min(best_so_far, best_here)
    result = search.result(list(search.scores.values()), skipped)
    comparison = result.comparison()
    if result.best.degree > comparison.reference.degree and comparison.within_noise:
        warnings.warn(
            f"The selected {result.best.label} beats {comparison.reference.label} by {comparison.margin:.3g} "
            f"({result.metric}) on average, less than twice the standard error of the fold-to-fold differences "
            f"({comparison.standard_error:.3g}): the choice is within the noise of {result.n_folds} folds. "
            "Consider the simpler model or record more load cases.", FtcalWarning, stacklevel=2)
    return result


class GroupedStatistics(Protocol):
    """What cross-validation needs of the data; :class:`DatasetStatistics` for a :class:`Dataset` in memory,
    :class:`ftcal.data.streaming.StreamedStatistics` for files streamed by per-file tasks."""

    output_names: tuple[str, ...]

    def group_sizes(self) -> dict[str, int]:
        """Samples per group label (as str)."""

    def frame(self, model: CalibrationModel) -> FitFrame:
        """``model``'s fit frame over all the data."""

    def fold_statistics(self, frame: FitFrame, fold_of: dict[str, int], n_folds: int) -> list[SufficientStatistics]:
        """Statistics of each fold (the sum of its groups'), for ``frame``'s layout in its solve basis."""


class DatasetStatistics:
    """:class:`GroupedStatistics` of a :class:`Dataset` in memory."""

    def __init__(self, data: Dataset):
        self.data = data
        self.output_names = tuple(data.output_names)

    def group_sizes(self) -> dict[str, int]:
        labels, counts = np.unique(np.asarray(self.data.groups, dtype=str), return_counts=True)
        return dict(zip(labels.tolist(), counts.tolist()))

    def frame(self, model: CalibrationModel) -> FitFrame:
        return model.frame(self.data)

    def fold_statistics(self, frame: FitFrame, fold_of: dict[str, int], n_folds: int) -> list[SufficientStatistics]:
        sample_fold = np.array([fold_of[g] for g in np.asarray(self.data.groups, dtype=str)])
        parts = []
        with progress_bar(f"statistics, degree {frame.layout.basis.degree}", n_folds) as advance:
            for f in range(n_folds):
                parts.append(CalibrationModel.statistics(
                    self.data.subset(sample_fold == f), frame.layout, frame.solve_input_normalization,
                    frame.solve_output_normalization))
                advance(1)
        return parts


class _Search:
    """Fold statistics per (degree, basis), computed once, and the scores of every candidate tried."""

    def __init__(self, data: "Dataset | GroupedStatistics", template: CalibrationModel | None, n_folds: int,
                 seed: int):
        if isinstance(data, Dataset):
            if data.outputs is None:
                raise FtcalError("Cross-validation needs reference outputs in the data.")
            data = DatasetStatistics(data)
        self.data = data
        self.template = template if template is not None else CalibrationModel()
        self.fold_of = fold_of_groups(data.group_sizes(), n_folds, seed)
        self.n_folds = max(self.fold_of.values()) + 1
        forces, _ = metrics.force_torque_columns(data.output_names)
        self.forces = forces
        self.metric = "force error-norm RMSE" if forces is not None else "mean RMSE"
        self.scores: dict[Candidate, CandidateScore] = {}
        self._stats: dict[tuple[int, str], list[SufficientStatistics]] = {}
        self._frames: dict[tuple[int, str], FitFrame] = {}
        self._train: dict[tuple[tuple[int, str], int], tuple[SufficientStatistics, ScaledProblem]] = {}
        self._eigen: dict[tuple[tuple[int, str], int], tuple[np.ndarray, np.ndarray]] = {}

    # ------------------------------------------------------------ statistics
    def _model(self, candidate: Candidate) -> CalibrationModel:
        return self.template.clone(degree=candidate.degree, solver=candidate.solver())

    def _key(self, candidate: Candidate) -> tuple[tuple[int, str], CalibrationModel, FitFrame]:
        model = self._model(candidate)
        with warnings.catch_warnings():
            # Ill-posedness is judged by the validation score.
            warnings.simplefilter("ignore", IllPosedFitWarning)
            frame = self.data.frame(model)
        basis = frame.normalization if frame.solves_in_stored_basis else f"solve-{frame.normalization}"
        key = (candidate.degree, basis)
        self._frames.setdefault(key, frame)
        return key, model, frame

    def fold_statistics(self, key: tuple[int, str]) -> list[SufficientStatistics]:
        """Statistics of each validation fold (its groups' together), in the basis the key solves in."""
        if key not in self._stats:
            self._stats[key] = self.data.fold_statistics(self._frames[key], self.fold_of, self.n_folds)
        return self._stats[key]

    # -------------------------------------------------------------- λ grids
    def lambda_grid(self, degree: int, penalty: str) -> list[float]:
        """The default grid of ``penalty`` at ``degree`` from the statistics of all the data."""
        key, _, _ = self._key(Candidate(degree, penalty, 1.0))
        problem = ScaledProblem.from_statistics(sum_statistics(self.fold_statistics(key)))
        if penalty == "lasso":
            top = lasso_lambda_max(problem)
            return (top * np.logspace(0.0, -LASSO_DECADES, LASSO_POINTS + 1)[1:]).tolist()
        # The mean eigenvalue of G: above it the penalty dominates most directions.
        top = float(np.trace(problem.gram)) / problem.n_features
        return (top * np.logspace(0.0, -RIDGE_DECADES, RIDGE_POINTS)).tolist()

    def extend_at_edges(self, degree: int, penalty: str) -> None:
        """Grow the grid by a decade past an edge where the best λ sits (LASSO: the small edge only)."""
        step = LASSO_DECADES / LASSO_POINTS if penalty == "lasso" else RIDGE_DECADES / (RIDGE_POINTS - 1)
        for _ in range(MAX_EXTENSIONS):
            tried = sorted(c.lam for c in self.scores if c.degree == degree and c.penalty == penalty)
            best = min((s for c, s in self.scores.items() if c.degree == degree and c.penalty == penalty),
                       key=lambda s: s.score).candidate.lam
            factors = 10.0 ** (-step * np.arange(1, int(round(1.0 / step)) + 1))
            plain = self.scores.get(Candidate(degree, "none", None))
            if best == tried[0] and plain is not None and plain.score <= self.scores[
                    Candidate(degree, penalty, best)].score:
                # Smaller λ only moves toward least squares, which already scores better.
                return
            if best == tried[0]:
                new = tried[0] * factors
            elif best == tried[-1] and penalty == "ridge":
                new = tried[-1] / factors
            else:
                return
            self.score([Candidate(degree, penalty, float(lam)) for lam in new])

    # --------------------------------------------------------------- scores
    def score(self, candidates: Sequence[Candidate]) -> None:
        """Score ``candidates`` (one degree) on every fold, from the fold statistics."""
        by_key: dict[tuple[int, str], list[tuple[Candidate, CalibrationModel, FitFrame]]] = {}
        for c in candidates:
            if c in self.scores:
                continue
            key, model, frame = self._key(c)
            by_key.setdefault(key, []).append((c, model, frame))
        for key, group in by_key.items():
            parts = self.fold_statistics(key)
            with warnings.catch_warnings(), single_threaded_blas():
                # Fold fits of high degrees on few groups are often ill-posed; the score says how much that matters.
                warnings.simplefilter("ignore", IllPosedFitWarning)
                # Folds run in parallel threads (numpy releases the GIL in its kernels).
                with ThreadPoolExecutor(min(worker_count(), self.n_folds)) as pool:
                    rows = list(pool.map(lambda f: self._fold(key, group, parts, f), range(self.n_folds)))
            for fold_rows in rows:
                for candidate, val_score, train_score, nonzero in fold_rows:
                    entry = self.scores.setdefault(candidate, CandidateScore(candidate))
                    entry.fold_scores.append(val_score)
                    entry.fold_train_scores.append(train_score)
                    entry.n_nonzero.append(nonzero)

    def _fold(self, key, group, parts: list[SufficientStatistics], f: int) -> list[tuple]:
        """(candidate, validation score, training score, nonzero count) of ``group`` on fold ``f``."""
        if (key, f) not in self._train:
            train = sum_statistics([parts[g] for g in range(len(parts)) if g != f])
            self._train[(key, f)] = (train, ScaledProblem.from_statistics(train))
        train, problem = self._train[(key, f)]
        rows = []
        for (candidate, _, _), result, prior in self._solve(problem, group, (key, f)):
            coef = (result.coef + (0.0 if prior is None else prior)) / problem.column_scale[:, None]
            rows.append((candidate, self._error(parts[f], coef), self._error(train, coef),
                         int(np.count_nonzero(coef))))
        return rows

    def _solve(self, problem: ScaledProblem, group, fold_key):
        """Yield ((candidate, model, frame), SolverResult, prior) for one fold; paths share one eigen-decomposition.

        The LASSO path is warm-started from λ to λ within the fold. (Starting a fold from another
        fold's solutions was measured slower: ADMM's step size and dual do not transfer.)
        """
        plain = [g for g in group if g[0].penalty == "none"]
        for item in plain:
            yield item, item[1]._solver().fit(problem), None
        penalized = [g for g in group if g[0].penalty != "none"]
        if not penalized:
            return
        prior = penalized[0][1]._prior_coef(penalized[0][2], problem)
        shifted = problem if prior is None else problem.shifted(prior)
        # The shift changes c, not G: one eigen-decomposition per fold serves every λ, both penalties.
        if fold_key not in self._eigen:
            self._eigen[fold_key] = np.linalg.eigh(problem.gram)
        eigen = self._eigen[fold_key]
        lasso = [g for g in penalized if g[0].penalty == "lasso"]
        if lasso:
            results = Lasso(lasso[0][0].lam).fit_path(shifted, [g[0].lam for g in lasso], eigen=eigen)
            for item, result in zip(lasso, results):
                yield item, result, prior
        ridge = [g for g in penalized if g[0].penalty == "ridge"]
        if ridge:
            results = Ridge(ridge[0][0].lam).fit_path(shifted, [g[0].lam for g in ridge], eigen=eigen)
            for item, result in zip(ridge, results):
                yield item, result, prior

    def _error(self, stats: SufficientStatistics, coef: np.ndarray) -> float:
        """The score of coefficients ``coef`` (unscaled columns) on the rows ``stats`` summarize."""
        # ‖Aθ − y‖² per output, exactly, from AᵀA, Aᵀy and ‖y‖².
        sse = (np.einsum("ij,ij->j", coef, stats.gram @ coef) - 2.0 * np.einsum("ij,ij->j", coef, stats.cross)
               + stats.target_sq)
        mse = np.maximum(sse, 0.0) / max(stats.n_samples, 1)
        if self.forces is not None:
            return float(np.sqrt(mse[self.forces].sum()))
        return float(np.mean(np.sqrt(mse)))

    def result(self, ordered: list[CandidateScore], skipped: tuple[int, ...] = ()) -> CrossValidationResult:
        best = min(ordered, key=lambda s: s.score)
        folds = np.asarray(best.fold_scores)

        def tied(s: CandidateScore) -> bool:
            difference = np.asarray(s.fold_scores) - folds
            noise = np.std(difference, ddof=1) / np.sqrt(difference.size) if difference.size > 1 else 0.0
            return s.score <= best.score * (1 + TIE_TOLERANCE) or difference.mean() <= noise

        winner = min((s for s in ordered if tied(s)), key=lambda s: (s.nonzero, s.score)).candidate
        return CrossValidationResult(ordered, winner, self.metric, self.n_folds, skipped)


def lasso_lambda_max(problem: ScaledProblem) -> float:
    """The smallest λ at which every non-offset coefficient of the LASSO is zero (offset penalized too).

    With only the offset x₀ active, x₀ = (c₀ − λ·s)/G₀₀ (s = sign c₀), and column j
    stays at zero while |c_j − G_j0·x₀| <= λ; solving that for λ gives a bound
    per column and output, and λ_max is the largest.

    Parameters
    ----------
    problem : ScaledProblem
        The offset is its last column.

    Returns
    -------
    float

    Examples
    --------
    >>> import numpy as np
    >>> from ftcal.core.statistics import dense_statistics
    >>> a = np.c_[[1.0, -1.0, 1.0, -1.0], np.ones(4)]   # a zero-mean column and the offset
    >>> y = np.array([[3.0], [1.0], [3.0], [1.0]])      # y = 2 + 1·a
    >>> lasso_lambda_max(ScaledProblem.from_statistics(dense_statistics(a, y)))  # |Σ a·y| = 4
    4.0
    """
    g, c = problem.gram, problem.cross
    g00 = g[-1, -1]
    if g00 <= 0:
        return float(np.abs(c[:-1]).max())
    sign = np.sign(c[-1])                       # (n_outputs,)
    a = c[:-1] - np.outer(g[:-1, -1], c[-1]) / g00
    b = np.outer(g[:-1, -1], sign) / g00
    with np.errstate(divide="ignore", invalid="ignore"):
        bound = np.where(a > 0, a / (1.0 - b), -a / (1.0 + b))
    # Columns equal to ± the offset (b = ±1) never leave zero alone; skip them.
    bound = np.where(np.abs(b) < 1.0 - 1e-12, bound, 0.0)
    return float(max(np.nanmax(bound), np.finfo(float).tiny))


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
    return best_model(result, template).fit(data)


def best_model(result: CrossValidationResult, template: CalibrationModel | None = None) -> CalibrationModel:
    """The winning candidate of ``result`` as an unfitted model (``template``'s other parameters).

    Parameters
    ----------
    result : CrossValidationResult
    template : CalibrationModel, optional
        The template ``result`` was computed with.

    Returns
    -------
    CalibrationModel
    """
    template = template if template is not None else CalibrationModel()
    best = result.best
    # Least squares does not shrink, so a prior has nothing to act on.
    changes = {"prior": None} if best.penalty == "none" else {}
    return template.clone(degree=best.degree, solver=best.solver(), **changes)


def fit_candidates(data: Dataset, candidates: Sequence[Candidate], *, template: CalibrationModel | None = None,
                   advance=None) -> dict[Candidate, CalibrationModel]:
    """Fit every candidate on all of ``data`` from one pass of statistics per (degree, basis).

    Equivalent to fitting each candidate separately (``template.clone(...).fit(data)``);
    LASSO candidates of one degree run as one warm-started λ path.

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
    template = template if template is not None else CalibrationModel()
    groups: dict[tuple[int, str], list[tuple[Candidate, CalibrationModel, FitFrame]]] = {}
    fitted = {}
    for c in candidates:
        model = template.clone(degree=c.degree, solver=c.solver())
        if model.prior is not None:
            # Shrinking toward a prior changes the problem per candidate: fit it on its own.
            fitted[c] = (model if c.penalty != "none" else model.clone(prior=None)).fit(data)
            if advance is not None:
                advance(1)
            continue
        frame = model.frame(data)
        basis = frame.normalization if frame.solves_in_stored_basis else f"solve-{frame.normalization}"
        groups.setdefault((c.degree, basis), []).append((c, model, frame))
    for _, group in sorted(groups.items()):
        frame = group[0][2]
        stats = CalibrationModel.statistics(data, frame.layout, frame.solve_input_normalization,
                                            frame.solve_output_normalization)
        problem = ScaledProblem.from_statistics(stats)
        for (candidate, model, frame), result in _solve_group(problem, group):
            model.adopt(frame, problem, result)
            model.training_metrics_ = model.score(data, warn_out_of_range=False)
            fitted[candidate] = model
            if advance is not None:
                advance(1)
    return {c: fitted[c] for c in candidates}


def _solve_group(problem: ScaledProblem, group):
    """Yield ((candidate, model, frame), SolverResult), each LASSO λ path warm-started."""
    with warnings.catch_warnings():
        # Fits of high degrees on few groups are often ill-posed; validation says how much that matters.
        warnings.simplefilter("ignore", IllPosedFitWarning)
        lasso = [g for g in group if g[0].penalty == "lasso"]
        if lasso:
            yield from zip(lasso, Lasso(lasso[0][0].lam).fit_path(problem, [g[0].lam for g in lasso]))
        for g in group:
            if g not in lasso:
                yield g, g[1]._solver().fit(problem)
