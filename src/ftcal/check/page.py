"""The ``ftcal check --html`` page: findings or acceptance tables, residuals by pose, before/after plots.

Built with the report machinery (:mod:`ftcal.report`): the same figure canvas, embedded
PNGs, CSS and tables, so the page is one self-contained file.
"""

from __future__ import annotations

import html
import os
from collections.abc import Sequence
from datetime import datetime, timezone
from pathlib import Path

import numpy as np

from ..files.model_json import ftcal_version
from ..report.figures import envelope_indices, new_figure
from ..report.html import CSS, STYLE, figure_html
from ..report.tables import html_table
from ..runtime.atomic import write_text_atomic
from .accept import Acceptance, axis_limits
from .conventions import AXES, ConventionReport


def _page(title: str, meta: Sequence[str], sections: Sequence[tuple[str, list[str]]], out: str | os.PathLike) -> Path:
    path = Path(out)
    write_text_atomic(path, _page_text(title, meta, sections))
    return path


def _page_text(title: str, meta: Sequence[str], sections: Sequence[tuple[str, list[str]]]) -> str:
    created = datetime.now(timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
    lines = [f"Made by ftcal {ftcal_version()} on {created}.", *meta]
    body = "\n".join(f"<section><h2>{html.escape(name)}</h2>\n" + "\n".join(parts) + "</section>"
                     for name, parts in sections)
    page = ("<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n"
            f"<title>{html.escape(title)}</title>\n<style>{CSS}</style>\n</head>\n<body>\n"
            f"<h1>{html.escape(title)}</h1>\n"
            + "".join(f'<p class="meta">{html.escape(line)}</p>\n' for line in lines)
            + f"{body}\n</body>\n</html>\n")
    return page


def _hold_bars(report: ConventionReport):
    """Force and torque residual norm per hold, as declared and with the fixes."""
    fig = new_figure(9.0, 4.5)
    axes = fig.subplots(2, 1, sharex=True)
    index = np.arange(1, report.holds.n_holds + 1)
    for ax, cols, unit, what in ((axes[0], slice(0, 3), "N", "force"), (axes[1], slice(3, 6), "N·m", "torque")):
        ax.bar(index - 0.2, np.linalg.norm(report.hold_residual[:, cols], axis=1), 0.4, label="as declared",
               color="#c0504d")
        ax.bar(index + 0.2, np.linalg.norm(report.fixed_residual[:, cols], axis=1), 0.4,
               label="with the fixes", color="#4f81bd")
        ax.set_ylabel(f"{what} residual ({unit})")
        ax.legend(loc="upper right")
    axes[1].set_xlabel("static hold")
    fig.suptitle("Payload-fit residual of each static hold, before and after the fixes")
    return fig


def conventions_page(report: ConventionReport, out: str | os.PathLike, *, source: str = "") -> Path:
    """Write the page of a :func:`~ftcal.check.conventions.check_conventions` result."""
    from matplotlib import rc_context

    rows = [[f.kind, f.message, f.fix, f"{100 * f.confidence:.2f} %",
             f"{f.before[0]:.4g} N, {f.before[1]:.4g} N·m", f"{f.after[0]:.4g} N, {f.after[1]:.4g} N·m"]
            for f in report.findings]
    findings = (html_table(["finding", "what the data show", "fix", "confidence", "residual before",
                            "residual after"], rows, caption="Convention findings")
                if rows else "<p>No finding: the recording is signed, oriented and referenced as declared.</p>")
    holds = [[str(k + 1), f"{report.holds.start[k]}–{report.holds.stop[k] - 1}",
              *(f"{v:.4g}" for v in report.holds.gravity[k]), *(f"{v:.4g}" for v in report.holds.wrench[k])]
             for k in range(report.holds.n_holds)]
    with rc_context(STYLE):
        figure = figure_html(_hold_bars(report), "holds", "Residual of each hold as declared (red) and with the "
                             "findings' fixes applied (blue).")
    notes = ['<ul class="notes">' + "".join(f"<li>{html.escape(n)}</li>" for n in report.notes) + "</ul>"] \
        if report.notes else []
    return _page("ftcal check: conventions", [f"Data: {source}"] if source else [], [
        ("Findings", [findings, *notes]),
        ("Residuals by hold", [figure]),
        ("Static holds", [html_table(["hold", "rows", "gx", "gy", "gz", *AXES], holds,
                                     caption="Mean gravity (m/s², declared sensor frame) and reading (N, N·m)")]),
    ], out)


# Poses drawn in the figure and listed in the table: the worst ones, so thousands of poses stay a quick page.
MAX_PAGE_POSES = 40
MAX_TABLE_POSES = 500


def worst_poses(result: Acceptance, count: int) -> list:
    """The ``count`` poses furthest over (or nearest to) their thresholds, in recording order."""
    limits = axis_limits(result.outputs, result.thresholds)
    with np.errstate(invalid="ignore", divide="ignore"):
        ratio = [float(np.nan_to_num(p.rmse / limits, nan=np.inf).max()) for p in result.poses]
    keep = sorted(np.argsort(ratio, kind="stable")[::-1][:count].tolist())
    return [result.poses[k] for k in keep]


def _pose_figure(result: Acceptance):
    limits = axis_limits(result.outputs, result.thresholds)
    poses = worst_poses(result, MAX_PAGE_POSES)
    fig = new_figure(10.0, 5.0)
    axes = fig.subplots(2, 3, sharex=True)
    index = np.arange(len(poses))
    for j, ax in enumerate(axes.ravel()):
        values = np.array([p.rmse[j] for p in poses])
        ax.bar(index, np.nan_to_num(values, nan=0.0, posinf=0.0),
               color=["#4f81bd" if v <= limits[j] else "#c0504d" for v in values])
        ax.axhline(limits[j], color="black", lw=0.8, ls="--")
        ax.set_title(result.outputs[j])
    for ax in axes[1]:
        ax.set_xticks(index, [p.label[-12:] for p in poses], rotation=60, fontsize=6)
    shown = "" if len(poses) == len(result.poses) else f"; the {len(poses)} worst of {len(result.poses)} poses"
    fig.suptitle(f"RMS error by pose (dashed: threshold; red: over it{shown})")
    return fig


def _series_figure(result: Acceptance):
    fig = new_figure(10.0, 6.0)
    axes = fig.subplots(3, 2, sharex=True)
    for j, ax in enumerate(axes.T.ravel()):
        keep = envelope_indices(result.error[:, j])
        ax.plot(keep, result.reference[keep, j], color="black", lw=0.8, label="reference")
        ax.plot(keep, result.reference[keep, j] + result.error[keep, j], color="#4f81bd", lw=0.6,
                label="calibrated")
        ax.set_ylabel(result.outputs[j])
    axes[0, 0].legend(loc="upper right")
    fig.suptitle("Reference and calibrated wrench over the test recording")
    return fig


def acceptance_page(result: Acceptance, out: str | os.PathLike, *, model: str = "",
                    data: Sequence[str] = ()) -> Path:
    """Write the page of an acceptance test."""
    out = Path(out)
    write_text_atomic(out, acceptance_page_text(result, model=model, data=data))
    return out


def acceptance_page_text(result: Acceptance, *, model: str = "", data: Sequence[str] = ()) -> str:
    """The page of an acceptance test, as text."""
    from matplotlib import rc_context

    limits = axis_limits(result.outputs, result.thresholds)
    verdict = "PASS" if result.passed else "FAIL"
    axis_rows = [[name, f"{r:.4g}", f"{m:.4g}", f"{lim:.4g}", "ok" if r <= lim else "over"]
                 for name, r, m, lim in zip(result.outputs, result.rmse, result.max_abs_error, limits)]
    listed = worst_poses(result, MAX_TABLE_POSES)
    pose_rows = [[p.label, str(p.n_samples), *(f"{v:.4g}" for v in p.rmse),
                  ", ".join(p.failed) or "ok"] for p in listed]
    left_out = ([f"<p>The {len(listed)} worst of {len(result.poses)} poses are listed.</p>"]
                if len(listed) < len(result.poses) else [])
    notes = [*(f"unusable: {p}" for p in result.problems), *result.channel_issues]
    issues = (['<ul class="notes">' + "".join(f"<li>{html.escape(i)}</li>" for i in notes)
               + "</ul>"] if notes else ["<p>No saturated, stuck or dead input channel.</p>"])
    with rc_context(STYLE):
        poses = figure_html(_pose_figure(result), "poses", "RMS error of each pose against the thresholds.")
        series = (figure_html(_series_figure(result), "series", "Reference (black) and calibrated (blue) wrench.")
                  if result.reference is not None else "<p>No reference wrench kept.</p>")
    return _page_text(f"ftcal check: acceptance {verdict}",
                 [f"Model: {model}", f"Data: {', '.join(map(str, data))}",
                  f"Thresholds: {result.thresholds.force:.4g} N, {result.thresholds.torque:.4g} N·m "
                  f"({result.thresholds.origin})"], [
        ("Errors per axis", [html_table(["axis", "RMS error", "max |error|", "threshold", ""], axis_rows)]),
        ("Errors by pose", [html_table(["pose", "samples", *result.outputs, "over threshold"], pose_rows),
                            *left_out, poses]),
        ("Input channels", issues),
        ("Reference and calibrated wrench", [series]),
    ])
