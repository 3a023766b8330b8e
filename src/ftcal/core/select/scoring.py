"""Fold scores of candidates per output, block or model, margins over the affine model, the stable choice.

A candidate's fold scores come from its per-output mean squared errors; blocks are
scored by their error-norm RMSE, the whole model by the objective (:class:`Scorer`).
:class:`Comparison` is a margin over a reference with its fold-to-fold noise, and
:func:`stable_choice` picks the candidate of a part: the best score (ties within 1 % go to
fewer nonzeros), kept only when it beats the affine model beyond the fold noise.

The fold noise of one decision (a block, or the whole model, over 5 folds or more of 4 groups a fold
or more) is the one-standard-error rule (Breiman, Friedman, Olshen & Stone 1984, *Classification and
Regression Trees*, §3.4.3; Hastie, Tibshirani & Friedman 2009, *The Elements of Statistical Learning*, §7.10):
the affine model, the simplest, is kept unless the best candidate beats it by more than one standard
error, here of the paired fold log ratio log(affine / candidate), and that standard error corrected
for the training sets the folds share (Nadeau & Bengio 2003, *Inference for the Generalization
Error*, Machine Learning 52: the variance of a mean over K splits is σ² (1/K + n_test/n_train), not
σ²/K; for K balanced folds n_test/n_train = 1/(K − 1), so the corrected standard error is
√(1 + K/(K − 1)) ≈ 1.5 naive ones at 5 folds). Several parts judged together (the outputs of a block,
:meth:`Comparison.quantile`) or few folds (:func:`few_folds`) keep the one-sided t test at 5 % with a
Bonferroni factor, which their false-win rates need; folds of few groups add nested cross-validation
(:func:`nested_comparison`: the procedure that chooses within the training folds must beat affine on the
held-out fold, over the outer folds). Choosing per block, a block takes the whole model's choice unless its own
beats that beyond the fold noise (:func:`anchored_choice`). Measured on simulated sensors with a known truth
(``benchmarks/bench_select_rates.py``, BENCHMARKS.md): see :data:`SELECTION_RULE`.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from ...runtime.checks import check_choice
from ...runtime.errors import FtcalError
from .. import metrics
from ..limits import OBJECTIVES, SELECT_PER
from ..precision import MEAN_SQUARE, SCORE, settle
from ..statistics import SufficientStatistics
from .candidates import AFFINE, Candidate

# Candidates within 1 % of the best score count as tied (and go to fewer nonzeros). Not one standard error:
# a nonzero count does not rank penalties (a heavy-λ LASSO has few nonzeros and biased coefficients), and
# the sparsest candidate within one standard error validated 1.36x the affine model's force error on new
# load cases where the best scored 0.75x (seed 21 of benchmarks/bench_select_rates.py); parsimony is the
# affine test's job.
TIE_TOLERANCE = 0.01
# One-sided level of a claimed win over the affine model where the t test applies (several parts judged
# together, or few folds).
WIN_LEVEL = 0.05
# Below this many folds (3 degrees of freedom or fewer, a fold of one or two load cases) the fold log ratio
# is far from normal: at 4 folds of 8 load cases the one-sided test alone chose a richer model on an
# affine truth in 10 % of seeds; there the level is also divided by the degrees searched (2 %), and the
# one-standard-error rule (a lower bar) is not used.
FOLDS_WITHOUT_DEGREE_CORRECTION = 5
# Fewer load cases (groups) than this per fold count as few folds too (the t test with the degrees searched as a
# Bonferroni factor, not the one-standard-error rule): with 12 load cases in 5 folds (2-3 per fold) and an
# affine truth, the best candidate's fold log ratio exceeded 4 standard errors in 2 of 40 seeds and the
# one-standard-error rule chose a richer model in 25 % of them (the t test at 5 %: 17.5 %; with the degree
# factor: 7.5 %); with 20 (4 per fold) no richer candidate came within one standard error in 40 seeds.
MIN_GROUPS_PER_FOLD = 4
# The rule of one decision over enough folds and groups (not few_folds): "one-se" (the corrected
# one-standard-error rule of the module docstring) or "t-test" (one-sided t at WIN_LEVEL, the rule before
# issue 44 item 1; the benchmark judges the same folds by it). 40 load cases, seeds 0-59 in three sets: the
# share of the oracle degree's force gain kept 96/94/98 % (t test: 92/79/90 %), torque 99/120/108 %
# (96/109/105 %); with an affine truth neither chose a richer model in any of the 60 seeds.
SELECTION_RULE = "one-se"
# Folds of few groups (fewer than MIN_GROUPS_PER_FOLD) over NESTED_MIN_FOLDS folds or more: a win must also
# survive nested cross-validation, the selection procedure scored on folds it never saw
# (:func:`nested_comparison`). 12 load cases in 5 folds (benchmarks/bench_select_rates.py, seeds 0-59 in three
# sets, same folds): affine truth, a richer model in 5/0/5 % of seeds (2 of 60) against 10/5/10 % (5 of 60)
# by the t test over the degrees alone; paper-level nonlinearity, the oracle's force gain kept 43 % against
# 48 % pooled, torque 70 % against 70 %. Its inner selection is the best candidate (ties to fewer nonzeros)
# without a test of its own: with the t test inside too (offline, seeds 0-42) the procedure kept affine in most
# folds and the force gain kept fell to 16 %. Tried and not taken (offline, the same searches re-judged, seeds
# 0-59): the flat test without the degrees as a Bonferroni factor, the nested one kept, keeps about 89 / 96 % of
# the oracle's force / torque gain but chose a richer model on an affine truth in 4 of 60 seeds (6.7 %, over the
# 5 % target); the nested test alone, or by the t test, 5-15 % per seed set. NESTED False: the rule before (the
# benchmark's flat_rule).
NESTED = True
NESTED_MIN_FOLDS = 4
# Choosing per block (the default), a block takes the whole model's stable choice unless its own best beats that on
# the block beyond the fold noise (:func:`anchored_choice`); a block that kept affine alone takes it only when the
# other did not. make bench (selection_rates, seeds 0-59 pooled, same searches): oracle's force / torque gain kept
# at 40 load cases 98 / 106 % (each block alone: 96 / 108 %), 12 load cases 62 / 76 % (43 / 70 %), 54 rows 87 / 94 %
# (74 / 93 %); an affine truth chose a richer model as often (0 %; 3.3 % at 12 load cases). Real-like sensors
# (real_like, seeds 0-1, over OLS): plate torque one level out 0.59 (alone 0.87), fingertip torque one direction out
# 0.41 (0.78), optical force on new load cases 0.81 (0.94); over the 24 blocks 6 better and 6 worse by more than
# 5 % (worse by 8-14 %: the fingertip's, an optical orientation's torque), 0.95x alone in geometric mean.
# False: each block alone (the benchmark's unanchored rule).
ANCHOR_BLOCKS = True
UNITS = {"force": "N", "torque": "N·m"}


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
            # An exact affine fit (noiseless readings, its error 0 to precision) has no ratio: the error itself
            # then ranks, in its units (a floor of the smallest float made any error ~1e307, ties by overflow).
            ratios = [self.block(mse, cols) / (self.block(np.asarray(self.affine.fold_mse), cols).mean() or 1.0)
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
    # Nested cross-validation (:func:`nested_comparison`): (k, j) -> per-output MSE on fold j of the fit on every
    # fold but j and k (outer fold k held out, inner fold j validated), and its nonzeros per output.
    inner_mse: dict = field(default_factory=dict)
    inner_nonzero: dict = field(default_factory=dict)

    def inner(self, k: int) -> "CandidateScore":
        """The scores of the cross-validation within the training folds of outer fold ``k`` (folds j != k)."""
        folds = [j for j in range(len(self.fold_mse)) if j != k]
        # Ranking only: no training errors kept for the pair fits.
        return CandidateScore(self.candidate, self.scorer, [self.inner_mse[(k, j)] for j in folds], [],
                              [self.inner_nonzero[(k, j)] for j in folds])

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
    searched: int = 1  # parts judged together (outputs of one block with select_per="output"): a Bonferroni factor
    log_margin: float | None = None  # mean over folds of log(reference score / selection score)
    log_standard_error: float | None = None  # its standard error (None: a score not positive)
    rule: str = "t-test"  # "one-se": the selection's rule for one decision (see selection_rule); "corrected-t": the MLP's

    @property
    def quantile(self) -> float:
        """How many (naive, fold-to-fold) standard errors a win must exceed (2 when K is unknown).

        ``rule="t-test"``: ``t_{K−1, 1 − WIN_LEVEL/M}`` for K folds and M parts judged together, a
        one-sided test at :data:`WIN_LEVEL` (M = 1: 6.31 for 2 folds, 2.13 for 5, 1.83 for 10; M = 3
        over 5 folds: 3.00). ``rule="one-se"``: one standard error corrected for the training sets the
        folds share (Nadeau & Bengio 2003), √(1 + K/(K − 1)) naive ones (1.50 for 5 folds, 1.45 for 10).
        ``rule="corrected-t"``: that t quantile in corrected standard errors (Nadeau & Bengio's corrected
        resampled t test; 3.20 naive ones for 5 folds), the bar of a model that was not searched for (the MLP).

        The degrees searched are not counted: their fold log ratios move together (they are scored on the
        same held-out groups), so a correction per degree counts one comparison several times and gave the
        real gains away (the measured false-win and gain rates are in BENCHMARKS.md)."""
        if self.rule == "one-se" and self.n_folds >= 2:
            return corrected_standard_errors(self.n_folds)
        if self.rule == "corrected-t" and self.n_folds >= 2:
            return self.test_quantile * corrected_standard_errors(self.n_folds)
        return self.test_quantile

    @property
    def test_quantile(self) -> float:
        """``t_{K−1, 1 − WIN_LEVEL/M}`` whatever the rule (2 when K is unknown): the bar of a claimed loss."""
        if self.n_folds < 2:
            return 2.0
        from scipy.special import stdtrit  # not scipy.stats: a second of imports

        return float(stdtrit(self.n_folds - 1, 1.0 - WIN_LEVEL / max(self.searched, 1)))

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
        """Worse than the reference by more than the fold noise (on the log ratio when defined), by the t test
        whatever the rule: a loss is a warning, and the one-standard-error rule is a bar for a win only."""
        if self.log_standard_error is not None:
            return self.log_margin < -self.test_quantile * self.log_standard_error
        return self.margin < -self.test_quantile * self.standard_error

    @classmethod
    def of(cls, reference: Candidate, reference_folds: np.ndarray, folds: np.ndarray,
           searched: int = 1, rule: str = "t-test") -> "Comparison":
        reference_folds, folds = np.asarray(reference_folds, dtype=float), np.asarray(folds, dtype=float)
        difference = reference_folds - folds
        n = difference.size
        # Stated to the scores' precision (core.precision): two candidates that predict alike to rounding
        # (a tiny ridge λ and least squares) differ by exactly 0, so their verdict is the same on every CPU.
        scale = float(np.abs(np.r_[reference_folds, folds]).max(initial=0.0))
        difference = settle(difference, SCORE, scale)
        spread = settle(float(np.std(difference, ddof=1)), SCORE, scale) if n > 1 else 0.0
        log_margin = log_se = None
        if n > 1 and np.all(reference_folds > 0) and np.all(folds > 0):
            ratio = settle(np.log(reference_folds / folds), SCORE, 1.0)
            log_margin, log_se = float(ratio.mean()), settle(float(np.std(ratio, ddof=1) / np.sqrt(n)), SCORE, 1.0)
        return cls(reference, float(difference.mean()), spread, spread / np.sqrt(n), n, searched, log_margin, log_se,
                   rule)


def corrected_standard_errors(n_folds: int) -> float:
    """One standard error of a K-fold mean corrected for overlapping training sets, in naive standard errors.

    Nadeau & Bengio (2003): the variance of the mean of K split-wise differences is σ² (1/K + n_test/n_train)
    rather than σ²/K; with K folds balanced by sample count (:func:`~ftcal.core.select.folds.fold_of_groups`)
    n_test/n_train = 1/(K − 1), so the ratio of the two standard errors is √(1 + K/(K − 1)).
    """
    return float(np.sqrt(1.0 + n_folds / (n_folds - 1.0)))


def few_folds(n_folds: int, n_groups: int | None = None) -> bool:
    """Fewer than :data:`FOLDS_WITHOUT_DEGREE_CORRECTION` folds, or fewer than :data:`MIN_GROUPS_PER_FOLD`
    groups per fold (``n_groups`` None: unknown, not counted): fold log ratios far from normal."""
    return n_folds < FOLDS_WITHOUT_DEGREE_CORRECTION or (n_groups is not None
                                                         and n_groups < MIN_GROUPS_PER_FOLD * n_folds)


def selection_rule(n_folds: int, family: int = 1, n_groups: int | None = None) -> str:
    """The rule a claimed win over the affine model is judged by: ``"one-se"`` for one decision over enough
    folds and groups (not :func:`few_folds`; under :data:`SELECTION_RULE`), else ``"t-test"`` (with
    ``family`` parts judged together, a Bonferroni factor)."""
    return SELECTION_RULE if family <= 1 and not few_folds(n_folds, n_groups) else "t-test"


def nested_folds(n_folds: int, n_groups: int | None) -> bool:
    """Whether the search scores the selection procedure by nested cross-validation (K(K − 1)/2 fits more per
    candidate, on each pair of folds' complement): :data:`NESTED_MIN_FOLDS` folds or more (the inner
    cross-validation has one fewer), of fewer than :data:`MIN_GROUPS_PER_FOLD` groups a fold (``n_groups`` None:
    unknown, no)."""
    return n_groups is not None and n_folds >= NESTED_MIN_FOLDS and n_groups < MIN_GROUPS_PER_FOLD * n_folds


def statistics_mse(stats: SufficientStatistics, coef: np.ndarray) -> np.ndarray:
    """Mean squared error per output of coefficients ``coef`` (unscaled columns) on the rows ``stats`` sum.

    Exact algebra, no pass over the rows: ‖Aθ − y‖² = θᵀGθ − 2θᵀc + ‖y‖² per output.

    Parameters
    ----------
    stats : SufficientStatistics
    coef : ndarray of shape (n_features, n_outputs)

    Returns
    -------
    ndarray of shape (n_outputs,)
    """
    sse = (np.einsum("ij,ij->j", coef, stats.gram @ coef) - 2.0 * np.einsum("ij,ij->j", coef, stats.cross)
           + stats.target_sq)
    n = max(stats.n_samples, 1)
    # Stated to its precision (core.precision.MEAN_SQUARE of the readings' mean square): a fit exact in exact
    # arithmetic scores 0 on every CPU, not a rounding residue that would pick the degree (noiseless data).
    return np.array([settle(e, MEAN_SQUARE, s) for e, s in zip(np.maximum(sse, 0.0) / n, stats.target_sq / n)])


def tied(folds: np.ndarray, best_folds: np.ndarray) -> bool:
    """``folds`` score within :data:`TIE_TOLERANCE` of the best candidate's on average."""
    return float(np.mean(folds)) <= float(np.mean(best_folds)) * (1 + TIE_TOLERANCE)


