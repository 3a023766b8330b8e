"""The grouped cross-validation loop: fold statistics once per (degree, basis), every candidate scored
from them, degrees in increasing order with early stopping and a CPU budget (:func:`select_model`,
:func:`cross_validate`)."""

from __future__ import annotations

import warnings
from collections.abc import Callable, Sequence
from concurrent.futures import ThreadPoolExecutor

import numpy as np

from ...runtime.checks import check_int
from ...runtime.errors import FtcalError, FtcalWarning, IllPosedFitWarning, ParameterWarning
from ...runtime.threads import single_threaded_blas, worker_count
from ..dataset import Dataset
from ..model import CalibrationModel, FitFrame
from ..solvers.base import ScaledProblem
from ..solvers.lasso import Lasso
from ..solvers.least_squares import Ridge
from ..statistics import SufficientStatistics, sum_statistics
from .candidates import (AFFINE, DEFAULT_DEGREES, DEFAULT_PENALTIES, LASSO_DECADES, LASSO_POINTS, MAX_EXTENSIONS,
                         RIDGE_DECADES, RIDGE_POINTS, Candidate, lasso_lambda_max)
from .cost import SearchBudget, candidate_work, decomposition_work, statistics_work
from .folds import DatasetStatistics, GroupedStatistics, fold_of_groups
from .result import CrossValidationResult
from .scoring import CandidateScore, Part, Scorer, anchored_choice, nested_folds, stable_choice, statistics_mse


# Degrees in a row that improve no part before the search stops. Two, not one: a sensor whose
# nonlinearity is odd (cubic) gains nothing at degree 2 and half its error at degree 3 (the paper's
# 4.58 N -> 4.01 N -> 2.67 N); stopping at the first idle degree kept the affine model there.
STOP_AFTER = 2


