"""The report page: one self-contained HTML file, figures embedded as base64 PNG.

The page loads nothing from anywhere (no scripts, fonts or stylesheets from
the network), so it can be mailed, archived and opened offline.
"""

from __future__ import annotations

import base64
import html
import io
import os
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from datetime import datetime, timezone
from pathlib import Path

import numpy as np

from ..core.dataset import Dataset
from ..core.metrics import force_torque_columns
from ..core.select import CrossValidationResult
from ..files.model_json import ftcal_version
from ..runtime.atomic import write_text_atomic
from ..runtime.errors import FtcalError
from . import figures, tables
from .runs import ModelRun, expected_outputs, temperature_column

DPI = 90
MAX_RUNS_PER_FIGURE = 6
# text.parse_math off: names come from file names and columns, where '$' is a character, not TeX.
STYLE = {"font.size": 9, "axes.titlesize": 10, "figure.titlesize": 12, "axes.labelsize": 9,
         "legend.fontsize": 8, "savefig.facecolor": "white", "text.parse_math": False}

CSS = """
body { font-family: system-ui, -apple-system, "Segoe UI", Helvetica, Arial, sans-serif; margin: 0 auto;
       max-width: 1240px; padding: 1em 1.5em 3em; color: #1d1d1f; background: #fff; line-height: 1.45; }
h1 { font-size: 1.6em; margin-bottom: 0.2em; }
h2 { font-size: 1.25em; margin-top: 2em; border-bottom: 1px solid #ccd; padding-bottom: 0.2em; }
.meta { color: #555; font-size: 0.9em; }
nav ol { columns: 2; font-size: 0.95em; }
table { border-collapse: collapse; margin: 0.8em 0 1.4em; font-size: 0.85em; }
caption { caption-side: top; text-align: left; color: #444; padding-bottom: 0.4em; max-width: 1200px; }
th, td { border: 1px solid #ccd; padding: 0.25em 0.55em; text-align: right; }
th { background: #eef0f6; font-weight: 600; }
td.name { text-align: left; font-weight: 600; white-space: nowrap; }
td.best { font-weight: 700; background: #e3f4e1; }
tbody tr:nth-child(even) { background: #f8f8fb; }
figure { margin: 1em 0 2em; }
figure img { max-width: 100%; height: auto; border: 1px solid #e4e4ea; }
figcaption { color: #444; font-size: 0.9em; margin-top: 0.3em; }
p.skipped { color: #8a5a00; background: #fff7e0; border-left: 4px solid #e0b040; padding: 0.4em 0.8em; }
ul.notes li { margin-bottom: 0.3em; }
"""


@dataclass
class _Section:
    anchor: str
    title: str
    parts: list[str]

    @property
    def skipped(self) -> bool:
        """Every part says why it was skipped: nothing to show."""
        return all(part.startswith(_SKIPPED) for part in self.parts)


def figure_html(fig, key: str, caption: str) -> str:
    """A matplotlib figure as an HTML ``<figure>`` with an embedded PNG.

    Parameters
    ----------
    fig : matplotlib Figure
    key : the figure's id in the page
    caption : its caption (plain text, escaped)

    Returns
    -------
    str, the HTML
    """
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=DPI)
    data = base64.b64encode(buffer.getvalue()).decode("ascii")
    width, height = (int(round(v * DPI)) for v in fig.get_size_inches())
    return (f'<figure id="fig-{html.escape(key)}">'
            f'<img src="data:image/png;base64,{data}" width="{width}" height="{height}" '
            f'alt="{html.escape(caption)}">'
            f"<figcaption>{html.escape(caption)}</figcaption></figure>")


_SKIPPED = '<p class="skipped">'


def _skipped(text: str) -> str:
    return f"{_SKIPPED}{html.escape(text)}</p>"


