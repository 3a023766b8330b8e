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
    from ..files.model_info import light_facts

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


def loaded_facts(path: str, n_terms: int) -> dict:
    """What ``info`` prints, from the fully loaded model file (any family and format).

    :func:`ftcal.files.model_info.light_facts` gives the same keys without numpy for static polynomial
    JSON files.
    """
    import numpy as np

    from ..files.model_files import load_model_file

    loaded = load_model_file(path)
    model = loaded.model
    info = model.describe()
    polynomial = model.family == "polynomial"  # terms and raw coefficients exist for polynomials only
    arx = f", ARX na={info['na']} nb={info['nb']}" if info["na"] or info["nb"] else ""
    facts = {
        "kind": (f"polynomial degree {info['degree']}{arx}" if polynomial
                 else f"{model.label()} ({model.family} family)"),
        "polynomial": polynomial, "n_inputs": info["n_inputs"], "n_outputs": info["n_outputs"],
        "n_coefficients": info["n_coefficients"], "n_nonzero": info["n_nonzero"],
        "solver": model.solver_info_.get("name"), "lambda": model.solver_info_.get("lambda"),
        "created_utc": loaded.created_utc, "ftcal_version": loaded.ftcal_version,
        "n_samples": model.n_samples_fit_, "n_sources": len(loaded.sources), "prior": loaded.prior,
        "inputs": [(name, unit, low, high)
                   for name, unit, (low, high) in zip(model.input_names_, loaded.input_units, model.input_range_)],
        "metrics": model.training_metrics_ or {},
    }
    if not polynomial:
        return facts
    from ..core.conversion import to_raw

    facts["raw_nonzero"] = int(np.sum(np.abs(to_raw(model)) > 1e-9))
    names = model.layout_.column_names(model.input_names_, model.output_names_)
    # Features are normalized to about [-1, 1], so |coefficient| measures a term's contribution.
    magnitude = np.abs(model.coef_)
    # stable: equal magnitudes (a LASSO's exact zeros) listed in term order on every CPU (AVX-512 sorts ties its own way)
    order = np.argsort(-magnitude, axis=None, kind="stable")[:max(n_terms, 0)]
    norm = model.input_normalization_
    facts["raw_basis"] = not (norm.offset.any() or (norm.scale != 1).any())
    facts["largest"] = []
    for flat in order:
        row, col = np.unravel_index(flat, magnitude.shape)
        facts["largest"].append((model.output_names_[col], names[row], model.coef_[row, col]))
    return facts
