"""The public steps' arguments, checked at each step's entry: one table per step, one line per argument.

A wrong type or value is a :class:`~ftcal.runtime.errors.ParameterError` naming the argument by its
Python name (the CLI prints its flag), raised before any file is read, instead of a ``TypeError``
or ``AttributeError`` from deep inside. Only what no later check of the step covers is listed:
ranges the step checks itself (``degree``, ``folds``, ``max_degree``, ...) keep their own messages.
The checks are those of :mod:`ftcal.runtime.checks`, in its style.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping

from ..core.limits import (
    ARX_WARMUP,
    FREE_RUN_STARTS,
    NORMALIZATIONS,
    OBJECTIVES,
    PENALTIES,
    PLAN_OBJECTIVES,
    PREDICTION_MODES,
    SELECT_PER,
    SOLVERS,
)
from ..runtime.checks import check_choice, check_float, check_int, check_path
from ..runtime.errors import ParameterError

Check = Callable[[object, str, str], None]


def choice(options, optional: bool = False) -> Check:
    def check(value, name, owner):
        if optional and value is None:
            return
        if not isinstance(value, str):
            _refuse(name, owner, f"one of {', '.join(map(repr, options))}", value)
        check_choice(value, name, owner, tuple(options))
    return check


def whole(low: int, high: int | None = None, optional: bool = False) -> Check:
    def check(value, name, owner):
        if not (optional and value is None):
            check_int(value, name, owner, low, high)
    return check


def integer(value, name, owner) -> None:
    """An int of any value (the step checks the range itself, in its own words); bool is none."""
    if isinstance(value, bool) or not isinstance(value, int):
        _refuse(name, owner, "an int", value)


def number(low: float = 0.0, strict: bool = True, optional: bool = True) -> Check:
    """A finite real number above ``low`` (at least ``low`` when not ``strict``); bool is none."""
    def check(value, name, owner):
        if not (optional and value is None):
            check_float(value, name, owner, low, low_inclusive=not strict)
    return check


def path(optional: bool = False) -> Check:
    def check(value, name, owner):
        if not (optional and value is None):
            check_path(value, name, owner)
    return check


def flag(value, name, owner) -> None:
    if not isinstance(value, bool):
        _refuse(name, owner, "True or False", value)


def text(value, name, owner) -> None:
    """None or a non-empty str (a column, a frame, a scheduler address)."""
    if value is not None and (not isinstance(value, str) or not value):
        _refuse(name, owner, "None or a non-empty str", value)


def names(value, name, owner) -> None:
    """None or a list/tuple of distinct non-empty column names (a bare str is refused: it is not a list)."""
    if value is None:
        return
    if isinstance(value, str) or not isinstance(value, (list, tuple)) or not value \
            or not all(isinstance(v, str) and v for v in value):
        _refuse(name, owner, "a non-empty list of column names (str)", value)
    repeated = sorted({v for v in value if list(value).count(v) > 1})
    if repeated:
        raise ParameterError(name, f"The '{name}' parameter of {owner} names {', '.join(map(repr, repeated))} "
                                   "more than once; each column can be used once.")


def numbers(value, name, owner) -> None:
    """None or a non-empty list, tuple or 1-D array of finite real numbers (bool is none; the step checks their
    range)."""
    import math
    import numbers as kinds

    import numpy as np

    if value is None:
        return
    items = list(value) if isinstance(value, (list, tuple)) or (isinstance(value, np.ndarray) and value.ndim == 1) \
        else None
    if not items or not all(isinstance(v, kinds.Real) and not isinstance(v, (bool, np.bool_)) and math.isfinite(v)
                            for v in items):
        _refuse(name, owner, "None or a non-empty list of finite numbers", value)


def _real(value) -> bool:
    import math
    import numbers as kinds

    return isinstance(value, kinds.Real) and not isinstance(value, bool) and math.isfinite(value)


def texts(value, name, owner) -> None:
    """A list/tuple (maybe empty) of non-empty str: load specs, payload specs."""
    if isinstance(value, (str, bytes)) or not isinstance(value, (list, tuple)) \
            or not all(isinstance(v, str) and v for v in value):
        _refuse(name, owner, "a list of non-empty str", value)


def files(value, name, owner) -> None:
    """A list/tuple (maybe empty) of file names."""
    import os

    if isinstance(value, (str, bytes)) or not isinstance(value, (list, tuple)) \
            or not all(isinstance(v, (str, os.PathLike)) and os.fspath(v) for v in value):
        _refuse(name, owner, "a list of file names (str or Path)", value)


def joint_ranges(value, name, owner) -> None:
    """(joint, low, high) triples."""
    if not isinstance(value, (list, tuple)) or not all(
            isinstance(r, (list, tuple)) and len(r) == 3 and isinstance(r[0], str) and _real(r[1]) and _real(r[2])
            for r in value):
        _refuse(name, owner, "a list of (joint, low, high) with finite numbers", value)


def joint_values(value, name, owner) -> None:
    """A mapping joint -> value, or (joint, value) pairs."""
    items = list(value.items()) if isinstance(value, Mapping) else value
    if not isinstance(items, (list, tuple)) or not all(
            isinstance(p, (list, tuple)) and len(p) == 2 and isinstance(p[0], str) and _real(p[1]) for p in items):
        _refuse(name, owner, "a mapping of joint name to a finite number, or (joint, value) pairs", value)


def two_numbers(value, name, owner) -> None:
    """Two finite numbers >= 0 (force, torque)."""
    if not isinstance(value, (list, tuple)) or len(value) != 2 or not all(_real(v) and v >= 0 for v in value):
        _refuse(name, owner, "two finite numbers >= 0 (force, torque)", value)


def given_names(value, name, owner) -> None:
    """As :func:`names`, without None (a step whose default is a list of columns)."""
    if value is None:
        _refuse(name, owner, "a non-empty list of column names (str)", value)
    names(value, name, owner)


def penalties(value, name, owner) -> None:
    if isinstance(value, str) or not isinstance(value, (list, tuple)) or not all(v in PENALTIES for v in value):
        _refuse(name, owner, f"a list of penalties from {', '.join(map(repr, PENALTIES))}", value)


def _refuse(name: str, owner: str, what: str, value) -> None:
    shown = repr(value)
    shown = shown if len(shown) <= 60 else shown[:57] + "..."
    raise ParameterError(name, f"The '{name}' parameter of {owner} must be {what}. "
                               f"Got {type(value).__name__} {shown} instead.")


FIT = dict(inputs=names, outputs=names, lasso=number(), ridge=number(), na=whole(0), nb=whole(0),
           solver=choice(SOLVERS), normalization=choice(NORMALIZATIONS, optional=True), folds=integer,
           penalties=penalties, lambdas=numbers, select_per=choice(SELECT_PER),
           objective=choice(OBJECTIVES),
           max_degree=integer, budget=number(), verbose=flag, drop_incomplete=flag,
           family=choice(("polynomial", "mlp")), segment_by=text, group_by=text, scheduler=text)
EVALUATE = dict(mode=choice(PREDICTION_MODES), start=choice(FREE_RUN_STARTS), warmup=choice(ARX_WARMUP),
                segment_by=text, group_by=text, scheduler=text)
PREDICT = dict(mode=choice(PREDICTION_MODES), start=choice(FREE_RUN_STARTS), segment_by=text, scheduler=text)
PAYLOAD = dict(inputs=given_names, group_by=text, keep_moving=flag, reaction=flag, frame=text,
               temperature=text, output=path(optional=True))  # bias_drift: checked by the step in its own words
REBIAS = dict(inputs=given_names, keep_moving=flag, reaction=flag, temperature=text)
COMPENSATE = dict(payload=path(), inputs=names, calibration=path(optional=True), output=path(optional=True))
CHECK = dict(accept=path(optional=True), inputs=given_names, group_by=text, rate=number(), reaction=flag,
             max_com_distance=number(),
             max_force_error=number(), max_torque_error=number(), max_error_percent=number(), rated_force=number(),
             rated_torque=number(), serial=text)
PLAN = dict(poses=whole(1), objective=choice(PLAN_OBJECTIVES), degree=integer, candidates=whole(1),
            reference_every=whole(0), seed=whole(0, 2**32 - 1), robot=text, ft_joint=text, ft_frame=text,
            base=text, sensor=text, payload=texts, load=texts, joint_range=joint_ranges, fixed=joint_values,
            noise=two_numbers, recorded=files, output=path(optional=True), html=path(optional=True))
CONVERT = dict(model=path(), to=text, single_precision=flag, serial=text, sensor=text, name=text)


def check_arguments(spec: Mapping[str, Check], values: Mapping[str, object], owner: str) -> None:
    """Check the ``values`` of a step's arguments (its ``locals()`` at entry) against ``spec``."""
    for name, check in spec.items():
        check(values[name], name, owner)
