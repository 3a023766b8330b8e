"""The typed parts of a fit's report that no lower object holds: each keeps the numbers and renders its lines.

:class:`~ftcal.workflow.fitting.FitResult` holds these beside the objects of ``core`` that render
themselves (the excitation, the payload estimate, the search and its held-out span): the search's
planned cost against the budget, an explicit fit's grouped comparison with affine least squares, and
the MLP's sizing and validation against the affine model.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..core.limits import MLP_EQUATIONS_PER_WEIGHT
from .result import plain


@dataclass(frozen=True)
class SearchCost:
    """The ``degree="auto"`` search's predicted cost, the budget it was held to and the degrees that fit.

    Attributes
    ----------
    estimate : CostEstimate
        The prediction for every degree up to ``max_degree`` (:func:`ftcal.core.select.estimate_cost`).
    budget : float
        CPU seconds the whole fit may take.
    memory_bytes : float
        Statistics the search may hold.
    """

    estimate: object
    budget: float
    memory_bytes: float

    @property
    def degrees(self) -> tuple[int, ...]:
        """The degrees searched: those whose predicted CPU and memory fit (:meth:`CostEstimate.within`)."""
        return self.estimate.within(self.budget, self.memory_bytes)[0]

    @property
    def dropped(self) -> tuple[int, ...]:
        """The degrees not tried for cost."""
        return tuple(d for d in self.estimate.degrees if d not in self.degrees)

    @property
    def planned(self):
        """The estimate of the degrees searched only."""
        return self.estimate.restricted(self.degrees)

    @property
    def note(self) -> str | None:
        """What was dropped and why, in a sentence; None when every degree fits."""
        return self.estimate.within(self.budget, self.memory_bytes)[1]

    def lines(self) -> list[str]:
        """The estimate against the budget, then :attr:`note` (when something was dropped)."""
        return [self.planned.describe() + f" (--budget {self.budget:g} s)"] + ([self.note] if self.note else [])

    def to_frame(self):
        """One row per degree asked: predicted search and final-fit CPU seconds, peak statistics bytes, and
        whether the degree was searched."""
        import pandas as pd

        e = self.estimate
        return pd.DataFrame({"search_seconds": list(e.seconds),
                             "final_seconds": list(e.final_seconds) or [0.0] * len(e.degrees),
                             "peak_bytes": list(e.peak_bytes), "searched": [d in self.degrees for d in e.degrees]},
                            index=pd.Index(list(e.degrees), name="degree"))

    def to_dict(self) -> dict:
        planned = self.planned
        return plain({"degrees": self.degrees, "dropped_degrees": self.dropped, "budget_seconds": self.budget,
                      "memory_bytes": self.memory_bytes, "n_folds": planned.n_folds,
                      "candidates_per_degree": planned.candidates, "spent_seconds": planned.spent_seconds,
                      "search_seconds": planned.search_seconds, "total_seconds": planned.total_seconds,
                      "peak_bytes": planned.total_peak_bytes})


@dataclass(frozen=True)
class BlockVersusAffine:
    """One block's mean held-out error (RMSE of its error norm) for a candidate and for affine least squares."""

    name: str
    unit: str
    error: float
    affine_error: float
    # The verdict in words (a win / within the fold noise / worse beyond it), so a fit that does not beat
    # affine says so even without a warning.
    verdict: str = ""

    @property
    def ratio(self) -> float:
        """The candidate's error over affine's (below 1: the candidate validates better)."""
        return float(self.error / max(self.affine_error, np.finfo(float).tiny))

    def text(self) -> str:
        unit = f" {self.unit}" if self.unit else ""
        verdict = f" {self.verdict}" if self.verdict else ""
        return f"{self.name} {self.error:.4g}{unit} vs affine {self.affine_error:.4g} ({self.ratio:.3g}x){verdict}"


@dataclass(frozen=True)
class AffineComparison:
    """An explicit fit (a degree above 1, or penalized) beside affine least squares on the same grouped folds.

    Attributes
    ----------
    candidate : str, the explicit fit's label (``np2``, ``np3 lasso λ=1``)
    n_folds, n_groups : int, folds of whole groups and the groups they hold
    blocks : tuple of BlockVersusAffine, one per wrench block (or ``outputs``)
    """

    candidate: str
    n_folds: int
    n_groups: int
    blocks: tuple[BlockVersusAffine, ...]

    def summary(self) -> str:
        return (f"grouped cross-validation of {self.candidate} against affine least squares ({self.n_folds} folds "
                f"of whole groups, {self.n_groups} groups): " + "; ".join(b.text() for b in self.blocks))

    def to_dict(self) -> dict:
        return plain({"candidate": self.candidate, "n_folds": self.n_folds, "n_groups": self.n_groups,
                      "blocks": [{"name": b.name, "unit": b.unit, "error": b.error, "affine_error": b.affine_error, "verdict": b.verdict,
                                  "ratio": b.ratio} for b in self.blocks]})

    def to_frame(self):
        """One row per block: ``error``, ``affine_error``, ``ratio`` and ``unit``."""
        import pandas as pd

        return pd.DataFrame({"error": [b.error for b in self.blocks],
                             "affine_error": [b.affine_error for b in self.blocks],
                             "ratio": [b.ratio for b in self.blocks], "unit": [b.unit for b in self.blocks]},
                            index=pd.Index([b.name for b in self.blocks], name="block"))


