"""The native model file: JSON validated by ``schemas/model-1.json``, with a sha256 digest.

The file keeps the normalized-basis coefficients the model was fitted with,
every float written by ``repr`` (which round-trips exactly), so a loaded model
predicts bit-identically to the saved one. Non-finite numbers (NaN metrics, an
unknown condition number, unknown training ranges) are written as ``null``.

The digest is the sha256 of the canonical JSON (sorted keys, no spaces, UTF-8)
of every field except ``sha256``; it is computed from parsed values, so the
file's layout and number spelling do not matter, only its content.
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Sequence
from dataclasses import dataclass
from datetime import datetime, timezone
from pathlib import Path

import numpy as np

from ..core.families import DEFAULT_FAMILY, ModelFamily, family_class, family_of
from ..core.limits import COVARIANCE_ASYMMETRY, COVARIANCE_NEGATIVE, MIN_SCALE
from ..core.normalization import Normalization
from ..runtime.atomic import write_text_atomic
from ..runtime.deprecation import deprecated_alias
from ..runtime.errors import FtcalError
from .json_document import (  # noqa: F401  (the strict reader, schema and digest: one source, re-exported)
    _MAX_INT_DIGITS, _MESSAGE_LIMIT, FORMAT, FORMAT_VERSION, SCHEMA_RESOURCE, _schema, _validator, check_document,
    check_model_size, check_version, digest, ftcal_version, parse_json, read_document_text)

PER_OUTPUT_METRICS = ("rmse", "best_fit", "max_abs_error", "residual_autocorrelation_lag1")


@dataclass(frozen=True)
class ModelFile:
    """A loaded model file: the model plus what the model object does not carry."""

    model: ModelFamily  # a fitted model of a registered family (CalibrationModel for polynomials)
    input_units: tuple[str | None, ...]
    output_units: tuple[str | None, ...]
    sources: tuple[str, ...]
    created_utc: str | None  # None for formats without creation metadata
    ftcal_version: str | None
    # fingerprints of the training segments (ftcal.core.fingerprint); empty when the file has none
    training_segments: tuple[dict, ...] = ()
    prior: dict | None = None  # {"source", "file_sha256"} of a --prior fit's prior model file


# ---------------------------------------------------------------- writing
def write_model_json(model: ModelFamily, path: str | Path, *, sources: Sequence[str] = (),
                     input_units: Sequence[str | None] | None = None,
                     output_units: Sequence[str | None] | None = None,
                     training_segments: Sequence[dict] | None = None, prior: str | Path | None = None) -> None:
    """Write ``model`` to ``path`` as a native JSON model file (atomically); ``ftcal.save_model``'s default format.

    ``training_segments``: :func:`ftcal.core.fingerprint.segment_fingerprints` of the training
    data, so that ``ftcal evaluate`` can warn about evaluation data the model was trained on.
    ``prior``: the model file the fit was shrunk toward (``--prior``), recorded with its digest.

    Examples
    --------
    >>> import pathlib, tempfile
    >>> import numpy as np
    >>> from ftcal import CalibrationModel
    >>> path = pathlib.Path(tempfile.mkdtemp()) / "model.json"
    >>> write_model_json(CalibrationModel(1).fit(np.array([[0.0], [1.0], [2.0]]), np.array([[1.0], [3.0], [5.0]])),
    ...                  path)
    >>> read_model_json(path).model.n_coefficients
    2
    """
    write_text_atomic(path, format_document(model_document(model, sources=sources, input_units=input_units,
                                                           output_units=output_units,
                                                           training_segments=training_segments, prior=prior)))


def model_document(model: ModelFamily, *, sources: Sequence[str] = (),
                   input_units: Sequence[str | None] | None = None,
                   output_units: Sequence[str | None] | None = None,
                   training_segments: Sequence[dict] | None = None, prior: str | Path | None = None) -> dict:
    """The model file content as a JSON-ready dict, digest included (see :func:`write_model_json`).

    The envelope (inputs, outputs, training metrics, creation data, digest) is the same for
    every family; the family adds its own fields (:meth:`ModelFamily.to_document`).
    """
    family = family_of(model)
    model.describe()  # raises NotFittedError before anything else
    own = model.to_document()
    info = jsonable(model.solver_info_)
    doc = {"format": FORMAT, "format_version": FORMAT_VERSION, "family": family}
    if "model" in own:
        doc["model"] = jsonable(own["model"])
    doc["inputs"] = _variables(model.input_names_, input_units, model.input_normalization_,
                               model.input_range_, "input_units")
    doc["outputs"] = _variables(model.output_names_, output_units, model.output_normalization_,
                                model.output_range_, "output_units")
    doc.update({key: jsonable(value) for key, value in own.items() if key not in ("model", "fit")})
    doc["fit"] = {"solver": {**info, "name": info.get("name"), "lambda": info.get("lambda")},
                  "n_samples": model.n_samples_fit_, **jsonable(own.get("fit", {})),
                  "metrics": jsonable(model.training_metrics_)}
    doc["created"] = {
        "ftcal_version": ftcal_version(),
        "time_utc": datetime.now(timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ"),
        "sources": [str(s) for s in sources],
    }
    if training_segments:
        doc["fit"]["training_segments"] = [dict(fp) for fp in training_segments]
    if getattr(model, "input_spread_", None) is not None:
        doc["fit"]["input_spread"] = jsonable(model.input_spread_.to_json())
    if prior is not None:
        digest_of_file = hashlib.sha256(Path(prior).read_bytes()).hexdigest()
        doc["fit"]["prior"] = {"source": str(prior), "file_sha256": digest_of_file}
    if any(v[key] is None for v in (*doc["inputs"], *doc["outputs"]) for key in ("offset", "scale")):
        raise FtcalError("The model has a non-finite normalization offset or scale; refusing to save it.")
    doc["sha256"] = digest(doc)
    return doc


def _variables(names: Sequence[str], units: Sequence[str | None] | None, norm: Normalization,
               ranges: np.ndarray, what: str) -> list[dict]:
    if units is not None and len(units) != len(names):
        raise FtcalError(f"{what} has {len(units)} entries; the model has {len(names)} ({', '.join(names)}).")
    units = list(units) if units is not None else [None] * len(names)
    return [{"name": n, "unit": u, "offset": float(o), "scale": float(s), "range": jsonable(r)}
            for n, u, o, s, r in zip(names, units, norm.offset, norm.scale, ranges)]


def jsonable(value):
    """Plain JSON values: numpy scalars and arrays converted, non-finite floats as None.

    Parameters
    ----------
    value : dict, list, tuple, ndarray, numpy or Python scalar, str or None (nested freely)

    Returns
    -------
    The same structure with only dict, list, str, int, float, bool and None.
    """
    if isinstance(value, dict):
        return {str(k): jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple, np.ndarray)):
        return [jsonable(v) for v in value]
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, (int, np.integer)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        return float(value) if np.isfinite(value) else None
    if value is None or isinstance(value, str):
        return value
    return str(value)


def format_document(doc: dict) -> str:
    """Indented JSON with each flat list (a coefficient row, an exponent row) on one line."""
    return _format(doc, 0) + "\n"


def _format(value, depth: int) -> str:
    pad, close = "  " * (depth + 1), "  " * depth
    if isinstance(value, dict) and value:
        items = [f"{pad}{json.dumps(k, ensure_ascii=False)}: {_format(v, depth + 1)}" for k, v in value.items()]
        return "{\n" + ",\n".join(items) + "\n" + close + "}"
    if isinstance(value, list) and any(isinstance(v, (dict, list)) for v in value):
        return "[\n" + ",\n".join(pad + _format(v, depth + 1) for v in value) + "\n" + close + "]"
    return json.dumps(value, ensure_ascii=False, allow_nan=False)


# ---------------------------------------------------------------- reading
def read_model_json(path: str | Path) -> ModelFile:
    """Read a native JSON model file: the model, its units, data sources and creation metadata.

    ``ftcal.load_model`` reads this format and the others, told apart by content.

    Raises
    ------
    FtcalError
        Saying what is wrong and where.
    """
    path = Path(path)
    return parse_model(read_document_text(path), str(path))


def parse_model(text: str, source: str = "<model>") -> ModelFile:
    """Parse and validate model-file ``text``; ``source`` names it in error messages."""
    doc = parse_json(text, source)
    check_version(doc, source)
    check_document(doc, source)
    return _build(doc, source)


def _build(doc: dict, source: str) -> ModelFile:
    """The model from a schema-valid document: envelope checks here, the rest by the model's family."""
    inputs, outputs = doc["inputs"], doc["outputs"]
    for what, variables in (("inputs", inputs), ("outputs", outputs)):
        names = [v["name"] for v in variables]
        if len(set(names)) != len(names):
            raise FtcalError(f"{source}: {what} names repeat ({', '.join(names)}); each must be unique.")
    fit = doc["fit"]
    for key in PER_OUTPUT_METRICS:
        values = fit["metrics"].get(key)
        if values is not None and len(values) != len(outputs):
            raise FtcalError(f"{source}: fit.metrics.{key} has {len(values)} values; the model has "
                             f"{len(outputs)} outputs.")
    # No family field: a file written before families existed, a polynomial.
    model = family_class(doc.get("family", DEFAULT_FAMILY), source).from_document(doc, source)
    check_envelope_consistency(doc, source)
    _check_finite_over_training_range(model, doc, source)
    created = doc["created"]
    return ModelFile(model, tuple(v["unit"] for v in inputs), tuple(v["unit"] for v in outputs),
                     tuple(created["sources"]), created["time_utc"], created["ftcal_version"],
                     tuple(fit.get("training_segments", ())), fit.get("prior"))


