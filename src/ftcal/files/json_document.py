"""ftcal's JSON documents (model and payload files; the live state file's model digest) read strictly,
validated by their packaged schema and sealed by a sha256 digest, without numpy: ``ftcal info`` reads a
model file through this module alone (:mod:`ftcal.files.model_info`), :mod:`ftcal.files.model_json`
builds the model from what it returns."""

from __future__ import annotations

import hashlib
import json
import math
from functools import cache
from importlib import resources
from pathlib import Path

from ..core.limits import MAX_MODEL_BYTES
from ..runtime.errors import FtcalError
from ..runtime.inputs import check_input_file

FORMAT = "ftcal-model"
FORMAT_VERSION = "1.0"
SCHEMA_RESOURCE = "schemas/model-1.json"
_MESSAGE_LIMIT = 160
# Integers in a model file are counts and exponents; longer ones are hostile (and slow to parse).
_MAX_INT_DIGITS = 18


def ftcal_version() -> str:
    """The running ftcal's version (recorded in the files ftcal writes)."""
    from .. import __version__

    return __version__


def digest(doc: dict) -> str:
    """sha256 hex digest of the canonical JSON of ``doc`` without its ``sha256`` field."""
    content = {k: v for k, v in doc.items() if k != "sha256"}
    canonical = json.dumps(content, sort_keys=True, separators=(",", ":"), ensure_ascii=False, allow_nan=False)
    return hashlib.sha256(canonical.encode("utf-8")).hexdigest()


def check_model_size(path: Path, kind: str = "model") -> None:
    """Refuse a ``kind`` file larger than :data:`MAX_MODEL_BYTES` before reading it."""
    check_input_file(path, f"{kind} file", max_bytes=MAX_MODEL_BYTES)


def read_document_text(path: Path, kind: str = "model") -> str:
    """The UTF-8 text of an ftcal JSON document, size-checked first; one-line errors naming ``kind``."""
    check_model_size(path, kind)
    try:
        return path.read_text(encoding="utf-8")
    except UnicodeDecodeError as exc:
        raise FtcalError(f"{path}: not a JSON {kind} file (not UTF-8 text at byte {exc.start}).") from None
    except OSError as exc:
        raise FtcalError(f"Cannot read {kind} file {path}: {exc.strerror}.") from None


def check_document(doc: dict, source: str, resource: str = SCHEMA_RESOURCE, kind: str = "model") -> None:
    """Validate ``doc`` against the packaged schema ``resource``, then its sha256 digest.

    Raises
    ------
    FtcalError
        Naming ``source``, where the document breaks the schema, or that the
        content no longer matches its digest.
    """
    from .schema_subset import Unsupported, is_valid

    try:
        valid = is_valid(_schema(resource), doc)
    except Unsupported:
        valid = False
    if not valid:  # jsonschema finds the error and words it (imported only then: 0.2-0.3 s)
        import jsonschema

        error = jsonschema.exceptions.best_match(_validator(resource).iter_errors(doc))
    if not valid and error is not None:
        message = error.message if len(error.message) <= _MESSAGE_LIMIT else error.message[:_MESSAGE_LIMIT] + "…"
        raise FtcalError(f"{source}: invalid {kind} file at {error.json_path}: {message}.")
    try:
        sealed = digest(doc)
    except UnicodeEncodeError as exc:  # a JSON escape of a lone surrogate: it has no UTF-8
        raise FtcalError(f"{source}: a string holds U+{ord(exc.object[exc.start]):04X}, a lone surrogate, "
                         f"which is not text; not a valid {kind} file.") from None
    if sealed != doc["sha256"]:
        raise FtcalError(f"{source}: the sha256 digest does not match the content: the file was modified "
                         f"after it was written. Re-export it from the original {kind}.")


def parse_json(text: str, source: str, fmt: str = FORMAT, kind: str = "model") -> dict:
    """Parse an ftcal JSON file strictly: finite floats, bounded integers, no repeated keys.

    Parameters
    ----------
    text : the file's text
    source : the file's name, for messages
    fmt : the ``format`` field the document must have
    kind : what the file is (``"model"``, ``"payload"``), for messages

    Returns
    -------
    dict, the document

    Raises
    ------
    FtcalError
        Invalid JSON, NaN/Infinity, an overflowing number, an integer of more than 18
        digits, a key repeated in one object, too deep nesting, or another ``format``.
    """

    def reject_constant(name: str):
        raise FtcalError(f"{source}: {name} is not valid JSON ({kind} files write unknown numbers as null).")

    def finite_float(text: str) -> float:
        value = float(text)
        if not math.isfinite(value):
            raise FtcalError(f"{source}: the number {text[:40]} overflows float64.")
        return value

    def small_int(text: str) -> int:
        if len(text.lstrip("-")) > _MAX_INT_DIGITS:
            raise FtcalError(f"{source}: the integer {text[:20]}… has more than {_MAX_INT_DIGITS} digits.")
        return int(text)

    def unique_keys(pairs: list[tuple[str, object]]) -> dict:
        # A parser keeping the first of two equal keys would see other values than the digest covers.
        keys = [k for k, _ in pairs]
        if len(set(keys)) != len(keys):
            twice = next(k for k in keys if keys.count(k) > 1)
            raise FtcalError(f"{source}: the key {twice!r} appears twice in one JSON object.")
        return dict(pairs)

    try:
        doc = json.loads(text, parse_constant=reject_constant, parse_float=finite_float, parse_int=small_int,
                         object_pairs_hook=unique_keys)
    except json.JSONDecodeError as exc:
        raise FtcalError(f"{source}: not valid JSON: {exc.msg} at line {exc.lineno}, column {exc.colno}.") from None
    except RecursionError:
        raise FtcalError(f"{source}: JSON nested too deeply to be a {kind} file.") from None
    if not isinstance(doc, dict) or doc.get("format") != fmt:
        raise FtcalError(f"{source}: not an ftcal {kind} file (expected a JSON object with "
                         f"\"format\": \"{fmt}\").")
    return doc


def check_version(doc: dict, source: str, supported: str = FORMAT_VERSION) -> None:
    """Refuse a document whose ``format_version`` is not ``supported``, saying whether it is newer.

    Parameters
    ----------
    doc : the parsed document
    source : the file's name, for messages
    supported : the version this ftcal reads

    Raises
    ------
    FtcalError
    """
    version = doc.get("format_version")
    if version == supported:
        return
    try:
        newer = tuple(map(int, str(version).split("."))) > tuple(map(int, supported.split(".")))
    except ValueError:
        newer = False
    if newer:
        raise FtcalError(f"{source}: format_version {version} is newer than this ftcal ({ftcal_version()}) "
                         f"reads (up to {supported}); upgrade ftcal to load it.")
    raise FtcalError(f"{source}: unknown format_version {version!r}; this ftcal reads {supported}.")


@cache
def _schema(resource: str = SCHEMA_RESOURCE) -> dict:
    """The packaged schema ``resource``, parsed."""
    return json.loads(resources.files("ftcal").joinpath(resource).read_text(encoding="utf-8"))


@cache
def _validator(resource: str = SCHEMA_RESOURCE):
    """The schema validator (jsonschema is imported only when a document is not valid: it words the error)."""
    import jsonschema

    schema = _schema(resource)
    # JSON integers only: jsonschema would also accept 2.0 as an "integer".
    strict = jsonschema.Draft202012Validator.TYPE_CHECKER.redefine(
        "integer", lambda _, value: isinstance(value, int) and not isinstance(value, bool))
    return jsonschema.validators.extend(jsonschema.Draft202012Validator, type_checker=strict)(schema)
