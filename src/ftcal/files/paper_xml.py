"""The paper's model XML (docs/formats.md §1): raw-input coefficients, one ``rowK`` per regressor column.

Writing converts the model to raw-input monomials (:func:`ftcal.core.conversion.to_raw`)
and warns when that loses precision; every float is written with ``repr``.
Reading accepts any white space and float spelling (Fortran ``1.5D+03``
included) and returns a model that evaluates the raw monomials directly
(identity normalization, unbounded training ranges since the file has none).
"""

from __future__ import annotations

import re
import xml.etree.ElementTree as ET
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from ..core.conversion import from_raw, precision_loss, to_raw_finite
from ..core.dataset import DEFAULT_INPUTS, DEFAULT_OUTPUTS, default_names
from ..core.features import MAX_DEGREE, n_coefficients
from ..core.limits import MAX_LAG, MAX_MODEL_BYTES
from ..core.model import CalibrationModel
from ..runtime.atomic import write_text_atomic
from ..runtime.errors import FtcalError
from ..runtime.inputs import check_input_file

GROUP_NAME = "modelClassParams"
# (name, lowest, highest) of the integer parameters every file must have.
INT_PARAMS = (("np", 1, MAX_DEGREE), ("ny", 1, None), ("nu", 1, None), ("na", 0, MAX_LAG), ("nb", 0, MAX_LAG))
_ROW = re.compile(r"row(\d+)")
_PARENTHESIZED = re.compile(r"\(\s*(.*?)\s*\)", re.DOTALL)


def write_paper_xml(model: CalibrationModel, path: str | Path) -> float:
    """Write ``model`` as the paper's XML; returns the measured precision loss (output units)."""
    raw = to_raw_finite(model, f"Paper XML {path}")
    loss = precision_loss(model, raw)
    write_text_atomic(path, format_paper_xml(model, raw))
    return loss


def format_paper_xml(model: CalibrationModel, raw_coef: np.ndarray) -> str:
    """The XML text for raw-input coefficients ``raw_coef`` (n_features, n_outputs) of ``model``."""
    layout = model.layout_
    degree = layout.basis.degree
    label = f"{_ordinal(degree)}_degree" + (f"_na{layout.na}_nb{layout.nb}" if not layout.is_static else "")
    params = [("np", degree), ("ny", layout.n_outputs), ("nu", layout.basis.n_inputs),
              ("na", layout.na), ("nb", layout.nb), ("string", label)]
    params += [(f"row{k}", "(" + "  ".join(repr(float(v)) for v in row) + ")")
               for k, row in enumerate(raw_coef, start=1)]
    lines = ['<?xml version="1.0" encoding="utf-8"?>', f'<group name="{GROUP_NAME}">']
    lines += [f'   <param name="{name}">{value}</param>' for name, value in params]
    lines.append("</group>")
    return "\n".join(lines) + "\n"


def _ordinal(n: int) -> str:
    suffix = "th" if 10 <= n % 100 <= 20 else {1: "st", 2: "nd", 3: "rd"}.get(n % 10, "th")
    return f"{n}{suffix}"


def read_paper_xml(path: str | Path, *, input_names: Sequence[str] | None = None,
                   output_names: Sequence[str] | None = None) -> CalibrationModel:
    """Read a paper XML model file; names default to u1..u6, T and Fx..Tz when the counts fit."""
    path = check_input_file(path, "model file", max_bytes=MAX_MODEL_BYTES)
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise FtcalError(f"Cannot read model file {path}: {exc.strerror}.") from None
    return parse_paper_xml(data, str(path), input_names=input_names, output_names=output_names)


