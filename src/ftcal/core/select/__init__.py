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
stops after two degrees in a row that improve no output (or block) it selects for.
:func:`estimate_cost` predicts the work before it starts.

One module per job:

- ``candidates``: :class:`Candidate`, the default candidates and grids' reference λ (:func:`lasso_lambda_max`);
- ``folds``: grouped folds and the per-fold statistics of the data (:class:`GroupedStatistics`);
- ``scoring``: fold scores per output, block or model, margins over the affine model, the stable choice;
- ``result``: :class:`CrossValidationResult`, its tables and verdict;
- ``cost``: :func:`estimate_cost` and :class:`SearchBudget`;
- ``search``: the cross-validation loop (:func:`cross_validate`, :func:`select_model`);
- ``refit``: the selection fitted on all the data (:func:`fit_selection`, :func:`fit_best`, :func:`fit_candidates`);
- ``poses``: distinct poses and the saturation warning.
"""

from ..limits import PAPER_LAMBDAS
from .candidates import (AFFINE, DEFAULT_DEGREES, DEFAULT_PENALTIES, LASSO_DECADES, LASSO_POINTS, MAX_EXTENSIONS,
                         RIDGE_DECADES, RIDGE_POINTS, Candidate, default_candidates, lasso_lambda_max)
from .cost import (CANDIDATE_OVERHEAD, DENSE_CUBE, EVENT_OVERHEAD, EVENT_PER_COLUMN, FULL_PATH_EVENTS_PER_SQRT_P,
                   METRICS_PER_CELL, PASS_OVERHEAD, PATH_EVENTS_PER_SQRT_P, ROW_COST, SECONDS_PER_UNIT, CostEstimate,
                   SearchBudget, candidate_work, decomposition_work, estimate_cost, path_events, statistics_work)
from .folds import DatasetStatistics, GroupedStatistics, fold_of_groups, grouped_folds
from .poses import SaturationWarning, pose_cells, warn_if_saturated
from .refit import best_model, fit_best, fit_candidates, fit_selection
from .result import CrossValidationResult
from .scoring import TIE_TOLERANCE, UNITS, CandidateScore, Comparison, Part, Scorer, stable_choice, statistics_mse
from .search import SelectionLossWarning, _Search, cross_validate, select_model

__all__ = ["Candidate", "CostEstimate", "SearchBudget", "CrossValidationResult", "DatasetStatistics", "GroupedStatistics",
           "PAPER_LAMBDAS", "SaturationWarning", "SelectionLossWarning", "best_model", "cross_validate",
           "default_candidates", "estimate_cost", "fit_best", "fit_candidates", "fit_selection", "fold_of_groups",
           "grouped_folds", "pose_cells", "select_model", "warn_if_saturated"]
