"""Every report figure reads: no raw TeX in its text, no text box over another, no value label on a marker.

Figures are drawn with the report's style (mathtext off) and their text written to SVG as
text; the boxes come from matplotlib's own renderer (``Text.get_window_extent``) for exactly
the texts it drew.
"""

from __future__ import annotations

import io
import itertools

import numpy as np
import pytest
from matplotlib import rc_context
from matplotlib.lines import Line2D
from matplotlib.transforms import Bbox

from ftcal.core.model import CalibrationModel
from ftcal.core.select import Candidate, cross_validate
from ftcal.core.solvers.lasso import Lasso
from ftcal.report import evaluate_run, figures
from ftcal.report.html import STYLE
from ftcal.sim.synthetic import synthetic_recordings

TEX = ("mathdefault", "$\\", "^{", "\\times")
MIN_LEGEND_PX = 9  # the page shows figures at 90 dpi, at most 1.03x smaller than drawn here


@pytest.fixture(scope="module")
def made():
    full = synthetic_recordings(6, 200, seed=7)
    held = np.isin(full.segments, [4])
    train, validation = full.subset(~held), full.subset(held)
    models = {"np1": CalibrationModel(1).fit(train), "np2": CalibrationModel(2).fit(train),
              "np2 λ=1": CalibrationModel(2, solver=Lasso(1.0)).fit(train),
              "np2 λ=30": CalibrationModel(2, solver=Lasso(30.0)).fit(train)}
    runs = [evaluate_run(m, validation, name=n, train=train) for n, m in models.items()]
    cv = cross_validate(train, [Candidate(1, "none", None), Candidate(2, "none", None),
                                Candidate(2, "lasso", 0.3), Candidate(2, "lasso", 3.0),
                                Candidate(2, "lasso", 30.0)], n_folds=3)
    lasso = [r for r in runs if r.family == "LASSO"]
    plain = [r for r in runs if r.family == "least squares"]
    t = train.input_names.index("T")
    makers = {
        "errors": lambda: figures.validation_errors(runs, validation),
        "norms": lambda: figures.norm_comparison(runs, validation),
        "readings": lambda: figures.readings_space(train),
        "wrench-space": lambda: figures.wrench_space(train),
        "temperature": lambda: figures.temperature_effect(train, runs, validation, data_temperature=t,
                                                          validation_temperature=t),
        "validation-curve": lambda: figures.validation_curve(plain),
        "lasso-path": lambda: figures.lasso_path(lasso),
        "cross-validation": lambda: figures.cross_validation_curve(cv),
    }
    out = {}
    with rc_context({**STYLE, "svg.fonttype": "none"}):  # SVG text as text, to search it
        for name, make in makers.items():
            fig = make()
            renderer, texts = drawn_texts(fig)
            out[name] = (fig, renderer, texts, svg(fig))
    return out


def drawn_texts(fig):
    """(renderer, [(text, its box in pixels, its drawn lines as rotated rectangles)]) for the texts drawn.

    A rotated line's rectangle is its own (corners, 4 x 2), not the upright box around it,
    which would report false overlaps for the slanted labels of 3D axes.
    """
    renderer = fig.canvas.get_renderer()
    lines: dict = {}
    original = renderer.draw_text

    def record(gc, x, y, s, prop, angle, ismath=False, mtext=None):
        if mtext is not None and s.strip():
            w, h, d = renderer.get_text_width_height_descent(s, prop, ismath=ismath)
            turn = np.deg2rad(angle)
            rotation = np.array([[np.cos(turn), -np.sin(turn)], [np.sin(turn), np.cos(turn)]])
            upright = np.array([[0.0, -d], [w, -d], [w, h - d], [0.0, h - d]])  # about the baseline start
            if renderer.flipy():  # Agg gets y from the top; the boxes are in y-up display coordinates
                y = renderer.height - y
            lines.setdefault(mtext, []).append(upright @ rotation.T + [x, y])
        return original(gc, x, y, s, prop, angle, ismath=ismath, mtext=mtext)

    renderer.draw_text = record
    try:
        fig.draw(renderer)
    finally:
        renderer.draw_text = original
    return renderer, [(text, text.get_window_extent(renderer), quads) for text, quads in lines.items()]


