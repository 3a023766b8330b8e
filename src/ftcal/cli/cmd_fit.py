"""``ftcal fit``: fit a calibration model to tables of samples."""

from __future__ import annotations

import argparse
import sys
import time

from ..core.limits import (
    MAX_DEGREE,
    MAX_LAG,
    NORMALIZATIONS,
    OBJECTIVES,
    PAPER_LAMBDAS,
    SELECT_PER,
    SELECTION_BUDGET_SECONDS,
    SOLVERS,
)
from ._common import (
    norm_rmse_text,
    add_column_options,
    add_scheduler_option,
    default_inputs,
    float_list,
    nonnegative_int,
    positive_float,
    require_suffix,
)
from ._examples import epilog
from ._fit_mlp import add_family_options

STREAMING_NOTE = """Fits stream the files (except --solver osqp and --estimate-payload, which read
them whole): a pass for the column ranges (the normalization), one for the sufficient statistics
(summed, then solved here; --degree auto: a pass per degree and basis tried, per fold, and the
selection is solved from those sums; ARX: lags inside segments), one for the training metrics;
memory: one chunk (one file for ARX) plus p x p (--degree auto: p x p per fold).

--degree auto chooses a degree, penalty and lambda per force/torque block (--select-per block, the
default), per output, or one for the whole model, by grouped cross-validation, and prints force
(N) and torque (N.m) errors side by side against the affine model (--verbose: every candidate; the
model file keeps the whole table under fit.solver.cross_validation). Lambda grids are relative, so
they mean the same whatever the number of samples: LASSO lambda / lambda_max (the smallest lambda
that zeroes every coefficient), ridge lambda / lambda_ref (the mean eigenvalue of the Gram matrix:
its trace over p). It estimates its cost first and leaves out degrees over --budget.
"""


def lambda_grid(text: str) -> tuple[float, ...]:
    """``paper`` (the paper's six absolute values) or a comma-separated list of positive relative values."""
    if text == "paper":
        return PAPER_LAMBDAS
    values = float_list(text)
    if len(set(values)) != len(values):
        raise argparse.ArgumentTypeError(f"each value once, got {text!r}")
    return values


def penalty_list(text: str) -> tuple[str, ...]:
    names = tuple(part.strip() for part in text.split(",") if part.strip())
    bad = [n for n in names if n not in ("lasso", "ridge")]
    if bad or not names:
        raise argparse.ArgumentTypeError(f"expected a list of lasso, ridge; got {text!r}")
    return names


def degree_value(text: str) -> int | str:
    if text == "auto":
        return text
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected 1..{MAX_DEGREE} or 'auto', got {text!r}") from None
    if not 1 <= value <= MAX_DEGREE:
        raise argparse.ArgumentTypeError(f"must be in 1..{MAX_DEGREE} or 'auto', got {text!r}")
    return value


