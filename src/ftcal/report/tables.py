"""Report tables as HTML: the runs (Tables II/III), per-axis metrics, data ranges (Table I), CV.

Numbers are formatted by :func:`format_metric` (errors, 4 decimals) and
:func:`format_percent` (BestFit), so a reader can compare them with
``model.metrics(...)`` output directly.
"""

from __future__ import annotations

import html
from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

from ..core.conversion import to_raw
from ..core.dataset import Dataset
from ..core.metrics import output_units
from ..core.select import CrossValidationResult
from .runs import ModelRun, natural_key, temperature_column

if TYPE_CHECKING:
    from ..core.baseline import BaselineComparison

MISSING = "–"


def format_metric(value: float | None) -> str:
    """An error value (N, N·m) with 4 decimals, like the paper's tables; '–' when undefined."""
    if value is None or not np.isfinite(value):
        return MISSING
    return f"{value:.4f}"


def format_percent(value: float | None) -> str:
    """A BestFit fraction as a percentage with 2 decimals."""
    if value is None or not np.isfinite(value):
        return MISSING
    return f"{100.0 * value:.2f}"


def format_lambda(value: float | None) -> str:
    return MISSING if value is None else f"{value:g}"


def _cell(text: str, *, header: bool = False, cls: str = "", title: str = "") -> str:
    tag = "th" if header else "td"
    attrs = (f' class="{cls}"' if cls else "") + (f' title="{html.escape(title)}"' if title else "")
    return f"<{tag}{attrs}>{html.escape(text)}</{tag}>"


def html_table(header: Sequence[str], rows: Sequence[Sequence[str]], *, caption: str = "",
               bold: Sequence[tuple[int, int]] = (), cls: str = "") -> str:
    """A plain table; ``bold`` cells (row, column) are highlighted."""
    marked = set(bold)
    lines = [f'<table class="{cls}">' if cls else "<table>"]
    if caption:
        lines.append(f"<caption>{html.escape(caption)}</caption>")
    lines.append("<thead><tr>" + "".join(_cell(h, header=True) for h in header) + "</tr></thead><tbody>")
    for r, row in enumerate(rows):
        cells = [_cell(text, cls="best" if (r, c) in marked else ("name" if c == 0 else ""))
                 for c, text in enumerate(row)]
        lines.append("<tr>" + "".join(cells) + "</tr>")
    lines.append("</tbody></table>")
    return "\n".join(lines)


def _best_rows(values: Sequence[float | None]) -> list[int]:
    finite = [(v, i) for i, v in enumerate(values) if v is not None and np.isfinite(v)]
    if not finite:
        return []
    best = min(finite)[0]
    return [i for v, i in finite if v == best]


def runs_table(runs: Sequence[ModelRun]) -> str:
    """One row per run: model class, λ, coefficient counts, norm RMSEs (the paper's Tables II and III)."""
    arx = any(r.model.describe()["na"] or r.model.describe()["nb"] for r in runs)
    header = ["model", "solver", "degree"] + (["na", "nb"] if arx else []) + [
        "λ", "coefficients", "nonzero", "raw > 1e-9",
        "train force-norm RMSE [N]", "train torque-norm RMSE [N·m]",
        "validation force-norm RMSE [N]", "validation torque-norm RMSE [N·m]",
        "validation RMSE of the force error norm [N]", "samples out of range"]
    rows = []
    for run in runs:
        d = run.model.describe()
        train = run.train_metrics or {}
        val = run.validation_metrics
        polynomial = run.model.family == "polynomial"  # degree and raw coefficients exist for polynomials only
        rows.append([run.name, str(run.model.solver_info_.get("name") or MISSING),
                     str(d["degree"]) if polynomial else MISSING]
                    + ([str(d["na"]), str(d["nb"])] if arx else [])
                    + [format_lambda(run.lam), str(d["n_coefficients"]), str(d["n_nonzero"]),
                       str(int((np.abs(to_raw(run.model)) > 1e-9).sum())) if polynomial else MISSING,
                       format_metric(train.get("force_norm_rmse")), format_metric(train.get("torque_norm_rmse")),
                       format_metric(val.get("force_norm_rmse")), format_metric(val.get("torque_norm_rmse")),
                       format_metric(val.get("force_error_norm_rmse")),
                       str(val.get("n_out_of_range", MISSING))])
    first_metric = header.index("validation force-norm RMSE [N]")
    bold = [(r, first_metric) for r in _best_rows([run.validation_metrics.get("force_norm_rmse") for run in runs])]
    bold += [(r, first_metric + 1) for r in _best_rows([run.validation_metrics.get("torque_norm_rmse")
                                                         for run in runs])]
    return html_table(header, rows, bold=bold, cls="runs",
                      caption="Models on the validation data (best validation value in bold). "
                              "Force-norm RMSE is the RMSE of ‖f‖ − ‖f̂‖ (the paper's 'RMSE of force norm'); "
                              "the RMSE of the force error norm is sqrt(mean ‖f − f̂‖²), direction errors "
                              "included (docs/metrics.md). Nonzero counts exact nonzero coefficients (normalized basis); "
                              "raw > 1e-9 is the paper's count, of raw-input coefficients above 1e-9.")


