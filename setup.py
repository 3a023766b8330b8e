"""Build script for the one compiled part of ftcal: the kernels of static polynomial models.

Everything else is declared in pyproject.toml. The extension is optional: on a
machine without a C compiler the build skips it and ftcal uses its numpy paths
(same results; statistics about three times slower). See src/ftcal/core/kernels.py.
"""

from setuptools import Extension, setup

setup(ext_modules=[Extension("ftcal.core._polynomial", ["src/ftcal/core/_polynomial.c"], optional=True)])
