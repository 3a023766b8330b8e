"""Exceptions and warnings that users are meant to see.

The CLI turns :class:`FtcalError` into one line on stderr and exit code 2, so
every message must name the file, column or parameter at fault and say what is
wrong with it.
"""

from __future__ import annotations


class FtcalError(ValueError):
    """Bad input or an impossible request, explained in one sentence."""


class NotFittedError(FtcalError):
    """A model method that needs fitted state was called before ``fit``."""


class FtcalWarning(UserWarning):
    """Something the user should know about, that does not stop the work."""


class IllPosedFitWarning(FtcalWarning):
    """The fit is rank-deficient, ill-conditioned or under-determined."""


class UndeterminedWarning(IllPosedFitWarning):
    """The data determine only some parameters; the others are held at a stated default and reported undetermined."""


class OutOfRangeWarning(FtcalWarning):
    """Prediction inputs fall outside the range seen during training."""


class PrecisionLossWarning(FtcalWarning):
    """Converting a model to raw-input monomials lost significant digits."""
