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
    import numpy as np

    from ..files.model_files import load_model_file

    loaded = load_model_file(args.model)
    model = loaded.model
    info = model.describe()
    lam = model.solver_info_.get("lambda")
    polynomial = model.family == "polynomial"  # terms and raw coefficients exist for polynomials only
    arx = f", ARX na={info['na']} nb={info['nb']}" if info["na"] or info["nb"] else ""
    kind = f"polynomial degree {info['degree']}{arx}" if polynomial else f"{model.label()} ({model.family} family)"
    print(f"{args.model}: {kind}, {info['n_inputs']} inputs -> {info['n_outputs']} outputs")
    print(f"{'coefficients' if polynomial else 'parameters'} {info['n_coefficients']}, nonzero {info['n_nonzero']}; "
          f"solver {model.solver_info_.get('name') or 'unknown'}" + (f", lambda {lam:g}" if lam else ""))
    if polynomial:
        from ..core.conversion import to_raw

        raw_nonzero = int(np.sum(np.abs(to_raw(model)) > 1e-9))
        print(f"raw-input coefficients with |value| > 1e-9 (the paper's count): {raw_nonzero}")
    if loaded.created_utc:
        print(f"created {loaded.created_utc} by ftcal {loaded.ftcal_version}; "
              f"trained on {model.n_samples_fit_} samples from {len(loaded.sources)} file(s)")
    if loaded.prior:
        print(f"shrunk toward the prior {loaded.prior['source']} (sha256 {loaded.prior['file_sha256'][:12]}…)")
    print("training ranges:")
    for name, unit, (low, high) in zip(model.input_names_, loaded.input_units, model.input_range_):
        print(f"  {single_line(name):<8} {low:>14.6g} .. {high:<14.6g} {single_line(unit or '')}")
    metrics = model.training_metrics_ or {}
    if norm_rmse_text(metrics):
        print("training " + norm_rmse_text(metrics, ".4g"))
    if not polynomial:
        return 0
    names = model.layout_.column_names(model.input_names_, model.output_names_)
    # Features are normalized to about [-1, 1], so |coefficient| measures a term's contribution.
    magnitude = np.abs(model.coef_)
    order = np.argsort(-magnitude, axis=None)[:max(args.terms, 0)]
    norm = model.input_normalization_
    basis = "raw inputs" if not (norm.offset.any() or (norm.scale != 1).any()) else "normalized features"
    print(f"largest terms (coefficients of {basis}):")
    for flat in order:
        row, col = np.unravel_index(flat, magnitude.shape)
        print(f"  {single_line(model.output_names_[col]):<6} {single_line(names[row]):<28} {model.coef_[row, col]: .6g}")
    return 0
