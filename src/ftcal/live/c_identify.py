"""Identification in place in the C core (``csrc/ftcal_live.h``, its identification sections): the constants.

The C (hand-written in ``csrc/ftcal_live.h``) of :meth:`ftcal.live.LiveCalibrator.start_identification` / ``finish_identification``: while
identifying, each static hold's moments ``Σ z zᵀ`` of ``z = (g, 1, w)`` (gravity in sensor axes, the
calibrated wrench) go into a fixed array of :data:`~ftcal.core.limits.C_RUNTIME_MAX_HOLDS` holds; the
bias filter and the contact and unexplained flags pause, as in Python. ``NAME_finish_identification``
then runs what :func:`ftcal.payload.identify.identify_from_statistics` runs for that call (static parameters
θ = [m, m·c, force bias, torque bias], ``weighting="auto"``, the holds as clusters, no
cross-validation), on fixed-size 10 × 10 matrices:

- the rank test of :func:`~ftcal.payload.identify.find_undetermined` (eigenvalues of the equilibrated
  Gram by cyclic Jacobi, the same threshold and floor): the mass undetermined is refused as in Python;
  other undetermined parameters are named in a bit mask, and as many as the null space has dimensions
  are held at zero in Python's order (``_choose_held``: COM first, then torque, then force biases,
  largest pivot), the others estimated on the remaining columns; their standard errors are NaN;
- OLS or per-axis WLS chosen by held-out error over the holds (``_choose_weighting``), the refits
  with ``_refit``'s condition-number test (1e12);
- the grouped-jackknife covariance over the holds, t-scaled (``robust_covariance``), else the
  classical one; variance inflation factors; the COM's standard error by the delta method.

Every number of the method (thresholds, the t quantiles, the regressor's maps) reaches the C as configuration
data from the Python constants it mirrors (:func:`identify_config`); nothing from a file reaches this C.
"""

from __future__ import annotations

import math

import numpy as np

from ..core.directions import CANONICAL_TIE
from ..core.jackknife import t_scale
from ..payload.accumulate import _static_maps
from ..payload.identify import _REFIT_CONDITION, EXCITATION_LIMIT, NULL_ROW, ROUNDING_COLUMN, WEIGHTING_TIE
from ..runtime.errors import FtcalError

# find_undetermined's null-eigenvalue threshold, relative to the largest (Spectrum.rank_threshold for p = 10).
RANK_RELATIVE = float(np.finfo(float).eps * max(10, 10) * 10)

# Status codes of NAME_finish_identification (the C's #defines; tests and docs read them here).
STATUS = {"OK": 0, "NOT_IDENTIFYING": -1, "TOO_FEW_HOLDS": -2, "MASS_UNDETERMINED": -3, "SINGULAR": -4}
# Return codes of the tool library (NAME_start_identification, NAME_adopt_identification), NAME_TOOL_* in the C.
TOOL_STATUS = {"OK": 0, "NO_NAME": -5, "NAME_TOO_LONG": -6, "NAME_RESERVED": -7, "LIBRARY_FULL": -8}


def _num(x: float) -> str:
    """A double literal that round-trips; infinities as ``HUGE_VAL``."""
    x = float(x)
    if math.isnan(x):
        raise FtcalError("the model has a NaN where a number is needed; refusing to generate code.")
    if math.isinf(x):
        return "HUGE_VAL" if x > 0 else "(-HUGE_VAL)"
    text = format(x, ".17g")
    return text if any(ch in text for ch in ".en") else text + ".0"


def _array(values) -> str:
    return "{" + ", ".join(_num(v) for v in np.ravel(values)) + "}"


def identify_config(max_holds: int) -> dict:
    """The configuration fields of the identification in place (``FTL_(config)``), from the Python it mirrors.

    Parameters
    ----------
    max_holds : the holds an identification keeps (``NAME_MAX_HOLDS``)

    Returns
    -------
    dict field → float or ndarray
    """
    return {"rank_relative": RANK_RELATIVE, "rounding_column": ROUNDING_COLUMN, "null_row": NULL_ROW,
            "canonical_tie": CANONICAL_TIE, "weighting_tie": WEIGHTING_TIE, "refit_condition": _REFIT_CONDITION,
            "excitation_limit": EXCITATION_LIMIT,
            "id_maps": np.asarray(_static_maps(), float),  # (6, 10, 4): axis i's row is maps[i] @ (g, 1)
            "t_scale": np.array([0.0, *(t_scale(d) for d in range(1, max_holds))])}


def status_macros(macro: str) -> str:
    """``#define``s of the identification's and the tool library's status codes."""
    return "\n".join([*(f"#define {macro}_ID_{key} ({value})" for key, value in STATUS.items()),
                      *(f"#define {macro}_TOOL_{key} ({value})" for key, value in TOOL_STATUS.items())])
