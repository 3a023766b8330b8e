"""Every calibration path on simulated real-like recordings, against affine least squares on the same folds.

``python -m benchmarks.bench_real_like [SEED]``: the three sensors of :mod:`ftcal.sim.real_like` (an
8-channel optical sensor at 47 load cases, a six-bridge bench plate at 60 loads, a soft fingertip with
8 Hall voltages at 418 loads), held out as issue 44 held out its real recordings: whole load cases (5
folds), one orientation, one load level, random tenths, whole load directions. Per outer fold every
path is fitted with :func:`ftcal.fit` on the kept rows (their load cases as the groups of its own
validation) and scored on the held-out rows against the *reference* (what a lab can measure); OLS is
``ftcal.fit(degree=1)`` on the same rows. Reported per path: the force / torque error-norm RMSE over
all held-out rows divided by OLS's, and the outer folds where the path lost to OLS by more than
:data:`LOSS_MARGIN` on force or torque without saying so (no refusal, no warning naming the affine
model, not the affine model written instead).
"""

from __future__ import annotations

import json
import sys
import time
import warnings

import numpy as np

# (sensor, split, paths): the splits; the MLP only where the issue ran it (it costs most).
CASES = (("optical", "cases"), ("optical", "orientation"), ("plate", "level"), ("plate", "tenths"),
         ("fingertip", "tenths"), ("fingertip", "direction"))
PATHS = {"default": dict(degree="auto"), "default, each block alone": dict(degree="auto", anchor_blocks=False),
         "select_per model": dict(degree="auto", select_per="model"),
         "degree 2": dict(degree=2), "degree 3": dict(degree=3), "degree 3, lasso 10": dict(degree=3, lasso=10.0),
         "degree 2, ridge 1": dict(degree=2, ridge=1.0), "mlp": dict(family="mlp", seed=0)}
LOSS_MARGIN = 0.10  # an outer fold lost: held-out error above OLS's by more than this fraction


def block_rmse(error: np.ndarray) -> np.ndarray:
    """Force and torque error-norm RMSE of error rows (n, 6)."""
    return np.array([np.sqrt(np.mean(np.sum(error[:, b] ** 2, axis=1))) for b in (slice(0, 3), slice(3, 6))])


SAYS_NO_WIN = ("within the fold noise", "worse beyond the fold noise", "WORSE beyond the fold noise",
               "validates worse than the affine model")


def says_it_loses(caught, model, lines) -> bool:
    """The fit says it does not beat affine: a warning naming the affine model (the grouped comparison,
    saturation, the MLP guard), a comparison line or report warning without a win (within the fold noise,
    worse on average, or worse), or the affine model written in the network's place."""
    named = any("affine" in str(w.message) for w in caught)
    printed = any(word in line for line in lines for word in SAYS_NO_WIN)
    written = getattr(model, "family", "polynomial") == "polynomial" and getattr(model, "degree", 0) == 1
    return named or printed or written


def run_path(train, options: dict):
    """(model or None when refused, said-so flag, the report's lines) of one ``ftcal.fit`` call."""
    from contextlib import nullcontext

    import ftcal
    from ftcal.runtime.errors import FtcalError

    from benchmarks.bench_select_rates import unanchored_rule

    options = dict(options)
    rule = nullcontext() if options.pop("anchor_blocks", True) else unanchored_rule()  # the rule before, same data
    with warnings.catch_warnings(record=True) as caught, rule:
        warnings.simplefilter("always")
        try:
            result = ftcal.fit(train, **options)
        except FtcalError as exc:
            return None, True, [f"refused: {exc}"]
    lines = [str(line) for line in (*result.lines, *result.notes)]
    return result.model, says_it_loses(caught, result.model, lines), lines


def predict_named(model, inputs) -> tuple[np.ndarray, bool]:
    """The prediction and whether it warned that the inputs leave the training range or span."""
    from ftcal.runtime.errors import OutOfRangeWarning

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        prediction = model.predict(inputs)
    return prediction, any(issubclass(w.category, OutOfRangeWarning) for w in caught)


