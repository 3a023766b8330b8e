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

# --- Limits on what a file may make ftcal do (docs/security.md lists each with its reason). ---
# ftcal trusts its command line, not the files it reads: every reader checks what a file declares
# against these before it allocates or loops.

MAX_MODEL_BYTES = 100 * 10**6
"""Largest model or payload file (JSON or paper XML): degree 10 over 7 inputs is ~2 MB of text."""

MAX_TEXT_FILE_BYTES = 50 * 10**6
"""Largest URDF, TOML load-case file or other text configuration read whole into memory."""

MAX_TABLE_COLUMNS = 10_000
"""Most columns in a CSV or Parquet table (a calibration table has tens; a malformed header can claim millions)."""

MAX_HEADER_BYTES = 10**6
"""Longest CSV header line read to learn the column names."""

MAX_DECLARED_ELEMENTS = 2 * 10**9
"""Most numbers one array in a .mat log may declare (16 GB of float64); checked before reading it."""

MAX_NESTING = 32
"""Deepest nesting of groups in a .mat (HDF5) log: the logger's structs are a few levels deep; deeper
means a hostile file or a link loop. (JSON and XML nesting is bounded by the parsers' recursion
limit, caught as a one-line refusal.)"""

MAX_GRAM_BYTES = 4 * 10**9
"""Largest Gram matrix of a fit (p² doubles for p regressor columns per output), checked before it is
allocated: degree 10 over 7 inputs (19,448 columns, 3.0 GB) fits; ARX na = nb = 50 at degree 5
(40,642 columns, 13 GB, and a fit holds a few copies) does not."""

MAX_OPTION_MAGNITUDE = 1e12
"""Largest magnitude of a number option (--g, --gravity, --lasso, --payload-mass, ...): physical values
are far smaller, and values near 1e308 overflow the first product they meet."""

MAX_CELL_MAGNITUDE = 1e100
"""Largest magnitude of a number in a table: sums of squares and products of such values still fit in
float64 (about 1e308); larger ones are corrupt data, and would make fits overflow into NaN."""
