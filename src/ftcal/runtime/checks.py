"""Parameter checks with messages in one shared style."""

from __future__ import annotations

import numbers
import re

import numpy as np

from .errors import FtcalError, ParameterError


def check_int(value: object, name: str, owner: str, low: int, high: int | None = None) -> int:
    """Return ``value`` as an int in ``[low, high]`` or raise :class:`FtcalError`."""
    ok = isinstance(value, numbers.Integral) and not isinstance(value, bool)
    if ok and value >= low and (high is None or value <= high):
        return int(value)
    bound = f"[{low}, {high}]" if high is not None else f">= {low}"
    raise ParameterError(name,
        f"The '{name}' parameter of {owner} must be an int in {bound}. Got {value!r} instead."
    )


def check_float(value: object, name: str, owner: str, low: float = 0.0,
                low_inclusive: bool = True) -> float:
    """Return ``value`` as a finite float ``>= low`` (or ``> low``) or raise."""
    ok = isinstance(value, numbers.Real) and not isinstance(value, bool) and np.isfinite(value)
    if ok and (value >= low if low_inclusive else value > low):
        return float(value)
    op = ">=" if low_inclusive else ">"
    raise ParameterError(name,
        f"The '{name}' parameter of {owner} must be a finite number {op} {low}. Got {value!r} instead."
    )


def check_path(value: object, name: str, owner: str) -> None:
    """Refuse ``value`` unless it is a file name (str or os.PathLike), naming the parameter."""
    import os

    if not isinstance(value, (str, os.PathLike)) or not os.fspath(value):
        raise ParameterError(name, f"The '{name}' parameter of {owner} must be a file name (str or Path). "
                                   f"Got {type(value).__name__} {value!r:.60} instead.")


def check_choice(value: object, name: str, owner: str, choices: tuple[str, ...]) -> str:
    """Return ``value`` if it is one of ``choices`` or raise."""
    if value in choices:
        return str(value)
    raise ParameterError(name,
        f"The '{name}' parameter of {owner} must be one of {', '.join(map(repr, choices))}. "
        f"Got {value!r} instead."
    )


def check_finite_matrix(array: object, name: str, n_columns: int | None = None,
                        column_names: tuple[str, ...] | None = None) -> np.ndarray:
    """Return a 2-D float64 array, raising on wrong shape or NaN/inf cells.

    The message names the first bad column (by name when given) and row.
    """
    arr = np.asarray(array, dtype=np.float64)
    if arr.ndim == 1 and n_columns == 1:
        arr = arr[:, None]
    if arr.ndim != 2:
        raise FtcalError(f"{name} must be a 2-D array of shape (n_samples, n_columns); got shape {arr.shape}.")
    if n_columns is not None and arr.shape[1] != n_columns:
        raise FtcalError(f"{name} has {arr.shape[1]} columns; the model expects {n_columns}.")
    bad = ~np.isfinite(arr)
    if bad.any():
        row, col = np.argwhere(bad)[0]
        label = column_names[col] if column_names is not None else f"column {col}"
        raise FtcalError(
            f"{name}: {int(bad.sum())} non-finite value(s) (NaN or inf); first in {label!r} at row {row}."
        )
    return arr


_SAFE_NAME = re.compile(r"[A-Za-z0-9_\-][A-Za-z0-9_.\-]{0,63}")


def check_safe_name(value: str, parameter: str | None = None) -> str:
    """Return ``value`` if it can be part of a file name: 1-64 letters, digits, ``_ - .``, not starting with ``.``.

    Raises
    ------
    FtcalError
        Anything else (``/``, ``..``, spaces, control characters, an empty name); a
        :class:`ParameterError` naming ``parameter`` when it is given.
    """
    if isinstance(value, str) and _SAFE_NAME.fullmatch(value):
        return value
    why = f"{value!r}: use 1 to 64 letters, digits, '_', '-' or '.' (not first); it becomes part of a file name."
    raise ParameterError(parameter, f"{{{parameter}}} {why}") if parameter else FtcalError(why)