def _gather_skipped(sections: list[_Section]) -> list[_Section]:
    """Sections with something to show, then one "Not shown" section saying why the others are not.

    The contents then list only what the page shows.
    """
    shown = [s for s in sections if not s.skipped]
    skipped = [s for s in sections if s.skipped]
    if skipped:
        shown.append(_Section("not-shown", f"Not shown ({len(skipped)})",
                              [f"<h3>{html.escape(s.title)}</h3>\n" + "\n".join(s.parts) for s in skipped]))
    return shown


def _chunks(items: Sequence, size: int) -> list[list]:
    return [list(items[i:i + size]) for i in range(0, len(items), size)]


def _families(runs: Sequence[ModelRun]) -> list[tuple[str, list[ModelRun]]]:
    """Runs by family in the order the families first appear."""
    out: dict[str, list[ModelRun]] = {}
    for run in runs:
        out.setdefault(run.family, []).append(run)
    return list(out.items())


def _slug(text: str) -> str:
    return "".join(ch if ch.isalnum() else "-" for ch in text.lower()).strip("-")


def _check(runs: Sequence[ModelRun], validation: Dataset) -> None:
    if not runs:
        raise FtcalError("A report needs at least one model run.")
    names = [r.name for r in runs]
    duplicates = sorted({n for n in names if names.count(n) > 1})
    if duplicates:
        raise FtcalError(f"Model run names must be unique; repeated: {', '.join(duplicates)}.")
    if validation.outputs is None:
        raise FtcalError("The report needs reference outputs (the expected wrench) in the validation data.")
    for run in runs:
        shape = (validation.n_samples, len(run.model.output_names_))
        if np.shape(run.validation_prediction) != shape:
            raise FtcalError(f"Model run {run.name!r}: validation prediction has shape "
                             f"{np.shape(run.validation_prediction)}, expected {shape}.")
        expected_outputs(run, validation)


def _dataset_line(label: str, data: Dataset) -> str:
    groups = np.unique(np.asarray(data.groups, dtype=str))
    return (f"{label}: {data.n_samples} samples, {len(data.segment_bounds())} segment(s), "
            f"{len(groups)} group(s); inputs {', '.join(data.input_names)}; "
            f"outputs {', '.join(data.output_names)}.")


