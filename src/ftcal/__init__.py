"""ftcal: in-situ nonlinear calibration of six-axis strain-gauge F/T sensors."""

from .dataset import Dataset
from .errors import FtcalError, FtcalWarning

__all__ = ["Dataset", "FtcalError", "FtcalWarning"]
