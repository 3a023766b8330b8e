"""The mathematics of calibration, free of files and user interface.

Owns the :class:`~ftcal.core.dataset.Dataset`, the monomial bases and ARX layouts
(``features``), normalization, the streamed sufficient statistics and their compiled
kernels, the solvers, the model families (``families``, ``model``), conversion to the
paper's raw basis, metrics, model selection, grouped-jackknife standard errors
(``jackknife``) and every declared limit (``limits``).
May import :mod:`ftcal.runtime` only. Nothing heavy is imported by this package itself,
so ``ftcal --help`` can read ``limits`` and ``columns`` cheaply.
"""
