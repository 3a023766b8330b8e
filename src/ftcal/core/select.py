"""Grouped cross-validation over degree, penalty and λ, per output, per block or for the whole model.

Folds are made of whole groups (load cases or recordings), never of random
samples: consecutive samples of one recording are near-duplicates, so a random
split would validate on data the model has effectively seen.

Everything is scored from sufficient statistics: each fold's statistics are
accumulated once per degree, a training set's are the sum of the other folds',
and a candidate's validation error is exact algebra on the held-out fold's
statistics, ‖Aθ − y‖² = θᵀGθ − 2θᵀc + ‖y‖², per output, so no candidate is
ever evaluated sample by sample. For ARX models it is the one-step error on rows
past the warm-up, the paper's evaluation.

Every candidate is solved for all outputs at once, but each output's
validation error is its own, so the search can choose per output
(``select_per="output"``), per force and torque block (``"block"``) or one
candidate for everything (``"model"``, ranked by ``objective``). A selection
that mixes candidates is one model at the largest selected degree: each output's
coefficients are mapped into the common basis (exact algebra) and embedded with
exact zeros for the terms its degree does not use (:func:`fit_selection`).
Force (N) and torque (N·m) are always reported side by side, each against
the affine model with the fold-to-fold standard error.

:func:`select_model` builds the grid from the data, in units that mean the
same whatever the number of samples: LASSO λ relative to λ_max (the smallest λ
that zeroes every coefficient, :func:`lasso_lambda_max`), from 1 down three
decades, and ridge λ relative to λ_ref = trace(AᵀA)/p (the mean eigenvalue of
the Gram matrix), from 1 down six decades; both scale with N, so 10⁻² λ_max
is the same penalty for 1 000 or 100 000 samples. Grids are extended when the
best λ sits at an edge. Degrees are tried in increasing order and the search
stops at the first degree that improves no output (or block) it selects for.
:func:`estimate_cost` predicts the work before it starts.
"""

from __future__ import annotations

import time
import warnings
from collections.abc import Callable, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

from ..runtime.checks import check_choice, check_int
from ..runtime.errors import FtcalError, FtcalWarning, IllPosedFitWarning
from ..runtime.progress import progress_bar
from ..runtime.threads import single_threaded_blas, worker_count
from . import metrics
from .dataset import Dataset
from .features import MonomialBasis, RegressorLayout
from .limits import OBJECTIVES, PAPER_LAMBDAS, POSE_BINS, SATURATION_RATIO, SELECT_PER
from .model import CalibrationModel, FitFrame, change_basis
from .solvers.base import ScaledProblem, Solver
from .solvers.lasso import Lasso
from .solvers.least_squares import LeastSquares, Ridge
from .statistics import SufficientStatistics, moment_plan, sum_statistics

__all__ = ["Candidate", "CostEstimate", "SearchBudget", "CrossValidationResult", "DatasetStatistics", "GroupedStatistics",
           "PAPER_LAMBDAS", "SaturationWarning", "SelectionLossWarning", "best_model", "cross_validate",
           "default_candidates", "estimate_cost", "fit_best", "fit_candidates", "fit_selection", "fold_of_groups",
           "grouped_folds", "pose_cells", "select_model", "warn_if_saturated"]

TIE_TOLERANCE = 0.01  # candidates within 1% of the best score count as tied
DEFAULT_DEGREES = (1, 2, 3, 4, 5)
DEFAULT_PENALTIES = ("lasso", "ridge")
LASSO_POINTS, LASSO_DECADES = 10, 3.0
RIDGE_POINTS, RIDGE_DECADES = 13, 6.0
MAX_EXTENSIONS = 2  # times the grid grows past an edge where the best λ sits
UNITS = {"force": "N", "torque": "N·m"}


class SelectionLossWarning(FtcalWarning):
    """The selected model validates worse than the affine model on a block, beyond the fold noise."""


class SaturationWarning(FtcalWarning):
    """A least-squares fit has nearly as many coefficients per output as distinct poses."""


def pose_cells(u: np.ndarray, input_range: np.ndarray, bins: int = POSE_BINS) -> set[bytes]:
    """The cells of a grid over the inputs' ranges (``bins`` per input) that samples ``u`` occupy.

    Their number counts distinct poses: a static load case (one pose and its noise) fills
    one cell, or a few at a cell border; a sweep fills one cell per 1/``bins`` of the range.

    Parameters
    ----------
    u : ndarray of shape (n_samples, n_inputs), raw inputs
    input_range : ndarray of shape (n_inputs, 2), min and max of each input over all the data
    bins : int

    Returns
    -------
    set, one entry per occupied cell (an int, or bytes when the grid has 2⁶³ cells or more;
    the sets of several chunks of the same inputs unite)

    Examples
    --------
    >>> u = np.array([[0.0, 0.0], [0.01, 0.0], [1.0, 1.0]])
    >>> len(pose_cells(u, np.array([[0.0, 1.0], [0.0, 1.0]])))
    2
    """
    low, span = input_range[:, 0], np.maximum(input_range[:, 1] - input_range[:, 0], np.finfo(float).tiny)
    cells = np.clip(np.floor((np.asarray(u) - low) / span * bins), 0, bins - 1).astype(np.int64)
    if float(bins) ** cells.shape[1] < 2.0**63:  # one integer per cell: far faster to make unique than bytes
        return set((cells @ (bins ** np.arange(cells.shape[1], dtype=np.int64))).tolist())
    rows = np.ascontiguousarray(cells.astype(np.uint8)).view(np.dtype((np.void, cells.shape[1])))
    return {bytes(r) for r in np.unique(rows.ravel())}


def warn_if_saturated(n_coefficients: int, n_poses: int, n_groups: int, what: str = "The fit") -> bool:
    """Warn (:class:`SaturationWarning`) when coefficients per output exceed
    :data:`~ftcal.core.limits.SATURATION_RATIO` times the distinct poses; True when it warned.

    Samples do not count: many samples of one pose determine one point of the map.
    """
    if n_coefficients <= SATURATION_RATIO * n_poses:
        return False
    warnings.warn(
        f"{what} is near saturation: {n_coefficients} coefficients per output for {n_poses} distinct poses "
        f"({n_groups} groups); it can fit the poses' noise and validate worse than affine. Lower the degree, "
        "use --ridge/--lasso (or --degree auto), or record more poses.", SaturationWarning, stacklevel=2)
    return True


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
        The penalty weight λ (None for least squares), absolute: the solver's λ.
    reference : float or None
        The λ its grid is relative to (λ_max for LASSO, trace(AᵀA)/p for ridge, on all
        the data), when the grid came from the data; not part of the candidate's identity.

    Examples
    --------
    >>> Candidate(3, "lasso", 50.0).label
    'np3 lasso λ=50'
    >>> Candidate(3, "lasso", 50.0, reference=5000.0).label
    'np3 lasso λ=0.01·λmax'
    """

    degree: int
    penalty: str
    lam: float | None
    reference: float | None = field(default=None, compare=False)

    @property
    def relative_lam(self) -> float | None:
        """λ over its grid's reference (λ_max or λ_ref), or None."""
        return None if self.lam is None or self.reference is None else self.lam / self.reference

    @property
    def label(self) -> str:
        if self.penalty == "none":
            return f"np{self.degree}"
        if self.reference is not None:
            unit = "λmax" if self.penalty == "lasso" else "λref"
            return f"np{self.degree} {self.penalty} λ={self.relative_lam:.3g}·{unit}"
        return f"np{self.degree} {self.penalty} λ={self.lam:g}"

    def solver(self) -> Solver:
        """A solver for this candidate's penalty and λ."""
        if self.penalty == "lasso":
            return Lasso(self.lam)
        if self.penalty == "ridge":
            return Ridge(self.lam)
        return LeastSquares()

    def as_dict(self) -> dict:
        return {"degree": self.degree, "penalty": self.penalty, "lambda": self.lam,
                "lambda_relative": self.relative_lam}


