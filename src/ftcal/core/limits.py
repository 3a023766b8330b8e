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

PAYLOAD_WEIGHTINGS = ("auto", "ols", "wls")
"""Payload fits: per-axis weighting chosen by held-out evidence, plain least squares, or per-axis 1/σ²."""

BIAS_DRIFTS = ("none", "linear", "random-walk", "auto")
"""Bias over a payload recording: constant, affine in time, a random walk (state-space model), or chosen
by evidence (BIC, the simpler model unless the evidence is strong)."""

ROBUST_CLUSTERS = 20
"""Contiguous time blocks of a payload recording for cluster-robust standard errors and held-out folds."""

DRIFT_BLOCKS = 1000
"""Most time blocks (equal sample counts) the random-walk bias model is fitted on."""

DRIFT_BLOCK_SECONDS = 1.0
"""Shortest time block of the random-walk bias model, s: faster wandering is noise, slower is drift."""
