"""``ftcal fit --family mlp``: the neural baseline, early-stopped and compared on the grouped folds."""

from __future__ import annotations

import argparse
import sys

from ..core.limits import (FAMILY_NAMES, MLP_ACTIVATIONS, MLP_EQUATIONS_PER_WEIGHT, MLP_MAX_ITER, MLP_MAX_LAYERS,
                           MLP_MAX_UNITS)
from ._common import norm_rmse_text

# Rows × weights below which the default --max-iter is 2000 instead of 400 (a few seconds either way).
SMALL_MLP_WORK = 2_000_000


def hidden_sizes(text: str) -> tuple[int, ...]:
    """``"32,32"`` → (32, 32); one-line FtcalError unless 1 to MLP_MAX_LAYERS layers of 1 to MLP_MAX_UNITS units."""
    from ..runtime.errors import FtcalError

    try:
        sizes = tuple(int(part) for part in str(text).split(","))
    except ValueError:
        sizes = ()
    if not 1 <= len(sizes) <= MLP_MAX_LAYERS or not all(1 <= s <= MLP_MAX_UNITS for s in sizes):
        raise FtcalError(f"--hidden {text}: expected 1 to {MLP_MAX_LAYERS} comma-separated layer sizes of 1 to "
                         f"{MLP_MAX_UNITS} units, such as 32,32.")
    return sizes


def weight_decay(text: str) -> float:
    """A finite number >= 0; one-line FtcalError otherwise."""
    import math

    from ..runtime.errors import FtcalError

    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not math.isfinite(value) or value < 0:
        raise FtcalError(f"--weight-decay {text}: must be a finite number >= 0 (0 turns the penalty off).")
    return value


def whole_number(text: str, option: str, low: int, high: int) -> int:
    """An int in [low, high]; one-line FtcalError otherwise."""
    from ..runtime.errors import FtcalError

    try:
        value = int(text)
    except ValueError:
        value = low - 1
    if not low <= value <= high:
        raise FtcalError(f"{option} {text}: must be a whole number in {low}..{high}.")
    return value


def add_family_options(parser: argparse.ArgumentParser) -> None:
    """``--family`` and the MLP's options."""
    parser.add_argument("--family", choices=FAMILY_NAMES, default="polynomial",
                        help="model family: polynomial (default) or mlp, a small neural network early-stopped on "
                             "the grouped folds (--folds, groups from --group-by or the files), printing its "
                             "held-out scores beside the affine model's")
    group = parser.add_argument_group("mlp options (--family mlp)")
    # Checked in check_family_options (one error line), not by argparse (usage plus error).
    group.add_argument("--hidden", metavar="H1,H2",
                       help=f"units per hidden layer (default 32,32, smaller when the data have fewer than "
                            f"{MLP_EQUATIONS_PER_WEIGHT} equations (rows x outputs) per weight; at most "
                            f"{MLP_MAX_LAYERS} layers of {MLP_MAX_UNITS})")
    group.add_argument("--activation", choices=MLP_ACTIVATIONS, help="hidden activation (default tanh)")
    group.add_argument("--weight-decay", metavar="ALPHA",
                       help="1/2 ALPHA |W|^2 added to the mean squared error of the normalized outputs (default 1e-4)")
    group.add_argument("--max-iter", metavar="N",
                       help="L-BFGS iterations at most; early stopping picks the count (default 400, or 2000 "
                            "for a small network on few rows)")
    group.add_argument("--seed", metavar="N",
                       help="initial weights (default 0): the same seed, the same model")


def check_family_options(args) -> None:
    """Options the MLP does not take, refused before any data is read."""
    from ..runtime.errors import FtcalError

    own = {"--hidden": args.hidden, "--activation": args.activation, "--weight-decay": args.weight_decay,
           "--max-iter": args.max_iter, "--seed": args.seed}
    if args.family != "mlp":
        given = [flag for flag, value in own.items() if value is not None]
        if given:
            raise FtcalError(f"{', '.join(given)} go with --family mlp.")
        return
    args.hidden = None if args.hidden is None else hidden_sizes(args.hidden)  # None: sized to the data
    args.activation = args.activation or "tanh"
    args.weight_decay = weight_decay("1e-4" if args.weight_decay is None else args.weight_decay)
    # None: 400, or 2000 for a small network on few rows (sized in fit_mlp, where the rows are known).
    args.max_iter = None if args.max_iter is None else whole_number(args.max_iter, "--max-iter", 1, MLP_MAX_ITER)
    args.seed = whole_number("0" if args.seed is None else args.seed, "--seed", 0, 2**32 - 1)
    given = [flag for flag, on in (("--degree", args.degree is not None), ("--lasso", args.lasso),
                                   ("--ridge", args.ridge), ("--na", args.na), ("--nb", args.nb),
                                   ("--prior", args.prior), ("--estimate-payload", args.estimate_payload),
                                   ("--solver osqp", args.solver == "osqp"), ("--scheduler", args.scheduler),
                                   ("--normalization", args.normalization)) if on]
    if given:
        raise FtcalError(f"--family mlp does not take {', '.join(given)} (polynomial options); its own are "
                         "--hidden, --activation, --weight-decay, --max-iter and --seed.")
    if args.folds < 2:
        raise FtcalError(f"--folds must be at least 2; got {args.folds}.")


