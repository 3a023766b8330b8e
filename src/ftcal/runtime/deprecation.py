"""Old names kept working: renamed public functions, keywords, flags, file keys and columns.

One name per idea: when a public function is renamed, its old name stays one release as a shim
made by :func:`deprecated_alias` (a ``DeprecationWarning``, for programmers). An old spelling in
what a user writes (a keyword, a flag, a TOML key, a column) is read under its new name with one
:class:`OldSpellingWarning` (a ``FutureWarning``, shown by default; the CLI prints it as one
``notice:`` line).
"""

from __future__ import annotations

import functools
import warnings
from collections.abc import Callable
from importlib import import_module
from typing import Any

from .errors import FtcalError

# The release in which the shims made today disappear (ftcal keeps an old name one release).
REMOVED_IN = "0.2.0"


def deprecated_alias(target: Callable | str, old: str, new: str) -> Callable:
    """A function named ``old`` that warns (:class:`DeprecationWarning` naming ``new``) and calls ``target``.

    Parameters
    ----------
    target : callable, or ``"module:attribute"`` resolved on the first call (a shim in a module
        that the new function's module imports, without an import circle)
    old : the old public name, as users spell it (``ftcal.files.model_files.read_model``)
    new : the name to use instead (``ftcal.load_model``)

    Returns
    -------
    callable
        Same arguments and result as ``target``.

    Examples
    --------
    >>> import warnings
    >>> double = deprecated_alias(lambda x: 2 * x, "ftcal.twice", "ftcal.double")
    >>> with warnings.catch_warnings(record=True) as caught:
    ...     warnings.simplefilter("always")
    ...     double(21)
    42
    >>> str(caught[0].message)
    'ftcal.twice is deprecated and will be removed in ftcal 0.2.0; use ftcal.double.'
    """
    message = f"{old} is deprecated and will be removed in ftcal {REMOVED_IN}; use {new}."

    def resolve() -> Callable:
        if callable(target):
            return target
        module, attribute = target.split(":")
        return getattr(import_module(module), attribute)

    def shim(*args: Any, **kwargs: Any):
        warnings.warn(message, DeprecationWarning, stacklevel=2)
        return resolve()(*args, **kwargs)

    if callable(target):
        functools.update_wrapper(shim, target)
    shim.__name__ = shim.__qualname__ = old.rsplit(".", 1)[-1]
    shim.__doc__ = f"Deprecated: {message}"
    shim.deprecated_for = new  # the name the shim points to (the public-API tests read it)
    return shim


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
