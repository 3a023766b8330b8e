"""The evaluate, predict and report steps: a model's metrics on data with reference outputs, its predictions, a page.

:func:`evaluate`, :func:`predict` and :func:`report` are ``ftcal evaluate``, ``predict`` and ``report`` as calls.
Files are streamed (one task per file; static models chunk by chunk, ``scheduler``: on Dask);
ARX models read in this process are scored on the data read whole, which gives the same metrics.
"""

from __future__ import annotations

import math
import os
import warnings
from collections.abc import Sequence
from contextlib import nullcontext
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from .arguments import EVALUATE, PREDICT, check_arguments
from ..runtime.errors import FtcalError, ParameterError
from .result import StepResult
from .sources import default_label_columns, tables_of


@dataclass(repr=False)
class EvaluationResult(StepResult):
    """What :func:`evaluate` returns: the metrics and the table ``ftcal evaluate`` prints.

    Attributes
    ----------
    model : the model evaluated
    metrics : dict
        The keys of ``ftcal evaluate --json`` (:data:`ftcal.core.metrics.EVALUATION_KEYS`, the counts
        outside the training range and span, ``out_of_range``, and the other ARX mode's metrics).
    mode, start, warmup : the ARX prediction the metrics score
    notes : list of str, the defaults taken (printed first)

    Examples
    --------
    >>> import numpy as np, pandas as pd
    >>> import ftcal
    >>> u = np.linspace(-1.0, 1.0, 30)
    >>> frame = pd.DataFrame({"u1": u, "Fx": 4.0 * u + 0.02 * np.cos(25 * u)})
    >>> result = ftcal.evaluate(ftcal.fit(frame, inputs=["u1"], outputs=["Fx"]).model, frame)
    >>> result.to_dict()["n_outside_range"], result.summary().splitlines()[0]
    (0, '30 samples, 0 outside the training input range (an input beyond its training min/max)')
    """

    model: Any
    metrics: dict
    mode: str = "one-step"
    start: str = "zeros"
    warmup: str = "drop"
    notes: list[str] = field(default_factory=list)

    def to_dict(self) -> dict:
        from .result import plain

        return plain(self.metrics)

    def headline(self) -> str:
        """Samples and RMSE per output, in each output's unit."""
        from ..core.metrics import output_units

        m = self.metrics
        units = output_units(m["outputs"])
        errors = ", ".join(f"{name} {r:.4g}{' ' + u if u else ''}" for name, u, r in zip(m["outputs"], units, m["rmse"]))
        return f"{m['n_samples']} samples; RMSE {errors}"

    def summary(self) -> str:
        from ..core.metrics import METRIC_NAMES, METRIC_NOTES, format_metric, output_units
        from ..core.ranges import channel_text, effect_text, loads_text

        summary = self.metrics
        lines = list(self.notes)
        if not self.model.is_static:  # which prediction the table scores (predict defaults to free-run)
            lines.append(f"ARX model: metrics of {self.mode} prediction"
                         + (" (measured past outputs, the paper's evaluation)" if self.mode == "one-step"
                            else f" from {self.start} history") + "; the other mode's norm RMSE is at the end")
        outside_range, outside_span = summary["n_outside_range"], summary["n_outside_span"]
        lines.append(f"{summary['n_samples']} samples, {outside_range} outside the training input range (an input "
                     "beyond its training min/max)"
                     + (f"; {outside_span} more inside every input's range but outside the training span (input "
                        "combinations the training data never had)" if outside_span else ""))
        if outside_range:  # said once, here, with what it did to the error
            lines.append(f"  outside: {channel_text(summary['out_of_range'])}")
            if effect_text(summary["out_of_range"]):
                lines.append(f"  {effect_text(summary['out_of_range'])}")
        loads = loads_text(summary.get("loads_beyond_training"))
        if loads:  # the cross-validated error does not forecast these
            lines.append(loads)
        units = output_units(summary["outputs"])
        acf = METRIC_NAMES["residual_autocorrelation_lag1"]
        # RMSE and max |error| are in each output's unit (last column); BestFit in %; the acf has none.
        lines.append(f"{'output':<10}{'RMSE':>12}{'BestFit %':>10}{'max |error|':>13}{acf:>15}  unit")
        for name, unit, r, b, m, a in zip(summary["outputs"], units, summary["rmse"], summary["best_fit"],
                                          summary["max_abs_error"], summary["residual_autocorrelation_lag1"]):
            best = f"{100.0 * b:.2f}" if b is not None else "n/a"
            lines.append(f"{name:<10}{r:>12.5g}{best:>10}{m:>13.5g}{a:>15.3f}  {unit}")
        for key in ("force_norm_rmse", "torque_norm_rmse", "force_error_norm_rmse", "torque_error_norm_rmse"):
            if summary[key] is not None:
                lines.append(format_metric(key, summary[key]))
        for other, label in (("one_step", "one-step-ahead"), ("free_run", "free-run")):
            if other in summary and summary[other]["force_norm_rmse"] is not None:
                lines.append(f"{label} {format_metric('force_norm_rmse', summary[other]['force_norm_rmse'])}")
        lines.extend(f"  {note}" for note in METRIC_NOTES)
        return "\n".join(lines)


