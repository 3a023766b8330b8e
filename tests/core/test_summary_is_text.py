"""``summary()`` renders text everywhere in ftcal; the numbers are ``to_dict()`` (statsmodels' convention)."""

from __future__ import annotations

import ast
import warnings
from pathlib import Path

import numpy as np
import pytest

import ftcal
from ftcal.core import metrics
from ftcal.core.ranges import RangeSums

SRC = Path(ftcal.__file__).parent


def test_every_summary_method_returns_text():
    found, not_text = 0, []
    for path in sorted(SRC.rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.FunctionDef) and node.name == "summary":
                doc = ast.get_docstring(node) or ""
                if doc.startswith("Deprecated"):
                    continue  # the old name of a to_dict, kept one release
                found += 1
                if ast.unparse(node.returns) != "str" if node.returns is not None else True:
                    not_text.append(f"{path.relative_to(SRC)}:{node.lineno}")
    assert found >= 10 and not_text == [], not_text


def test_the_numbers_moved_to_to_dict_and_the_old_name_warns():
    y = np.array([[1.0], [2.0], [4.0]])
    sums = metrics.ErrorSums.of(y, np.zeros_like(y), ["a"])
    with pytest.warns(DeprecationWarning, match="use ErrorSums.to_dict"):
        old = sums.summary(["a"])
    assert old == sums.to_dict(["a"]) and sums.to_dict(["a"])["max_abs_error"] == [4.0]  # |4 - 0|
    ranges = RangeSums.of(np.array([[0.5], [3.0]]), np.array([[0.0, 1.0]]))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        counted = ranges.to_dict(["u1"])
    with pytest.warns(DeprecationWarning, match="use RangeSums.to_dict"):
        assert ranges.summary(["u1"]) == counted