def best_of(ordered: list[CandidateScore], part: Part) -> tuple[CandidateScore, CandidateScore, dict]:
    """The best candidate for ``part`` by mean fold score, the one chosen among its ties (within
    :data:`TIE_TOLERANCE`, fewer nonzeros first), and every candidate's fold scores (by ``id``)."""
    folds = {id(s): s.part_scores(part) for s in ordered}
    best = min(ordered, key=lambda s: folds[id(s)].mean())
    chosen = min((s for s in ordered if tied(folds[id(s)], folds[id(best)])),
                 key=lambda s: (s.part_nonzero(part), folds[id(s)].mean()))
    return best, chosen, folds


def nested_comparison(ordered: list[CandidateScore], part: Part) -> Comparison | None:
    """The selection procedure itself against the affine model, by nested cross-validation (None without the
    inner scores, :func:`nested_folds`).

    For each outer fold k the candidates are ranked by a cross-validation within the other folds alone (each
    fold j != k validated after a fit on the folds but j and k, :attr:`CandidateScore.inner_mse`), the best kept
    (ties within :data:`TIE_TOLERANCE` to fewer nonzeros, as :func:`best_of`); what that chose is scored on
    fold k, which it never saw (the fit on every fold but k: the candidate's own fold-k score). The procedure's
    fold scores against affine's carry no winner's curse: a richer candidate that is best over all the folds
    by chance is rarely best within each training set, and loses on the folds where it was not. One decision,
    judged by the corrected one-standard-error rule (:func:`corrected_standard_errors`)."""
    affine = next((s for s in ordered if s.candidate == AFFINE), None)
    if affine is None or any(not s.inner_mse for s in ordered):
        return None
    outer = {s.candidate: s.part_scores(part) for s in ordered}
    procedure = [outer[best_of([s.inner(k) for s in ordered], part)[1].candidate][k]
                 for k in range(len(affine.fold_mse))]
    return Comparison.of(AFFINE, outer[AFFINE], np.asarray(procedure), rule="one-se")


