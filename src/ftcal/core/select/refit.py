"""The selection refitted on all the data: from the statistics the search holds (:func:`fit_selection`),
mixed candidates embedded in one basis, or every candidate of a list from one pass (:func:`fit_candidates`)."""

from __future__ import annotations

import warnings
from collections.abc import Sequence

import numpy as np

from ...runtime.errors import FtcalError, IllPosedFitWarning
from ..dataset import Dataset
from ..model import CalibrationModel, FitFrame, change_basis
from ..solvers.base import ScaledProblem
from ..solvers.lasso import Lasso
from ..solvers.least_squares import LeastSquares, Ridge
from .candidates import Candidate
from .result import CrossValidationResult


def fit_best(data: Dataset, result: CrossValidationResult, *,
             template: CalibrationModel | None = None) -> CalibrationModel:
    """Refit the selection of ``result`` on all of ``data``, with training metrics.

    Parameters
    ----------
    data : Dataset
        The data ``result`` was computed on.
    result : CrossValidationResult
    template : CalibrationModel, optional
        The template ``result`` was computed with (a selection of one candidate only).

    Returns
    -------
    CalibrationModel
    """
    if result.search is not None and (result.mixed or template is None or template is result.search.template):
        model = fit_selection(result)
        model.training_metrics_ = model.metrics(data, warn_out_of_range=False)
        return model
    return best_model(result, template).fit(data)


def best_model(result: CrossValidationResult, template: CalibrationModel | None = None) -> CalibrationModel:
    """The best single candidate of ``result`` as an unfitted model (``template``'s other parameters).

    Parameters
    ----------
    result : CrossValidationResult
    template : CalibrationModel, optional
        The template ``result`` was computed with.

    Returns
    -------
    CalibrationModel
    """
    template = template if template is not None else CalibrationModel()
    best = result.best
    # Least squares does not shrink, so a prior has nothing to act on.
    changes = {"prior": None} if best.penalty == "none" else {}
    return template.clone(degree=best.degree, solver=best.solver(), **changes)


def fit_selection(result: CrossValidationResult) -> CalibrationModel:
    """The selection of ``result`` fitted on all the data, from the statistics the search already holds.

    Each candidate selected is solved once on the sum of its fold statistics (no pass
    over the data). When outputs use different candidates, every output's coefficients
    are mapped into one basis (the template's normalization, else ``maxabs`` when a
    penalized candidate is selected, else ``center``: exact algebra) and embedded in
    the layout of the largest selected degree with exact zeros for the terms its own
    degree does not have, so the model predicts each output exactly as its own
    candidate does, and every file format and export holds it unchanged.

    Parameters
    ----------
    result : CrossValidationResult
        From :func:`select_model` or :func:`cross_validate`.

    Returns
    -------
    CalibrationModel
        Fitted, with empty ``training_metrics_`` (the caller scores). ``solver_info_``
        names the selection (``"selection"``: part, outputs, degree, penalty, λ and relative λ).
    """
    search = result.search
    chosen = result.candidate_of_output()
    fitted: dict[Candidate, CalibrationModel] = {}
    for candidate in dict.fromkeys(chosen):
        key, model, frame = search._key(candidate)
        with warnings.catch_warnings():
            # Ill-posedness of the winner was judged by validation; the fit's own warning repeats what CV saw.
            warnings.simplefilter("ignore", IllPosedFitWarning)
            fitted[candidate] = model.fit_statistics(frame, search.full_statistics(key))
    info = {"selection": [{"part": part.name, "outputs": [search.scorer.output_names[j] for j in part.columns],
                           **candidate.as_dict()} for part, candidate in result.selection],
            "select_per": result.select_per}
    if len(fitted) == 1:
        model = fitted[chosen[0]]
        model.solver_info_.update(info)
        return model
    top = max(fitted.values(), key=lambda m: m.layout_.n_features)
    penalized = any(c.penalty != "none" for c in fitted)
    stored = search.template.clone(degree=top.layout_.basis.degree, prior=None,
                                   solver=Ridge(1.0) if penalized else LeastSquares())
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", IllPosedFitWarning)
        frame = search.data.frame(stored)
    coef = np.zeros((frame.layout.n_features, len(chosen)))
    for j, candidate in enumerate(chosen):
        part = fitted[candidate]
        own = part.coef_
        if part.normalization_ != frame.normalization:
            own = change_basis(part.layout_, own, part.input_normalization_, part.output_normalization_,
                               frame.input_normalization, frame.output_normalization)
        coef[part.layout_.index_in(frame.layout), j] = own[:, j]
    per = {"output": "per-output", "block": "per-block"}.get(result.select_per, "per-part")
    stored._set_fitted(
        layout=frame.layout, coef=coef, normalization=frame.normalization,
        input_normalization=frame.input_normalization, output_normalization=frame.output_normalization,
        input_names=frame.input_names, output_names=frame.output_names, input_range=frame.input_range,
        output_range=frame.output_range, n_samples_fit=frame.n_rows, rank=top.rank_,
        condition_number=max(m.condition_number_ for m in fitted.values()),
        solver_info={"name": f"{per} selection", "lambda": None, **info}, training_metrics={})
    return stored