AFFINE = Candidate(1, "none", None)


@dataclass(frozen=True)
class Part:
    """What one selection serves: one output, a force or torque block, or all outputs (``"model"``)."""

    name: str
    columns: tuple[int, ...]


class Scorer:
    """Fold scores of candidates for a part of the outputs, from their per-output mean squared errors.

    Blocks are scored by their error-norm RMSE (√Σ MSE over the block's outputs); the
    ``"model"`` part by ``objective``: the force or torque block, or (``"both"``) the mean
    of the force and torque scores each divided by the affine model's.
    """

    def __init__(self, output_names: Sequence[str], objective: str = "both"):
        self.output_names = tuple(output_names)
        self.objective = check_choice(objective, "objective", "select_model", OBJECTIVES)
        self.blocks = {name: tuple(cols) for name, cols in metrics.wrench_blocks(self.output_names).items()}
        if objective != "both" and objective not in self.blocks:
            raise FtcalError(f"objective={objective!r} needs {objective} outputs; the outputs are "
                             f"{', '.join(self.output_names)}.")
        self.affine: CandidateScore | None = None

    @property
    def metric(self) -> str:
        if self.objective != "both":
            return f"RMSE of the {self.objective} error norm ({UNITS[self.objective]})"
        if len(self.blocks) == 2:  # the mean of the force and the torque block's ratio to the affine model's
            return "error vs affine (force & torque)"
        return "mean RMSE"

    def block(self, mse: np.ndarray, columns: Sequence[int]) -> np.ndarray:
        """√Σ MSE over ``columns``, per fold: the error-norm RMSE of a block, or an output's RMSE."""
        return metrics.block_error_norm_rmse(mse, columns)

    def objective_folds(self, mse: np.ndarray) -> np.ndarray:
        mse = np.asarray(mse)
        if self.objective != "both":
            return self.block(mse, self.blocks[self.objective])
        if len(self.blocks) == 2 and self.affine is not None:
            ratios = [self.block(mse, cols) / max(self.block(np.asarray(self.affine.fold_mse), cols).mean(),
                                                   np.finfo(float).tiny)
                      for cols in self.blocks.values()]
            return 0.5 * (ratios[0] + ratios[1])
        return np.sqrt(mse).mean(axis=1)

    def part_folds(self, mse: np.ndarray, part: Part) -> np.ndarray:
        return self.objective_folds(mse) if part.name == "model" else self.block(mse, part.columns)

    def parts(self, select_per: str) -> list[Part]:
        """The parts a ``select_per`` selection chooses for (blocks fall back to outputs without a wrench)."""
        select_per = check_choice(select_per, "select_per", "select_model", SELECT_PER)
        everything = tuple(range(len(self.output_names)))
        if select_per == "model":
            return [Part("model", everything)]
        if select_per == "block" and self.blocks:
            used = {c for cols in self.blocks.values() for c in cols}
            return ([Part(name, cols) for name, cols in self.blocks.items()]
                    + [Part(self.output_names[j], (j,)) for j in everything if j not in used])
        return [Part(self.output_names[j], (j,)) for j in everything]


@dataclass
class CandidateScore:
    """A candidate's per-output validation and training MSE, one row per fold, and nonzero counts per output."""

    candidate: Candidate
    scorer: Scorer
    fold_mse: list[np.ndarray] = field(default_factory=list)
    fold_train_mse: list[np.ndarray] = field(default_factory=list)
    fold_nonzero: list[np.ndarray] = field(default_factory=list)

    @property
    def fold_scores(self) -> list[float]:
        """The objective's validation score per fold."""
        return self.scorer.objective_folds(self.fold_mse).tolist()

    @property
    def fold_train_scores(self) -> list[float]:
        return self.scorer.objective_folds(self.fold_train_mse).tolist()

    @property
    def score(self) -> float:
        return float(np.mean(self.fold_scores))

    @property
    def train_score(self) -> float:
        return float(np.mean(self.fold_train_scores))

    @property
    def nonzero(self) -> float:
        return float(np.mean(np.sum(self.fold_nonzero, axis=1)))

    def part_scores(self, part: Part, train: bool = False) -> np.ndarray:
        return self.scorer.part_folds(self.fold_train_mse if train else self.fold_mse, part)

    def part_nonzero(self, part: Part) -> float:
        return float(np.mean(np.asarray(self.fold_nonzero)[:, list(part.columns)].sum(axis=1)))

    def block_score(self, block: str, train: bool = False) -> float:
        """Mean over folds of the ``"force"`` or ``"torque"`` error-norm RMSE (N, N·m)."""
        return float(self.scorer.block(self.fold_train_mse if train else self.fold_mse,
                                       self.scorer.blocks[block]).mean())

    def as_dict(self) -> dict:
        out = {**self.candidate.as_dict(), "validation_score": self.score, "train_score": self.train_score,
               "fold_scores": self.fold_scores, "n_nonzero": self.nonzero,
               "validation_rmse": dict(zip(self.scorer.output_names,
                                           np.sqrt(np.mean(self.fold_mse, axis=0)).tolist()))}
        for block in self.scorer.blocks:
            out[f"validation_{block}_error_norm_rmse"] = self.block_score(block)
        return out


@dataclass(frozen=True)
class Comparison:
    """A selection against the affine model, fold by fold.

    Attributes
    ----------
    reference : Candidate
        Least squares at the lowest degree scored (affine), or the best candidate of that degree.
    margin : float
        Mean over folds of (reference score − selection score); positive when the selection is better.
    spread : float
        Standard deviation of that difference over folds.
    standard_error : float
        ``spread / sqrt(n_folds)``.
    """

    reference: Candidate
    margin: float
    spread: float
    standard_error: float
    n_folds: int = 0  # 0: unknown (two standard errors)
    searched: int = 1  # degrees the selection was the best of (a Bonferroni correction of the quantile)
    log_margin: float | None = None  # mean over folds of log(reference score / selection score)
    log_standard_error: float | None = None  # its standard error (None: a score not positive)

    @property
    def quantile(self) -> float:
        """``t_{K−1, 1 − 0.025/D}`` for K folds and the best of D degrees (2 when K is unknown): the
        half-width of a 95 % interval in standard errors (D = 1: 12.7 for 2 folds, 2.78 for 5, 2.26 for 10;
        the best of 4 degrees over 5 folds needs 3.96)."""
        if self.n_folds < 2:
            return 2.0
        from scipy.special import stdtrit  # not scipy.stats: a second of imports

        return float(stdtrit(self.n_folds - 1, 1.0 - 0.025 / max(self.searched, 1)))

    @property
    def noise(self) -> float:
        """The fold noise in the scores' units: :attr:`quantile` × the standard error of the margin."""
        return self.quantile * self.standard_error

    @property
    def within_noise(self) -> bool:
        """The advantage is under the fold noise. Judged on the log ratio of the fold scores when they are
        positive: a fold with a large error and a large win does not drown out three consistent ones."""
        if self.log_standard_error is not None:
            return self.log_margin < self.quantile * self.log_standard_error
        return self.margin < self.noise

    @property
    def loses(self) -> bool:
        """Worse than the reference by more than the fold noise (on the log ratio when defined)."""
        if self.log_standard_error is not None:
            return self.log_margin < -self.quantile * self.log_standard_error
        return self.margin < -self.noise

    @classmethod
    def of(cls, reference: Candidate, reference_folds: np.ndarray, folds: np.ndarray,
           searched: int = 1) -> "Comparison":
        reference_folds, folds = np.asarray(reference_folds, dtype=float), np.asarray(folds, dtype=float)
        difference = reference_folds - folds
        n = difference.size
        spread = float(np.std(difference, ddof=1)) if n > 1 else 0.0
        log_margin = log_se = None
        if n > 1 and np.all(reference_folds > 0) and np.all(folds > 0):
            ratio = np.log(reference_folds / folds)
            log_margin, log_se = float(ratio.mean()), float(np.std(ratio, ddof=1) / np.sqrt(n))
        return cls(reference, float(difference.mean()), spread, spread / np.sqrt(n), n, searched, log_margin, log_se)


