"""``ftcal info``: what a model file holds."""

from __future__ import annotations

from ..core.limits import INFO_TERMS
from ._examples import epilog


def register(sub) -> None:
    p = sub.add_parser("info", **epilog("info"), help="model class, counts, training ranges, largest terms")
    p.add_argument("model", metavar="MODEL", help="ftcal JSON or paper XML model file")
    p.add_argument("--terms", type=int, default=INFO_TERMS, help=f"largest terms to list (default {INFO_TERMS})")
    p.set_defaults(func=run)


def run(args) -> int:
    from ..workflow.info import model_info

    print(model_info(args.model, args.terms).summary())
    return 0