def stable_choice(ordered: list[CandidateScore], part: Part, notes: list[str], family: int = 1,
                  n_groups: int | None = None) -> Candidate:
    """The best candidate for ``part``; ties (within 1 %) go to fewer nonzeros.

    A win over the affine model within the fold noise keeps the affine model, and says so in ``notes``:
    the mean fold log ratio (affine / candidate) must exceed :attr:`Comparison.quantile` standard errors,
    by the rule of :func:`selection_rule`: one corrected standard error for one decision over 5 folds or
    more of ``n_groups`` groups (4 a fold or more), else the one-sided t test with ``family`` parts judged
    together (a Bonferroni factor, e.g. the three outputs of a block), or the degrees searched if more,
    when the folds are few (:func:`few_folds`). When the candidates carry nested scores (few groups a fold,
    :func:`nested_folds`), the selection procedure must also beat affine on the folds it never saw
    (:func:`nested_comparison`).
    """
    best, chosen, folds = best_of(ordered, part)
    best_folds = folds[id(best)]
    # The stable choice: a win over affine least squares must exceed the fold noise (t-scaled), else a
    # held-out set of another kind (a new orientation, a new load) can reverse it. One test per part, of the
    # best candidate: the sparsest tie is then kept for parsimony (judging the sparse tie itself kept affine
    # where the best won clearly; letting any winning tie through doubled the false wins, tests).
    affine = next((s for s in ordered if s.candidate == AFFINE), None)
    if affine is None or chosen is affine:
        return chosen.candidate
    rule = selection_rule(len(folds[id(affine)]), family, n_groups)
    nested = nested_comparison(ordered, part) if NESTED else None
    if few_folds(len(folds[id(affine)]), n_groups):
        family = max(family, len({s.candidate.degree for s in ordered} - {AFFINE.degree}))
    comparison = Comparison.of(AFFINE, folds[id(affine)], best_folds, family, rule)
    # Exact (0 to precision) in every held-out fold where affine is not: a win no fold noise explains (the log
    # ratio is infinite in each fold; noiseless readings of a nonlinear truth).
    exact = not np.any(best_folds) and np.all(folds[id(affine)] > 0)
    if exact or (not comparison.within_noise and (nested is None or not nested.within_noise)):
        return chosen.candidate
    if best.candidate.degree > AFFINE.degree and not comparison.within_noise:
        notes.append(
            f"{part.name}: {AFFINE.label} kept; {best.candidate.label} beats it by {comparison.margin:+.3g} on "
            f"average over {comparison.n_folds} folds, but the selection made within the training folds alone "
            f"(nested cross-validation) beats it on the folds it never saw by {nested.margin:+.3g}, within their "
            f"noise (one standard error corrected for the shared training sets, {nested.quantile:.3g} x the "
            "standard error of the fold-by-fold log ratio)")
    elif best.candidate.degree > AFFINE.degree:  # a penalty at degree 1 changes next to nothing
        notes.append(
            f"{part.name}: {AFFINE.label} kept; {best.candidate.label} beats it by "
            f"{comparison.margin:+.3g} on average over {comparison.n_folds} folds, within their noise "
            + (f"(one standard error corrected for the shared training sets, {comparison.quantile:.3g}"
               if rule == "one-se" else
               f"(one-sided t quantile {comparison.quantile:.3g} at {WIN_LEVEL:g}"
               + (f" over {family} parts or degrees" if family > 1 else ""))
            + " x the standard error of the fold-by-fold log ratio)")
    return AFFINE