@dataclass
class CrossValidationResult:
    """Scores of every candidate tried, the selection and how it compares with the affine model.

    Attributes
    ----------
    scores : list of CandidateScore, in the order tried
    best : Candidate
        The best single candidate for all outputs, ranked by the objective.
    metric : str
        What the objective scores measure.
    n_folds : int
    skipped_degrees : tuple of int
        Degrees not tried because a lower degree already did better.
    select_per : {"output", "block", "model"}
    selection : list of (Part, Candidate)
        The candidate chosen for each part; all ``best`` for ``"model"``.
    notes : list of str
        Degrees dropped for cost, and similar facts the summary repeats.
    """

    scores: list[CandidateScore]
    best: Candidate
    metric: str
    n_folds: int
    skipped_degrees: tuple[int, ...] = ()
    select_per: str = "model"
    selection: list = field(default_factory=list)
    notes: list = field(default_factory=list)
    search: "_Search | None" = field(default=None, repr=False)

    @property
    def scorer(self) -> Scorer:
        return self.scores[0].scorer

    def score_of(self, candidate: Candidate) -> CandidateScore:
        return next(s for s in self.scores if s.candidate == candidate)

    def candidate_of_output(self) -> list[Candidate]:
        """The candidate serving each output, in output order."""
        chosen = [self.best] * len(self.scorer.output_names)
        for part, candidate in self.selection:
            for j in part.columns:
                chosen[j] = candidate
        return chosen

    @property
    def mixed(self) -> bool:
        return len(set(self.candidate_of_output())) > 1

    def selection_mse(self, train: bool = False) -> np.ndarray:
        """Per-fold, per-output MSE of the selection (each output's from its candidate), shape (n_folds, ny)."""
        chosen = self.candidate_of_output()
        def mse(c: Candidate) -> np.ndarray:
            return np.asarray(self.score_of(c).fold_train_mse if train else self.score_of(c).fold_mse)

        return np.column_stack([mse(c)[:, j] for j, c in enumerate(chosen)])

    def comparison(self) -> Comparison:
        """The best single candidate's margin over the affine model on the objective, with its fold spread."""
        lowest = min(s.candidate.degree for s in self.scores)
        plain = [s for s in self.scores if s.candidate == Candidate(lowest, "none", None)]
        pool = plain or [s for s in self.scores if s.candidate.degree == lowest]
        reference = min(pool, key=lambda s: s.score)
        return Comparison.of(reference.candidate, reference.fold_scores, self.score_of(self.best).fold_scores)

    def block_comparisons(self) -> dict[str, Comparison]:
        """The selection against the affine model on each block (force, torque), or on the mean RMSE."""
        scorer, mse = self.scorer, self.selection_mse()
        affine = self.score_of(AFFINE) if any(s.candidate == AFFINE for s in self.scores) else None
        if affine is None:
            return {}
        if not scorer.blocks:
            return {"outputs": Comparison.of(AFFINE, np.sqrt(np.asarray(affine.fold_mse)).mean(axis=1),
                                             np.sqrt(mse).mean(axis=1))}
        return {name: Comparison.of(AFFINE, scorer.block(affine.fold_mse, cols), scorer.block(mse, cols))
                for name, cols in scorer.blocks.items()}

    def losses(self) -> list[str]:
        """Blocks on which the selection validates worse than affine beyond the fold noise (t-scaled)."""
        return [name for name, c in self.block_comparisons().items() if c.loses]

    def describe_selection(self) -> str:
        if not self.mixed:
            return self.best.label if self.select_per == "model" else self.candidate_of_output()[0].label
        return "; ".join(f"{part.name} {candidate.label}" for part, candidate in self.selection)

    def _block_columns(self) -> list[tuple[str, str, Sequence[int]]]:
        scorer = self.scorer
        if scorer.blocks:
            return [(name, UNITS[name], cols) for name, cols in scorer.blocks.items()]
        return [("mean RMSE", "", range(len(scorer.output_names)))]

    def _block_values(self, mse: np.ndarray) -> list[float]:
        scorer = self.scorer
        if scorer.blocks:
            return [float(scorer.block(mse, cols).mean()) for _, _, cols in self._block_columns()]
        return [float(np.sqrt(np.asarray(mse)).mean(axis=1).mean())]

    def _header(self) -> str:
        blocks = "   ".join(f"{name} {unit}".strip() for name, unit, _ in self._block_columns())
        return blocks

    def table(self) -> str:
        """Every candidate: validation and training error per block (N, N·m) and nonzeros; then the verdict."""
        columns = self._block_columns()
        head = "".join(f" {('val ' + name + ' ' + unit).strip():>16} {('train ' + name).strip():>14}"
                       for name, unit, _ in columns)
        lines = [f"{'model':<28}{head} {'nonzero':>8}   ({self.n_folds} folds; * best for the objective: "
                 f"{self.metric})"]
        for s in self.scores:
            mark = "*" if s.candidate == self.best else " "
            values = "".join(f" {v:>16.4g} {t:>14.4g}" for v, t in zip(self._block_values(s.fold_mse),
                                                                      self._block_values(s.fold_train_mse)))
            lines.append(f"{mark}{s.candidate.label:<27}{values} {s.nonzero:>8.0f}")
        return "\n".join(lines + self._closing_lines())

    def summary(self) -> str:
        """The best candidate of each degree, force and torque side by side, the runner-up and the verdict."""
        columns = self._block_columns()
        head = "".join(f" {('val ' + name + ' ' + unit).strip():>16}" for name, unit, _ in columns)
        lines = [f"grouped cross-validation, {self.n_folds} folds, {len(self.scores)} candidates; best of each "
                 f"degree by {self.metric}:", f"  {'degree':<7}{'best candidate':<28}{head}"]
        ranked = sorted(self.scores, key=lambda s: s.score)
        for degree in sorted({s.candidate.degree for s in self.scores}):
            best = min((s for s in self.scores if s.candidate.degree == degree), key=lambda s: s.score)
            values = "".join(f" {v:>16.4g}" for v in self._block_values(best.fold_mse))
            lines.append(f"  {degree:<7}{best.candidate.label:<28}{values}")
        if len(ranked) > 1:
            winner = self.score_of(self.best)
            runner = next(s for s in ranked if s.candidate != self.best)
            lines.append(f"best single model {self.best.label}; runner-up {runner.candidate.label} "
                         f"({runner.score - winner.score:+.3g} on the objective)")
        return "\n".join(lines + self._closing_lines())

    def _closing_lines(self) -> list[str]:
        """What the table and the summary both end with: degrees not tried, notes, the verdict."""
        lines = []
        if self.skipped_degrees:
            lines.append(f"degrees {', '.join(map(str, self.skipped_degrees))} not tried: a lower degree already "
                         "validated better")
        return lines + list(self.notes) + [self.verdict()]

    def verdict(self) -> str:
        """The selection, then per block its validation error, its margin over affine and the fold noise."""
        per = {"output": "per output", "block": "per block", "model": "one model"}[self.select_per]
        head = f"selected ({per}): {self.describe_selection()}"
        comparisons = self.block_comparisons()
        mse = self.selection_mse()
        values = dict(zip([name for name, _, _ in self._block_columns()], self._block_values(mse)))
        pieces = []
        chosen = self.candidate_of_output()
        for name, unit, columns in self._block_columns():
            c = comparisons.get(name if name in comparisons else "outputs")
            text = f"{name} {values[name]:.4g}{(' ' + unit) if unit else ''}"
            if c is not None:
                unit_text = f" {unit}" if unit else ""
                text += (f", margin over {c.reference.label} {c.margin:+.3g}{unit_text} on average over "
                         f"{self.n_folds} folds (fold-to-fold spread {c.spread:.3g}, standard error "
                         f"{c.standard_error:.3g})")
                if c.loses:
                    text += f"; WORSE than {c.reference.label} beyond the fold noise"
                elif c.within_noise and max(chosen[j].degree for j in columns) > 1:
                    text += "; within the fold noise"
            pieces.append(text)
        return head + "\n  " + "\n  ".join(pieces)

    def as_dict(self) -> dict:
        """The whole search as plain data (for JSON): every candidate, the selection and the comparisons."""
        return {"select_per": self.select_per, "objective": self.scorer.objective, "metric": self.metric,
                "n_folds": self.n_folds, "best_single": self.best.as_dict(),
                "selection": [{"part": part.name, "outputs": [self.scorer.output_names[j] for j in part.columns],
                               **candidate.as_dict()} for part, candidate in self.selection],
                "against_affine": {name: {"margin": c.margin, "standard_error": c.standard_error,
                                          "worse_beyond_noise": c.loses}
                                   for name, c in self.block_comparisons().items()},
                "skipped_degrees": list(self.skipped_degrees), "notes": list(self.notes),
                "candidates": [s.as_dict() for s in self.scores]}


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
                   template: CalibrationModel | None = None, n_folds: int = 5, seed: int = 0,
                   select_per: str = "model", objective: str = "both",
                   advance: Callable[[int], None] | None = None) -> CrossValidationResult:
    """Score every candidate by grouped K-fold validation; pick the best (per output, block or model).

    Parameters
    ----------
    data : Dataset or GroupedStatistics (e.g. streamed files)
        With reference outputs and at least two groups.
    candidates : sequence of Candidate
        Degrees and penalties to try. The affine model (degree 1, least squares) is
        always scored too: it is the reference of every comparison.
    template : CalibrationModel, optional
        Unfitted model whose other parameters (ARX orders, basis, prior) every
        candidate shares; each candidate is ``template.clone(degree=..., solver=...)``.
    n_folds : int
    seed : int
        Fold assignment seed (see :func:`grouped_folds`).
    select_per : {"output", "block", "model"}
    objective : {"both", "force", "torque"}
        What ranks the single best model (``select_per="model"``); see :class:`Scorer`.
    advance : callable, optional
        Called with the number of (candidate, fold) fits done, as they finish (a progress bar).

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
    search = _Search(data, template, n_folds, seed, objective, advance)
    wanted = [AFFINE] + [c for c in candidates if c != AFFINE]
    for degree in sorted({c.degree for c in wanted}):
        search.score([c for c in wanted if c.degree == degree])
        search.release(degree)
    return search.result([search.scores[c] for c in wanted], select_per)


def select_model(data: "Dataset | GroupedStatistics", *, template: CalibrationModel | None = None,
                 degrees: Sequence[int] = DEFAULT_DEGREES, penalties: Sequence[str] = DEFAULT_PENALTIES,
                 lambdas: Sequence[float] | None = None, relative: bool = False, n_folds: int = 5, seed: int = 0,
                 stop_early: bool = True, select_per: str = "model", objective: str = "both",
                 notes: Sequence[str] = (), budget: "SearchBudget | None" = None,
                 advance: Callable[[int], None] | None = None) -> CrossValidationResult:
    """Grouped cross-validation over degrees, penalties and a λ grid, choosing per output, block or model.

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
        A fixed λ grid for every degree and penalty: absolute (e.g. :data:`PAPER_LAMBDAS`) or,
        with ``relative``, fractions of λ_max (LASSO) and of λ_ref = trace(AᵀA)/p (ridge).
        By default the grid comes from the data (see the module docstring).
    relative : bool
        Read ``lambdas`` as relative.
    n_folds, seed : int
    stop_early : bool
        Stop at the first degree that improves none of the parts selected for.
    select_per : {"output", "block", "model"}
        Choose a candidate per output, per force/torque block, or one for all outputs.
    objective : {"both", "force", "torque"}
        What ranks a candidate serving both blocks (see :class:`Scorer`).
    notes : sequence of str
        Lines for the summary (e.g. degrees dropped by a cost budget).
    budget : SearchBudget, optional
        A CPU budget kept during the search: a degree starts only when the CPU used so far plus its
        predicted cost (scaled by how the degrees done compared with their prediction) fits; the
        degrees left out are named in the notes.
    advance : callable, optional
        Called with the number of (candidate, fold) fits done, as they finish (a progress bar).

    Returns
    -------
    CrossValidationResult
        Emits a :class:`SelectionLossWarning` when the selection validates worse than the
        affine model on a block by more than two fold standard errors, and a
        :class:`~ftcal.runtime.errors.FtcalWarning` when a selection of higher degree beats
        affine by less than that on every block.
    """
    penalties = tuple(penalties)
    for penalty in penalties:
        if penalty not in ("lasso", "ridge"):
            raise FtcalError(f"Unknown penalty {penalty!r}; choose from 'lasso', 'ridge'.")
    degrees = sorted({check_int(d, "degrees", "select_model", 1) for d in degrees})
    if not degrees:
        raise FtcalError("No degrees to select from.")
    search = _Search(data, template, n_folds, seed, objective, advance)
    parts = search.scorer.parts(select_per)
    best_so_far = {part: np.inf for part in parts}
    skipped: tuple[int, ...] = ()
    notes = list(notes)
    search.score([AFFINE])
    for i, degree in enumerate(degrees):
        overrun = budget.overrun(degree) if budget is not None and i > 0 else None
        if overrun is not None:
            notes.append(f"degrees {', '.join(map(str, degrees[i:]))} not tried: {overrun}")
            break
        if budget is not None:
            budget.start(degree)
        search.score([Candidate(degree, "none", None)])
        for penalty in penalties:
            if lambdas is None:
                grid = search.lambda_grid(degree, penalty)
            elif relative:
                reference = search.reference_lambda(degree, penalty)
                grid = [Candidate(degree, penalty, float(r) * reference, reference) for r in lambdas]
            else:
                grid = [Candidate(degree, penalty, float(lam)) for lam in lambdas]
            search.score(grid)
            if lambdas is None:
                search.extend_at_edges(degree, penalty)
        search.release(degree)
        if budget is not None:
            budget.finish(degree)
        here = [s for c, s in search.scores.items() if c.degree == degree]
        improved = False
        for part in parts:
            best_here = min(float(s.part_scores(part).mean()) for s in here)
            improved |= best_here < best_so_far[part]
            best_so_far[part] = min(best_so_far[part], best_here)
        if stop_early and not improved and i + 1 < len(degrees):
            skipped = tuple(degrees[i + 1:])
            break
    ordered = [search.scores[AFFINE]] + [s for c, s in search.scores.items() if c != AFFINE]
    result = search.result(ordered, select_per, skipped, notes)
    lost = result.losses()
    if lost:
        warnings.warn(f"The selection ({result.describe_selection()}) validates worse than the affine model on "
                      f"{' and '.join(lost)} beyond the fold noise (more than the t quantile of {result.n_folds} folds "
                      "times the fold standard error). "
                      "Select per block or per output (--select-per), or use --objective both.",
                      SelectionLossWarning, stacklevel=2)
    comparisons = result.block_comparisons()
    if (comparisons and max(c.degree for c in result.candidate_of_output()) > 1
            and all(c.within_noise for c in comparisons.values())):
        margins = ", ".join(f"{name} {c.margin:+.3g} (standard error {c.standard_error:.3g})"
                            for name, c in comparisons.items())
        warnings.warn(
            f"The selection ({result.describe_selection()}) beats the affine model by less than the fold noise "
            f"(t quantile of {result.n_folds} folds times the standard error of the fold-to-fold differences: "
            f"{margins}): the choice is within the noise of "
            f"{result.n_folds} folds. Consider the simpler model or record more load cases.",
            FtcalWarning, stacklevel=2)
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

    def full_statistics(self, frame: FitFrame) -> SufficientStatistics:
        """Statistics of all the data for ``frame``'s layout in its solve basis (the refit of ARX selections)."""


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

    def full_statistics(self, frame: FitFrame) -> SufficientStatistics:
        return CalibrationModel.statistics(self.data, frame.layout, frame.solve_input_normalization,
                                           frame.solve_output_normalization)