def register(sub) -> None:
    p = sub.add_parser("fit", help="fit a calibration model", **epilog("fit", STREAMING_NOTE))
    p.add_argument("data", nargs="+", metavar="DATA", help="CSV or Parquet files (each one segment and group)")
    add_column_options(p)
    p.add_argument("--degree", type=degree_value,
                   help=f"polynomial degree, 1 to {MAX_DEGREE} (the paper fits 1 to 5), or 'auto' for grouped "
                        "cross-validation over 1 to --max-degree (default 1: affine)")
    penalty = p.add_mutually_exclusive_group()
    penalty.add_argument("--lasso", type=positive_float, metavar="LAMBDA",
                         help="LASSO: minimize 1/2|A t - y|^2 + LAMBDA |t|_1 on the paper's regressor A (raw "
                              "monomials, each column divided by its max |value|, offset column 1). An absolute "
                              "weight, for reproducing the paper: its 0.5 .. 200 (Table III) are on the scale of its "
                              "own data set's sum of squares; the useful value grows with the number of samples and "
                              "the output units, so prefer --degree auto, whose grid is relative to lambda_max")
    penalty.add_argument("--ridge", type=positive_float, metavar="LAMBDA",
                         help="ridge: minimize 1/2|A t - y|^2 + 1/2 LAMBDA |t|^2 on the same regressor (sklearn "
                              "Ridge alpha; a QP written 1/2|A t - y|^2 + L |t|^2, as in the paper's MATLAB, "
                              "has LAMBDA = 2 L)")
    p.add_argument("--na", type=nonnegative_int, default=0, help=f"ARX: number of past outputs, 0-{MAX_LAG} (default 0)")
    p.add_argument("--nb", type=nonnegative_int, default=0, help=f"ARX: input lags, 0-{MAX_LAG} (default 0)")
    p.add_argument("--solver", choices=SOLVERS, default="lstsq",
                   help="lstsq: streaming exact solver (default); osqp: the paper's QP, for comparison")
    p.add_argument("--normalization", choices=NORMALIZATIONS, default=None,
                   help="basis of the coefficients: maxabs (the paper's: inputs over max |u|; default with "
                        "--lasso/--ridge, whose LAMBDA is defined on its columns) or center (inputs mapped to "
                        "[-1, 1]; default for least squares). Least squares is exact whatever this says: it is "
                        "solved in the centred basis and mapped. 'center' with --lasso is the centred LASSO, "
                        "a different problem")
    p.add_argument("--folds", type=int, default=5, help="cross-validation folds for --degree auto (default 5)")
    p.add_argument("--penalties", type=penalty_list, default=("lasso", "ridge"), metavar="P1,P2",
                   help="penalized candidates for --degree auto beside least squares (default lasso,ridge)")
    p.add_argument("--lambdas", type=lambda_grid, metavar="R1,R2,...",
                   help="fixed relative lambda grid for --degree auto: fractions of lambda_max (LASSO) and of "
                        "lambda_ref = trace(A'A)/p (ridge), the same whatever the number of samples; or 'paper' "
                        "for the paper's absolute 0.5,1,10,50,100,200 (default: from the data, 1 down three "
                        "decades of lambda_max for LASSO, six decades of lambda_ref for ridge, extended where "
                        "the best value sits at an edge)")
    p.add_argument("--select-per", choices=SELECT_PER, default="block",
                   help="--degree auto: choose degree, penalty and lambda for the force and the torque block "
                        "(default: on held-out load cases it was never worse than one model, and per output was "
                        "less robust; see benchmarks/bench_select.py), for each output, or one for the whole "
                        "model. A mixed selection is stored at the largest selected degree with exact zeros for "
                        "the terms an output does not use")
    p.add_argument("--objective", choices=OBJECTIVES, default="both",
                   help="--degree auto: what ranks one candidate serving force and torque (--select-per model): "
                        "both (force and torque errors each relative to affine, averaged; default), force or "
                        "torque. Force and torque are always reported, and a selection worse than affine on "
                        "either beyond the fold noise is flagged")
    p.add_argument("--max-degree", type=int, default=5, metavar="D",
                   help=f"--degree auto: highest degree tried, 1 to {MAX_DEGREE} (default 5)")
    p.add_argument("--budget", type=positive_float, default=SELECTION_BUDGET_SECONDS, metavar="SECONDS",
                   help="--degree auto: CPU seconds for the whole command; degrees whose estimated cost (printed "
                        "before the search, re-checked before each degree at the pace measured so far) would "
                        f"exceed it are left out and named (default {SELECTION_BUDGET_SECONDS:g} s, or 1 GB of "
                        "statistics)")
    p.add_argument("--verbose", action="store_true",
                   help="--degree auto: print every candidate, not only the best of each degree")
    p.add_argument("--drop-incomplete", action="store_true",
                   help="drop the rows with an empty cell in the columns used, and say how many (default: "
                        "refuse them)")
    p.add_argument("--prior", metavar="MODEL.json",
                   help="shrink toward this model (e.g. the workbench or last month's calibration) instead of "
                        "toward zero: the --ridge/--lasso penalty acts on theta - theta_prior (same inputs, "
                        "outputs and lags, degree at most this fit's)")
    p.add_argument("--estimate-payload", metavar="LINK",
                   help="estimate an unknown payload on LINK (mass, first moments; inertia with dynamic data) from "
                        "the same data, then fit the calibration to the completed wrench; needs a dataset from "
                        "'ftcal dataset --estimate-payload LINK'")
    p.add_argument("--payload-mass", type=positive_float, metavar="KG",
                   help="known mass of that payload (needed when nothing else beyond the sensor moves relative "
                        "to LINK: the mass would trade against the force gains)")
    add_scheduler_option(p)
    add_family_options(p)
    p.add_argument("-o", "--output", required=True, metavar="MODEL.json", help="model file to write")
    p.set_defaults(func=run)