def fit_candidates(data: Dataset, candidates: Sequence[Candidate], *, template: CalibrationModel | None = None,
                   advance=None) -> dict[Candidate, CalibrationModel]:
    """Fit every candidate on all of ``data`` from one pass of statistics per (degree, basis).

    Equivalent to fitting each candidate separately (``template.clone(...).fit(data)``);
    LASSO candidates of one degree run as one warm-started λ path.

    Parameters
    ----------
    data : Dataset
    candidates : sequence of Candidate
    template : CalibrationModel, optional
    advance : callable, optional
        Called with 1 after each candidate (progress).

    Returns
    -------
    dict of Candidate to fitted CalibrationModel
    """
    if data.outputs is None:
        raise FtcalError("Fitting needs reference outputs in the data.")
    template = template if template is not None else CalibrationModel()
    groups: dict[tuple[int, str], list[tuple[Candidate, CalibrationModel, FitFrame]]] = {}
    fitted = {}
    for c in candidates:
        model = template.clone(degree=c.degree, solver=c.solver())
        if model.prior is not None:
            # Shrinking toward a prior changes the problem per candidate: fit it on its own.
            fitted[c] = (model if c.penalty != "none" else model.clone(prior=None)).fit(data)
            if advance is not None:
                advance(1)
            continue
        frame = model.frame(data)
        basis = frame.normalization if frame.solves_in_stored_basis else f"solve-{frame.normalization}"
        groups.setdefault((c.degree, basis), []).append((c, model, frame))
    for _, group in sorted(groups.items()):
        frame = group[0][2]
        stats = CalibrationModel.statistics(data, frame.layout, frame.solve_input_normalization,
                                            frame.solve_output_normalization)
        problem = ScaledProblem.from_statistics(stats)
        for (candidate, model, frame), result in _solve_group(problem, group):
            model.adopt(frame, problem, result)
            model.training_metrics_ = model.metrics(data, warn_out_of_range=False)
            fitted[candidate] = model
            if advance is not None:
                advance(1)
    return {c: fitted[c] for c in candidates}


def _solve_group(problem: ScaledProblem, group):
    """Yield ((candidate, model, frame), SolverResult), each LASSO λ path warm-started."""
    with warnings.catch_warnings():
        # Fits of high degrees on few groups are often ill-posed; validation says how much that matters.
        warnings.simplefilter("ignore", IllPosedFitWarning)
        lasso = [g for g in group if g[0].penalty == "lasso"]
        if lasso:
            yield from zip(lasso, Lasso(lasso[0][0].lam).fit_path(problem, [g[0].lam for g in lasso]))
        for g in group:
            if g not in lasso:
                yield g, g[1]._solver().fit(problem)