def check_envelope_consistency(doc: dict, source: str) -> None:
    """Refuse a schema-valid, correctly signed document whose envelope contradicts itself.

    A digest proves the file was not changed after it was written, not that the writer was
    right: a hand-edited and re-signed file, or one from another tool, can hold an input range
    with min > max, a scale too small to divide by, per-output metrics for other outputs or a
    covariance that is no covariance. Each is refused here, once, for every consumer (``predict``,
    ``evaluate``, ``report``, ``info``, ``check``, ``compensate``, every ``convert`` target).

    Raises
    ------
    FtcalError
        Naming ``source``, the field (JSON path) and what is wrong with it.
    """
    tiny = MIN_SCALE
    for what in ("inputs", "outputs"):
        for k, variable in enumerate(doc[what]):
            where = f"{source}: {what}[{k}] ({variable['name']!r})"
            low, high = variable["range"]
            if low is not None and high is not None and low > high:
                raise FtcalError(f"{where}: range [{low:g}, {high:g}] has min > max.")
            offset, scale = variable["offset"], variable["scale"]
            if not tiny <= scale < np.inf:
                raise FtcalError(f"{where}: scale {scale:g} is too small to divide by (a normalization scale "
                                 f"must be at least {tiny:.3g}).")
            for bound in (low, high):
                if bound is not None and not np.isfinite((bound - offset) / scale):
                    raise FtcalError(f"{where}: range bound {bound:g} with offset {offset:g} and scale {scale:g} "
                                     "normalizes to an infinite value.")
    fit = doc["fit"]
    names = [v["name"] for v in doc["outputs"]]
    listed = fit["metrics"].get("outputs")
    if listed is not None and list(listed) != names:
        raise FtcalError(f"{source}: fit.metrics.outputs lists {', '.join(map(str, listed))}; the model's outputs "
                         f"are {', '.join(names)}.")
    n_terms = len(doc.get("coefficients", ()))
    if n_terms and fit["rank"] > n_terms:
        raise FtcalError(f"{source}: fit.rank {fit['rank']} exceeds the {n_terms} terms per output.")
    spread = fit.get("input_spread")
    if spread is not None and all(isinstance(r, list) for r in spread["covariance"]):
        try:
            cov = np.array(spread["covariance"], dtype=np.float64)
        except (TypeError, ValueError):
            return  # wrong shapes or nulls: the family's reader names them
        if cov.ndim == 2 and cov.shape[0] == cov.shape[1] and np.isfinite(cov).all():
            size = max(float(np.abs(np.diag(cov)).max(initial=0.0)), tiny)
            if np.abs(cov - cov.T).max(initial=0.0) > COVARIANCE_ASYMMETRY * size:
                raise FtcalError(f"{source}: fit.input_spread.covariance is not symmetric.")
            if cov.size and np.linalg.eigvalsh(cov).min() < -COVARIANCE_NEGATIVE * size * len(cov):
                raise FtcalError(f"{source}: fit.input_spread.covariance has a negative variance direction "
                                 "(not positive semi-definite).")