def statistics_work(layout: RegressorLayout, n_rows: int, n_folds: int) -> int:
    """Work units of one statistics pass over ``n_folds`` folds: rows × accumulated products (moments, or
    Gram cells for ARX), plus a cost per row (reading and normalizing it) and a fixed cost per fold."""
    if layout.is_static:
        cells = n_rows * moment_plan(layout.basis.n_inputs, layout.basis.degree).n_moments
    else:
        cells = n_rows * layout.n_features * (layout.n_features + 1) // 2
    return cells + n_rows * ROW_COST + n_folds * PASS_OVERHEAD


# Costs in work units of ≈ 1e-10 s (:data:`SECONDS_PER_UNIT`), measured on the demo's dataset and on
# load-case tables of 2e4-1e6 rows with 6-8 inputs (benchmarks/bench_cost.py):
# Python and BLAS call overhead per candidate and fold (≈ 2 ms); per fold of a statistics pass (≈ 4 ms);
# per row of a pass (reading, normalizing: ≈ 0.5 µs).
CANDIDATE_OVERHEAD = 18_000_000
PASS_OVERHEAD = 20_000_000
ROW_COST = 5_000
# Dense p × p factorizations (eigen-decomposition, Cholesky with condition estimate), one thread: ≈ 2.5 p³.
DENSE_CUBE = 2.5
# The LASSO path (solvers.lasso): about 0.45·√p events per λ and output on the default grid (3 decades
# below λ_max), about 10·√p for a path down to a λ near least squares (a fixed, absolute λ), each one
# small Cholesky factorization and two products with p × k rows, ≈ 0.2 ms of overhead plus ≈ 0.16 µs per column.
PATH_EVENTS_PER_SQRT_P = 0.45
FULL_PATH_EVENTS_PER_SQRT_P = 10.0
EVENT_OVERHEAD = 2_000_000
EVENT_PER_COLUMN = 1_800
# The final pass (training metrics): ≈ 5 units per row, column and output.
METRICS_PER_CELL = 5


