"""What a plan is worth, as text and as an HTML page (``ftcal plan`` printout and ``--html``).

Both compare the plan with a random design of the same size (random
configurations with random loads, from the same seed stream) and, with
``--from``, with the recorded data alone.
"""

from __future__ import annotations

import html
import math
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from ..core.columns import DEFAULT_OUTPUTS
from ..report.figures import new_figure, spread_indices
from ..report.html import STYLE, figure_html, render_page
from ..report.tables import html_table
from ..runtime.atomic import write_text_atomic
from .experiment import Plan, Recorded

NO_COLLISION_CHECK = ("ftcal does no collision checking: the only safety limits are the joint limits, "
                      "--joint-range, --fixed and --min-height; check every pose on your robot before running it.")
STYLES = {"candidates": {"color": "0.75", "s": 1, "alpha": 0.4},
          "random": {"color": "tab:blue", "s": 10, "alpha": 0.8},
          "recorded (--from)": {"color": "tab:orange", "s": 10, "alpha": 0.8},
          "planned": {"color": "tab:red", "s": 18, "alpha": 0.95}}


def _efficiency(plan: Plan) -> float:
    """exp(Δ log det / p): how much larger, per parameter, the plan's determinant is than the random design's."""
    delta = plan.planned.log_det - plan.random.log_det
    return math.exp(delta / plan.n_parameters) if math.isfinite(delta) else math.inf


def summary_rows(plan: Plan) -> tuple[list[str], list[list[str]]]:
    """Header and rows comparing planned, random (and recorded-only) designs."""
    with_recorded = plan.n_recorded > 0
    header = ["", "planned", "random"] + (["recorded only"] if with_recorded else [])
    scores = [plan.planned, plan.random] + ([plan.recorded] if with_recorded else [])
    rows = [["log det(information)"] + [f"{s.log_det:.2f}" for s in scores]]
    if plan.request.objective == "calibration":
        rows.append(["prediction std. error / noise (RMS over candidates)"]
                    + [f"{s.prediction_error:.3g}" for s in scores])
    else:
        for label, unit, names, factor in _payload_lines(plan):
            rows.append([f"{label} [{unit}]"]
                        + [f"{max(s.standard_errors[n] for n in names) * factor:.3g}" for s in scores])
    rows.append(["joint travel [rad]", f"{plan.travel:.1f}", f"{plan.random_travel:.1f}"]
                + (["—"] if with_recorded else []))
    return header, rows


def _payload_lines(plan: Plan) -> list[tuple[str, str, tuple[str, ...], float]]:
    """(label, unit, parameters, factor) of the payload standard errors printed: the largest of the parameters."""
    lines = []
    for k in range(plan.candidates.n_loads):
        lines.append((f"std. error, mass with load {k}", "g", (f"m[{k}]",), 1000.0))
        lines.append((f"std. error, m·c with load {k} (worst axis)", "g mm", tuple(f"mc{a}[{k}]" for a in "xyz"), 1e6))
    lines.append(("std. error, force bias (worst axis)", "N", tuple(f"F{a}_bias" for a in "xyz"), 1.0))
    lines.append(("std. error, torque bias (worst axis)", "mN m", tuple(f"T{a}_bias" for a in "xyz"), 1000.0))
    return lines


