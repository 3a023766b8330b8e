"""``ftcal fit``: fit a calibration model to tables of samples."""

from __future__ import annotations

import argparse
import sys

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
    add_column_options,
    add_scheduler_option,
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
selection is solved from those sums; ARX: lags inside segments), and for ARX and --degree auto one
for the training metrics (a static fit of a given degree takes its training RMSE and BestFit from the
summed statistics; max |error| and the norm RMSEs: ftcal evaluate); memory: one chunk (one file for
ARX) plus p x p (--degree auto: p x p per fold).

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


def run(args) -> int:
    from ..runtime.allocator import collect_less, keep_freed_memory
    from ..workflow.fitting import fit

    require_suffix(args.output, (".json",), "-o")
    keep_freed_memory()  # chunk temporaries reuse the heap instead of faulting fresh pages in each time
    collect_less()
    result = fit(args.data, inputs=args.inputs, outputs=args.outputs, degree=args.degree, lasso=args.lasso,
                 ridge=args.ridge, na=args.na, nb=args.nb, solver=args.solver, normalization=args.normalization,
                 folds=args.folds, penalties=args.penalties, lambdas=args.lambdas, select_per=args.select_per,
                 objective=args.objective, max_degree=args.max_degree, budget=args.budget, verbose=args.verbose,
                 drop_incomplete=args.drop_incomplete, prior=args.prior, estimate_payload=args.estimate_payload,
                 payload_mass=args.payload_mass, family=args.family, hidden=args.hidden,
                 activation=args.activation, weight_decay=args.weight_decay, max_iter=args.max_iter,
                 seed=args.seed, segment_by=args.segment_by, group_by=args.group_by, scheduler=args.scheduler,
                 output=args.output, cpu_start=args.cpu_start, echo=echo_line)
    for note in result.notes:
        print(note, file=sys.stderr)
    return 0


def echo_line(line: str) -> None:
    """Print one line of the fit's report as soon as the step knows it (the estimate before the search)."""
    print(line, flush=True)
