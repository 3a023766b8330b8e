"""ftcal: in-situ nonlinear calibration of six-axis strain-gauge F/T sensors."""

from importlib import import_module

from .errors import FtcalError, FtcalWarning

# The one place the version is declared (pyproject.toml reads it); reading it from the
# installed metadata instead costs ~30 ms of imports on every run.
__version__ = "0.1.0"

# Loaded on first use, so that `ftcal --help` does not pay for numpy and scipy.
_LAZY = {"CalibrationModel": "model", "Dataset": "dataset", "MonomialBasis": "features",
         "RegressorLayout": "features", "n_coefficients": "features"}

__all__ = ["CalibrationModel", "Dataset", "FtcalError", "FtcalWarning", "MonomialBasis",
           "RegressorLayout", "n_coefficients"]


def __getattr__(name: str):
    if name in _LAZY:
        return getattr(import_module(f".{_LAZY[name]}", __name__), name)
    raise AttributeError(f"module 'ftcal' has no attribute {name!r}")
