"""Build script for the one compiled part of ftcal: the statistics kernel.

Everything else is declared in pyproject.toml. The extension is optional: on a
machine without a C compiler the build skips it and ftcal uses its numpy path
(same results, about three times slower statistics).
"""

from setuptools import Extension, setup

setup(ext_modules=[Extension("ftcal._moments", ["src/ftcal/_moments.c"], optional=True)])
