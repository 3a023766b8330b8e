"""What a search costs before it starts (:func:`estimate_cost`) and a CPU budget kept while it runs.

Work is counted in units of about 1e-10 s: statistics passes (rows × moments, or Gram
cells for ARX) and solves (dense factorizations, LASSO path events, scoring), each
with a per-call overhead, converted to seconds by :data:`SECONDS_PER_UNIT`.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from ..features import MonomialBasis, RegressorLayout
from ..statistics import moment_plan
from .candidates import DEFAULT_PENALTIES, LASSO_POINTS, RIDGE_POINTS
from .scoring import nested_folds


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
                  nb: int = 0, n_bases: int | None = None, spent_seconds: float = 0.0,
                  n_groups: int | None = None) -> CostEstimate:
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
    n_groups : int, optional
        Groups (load cases) in the data: with few a fold (:func:`~.scoring.nested_folds`) every candidate is
        also solved on each pair of folds' complement, K(K − 1)/2 fits more (nested cross-validation).

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
    # Training sets per degree: one per fold, and one per pair of folds under nested cross-validation.
    trainings = n_folds + (n_folds * (n_folds - 1) // 2 if nested_folds(n_folds, n_groups) else 0)
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
        solve *= trainings
        units.append((stats, solve))
        seconds.append(stats * SECONDS_PER_UNIT["statistics"] + solve * SECONDS_PER_UNIT["solve"])
        # The refit of the selection (one more candidate of each kind on all the data) and the metrics pass.
        refit = solve / trainings / per_degree * (1 + len(penalties))
        finals.append(refit * SECONDS_PER_UNIT["solve"]
                      + (rows * p * n_outputs * METRICS_PER_CELL + rows * ROW_COST) * SECONDS_PER_UNIT["statistics"])
        # Kept: each fold's statistics per basis; while scored: training sums and scaled problems per basis
        # and fold, and the eigenvectors.
        kept += n_bases * n_folds * p * p * 8.0
        peaks.append(kept + (2 * n_bases + 1) * trainings * p * p * 8.0)
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
