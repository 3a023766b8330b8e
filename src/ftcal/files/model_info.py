"""What ``ftcal info`` prints about a static polynomial JSON model file, without numpy (issue 43, item 5).

numpy's import alone costs more than the rest of ``ftcal info MODEL``. This module reads the document
(:mod:`ftcal.files.json_document`: strict JSON, the schema subset, the digest) and repeats the loader's
other checks (:func:`ftcal.files.model_json._build`, the polynomial's ``from_document``) in plain Python,
only to *accept*: whatever it cannot prove the full loader accepts (another family, an ARX model, a
prediction or raw coefficient near a limit, a tie in the largest terms, any failed check) returns None,
and ``info`` loads the file with the full loader, which refuses it with its own message or prints it.
So the light path never words an error, and never accepts a file the loader refuses.
:func:`loaded_facts` gives the same keys from the full loader (numpy, imported when it is called).
"""

from __future__ import annotations

import math
import sys
from itertools import combinations_with_replacement, product
from math import comb
from pathlib import Path

from ..core.limits import COVARIANCE_ASYMMETRY, COVARIANCE_NEGATIVE, MAX_DEGREE, MIN_SCALE, NORMALIZATIONS
from .json_document import check_document, check_version, parse_json, read_document_text

PER_OUTPUT_METRICS = ("rmse", "best_fit", "max_abs_error", "residual_autocorrelation_lag1")
RAW_THRESHOLD = 1e-9  # the paper's count of raw-input coefficients: |value| > 1e-9
# Far from float64's overflow (1.8e308): a plain-Python bound below it proves numpy's prediction finite.
_SAFE = 1e300
# Plain Python and numpy (sparse products, other summation orders) round differently: a sum of n parts,
# each a product of about 3 * degree roundings, errs by at most (n + 3 * degree) * epsilon of the summed
# |parts|; a raw coefficient within 4 times that of the threshold is left to numpy.
_ROUNDING = 4 * sys.float_info.epsilon


def light_facts(path: str | Path, n_terms: int) -> dict | None:
    """The plain values ``ftcal info`` prints for the model file at ``path``, or None (load it fully).

    Parameters
    ----------
    path : a model file (any content: what is not a valid static polynomial JSON file gives None)
    n_terms : how many of the largest terms to list

    Returns
    -------
    dict or None
        The keys of :func:`loaded_facts`'s result.
    """
    path = Path(path)
    try:
        with path.open("rb") as fh:
            head = fh.read(512).lstrip(b"\xef\xbb\xbf \t\r\n")[:1]
        if head != b"{":
            return None
        doc = parse_json(read_document_text(path), str(path))
        check_version(doc, str(path))
        check_document(doc, str(path))
        return _summary(doc, n_terms)
    except Exception:  # noqa: BLE001  any doubt: the full loader decides, and words its message
        return None


