"""``ftcal fit``: fit a calibration model to tables of samples."""

from __future__ import annotations

import argparse
import sys

from ..limits import MAX_DEGREE, MAX_LAG, NORMALIZATIONS, SOLVERS
from ._common import add_column_options, default_inputs, float_list, nonnegative_int, positive_float, require_suffix

EPILOG = """examples:
  ftcal fit train/*.csv -o model.json                      affine model, u1..u6,T -> Fx..Tz
  ftcal fit data.parquet --degree 4 --lasso 50 -o m4.json  LASSO: the paper's problem and lambda scale
  ftcal fit logs/*.parquet --degree auto --group-by group -o best.json
"""


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
    p = sub.add_parser("fit", help="fit a calibration model", epilog=EPILOG,
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("data", nargs="+", metavar="DATA", help="CSV or Parquet files (each one segment and group)")
    add_column_options(p)
    p.add_argument("--degree", type=degree_value,
                   help=f"polynomial degree 1-5 (up to {MAX_DEGREE}), or 'auto' for grouped cross-validation "
                        "(default 1: affine)")
    penalty = p.add_mutually_exclusive_group()
    penalty.add_argument("--lasso", type=positive_float, metavar="LAMBDA",
                         help="LASSO: minimize 1/2|A t - y|^2 + LAMBDA |t|_1 on the paper's regressor A (raw "
                              "monomials, each column divided by its max |value|, offset column 1); the paper "
                              "uses 0.5 .. 200")
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
    p.add_argument("--lambdas", type=float_list, metavar="L1,L2,...",
                   help="lambda grid for --degree auto (default the paper's 0.5,1,10,50,100,200)")
    p.add_argument("-o", "--output", required=True, metavar="MODEL.json", help="model file to write")
    p.set_defaults(func=run)


def make_solver(args):
    from ..solvers.lasso import Lasso
    from ..solvers.least_squares import LeastSquares, Ridge
    from ..solvers.osqp_qp import OsqpLasso, OsqpLeastSquares

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

    from ..errors import FtcalError, FtcalWarning

    if args.solver == "osqp" and args.ridge:
        raise FtcalError("--solver osqp implements the paper's least-squares and LASSO programs, not --ridge.")
    if args.degree == "auto" and args.solver == "osqp":
        raise FtcalError("--degree auto uses the streaming solvers; drop --solver osqp.")
    if args.degree is None:
        if args.lasso or args.ridge:
            warnings.warn(f"--{'lasso' if args.lasso else 'ridge'} without --degree fits degree 1 (affine); "
                          "give --degree (the paper's LASSO models are degree 4).", FtcalWarning, stacklevel=2)
        args.degree = 1
    if args.folds < 2:
        raise FtcalError(f"--folds must be at least 2; got {args.folds}.")
    for flag in ("na", "nb"):
        if getattr(args, flag) > MAX_LAG:
            raise FtcalError(f"--{flag} must be at most {MAX_LAG}; got {getattr(args, flag)}.")


def run(args) -> int:
    from ..fingerprint import segment_fingerprints
    from ..io.model_json import save_model
    from ..io.tables import read_dataset
    from ..model import CalibrationModel

    require_suffix(args.output, (".json",), "-o")
    check_options(args)
    inputs = args.inputs or default_inputs(args.data)
    outputs = args.outputs or ("Fx", "Fy", "Fz", "Tx", "Ty", "Tz")
    data = read_dataset(args.data, inputs, outputs, segment_by=args.segment_by, group_by=args.group_by)
    print(f"read {data.n_samples} samples from {len(args.data)} file(s): inputs {','.join(inputs)} "
          f"-> outputs {','.join(outputs)}", file=sys.stderr)
    if args.degree == "auto":
        from ..select import PAPER_LAMBDAS, Candidate, cross_validate, default_candidates, fit_best

        if args.lasso or args.ridge:
            kind = "lasso" if args.lasso else "ridge"
            candidates = [Candidate(d, kind, args.lasso or args.ridge) for d in range(1, 6)]
        else:
            candidates = default_candidates(lams=args.lambdas or PAPER_LAMBDAS)
        template = CalibrationModel(na=args.na, nb=args.nb, normalization=args.normalization)
        result = cross_validate(data, candidates, template=template, n_folds=args.folds)
        print(result.table())
        model = fit_best(data, result, template=template)
        print(f"selected {result.best.label} by grouped {result.n_folds}-fold cross-validation")
    else:
        model = CalibrationModel(args.degree, solver=make_solver(args), na=args.na, nb=args.nb,
                                 normalization=args.normalization).fit(data)
    save_model(model, args.output, sources=[str(p) for p in args.data],
               training_segments=segment_fingerprints(data))
    report_fit(model, args.output)
    return 0


def report_fit(model, path: str) -> None:
    info = model.describe()
    metrics = model.training_metrics_
    lam = model.solver_info_.get("lambda")
    print(f"model: degree {info['degree']}" + (f", ARX na={info['na']} nb={info['nb']}" if info["na"] or info["nb"] else "")
          + f", solver {model.solver_info_.get('name')}" + (f" lambda={lam:g}" if lam else ""))
    print(f"coefficients: {info['n_coefficients']} ({info['n_nonzero']} nonzero); samples: {model.n_samples_fit_}; "
          f"condition number: {model.condition_number_:.3g}")
    if lam:
        from ..conversion import to_raw

        raw_count = int((abs(to_raw(model)) > 1e-9).sum())
        print(f"raw-input coefficients with |value| > 1e-9 (the paper's count): {raw_count}")
    if metrics.get("force_norm_rmse") is not None:
        print(f"training force-norm RMSE {metrics['force_norm_rmse']:.4f}, "
              f"torque-norm RMSE {metrics['torque_norm_rmse']:.4f}")
    print("training RMSE per output: " + ", ".join(f"{n} {v:.4g}" for n, v in zip(model.output_names_, metrics["rmse"])))
    print(f"wrote {path}")
