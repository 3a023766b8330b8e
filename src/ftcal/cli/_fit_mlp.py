"""``ftcal fit --family mlp``: the neural baseline, early-stopped and compared on the grouped folds."""

from __future__ import annotations

import argparse
import sys

from ..core.limits import FAMILY_NAMES, MLP_ACTIVATIONS, MLP_MAX_ITER, MLP_MAX_LAYERS, MLP_MAX_UNITS
from ._common import norm_rmse_text


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
                       help=f"units per hidden layer (default 32,32; at most {MLP_MAX_LAYERS} layers of "
                            f"{MLP_MAX_UNITS})")
    group.add_argument("--activation", choices=MLP_ACTIVATIONS, help="hidden activation (default tanh)")
    group.add_argument("--weight-decay", metavar="ALPHA",
                       help="1/2 ALPHA |W|^2 added to the mean squared error of the normalized outputs (default 1e-4)")
    group.add_argument("--max-iter", metavar="N",
                       help="L-BFGS iterations at most; early stopping picks the count (default 400)")
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
    args.hidden = hidden_sizes("32,32" if args.hidden is None else args.hidden)
    args.activation = args.activation or "tanh"
    args.weight_decay = weight_decay("1e-4" if args.weight_decay is None else args.weight_decay)
    args.max_iter = whole_number("400" if args.max_iter is None else args.max_iter, "--max-iter", 1, MLP_MAX_ITER)
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
    """Read the data whole, fit the MLP and print its grouped cross-validation beside affine least squares."""
    import warnings

    from ..core.mlp import MLPModel
    from ..core.select import Candidate, cross_validate
    from ..data.tables import read_dataset
    from ..runtime.errors import IllPosedFitWarning

    data = read_dataset(args.data, inputs, outputs, segment_by=args.segment_by, group_by=args.group_by)
    print(f"read {data.n_samples} samples from {len(args.data)} file(s): inputs {','.join(inputs)} "
          f"-> outputs {','.join(outputs)}", file=sys.stderr)
    model = MLPModel(args.hidden, activation=args.activation, weight_decay=args.weight_decay,
                     max_iter=args.max_iter, n_folds=args.folds, seed=args.seed).fit(data)
    if model.cv_ is not None:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", IllPosedFitWarning)  # judged by its score
            affine = cross_validate(data, [Candidate(1, "none", None)], n_folds=args.folds, objective="force")
        print(cross_validation_table(model, affine.score_of(Candidate(1, "none", None)).fold_scores))
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