def anchored_choice(ordered: list[CandidateScore], part: Part, own: Candidate, anchor: Candidate, notes: list[str],
                    n_groups: int | None = None, evidence: bool = True) -> Candidate:
    """A block's candidate given the whole model's stable choice ``anchor``: the block's ``own`` stable choice
    only when it beats the anchor on the block beyond the fold noise (the rule of :func:`selection_rule`), else
    the anchor, when it validates better than affine on the block on average, by more than a tie (else ``own``).
    A block that kept affine alone takes the anchor only with ``evidence`` (another block left affine alone).

    Why: a block chosen alone is picked from every candidate by its own three outputs, and its winner's curse is
    larger than the whole model's, chosen by six; on held-out load levels a torque block's own degree-3 pick lost
    to the whole model's degree 2 (and a torque block that kept affine lost the whole model's gain)."""
    if not ANCHOR_BLOCKS or anchor == AFFINE or own == anchor or (own == AFFINE and not evidence):
        return own
    scores = {s.candidate: s for s in ordered}
    anchor_folds, affine_folds = scores[anchor].part_scores(part), scores[AFFINE].part_scores(part)
    if tied(affine_folds, anchor_folds):  # not better than affine on this block by more than a tie
        return own
    if own != AFFINE:
        rule = selection_rule(len(anchor_folds), 1, n_groups)
        beyond = Comparison.of(anchor, anchor_folds, scores[own].part_scores(part), rule=rule)
        if not beyond.within_noise:
            return own
        notes.append(f"{part.name}: {anchor.label} (the whole model's choice) kept; the block's own best "
                     f"{own.label} beats it by {beyond.margin:+.3g} on average over {beyond.n_folds} folds, within "
                     "their noise")
    else:
        notes.append(f"{part.name}: {anchor.label} (the whole model's choice, a win beyond the fold noise over "
                     f"{AFFINE.label}) used; it validates better than {AFFINE.label} on this block on average")
    return anchor