class SelectionLossWarning(ParameterWarning):
    """The selected model validates worse than the affine model on a block, beyond the fold noise."""


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
    Candidates whose mean score is within 1% of the best count as tied; ties go
    to fewer nonzero coefficients. A win over the affine model must exceed the
    fold noise (:func:`~.scoring.stable_choice`). Input normalization uses the
    ranges of all the data.
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
        Stop after :data:`STOP_AFTER` degrees in a row that improve none of the parts selected for.
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
        affine model on a block beyond the fold noise (the one-sided t test), and a
        :class:`~ftcal.runtime.errors.FtcalWarning` when a selection of higher degree beats
        affine by less than the selection's bar (:attr:`~.scoring.Comparison.quantile`) on every block.
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
    idle = 0  # consecutive degrees that improved no part
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
        idle = 0 if improved else idle + 1
        if stop_early and idle >= STOP_AFTER and i + 1 < len(degrees):
            skipped = tuple(degrees[i + 1:])
            break
    ordered = [search.scores[AFFINE]] + [s for c, s in search.scores.items() if c != AFFINE]
    result = search.result(ordered, select_per, skipped, notes)
    lost = result.losses()
    if lost:
        warnings.warn(SelectionLossWarning(
                      ("select_per", "objective"),
                      f"The selection ({result.describe_selection()}) validates worse than the affine model on "
                      f"{' and '.join(lost)} beyond the fold noise (more than the t quantile of {result.n_folds} folds "
                      "times the fold standard error). "
                      "Select per block or per output ({select_per}), or use {objective} both."),
                      stacklevel=2)
    comparisons = result.block_comparisons()
    if (comparisons and max(c.degree for c in result.candidate_of_output()) > 1
            and all(c.within_noise for c in comparisons.values())):
        margins = ", ".join(f"{name} {c.margin:+.3g} (standard error {c.standard_error:.3g})"
                            for name, c in comparisons.items())
        bar = next(iter(comparisons.values())).quantile
        warnings.warn(
            f"The selection ({result.describe_selection()}) beats the affine model by less than the fold noise "
            f"({bar:.3g} standard errors of the fold-to-fold log ratios over {result.n_folds} folds: "
            f"{margins}): the choice is within the noise of "
            f"{result.n_folds} folds. Consider the simpler model or record more load cases.",
            FtcalWarning, stacklevel=2)
    return result


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
        # Few groups a fold: every candidate is also fitted on each pair of folds' complement (nested CV).
        self.nested = nested_folds(self.n_folds, len(self.fold_of))
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
            if self.nested:
                self._score_pairs(key, group, parts)

    def _score_pairs(self, key, group, parts: list[SufficientStatistics]) -> None:
        """Nested cross-validation's fits: on every fold but j and k, validated on j and on k (one fit serves the
        inner fold j of outer fold k and the inner fold k of outer fold j), for each pair j < k."""
        pairs = [(j, k) for j in range(self.n_folds) for k in range(j + 1, self.n_folds)]
        p, ny = parts[0].n_features, parts[0].cross.shape[1]
        penalized = any(c.penalty != "none" for c, _, _ in group)
        decompositions = sum((key, pair) not in self._eigen for pair in pairs) if penalized else 0
        self.work["solve"] += decompositions * decomposition_work(p)
        with warnings.catch_warnings(), single_threaded_blas(scipy=True):
            warnings.simplefilter("ignore", IllPosedFitWarning)
            with ThreadPoolExecutor(min(worker_count(), len(pairs))) as pool:
                rows = list(pool.map(lambda pair: self._fold(key, group, parts, pair), pairs))
        for (j, k), pair_rows in zip(pairs, rows):
            for candidate, (mse_j, mse_k), _, nonzero, events in pair_rows:
                self.work["solve"] += candidate_work(p, ny, candidate.penalty, events)
                entry = self.scores[candidate]
                entry.inner_mse[(k, j)], entry.inner_mse[(j, k)] = mse_j, mse_k
                entry.inner_nonzero[(k, j)] = entry.inner_nonzero[(j, k)] = nonzero

    def _fold(self, key, group, parts: list[SufficientStatistics], f: "int | tuple[int, int]") -> list[tuple]:
        """(candidate, validation MSE, training MSE, nonzeros per output, LASSO path events) of ``group``, fold ``f``.

        ``f`` a pair of folds (nested cross-validation): fitted on the other folds, and the validation MSE is
        the pair of the two folds' (the training MSE is not computed: None)."""
        held = f if isinstance(f, tuple) else (f,)
        if (key, f) not in self._train:
            train = sum_statistics([parts[g] for g in range(len(parts)) if g not in held])
            self._train[(key, f)] = (train, ScaledProblem.from_statistics(train))
        train, problem = self._train[(key, f)]
        rows = []
        for (candidate, _, _), result, prior in self._solve(problem, group, (key, f)):
            coef = (result.coef + (0.0 if prior is None else prior)) / problem.column_scale[:, None]
            validation = tuple(statistics_mse(parts[g], coef) for g in held)
            rows.append((candidate, validation if len(held) > 1 else validation[0],
                         None if len(held) > 1 else statistics_mse(train, coef),
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

    def result(self, ordered: list[CandidateScore], select_per: str = "model", skipped: tuple[int, ...] = (),
               notes: list[str] | None = None) -> CrossValidationResult:
        self.stable_notes = []
        n_groups = len(self.fold_of)
        best = stable_choice(ordered, Part("model", tuple(range(len(self.scorer.output_names)))), self.stable_notes,
                             n_groups=n_groups)
        parts = self.scorer.parts(select_per)
        gates = self.gates(ordered, parts)
        own = [(part, best if part.name == "model" else gates.get(part.name) or
                stable_choice(ordered, part, self.stable_notes, self.family(part, parts), n_groups))
               for part in parts]
        # The anchor never makes a richer selection where every block alone kept affine: at 12 load cases and an
        # affine truth it did so in 1 of 60 seeds (5.0 % against 3.3 %), the whole model's test passing alone.
        evidence = any(c != AFFINE for p, c in own if p.name in self.scorer.blocks)
        selection = [(part, anchored_choice(ordered, part, c, best, self.stable_notes, n_groups, evidence)
                      if part.name in self.scorer.blocks else c) for part, c in own]
        if select_per == "model":
            self.stable_notes = self.stable_notes[:1]
        return CrossValidationResult(ordered, best, self.scorer.metric, self.n_folds, skipped, select_per,
                                     selection, [self.fold_note()] + list(notes or []) + self.stable_notes, self)

    def gates(self, ordered: list[CandidateScore], parts: list[Part]) -> dict[str, Candidate]:
        """Outputs held at the affine model because their block keeps it (choosing per output only).

        Hierarchical testing: an output of a force or torque block may leave the affine model only when a
        richer model beats it on the whole block beyond the fold noise (the blocks' tests share the level, a
        Bonferroni factor of the number of blocks); the outputs' tests then share it within the block
        (:meth:`family`). Judged on each output alone, six tests at 4 folds
        chose a richer model on an affine truth in 20 % of seeds (12 load cases, BENCHMARKS.md).
        """
        held: dict[str, Candidate] = {}
        if not any(len(part.columns) == 1 for part in parts) or len(parts) == 1:
            return held
        for name, cols in self.scorer.blocks.items():
            outputs = [part for part in parts if len(part.columns) == 1 and part.columns[0] in cols]
            if not outputs or stable_choice(ordered, Part(name, tuple(cols)), [], len(self.scorer.blocks),
                                            len(self.fold_of)) != AFFINE:
                continue
            for part in outputs:
                held[part.name] = AFFINE
            self.stable_notes.append(f"{', '.join(p.name for p in outputs)}: {AFFINE.label} kept; no richer "
                                     f"model beats it on the {name} block beyond the fold noise, which an output "
                                     "must pass before it is judged alone")
        return held

    def family(self, part: Part, parts: list[Part]) -> int:
        """How many parts are judged together with ``part`` (a Bonferroni factor of its win test): the outputs
        of its block when choosing per output, else 1 (a block, or the model, is one decision)."""
        if len(part.columns) != 1 or len(parts) == 1:
            return 1
        block = next((cols for cols in self.scorer.blocks.values() if part.columns[0] in cols), None)
        return len(block) if block is not None else sum(len(p.columns) == 1 for p in parts)

    def fold_note(self) -> str:
        """What the folds hold out, and so what the validation errors promise."""
        n_groups = len(self.fold_of)
        return (f"folds: each holds out whole groups (about {n_groups / self.n_folds:.3g} of the {n_groups} groups: "
                "load cases, files or --group-by), never single samples; the validation errors are for new groups "
                "like these, not for loads, orientations or temperatures that no group covers")