def one_case(sensor: str, split: str, seed: int = 0, paths: tuple | None = None) -> dict:
    """Held-out ratios to OLS and silent losses of every path in ``paths`` on one sensor and split."""
    from ftcal.sim.real_like import held_out_masks, simulate_table

    table = simulate_table(sensor, seed)
    masks = held_out_masks(table, split)
    chosen = tuple(PATHS) if paths is None else tuple(paths)
    errors = {name: np.zeros_like(table.reference) for name in ("ols", *chosen)}
    silent = {name: [] for name in chosen}
    said = {name: 0 for name in chosen}
    refused = {name: 0 for name in chosen}
    named_at_prediction = {name: 0 for name in chosen}  # of the silent folds: prediction warned of extrapolation
    cpu = {name: 0.0 for name in ("ols", *chosen)}
    fold_ratios = {name: [] for name in chosen}
    broken = {name: [] for name in chosen}  # outer folds where a claimed win over affine measured a loss
    for f, held in enumerate(masks):
        train = table.dataset(~held)
        start = time.process_time()
        ols, _, _ = run_path(train, dict(degree=1))  # the reference path
        cpu["ols"] += time.process_time() - start
        base = ols.predict(table.inputs[held], warn_out_of_range=False) - table.reference[held]
        errors["ols"][held] = base
        for name in chosen:
            start = time.process_time()
            model, flagged, lines = run_path(train, PATHS[name])
            cpu[name] += time.process_time() - start
            said[name] += bool(flagged)
            if model is None:  # refused: nothing written, the user is told why
                errors[name][held] = np.nan
                refused[name] += 1
                continue
            prediction, extrapolating = predict_named(model, table.inputs[held])
            error = prediction - table.reference[held]
            errors[name][held] = error
            ratio = block_rmse(error) / block_rmse(base)
            fold_ratios[name].append(ratio.tolist())
            if np.any(ratio > 1 + LOSS_MARGIN) and not flagged:
                silent[name].append(f)
                named_at_prediction[name] += extrapolating
            if any("a win beyond the noise" in line for line in lines) and np.any(ratio > 1.0):
                broken[name].append(f)
    ols_rmse = block_rmse(errors["ols"])
    out = {"sensor": sensor, "split": split, "seed": seed, "n_folds": len(masks), "rows": table.n_samples,
           "ols_rmse": ols_rmse.tolist(), "paths": {}}
    for name in chosen:
        e = errors[name]
        out["paths"][name] = {"ratio": None if refused[name] else (block_rmse(e) / ols_rmse).tolist(),
                              "refused_folds": refused[name],
                              "silent_but_extrapolation_named": named_at_prediction[name],
                              "said_folds": said[name], "silent_loss_folds": silent[name],
                              "fold_ratios": fold_ratios[name], "broken_claim_folds": broken[name],
                              "cpu_seconds": cpu[name]}
    out["ols_cpu_seconds"] = cpu["ols"]
    return out


def real_like(sensor: str, split: str, seed: int = 0, mlp: bool = True) -> dict:
    """The case ``make bench`` runs: :func:`one_case` of one sensor and split (``mlp`` False: without the MLP)."""
    start, cpu = time.perf_counter(), time.process_time()
    paths = tuple(p for p in PATHS if mlp or p != "mlp")
    return {**one_case(sensor, split, seed, paths), "seconds": time.perf_counter() - start,
            "cpu_seconds": time.process_time() - cpu}


REAL_LIKE_CASES = {"real_like": real_like}


def main(seed: int = 0) -> None:
    for sensor, split in CASES:
        print(json.dumps(one_case(sensor, split, seed)), flush=True)


if __name__ == "__main__":
    main(*(int(a) for a in sys.argv[1:]))
