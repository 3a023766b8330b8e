"""Report figures: one function per figure, each returning a matplotlib Figure.

Figures are made with the object-oriented API on an Agg canvas, so nothing
here selects a backend or touches the global rcParams. Long series are
decimated before plotting (a min/max envelope keeps the error peaks visible),
which keeps the embedded PNGs small and the page fast.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from ..core.dataset import Dataset
from ..core.metrics import METRIC_NAMES, force_torque_columns, output_units
from ..core.select import CrossValidationResult
from .runs import ModelRun, expected_outputs, natural_key

MAX_LINE_POINTS = 5000  # per plotted series
# Legend and annotation text in points: at the page's 90 dpi, 8 pt is 10 px (at least 9 px as displayed).
SMALL_TEXT = 8
MAX_SCATTER_POINTS = 4000  # per 3D scatter
TEMPERATURE_BINS = 12
EXPECTED_STYLE = {"color": "black", "lw": 0.9, "label": "expected"}


def new_figure(width: float, height: float) -> Figure:
    """A figure on its own Agg canvas (no pyplot, no global state)."""
    fig = Figure(figsize=(width, height), layout="constrained")
    FigureCanvasAgg(fig)
    return fig


def envelope_indices(values: np.ndarray, max_points: int = MAX_LINE_POINTS) -> np.ndarray:
    """At most ``max_points`` sorted indices of ``values`` keeping each bucket's min and max.

    values : ndarray of shape (n_samples,)
    """
    n = values.shape[0]
    if n <= max_points:
        return np.arange(n)
    width = int(np.ceil(n / (max_points // 2)))
    full = n // width * width
    blocks = values[:full].reshape(-1, width)
    starts = np.arange(0, full, width)
    picks = [starts + blocks.argmin(axis=1), starts + blocks.argmax(axis=1)]
    if full < n:
        tail = values[full:]
        picks.append(np.array([full + tail.argmin(), full + tail.argmax()]))
    return np.unique(np.concatenate(picks))


def spread_indices(n: int, max_points: int = MAX_SCATTER_POINTS) -> np.ndarray:
    """At most ``max_points`` evenly spread indices in [0, n)."""
    if n <= max_points:
        return np.arange(n)
    return np.unique(np.linspace(0, n - 1, max_points).astype(np.int64))


def run_colors(runs: Sequence[ModelRun]) -> dict[str, str]:
    """One colour per run name, kept the same in every figure."""
    palette = [f"C{i}" for i in range(10)]
    return {run.name: palette[i % len(palette)] for i, run in enumerate(runs)}


def _colors(runs: Sequence[ModelRun], colors: Mapping[str, str] | None) -> Mapping[str, str]:
    return colors if colors is not None else run_colors(runs)


def _plain_log_ticks(axis) -> None:
    """Plain-text labels ("0.1", "10") on a log axis.

    The report turns mathtext off (``text.parse_math``: names are user text), and the
    default log formatter writes its labels in mathtext, which then shows as raw TeX.
    """
    from matplotlib.ticker import LogFormatter

    axis.set_major_formatter(LogFormatter(labelOnlyBase=False))
    axis.set_minor_formatter(LogFormatter(labelOnlyBase=False, minor_thresholds=(1, 0.4)))


def _label(name: str, unit: str, what: str = "") -> str:
    text = f"{name} {what}".strip()
    return f"{text} [{unit}]" if unit else text


def _segment_lines(ax, data: Dataset, limit: int = 100) -> None:
    bounds = data.segment_bounds()
    if 1 < len(bounds) <= limit:
        for start, _ in bounds[1:]:
            ax.axvline(start, color="0.85", lw=0.6, zorder=0)


def _rank_zorder(runs: Sequence[ModelRun]) -> dict[str, float]:
    """Better runs (lower validation error) are drawn on top."""
    def key(run: ModelRun) -> float:
        m = run.validation_metrics
        value = m.get("force_norm_rmse")
        return float(value) if value is not None else float(np.mean(m["rmse"]))
    order = sorted(runs, key=key, reverse=True)
    return {run.name: 2.0 + i for i, run in enumerate(order)}


def validation_errors(runs: Sequence[ModelRun], validation: Dataset, *, title: str = "",
                      colors: Mapping[str, str] | None = None) -> Figure:
    """Expected minus predicted output over the validation samples: one small panel per axis and model.

    Rows are the axes (forces, then torques), columns the models, so no trace hides another;
    panels of one axis share their y scale. Each panel names the model and its BestFit on
    that axis (the paper's Figs 9 and 11).
    """
    from matplotlib.ticker import MaxNLocator

    colors = _colors(runs, colors)
    names = list(runs[0].model.output_names_)
    units = output_units(names)
    forces, torques = force_torque_columns(names)
    both = forces is not None and torques is not None
    order = [*forces, *torques] if both else list(range(len(names)))
    n_rows, n_cols = len(order), len(runs)
    width, height = max(6.0, min(13.0, 2.6 * n_cols + 1.0)), 1.35 * n_rows + 0.9
    fig = new_figure(width, height)
    # Fixed margins (in inches) instead of the constrained layout, which is slow for dozens of panels.
    fig.set_layout_engine("none")
    margins = {"left": 0.85 / width, "right": 1 - 0.15 / width, "bottom": 0.55 / height, "top": 1 - 0.6 / height,
               "wspace": 0.12, "hspace": 0.38}
    axes = fig.subplots(n_rows, n_cols, sharex=True, sharey="row", squeeze=False, gridspec_kw=margins)
    for c, run in enumerate(runs):
        error = expected_outputs(run, validation) - run.validation_prediction
        for r, column in enumerate(order):
            ax = axes[r, c]
            j = list(run.model.output_names_).index(names[column])
            err = error[:, j]
            idx = envelope_indices(err)
            ax.plot(idx, err[idx], lw=0.5, color=colors[run.name])
            ax.axhline(0.0, color="0.4", lw=0.6, zorder=1)
            _segment_lines(ax, validation)
            ax.grid(True, alpha=0.3)
            fit = run.validation_metrics["best_fit"][j]
            # y fixed: automatic title placement measures every axis again, slow over dozens of panels
            ax.set_title(f"BestFit {'n/a' if fit is None else f'{100.0 * fit:.1f} %'}", fontsize=SMALL_TEXT,
                         loc="right", pad=2, y=1.0)
            if c == 0:
                ax.set_ylabel(_label(names[column], units[column]))
            ax.tick_params(labelsize=SMALL_TEXT)
            ax.xaxis.set_major_locator(MaxNLocator(4))
            ax.yaxis.set_major_locator(MaxNLocator(4))
        axes[0, c].set_title(run.name, loc="left", fontsize=SMALL_TEXT + 1, color=colors[run.name], pad=2, y=1.0)
        axes[-1, c].set_xlabel("validation sample")
    fig.suptitle(title or "Validation error (expected − predicted)")
    return fig


def norm_comparison(runs: Sequence[ModelRun], validation: Dataset, *, title: str = "",
                    colors: Mapping[str, str] | None = None) -> Figure:
    """Force and torque norms predicted by each model against the expected ones (Figs 10 and 12).

    Left: the norms; right: ‖ŷ‖ − ‖y‖, whose RMSE is the paper's "RMSE of force norm".
    """
    colors = _colors(runs, colors)
    zorder = _rank_zorder(runs)
    forces, torques = force_torque_columns(runs[0].model.output_names_)
    rows = [(cols, label, unit, key) for cols, label, unit, key in
            ((forces, "force norm", "N", "force_norm_rmse"), (torques, "torque norm", "N·m", "torque_norm_rmse"))
            if cols is not None]
    fig = new_figure(12.0, 3.0 * len(rows) + 0.6)
    axes = fig.subplots(len(rows), 2, sharex=True, squeeze=False)
    expected0 = expected_outputs(runs[0], validation)
    for r, (cols, label, unit, key) in enumerate(rows):
        left, right = axes[r]
        expected_norm = np.linalg.norm(expected0[:, cols], axis=1)
        idx = envelope_indices(expected_norm)
        left.plot(idx, expected_norm[idx], zorder=50, **EXPECTED_STYLE)
        for run in runs:
            names = list(run.model.output_names_)
            own = [names.index(runs[0].model.output_names_[c]) for c in cols]
            predicted = np.linalg.norm(run.validation_prediction[:, own], axis=1)
            idx = envelope_indices(predicted)
            left.plot(idx, predicted[idx], lw=0.6, color=colors[run.name], zorder=zorder[run.name],
                      label=run.name)
            diff = predicted - expected_norm
            idx = envelope_indices(diff)
            value = run.validation_metrics.get(key)
            rmse_text = "" if value is None else f"  RMSE {value:.3g} {unit}"
            right.plot(idx, diff[idx], lw=0.6, color=colors[run.name], zorder=zorder[run.name],
                       label=f"{run.name}{rmse_text}")
        right.axhline(0.0, color="0.4", lw=0.6, zorder=1)
        for ax in (left, right):
            _segment_lines(ax, validation)
            ax.grid(True, alpha=0.3)
            ax.legend(loc="upper right", fontsize=SMALL_TEXT, framealpha=0.8)
        left.set_ylabel(f"{label} [{unit}]")
        right.set_ylabel(f"predicted − expected {label} [{unit}]")
    for ax in axes[-1]:
        ax.set_xlabel("validation sample index")
    fig.suptitle(title or "Force and torque norms on the validation data")
    return fig


def _group_colors(labels: Sequence) -> dict:
    from matplotlib import colormaps

    if len(labels) <= 10:
        cmap, positions = colormaps["tab10"], range(len(labels))
    elif len(labels) <= 20:
        cmap, positions = colormaps["tab20"], range(len(labels))
    else:
        cmap, positions = colormaps["viridis"], np.linspace(0.0, 1.0, len(labels))
    return {label: cmap(p) for label, p in zip(labels, positions)}


def _scatter3d(ax, points: np.ndarray, names: Sequence[str], unit: str, **style) -> object:
    from matplotlib.ticker import MaxNLocator

    artist = ax.scatter(points[:, 0], points[:, 1], points[:, 2], s=2, depthshade=False, **style)
    for axis in (ax.xaxis, ax.yaxis, ax.zaxis):  # foreshortened 3D axes: few ticks, so labels never collide
        axis.set_major_locator(MaxNLocator(3))
    # The layout does not see 3D axis labels: a smaller box keeps them inside the figure.
    ax.set_box_aspect(None, zoom=0.8)
    # labelpad: clear of the tick labels, which 3D axes draw close to their label
    ax.set_xlabel(f"{names[0]} [{unit}]", labelpad=18)
    ax.set_ylabel(f"{names[1]} [{unit}]", labelpad=18)
    ax.set_zlabel(f"{names[2]} [{unit}]", labelpad=18)
    return artist


def reading_columns(data: Dataset) -> list[int] | None:
    """Indices of the six measured F/T channels (the inputs other than temperature), or None."""
    from .runs import temperature_column

    t = temperature_column(data.input_names)
    channels = [i for i in range(len(data.input_names)) if i != t]
    return channels[:6] if len(channels) >= 6 else None


def readings_space(data: Dataset, *, title: str = "") -> Figure:
    """The sensor's measured readings in 3D (channels 1–3 and 4–6), coloured by group: the paper's full-trajectory force and torque figures (Figs 6–8 with the temperature one).

    Parameters
    ----------
    data : Dataset
        Its first six non-temperature inputs are the F/T readings (see :func:`reading_columns`).
    title : str

    Returns
    -------
    Figure
    """
    channels = reading_columns(data)
    panels = [channels[:3], channels[3:]]
    fig = new_figure(13.6, 5.6)
    idx = spread_indices(data.n_samples)
    groups = np.asarray(data.groups, dtype=str)[idx]
    labels = sorted(set(groups), key=natural_key)
    palette = _group_colors(labels)
    for p, cols in enumerate(panels):
        ax = fig.add_subplot(1, 2, p + 1, projection="3d")
        points = data.inputs[np.ix_(idx, cols)]
        names = [data.input_names[c] for c in cols]
        for label in labels:
            mask = groups == label
            _scatter3d(ax, points[mask], names, "reading", color=palette[label], label=label, alpha=0.7)
        ax.set_title(f"measured {'force' if p == 0 else 'torque'} channels {', '.join(names)}")
    if len(labels) <= 20:
        handles, names = fig.axes[0].get_legend_handles_labels()
        fig.legend(handles, names, loc="outside right center", markerscale=4, title="group",
                   fontsize=SMALL_TEXT)
    fig.suptitle(title or "Measured F/T readings by group")
    return fig


def wrench_space(data: Dataset, *, title: str = "") -> Figure:
    """Expected forces and torques in 3D, coloured by group (load case): the coverage of the wrench space.

    The paper's Figs 6–8 show the measured readings instead, see
    :func:`readings_space` and :func:`temperature_effect`.
    """
    forces, torques = force_torque_columns(data.output_names)
    panels = [(c, u) for c, u in ((forces, "N"), (torques, "N·m")) if c is not None]
    fig = new_figure(6.0 * len(panels) + 1.6, 5.6)
    idx = spread_indices(data.n_samples)
    groups = np.asarray(data.groups, dtype=str)[idx]
    labels = sorted(set(groups), key=natural_key)
    palette = _group_colors(labels)
    for p, (cols, unit) in enumerate(panels):
        ax = fig.add_subplot(1, len(panels), p + 1, projection="3d")
        points = data.outputs[np.ix_(idx, cols)]
        names = [data.output_names[c] for c in cols]
        for label in labels:
            mask = groups == label
            _scatter3d(ax, points[mask], names, unit, color=palette[label], label=label, alpha=0.7)
        ax.set_title(f"{'forces' if unit == 'N' else 'torques'} [{unit}]")
    if len(labels) <= 20:
        handles, names = fig.axes[0].get_legend_handles_labels()
        fig.legend(handles, names, loc="outside right center", markerscale=4, title="group",
                   fontsize=SMALL_TEXT)
    fig.suptitle(title or "Expected wrench by group")
    return fig


def temperature_effect(data: Dataset, runs: Sequence[ModelRun], validation: Dataset, *,
                       data_temperature: int, validation_temperature: int, title: str = "",
                       colors: Mapping[str, str] | None = None) -> Figure:
    """Left: the measured force readings coloured by sensor temperature, their drift (the paper's
    temperature figure); right: each model's mean force-norm error on the validation data, binned by
    temperature.

    Parameters
    ----------
    data : Dataset
        Whose first three non-temperature inputs are the force readings.
    runs : sequence of ModelRun
    validation : Dataset
    data_temperature, validation_temperature : int
        Index of the temperature input in each dataset.
    title : str
    colors : mapping of run name to colour, optional

    Returns
    -------
    Figure
    """
    colors = _colors(runs, colors)
    channels = reading_columns(data)[:3]
    fig = new_figure(13.0, 5.4)
    ax3d = fig.add_subplot(1, 2, 1, projection="3d")
    idx = spread_indices(data.n_samples)
    temperature = data.inputs[idx, data_temperature]
    artist = _scatter3d(ax3d, data.inputs[np.ix_(idx, channels)], [data.input_names[c] for c in channels],
                        "reading", c=temperature, cmap="plasma")
    # pad: room between the 3D z label and the colour bar's label
    fig.colorbar(artist, ax=ax3d, shrink=0.7, pad=0.12, label=f"{data.input_names[data_temperature]} [°C]")
    ax3d.set_title("measured force readings coloured by temperature")

    ax = fig.add_subplot(1, 2, 2)
    t_val = validation.inputs[:, validation_temperature]
    edges = np.linspace(t_val.min(), t_val.max(), TEMPERATURE_BINS + 1)
    which = np.clip(np.digitize(t_val, edges) - 1, 0, TEMPERATURE_BINS - 1)
    centres = 0.5 * (edges[:-1] + edges[1:])
    counts = np.bincount(which, minlength=TEMPERATURE_BINS)
    filled = counts > 0
    for run in runs:
        run_forces, _ = force_torque_columns(run.model.output_names_)
        expected = expected_outputs(run, validation)[:, run_forces]
        diff = (np.linalg.norm(run.validation_prediction[:, run_forces], axis=1)
                - np.linalg.norm(expected, axis=1))
        sums = np.bincount(which, weights=diff, minlength=TEMPERATURE_BINS)
        # Empty bins are NaN, so lines do not bridge temperature gaps.
        mean = np.full(TEMPERATURE_BINS, np.nan)
        mean[filled] = sums[filled] / counts[filled]
        ax.plot(centres, mean, "o-", ms=3, lw=1.0, color=colors[run.name], label=run.name)
    ax.axhline(0.0, color="0.4", lw=0.6)
    ax.set_xlabel(f"{validation.input_names[validation_temperature]} [°C]")
    ax.set_ylabel("mean predicted − expected force norm [N]")
    ax.set_title("validation force-norm error by temperature")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=SMALL_TEXT, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    fig.suptitle(title or "Temperature effect")
    return fig


def _metric(m: dict | None, key: str) -> float:
    value = None if m is None else m.get(key)
    return np.nan if value is None else float(value)


def validation_curve(runs: Sequence[ModelRun], *, title: str = "") -> Figure:
    """Train and validation norm RMSE against degree for unpenalized runs (Table II)."""
    configs: dict[tuple[int, int], list[ModelRun]] = {}
    for run in runs:
        d = run.model.describe()
        configs.setdefault((d["na"], d["nb"]), []).append(run)
    panels = [(k, u, n) for k, u, n in (("force_norm_rmse", "N", "force norm"),
                                        ("torque_norm_rmse", "N·m", "torque norm"))
              if runs[0].validation_metrics.get(k) is not None]
    fig = new_figure(6.0 * len(panels), 4.4)
    axes = fig.subplots(1, len(panels), squeeze=False)[0]
    for ax, (key, unit, label) in zip(axes, panels):
        for c, ((na, nb), members) in enumerate(sorted(configs.items())):
            members = sorted(members, key=lambda r: r.model.describe()["degree"])
            degrees = [r.model.describe()["degree"] for r in members]
            suffix = f" (na={na}, nb={nb})" if na or nb else ""
            val = [_metric(r.validation_metrics, key) for r in members]
            train = [_metric(r.train_metrics, key) for r in members]
            ax.plot(degrees, val, "o-", color=f"C{c}", label=f"validation{suffix}")
            for x, y in zip(degrees, val):
                ax.annotate(f"{y:.3g}", (x, y), textcoords="offset points", xytext=(0, 6),
                            ha="center", fontsize=SMALL_TEXT)
            if not np.all(np.isnan(train)):
                ax.plot(degrees, train, "s--", mfc="none", color=f"C{c}", label=f"training{suffix}")
        ax.set_xlabel("polynomial degree np")
        ax.set_ylabel(f"{METRIC_NAMES[key]} [{unit}]")
        ax.margins(y=0.12)
        ax.xaxis.get_major_locator().set_params(integer=True)
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=SMALL_TEXT)
    fig.suptitle(title or "Validation curve (least squares)")
    return fig


def lasso_path(runs: Sequence[ModelRun], *, title: str = "") -> Figure:
    """Norm RMSE and nonzero coefficients against λ for LASSO runs (Table III)."""
    by_degree: dict[int, list[ModelRun]] = {}
    for run in runs:
        by_degree.setdefault(run.model.describe()["degree"], []).append(run)
    key, unit, label = (("force_norm_rmse", "N", "force norm")
                        if runs[0].validation_metrics.get("force_norm_rmse") is not None
                        else ("rmse", "", "outputs (mean)"))
    fig = new_figure(12.0, 4.4)
    ax_rmse, ax_nz = fig.subplots(1, 2)
    for c, (degree, members) in enumerate(sorted(by_degree.items())):
        members = sorted(members, key=lambda r: r.lam)
        lams = [r.lam for r in members]
        if key == "rmse":
            val = [float(np.mean(r.validation_metrics["rmse"])) for r in members]
            train = [float(np.mean(r.train_metrics["rmse"])) if r.train_metrics else np.nan for r in members]
        else:
            val = [_metric(r.validation_metrics, key) for r in members]
            train = [_metric(r.train_metrics, key) for r in members]
        ax_rmse.plot(lams, val, "o-", color=f"C{c}", label=f"np{degree} validation")
        if not np.all(np.isnan(train)):
            ax_rmse.plot(lams, train, "s--", mfc="none", color=f"C{c}", label=f"np{degree} training")
        described = [r.model.describe() for r in members]
        ax_nz.plot(lams, [d["n_nonzero"] for d in described], "o-", color=f"C{c}", label=f"np{degree} nonzero")
        ax_nz.axhline(described[0]["n_coefficients"], color=f"C{c}", ls=":", lw=1.0,
                      label=f"np{degree} all coefficients")
    for ax in (ax_rmse, ax_nz):
        ax.set_xscale("log")
        _plain_log_ticks(ax.xaxis)
        ax.set_xlabel("λ (normalized features)")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=SMALL_TEXT)
    ax_rmse.set_ylabel(METRIC_NAMES.get(key, f"RMSE of {label}") + (f" [{unit}]" if unit else ""))
    ax_nz.set_ylabel("nonzero coefficients")
    ax_nz.set_ylim(bottom=0)
    fig.suptitle(title or "LASSO path")
    return fig


def cross_validation_curve(cv: CrossValidationResult, *, title: str = "") -> Figure:
    """Mean fold scores: against degree (no penalty) and against λ (penalized candidates)."""
    plain = [s for s in cv.scores if s.candidate.penalty == "none"]
    penalized = [s for s in cv.scores if s.candidate.penalty != "none"]
    n_panels = int(bool(plain)) + int(bool(penalized))
    fig = new_figure(6.0 * n_panels, 4.4)
    axes = list(fig.subplots(1, n_panels, squeeze=False)[0])
    unit = " [N]" if cv.metric == "force-norm RMSE" else ""
    if plain:
        ax = axes.pop(0)
        plain = sorted(plain, key=lambda s: s.candidate.degree)
        degrees = [s.candidate.degree for s in plain]
        ax.plot(degrees, [s.score for s in plain], "o-", color="C0", label="validation folds")
        ax.plot(degrees, [s.train_score for s in plain], "s--", mfc="none", color="C0", label="training folds")
        ax.set_xlabel("polynomial degree np")
        ax.xaxis.get_major_locator().set_params(integer=True)
        ax.set_ylabel(f"{cv.metric}{unit}")
        ax.set_title("least squares")
    if penalized:
        ax = axes.pop(0)
        series: dict[tuple[int, str], list] = {}
        for s in penalized:
            series.setdefault((s.candidate.degree, s.candidate.penalty), []).append(s)
        for c, ((degree, penalty), members) in enumerate(sorted(series.items())):
            members = sorted(members, key=lambda s: s.candidate.lam)
            ax.plot([s.candidate.lam for s in members], [s.score for s in members], "o-", color=f"C{c}",
                    label=f"np{degree} {penalty}")
        ax.set_xscale("log")
        _plain_log_ticks(ax.xaxis)
        ax.set_xlabel("λ (normalized features)")
        ax.set_ylabel(f"validation {cv.metric}{unit}")
        ax.set_title("penalized")
    for ax in fig.axes:
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=SMALL_TEXT)
    fig.suptitle(title or f"Grouped cross-validation ({cv.n_folds} folds), best: {cv.best.label}")
    return fig
