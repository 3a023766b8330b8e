"""The payload file (``ftcal payload -o payload.json``): JSON validated by ``schemas/payload-1.json``.

Same machinery as the model file (:mod:`ftcal.files.model_json`): floats written
by ``repr``, a sha256 digest of the canonical JSON, schema and version checks
with one-line errors.
"""

from __future__ import annotations

from collections.abc import Sequence
from datetime import datetime, timezone
from pathlib import Path

import numpy as np

from ..core.precision import DIRECTION, settle
from ..payload.drift import BiasDrift
from ..payload.identify import Undetermined, undetermined_fields
from ..payload.parameters import PayloadParameters
from ..runtime.atomic import write_text_atomic
from ..runtime.errors import FtcalError
from .model_json import (
    check_document,
    check_version,
    digest,
    format_document,
    ftcal_version,
    jsonable,
    parse_json,
    read_document_text,
)

FORMAT = "ftcal-payload"
# 1.1 adds the optional ``undetermined`` field (and null standard errors for what it names); files
# without it are written as 1.0, so older ftcal reads them as before.
FORMAT_VERSION = "1.1"
BASE_VERSION = "1.0"
SCHEMA_RESOURCE = "schemas/payload-1.json"


def payload_document(payload: PayloadParameters, *, sources: Sequence[str] = ()) -> dict:
    """The payload file content as a JSON-ready dict, digest included.

    Raises
    ------
    FtcalError
        When a value is not finite (nothing would be worth writing).
    """
    stderr = {k: jsonable(v) for k, v in payload.stderr.items()}
    doc = {
        "format": FORMAT,
        "format_version": BASE_VERSION,
        "mass": jsonable(payload.mass),
        "com": jsonable(np.asarray(payload.com)),
        "force_bias": jsonable(np.asarray(payload.force_bias)),
        "torque_bias": jsonable(np.asarray(payload.torque_bias)),
        "gravity": jsonable(payload.gravity),
        "frame": payload.frame,
        "reaction": bool(payload.reaction),
        "stderr": stderr,
        "fit": jsonable(payload.fit),
        "created": {"ftcal_version": ftcal_version(),
                    "time_utc": datetime.now(timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ"),
                    "sources": [str(s) for s in sources]},
    }
    if payload.inertia is not None:
        doc["inertia"] = jsonable(np.asarray(payload.inertia))
    if payload.drift is not None:
        doc["drift"] = drift_document(payload.drift)
    if payload.undetermined is not None:
        doc["format_version"] = FORMAT_VERSION
        doc["undetermined"] = undetermined_document(payload.undetermined)
    if None in _leaves([doc[k] for k in ("mass", "com", "force_bias", "torque_bias", "gravity")]
                       + [_determined(stderr, payload.undetermined), doc.get("undetermined", {}).get("directions", [])]
                       + [doc.get("inertia", []), doc.get("drift", {}).get("knots", {}),
                          doc.get("drift", {}).get("temperature", {}).get("coefficients", []),
                          doc.get("drift", {}).get("random_walk", {})]):
        raise FtcalError("The payload has non-finite values (NaN or inf); refusing to save it.")
    doc["sha256"] = digest(doc)
    return doc


def drift_document(drift: BiasDrift) -> dict:
    """The ``drift`` field of a payload file."""
    doc = {"model": drift.model, "time_column": drift.time_column,
           "time_start": jsonable(drift.time_start), "time_end": jsonable(drift.time_end)}
    if drift.knot_times is not None:
        doc["knots"] = {"time": jsonable(np.asarray(drift.knot_times)), "bias": jsonable(np.asarray(drift.knot_bias))}
    if drift.temperature_coefficients is not None:
        doc["temperature"] = {"column": drift.temperature_column,
                              "reference": jsonable(drift.temperature_reference),
                              "coefficients": jsonable(np.asarray(drift.temperature_coefficients))}
    if drift.walk_variance is not None:
        doc["random_walk"] = {"walk_variance": jsonable(np.asarray(drift.walk_variance)),
                              "noise_variance": jsonable(np.asarray(drift.noise_variance)),
                              "block_samples": jsonable(drift.block_samples)}
        for key in ("sample_variance", "wander_variance", "wander_tau", "block_seconds", "hold_seconds",
                    "hold_walk_variance"):
            value = getattr(drift, key)  # optional: files written before them lack them
            if value is not None:
                doc["random_walk"][key] = jsonable(value if np.ndim(value) == 0 else np.asarray(value))
    if drift.selection:
        doc["selection"] = drift.selection
    return doc


def _determined(stderr: dict, undetermined: Undetermined | None) -> dict:
    """The standard errors of what the poses determined: null (NaN) is allowed only where
    ``undetermined`` says there is no estimate (the whole inertia when any COM component or inertia
    parameter is undetermined)."""
    if undetermined is None:
        return stderr
    fields = undetermined_fields(undetermined.parameters)
    out = dict(stderr)
    for key, index in fields.items():
        if key in out and key != "inertia":
            out[key] = [0.0 if j in index else v for j, v in enumerate(out[key])]
    if "inertia" in fields or "com" in fields:
        out.pop("inertia", None)
    return out


def undetermined_document(undetermined: Undetermined) -> dict:
    """The ``undetermined`` field of a payload file."""
    return {"parameter_names": list(undetermined.names), "parameters": list(undetermined.parameters),
            "held_at_zero": list(undetermined.held), "rank": int(undetermined.rank),
            # A null space: stated to its precision, each direction relative to its largest component.
            "directions": [jsonable(settle(d, DIRECTION)) for d in np.asarray(undetermined.directions).T],
            "message": undetermined.message}


def _parse_undetermined(doc: dict, source: str) -> Undetermined:
    names = tuple(doc["parameter_names"])
    directions = np.asarray(doc["directions"], dtype=float).T
    if directions.shape != (len(names), len(doc["held_at_zero"])) or not set(doc["held_at_zero"]) <= set(
            doc["parameters"]) or not set(doc["parameters"]) <= set(names) or "m" in doc["parameters"]:
        raise FtcalError(f"{source}: undetermined needs one direction of {len(names)} numbers per held parameter, "
                         "held parameters among the undetermined ones, and a determined mass.")
    return Undetermined(names, tuple(doc["parameters"]), tuple(doc["held_at_zero"]), directions, int(doc["rank"]),
                        doc["message"])


def _parse_drift(doc: dict, source: str) -> BiasDrift:
    knots = doc.get("knots")
    temperature = doc.get("temperature")
    walk = doc.get("random_walk")
    if walk is not None and doc["model"] != "random-walk":
        raise FtcalError(f"{source}: drift.random_walk belongs to the random-walk model, not {doc['model']!r}.")
    if knots is not None:
        times = np.asarray(knots["time"], dtype=float)
        if len(knots["bias"]) != len(times) or np.any(np.diff(times) <= 0):
            raise FtcalError(f"{source}: drift.knots needs increasing times and one bias per time.")
        if doc["time_start"] is None or doc["time_end"] is None or doc["time_column"] is None:
            raise FtcalError(f"{source}: drift.knots needs time_column, time_start and time_end.")
    if temperature is not None and temperature["column"] is None:
        raise FtcalError(f"{source}: drift.temperature needs its column.")
    return BiasDrift(doc["model"], doc["time_column"], doc["time_start"], doc["time_end"],
                     None if knots is None else np.asarray(knots["time"], dtype=float),
                     None if knots is None else np.asarray(knots["bias"], dtype=float),
                     None if temperature is None else temperature["column"],
                     None if temperature is None else float(temperature["reference"]),
                     None if temperature is None else np.asarray(temperature["coefficients"], dtype=float),
                     doc.get("selection", ""),
                     *((None, None, None) if walk is None else (np.asarray(walk["walk_variance"], dtype=float),
                                                                 np.asarray(walk["noise_variance"], dtype=float),
                                                                 float(walk["block_samples"]))),
                     *((None,) * 6 if walk is None else (
                         *(None if walk.get(k) is None else np.asarray(walk[k], float)
                           for k in ("sample_variance", "wander_variance", "wander_tau")),
                         *(None if walk.get(k) is None else float(walk[k]) for k in ("block_seconds", "hold_seconds")),
                         None if walk.get("hold_walk_variance") is None else np.asarray(walk["hold_walk_variance"],
                                                                                        float))))


def _check_inertia(inertia: np.ndarray, source: str) -> None:
    """A rigid body's inertia about its COM: symmetric, principal moments >= 0 meeting the triangle inequality."""
    size = max(float(np.abs(inertia).max()), np.finfo(np.float64).tiny)
    if np.abs(inertia - inertia.T).max() > 1e-9 * size:
        raise FtcalError(f"{source}: inertia is not symmetric; it must be a rigid body's inertia matrix.")
    moments = np.linalg.eigvalsh((inertia + inertia.T) / 2.0)  # ascending
    if moments[0] < -1e-9 * size or moments[2] > moments[0] + moments[1] + 1e-9 * size:
        raise FtcalError(f"{source}: inertia has principal moments {', '.join(f'{v:.3g}' for v in moments)} kg m^2; "
                         "a rigid body's are >= 0 and each at most the sum of the other two.")


def _check_drift_span(drift: dict, source: str) -> None:
    """The drift's recording span must run forward and hold its knots."""
    start, end = drift["time_start"], drift["time_end"]
    if start is not None and end is not None and start > end:
        raise FtcalError(f"{source}: drift.time_start {start:g} s is after drift.time_end {end:g} s.")
    knots = drift.get("knots")
    if knots is not None and start is not None and end is not None and (
            min(knots["time"]) < start - 1e-9 * max(abs(start), 1.0)
            or max(knots["time"]) > end + 1e-9 * max(abs(end), 1.0)):
        raise FtcalError(f"{source}: drift.knots.time runs outside [time_start, time_end] = [{start:g}, {end:g}] s.")
def _check_plausible(doc: dict, source: str) -> None:
    """Refuse physically absurd values (a typo or a hostile file) and a wrench read from repeated columns."""
    import math

    from ..core.limits import GRAVITY_RANGE, MAX_LOAD_DISTANCE, MAX_LOAD_MASS, MAX_WRENCH

    if not doc["mass"] <= MAX_LOAD_MASS:
        raise FtcalError(f"{source}: mass {doc['mass']:g} kg is beyond {MAX_LOAD_MASS:g} kg.")
    distance = math.hypot(*map(float, doc["com"]))
    if not distance <= MAX_LOAD_DISTANCE:
        raise FtcalError(f"{source}: centre of mass {distance:g} m from the sensor is beyond {MAX_LOAD_DISTANCE:g} m.")
    if not GRAVITY_RANGE[0] <= doc["gravity"] <= GRAVITY_RANGE[1]:
        raise FtcalError(f"{source}: gravity {doc['gravity']:g} m/s² is outside {GRAVITY_RANGE[0]:g} to "
                         f"{GRAVITY_RANGE[1]:g} m/s².")
    for key in ("force_bias", "torque_bias"):
        if not max(abs(float(v)) for v in doc[key]) <= MAX_WRENCH:
            raise FtcalError(f"{source}: {key} holds values beyond {MAX_WRENCH:g}.")
    columns = doc["fit"].get("wrench_columns") or []
    repeated = sorted({c for c in columns if columns.count(c) > 1})
    if repeated:
        raise FtcalError(f"{source}: fit.wrench_columns repeats {', '.join(map(repr, repeated))}; six distinct "
                         "columns make a wrench.")


def _leaves(value) -> list:
    """Every scalar in nested lists and dict values (non-finite floats are None after jsonable)."""
    if isinstance(value, dict):
        return _leaves(list(value.values()))
    if isinstance(value, list):
        return [x for v in value for x in _leaves(v)]
    return [value]


def save_payload(payload: PayloadParameters, path: str | Path, *, sources: Sequence[str] = ()) -> None:
    """Write ``payload`` to ``path`` as a payload file, atomically."""
    write_text_atomic(path, format_document(payload_document(payload, sources=sources)))


def load_payload(path: str | Path) -> PayloadParameters:
    """Read and check a payload file.

    Raises
    ------
    FtcalError
        Unreadable, not JSON, another format or version, schema violation,
        or a digest that does not match (the file was edited).
    """
    path = Path(path)
    return parse_payload(read_document_text(path, "payload"), str(path))


def parse_payload(text: str, source: str = "<payload>") -> PayloadParameters:
    """Parse and validate payload-file ``text``; ``source`` names it in error messages."""
    doc = parse_json(text, source, FORMAT, "payload")
    if doc.get("format_version") != BASE_VERSION:
        check_version(doc, source, FORMAT_VERSION)
    check_document(doc, source, SCHEMA_RESOURCE, "payload")
    if ("undetermined" in doc) != (doc["format_version"] == FORMAT_VERSION):
        raise FtcalError(f"{source}: format_version {FORMAT_VERSION} goes with the undetermined field, "
                         f"{BASE_VERSION} without it.")
    undetermined = _parse_undetermined(doc["undetermined"], source) if "undetermined" in doc else None
    if undetermined is None and None in _leaves(doc["stderr"]):
        raise FtcalError(f"{source}: stderr has null entries but no undetermined field says why.")
    stderr = {k: np.asarray(v, dtype=float) if isinstance(v, list) else float(v) for k, v in doc["stderr"].items()}
    if doc["mass"] <= 0:
        raise FtcalError(f"{source}: mass is {doc['mass']} kg; a payload file needs a positive mass.")
    _check_plausible(doc, source)
    inertia = np.asarray(doc["inertia"], dtype=float) if "inertia" in doc else None
    if inertia is not None:
        _check_inertia(inertia, source)
    if "drift" in doc:
        _check_drift_span(doc["drift"], source)
    fit = dict(doc["fit"])
    fit["residual_rms"] = np.asarray(fit["residual_rms"], dtype=float)
    return PayloadParameters(float(doc["mass"]), np.asarray(doc["com"], dtype=float),
                             np.asarray(doc["force_bias"], dtype=float), np.asarray(doc["torque_bias"], dtype=float),
                             float(doc["gravity"]), doc["frame"], doc["reaction"], inertia, stderr, fit,
                             _parse_drift(doc["drift"], source) if "drift" in doc else None, undetermined)
