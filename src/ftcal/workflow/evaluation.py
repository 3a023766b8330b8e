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
    comparison : :class:`~ftcal.core.baseline.BaselineComparison` or None
        Against ``baseline`` (after ``tare``): per-axis ratios and the grouped folds' verdict (printed last;
        ``metrics["baseline"]`` in the JSON).

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
    comparison: Any = None

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
        if self.comparison is not None:
            lines.extend(self.comparison.lines())
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


def _model_and_segments(model, parameter: str = "model") -> tuple[Any, tuple, str]:
    """(model, its training fingerprints, its name) from a model file path or a fitted model (``parameter``: the
    argument it came in, named when it is neither)."""
    if isinstance(model, (str, os.PathLike)):
        from ..files.model_files import load_model_file

        if not os.fspath(model):
            raise ParameterError(parameter, f"{{{parameter}}}: an empty file name; give a model file or a fitted "
                                            "model.")

        loaded = load_model_file(model)
        return loaded.model, tuple(loaded.training_segments), str(model)
    if not hasattr(model, "predict") or not hasattr(model, "input_names_"):
        raise ParameterError(parameter, f"{{{parameter}}}: expected a model file name or a fitted model; "
                                        f"got {type(model).__name__}.")
    return model, (), "the model"


def evaluate(model, data, *, mode: str = "one-step", start: str = "zeros", warmup: str = "drop",
             segment_by: str | None = None, group_by: str | None = None, scheduler: str | None = None,
             executor=None, baseline=None, tare: str = "none") -> EvaluationResult:
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
        every table has one, as fit's); group_by : the folds of the baseline comparison (default: the 'load'
        column ftcal dataset writes, when every table has one, else one per file)
    scheduler : str, optional
        ``local:N`` or a Dask address; ``executor``: an executor already open (wins over it).
    baseline : ``"identity"``, a model file or a fitted model, optional
        What the model is compared with on the same samples: ``identity`` reads the model's first six inputs
        as its outputs (the channels already are a wrench: the vendor's matrix); a model file predicts
        from its own inputs. Static models only.
    tare : ``"none"``, ``"first-hold"`` or ``"per-file"``
        Remove each recording's offset (or each file's) at its first static hold, from the model and the
        baseline alike, as users re-tare (:mod:`ftcal.data.tare`); the comparison is then of tared errors.

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
    comparison = None
    if baseline is not None or tare != "none":
        with tables_of(data) as (paths, dataset, _):
            comparison = compare_with_baseline(model, paths, dataset, baseline, tare, segment_by, group_by, notes)
        metrics["baseline"] = comparison.as_dict()
    return EvaluationResult(model, metrics, mode, start, warmup, notes, comparison)


IDENTITY = "identity"


def baseline_predictor(baseline, model) -> tuple[Any, tuple[str, ...], str]:
    """(predict(inputs) -> outputs in the model's order, its input columns, its name) of a baseline.

    ``identity``: the model's first len(outputs) inputs read as its outputs (the channels already are a
    wrench); a model file or fitted model: its prediction, its columns reordered as the model's outputs.
    """
    import numpy as np

    outputs = tuple(model.output_names_)
    if isinstance(baseline, str) and baseline == IDENTITY:
        inputs = tuple(model.input_names_[:len(outputs)])
        if len(inputs) < len(outputs):
            raise FtcalError(f"baseline identity: the model has {len(inputs)} inputs for {len(outputs)} outputs; "
                             "identity reads its first inputs as the wrench.")
        return (lambda u: np.asarray(u, float)), inputs, f"identity ({','.join(inputs)} read as "\
                                                       f"{','.join(outputs)})"
    other, _, name = _model_and_segments(baseline, "baseline")
    if not other.is_static:
        raise FtcalError(f"baseline {name}: an ARX model; baselines are static models (or identity).")
    missing = [n for n in outputs if n not in other.output_names_]
    if missing:
        raise FtcalError(f"baseline {name}: has no output(s) {', '.join(missing)} of the model.")
    order = [list(other.output_names_).index(n) for n in outputs]
    return (lambda u: other.predict(u, warn_out_of_range=False)[:, order]), tuple(other.input_names_), name


def compare_with_baseline(model, paths, dataset, baseline, tare: str, segment_by, group_by, notes: list[str]):
    """The model's and the baseline's errors on the data read whole, tared alike, compared fold by fold.

    Returns
    -------
    :class:`~ftcal.core.baseline.BaselineComparison`
    """
    import numpy as np

    from ..core.baseline import compare_to_baseline
    from ..data.tare import check_tare, tare_offsets

    check_tare(tare, "tare")
    if not model.is_static:
        raise FtcalError("baseline/tare: the comparison takes static models (no ARX lags).")
    outputs = tuple(model.output_names_)
    if baseline is None:  # a tare alone: the model tared against itself untared (what the re-tare gives)
        predict, base_inputs, base_name = None, tuple(model.input_names_), "the model without tare"
    else:
        predict, base_inputs, base_name = baseline_predictor(baseline, model)
    parts = _comparison_parts(paths, dataset, model, base_inputs, outputs, segment_by, group_by, notes)
    u, ub, y, recordings, folds, files, time, hold = (np.concatenate([p[k] for p in parts]) if parts[0][k] is not None
                                                      else None for k in range(8))
    model_error = model.predict(u, warn_out_of_range=False) - y
    base_error = model_error if predict is None else predict(ub) - y
    offsets = tare_offsets([model_error, base_error], y, recordings, files, tare, time=time, hold=hold,
                           notes=notes)
    if predict is None:
        return compare_to_baseline(model_error - offsets[0], base_error, folds, outputs, base_name, f"{tare}, "
                                   "the model only")
    return compare_to_baseline(model_error - offsets[0], base_error - offsets[1], folds, outputs, base_name, tare)