def _check_finite_over_training_range(model: ModelFamily, doc: dict, source: str) -> None:
    """Refuse a static model whose prediction overflows at its own training range's ends or centre."""
    spec = doc.get("model", {})
    if spec.get("na", 0) or spec.get("nb", 0):
        return  # ARX: a prediction needs past outputs; its coefficients and scales are checked above
    low = np.array([v["offset"] if v["range"][0] is None else v["range"][0] for v in doc["inputs"]], dtype=float)
    high = np.array([v["offset"] if v["range"][1] is None else v["range"][1] for v in doc["inputs"]], dtype=float)
    points = np.vstack([low, (low + high) / 2.0, high])
    with np.errstate(all="ignore"):
        predicted = np.asarray(model.predict(points, warn_out_of_range=False), dtype=np.float64)
    if not np.isfinite(predicted).all():
        raise FtcalError(f"{source}: the model's prediction overflows (inf or NaN) inside its own training range; "
                         "its coefficients or normalization are not those of a fitted model.")


# The old names, one release (runtime.deprecation); the entry points read and write every format.
save_model = deprecated_alias("ftcal.files.model_files:save_model", "ftcal.files.model_json.save_model",
                              "ftcal.save_model")
load_model = deprecated_alias("ftcal.files.model_files:load_model", "ftcal.files.model_json.load_model",
                              "ftcal.load_model")
load_model_file = deprecated_alias("ftcal.files.model_files:load_model_file",
                                   "ftcal.files.model_json.load_model_file",
                                   "ftcal.files.model_files.load_model_file")
