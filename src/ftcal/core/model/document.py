"""The polynomial's own fields of the model file (:mod:`ftcal.files.model_json` writes the envelope):
to and from a document, with the checks the schema cannot express, and the rebuild of a fitted model."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ...runtime.errors import FtcalError
from ..excitation import Spread
from ..features import MonomialBasis, RegressorLayout, n_coefficients
from ..normalization import Normalization, variables_normalization, variables_range
from ..solvers.base import Solver


class DocumentMixin:
    """``to_document``, ``from_document`` and the rebuild from stored parts of
    :class:`~ftcal.core.model.CalibrationModel`."""

    def to_document(self) -> dict:
        """The polynomial's model-file fields: ``model``, ``terms``, ``coefficients`` and fit diagnostics.

        Raises
        ------
        FtcalError
            Non-finite coefficients.
        """
        self._check_fitted()
        if not np.all(np.isfinite(self.coef_)):
            raise FtcalError("The model has non-finite coefficients (NaN or inf); refusing to save it.")
        layout = self.layout_
        exponents, lags = layout.exponent_rows()
        return {"model": {"degree": layout.basis.degree, "na": layout.na, "nb": layout.nb,
                          "normalization": self.normalization_},
                "terms": {"exponents": exponents.tolist(), "lags": lags.tolist(),
                          "names": layout.column_names(self.input_names_, self.output_names_)},
                "coefficients": self.coef_.tolist(),
                "fit": {"rank": self.rank_, "condition_number": self.condition_number_}}

    @classmethod
    def from_document(cls, doc: dict, source: str) -> "CalibrationModel":
        """The model of a schema-valid model-file document (checks the schema cannot express).

        Raises
        ------
        FtcalError
            Term or coefficient counts that do not match the degree, lags and outputs, terms out of
            the paper's column order; the message names ``source`` and the field.
        """
        spec, inputs, outputs = doc["model"], doc["inputs"], doc["outputs"]
        nu, ny = len(inputs), len(outputs)
        model_class = (f"degree {spec['degree']}, na={spec['na']}, nb={spec['nb']} with {nu} inputs "
                       f"and {ny} outputs")
        # Count by formula before building the basis, which enumerates every term.
        n_terms = n_coefficients(nu, spec["degree"], ny, spec["na"], spec["nb"]) // ny
        coef = doc["coefficients"]
        for field, entries in (("terms.exponents", doc["terms"]["exponents"]), ("terms.lags", doc["terms"]["lags"]),
                               ("terms.names", doc["terms"]["names"]), ("coefficients", coef)):
            if len(entries) != n_terms:
                raise FtcalError(f"{source}: {field} has {len(entries)} entries; {model_class} has {n_terms} terms.")
        layout = RegressorLayout(MonomialBasis(nu, spec["degree"]), ny, spec["na"], spec["nb"])
        _check_terms(doc["terms"], layout, model_class, source)
        bad_row = next((i for i, row in enumerate(coef) if len(row) != ny), None)
        if bad_row is not None:
            raise FtcalError(f"{source}: coefficients[{bad_row}] has {len(coef[bad_row])} values; the model has "
                             f"{ny} outputs.")
        fit = doc["fit"]
        return cls._from_fitted(
            degree=spec["degree"], na=spec["na"], nb=spec["nb"], normalization=spec["normalization"],
            coef=np.array(coef, dtype=np.float64),
            input_normalization=variables_normalization(inputs), output_normalization=variables_normalization(outputs),
            input_names=[v["name"] for v in inputs], output_names=[v["name"] for v in outputs],
            input_range=variables_range(inputs), output_range=variables_range(outputs),
            n_samples_fit=fit["n_samples"], rank=fit["rank"],
            condition_number=float("nan") if fit["condition_number"] is None else float(fit["condition_number"]),
            solver_info=fit["solver"], training_metrics=fit["metrics"], input_spread=_spread(fit, nu, source))

    @classmethod
    def _from_fitted(cls, *, degree: int, na: int, nb: int, normalization: str, coef: np.ndarray,
                          input_normalization: Normalization, output_normalization: Normalization,
                          input_names: Sequence[str], output_names: Sequence[str],
                          input_range: np.ndarray, output_range: np.ndarray, n_samples_fit: int = 0,
                          rank: int | None = None, condition_number: float = float("nan"),
                          solver_info: dict | None = None, training_metrics: dict | None = None,
                          solver: Solver | None = None, input_spread: Spread | None = None):
        """A fitted model of this class from stored parts (see :func:`~ftcal.core.model.model_from_fitted`)."""
        model = cls(degree, solver=solver, na=na, nb=nb, normalization=normalization)
        layout = RegressorLayout(MonomialBasis(len(input_names), degree), len(output_names), na, nb)
        model._set_fitted(
            layout=layout, coef=coef, normalization=normalization, input_normalization=input_normalization,
            output_normalization=output_normalization, input_names=input_names, output_names=output_names,
            input_range=input_range, output_range=output_range, n_samples_fit=n_samples_fit,
            rank=layout.n_features if rank is None else rank, condition_number=condition_number,
            solver_info=solver_info or {}, training_metrics=training_metrics or {}, input_spread=input_spread)
        return model


def _spread(fit: dict, n_inputs: int, source: str) -> Spread | None:
    """The training inputs' mean and covariance (optional: files from before ftcal recorded them)."""
    doc = fit.get("input_spread")
    if doc is None:
        return None
    mean, cov = doc["mean"], doc["covariance"]
    if len(mean) != n_inputs or len(cov) != n_inputs or any(len(row) != n_inputs for row in cov):
        raise FtcalError(f"{source}: fit.input_spread has {len(mean)} means and a {len(cov)}-row covariance; "
                         f"the model has {n_inputs} inputs.")
    if any(v is None for v in (*mean, *(x for row in cov for x in row))):
        raise FtcalError(f"{source}: fit.input_spread holds non-finite values.")
    return Spread.from_json(doc)


def _check_terms(terms: dict, layout: RegressorLayout, model_class: str, source: str) -> None:
    expected_exps, expected_lags = layout.exponent_rows()
    for row, (got, want) in enumerate(zip(terms["exponents"], expected_exps.tolist())):
        if got != want:
            raise FtcalError(f"{source}: terms.exponents[{row}] is {got}; {model_class} has {want} there "
                             "(the paper's column order).")
    for row, (got, want) in enumerate(zip(terms["lags"], expected_lags.tolist())):
        if got != want:
            raise FtcalError(f"{source}: terms.lags[{row}] is {got}; {model_class} has {want} there.")
