"""The precision of what ftcal prints and stores: the same text and files on every CPU.

BLAS kernels (OpenBLAS picks them by CPU), thread counts and the order of a sum change every
floating-point result in its last bits, and a rank-deficient or near-zero result by far more: a
singular value that is zero in exact arithmetic comes out as 6.5e-09 on one machine and 0 on
another, a component that should be 0 as ±1e-17. So every result ftcal prints or stores as a
result goes through one rule, :func:`settle`:

**A number is stated to a precision relative to its scale** (the largest magnitude of the vector
it is a component of, or a scale the caller names: the largest singular value, the load's size).
**It is rounded to the power of ten nearest to precision × scale, so a component below half that
step is exactly 0** (never −0, never a residue like 6.5e-09). The precision is what the computation
can promise (the named constants below), far coarser than the machines' differences and far finer
than the figures printed, so the text and the files are the same wherever they were computed.
"""

from __future__ import annotations

import math

import numpy as np

SPECTRUM = 1e-5
"""Relative singular values taken from the eigenvalues of a Gram or covariance matrix (the square root
halves the digits: a Gram summed over 10⁶ samples to ~1e-10 gives singular values to ~1e-5 of the largest)."""

DIRECTION = 1e-6
"""Components of a unit direction (an eigenvector, a null-space vector): as :data:`ftcal.core.directions.CANONICAL_TIE`."""

SCORE = 1e-6
"""Figures taken from sums of squares that cancel (θᵀGθ − 2θᵀc + ‖y‖²): cross-validated scores and their
differences relative to the largest score compared, residual RMS relative to the readings' RMS (a residual
1e-4 of the signal keeps ~1e-8 of its mean square; its square root ~1e-7 of the readings)."""

MEAN_SQUARE = SCORE ** 2
"""A mean squared error relative to the mean square of the readings it is an error of (the square of
:data:`SCORE`): θᵀGθ − 2θᵀc + ‖y‖² cancels to ~1e-16 × ‖y‖² × the conditioning, so a fit that is exact in
exact arithmetic (noiseless readings) scores 0 on every CPU, and candidates tied to rounding go to the
simpler model."""

SOLUTION = 1e-9
"""Least-squares results, residuals and figures derived from them, relative to their vector's scale
(conditioning of the fits ftcal accepts stays below 1e6: 1e-16 × 1e6 × margin)."""


def settle(values, precision: float, scale: float | None = None):
    """``values`` rounded to ``precision`` of ``scale``; below half a step, exactly 0.

    Parameters
    ----------
    values : float or array_like
    precision : float, relative to ``scale`` (e.g. :data:`SPECTRUM`)
    scale : float or None
        The size the precision is relative to; None: the largest finite magnitude in ``values``.

    Returns
    -------
    float or ndarray, as ``values`` (a Python float for a scalar); NaN and infinities unchanged.

    Examples
    --------
    >>> settle([1.0, 0.92, 0.38, 6.5e-09], SPECTRUM).tolist()
    [1.0, 0.92, 0.38, 0.0]
    >>> settle([0.7071067811865476, -1e-17, -0.7071067811865475], DIRECTION).tolist()
    [0.707107, 0.0, -0.707107]
    """
    array = np.asarray(values, dtype=np.float64)
    finite = np.isfinite(array)
    if scale is None:
        scale = float(np.abs(array[finite]).max(initial=0.0))
    step = abs(float(scale)) * precision
    if not math.isfinite(step) or step <= 0.0:
        out = np.where(finite, 0.0, array)
    else:
        # The power of ten nearest to the step (half-decades are the boundary: a scale that sits on a
        # power of ten, such as a largest relative singular value of 1, never flips between two grids).
        decimals = -round(math.log10(step))
        with np.errstate(invalid="ignore", over="ignore"):
            rounded = np.round(array, decimals) if decimals >= 0 else np.round(array / 10.0 ** -decimals) * 10.0 ** -decimals
        out = np.where(finite, rounded + 0.0, array)  # + 0.0 turns −0 into 0
    return float(out) if out.ndim == 0 else out
