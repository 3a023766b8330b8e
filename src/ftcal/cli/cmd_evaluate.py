"""``ftcal evaluate``: metrics of a model on data with reference outputs."""

from __future__ import annotations

import math
import warnings

from ..core.limits import ARX_WARMUP, FREE_RUN_STARTS, PREDICTION_MODES
from ._common import add_scheduler_option, print_json
from ._examples import epilog


def register(sub) -> None:
    p = sub.add_parser("evaluate", **epilog("evaluate"), help="metrics of a model on held-out data")
    p.add_argument("model", metavar="MODEL", help="model file (ftcal JSON or paper XML)")
    p.add_argument("data", nargs="+", metavar="DATA", help="CSV or Parquet files with the model's columns")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.add_argument("--mode", choices=PREDICTION_MODES, default="one-step",
                   help="ARX prediction mode: one-step (default, the paper's evaluation: measured past outputs, "
                        "which evaluation data hold) or free-run (fed-back predictions, as on the robot and "
                        "'ftcal predict''s default); the table scores this mode and says so, the other mode's "
                        "norm RMSE follows it")
    p.add_argument("--start", choices=FREE_RUN_STARTS, default="zeros",
                   help="ARX free-run history at each segment start: zeros (default, the paper's code: the "
                        "first max(na,nb) rows predict 0) or measured (ftcal's: the first measured output)")
    p.add_argument("--warmup", choices=ARX_WARMUP, default="drop",
                   help="ARX metrics: drop (default, as the paper's code) or keep the first max(na,nb) rows "
                        "of each segment")
    p.add_argument("--segment-by", metavar="COL", help="column separating segments (ARX)")
    p.add_argument("--group-by", metavar="COL", help="accepted for symmetry with fit; unused")
    add_scheduler_option(p)
    p.set_defaults(func=run)


def evaluate(args):
    import numpy as np

    from ..core.fingerprint import warn_if_trained_on
    from ..core.ranges import LoadSums
    from ..data.tables import read_dataset
    from ..files.model_files import read_model_file
    from ..runtime.errors import OutOfRangeWarning

    loaded = read_model_file(args.model)
    model = loaded.model
    if model.is_static or args.scheduler:
        return model, evaluate_streaming(args, model, loaded.training_segments)
    data = read_dataset(args.data, model.input_names_, model.output_names_, segment_by=args.segment_by)
    warn_if_trained_on(data, loaded.training_segments, args.model)
    with warnings.catch_warnings(), np.errstate(over="ignore", invalid="ignore"):
        # Reported once in the output (run()), not as a warning line. Overflow is refused in run().
        warnings.simplefilter("ignore", OutOfRangeWarning)
        summary = model.score(data, mode=args.mode, start=args.start, warmup=args.warmup)
        summary["out_of_range"] = range_summary(model, data, args) if summary["n_out_of_range"] else None
    summary["loads_beyond_training"] = load_summary(
        model, LoadSums.of(data.outputs[:, [data.output_names.index(n) for n in model.output_names_]],
                           model.output_range_, model.output_names_))
    return model, summary


def load_summary(model, loads) -> dict | None:
    """:meth:`~ftcal.core.ranges.LoadSums.summary` of the reference loads, None without them."""
    return None if loads is None else loads.summary(model.output_range_, model.output_names_)


def range_summary(model, data, args) -> dict:
    """Which inputs left the training range, how far, and the error there (ARX models, data read whole)."""
    import numpy as np

    from ..core.ranges import RangeSums, span_of

    rows = np.ones(data.n_samples, dtype=bool)
    if args.warmup == "drop":  # the rows the metrics score, as CalibrationModel.score
        for a, b in data.segment_bounds():
            rows[a:a + (0 if model.is_static else model.layout_.max_lag)] = False
    prediction = model.predict(data, mode=args.mode, start=args.start, warn_out_of_range=False)
    inputs = data.select_inputs(model.input_names_)
    y = data.outputs[:, [data.output_names.index(n) for n in model.output_names_]]
    return RangeSums.of(inputs, model.input_range_, y, prediction, model.output_names_, scored=rows,
                        outside_span=span_of(model, inputs)).summary(model.input_names_)