@dataclass(repr=False)
class PredictionResult(StepResult):
    """What :func:`predict` returns: how many rows were predicted, and where they are.

    Attributes
    ----------
    n_rows : int
    output : str or None
        The file written (CSV or Parquet), or None when the predictions are kept in ``predictions``.
    predictions : pandas.DataFrame or None
        One column per model output, one row per input row (when no ``output`` was given).
    notes : list of str
        Side remarks (standard error of ``ftcal predict``): the ARX prediction mode.
    out_of_range : dict or None
        Which inputs left the training range, how far (:meth:`ftcal.core.ranges.RangeSums.summary`).

    Examples
    --------
    >>> import numpy as np, pandas as pd
    >>> import ftcal
    >>> u = np.linspace(-1.0, 1.0, 30)
    >>> model = ftcal.fit(pd.DataFrame({"u1": u, "Fx": 4.0 * u + 0.02 * np.cos(25 * u)}),
    ...                   inputs=["u1"], outputs=["Fx"]).model
    >>> ftcal.predict(model, pd.DataFrame({"u1": [0.0, 0.5]}))
    <PredictionResult: wrote 2 predictions to memory (.predictions)>
    """

    n_rows: int
    output: str | None
    predictions: Any = None
    notes: list[str] = field(default_factory=list)
    out_of_range: dict | None = None

    def summary(self) -> str:
        where = self.output if self.output is not None else "memory (.predictions)"
        return f"wrote {self.n_rows} predictions to {where}"

    def to_dict(self) -> dict:
        from .result import plain

        return plain({"n_rows": self.n_rows, "output": self.output, "notes": self.notes,
                      "out_of_range": self.out_of_range})


def _model_and_segments(model) -> tuple[Any, tuple, str]:
    """(model, its training fingerprints, its name) from a model file path or a fitted model."""
    if isinstance(model, (str, os.PathLike)):
        from ..files.model_files import load_model_file

        loaded = load_model_file(model)
        return loaded.model, tuple(loaded.training_segments), str(model)
    if not hasattr(model, "predict") or not hasattr(model, "input_names_"):
        raise FtcalError(f"model: expected a model file name or a fitted model; got {type(model).__name__}.")
    return model, (), "the model"