def make_solver(args):
    from ..core.solvers.lasso import Lasso
    from ..core.solvers.least_squares import LeastSquares, Ridge
    from ..core.solvers.osqp_qp import OsqpLasso, OsqpLeastSquares

    if args.solver == "osqp":
        return OsqpLasso(args.lasso) if args.lasso else OsqpLeastSquares()
    if args.lasso:
        return Lasso(args.lasso)
    if args.ridge:
        return Ridge(args.ridge)
    return LeastSquares()


def check_options(args) -> None:
    """Option combinations that cannot work, refused before any data is read."""
    import warnings

    from ..runtime.errors import FtcalError, FtcalWarning

    if args.solver == "osqp" and args.ridge:
        raise FtcalError("--solver osqp implements the paper's least-squares and LASSO programs, not --ridge.")
    if args.degree == "auto" and args.solver == "osqp":
        raise FtcalError("--degree auto uses the streaming solvers; drop --solver osqp.")
    if args.prior and args.degree != "auto" and not (args.lasso or args.ridge):
        raise FtcalError("--prior shrinks a penalized fit toward another model; add --ridge or --lasso "
                         "(or --degree auto).")
    if args.degree is None:
        if args.lasso or args.ridge:
            warnings.warn(f"--{'lasso' if args.lasso else 'ridge'} without --degree fits degree 1 (affine); "
                          "give --degree (the paper's LASSO models are degree 4).", FtcalWarning, stacklevel=2)
        args.degree = 1
    if args.folds < 2:
        raise FtcalError(f"--folds must be at least 2; got {args.folds}.")
    # Options of the --degree auto search are refused, not ignored, by a fit of a given degree.
    search = {"folds": 5, "penalties": ("lasso", "ridge"), "lambdas": None, "select_per": "block",
              "objective": "both", "max_degree": 5, "budget": SELECTION_BUDGET_SECONDS, "verbose": False}
    if args.degree != "auto":
        for name, default in search.items():
            if getattr(args, name) != default:
                raise FtcalError(f"--{name.replace('_', '-')} goes with --degree auto (the search); a fit of "
                                 f"--degree {args.degree} does not use it.")
    elif args.lasso or args.ridge:
        for name in ("penalties", "lambdas"):
            if getattr(args, name) != search[name]:
                raise FtcalError(f"--{name}: the search's penalty is fixed by --{'lasso' if args.lasso else 'ridge'} "
                                 "λ; give one or the other.")
    for flag in ("na", "nb"):
        if getattr(args, flag) > MAX_LAG:
            raise FtcalError(f"--{flag} must be at most {MAX_LAG}; got {getattr(args, flag)}.")
    if not 1 <= args.max_degree <= MAX_DEGREE:
        raise FtcalError(f"--max-degree must be in 1..{MAX_DEGREE}; got {args.max_degree}.")
    if args.objective != "both" and args.select_per != "model":
        raise FtcalError(f"--objective {args.objective} ranks one model for all outputs; add --select-per model "
                         f"(with --select-per {args.select_per} each part is ranked by its own error).")
    if args.drop_incomplete and args.scheduler:
        raise FtcalError("--drop-incomplete filters rows in this process; drop --scheduler to use it.")
    if args.scheduler and not streams(args):
        raise FtcalError("--scheduler runs fits with the streaming solvers; it does not run --estimate-payload "
                         "or --solver osqp (drop --scheduler for those).")


def streams(args) -> bool:
    """Whether this fit streams its files (one task per file, chunk by chunk) instead of reading them whole."""
    return args.estimate_payload is None and args.solver != "osqp"


