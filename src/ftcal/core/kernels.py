"""Which kernels compute static polynomial models: compiled, or numpy.

``_polynomial.c`` is built at install where a C compiler is available
(``setup.py``; optional). It fuses what numpy does in many calls: the
statistics of a fit (:class:`ftcal.core.statistics.MomentPlan`) and predictions
(:class:`ftcal.core.features.FeatureCombination`). Without it, or inside
:func:`use_numpy_kernel`, the numpy code computes the same values up to
rounding.
"""

from __future__ import annotations

from contextlib import contextmanager
from functools import cache
from types import ModuleType

import numpy as np

try:
    from . import _polynomial
except ImportError:  # pragma: no cover - depends on the machine that installed ftcal
    _polynomial = None

_numpy_only = False  # set inside use_numpy_kernel()


def compiled_kernel_available() -> bool:
    """Whether the compiled kernels were built at install.

    Returns
    -------
    bool
    """
    return _polynomial is not None


def compiled() -> ModuleType | None:
    """The compiled kernels to use now, or None for the numpy paths.

    Returns
    -------
    module ``ftcal.core._polynomial`` or None
    """
    return None if _numpy_only else _polynomial


@contextmanager
def use_numpy_kernel():
    """Use the numpy paths inside the block, even where the compiled kernels exist (for comparisons).

    Examples
    --------
    >>> with use_numpy_kernel():
    ...     compiled() is None
    True
    """
    global _numpy_only
    previous, _numpy_only = _numpy_only, True
    try:
        yield
    finally:
        _numpy_only = previous


@cache
def step_table(n_inputs: int, degree: int) -> np.ndarray:
    """The evaluation of ``MonomialBasis(n_inputs, degree)`` as the compiled kernels read it.

    Returns
    -------
    ndarray of int64, shape (n_steps, 4)
        Per step: input i, source row, destination row, rows; row destination + r
        is row source + r times input i (rows 0..n_inputs-1 are the inputs).
    """
    from .features import MonomialBasis

    steps = MonomialBasis(n_inputs, degree)._evaluator._steps
    return np.array([(i, src.start, dst.start, src.stop - src.start) for i, src, dst in steps],
                    dtype=np.int64).reshape(-1, 4)