def evaluate(model, data, *, mode: str = "one-step", start: str = "zeros", warmup: str = "drop",
             segment_by: str | None = None, group_by: str | None = None, scheduler: str | None = None,
             executor=None) -> EvaluationResult:
    """Metrics of a model on data with reference outputs, as ``ftcal evaluate`` gives them.

    Parameters
    ----------
    model : path or fitted model
        A model file (ftcal JSON or the paper's XML) or a model object.
    data : path, sequence of paths, pandas.DataFrame or Dataset
        With the model's input and output columns.
    mode : ``"one-step"`` (measured past outputs) or ``"free-run"``: the ARX prediction scored
    start : ``"zeros"`` or ``"measured"``: ARX free-run history at each segment start
    warmup : ``"drop"`` or ``"keep"`` the first max(na, nb) rows of each segment (ARX)
    segment_by : column separating segments (ARX; default: the 'segment' column ftcal dataset writes, when
        every table has one, as fit's); group_by : accepted for symmetry with fit, unused
    scheduler : str, optional
        ``local:N`` or a Dask address; ``executor``: an executor already open (wins over it).

    Returns
    -------
    EvaluationResult

    Raises
    ------
    FtcalError
        Bad input, or metrics that overflow (inf or NaN), in one line.

    Examples
    --------
    >>> import numpy as np, pandas as pd
    >>> import ftcal
    >>> u = np.linspace(-1.0, 1.0, 40)
    >>> frame = pd.DataFrame({"u1": u, "Fx": 2.0 * u + 0.1 * np.cos(30 * u)})
    >>> model = ftcal.fit(frame, inputs=["u1"], outputs=["Fx"]).model
    >>> result = ftcal.evaluate(model, frame)
    >>> result.metrics["n_samples"], round(result.metrics["rmse"][0], 4) == round(model.training_metrics_["rmse"][0], 4)
    (40, True)
    """
    check_arguments(EVALUATE, locals(), "ftcal.evaluate")
    from ..core.metrics import EVALUATION_KEYS

    model, training_segments, name = _model_and_segments(model)
    notes: list[str] = []
    with tables_of(data) as (paths, dataset, _):
        segment_by, _ = default_label_columns(paths, segment_by, notes)
        if dataset is None and (model.is_static or scheduler or executor is not None):
            summary = _evaluate_streaming(paths, model, training_segments, name, mode, start, warmup, segment_by,
                                          scheduler, executor)
        else:
            summary = _evaluate_whole(paths, dataset, model, training_segments, name, mode, start, warmup,
                                      segment_by)
    check_finite_metrics(summary, EVALUATION_KEYS)
    if "one_step" in summary:
        check_finite_metrics(summary["one_step"], EVALUATION_KEYS)
    outside_range, outside_span = range_and_span_counts(summary)
    metrics = {k: summary[k] for k in EVALUATION_KEYS}
    # The same two counts as the text: n_out_of_range = n_outside_range + n_outside_span.
    metrics["n_outside_range"], metrics["n_outside_span"] = outside_range, outside_span
    metrics["out_of_range"] = summary["out_of_range"]
    # loads beyond the training loads (the cross-validated error does not forecast them); see the text
    metrics["loads_beyond_training"] = summary.get("loads_beyond_training")
    for other in ("one_step", "free_run"):
        if other in summary:
            metrics[other] = {k: summary[other][k] for k in EVALUATION_KEYS if k in summary[other]}
    return EvaluationResult(model, metrics, mode, start, warmup, notes)


def _evaluate_whole(paths, dataset, model, training_segments, name, mode, start, warmup, segment_by) -> dict:
    """Metrics on the data read whole (ARX models in this process, or a Dataset given)."""
    import numpy as np

    from ..core.fingerprint import warn_if_trained_on
    from ..core.ranges import LoadSums
    from ..data.tables import load_dataset
    from ..runtime.errors import OutOfRangeWarning

    data = dataset if dataset is not None else load_dataset(paths, inputs=model.input_names_,
                                                             outputs=model.output_names_, segment_by=segment_by)
    warn_if_trained_on(data, training_segments, name)
    with warnings.catch_warnings(), np.errstate(over="ignore", invalid="ignore"):
        # Reported once in the result, not as a warning line. Overflow is refused by evaluate().
        warnings.simplefilter("ignore", OutOfRangeWarning)
        summary = model.metrics(data, mode=mode, start=start, warmup=warmup)
        summary["out_of_range"] = (range_summary(model, data, mode, start, warmup)
                                   if summary["n_out_of_range"] else None)
    y = data.outputs[:, [data.output_names.index(n) for n in model.output_names_]]
    summary["loads_beyond_training"] = load_summary(model, LoadSums.of(y, model.output_range_, model.output_names_))
    return summary


def load_summary(model, loads) -> dict | None:
    """:meth:`~ftcal.core.ranges.LoadSums.summary` of the reference loads, None without them."""
    return None if loads is None else loads.summary(model.output_range_, model.output_names_)


def range_summary(model, data, mode: str, start: str, warmup: str) -> dict:
    """Which inputs left the training range, how far, and the error there (data read whole)."""
    import numpy as np

    from ..core.ranges import RangeSums, span_of

    rows = np.ones(data.n_samples, dtype=bool)
    if warmup == "drop":  # the rows the metrics score, as CalibrationModel.metrics
        for a, _ in data.segment_bounds():
            rows[a:a + (0 if model.is_static else model.layout_.max_lag)] = False
    prediction = model.predict(data, mode=mode, start=start, warn_out_of_range=False)
    inputs = data.select_inputs(model.input_names_)
    y = data.outputs[:, [data.output_names.index(n) for n in model.output_names_]]
    return RangeSums.of(inputs, model.input_range_, y, prediction, model.output_names_, scored=rows,
                        outside_span=span_of(model, inputs)).summary(model.input_names_)