def cross_validation(args, data, template, n_samples: int, n_inputs: int):
    """The ``--degree auto`` search over ``data`` (a Dataset or streamed statistics), its cost and summary printed."""
    from ..core.limits import SELECTION_MEMORY_BYTES
    from ..core.dataset import Dataset
    from ..core.select import (
        Candidate,
        DatasetStatistics,
        SearchBudget,
        cross_validate,
        estimate_cost,
        select_model,
    )
    from ..runtime.progress import progress_bar

    if isinstance(data, Dataset):
        data = DatasetStatistics(data)
    n_outputs, n_groups = len(data.output_names), len(data.group_sizes())
    fixed = ("lasso",) if args.lasso else ("ridge",) if args.ridge else ()
    penalties = fixed or args.penalties
    n_lambdas = 1 if fixed else (len(args.lambdas) if args.lambdas else None)
    estimate = estimate_cost(n_samples, n_inputs, n_outputs, range(1, args.max_degree + 1),
                             min(args.folds, n_groups), penalties=penalties,
                             n_lambdas=n_lambdas, na=args.na, nb=args.nb,
                             n_bases=1 if template.normalization == "center" or fixed or not penalties else 2,
                             spent_seconds=time.process_time() - args.cpu_start)
    degrees, note = estimate.within(args.budget, SELECTION_MEMORY_BYTES)
    planned = estimate.restricted(degrees)
    print(planned.describe() + f" (--budget {args.budget:g} s)")
    if note:
        print(note)
    options = dict(template=template, n_folds=args.folds, select_per=args.select_per, objective=args.objective)
    # One bar over the whole search: (candidate, fold) fits, as many as the estimate plans.
    with progress_bar("search", planned.candidates * planned.n_folds * len(degrees)) as advance:
        if args.lasso or args.ridge:
            kind = "lasso" if args.lasso else "ridge"
            result = cross_validate(data, [Candidate(d, kind, args.lasso or args.ridge) for d in degrees],
                                    advance=advance, **options)
        else:
            paper = args.lambdas is not None and args.lambdas == PAPER_LAMBDAS
            budget = SearchBudget(args.budget, planned, clock=lambda: time.process_time() - args.cpu_start)
            result = select_model(data, degrees=degrees, penalties=args.penalties, lambdas=args.lambdas,
                                  relative=not paper, budget=budget, advance=advance, **options)
    print(result.table() if args.verbose else result.summary())
    from ..core.excitation import group_output_ranges, held_out_span

    ranges = group_output_ranges(data.data.outputs, data.data.groups) if isinstance(data, DatasetStatistics) \
        else getattr(getattr(data, "summary", None), "group_output_ranges", None)
    if ranges and result.search is not None:
        span = held_out_span(ranges, result.search.fold_of, data.output_names)
        print(span)
        result.notes.append(span)
    result.notes.extend([planned.describe()] + ([note] if note else []))  # for the model file
    return result


def run(args) -> int:
    from contextlib import nullcontext

    from ..core.fingerprint import segment_fingerprints
    from ..core.model import CalibrationModel
    from ..data.tables import drop_incomplete
    from ..files.model_json import save_model
    from ._fit_mlp import check_family_options, fit_mlp, report_mlp
    from ._fit_payload import check_payload_options

    require_suffix(args.output, (".json",), "-o")
    check_family_options(args)
    if args.family == "mlp":
        model, data = fit_mlp(args, args.inputs or default_inputs(args.data),
                              args.outputs or ("Fx", "Fy", "Fz", "Tx", "Ty", "Tz"))
        save_model(model, args.output, sources=[str(p) for p in args.data],
                   training_segments=segment_fingerprints(data))
        if getattr(model, "family", "polynomial") == "mlp":
            report_mlp(model, args.output)
        else:  # the MLP lost to the affine model beyond the fold noise: that is what was written
            report_fit(model, args.output)
        return 0
    check_options(args)
    check_payload_options(args)
    inputs = args.inputs or default_inputs(args.data)
    outputs = args.outputs or ("Fx", "Fy", "Fz", "Tx", "Ty", "Tz")
    prior = None
    if args.prior:
        from ..files.model_files import read_model

        prior = read_model(args.prior)
    template = CalibrationModel(na=args.na, nb=args.nb, normalization=args.normalization, prior=prior)
    with drop_incomplete() if args.drop_incomplete else nullcontext() as dropped:
        if streams(args):
            return fit_streaming(args, template, inputs, outputs, dropped)
        return fit_in_memory(args, template, inputs, outputs, dropped)


