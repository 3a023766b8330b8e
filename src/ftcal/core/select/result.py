"""The outcome of a search: every candidate's scores, the selection, its comparison with the affine model,
and the tables and verdict the CLI prints."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
import numpy as np

from ..precision import SCORE, settle
from .candidates import AFFINE, Candidate
from .scoring import UNITS, CandidateScore, Comparison, Scorer, selection_rule


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
    # The search that made it (its fold statistics: fit_selection refits from them); typed loosely, since the
    # search module imports this one.
    search: object | None = field(default=None, repr=False)

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
        """The selection against the affine model on each block (force, torque), or on the mean RMSE; "within
        the fold noise" by the selection's rule for one decision (:func:`~.scoring.selection_rule`)."""
        scorer, mse = self.scorer, self.selection_mse()
        affine = self.score_of(AFFINE) if any(s.candidate == AFFINE for s in self.scores) else None
        if affine is None:
            return {}
        rule = selection_rule(self.n_folds, n_groups=len(self.search.fold_of) if self.search is not None else None)
        if not scorer.blocks:
            return {"outputs": Comparison.of(AFFINE, np.sqrt(np.asarray(affine.fold_mse)).mean(axis=1),
                                             np.sqrt(mse).mean(axis=1), rule=rule)}
        return {name: Comparison.of(AFFINE, scorer.block(affine.fold_mse, cols), scorer.block(mse, cols), rule=rule)
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
        # Ranked by scores stated to their precision: candidates tied to rounding keep their search order.
        finite = [s.score for s in self.scores if np.isfinite(s.score)]
        floor = min(finite, default=0.0) or max(finite, default=0.0)  # a best score of exactly 0: the largest
        ranked = sorted(self.scores, key=lambda s: settle(s.score, SCORE, floor))
        for degree in sorted({s.candidate.degree for s in self.scores}):
            best = min((s for s in self.scores if s.candidate.degree == degree), key=lambda s: s.score)
            values = "".join(f" {v:>16.4g}" for v in self._block_values(best.fold_mse))
            lines.append(f"  {degree:<7}{best.candidate.label:<28}{values}")
        if len(ranked) > 1:
            winner = self.score_of(self.best)
            runner = next(s for s in ranked if s.candidate != self.best)
            lines.append(f"best single model {self.best.label}; runner-up {runner.candidate.label} "
                         f"({settle(runner.score - winner.score, SCORE, max(winner.score, runner.score)):+.3g} on the objective)")
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