def _evaluate_streaming(paths, model, training_segments, name, mode, start, warmup, segment_by, scheduler,
                        executor) -> dict:
    """Metrics from one task per file (``scheduler``: on Dask); static models read chunk by chunk."""
    from ..core.fingerprint import warn_training_segments
    from ..data.streaming import add_error_sums, file_error_sums
    from ..runtime.executors import open_executor

    opened = nullcontext(executor) if executor is not None else open_executor(scheduler)
    with opened as running:
        sums = running.map_reduce(file_error_sums, paths, model, list(training_segments), mode, start, warmup,
                                  segment_by, combine=add_error_sums, description="evaluate")
    if sums is None:
        raise FtcalError(f"Nothing to evaluate: every segment is shorter than the ARX warm-up "
                         f"max(na, nb) = {model.layout_.max_lag} rows.")
    main, other = sums if isinstance(sums, tuple) else (sums, None)
    warn_training_segments(sorted(main.training_segments), training_segments, name)
    summary = main.summary(model.output_names_)
    summary["out_of_range"] = main.ranges.summary(model.input_names_) if main.n_out_of_range else None
    summary["loads_beyond_training"] = load_summary(model, None if main.ranges is None else main.ranges.loads)
    if other is not None:
        second = other.summary(model.output_names_)
        del second["n_out_of_range"]
        second.pop("out_of_range", None)
        summary["free_run" if mode == "one-step" else "one_step"] = second
    return summary


def check_finite_metrics(summary: dict, keys) -> None:
    """Refuse to report a metric that is inf or NaN (the predictions overflowed)."""
    for key in keys:
        values = summary.get(key)
        for value in values if isinstance(values, list) else [values]:
            if isinstance(value, float) and not math.isfinite(value):
                raise FtcalError(f"metric {key} is {value} on this data: the model's predictions overflow "
                                 "(inputs far outside its training range?); nothing to report.")


def range_and_span_counts(summary: dict) -> tuple[int, int]:
    """(samples with an input outside its training range, samples inside every range but outside the span).

    ``summary["n_out_of_range"]`` counts both (the model's :meth:`out_of_range`); the split is
    ``summary["out_of_range"]``'s, so the text and the JSON give the same two numbers.
    """
    ranges = summary.get("out_of_range")
    if not ranges:
        return 0, 0
    return int(ranges["n_out_of_range"]), int(ranges.get("n_outside_span", 0))