def fit_in_memory(args, template, inputs, outputs, dropped) -> int:
    """Read the files whole (--solver osqp, --estimate-payload), fit, save."""
    import numpy as np

    from ..core.excitation import Spread
    from ..core.fingerprint import segment_fingerprints
    from ..core.select import pose_cells
    from ..data.tables import read_dataset
    from ..files.model_json import save_model
    from ._fit_payload import read_with_payload

    if args.estimate_payload is not None:
        data = read_with_payload(args, inputs, outputs)  # prints the payload, then the completed wrench's span
        report_excitation(Spread.of(data.outputs), data.output_names)
    else:
        data = read_dataset(args.data, inputs, outputs, segment_by=args.segment_by, group_by=args.group_by)
        report_excitation(Spread.of(data.outputs), data.output_names)
        print(f"read {data.n_samples} samples from {len(args.data)} file(s): inputs {','.join(inputs)} "
              f"-> outputs {','.join(outputs)}", file=sys.stderr)
    report_dropped(dropped)
    if args.degree == "auto":
        from ..core.select import fit_best

        result = cross_validation(args, data, template, data.n_samples, len(inputs))
        model = fit_best(data, result, template=template)
        model.solver_info_["cross_validation"] = result.as_dict()
    else:
        model = template.clone(degree=args.degree, solver=make_solver(args)).fit(data)
    if model.input_spread_ is None:
        model.input_spread_ = Spread.of(data.inputs)
    check_saturation(model, lambda: len(pose_cells(data.inputs, model.input_range_)),
                     len(np.unique(np.asarray(data.groups, dtype=str))))
    save_model(model, args.output, sources=[str(p) for p in args.data],
               training_segments=segment_fingerprints(data), prior=args.prior)
    report_fit(model, args.output)
    return 0


def report_dropped(dropped) -> None:
    if dropped is not None:
        print(f"dropped {sum(dropped.values())} row(s) with an empty cell (--drop-incomplete)", file=sys.stderr)


def check_saturation(model, count_poses, n_groups: int) -> None:
    """Warn when the least-squares part of ``model`` has nearly as many coefficients per output as distinct poses."""
    from ..core.features import MonomialBasis, RegressorLayout
    from ..core.select import warn_if_saturated

    selection = model.solver_info_.get("selection")
    if selection:
        degrees = [entry["degree"] for entry in selection if entry["penalty"] == "none"]
    else:
        degrees = [] if model.solver_info_.get("lambda") else [model.layout_.basis.degree]
    if not degrees:
        return  # ridge and LASSO are how to fit many coefficients to few poses
    layout = RegressorLayout(MonomialBasis(len(model.input_names_), max(degrees)), len(model.output_names_),
                             model.layout_.na, model.layout_.nb)
    warn_if_saturated(layout.n_features, count_poses(), n_groups,
                      f"The least-squares fit of degree {max(degrees)}")


def fit_streaming(args, template, inputs, outputs, dropped) -> int:
    """Fit with one task per file, in passes that each hold one chunk (or one ARX file), and save.

    Pass 1 gives the ranges, segment lengths and fingerprints; the normalization
    follows from the ranges, so pass 2 accumulates the statistics directly in the
    solve basis (accumulating raw moments and changing basis afterwards would be
    exact algebra but not exact arithmetic: degree-8 moments of raw ADC counts
    lose every digit to cancellation). The client solves; pass 3 gives the
    training metrics from additive error sums, as ``ftcal evaluate`` does.
    ``--degree auto`` replaces pass 2 by one pass per (degree, basis) the search
    tries, giving per-fold statistics whose sums solve the selection. Run here, the
    passes parse each small file once (:func:`ftcal.data.table_chunks.keep_in_memory`).
    """
    from ..core.statistics import sum_statistics
    from ..data.streaming import (
        StreamedStatistics,
        add_error_sums,
        add_statistics,
        file_error_sums,
        file_layout_statistics,
        file_summary,
    )
    from ..data.table_chunks import keep_in_memory
    from ..files.model_json import save_model
    from ..runtime.executors import open_executor

    with open_executor(args.scheduler) as executor, keep_in_memory():
        summary = executor.map_reduce(file_summary, args.data, inputs, outputs, args.segment_by,
                                      args.group_by, combine=add_statistics, description="ranges")
        n_in = len(inputs)
        report_excitation(summary.spread.take(slice(n_in, None)), outputs)
        print(f"read {sum(summary.segment_lengths)} samples from {len(args.data)} file(s): inputs "
              f"{','.join(inputs)} -> outputs {','.join(outputs)}", file=sys.stderr)
        report_dropped(dropped)
        if args.degree == "auto":
            from ..core.select import fit_selection

            source = StreamedStatistics(executor, args.data, inputs, outputs, summary, args.group_by,
                                        args.segment_by)
            result = cross_validation(args, source, template, sum(summary.segment_lengths), len(inputs))
            model = fit_selection(result)
            model.solver_info_["cross_validation"] = result.as_dict()
        else:
            model = template.clone(degree=args.degree, solver=make_solver(args))
            frame = model.frame_from_ranges(summary.input_range, summary.output_range, inputs, outputs,
                                            summary.segment_lengths)
            parts = executor.map_reduce(file_layout_statistics, args.data, frame.layout,
                                        frame.solve_input_normalization, frame.solve_output_normalization, inputs,
                                        outputs, args.segment_by, combine=add_statistics, description="statistics")
            model.fit_statistics(frame, sum_statistics(parts))
        model.input_spread_ = summary.spread.take(slice(0, n_in))
        sums = executor.map_reduce(file_error_sums, args.data, model, [], "one-step", "zeros", "drop",
                                   args.segment_by, True, combine=add_error_sums, description="training metrics")
    main, other = sums if isinstance(sums, tuple) else (sums, None)
    check_saturation(model, lambda: len(main.pose_cells), len(summary.group_sizes))
    model.training_metrics_ = main.summary(outputs)
    if other is not None:
        model.training_metrics_["free_run"] = other.summary(outputs)
        del model.training_metrics_["free_run"]["n_out_of_range"]
    save_model(model, args.output, sources=[str(p) for p in args.data], training_segments=summary.fingerprints,
               prior=args.prior)
    report_fit(model, args.output)
    return 0