def format_summary(plan: Plan) -> str:
    """The printout: what was planned, against what, and the safety note."""
    req = plan.request
    what = (f"a degree-{req.degree} calibration" if req.objective == "calibration"
            else "bias + mass + centre-of-mass identification")
    n_ref = sum(s.reference for s in plan.steps)
    moved = ", ".join(f"{n} [{lo:.3g}, {hi:.3g}]" for n, lo, hi in zip(plan.space.free, plan.space.lower,
                                                                        plan.space.upper))
    lines = [f"planned {req.n_poses} poses for {what} (+{n_ref} visits of the reference pose, every "
             f"{req.reference_every} poses and at each load's start and end), from "
             f"{plan.candidates.n_configurations} configurations x {plan.candidates.n_loads} load(s)",
             f"joints moved (rad): {moved}"]
    if plan.space.fixed:
        lines.append("pinned: " + ", ".join(f"{n}={v:g}" for n, v in plan.space.fixed.items()))
    if req.min_height is not None:
        lines.append(f"sensor origin at least {req.min_height:g} m above the base's xy-plane")
    lines.append(f"the candidates excite {plan.n_excited} of the {plan.n_parameters} directions of the "
                 f"information matrix")
    header, rows = summary_rows(plan)
    width = max(len(r[0]) for r in rows)
    cells = [max(len(r[i]) for r in [header, *rows]) for i in range(1, len(header))]
    lines.append("  ".join([" " * width] + [h.rjust(w) for h, w in zip(header[1:], cells)]))
    for r in rows:
        lines.append("  ".join([r[0].ljust(width)] + [c.rjust(w) for c, w in zip(r[1:], cells)]))
    lines.append(f"determinant per parameter, planned / random: {_efficiency(plan):.3g}x")
    counts = np.bincount(plan.load, minlength=plan.candidates.n_loads)
    lines.append("poses per load: " + ", ".join(f"{k}: {c}" for k, c in enumerate(counts)))
    lines.append(f"note: {NO_COLLISION_CHECK}")
    return "\n".join(lines)


def coverage_figure(plan: Plan, recorded: Sequence[Recorded] = ()):
    """Expected forces and torques of the candidates, the random design, the recorded data and the plan."""
    w = plan.candidates.wrench
    sets = {"candidates": w.reshape(-1, 6)[spread_indices(w.shape[0] * w.shape[1], 3000)],
            "random": w[plan.random_configuration, plan.random_load]}
    rec = [r.wrench for r in recorded if r.wrench is not None]
    if rec:
        sets["recorded (--from)"] = np.concatenate(rec)
    sets["planned"] = w[plan.configuration, plan.load]
    fig = new_figure(12.0, 5.4)
    for p, (cols, unit, what) in enumerate((((0, 1, 2), "N", "forces"), ((3, 4, 5), "N m", "torques"))):
        ax = fig.add_subplot(1, 2, p + 1, projection="3d")
        for label, points in sets.items():
            ax.scatter(points[:, cols[0]], points[:, cols[1]], points[:, cols[2]], depthshade=False,
                       label=label, **STYLES[label])
        for setter, c in zip((ax.set_xlabel, ax.set_ylabel, ax.set_zlabel), cols):
            setter(f"{DEFAULT_OUTPUTS[c]} [{unit}]")
        ax.set_title(f"expected {what}")
    handles, labels = fig.axes[0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="outside right center", markerscale=2)
    fig.suptitle("Wrench-space coverage: planned vs random vs recorded")
    return fig


def write_page(plan: Plan, path: str | Path, recorded: Sequence[Recorded] = ()) -> Path:
    """Write the plan's HTML page (atomically) and return its path."""
    out = Path(path)
    write_text_atomic(out, page_text(plan, recorded))
    return out


def page_text(plan: Plan, recorded: Sequence[Recorded] = ()) -> str:
    """The plan's HTML page, as text (so it can be written together with the plan itself)."""
    from matplotlib import rc_context

    header, rows = summary_rows(plan)
    table = html_table(header, rows, caption="The plan against a random design of the same size "
                                             "(random configurations and loads, same seed stream).")
    notes = [format_summary(plan).splitlines()[0], NO_COLLISION_CHECK]
    with rc_context(STYLE):
        figure = figure_html(coverage_figure(plan, recorded), "coverage",
                             "Expected wrench at the planned poses, a random design, the recorded data "
                             "and (grey) the candidates.")
    sections = [("design", "Design", [table]), ("coverage", "Coverage of the wrench space", [figure]),
                ("notes", "Notes", ['<ul class="notes">' + "".join(f"<li>{html.escape(n)}</li>" for n in notes)
                                    + "</ul>"])]
    return render_page("ftcal experiment plan", [], sections)
