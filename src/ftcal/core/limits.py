"""Limits and vocabularies of the calibration model, declared once.

The library's parameter checks, the CLI's help and choices and the model-file
schema (``schemas/model-1.json``, checked against this table by the tests) all
read these names. The module imports nothing heavy, so ``ftcal --help`` can use it.
"""

from __future__ import annotations

MAX_DEGREE = 10
"""Highest polynomial degree np (degree 5 over 7 inputs is already 792 terms per output)."""

MAX_LAG = 50
"""Highest ARX order na (past outputs) and nb (input lags)."""

NORMALIZATIONS = ("center", "maxabs")
"""Input bases. ``maxabs`` (u / max|u|) with max-abs column scaling is the paper's basis;
``center`` maps each input's range onto [-1, 1], which keeps high degrees well conditioned."""

PENALTIES = ("none", "ridge", "lasso")
"""Penalty kinds: least squares, ½λ‖θ‖² (ridge) and λ‖θ‖₁ (LASSO), on max-abs scaled columns."""

SOLVERS = ("lstsq", "osqp")
"""``lstsq``: ftcal's streaming exact solvers; ``osqp``: the paper's QPs on the dense regressor."""

PREDICTION_MODES = ("one-step", "free-run")
"""ARX prediction: measured past outputs (the paper's evaluation, default) or fed-back predictions."""

FREE_RUN_STARTS = ("zeros", "measured")
"""Free-run history before the first sample: zeros (the paper's code) or the first measured output."""

ARX_WARMUP = ("drop", "keep")
"""Metrics over ARX predictions: drop the first max(na, nb) rows of each segment (the paper's code) or keep them."""

PAPER_LAMBDAS = (0.5, 1.0, 10.0, 50.0, 100.0, 200.0)
"""The LASSO weights of the paper's Table III."""

SELECT_PER = ("output", "block", "model")
"""What ``--degree auto`` selects a degree, penalty and λ for: each output, the force and the torque
blocks, or one model for all outputs."""

OBJECTIVES = ("both", "force", "torque")
"""What ranks candidates that serve several outputs: force and torque (each relative to the affine
model, averaged), or one block alone."""

SELECTION_BUDGET_SECONDS = 20.0
"""Default ``--budget``: degrees whose estimated cost would exceed it are not tried (the search says so)."""

SELECTION_MEMORY_BYTES = 1_000_000_000
"""Degrees whose estimated peak memory (statistics and eigen-decompositions held per fold) exceeds this are
not tried."""

SATURATION_RATIO = 0.5
"""Least-squares fits warn when coefficients per output exceed this fraction of the distinct poses."""

POSE_BINS = 20
"""Distinct poses are counted as occupied cells of a grid with this many bins per input over its range
(5 % of the range: a static load case with its noise is one cell, a sweep one cell per 5 % step)."""