def report_excitation(spread, outputs) -> None:
    """Print how far the reference wrenches excite each direction; warn, with the fix, when some are not.

    Raises FtcalError (through :func:`ftcal.core.excitation.output_excitation`) when no output varies.
    """
    import warnings

    from ..core.excitation import output_excitation
    from ..runtime.errors import IllPosedFitWarning

    excitation = output_excitation(spread, tuple(outputs))
    print(excitation.summary())
    message = excitation.warning()
    if message is not None:
        warnings.warn(message, IllPosedFitWarning, stacklevel=2)


def report_fit(model, path: str) -> None:
    from ..core.metrics import output_units

    info = model.describe()
    metrics = model.training_metrics_
    lam = model.solver_info_.get("lambda")
    print(f"model: degree {info['degree']}" + (f", ARX na={info['na']} nb={info['nb']}" if info["na"] or info["nb"] else "")
          + f", solver {model.solver_info_.get('name')}" + (f" lambda={lam:g}" if lam else ""))
    print(f"coefficients: {info['n_coefficients']} ({info['n_nonzero']} nonzero); samples: {model.n_samples_fit_}; "
          f"condition number: {model.condition_number_:.3g}")
    if lam:
        from ..core.conversion import to_raw

        raw_count = int((abs(to_raw(model)) > 1e-9).sum())
        print(f"raw-input coefficients with |value| > 1e-9 (the paper's count): {raw_count}")
    if norm_rmse_text(metrics):
        print("training " + norm_rmse_text(metrics))
    print("training RMSE per output: " + ", ".join(f"{n} {v:.4g}" + (f" {u}" if u else "") for n, v, u in
                                                  zip(model.output_names_, metrics["rmse"],
                                                      output_units(model.output_names_))))
    warn_if_exact(model.output_names_, metrics.get("best_fit"))
    print(f"wrote {path}")


def warn_if_exact(names, best_fit) -> None:
    """Say loudly when the training error is ~0 of the outputs' spread: no real sensor fits that well.

    Printed as a warning line, not raised as a Python warning: simulations without noise are legitimate
    inputs (tests, demos), and the line is for the person reading the fit's report.
    """
    from ..core.limits import EXACT_FIT

    exact = [n for n, b in zip(names, best_fit or ()) if b is not None and b > 1.0 - EXACT_FIT]
    if exact:
        print(f"warning: the training error of {', '.join(exact)} is ~0 of the outputs' spread (BestFit > 1 - "
              f"{EXACT_FIT:g}): the reference is an exact function of the inputs (a reference copied from or "
              "computed from the readings?); no measured sensor fits this well.", file=sys.stderr)