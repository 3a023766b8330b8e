"""Old public names kept for one release: each call warns once per call site, naming the new name.

One name per idea: when a public function is renamed, its old name stays one release as a shim
made by :func:`deprecated_alias`, so that existing scripts keep running and say what to change.
"""

from __future__ import annotations

import functools
import warnings
from collections.abc import Callable
from importlib import import_module
from typing import Any

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