def path_events(p: int) -> float:
    """Typical LASSO path events per λ and output for ``p`` columns (see :mod:`ftcal.core.solvers.lasso`)."""
    return 1.0 + PATH_EVENTS_PER_SQRT_P * float(np.sqrt(p))


def candidate_work(p: int, n_outputs: int, penalty: str, events: float | None = None) -> int:
    """Work units of solving and scoring one candidate of ``p`` columns on one fold.

    Least squares factorizes its own Gram (≈ 2.5 p³); ridge and LASSO share the fold's
    eigen-decomposition (counted once per fold, :func:`decomposition_work`): ridge is
    two products with the eigenvectors (as cheap as scoring), LASSO its path events per output (``events``: the
    number taken per λ, all outputs; by default :func:`path_events` per output). Scoring is
    ≈ 4 p² per output (the validation and training sums).
    """
    per_output = 4 * p * p * n_outputs + CANDIDATE_OVERHEAD
    if penalty == "none":
        return int(DENSE_CUBE * p ** 3) + per_output
    if penalty == "ridge":
        return per_output
    events = path_events(p) * n_outputs if events is None else events
    return int(events * (EVENT_OVERHEAD + EVENT_PER_COLUMN * p)) + per_output


def decomposition_work(p: int) -> int:
    """Work units of one fold's eigen-decomposition of its p × p Gram (≈ 2.5 p³)."""
    return int(DENSE_CUBE * p ** 3)


@dataclass(frozen=True)
class CostEstimate:
    """Predicted CPU of a selection, per degree, and of what comes before and after it.

    Attributes
    ----------
    degrees : tuple of int
    units : tuple of (statistics units, solve units) per degree
    seconds : tuple of float per degree (1 core, compiled kernel; see :data:`SECONDS_PER_UNIT`)
    peak_bytes : tuple of float per degree: memory held while that degree is scored
    candidates : int, candidates per degree assumed
    n_folds : int
    spent_seconds : float
        CPU the process had used when the estimate was made (start-up, reading the ranges).
    final_seconds : tuple of float per degree
        The refit and the training-metrics pass if that degree is the highest searched.
    """

    degrees: tuple[int, ...]
    units: tuple[tuple[int, int], ...]
    seconds: tuple[float, ...]
    peak_bytes: tuple[float, ...]
    candidates: int
    n_folds: int
    spent_seconds: float = 0.0
    final_seconds: tuple[float, ...] = ()

    @property
    def total_units(self) -> int:
        return int(sum(a + b for a, b in self.units))

    @property
    def search_seconds(self) -> float:
        return float(sum(self.seconds))

    @property
    def total_seconds(self) -> float:
        """Everything: spent so far, the search, the final fit."""
        final = self.final_seconds[-1] if self.final_seconds else 0.0
        return self.spent_seconds + self.search_seconds + final

    @property
    def total_peak_bytes(self) -> float:
        return float(max(self.peak_bytes)) if self.peak_bytes else 0.0

    def seconds_of(self, degree: int) -> float:
        """Predicted search seconds of ``degree``."""
        return self.seconds[self.degrees.index(degree)]

    def within(self, budget_seconds: float, memory_bytes: float) -> tuple[tuple[int, ...], str | None]:
        """The degrees (lowest first) that fit the budget, and a sentence naming what was dropped and why."""
        kept, total = [], self.spent_seconds
        for i, (degree, seconds, peak) in enumerate(zip(self.degrees, self.seconds, self.peak_bytes)):
            final = self.final_seconds[i] if self.final_seconds else 0.0
            if kept and (total + seconds + final > budget_seconds or peak > memory_bytes):
                reason = (f"estimated {total + seconds + final:.0f} s of CPU > --budget {budget_seconds:g} s"
                          if total + seconds + final > budget_seconds else
                          f"estimated peak {peak / 1e6:.0f} MB > {memory_bytes / 1e6:.0f} MB")
                dropped = self.degrees[len(kept):]
                return tuple(kept), (f"degrees {', '.join(map(str, dropped))} not tried: {reason} at degree {degree}; "
                                     "raise --budget, or lower --max-degree or --folds to silence this")
            kept.append(degree)
            total += seconds
        return tuple(kept), None

    def restricted(self, degrees: Sequence[int]) -> "CostEstimate":
        """The estimate of ``degrees`` only (a prefix of :attr:`degrees`, as :meth:`within` keeps)."""
        keep = [i for i, d in enumerate(self.degrees) if d in set(degrees)]
        return CostEstimate(tuple(self.degrees[i] for i in keep), tuple(self.units[i] for i in keep),
                            tuple(self.seconds[i] for i in keep), tuple(self.peak_bytes[i] for i in keep),
                            self.candidates, self.n_folds, self.spent_seconds,
                            tuple(self.final_seconds[i] for i in keep) if self.final_seconds else ())

    def describe(self) -> str:
        final = self.final_seconds[-1] if self.final_seconds else 0.0
        return (f"estimated work: degrees {self.degrees[0]}-{self.degrees[-1]} x {self.n_folds} folds x about "
                f"{self.candidates} candidates per degree: about {self.total_seconds:.1f} s of CPU in all "
                f"({self.spent_seconds:.1f} s so far, {self.search_seconds:.1f} s search, {final:.1f} s final fit), "
                f"peak {self.total_peak_bytes / 1e6:.3g} MB of statistics")