def _summary(doc: dict, n_terms: int) -> dict | None:
    if doc.get("family", "polynomial") != "polynomial":
        return None
    spec, inputs, outputs, fit = doc["model"], doc["inputs"], doc["outputs"], doc["fit"]
    degree, nu, ny = spec["degree"], len(inputs), len(outputs)
    if (not (nu and ny) or spec["na"] or spec["nb"] or not 1 <= degree <= MAX_DEGREE
            or spec["normalization"] not in NORMALIZATIONS):
        return None
    if not _envelope_ok(doc, inputs, outputs, fit, nu):
        return None
    combos = [c for p in range(1, degree + 1) for c in combinations_with_replacement(range(nu), p)] + [()]
    exponents = [[combo.count(i) for i in range(nu)] for combo in combos]
    terms, coef = doc["terms"], doc["coefficients"]
    if (len(coef) != len(combos) or terms["exponents"] != exponents or terms["lags"] != [0] * len(combos)
            or len(terms["names"]) != len(combos) or any(len(row) != ny for row in coef)):
        return None
    names = [v["name"] for v in inputs]
    in_off, in_scale = [v["offset"] for v in inputs], [v["scale"] for v in inputs]
    if not _prediction_finite(doc, coef, degree):
        return None
    raw = _raw_nonzero(coef, exponents, in_off, in_scale, degree)
    order = _largest(coef, ny, max(n_terms, 0))
    if raw is None:
        return None
    created, solver = doc["created"], fit["solver"]
    term_names = ["·".join(n if e == 1 else f"{n}^{e}" for n, e in zip(names, row) if e) or "1" for row in exponents]
    term_names[-1] = "1"
    return {
        "kind": f"polynomial degree {degree}", "polynomial": True, "n_inputs": nu, "n_outputs": ny,
        "n_coefficients": len(coef) * ny, "n_nonzero": sum(1 for row in coef for c in row if c != 0),
        "solver": solver.get("name"), "lambda": solver.get("lambda"), "raw_nonzero": raw,
        "created_utc": created["time_utc"], "ftcal_version": created["ftcal_version"],
        "n_samples": fit["n_samples"], "n_sources": len(created["sources"]), "prior": fit.get("prior"),
        "inputs": [(v["name"], v["unit"], -math.inf if v["range"][0] is None else v["range"][0],
                    math.inf if v["range"][1] is None else v["range"][1]) for v in inputs],
        "metrics": fit["metrics"] or {},
        "raw_basis": not (any(in_off) or any(s != 1 for s in in_scale)),
        "largest": [(outputs[f % ny]["name"], term_names[f // ny], coef[f // ny][f % ny]) for f in order],
    }


def _envelope_ok(doc: dict, inputs: list, outputs: list, fit: dict, nu: int) -> bool:
    """The loader's envelope checks (``_build``, ``check_envelope_consistency``), True only when all pass."""
    for variables in (inputs, outputs):
        names = [v["name"] for v in variables]
        if len(set(names)) != len(names):
            return False
        for v in variables:
            low, high = v["range"]
            if low is not None and high is not None and low > high:
                return False
            if not MIN_SCALE <= v["scale"] < math.inf:
                return False
            for bound in (low, high):
                if bound is not None and not math.isfinite((bound - v["offset"]) / v["scale"]):
                    return False
    metrics = fit["metrics"]
    if any(metrics.get(k) is not None and len(metrics[k]) != len(outputs) for k in PER_OUTPUT_METRICS):
        return False
    listed = metrics.get("outputs")
    if listed is not None and list(listed) != [v["name"] for v in outputs]:
        return False
    if doc["coefficients"] and fit["rank"] > len(doc["coefficients"]):
        return False
    spread = fit.get("input_spread")
    if spread is None:
        return True
    mean, cov = spread["mean"], spread["covariance"]
    if len(mean) != nu or len(cov) != nu or any(not isinstance(r, list) or len(r) != nu for r in cov):
        return False
    if any(x is None for x in (*mean, *(x for row in cov for x in row))):
        return False
    return covariance_acceptable(cov)


def covariance_acceptable(cov: list[list[float]]) -> bool:
    """Whether the loader surely accepts a finite square covariance: symmetric and positive semi-definite
    within :data:`~ftcal.core.limits.COVARIANCE_ASYMMETRY` and ``COVARIANCE_NEGATIVE`` (cyclic Jacobi
    eigenvalues, with a margin for their rounding: a matrix near the bound gives False, not a guess)."""
    n = len(cov)
    if not n:
        return True
    if not all(math.isfinite(x) for row in cov for x in row):
        return False
    size = max(max(abs(cov[i][i]) for i in range(n)), MIN_SCALE)
    if max(abs(cov[i][j] - cov[j][i]) for i in range(n) for j in range(n)) > COVARIANCE_ASYMMETRY * size:
        return False
    eigen = jacobi_eigenvalues(cov)
    frobenius = math.sqrt(sum(x * x for row in cov for x in row))
    if eigen is None or not all(math.isfinite(x) for x in (*eigen, frobenius)):
        return False
    return min(eigen) >= -COVARIANCE_NEGATIVE * size * n + 1e-12 * n * frobenius


def jacobi_eigenvalues(a: list[list[float]], sweeps: int = 50) -> list[float] | None:
    """Eigenvalues of the symmetric part of a small matrix by cyclic Jacobi rotations; None if not converged."""
    n = len(a)
    m = [[(a[i][j] + a[j][i]) / 2.0 for j in range(n)] for i in range(n)]
    scale = math.sqrt(sum(x * x for row in m for x in row))
    for _ in range(sweeps):
        off = math.sqrt(sum(m[i][j] ** 2 for i in range(n) for j in range(n) if i != j))
        if off <= 1e-15 * scale:
            return [m[i][i] for i in range(n)]
        for p in range(n - 1):
            for q in range(p + 1, n):
                if m[p][q] == 0.0:
                    continue
                theta = (m[q][q] - m[p][p]) / (2.0 * m[p][q])
                t = math.copysign(1.0, theta) / (abs(theta) + math.sqrt(theta * theta + 1.0))
                c = 1.0 / math.sqrt(t * t + 1.0)
                s = t * c
                for k in range(n):  # columns p, q, then rows p, q
                    mkp, mkq = m[k][p], m[k][q]
                    m[k][p], m[k][q] = c * mkp - s * mkq, s * mkp + c * mkq
                for k in range(n):
                    mpk, mqk = m[p][k], m[q][k]
                    m[p][k], m[q][k] = c * mpk - s * mqk, s * mpk + c * mqk
    return None


def _prediction_finite(doc: dict, coef: list, degree: int) -> bool:
    """True when the prediction at the training range's ends and centre is surely finite in numpy: every
    monomial of normalized inputs (and each partial product) is at most max(1, |z|)^degree, so a bound of
    their weighted sum far below float64's overflow proves it (the loader's own check decides the rest)."""
    inputs, outputs = doc["inputs"], doc["outputs"]
    low = [v["offset"] if v["range"][0] is None else v["range"][0] for v in inputs]
    high = [v["offset"] if v["range"][1] is None else v["range"][1] for v in inputs]
    biggest = 1.0
    for point in (low, [(a + b) / 2.0 for a, b in zip(low, high)], high):
        for u, v in zip(point, inputs):
            z = abs((u - v["offset"]) * (1.0 / v["scale"]))
            if not math.isfinite(z):
                return False
            biggest = max(biggest, z)
    reach = biggest ** degree if math.log10(biggest) * degree < 300 else math.inf
    for col, out in enumerate(outputs):
        bound = reach * sum(abs(row[col]) for row in coef) * 2.0 * out["scale"] + abs(out["offset"])
        if not bound < _SAFE:
            return False
    return True


def _raw_nonzero(coef: list, exponents: list, offset: list, scale: list, degree: int) -> int | None:
    """How many raw-input coefficients exceed :data:`RAW_THRESHOLD` in magnitude (``to_raw``'s substitution
    ``u = (x - offset) / scale`` expanded binomially); None when one is too near the threshold to tell."""
    column_of = {tuple(e): c for c, e in enumerate(exponents)}
    ny = len(coef[0]) if coef else 0
    total = [[0.0] * ny for _ in coef]
    parts = [[0.0] * ny for _ in coef]
    summands = [0] * len(coef)
    for c, e in enumerate(exponents):
        used = [i for i, k in enumerate(e) if k]
        for ks in product(*(range(e[i] + 1) for i in used)):
            factor = 1.0
            k = [0] * len(e)
            for i, ki in zip(used, ks):
                factor *= comb(e[i], ki) * (-offset[i]) ** (e[i] - ki) / scale[i] ** e[i]
                k[i] = ki
            row = column_of[tuple(k)]
            summands[row] += 1
            for j in range(ny):
                total[row][j] += factor * coef[c][j]
                parts[row][j] += abs(factor * coef[c][j])
    count = 0
    for row_t, row_p, n in zip(total, parts, summands):
        for value, bound in zip(row_t, row_p):
            if not (math.isfinite(value) and math.isfinite(bound)):
                return None
            if abs(abs(value) - RAW_THRESHOLD) <= (n + 3 * degree) * _ROUNDING * bound + 1e-300:
                return None
            count += abs(value) > RAW_THRESHOLD
    return count


def _largest(coef: list, ny: int, n: int) -> list[int]:
    """Flat indices (row-major) of the ``n`` largest |coefficients|, largest first, ties in term order (Python's
    sort is stable, as the loader's ``argsort(kind="stable")``)."""
    magnitude = [abs(x) for row in coef for x in row]
    return sorted(range(len(magnitude)), key=lambda f: -magnitude[f])[:n]


def loaded_facts(path: str, n_terms: int) -> dict:
    """What ``info`` prints, from the fully loaded model file (any family and format).

    :func:`light_facts` gives the same keys without numpy for static polynomial JSON files; this one
    imports numpy and the full loader, when it is called.
    """
    import numpy as np

    from .model_files import load_model_file

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
    # stable: equal magnitudes (a LASSO's exact zeros) listed in term order on every CPU (AVX-512 sorts ties its
    # own way)
    order = np.argsort(-magnitude, axis=None, kind="stable")[:max(n_terms, 0)]
    norm = model.input_normalization_
    facts["raw_basis"] = not (norm.offset.any() or (norm.scale != 1).any())
    facts["largest"] = []
    for flat in order:
        row, col = np.unravel_index(flat, magnitude.shape)
        facts["largest"].append((model.output_names_[col], names[row], model.coef_[row, col]))
    return facts