@dataclass(frozen=True)
class NetworkSize:
    """The network :func:`~ftcal.core.mlp.hidden_for_data` sized to the data (``hidden`` not given)."""

    n_inputs: int
    hidden: tuple[int, ...]
    n_outputs: int
    n_weights: int
    n_rows: int

    def line(self) -> str:
        return (f"network {self.n_inputs}-{'-'.join(map(str, self.hidden))}-{self.n_outputs}: {self.n_weights} "
                f"weights for {self.n_rows} rows x {self.n_outputs} outputs (at most one weight per "
                f"{MLP_EQUATIONS_PER_WEIGHT} equations where the data allow; --hidden overrides)")


@dataclass(frozen=True)
class MLPValidation:
    """The MLP's grouped cross-validation beside affine least squares on the same folds.

    Attributes
    ----------
    label : str, the network (``mlp 32,32 tanh decay=0.0001``)
    metric : str, what the fold scores measure
    iterations, max_iter : int, the iteration count early stopping chose, and the most it could
    fold_scores, affine_fold_scores : tuple of float, per fold
    comparisons : dict of str to Comparison
        Per block (or ``outputs``), the MLP against affine on folds that did not choose its iteration count.
    """

    label: str
    metric: str
    iterations: int
    max_iter: int
    fold_scores: tuple[float, ...]
    affine_fold_scores: tuple[float, ...]
    comparisons: dict = field(default_factory=dict)

    @property
    def n_folds(self) -> int:
        return len(self.fold_scores)

    @property
    def lost(self) -> list[str]:
        """The blocks on which the MLP validates worse than affine beyond the fold noise (then affine is written)."""
        return [name for name, c in self.comparisons.items() if c.loses]

    def lines(self) -> list[str]:
        from ..core.select import AFFINE, Comparison

        lines = []
        if self.iterations >= self.max_iter:
            lines.append(f"early stopping chose the last of the {self.max_iter} iterations: held-out error was "
                         "still falling (a larger --max-iter may help)")
        mlp, affine = np.asarray(self.fold_scores), np.asarray(self.affine_fold_scores)
        versus = Comparison.of(AFFINE, affine, mlp)  # stated to the scores' precision
        lines.append("\n".join([
            f"{'model':<24} {'validation':>11}   ({self.metric}, {self.n_folds} grouped folds)",
            f" {'np1':<23} {np.mean(affine):>11.4f}",
            f"*{self.label:<23} {mlp.mean():>11.4f}   (early stop at {self.iterations} iterations)",
            f"mlp margin over np1 {versus.margin:+.3g} on average over {self.n_folds} folds "
            f"(fold-to-fold spread {versus.spread:.3g}, standard error {versus.standard_error:.3g})"]))
        for name, c in self.comparisons.items():
            lines.append(f"mlp {name} on folds that did not choose its iteration count: margin over np1 "
                         f"{c.margin:+.3g} (standard error {c.standard_error:.3g}, {c.n_folds} folds)"
                         + ("; WORSE beyond the fold noise" if c.loses else
                            "; within the fold noise" if c.within_noise else "; a win beyond the noise"))
        if self.lost:
            lines.append("written: the affine model (least squares, degree 1), not the MLP: the MLP "
                         f"validates worse beyond the fold noise on {' and '.join(self.lost)}")
        elif self.comparisons and all(c.within_noise for c in self.comparisons.values()):
            lines.append("the MLP is within the fold noise of the affine model: no evidence that it "
                         "predicts new load cases better (the MLP is written, as asked)")
        return lines

    def to_frame(self):
        """One row per grouped fold: the MLP's held-out score and affine least squares' (:attr:`metric`)."""
        import pandas as pd

        return pd.DataFrame({"mlp": list(self.fold_scores), "affine": list(self.affine_fold_scores)},
                            index=pd.RangeIndex(self.n_folds, name="fold"))

    def to_dict(self) -> dict:
        return plain({"label": self.label, "metric": self.metric, "iterations": self.iterations,
                      "max_iter": self.max_iter, "fold_scores": self.fold_scores,
                      "affine_fold_scores": self.affine_fold_scores, "lost": self.lost,
                      "against_affine": {name: {"margin": c.margin, "standard_error": c.standard_error,
                                                "n_folds": c.n_folds, "worse_beyond_noise": c.loses,
                                                "within_noise": c.within_noise}
                                         for name, c in self.comparisons.items()}})


@dataclass(frozen=True)
class MLPReport:
    """What the MLP family adds to the report: the network sized to the data, and its validation."""

    network: NetworkSize | None = None
    validation: MLPValidation | None = None

    def lines(self) -> list[str]:
        return ([self.network.line()] if self.network else []) + (self.validation.lines() if self.validation else [])

    def to_dict(self) -> dict:
        return {"network": plain(self.network),
                "validation": self.validation.to_dict() if self.validation else None}