# CPU seconds per unit, calibrated with the compiled kernel and OpenBLAS on the 2-core development machine
# (benchmarks/bench_cost.py); a scale for the budget, kept honest during the search (select_model's budget).
SECONDS_PER_UNIT = {"statistics": 1.8e-10, "solve": 1.1e-10}


def estimate_cost(n_samples: int, n_inputs: int, n_outputs: int, degrees: Sequence[int], n_folds: int, *,
                  penalties: Sequence[str] = DEFAULT_PENALTIES, n_lambdas: int | None = None, na: int = 0,
                  nb: int = 0, n_bases: int | None = None, spent_seconds: float = 0.0) -> CostEstimate:
    """Predict the work of :func:`select_model` before it starts: candidates × folds × Gram size.

    Parameters
    ----------
    n_samples, n_inputs, n_outputs : int
    degrees : sequence of int, all assumed tried
    n_folds : int
    penalties : penalized families tried beside least squares
    n_lambdas : λ per penalty, or None for the default grids (10 LASSO, 13 ridge)
    na, nb : ARX orders
    n_bases : int, optional
        Statistics passes per degree: 2 when least squares (solved in the centred basis) and
        penalties (solved in the stored basis) differ, the default when there are penalties.
    spent_seconds : float
        CPU already used by the caller (start-up, earlier passes), counted in the total.

    Returns
    -------
    CostEstimate
        Statistics units (rows × moments) and solve units (≈ p³ per fold, LASSO path events)
        per degree, their seconds from :data:`SECONDS_PER_UNIT`, the final refit and metrics
        pass, and the memory the search holds at each degree: per fold its statistics (kept) and,
        while it is scored, the training sums, scaled problem and eigenvectors (three p × p arrays more).
    """
    degrees = sorted(set(degrees))
    units, seconds, peaks, finals = [], [], [], []
    per_degree = 1 + sum(n_lambdas if n_lambdas is not None else (LASSO_POINTS if p == "lasso" else RIDGE_POINTS)
                         for p in penalties)
    n_bases = n_bases if n_bases is not None else (2 if penalties else 1)
    kept = 0.0
    for degree in degrees:
        layout = RegressorLayout(MonomialBasis(n_inputs, degree), n_outputs, na, nb)
        p = layout.n_features
        rows = n_samples - (layout.max_lag if na or nb else 0)
        stats = n_bases * statistics_work(layout, rows, n_folds)
        solve = candidate_work(p, n_outputs, "none") + (decomposition_work(p) if penalties else 0)
        for penalty in penalties:
            points = n_lambdas if n_lambdas is not None else (LASSO_POINTS if penalty == "lasso" else RIDGE_POINTS)
            # Fixed λ are absolute: the path may run all the way down, whatever the number of points.
            events = (FULL_PATH_EVENTS_PER_SQRT_P * np.sqrt(p) * n_outputs / points
                      if penalty == "lasso" and n_lambdas is not None else None)
            solve += points * candidate_work(p, n_outputs, penalty, events)
        solve *= n_folds
        units.append((stats, solve))
        seconds.append(stats * SECONDS_PER_UNIT["statistics"] + solve * SECONDS_PER_UNIT["solve"])
        # The refit of the selection (one more candidate of each kind on all the data) and the metrics pass.
        refit = solve / n_folds / per_degree * (1 + len(penalties))
        finals.append(refit * SECONDS_PER_UNIT["solve"]
                      + (rows * p * n_outputs * METRICS_PER_CELL + rows * ROW_COST) * SECONDS_PER_UNIT["statistics"])
        # Kept: each fold's statistics per basis; while scored: training sums and scaled problems per basis
        # and fold, and the eigenvectors.
        kept += n_bases * n_folds * p * p * 8.0
        peaks.append(kept + (2 * n_bases + 1) * n_folds * p * p * 8.0)
    return CostEstimate(tuple(degrees), tuple(units), tuple(seconds), tuple(peaks), per_degree, n_folds,
                        float(spent_seconds), tuple(finals))


class SearchBudget:
    """A CPU budget for the whole command, kept while :func:`select_model` runs.

    Before each degree the CPU used so far (``clock``, the process's CPU seconds by default) plus
    the degree's predicted search and final-fit seconds must fit in ``seconds``. The prediction
    is the estimate's, scaled by how much the degrees already searched took against theirs
    (never below 1): a machine slower than the calibration, or a busy one, drops a degree
    before it overruns rather than after.

    Parameters
    ----------
    seconds : float
        CPU seconds allowed (``--budget``).
    estimate : CostEstimate
        The printed prediction, per degree.
    clock : callable, optional
        CPU seconds used so far (default :func:`time.process_time`).
    """

    def __init__(self, seconds: float, estimate: CostEstimate, clock: Callable[[], float] = time.process_time):
        self.seconds = seconds
        self.estimate = estimate
        self.clock = clock
        self.measured = 0.0
        self.predicted = 0.0
        self._started = 0.0

    @property
    def pace(self) -> float:
        """Measured over predicted search CPU of the degrees done (1 before any, never below 1)."""
        return max(1.0, self.measured / self.predicted) if self.predicted > 0 else 1.0

    def overrun(self, degree: int) -> str | None:
        """Why ``degree`` would overrun the budget, or None if it fits."""
        if degree not in self.estimate.degrees:
            return None
        i = self.estimate.degrees.index(degree)
        final = self.estimate.final_seconds[i] if self.estimate.final_seconds else 0.0
        used = self.clock()
        more = self.estimate.seconds[i] * self.pace + final
        if used + more <= self.seconds:
            return None
        return (f"{used:.1f} s of CPU used, degree {degree} would take about {more:.1f} s more "
                f"(> --budget {self.seconds:g} s)")

    def start(self, degree: int) -> None:
        self._started = self.clock()

    def finish(self, degree: int) -> None:
        if degree in self.estimate.degrees:
            self.measured += self.clock() - self._started
            self.predicted += self.estimate.seconds_of(degree)


