"""The info step: what a model file holds (``ftcal info``), read without numpy when the file allows it.

A valid static polynomial JSON file is summarized by :func:`ftcal.files.model_info.light_facts` (plain
Python); anything else is loaded fully (:func:`~ftcal.files.model_info.loaded_facts`), which refuses an
invalid file with its message. This module imports neither numpy nor the loader, so ``ftcal info``
stays light (tests/cli/test_light_commands.py).
"""

from __future__ import annotations

import os

from ..core.limits import INFO_TERMS
from ..core.metrics_text import norm_rmse_text
from ..runtime.errors import single_line
from .result import StepResult, plain


class ModelInfoResult(StepResult):
    """What :func:`model_info` read.

    A plain class, not a dataclass: importing :mod:`dataclasses` (and the :mod:`inspect` it loads) would be
    most of the import time the light path saves.

    Attributes
    ----------
    path : the model file, as given
    facts : the keys of :func:`~ftcal.files.model_info.loaded_facts` (kind, counts, solver, provenance,
        training ranges and metrics, and for a polynomial the raw-input count and the largest terms)
    """

    def __init__(self, path: str, facts: dict) -> None:
        self.path = path
        self.facts = facts

    def to_dict(self) -> dict:
        return plain({"path": self.path, "facts": self.facts})

    def summary(self) -> str:
        return report(self.path, self.facts).rstrip("\n")


def model_info(model: str | os.PathLike, terms: int = INFO_TERMS) -> ModelInfoResult:
    """Describe the model file ``model``: class, counts, training ranges and its ``terms`` largest terms.

    Parameters
    ----------
    model : an ftcal JSON or paper XML model file
    terms : how many of the largest terms to list

    Returns
    -------
    ModelInfoResult

    Raises
    ------
    FtcalError
        The file cannot be read or is not a valid model file (the full loader's message).
    """
    from ..files.model_info import light_facts, loaded_facts

    path = os.fspath(model)
    return ModelInfoResult(path, light_facts(path, terms) or loaded_facts(path, terms))


def report(name: str, facts: dict) -> str:
    """The text ``info`` prints for the ``facts`` (:func:`~ftcal.files.model_info.loaded_facts`'s keys) of the
    model file ``name``."""
    polynomial, lam = facts["polynomial"], facts["lambda"]
    lines = [f"{name}: {facts['kind']}, {facts['n_inputs']} inputs -> {facts['n_outputs']} outputs",
             f"{'coefficients' if polynomial else 'parameters'} {facts['n_coefficients']}, "
             f"nonzero {facts['n_nonzero']}; solver {facts['solver'] or 'unknown'}"
             + (f", lambda {lam:g}" if lam else "")]
    if polynomial:
        lines.append(f"raw-input coefficients with |value| > 1e-9 (the paper's count): {facts['raw_nonzero']}")
    if facts["created_utc"]:
        lines.append(f"created {facts['created_utc']} by ftcal {facts['ftcal_version']}; "
                     f"trained on {facts['n_samples']} samples from {facts['n_sources']} file(s)")
    if facts["prior"]:
        lines.append(f"shrunk toward the prior {facts['prior']['source']} "
                     f"(sha256 {facts['prior']['file_sha256'][:12]}…)")
    lines.append("training ranges:")
    for variable, unit, low, high in facts["inputs"]:
        lines.append(f"  {single_line(variable):<8} {low:>14.6g} .. {high:<14.6g} {single_line(unit or '')}")
    if norm_rmse_text(facts["metrics"]):
        lines.append("training " + norm_rmse_text(facts["metrics"], ".4g"))
    if polynomial:
        basis = "raw inputs" if facts["raw_basis"] else "normalized features"
        lines.append(f"largest terms (coefficients of {basis}):")
        for output, term, value in facts["largest"]:
            lines.append(f"  {single_line(output):<6} {single_line(term):<28} {value: .6g}")
    return "\n".join(lines) + "\n"
