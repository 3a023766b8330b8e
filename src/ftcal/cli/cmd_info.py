"""``ftcal info``: what a model file holds."""

from __future__ import annotations

from ._common import norm_rmse_text, single_line
from ._examples import epilog

N_LARGEST = 10


def register(sub) -> None:
    p = sub.add_parser("info", **epilog("info"), help="model class, counts, training ranges, largest terms")
    p.add_argument("model", metavar="MODEL", help="ftcal JSON or paper XML model file")
    p.add_argument("--terms", type=int, default=N_LARGEST, help=f"largest terms to list (default {N_LARGEST})")
    p.set_defaults(func=run)


def run(args) -> int:
    from ..files.model_info import light_facts, loaded_facts

    # A valid static polynomial JSON file is summarized without numpy; anything else is loaded fully
    # (which refuses an invalid file with its message).
    print(report(args.model, light_facts(args.model, args.terms) or loaded_facts(args.model, args.terms)), end="")
    return 0


def report(name: str, facts: dict) -> str:
    """The text ``info`` prints for the :func:`summary` ``facts`` of the model file ``name``."""
    polynomial, lam = facts["polynomial"], facts["lambda"]
    lines = [f"{name}: {facts['kind']}, {facts['n_inputs']} inputs -> {facts['n_outputs']} outputs",
             f"{'coefficients' if polynomial else 'parameters'} {facts['n_coefficients']}, "
             f"nonzero {facts['n_nonzero']}; solver {facts['solver'] or 'unknown'}"
             + (f", lambda {lam:g}" if lam else "")]
    if polynomial:
        lines.append(f"raw-input coefficients with |value| > 1e-9 (the paper's count): {facts['raw_nonzero']}")
    if facts["created_utc"]:
        lines.append(f"created {facts['created_utc']} by ftcal {facts['ftcal_version']}; "
                     f"trained on {facts['n_samples']} samples from {facts['n_sources']} file(s)")
    if facts["prior"]:
        lines.append(f"shrunk toward the prior {facts['prior']['source']} "
                     f"(sha256 {facts['prior']['file_sha256'][:12]}…)")
    lines.append("training ranges:")
    for variable, unit, low, high in facts["inputs"]:
        lines.append(f"  {single_line(variable):<8} {low:>14.6g} .. {high:<14.6g} {single_line(unit or '')}")
    if norm_rmse_text(facts["metrics"]):
        lines.append("training " + norm_rmse_text(facts["metrics"], ".4g"))
    if polynomial:
        basis = "raw inputs" if facts["raw_basis"] else "normalized features"
        lines.append(f"largest terms (coefficients of {basis}):")
        for output, term, value in facts["largest"]:
            lines.append(f"  {single_line(output):<6} {single_line(term):<28} {value: .6g}")
    return "\n".join(lines) + "\n"