def _sections(runs: list[ModelRun], validation: Dataset, train: Dataset | None,
              cv: CrossValidationResult | None) -> list[_Section]:
    colors = figures.run_colors(runs)
    families = _families(runs)
    forces_val, torques_val = force_torque_columns(validation.output_names)
    sections: list[_Section] = []

    def figure(key: str, caption: str, make: Callable) -> str:
        return figure_html(make(), key, caption)

    parts = [tables.runs_table(runs)]
    sections.append(_Section("models", "Models", parts))

    parts = []
    for family, members in families:
        for k, chunk in enumerate(_chunks(members, MAX_RUNS_PER_FIGURE)):
            key = f"errors-{_slug(family)}" + (f"-{k + 1}" if k else "")
            parts.append(figure(
                key, f"Validation error (expected − predicted) of the {family} models over the validation "
                     "samples: one panel per axis (rows) and model (columns), panels of an axis on one scale; "
                     "each panel's title gives the model's BestFit on that axis. Grey vertical lines separate "
                     "recordings. (Paper Figs 9 and 11.)",
                lambda chunk=chunk, family=family: figures.validation_errors(
                    chunk, validation, colors=colors, title=f"Validation error: {family} models")))
    sections.append(_Section("errors", "Validation error per axis", parts))

    parts = []
    if forces_val is None and torques_val is None:
        parts.append(_skipped("Skipped: the outputs are not named as forces and torques (Fx..Tz), "
                              "so there is no force or torque norm."))
    else:
        for family, members in families:
            for k, chunk in enumerate(_chunks(members, MAX_RUNS_PER_FIGURE)):
                key = f"norms-{_slug(family)}" + (f"-{k + 1}" if k else "")
                parts.append(figure(
                    key, f"Norms of the force and torque predicted by the {family} models against the "
                         "expected norms (left) and their difference, whose RMSE is the force-norm RMSE "
                         "(the paper's 'RMSE of force norm', right). (Paper Figs 10 and 12.)",
                    lambda chunk=chunk, family=family: figures.norm_comparison(
                        chunk, validation, colors=colors, title=f"Force and torque norms: {family} models")))
    sections.append(_Section("norms", "Force and torque norms", parts))

    parts = [tables.per_axis_table(runs, "rmse", "RMSE"),
             tables.per_axis_table(runs, "best_fit", "BestFit (%, larger is better)", percent=True),
             tables.per_axis_table(runs, "max_abs_error", "largest absolute error")]
    sections.append(_Section("axes", "Per-axis validation metrics", parts))

    datasets = ([("training", train)] if train is not None else []) + [("validation", validation)]
    coverage = train if train is not None and train.outputs is not None else validation
    coverage_label = "training" if coverage is train else "validation"
    parts = [tables.ranges_table(datasets), tables.groups_table(datasets)]
    if figures.reading_columns(coverage) is None:
        parts.append(_skipped("Skipped the readings plot: the data has fewer than six F/T channel inputs."))
    else:
        parts.append(figure(
            "readings", f"Measured F/T readings of the {coverage_label} data in 3D (force channels left, "
                        "torque channels right), one colour per group (load case). (The paper's full-trajectory force and torque figures.)",
            lambda: figures.readings_space(coverage, title=f"Measured readings of the {coverage_label} data")))
    if forces_val is None and torques_val is None:
        parts.append(_skipped("Skipped the 3D plot: the outputs are not named as forces and torques."))
    else:
        parts.append(figure(
            "wrench-space", f"Expected forces and torques of the {coverage_label} data in 3D, one colour per "
                            "group (load case): how much of the wrench space the data covers.",
            lambda: figures.wrench_space(coverage, title=f"Expected wrench of the {coverage_label} data by group")))
    sections.append(_Section("data", "Data coverage", parts))

    parts = []
    t_cov = temperature_column(coverage.input_names)
    t_val = temperature_column(validation.input_names)
    if t_cov is None or t_val is None:
        parts.append(_skipped("Skipped: the data has no temperature input (named T, temp or temperature)."))
    elif forces_val is None or figures.reading_columns(coverage) is None:
        parts.append(_skipped("Skipped: the outputs have no force components (Fx, Fy, Fz) or the data has "
                              "fewer than six F/T channel inputs."))
    else:
        parts.append(figure(
            "temperature", f"Left: measured force readings of the {coverage_label} data coloured by the sensor "
                           "temperature: their temperature drift (the paper's temperature-effect figure). Right: mean difference between predicted "
                           "and expected force norm on the validation data, in temperature bins; a flat line at "
                           "zero means the model compensates the temperature.",
            lambda: figures.temperature_effect(coverage, runs, validation, data_temperature=t_cov,
                                               validation_temperature=t_val, colors=colors)))
    sections.append(_Section("temperature", "Temperature effect", parts))

    parts = []
    plain = [r for r in runs if r.family == "least squares"]
    degrees = {r.model.describe()["degree"] for r in plain}
    if len(degrees) < 2:
        parts.append(_skipped("Skipped: the validation curve needs least-squares models of at least two degrees."))
    elif forces_val is None and torques_val is None:
        parts.append(_skipped("Skipped: the validation curve plots norm RMSE, and the outputs are not a wrench."))
    else:
        parts.append(figure(
            "validation-curve", "RMSE of the force and torque norms against the polynomial degree for the "
                                "least-squares models, on the validation data (solid) and the training data "
                                "(dashed, when given). A rising validation line means overfitting. "
                                "(Paper Table II.)",
            lambda: figures.validation_curve(plain)))
    sections.append(_Section("validation-curve", "Validation curve", parts))

    parts = []
    lasso = [r for r in runs if r.family == "LASSO"]
    if len(lasso) < 2:
        parts.append(_skipped("Skipped: the LASSO path needs at least two LASSO models (different λ)."))
    else:
        parts.append(figure(
            "lasso-path", "LASSO models: RMSE against λ on the validation data (solid) and the training data "
                          "(dashed, when given), and the number of nonzero coefficients against λ. "
                          "(Paper Table III.)",
            lambda: figures.lasso_path(lasso)))
    sections.append(_Section("lasso", "LASSO path", parts))

    if cv is not None:
        parts = [figure("cross-validation", f"Mean {cv.metric} over {cv.n_folds} grouped folds for each "
                                            f"candidate; the selected candidate is {cv.best.label}.",
                        lambda: figures.cross_validation_curve(cv)),
                 tables.cv_table(cv)]
        sections.append(_Section("cv", "Cross-validation", parts))
    return sections