def per_axis_table(runs: Sequence[ModelRun], key: str, what: str, *, percent: bool = False) -> str:
    """Validation ``key`` (``rmse``, ``best_fit``, ``max_abs_error``) per output axis, one row per run."""
    names = list(runs[0].model.output_names_)
    units = output_units(names)
    fmt = format_percent if percent else format_metric
    header = ["model"] + [f"{n} [{'%' if percent else u}]" if (percent or u) else n for n, u in zip(names, units)]
    rows, columns = [], []
    for run in runs:
        own = list(run.model.output_names_)
        per_axis = run.validation_metrics.get(key)
        values = [per_axis[own.index(n)] if per_axis is not None and n in own else None for n in names]
        rows.append([run.name] + [fmt(v) for v in values])
        columns.append(values)
    bold = []
    for c in range(len(names)):
        column = [row[c] for row in columns]
        if percent:  # larger BestFit is better
            column = [None if v is None else -v for v in column]
        bold += [(r, c + 1) for r in _best_rows(column)]
    return html_table(header, rows, bold=bold, cls="axes", caption=f"Validation {what} per axis.")


def ranges_table(datasets: Sequence[tuple[str, Dataset]]) -> str:
    """Minimum and maximum of each output and of the temperature (the paper's Table I)."""
    header = ["signal"] + [f"{label} {bound}" for label, _ in datasets for bound in ("min", "max")]
    first = datasets[0][1]
    signals: list[tuple[str, str]] = [(n, u) for n, u in zip(first.output_names, output_units(first.output_names))]
    t = temperature_column(first.input_names)
    if t is not None:
        signals.append((first.input_names[t], "°C"))
    rows = []
    for name, unit in signals:
        row = [f"{name} [{unit}]" if unit else name]
        for _, data in datasets:
            if name in data.output_names:
                column = data.outputs[:, data.output_names.index(name)]
            elif name in data.input_names:
                column = data.inputs[:, data.input_names.index(name)]
            else:
                row += [MISSING, MISSING]
                continue
            row += [f"{column.min():.2f}", f"{column.max():.2f}"]
        rows.append(row)
    return html_table(header, rows, cls="ranges", caption="Range of the expected wrench and the temperature.")


def groups_table(datasets: Sequence[tuple[str, Dataset]]) -> str:
    """Samples per group (load case) in each dataset."""
    counts = []
    for _, data in datasets:
        labels, n = np.unique(np.asarray(data.groups, dtype=str), return_counts=True)
        counts.append(dict(zip(labels, n)))
    labels = sorted(set().union(*counts), key=natural_key)
    header = ["group"] + [f"{label} samples" for label, _ in datasets]
    rows = [[g] + [str(c.get(g, 0)) for c in counts] for g in labels]
    return html_table(header, rows, cls="groups", caption="Samples per group (load case or recording).")


def cv_table(cv: CrossValidationResult) -> str:
    """Mean fold scores per candidate, the selected one in bold."""
    header = ["candidate", "degree", "penalty", "λ", f"training {cv.metric}", f"validation {cv.metric}",
              "nonzero (mean)"]
    rows, bold = [], []
    for r, s in enumerate(cv.scores):
        c = s.candidate
        rows.append([c.label, str(c.degree), c.penalty, format_lambda(c.lam), format_metric(s.train_score),
                     format_metric(s.score), f"{s.nonzero:.0f}"])
        if c == cv.best:
            bold.append((r, 5))
    return html_table(header, rows, bold=bold, cls="cv",
                      caption=f"Grouped {cv.n_folds}-fold cross-validation (selected: {cv.best.label}).")


def baseline_table(comparisons: Sequence[tuple[str, "BaselineComparison"]]) -> str:
    """One row per (model, axis): both RMSEs, their ratio, the fold ratios' range and the grouped verdict."""
    header = ["model", "output", "model RMSE", "baseline RMSE", "ratio", "fold ratios", "verdict", "unit"]
    rows = []
    for name, comparison in comparisons:
        for row in comparison.rows:
            ratios = [m / b for m, b in zip(row.model_folds, row.baseline_folds) if b > 0]
            rows.append([name, row.name, format_metric(row.model_rmse), format_metric(row.baseline_rmse),
                         MISSING if row.ratio is None else f"{row.ratio:.3g}",
                         f"{min(ratios):.3g}–{max(ratios):.3g}" if len(ratios) > 1 else MISSING, row.verdict,
                         row.unit])
    first = comparisons[0][1]
    tare = "" if first.tare == "none" else f", both tared ({first.tare})"
    caption = (f"Against baseline {first.baseline}{tare}, on {len(first.folds)} fold(s) (the groups "
               f"{', '.join(first.folds)}): better or worse when the fold-by-fold log ratio's mean exceeds t × "
               "its standard error, ties within it.")
    return html_table(header, rows, caption=caption)
