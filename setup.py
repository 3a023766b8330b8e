"""Build script for ftcal's compiled parts: the kernels of static polynomial models and the live step's C core.

Everything else is declared in pyproject.toml. Both extensions are optional: on a machine without a C compiler
the build skips them; ftcal then uses its numpy paths for the kernels (same results; statistics about three
times slower, see src/ftcal/core/kernels.py), and ftcal.live.core says how to build the live core
(src/ftcal/live/_core.c around src/ftcal/live/csrc/ftcal_live.h, the source `convert --to c-runtime` ships).
"""

from setuptools import Extension, setup

CORE_HEADERS = ["src/ftcal/live/csrc/ftcal_live.h", "src/ftcal/live/csrc/ftcal_live_selfcheck.h"]

setup(ext_modules=[
    Extension("ftcal.core._polynomial", ["src/ftcal/core/_polynomial.c"], optional=True),
    Extension("ftcal.live._core", ["src/ftcal/live/_core.c"], include_dirs=["src/ftcal/live/csrc"],
              depends=CORE_HEADERS, optional=True),
])