def render_page(title: str, meta: Sequence[str], sections: Sequence[tuple[str, str, Sequence[str]]]) -> str:
    """A self-contained HTML page: title, a line naming ftcal and the time, ``meta`` lines, a contents list, sections.

    Parameters
    ----------
    title : the page title (plain text)
    meta : lines shown under the title (plain text)
    sections : (anchor, heading, HTML parts) per section

    Returns
    -------
    str, the page
    """
    created = datetime.now(timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
    lines = [f"Made by ftcal {ftcal_version()} on {created}.", *meta]
    toc = "".join(f'<li><a href="#{a}">{html.escape(t)}</a></li>' for a, t, _ in sections)
    body = "\n".join(f'<section id="{a}"><h2>{html.escape(t)}</h2>\n' + "\n".join(parts) + "</section>"
                     for a, t, parts in sections)
    return ("<!DOCTYPE html>\n"
            '<html lang="en">\n<head>\n<meta charset="utf-8">\n'
            '<meta name="viewport" content="width=device-width, initial-scale=1">\n'
            f"<title>{html.escape(title)}</title>\n<style>{CSS}</style>\n</head>\n<body>\n"
            f"<h1>{html.escape(title)}</h1>\n"
            + "".join(f'<p class="meta">{html.escape(line)}</p>\n' for line in lines)
            + f"<nav><ol>{toc}</ol></nav>\n{body}\n</body>\n</html>\n")


def build_report(runs: Sequence[ModelRun], validation: Dataset, out_path: str | os.PathLike, *,
                 train: Dataset | None = None, title: str = "ftcal calibration report",
                 cv: CrossValidationResult | None = None, notes: Sequence[str] = (),
                 comparisons: Sequence[tuple] = ()) -> Path:
    """Write a self-contained HTML report comparing ``runs`` on ``validation``.

    Parameters
    ----------
    runs : models evaluated on ``validation`` (see :func:`ftcal.report.evaluate_run`)
    validation : the data the runs were evaluated on, with outputs
    out_path : the HTML file, written atomically
    train : the training data, for the data-coverage figures and tables
    cv : a cross-validation result to plot and tabulate
    notes : free text shown at the end of the page
    comparisons : (model name, :class:`~ftcal.core.baseline.BaselineComparison`) pairs: a section
        "Against the baseline" after the models' table

    Returns
    -------
    Path of the written file.
    """
    from matplotlib import rc_context

    runs = list(runs)
    _check(runs, validation)
    with rc_context(STYLE):
        sections = _gather_skipped(_sections(runs, validation, train, cv))
    if comparisons:
        sections.insert(1, _Section("baseline", "Against the baseline", [tables.baseline_table(list(comparisons))]))
    if notes:
        sections.append(_Section("notes", "Notes", ['<ul class="notes">' + "".join(
            f"<li>{html.escape(str(n))}</li>" for n in notes) + "</ul>"]))
    meta = []
    if train is not None:
        meta.append(_dataset_line("Training data", train))
    meta.append(_dataset_line("Validation data", validation))
    page = render_page(title, meta, [(s.anchor, s.title, s.parts) for s in sections])
    out = Path(out_path)
    write_text_atomic(out, page)
    return out
