"""``ftcal fit --family mlp``'s options (the fit itself: :func:`ftcal.workflow.fitting.fit`)."""

from __future__ import annotations

import argparse

from ..core.limits import FAMILY_NAMES, MLP_ACTIVATIONS, MLP_EQUATIONS_PER_WEIGHT, MLP_MAX_LAYERS, MLP_MAX_UNITS


def add_family_options(parser: argparse.ArgumentParser) -> None:
    """``--family`` and the MLP's options."""
    parser.add_argument("--family", choices=FAMILY_NAMES, default="polynomial",
                        help="model family: polynomial (default) or mlp, a small neural network early-stopped on "
                             "the grouped folds (--folds, groups from --group-by or the files), printing its "
                             "held-out scores beside the affine model's")
    group = parser.add_argument_group("mlp options (--family mlp)")
    # Checked by the fit step (ftcal.workflow.fitting: one error line), not by argparse (usage plus error).
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