def predict(model, data, *, output: str | os.PathLike | None = None, mode: str = "free-run",
            start: str = "zeros", segment_by: str | None = None, scheduler: str | None = None,
            executor=None) -> PredictionResult:
    """The wrench a model predicts from raw channels, as ``ftcal predict`` gives it.

    Parameters
    ----------
    model : path or fitted model
        A model file (ftcal JSON or the paper's XML) or a model object.
    data : path, sequence of paths, pandas.DataFrame or Dataset
        With the model's input columns.
    output : path, optional
        A ``.csv`` or ``.parquet`` file to write (atomically; files are predicted one task per
        file, static models chunk by chunk). Without it the predictions come back in
        ``result.predictions`` (a DataFrame: the data is read whole).
    mode : ``"free-run"`` (fed-back predictions, as on the robot) or ``"one-step"`` (ARX)
    start : ``"zeros"`` or ``"measured"``: ARX free-run history at each segment start
    segment_by : column separating segments (ARX; default: the 'segment' column, as evaluate's)
    scheduler : str, optional
        ``local:N`` or a Dask address; ``executor``: an executor already open (wins over it).

    Returns
    -------
    PredictionResult

    Raises
    ------
    FtcalError
        Bad input, in one line.

    Examples
    --------
    >>> import numpy as np, pandas as pd
    >>> import ftcal
    >>> u = np.linspace(-1.0, 1.0, 20)
    >>> model = ftcal.fit(pd.DataFrame({"u1": u, "Fx": 2.0 * u + 0.01 * np.sin(9 * u)}),
    ...                   inputs=["u1"], outputs=["Fx"]).model
    >>> result = ftcal.predict(model, pd.DataFrame({"u1": [0.25]}))
    >>> result.n_rows, round(float(result.predictions["Fx"][0]), 1)
    (1, 0.5)
    """
    check_arguments(PREDICT, locals(), "ftcal.predict")
    from ..core.ranges import describe, loads_text
    from ..runtime.errors import OutOfRangeWarning

    model, _, _ = _model_and_segments(model)
    notes = []
    if not model.is_static:
        notes.append(f"ARX model: {mode} prediction"
                     + (f" from {start} history" if mode == "free-run" else " (measured past outputs)"))
    if output is not None:
        output = str(output)
        if not output.lower().endswith((".csv", ".parquet")):
            raise ParameterError("output", f"{{output}} {output}: must end in .csv or .parquet.")
    with tables_of(data) as (paths, dataset, _):
        segment_by, _ = default_label_columns(paths, segment_by, notes)
        if output is None or dataset is not None:
            n_rows, ranges, frame = _predict_whole(paths, dataset, model, mode, start, segment_by)
            if output is not None:
                from ..runtime.atomic import check_not_an_input
                from ..data.tables import write_table

                check_not_an_input(Path(output), "-o")
                write_table(frame, output)
                frame = None
        else:
            n_rows, ranges = _predict_streaming(paths, model, output, mode, start, segment_by, scheduler,
                                                executor)
            frame = None
    out_of_range = ranges.summary(model.input_names_) if ranges is not None else None
    # One warning for the whole call (as CalibrationModel.predict on data read whole), never per file.
    message = out_of_range and describe(out_of_range)
    loads = ranges and ranges.loads and loads_text(ranges.loads.summary(model.output_range_, model.output_names_),
                                                   "the predicted loads")
    message = " ".join(part for part in (message, loads) if part)  # one line: inputs, then loads
    if message:
        warnings.warn(message, OutOfRangeWarning, stacklevel=2)
    return PredictionResult(n_rows, output, frame, notes, out_of_range)


def _predict_whole(paths, dataset, model, mode, start, segment_by):
    """(rows, RangeSums or None, DataFrame) of the data read whole."""
    import numpy as np
    import pandas as pd

    from ..core.ranges import RangeSums, span_of
    from ..data.tables import load_dataset

    data = dataset if dataset is not None else load_dataset(paths, inputs=model.input_names_,
                                                            outputs=model.output_names_, segment_by=segment_by,
                                                            require_outputs=False)
    with np.errstate(over="ignore", invalid="ignore"):
        prediction = model.predict(data, mode=mode, start=start, warn_out_of_range=False)
    bad = ~np.isfinite(prediction).all(axis=1)
    if bad.any():
        raise FtcalError(f"data: the prediction of row {int(np.flatnonzero(bad)[0])} holds non-finite value(s) "
                         "(inf or NaN); nothing written. Inputs far outside the training range can overflow a "
                         "high-degree model.")
    inputs = data.select_inputs(model.input_names_)
    ranges = None
    if data.n_samples:
        # As the streamed path (data.streaming.predict_part): the predicted loads where the model
        # extrapolates, and not an ARX free run from zeros (its warm-up rows predict 0).
        warm_zeros = not model.is_static and mode == "free-run" and start == "zeros"
        ranges = RangeSums.of(inputs, model.input_range_, output_names=model.output_names_,
                              outside_span=span_of(model, inputs), loads=None if warm_zeros else prediction,
                              output_range=getattr(model, "output_range_", None),
                              load_rows=model.out_of_range(inputs))
    return data.n_samples, ranges, pd.DataFrame(np.asarray(prediction), columns=list(model.output_names_))


def _predict_streaming(paths, model, output, mode, start, segment_by, scheduler, executor):
    """Predict file by file (``scheduler``: one Dask task per file); static models chunk by chunk.

    Each task writes a part file in a temporary folder beside the output (on Dask, the workers
    must see that folder too); the parts are then joined in input order into the output, which
    appears only when everything worked.

    Returns
    -------
    (n_rows, ranges) : int and :class:`~ftcal.core.ranges.RangeSums` (None without rows)
    """
    import shutil
    import tempfile

    from ..data.streaming import join_parts, predict_part
    from ..runtime.atomic import check_not_an_input
    from ..runtime.executors import open_executor

    target = Path(output)
    check_not_an_input(target, "-o")
    try:
        target.parent.mkdir(parents=True, exist_ok=True)
        folder = tempfile.mkdtemp(prefix=f".{target.name}.parts-", dir=target.parent)
    except OSError as exc:
        raise FtcalError(f"{target}: cannot create the output file ({exc.strerror or exc}).") from None
    try:
        tasks = [(path, os.path.join(folder, f"part-{index:05d}{target.suffix.lower()}"))
                 for index, path in enumerate(paths)]
        opened = nullcontext(executor) if executor is not None else open_executor(scheduler)
        with opened as running:
            counts = running.map(predict_part, tasks, model, mode, segment_by, start, description="predict")
        join_parts([part for _, part in tasks], target)
    finally:
        shutil.rmtree(folder, ignore_errors=True)
    ranges = [r for _, r in counts if r is not None]
    return sum(n for n, _ in counts), (sum(ranges[1:], ranges[0]) if ranges else None)


