"""What every step returns: a result that explains itself in text, JSON, a repr and HTML."""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path
from typing import Any


def plain(value: Any) -> Any:
    """``value`` as JSON-ready Python: arrays to lists, paths to strings, results to dicts.

    Non-finite floats become ``None`` so that the JSON stays valid (and says "no value").

    Examples
    --------
    >>> import numpy as np
    >>> plain({"a": np.array([1.0, np.nan]), "b": (np.int64(2),)})
    {'a': [1.0, None], 'b': [2]}
    """
    if isinstance(value, StepResult):
        return value.to_dict()
    # A module not imported yet holds no value (``ftcal info`` imports neither numpy nor dataclasses).
    dataclasses, np = sys.modules.get("dataclasses"), sys.modules.get("numpy")
    if dataclasses is not None and dataclasses.is_dataclass(value) and not isinstance(value, type):
        return _fields(value)
    if isinstance(value, dict):
        return {str(k): plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple, set, frozenset)):
        return [plain(v) for v in value]
    if np is not None and isinstance(value, np.ndarray):
        return plain(value.tolist())
    if np is not None and isinstance(value, np.generic):
        return plain(value.item())
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, Path):
        return str(value)
    if value is None or isinstance(value, (bool, int, str)):
        return value
    return repr(value)


def _fields(value: Any) -> dict:
    import dataclasses

    return {f.name: plain(getattr(value, f.name)) for f in dataclasses.fields(value)
            if not f.name.startswith("_")}


class StepResult:
    """Base of every step's result.

    A subclass (usually a dataclass) implements :meth:`summary`, the text the CLI prints.
    :meth:`to_dict` lists the public dataclass fields by default; a subclass overrides it when
    its JSON should hold something else (for example the JSON the CLI writes with ``--json``).

    Examples
    --------
    >>> from dataclasses import dataclass
    >>> @dataclass(repr=False)
    ... class Mass(StepResult):
    ...     mass: float
    ...     def summary(self) -> str:
    ...         return f"mass {self.mass:.3f} kg"
    >>> Mass(1.25)
    <Mass: mass 1.250 kg>
    >>> Mass(1.25).to_dict()
    {'mass': 1.25}
    """

    def summary(self) -> str:
        """The text the CLI prints for this result."""
        raise NotImplementedError

    def to_dict(self) -> dict:
        """The result as JSON-ready Python (finite floats, lists, strings; ``None`` for no value)."""
        dataclasses = sys.modules.get("dataclasses")
        if dataclasses is not None and dataclasses.is_dataclass(self):
            return _fields(self)
        raise NotImplementedError(f"{type(self).__name__} must define to_dict()")

    def to_json(self, indent: int | None = 2) -> str:
        """The result as JSON text (:meth:`to_dict`), ``allow_nan`` off so it is always valid."""
        return json.dumps(self.to_dict(), indent=indent, allow_nan=False)

    def __str__(self) -> str:
        return self.summary()

    def headline(self) -> str:
        """One line that says what the result is (the ``repr``); the summary's first line unless a step says better."""
        lines = self.summary().strip().splitlines()
        return lines[0] if lines else ""

    def __repr__(self) -> str:
        n_lines = len(self.summary().strip().splitlines())
        more = f" (+{n_lines - 1} lines: print() it)" if n_lines > 1 else ""
        return f"<{type(self).__name__}: {self.headline()}{more}>"

    def _repr_html_(self) -> str:
        import html

        return f"<pre>{html.escape(self.summary())}</pre>"