def fit_mlp(args, inputs, outputs):
    """Read the data whole, fit the MLP and print its grouped cross-validation beside affine least squares.

    The network is sized to the data unless ``--hidden`` is given (:func:`ftcal.core.mlp.hidden_for_data`).
    When its grouped cross-validation ranks it worse than the affine model beyond the fold noise (the
    polynomial search's rule), the affine model is fitted and returned instead, and the printout says so.
    """
    import warnings

    from ..core.mlp import MLPModel, hidden_for_data, n_weights
    from ..core.model import CalibrationModel
    from ..core.select import Candidate, Comparison, cross_validate
    from ..data.tables import read_dataset
    from ..runtime.errors import FtcalWarning, IllPosedFitWarning

    data = read_dataset(args.data, inputs, outputs, segment_by=args.segment_by, group_by=args.group_by)
    print(f"read {data.n_samples} samples from {len(args.data)} file(s): inputs {','.join(inputs)} "
          f"-> outputs {','.join(outputs)}", file=sys.stderr)
    n_in, n_out = len(inputs), len(outputs)
    equations = data.n_samples * n_out
    hidden = args.hidden
    if hidden is None:
        hidden = hidden_for_data(data.n_samples, n_in, n_out)
        print(f"network {n_in}-{'-'.join(map(str, hidden))}-{n_out}: {n_weights(n_in, hidden, n_out)} weights for "
              f"{data.n_samples} rows x {n_out} outputs (at most one weight per {MLP_EQUATIONS_PER_WEIGHT} "
              "equations where the data allow; --hidden overrides)")
    if n_weights(n_in, hidden, n_out) * MLP_EQUATIONS_PER_WEIGHT > equations:
        fix = "leave --hidden out to size it to the data" if args.hidden is not None else \
            "even the smallest network sized to the outputs is large for these rows"
        warnings.warn(f"hidden layers {','.join(map(str, hidden))}: {n_weights(n_in, hidden, n_out)} weights for "
                      f"{data.n_samples} rows x {n_out} outputs (fewer than {MLP_EQUATIONS_PER_WEIGHT} equations per "
                      f"weight): the network can fit the noise; {fix}.", FtcalWarning, stacklevel=2)
    max_iter = args.max_iter
    if max_iter is None:  # a small problem converges slowly but cheaply: let early stopping see further
        max_iter = 2000 if min(data.n_samples, 20_000) * n_weights(n_in, hidden, n_out) <= SMALL_MLP_WORK else 400
    model = MLPModel(hidden, activation=args.activation, weight_decay=args.weight_decay,
                     max_iter=max_iter, n_folds=args.folds, seed=args.seed).fit(data)
    if model.cv_ is not None and model.cv_["iterations"] >= max_iter:
        print(f"early stopping chose the last of the {max_iter} iterations: held-out error was still falling "
              "(a larger --max-iter may help)")
    if model.cv_ is not None:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", IllPosedFitWarning)  # judged by its score
            affine = cross_validate(data, [Candidate(1, "none", None)], n_folds=args.folds, objective="force")
        affine_folds = affine.score_of(Candidate(1, "none", None)).fold_scores
        print(cross_validation_table(model, affine_folds))
        comparison = Comparison.of(Candidate(1, "none", None), affine_folds, model.cv_["fold_scores"])
        if comparison.loses:
            warnings.warn(f"the MLP validates worse than the affine model beyond the fold noise (margin "
                          f"{comparison.margin:+.3g}, fold standard error {comparison.standard_error:.3g} over "
                          f"{model.cv_['n_folds']} grouped folds): the affine model is written instead; give "
                          "--family polynomial --degree auto to search the polynomials.", FtcalWarning, stacklevel=2)
            print("written: the affine model (least squares, degree 1), not the MLP: the MLP validates worse "
                  "beyond the fold noise")
            model = CalibrationModel(degree=1).fit(data)
        elif comparison.within_noise:
            print("the MLP is within the fold noise of the affine model: no evidence that it predicts new load "
                  "cases better (the MLP is written, as asked)")
    return model, data


def cross_validation_table(model, affine_folds) -> str:
    """The MLP's held-out scores beside affine least squares on the same grouped folds."""
    import numpy as np

    cv = model.cv_
    mlp_folds = np.asarray(cv["fold_scores"])
    difference = np.asarray(affine_folds) - mlp_folds
    spread = float(np.std(difference, ddof=1)) if difference.size > 1 else 0.0
    lines = [f"{'model':<24} {'validation':>11}   ({cv['metric']}, {cv['n_folds']} grouped folds)",
             f" {'np1':<23} {np.mean(affine_folds):>11.4f}",
             f"*{model.label():<23} {mlp_folds.mean():>11.4f}   (early stop at {cv['iterations']} iterations)",
             f"mlp margin over np1 {difference.mean():+.3g} on average over {cv['n_folds']} folds "
             f"(fold-to-fold spread {spread:.3g}, standard error {spread / np.sqrt(difference.size):.3g})"]
    return "\n".join(lines)


def report_mlp(model, path: str) -> None:
    info = model.describe()
    metrics = model.training_metrics_
    print(f"model: {model.label()}, {info['n_coefficients']} weights, {model.n_iter_} L-BFGS iterations, "
          f"samples: {model.n_samples_fit_}")
    if norm_rmse_text(metrics):
        print("training " + norm_rmse_text(metrics, units=False))
    print("training RMSE per output: " + ", ".join(f"{n} {v:.4g}" for n, v in zip(model.output_names_, metrics["rmse"])))
    print(f"wrote {path}")