def parse_paper_xml(data: bytes | str, source: str = "<xml>", *, input_names: Sequence[str] | None = None,
                    output_names: Sequence[str] | None = None) -> CalibrationModel:
    """Parse paper XML content; ``source`` names it in error messages."""
    params = _params(data, source)
    ints = {name: _int_param(params, name, low, high, source) for name, low, high in INT_PARAMS}
    degree, ny, nu, na, nb = (ints[k] for k in ("np", "ny", "nu", "na", "nb"))
    # Count by formula before building the basis: a typo such as nu=70 must not enumerate millions of terms.
    n_rows = n_coefficients(nu, degree, ny, na, nb) // ny
    rows = {int(m.group(1)): value for name, value in params.items() if (m := _ROW.fullmatch(name))}
    if len(rows) != n_rows:
        raise FtcalError(f"{source}: {len(rows)} rowK parameters, but np={degree}, nu={nu}, ny={ny}, "
                         f"na={na}, nb={nb} needs {n_rows} (ny·na + 1 + Σ_p (nb+1)·C(nu+p−1, p)).")
    missing = next((k for k in range(1, n_rows + 1) if k not in rows), None)
    if missing is not None:
        raise FtcalError(f"{source}: row{missing} is missing (rows must be numbered 1..{n_rows}).")
    raw = np.array([_row_values(rows[k], k, ny, source) for k in range(1, n_rows + 1)])
    names_in = _names(input_names, DEFAULT_INPUTS, "u", nu, "input", source)
    names_out = _names(output_names, DEFAULT_OUTPUTS, "y", ny, "output", source)
    return from_raw(raw, degree=degree, na=na, nb=nb, input_names=names_in, output_names=names_out)


def _params(data: bytes | str, source: str) -> dict[str, str]:
    try:
        root = ET.fromstring(data)
    except ET.ParseError as exc:
        line, column = exc.position
        raise FtcalError(f"{source}: not well-formed XML at line {line}, column {column + 1}.") from None
    except LookupError as exc:  # <?xml encoding="..."?> naming no codec
        raise FtcalError(f"{source}: the XML declaration names an encoding Python does not know ({exc}).") from None
    if root.tag != "group":
        raise FtcalError(f"{source}: the root element is <{root.tag}>; a paper model file has "
                         f'<group name="{GROUP_NAME}">.')
    params: dict[str, str] = {}
    for element in root.iter("param"):
        name = element.get("name")
        if name is None:
            raise FtcalError(f"{source}: a <param> element has no name attribute.")
        if name in params:
            raise FtcalError(f"{source}: param {name!r} appears twice.")
        params[name] = element.text or ""
    return params


def _int_param(params: dict[str, str], name: str, low: int, high: int | None, source: str) -> int:
    if name not in params:
        raise FtcalError(f"{source}: the required param {name!r} is missing.")
    text = params[name].strip()
    try:
        value = int(text)
    except ValueError:
        raise FtcalError(f"{source}: param {name!r} is {text!r}; expected a whole number.") from None
    if value < low or (high is not None and value > high):
        bound = f"[{low}, {high}]" if high is not None else f">= {low}"
        raise FtcalError(f"{source}: param {name!r} is {value}; it must be in {bound}.")
    return value


def _row_values(text: str, k: int, ny: int, source: str) -> list[float]:
    match = _PARENTHESIZED.fullmatch(text.strip())
    if match is None:
        raise FtcalError(f"{source}: row{k} is {text.strip()[:60]!r}; expected numbers in parentheses.")
    tokens = match.group(1).split()
    if len(tokens) != ny:
        raise FtcalError(f"{source}: row{k} has {len(tokens)} numbers; ny={ny} needs {ny}.")
    values = []
    for column, token in enumerate(tokens, start=1):
        try:
            # Fortran and MATLAB exports may spell the exponent with D.
            value = float(token.replace("D", "e").replace("d", "e"))
        except ValueError:
            value = float("nan")
        if not np.isfinite(value):
            raise FtcalError(f"{source}: row{k}, value {column} is {token!r}; expected a finite number.")
        values.append(value)
    return values


def _names(given: Sequence[str] | None, preferred: tuple[str, ...], prefix: str, count: int,
           what: str, source: str) -> tuple[str, ...]:
    if given is None:
        return default_names(preferred, prefix, count)
    if len(given) != count:
        raise FtcalError(f"{source}: the file has {count} {what}s but {len(given)} {what} names were given.")
    return tuple(given)