def quads_overlap(a: np.ndarray, b: np.ndarray, margin: float = 0.5) -> bool:
    """Two convex quadrilaterals overlap by more than ``margin`` px (separating axis test)."""
    for quad in (a, b):
        for k in range(4):
            edge = quad[(k + 1) % 4] - quad[k]
            normal = np.array([-edge[1], edge[0]]) / (np.hypot(*edge) or 1.0)
            pa, pb = a @ normal, b @ normal
            if pa.max() <= pb.min() + margin or pb.max() <= pa.min() + margin:
                return False
    return True


def svg(fig) -> str:
    buffer = io.StringIO()
    fig.savefig(buffer, format="svg")
    return buffer.getvalue()


@pytest.mark.slow
def test_no_raw_tex_in_any_figure(made):
    for name, (_, _, texts, text) in made.items():
        for marker in TEX:
            assert marker not in text, f"{name}: {marker!r} in the SVG"
        assert all("$" not in t.get_text() for t, _, _ in texts), name
    # The log axes still carry labels, as plain numbers.
    fig, _, texts, _ = made["lasso-path"]
    labels = {t.get_text() for t, _, _ in texts}
    assert {"1", "10"} <= labels, labels


def test_the_check_finds_raw_tex_when_a_log_axis_keeps_the_default_formatter():
    """The negative control: mathtext off plus matplotlib's default log labels gives raw TeX."""
    with rc_context({**STYLE, "svg.fonttype": "none"}):
        fig = figures.new_figure(3, 2)
        ax = fig.subplots()
        ax.plot([0.5, 1, 10, 100], [1, 2, 3, 4])
        ax.set_xscale("log")
        assert any(marker in svg(fig) for marker in TEX)


@pytest.mark.slow
def test_no_text_box_overlaps_another(made):
    for name, (_, _, texts, _) in made.items():
        clashes = [(a.get_text(), b.get_text()) for (a, _, quads_a), (b, _, quads_b) in itertools.combinations(texts, 2)
                   if any(quads_overlap(qa, qb) for qa in quads_a for qb in quads_b)]
        assert not clashes, f"{name}: {clashes[:5]}"
        page = made[name][0].bbox
        cut = [t.get_text() for t, box, _ in texts if box.x0 < page.x0 - 1 or box.y0 < page.y0 - 1
               or box.x1 > page.x1 + 1 or box.y1 > page.y1 + 1]
        assert not cut, f"{name}: cut off at the figure's edge: {cut}"


@pytest.mark.slow
def test_value_labels_sit_clear_of_the_markers(made):
    for name in ("validation-curve",):
        fig, renderer, texts, _ = made[name]
        for ax in fig.axes:
            markers = []
            for line in ax.get_lines():
                if line.get_marker() in ("None", None, ""):
                    continue
                half = line.get_markersize() * fig.dpi / 72 / 2
                for x, y in ax.transData.transform(line.get_xydata()):
                    markers.append(Bbox.from_extents(x - half, y - half, x + half, y + half))
            labels = [box for text, box, _ in texts if text.axes is ax and text in ax.texts]
            assert labels, name
            assert not [b for b in labels for m in markers if b.overlaps(m)], name


@pytest.mark.slow
def test_legends_are_readable(made):
    for name, (fig, _, _, _) in made.items():
        legends = [*fig.legends, *(ax.get_legend() for ax in fig.axes if ax.get_legend() is not None)]
        for legend in legends:
            for text in legend.get_texts():
                px = text.get_fontsize() * fig.dpi / 72
                assert px * 90 / fig.dpi >= MIN_LEGEND_PX, f"{name}: {text.get_text()!r} at {px:.1f} px"


def test_per_axis_errors_are_small_multiples(made):
    fig = made["errors"][0]
    visible = [ax for ax in fig.axes if ax.get_visible()]
    assert len(visible) == 6 * 4  # one panel per axis and model
    assert all(len([ln for ln in ax.get_lines() if isinstance(ln, Line2D) and len(ln.get_xdata()) > 2]) == 1
               for ax in visible)
