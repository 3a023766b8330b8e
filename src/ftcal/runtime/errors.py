"""Exceptions and warnings that users are meant to see.

The CLI turns :class:`FtcalError` into one line on stderr and exit code 2, so
every message must name the file, column or parameter at fault and say what is
wrong with it.
"""

from __future__ import annotations


class FtcalError(ValueError):
    """Bad input or an impossible request, explained in one sentence.

    Examples
    --------
    >>> from ftcal import CalibrationModel, FtcalError
    >>> try:
    ...     CalibrationModel(degree=0).fit([[0.0], [1.0]], [[0.0], [1.0]])
    ... except FtcalError as error:
    ...     print("refused:", "degree" in str(error))
    refused: True
    """


class NotFittedError(FtcalError):
    """A model method that needs fitted state was called before ``fit``."""


class FtcalWarning(UserWarning):
    """Something the user should know about, that does not stop the work.

    Examples
    --------
    >>> import warnings
    >>> import numpy as np
    >>> from ftcal import CalibrationModel, FtcalWarning
    >>> model = CalibrationModel(1).fit(np.array([[0.0], [1.0], [2.0]]), np.array([[0.0], [2.0], [4.0]]))
    >>> with warnings.catch_warnings(record=True) as caught:
    ...     warnings.simplefilter("always")
    ...     _ = model.predict(np.array([[5.0]]))  # outside the training range
    >>> any(issubclass(w.category, FtcalWarning) for w in caught)
    True
    """


class IllPosedFitWarning(FtcalWarning):
    """The fit is rank-deficient, ill-conditioned or under-determined."""


class UndeterminedWarning(IllPosedFitWarning):
    """The data determine only some parameters; the others are held at a stated default and reported undetermined."""


class OutOfRangeWarning(FtcalWarning):
    """Prediction inputs fall outside the range seen during training."""


class PrecisionLossWarning(FtcalWarning):
    """Converting a model to raw-input monomials lost significant digits."""


class OldSpellingWarning(FutureWarning):
    """An old spelling (a keyword, a flag, a file key or column) was read under its new name.

    A ``FutureWarning``, so Python shows it by default; the CLI prints it as one ``notice:`` line.
    """


def old_spelling(old: str, new: str, stacklevel: int = 3) -> None:
    """Say once that ``old`` was read as ``new`` (the one name of that idea today).

    Parameters
    ----------
    old, new : str, how the input spelled it and the name to use instead
    stacklevel : int, passed to :func:`warnings.warn` (3: the caller of the function that checks)

    Examples
    --------
    >>> import warnings
    >>> with warnings.catch_warnings(record=True) as caught:
    ...     warnings.simplefilter("always")
    ...     old_spelling("wrench=", "inputs=")
    >>> str(caught[0].message)
    'wrench= is now inputs= (the old spelling still works)'
    """
    import warnings

    warnings.warn(f"{old} is now {new} (the old spelling still works)", OldSpellingWarning, stacklevel=stacklevel)


def renamed_keyword(keywords: dict, old: str, new: str, value, default=None, stacklevel: int = 4):
    """``value`` of the keyword ``new``, or the one given under its old name ``old`` (popped from ``keywords``).

    Parameters
    ----------
    keywords : dict, the function's ``**kwargs``; ``old`` is removed from it
    old, new : str, the old and the current keyword names
    value : the value given as ``new``
    default : ``new``'s default (``value`` is that when ``new`` was not given)
    stacklevel : int, where the warning points (4: the caller of the function that calls this)

    Returns
    -------
    the value to use

    Raises
    ------
    FtcalError
        when both spellings are given

    Examples
    --------
    >>> import warnings
    >>> with warnings.catch_warnings():
    ...     warnings.simplefilter("ignore", OldSpellingWarning)
    ...     renamed_keyword({"wrench": ("Fx",)}, "wrench", "inputs", None)
    ('Fx',)
    """
    if old not in keywords:
        return value
    given = keywords.pop(old)
    if value is not default and value != default:
        raise FtcalError(f"{new}: given twice (also as {old}, its old spelling); give it once.")
    old_spelling(f"{old}=", f"{new}=", stacklevel=stacklevel)
    return given


def single_line(text: str) -> str:
    """``text`` with line breaks and tabs written as escapes: a name from a file (a bag topic, a column,
    a model's input) cannot start a line of its own in the output and forge it.

    Examples
    --------
    >>> single_line("topic\\nwrote model.json")
    'topic\\\\nwrote model.json'
    """
    import re

    return re.sub("[\t\n\x0b\x0c\r\x1c-\x1e\x85\u2028\u2029]",
                  lambda m: m.group(0).encode("unicode_escape").decode("ascii"), str(text))