def _comparison_parts(paths, dataset, model, base_inputs, outputs, segment_by, group_by, notes) -> list[tuple]:
    """Per table: (model inputs, baseline inputs, reference, recording, fold, file, time or None, hold or None)."""
    import numpy as np

    from ..data.tables import numeric_columns, read_table, table_label_column

    if dataset is not None:
        def columns(names):
            missing = [n for n in names if n not in dataset.input_names]
            if missing:
                raise FtcalError(f"data: no input column(s) {', '.join(missing)}.")
            return dataset.select_inputs(names)

        y = dataset.outputs[:, [dataset.output_names.index(n) for n in outputs]]
        return [(columns(model.input_names_), columns(base_inputs), y, dataset.segments, dataset.groups,
                 np.zeros(dataset.n_samples, dtype=int), None, None)]
    if group_by is None:
        _, group_by = default_label_columns(list(paths), "", notes, groups=True)
    parts = []
    for path in paths:
        frame = read_table(path)
        where = Path(path)
        n = len(frame)
        fold_column = table_label_column(list(frame.columns), group_by)
        if fold_column is not None and fold_column not in frame.columns:
            raise ParameterError("group_by", f"{path}: no group column {fold_column!r} ({{group_by}}).")
        if segment_by is not None and segment_by not in frame.columns:
            raise ParameterError("segment_by", f"{path}: no segment column {segment_by!r} ({{segment_by}}).")
        parts.append((numeric_columns(frame, model.input_names_, where, "input"),
                      numeric_columns(frame, base_inputs, where, "baseline input"),
                      numeric_columns(frame, outputs, where, "reference output"),
                      frame[segment_by].astype(str).to_numpy(dtype=object) if segment_by
                      else np.full(n, "", dtype=object),
                      frame[fold_column].astype(str).to_numpy(dtype=object) if fold_column
                      else np.full(n, str(path), dtype=object),
                      np.full(n, str(path), dtype=object),
                      numeric_columns(frame, ("time",), where, "time")[:, 0] if "time" in frame.columns else None,
                      numeric_columns(frame, ("hold",), where, "hold")[:, 0] if "hold" in frame.columns else None))
    if len({p[6] is None for p in parts}) > 1 or len({p[7] is None for p in parts}) > 1:
        # one clock for all or none: rows at the hold sample rate where a table has no time column
        raise FtcalError("data: some tables have a 'time' (or 'hold') column and others not; give tables alike.")
    return parts


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
    return None if loads is None else loads.to_dict(model.output_range_, model.output_names_)


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
                        outside_span=span_of(model, inputs)).to_dict(model.input_names_)


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
    summary = main.to_dict(model.output_names_)
    summary["out_of_range"] = main.ranges.to_dict(model.input_names_) if main.n_out_of_range else None
    summary["loads_beyond_training"] = load_summary(model, None if main.ranges is None else main.ranges.loads)
    if other is not None:
        second = other.to_dict(model.output_names_)
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

                check_not_an_input(Path(output))
                write_table(frame, output)
                frame = None
        else:
            n_rows, ranges = _predict_streaming(paths, model, output, mode, start, segment_by, scheduler,
                                                executor)
            frame = None
    out_of_range = ranges.to_dict(model.input_names_) if ranges is not None else None
    # One warning for the whole call (as CalibrationModel.predict on data read whole), never per file.
    message = out_of_range and describe(out_of_range)
    loads = ranges and ranges.loads and loads_text(ranges.loads.to_dict(model.output_range_, model.output_names_),
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
    check_not_an_input(target)
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
           title: str = "ftcal calibration report", baseline=None, tare: str = "none") -> ReportResult:
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
    baseline, tare : as :func:`evaluate`'s: a section compares every model with the baseline (identity: the
        inputs read as the wrench, or a model file), tared alike, fold by fold over the groups

    Returns
    -------
    ReportResult
    """
    from ..core.fingerprint import warn_if_trained_on
    from ..data.tables import load_dataset
    from ..files.model_files import load_model_file
    from ..report import build_report
    from ..report import evaluate_run

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
    comparisons = []
    if baseline is not None or tare != "none":
        comparisons = [(name, compare_with_baseline(model, data_paths, None, baseline, tare, segment_by, group_by,
                                                    defaults))
                       for model, name in zip(fitted, run_names(model_paths))]
    path = build_report(runs, validation, Path(output), train=training, title=title, notes=notes,
                        comparisons=comparisons)
    return ReportResult(path, len(runs), validation.n_samples, path.stat().st_size / 1e6, defaults)