@dataclass(repr=False)
class ReportResult(StepResult):
    """What :func:`report` returns: the page written and what it holds.

    Attributes
    ----------
    path : Path
        The HTML page.
    n_models, n_validation_samples : int
    size_mb : float
        The page's size in MB.
    notes : list of str, the defaults taken (printed first)
    """

    path: Path
    n_models: int
    n_validation_samples: int
    size_mb: float
    notes: list[str] = field(default_factory=list)

    def summary(self) -> str:
        return "\n".join(self.notes) + ("\n" if self.notes else "") + (f"wrote {self.path} ({self.n_models} model(s), {self.n_validation_samples} validation samples, "
                f"{self.size_mb:.1f} MB)")


def run_names(paths: Sequence[str]) -> list[str]:
    """Each model's file name without extension; the whole path where two names would clash."""
    stems = [Path(p).stem for p in paths]
    return [stem if stems.count(stem) == 1 else str(p) for stem, p in zip(stems, paths)]


def _union(name_lists) -> tuple[str, ...]:
    out: list[str] = []
    for names in name_lists:
        out += [n for n in names if n not in out]
    return tuple(out)


def report(models: Sequence[str], data: Sequence[str], output: str | os.PathLike, *, train: Sequence[str] = (),
           inputs: Sequence[str] | None = None, outputs: Sequence[str] | None = None,
           segment_by: str | None = None, group_by: str | None = None,
           title: str = "ftcal calibration report") -> ReportResult:
    """Evaluate model files on data files and write one self-contained HTML page, as ``ftcal report`` does.

    Parameters
    ----------
    models : model files (ftcal JSON or the paper's XML)
    data : validation data files (CSV or Parquet)
    output : the page (.html)
    train : training data files: adds training metrics and their coverage
    inputs, outputs : columns to read (default: every input and output any model uses)
    segment_by, group_by : columns naming segments and groups (default: the 'segment' and 'load' columns
        ftcal dataset writes, when every table has them, else one per file)
    title : the page's title

    Returns
    -------
    ReportResult
    """
    from ..core.fingerprint import warn_if_trained_on
    from ..data.tables import load_dataset
    from ..files.model_files import load_model_file
    from ..report import build_report
    from ..report import evaluate as evaluate_run

    model_paths, data_paths, train_paths = [str(p) for p in models], [str(p) for p in data], [str(p) for p in train]
    loaded = [load_model_file(p) for p in model_paths]
    fitted = [m.model for m in loaded]
    inputs = tuple(inputs or _union(m.input_names_ for m in fitted))
    outputs = tuple(outputs or _union(m.output_names_ for m in fitted))
    defaults: list[str] = []
    segment_by, group_by = default_label_columns(data_paths + train_paths, segment_by, defaults, group_by=group_by,
                                                 groups=True)

    def read(paths):
        return load_dataset(paths, inputs=inputs, outputs=outputs, segment_by=segment_by, group_by=group_by)

    validation = read(data_paths)
    for path, model_file in zip(model_paths, loaded):
        warn_if_trained_on(validation, model_file.training_segments, path)
    training = read(train_paths) if train_paths else None
    runs = [evaluate_run(model, validation, name=name, train=training)
            for model, name in zip(fitted, run_names(model_paths))]
    notes = [f"Model files: {', '.join(model_paths)}.", f"Validation data files: {', '.join(data_paths)}."]
    if train_paths:
        notes.append(f"Training data files: {', '.join(train_paths)}.")
    path = build_report(runs, validation, Path(output), train=training, title=title, notes=notes)
    return ReportResult(path, len(runs), validation.n_samples, path.stat().st_size / 1e6, defaults)