def evaluate_streaming(args, model, training_segments) -> dict:
    """Metrics from one task per file (``--scheduler``: on Dask); static models read chunk by chunk.

    ARX models in this process keep the whole-data path (:meth:`CalibrationModel.score`),
    which gives the same metrics.
    """
    from ..core.fingerprint import warn_training_segments
    from ..data.streaming import add_error_sums, file_error_sums
    from ..runtime.errors import FtcalError
    from ..runtime.executors import open_executor

    with open_executor(args.scheduler) as executor:
        sums = executor.map_reduce(file_error_sums, args.data, model, list(training_segments), args.mode,
                                   args.start, args.warmup, args.segment_by, combine=add_error_sums,
                                   description="evaluate")
    if sums is None:
        raise FtcalError(f"Nothing to evaluate: every segment is shorter than the ARX warm-up "
                         f"max(na, nb) = {model.layout_.max_lag} rows.")
    main, other = sums if isinstance(sums, tuple) else (sums, None)
    warn_training_segments(sorted(main.training_segments), training_segments, args.model)
    summary = main.summary(model.output_names_)
    summary["out_of_range"] = main.ranges.summary(model.input_names_) if main.n_out_of_range else None
    summary["loads_beyond_training"] = load_summary(model, None if main.ranges is None else main.ranges.loads)
    if other is not None:
        second = other.summary(model.output_names_)
        del second["n_out_of_range"]
        second.pop("out_of_range", None)
        summary["free_run" if args.mode == "one-step" else "one_step"] = second
    return summary


def check_finite_metrics(summary: dict, keys) -> None:
    """Refuse to report a metric that is inf or NaN (the predictions overflowed)."""
    from ..runtime.errors import FtcalError

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


def run(args) -> int:
    from ..core.metrics import EVALUATION_KEYS as JSON_KEYS
    from ..core.metrics import METRIC_NAMES, METRIC_NOTES, format_metric, output_units
    from ..core.ranges import channel_text, effect_text, loads_text

    model, summary = evaluate(args)
    check_finite_metrics(summary, JSON_KEYS)
    if "one_step" in summary:
        check_finite_metrics(summary["one_step"], JSON_KEYS)
    outside_range, outside_span = range_and_span_counts(summary)
    if args.json:
        payload = {k: summary[k] for k in JSON_KEYS}
        # The same two counts as the text: n_out_of_range = n_outside_range + n_outside_span.
        payload["n_outside_range"], payload["n_outside_span"] = outside_range, outside_span
        payload["out_of_range"] = summary["out_of_range"]
        # loads beyond the training loads (the cross-validated error does not forecast them); see the text
        payload["loads_beyond_training"] = summary.get("loads_beyond_training")
        for other in ("one_step", "free_run"):
            if other in summary:
                payload[other] = {k: summary[other][k] for k in JSON_KEYS if k in summary[other]}
        print_json(payload)
        return 0
    if not model.is_static:  # which prediction the table scores (predict defaults to free-run)
        print(f"ARX model: metrics of {args.mode} prediction"
              + (" (measured past outputs, the paper's evaluation)" if args.mode == "one-step"
                 else f" from {args.start} history") + "; the other mode's norm RMSE is at the end")
    print(f"{summary['n_samples']} samples, {outside_range} outside the training input range (an input beyond "
          "its training min/max)" + (f"; {outside_span} more inside every input's range but outside the training "
                                     "span (input combinations the training data never had)" if outside_span else ""))
    if outside_range:  # said once, here, with what it did to the error
        print(f"  outside: {channel_text(summary['out_of_range'])}")
        if effect_text(summary["out_of_range"]):
            print(f"  {effect_text(summary['out_of_range'])}")
    loads = loads_text(summary.get("loads_beyond_training"))
    if loads:
        print(loads)
    units = output_units(summary["outputs"])
    acf = METRIC_NAMES["residual_autocorrelation_lag1"]
    # RMSE and max |error| are in each output's unit (last column); BestFit in %; the acf has none.
    print(f"{'output':<10}{'RMSE':>12}{'BestFit %':>10}{'max |error|':>13}{acf:>15}  unit")
    for name, unit, r, b, m, a in zip(summary["outputs"], units, summary["rmse"], summary["best_fit"],
                                      summary["max_abs_error"], summary["residual_autocorrelation_lag1"]):
        best = f"{100.0 * b:.2f}" if b is not None else "n/a"
        print(f"{name:<10}{r:>12.5g}{best:>10}{m:>13.5g}{a:>15.3f}  {unit}")
    for key in ("force_norm_rmse", "torque_norm_rmse", "force_error_norm_rmse", "torque_error_norm_rmse"):
        if summary[key] is not None:
            print(format_metric(key, summary[key]))
    for other, label in (("one_step", "one-step-ahead"), ("free_run", "free-run")):
        if other in summary and summary[other]["force_norm_rmse"] is not None:
            print(f"{label} {format_metric('force_norm_rmse', summary[other]['force_norm_rmse'])}")
    for note in METRIC_NOTES:
        print(f"  {note}")
    return 0