class _Search:
    """Fold statistics per (degree, basis), computed once, and the scores of every candidate tried."""

    def __init__(self, data: "Dataset | GroupedStatistics", template: CalibrationModel | None, n_folds: int,
                 seed: int, objective: str = "both", advance: Callable[[int], None] | None = None):
        self.advance = advance if advance is not None else (lambda n: None)
        if isinstance(data, Dataset):
            if data.outputs is None:
                raise FtcalError("Cross-validation needs reference outputs in the data.")
            data = DatasetStatistics(data)
        self.data = data
        self.template = template if template is not None else CalibrationModel()
        self.fold_of = fold_of_groups(data.group_sizes(), n_folds, seed)
        self.n_folds = max(self.fold_of.values()) + 1
        self.scorer = Scorer(data.output_names, objective)
        self.scores: dict[Candidate, CandidateScore] = {}
        self.work = {"statistics": 0, "solve": 0}  # units counted as they are done (see estimate_cost)
        self._stats: dict[tuple[int, str], list[SufficientStatistics]] = {}
        self._frames: dict[tuple[int, str], FitFrame] = {}
        self._train: dict[tuple[tuple[int, str], int], tuple[SufficientStatistics, ScaledProblem]] = {}
        self._eigen: dict[tuple[tuple[int, str], int], tuple[np.ndarray, np.ndarray]] = {}
        self._references: dict[tuple[int, str], float] = {}
        self._full: dict[tuple, SufficientStatistics] = {}

    # ------------------------------------------------------------ statistics
    def _model(self, candidate: Candidate) -> CalibrationModel:
        model = self.template.clone(degree=candidate.degree, solver=candidate.solver())
        # Least squares does not shrink, so a prior has nothing to act on.
        return model.clone(prior=None) if candidate.penalty == "none" else model

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
            frame = self._frames[key]
            self._stats[key] = self.data.fold_statistics(frame, self.fold_of, self.n_folds)
            self.work["statistics"] += statistics_work(frame.layout, frame.n_rows, self.n_folds)
        return self._stats[key]

    def full_statistics(self, key: tuple[int, str]) -> SufficientStatistics:
        """Statistics of all the data: the sum of the folds' for static layouts (the folds partition the rows);
        a pass of their own for ARX layouts (a fold's segments lose their warm-up rows where groups change)."""
        frame = self._frames[key]
        if frame.layout.is_static:
            return sum_statistics(self.fold_statistics(key))
        if ("full",) + key not in self._full:
            self._full[("full",) + key] = self.data.full_statistics(frame)
        return self._full[("full",) + key]

    def release(self, degree: int) -> None:
        """Drop the training sums and eigen-decompositions of ``degree`` (its fold statistics stay, for the refit)."""
        for store in (self._train, self._eigen):
            for k in [k for k in store if k[0][0] == degree]:
                del store[k]

    # -------------------------------------------------------------- λ grids
    def reference_lambda(self, degree: int, penalty: str) -> float:
        """λ_max (LASSO) or λ_ref = trace(G)/p (ridge) at ``degree``, from the statistics of all the data."""
        if (degree, penalty) not in self._references:
            key, _, _ = self._key(Candidate(degree, penalty, 1.0))
            problem = ScaledProblem.from_statistics(self.full_statistics(key))
            if penalty == "lasso":
                value = lasso_lambda_max(problem)
            else:  # the mean eigenvalue of G: above it the penalty dominates most directions
                value = float(np.trace(problem.gram)) / problem.n_features
            self._references[(degree, penalty)] = value
        return self._references[(degree, penalty)]

    def lambda_grid(self, degree: int, penalty: str) -> list[Candidate]:
        """The default grid of ``penalty`` at ``degree``, relative to its reference λ."""
        top = self.reference_lambda(degree, penalty)
        if penalty == "lasso":
            relative = np.logspace(0.0, -LASSO_DECADES, LASSO_POINTS + 1)[1:]
        else:
            relative = np.logspace(0.0, -RIDGE_DECADES, RIDGE_POINTS)
        return [Candidate(degree, penalty, float(top * r), top) for r in relative]

    def extend_at_edges(self, degree: int, penalty: str) -> None:
        """Grow the grid by a decade past an edge where the best λ sits (LASSO: the small edge only)."""
        step = LASSO_DECADES / LASSO_POINTS if penalty == "lasso" else RIDGE_DECADES / (RIDGE_POINTS - 1)
        top = self.reference_lambda(degree, penalty)
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
            self.score([Candidate(degree, penalty, float(lam), top) for lam in new])

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
            p, ny = parts[0].n_features, parts[0].cross.shape[1]
            penalized = any(c.penalty != "none" for c, _, _ in group)
            decompositions = sum((key, f) not in self._eigen for f in range(self.n_folds)) if penalized else 0
            self.work["solve"] += decompositions * decomposition_work(p)
            # SciPy loaded before the limit: the fold threads' factorizations are SciPy's (its own OpenBLAS).
            with warnings.catch_warnings(), single_threaded_blas(scipy=True):
                # Fold fits of high degrees on few groups are often ill-posed; the score says how much that matters.
                warnings.simplefilter("ignore", IllPosedFitWarning)
                # Folds run in parallel threads (numpy releases the GIL in its kernels).
                with ThreadPoolExecutor(min(worker_count(), self.n_folds)) as pool:
                    rows = []
                    for fold_rows in pool.map(lambda f: self._fold(key, group, parts, f), range(self.n_folds)):
                        rows.append(fold_rows)
                        self.advance(len(fold_rows))
            for fold_rows in rows:
                for candidate, val_mse, train_mse, nonzero, events in fold_rows:
                    self.work["solve"] += candidate_work(p, ny, candidate.penalty, events)
                    entry = self.scores.setdefault(candidate, CandidateScore(candidate, self.scorer))
                    entry.fold_mse.append(val_mse)
                    entry.fold_train_mse.append(train_mse)
                    entry.fold_nonzero.append(nonzero)
                    if candidate == AFFINE:
                        self.scorer.affine = entry

    def _fold(self, key, group, parts: list[SufficientStatistics], f: int) -> list[tuple]:
        """(candidate, validation MSE, training MSE, nonzeros per output, LASSO path events) of ``group``, fold ``f``."""
        if (key, f) not in self._train:
            train = sum_statistics([parts[g] for g in range(len(parts)) if g != f])
            self._train[(key, f)] = (train, ScaledProblem.from_statistics(train))
        train, problem = self._train[(key, f)]
        rows = []
        for (candidate, _, _), result, prior in self._solve(problem, group, (key, f)):
            coef = (result.coef + (0.0 if prior is None else prior)) / problem.column_scale[:, None]
            rows.append((candidate, self._mse(parts[f], coef), self._mse(train, coef),
                         np.count_nonzero(coef, axis=0), result.info.get("events")))
        return rows

    def _solve(self, problem: ScaledProblem, group, fold_key):
        """Yield ((candidate, model, frame), SolverResult, prior) for one fold; paths share one eigen-decomposition.

        The LASSO λ of a fold are one exact path from λ_max (:mod:`ftcal.core.solvers.lasso`); ridge
        uses the eigen-decomposition, which the LASSO needs only when it falls back to ADMM.
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

    @staticmethod
    def _mse(stats: SufficientStatistics, coef: np.ndarray) -> np.ndarray:
        """Mean squared error per output of coefficients ``coef`` (unscaled columns) on the rows ``stats`` sum."""
        # ‖Aθ − y‖² per output, exactly, from AᵀA, Aᵀy and ‖y‖².
        sse = (np.einsum("ij,ij->j", coef, stats.gram @ coef) - 2.0 * np.einsum("ij,ij->j", coef, stats.cross)
               + stats.target_sq)
        return np.maximum(sse, 0.0) / max(stats.n_samples, 1)

    def _choose(self, ordered: list[CandidateScore], part: Part) -> Candidate:
        """The best candidate for ``part``; ties (within 1% or one paired standard error) go to fewer nonzeros."""
        folds = {id(s): s.part_scores(part) for s in ordered}
        best = min(ordered, key=lambda s: folds[id(s)].mean())
        best_folds = folds[id(best)]

        def tied(s: CandidateScore) -> bool:
            difference = folds[id(s)] - best_folds
            noise = np.std(difference, ddof=1) / np.sqrt(difference.size) if difference.size > 1 else 0.0
            return difference.mean() + best_folds.mean() <= best_folds.mean() * (1 + TIE_TOLERANCE) \
                or difference.mean() <= noise

        chosen = min((s for s in ordered if tied(s)), key=lambda s: (s.part_nonzero(part), folds[id(s)].mean()))
        # The stable choice: a win over affine least squares must exceed the fold noise (t-scaled), else a
        # held-out set of another kind (a new orientation, a new load) can reverse it.
        affine = next((s for s in ordered if s.candidate == AFFINE), None)
        if affine is not None and chosen is not affine:
            # The best of several degrees on the same folds: its margin is the largest of several (Bonferroni).
            searched = max(len({s.candidate.degree for s in ordered} - {AFFINE.degree}), 1)
            comparison = Comparison.of(AFFINE, folds[id(affine)], folds[id(chosen)], searched)
            if comparison.within_noise:
                if chosen.candidate.degree > AFFINE.degree:  # a penalty at degree 1 changes next to nothing
                    self.stable_notes.append(
                        f"{part.name}: {AFFINE.label} kept; {chosen.candidate.label} beats it by "
                        f"{comparison.margin:+.3g} on average over {comparison.n_folds} folds, within their noise "
                        f"(t quantile {comparison.quantile:.3g} for the best of {searched} degree(s) x the standard "
                        "error of the fold-by-fold log ratio)")
                return AFFINE
        return chosen.candidate

    def result(self, ordered: list[CandidateScore], select_per: str = "model", skipped: tuple[int, ...] = (),
               notes: list[str] | None = None) -> CrossValidationResult:
        self.stable_notes = []
        best = self._choose(ordered, Part("model", tuple(range(len(self.scorer.output_names)))))
        parts = self.scorer.parts(select_per)
        selection = [(part, best if part.name == "model" else self._choose(ordered, part)) for part in parts]
        if select_per == "model":
            self.stable_notes = self.stable_notes[:1]
        return CrossValidationResult(ordered, best, self.scorer.metric, self.n_folds, skipped, select_per,
                                     selection, [self.fold_note()] + list(notes or []) + self.stable_notes, self)

    def fold_note(self) -> str:
        """What the folds hold out, and so what the validation errors promise."""
        n_groups = len(self.fold_of)
        return (f"folds: each holds out whole groups (about {n_groups / self.n_folds:.3g} of the {n_groups} groups: "
                "load cases, files or --group-by), never single samples; the validation errors are for new groups "
                "like these, not for loads, orientations or temperatures that no group covers")


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
    """Refit the selection of ``result`` on all of ``data``, with training metrics.

    Parameters
    ----------
    data : Dataset
        The data ``result`` was computed on.
    result : CrossValidationResult
    template : CalibrationModel, optional
        The template ``result`` was computed with (a selection of one candidate only).

    Returns
    -------
    CalibrationModel
    """
    if result.search is not None and (result.mixed or template is None or template is result.search.template):
        model = fit_selection(result)
        model.training_metrics_ = model.score(data, warn_out_of_range=False)
        return model
    return best_model(result, template).fit(data)


def best_model(result: CrossValidationResult, template: CalibrationModel | None = None) -> CalibrationModel:
    """The best single candidate of ``result`` as an unfitted model (``template``'s other parameters).

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


def fit_selection(result: CrossValidationResult) -> CalibrationModel:
    """The selection of ``result`` fitted on all the data, from the statistics the search already holds.

    Each candidate selected is solved once on the sum of its fold statistics (no pass
    over the data). When outputs use different candidates, every output's coefficients
    are mapped into one basis (the template's normalization, else ``maxabs`` when a
    penalized candidate is selected, else ``center``: exact algebra) and embedded in
    the layout of the largest selected degree with exact zeros for the terms its own
    degree does not have, so the model predicts each output exactly as its own
    candidate does, and every file format and export holds it unchanged.

    Parameters
    ----------
    result : CrossValidationResult
        From :func:`select_model` or :func:`cross_validate`.

    Returns
    -------
    CalibrationModel
        Fitted, with empty ``training_metrics_`` (the caller scores). ``solver_info_``
        names the selection (``"selection"``: part, outputs, degree, penalty, λ and relative λ).
    """
    search = result.search
    chosen = result.candidate_of_output()
    fitted: dict[Candidate, CalibrationModel] = {}
    for candidate in dict.fromkeys(chosen):
        key, model, frame = search._key(candidate)
        with warnings.catch_warnings():
            # Ill-posedness of the winner was judged by validation; the fit's own warning repeats what CV saw.
            warnings.simplefilter("ignore", IllPosedFitWarning)
            fitted[candidate] = model.fit_statistics(frame, search.full_statistics(key))
    info = {"selection": [{"part": part.name, "outputs": [search.scorer.output_names[j] for j in part.columns],
                           **candidate.as_dict()} for part, candidate in result.selection],
            "select_per": result.select_per}
    if len(fitted) == 1:
        model = fitted[chosen[0]]
        model.solver_info_.update(info)
        return model
    top = max(fitted.values(), key=lambda m: m.layout_.n_features)
    penalized = any(c.penalty != "none" for c in fitted)
    stored = search.template.clone(degree=top.layout_.basis.degree, prior=None,
                                   solver=Ridge(1.0) if penalized else LeastSquares())
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", IllPosedFitWarning)
        frame = search.data.frame(stored)
    coef = np.zeros((frame.layout.n_features, len(chosen)))
    for j, candidate in enumerate(chosen):
        part = fitted[candidate]
        own = part.coef_
        if part.normalization_ != frame.normalization:
            own = change_basis(part.layout_, own, part.input_normalization_, part.output_normalization_,
                               frame.input_normalization, frame.output_normalization)
        coef[part.layout_.index_in(frame.layout), j] = own[:, j]
    per = {"output": "per-output", "block": "per-block"}.get(result.select_per, "per-part")
    stored._set_fitted(
        layout=frame.layout, coef=coef, normalization=frame.normalization,
        input_normalization=frame.input_normalization, output_normalization=frame.output_normalization,
        input_names=frame.input_names, output_names=frame.output_names, input_range=frame.input_range,
        output_range=frame.output_range, n_samples_fit=frame.n_rows, rank=top.rank_,
        condition_number=max(m.condition_number_ for m in fitted.values()),
        solver_info={"name": f"{per} selection", "lambda": None, **info}, training_metrics={})
    return stored


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
