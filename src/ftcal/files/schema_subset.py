"""Whether a document is valid under one of ftcal's packaged JSON schemas, without importing jsonschema.

jsonschema's import costs 0.2-0.3 CPU s (its referencing and metaschema packages), more than the rest of
``ftcal info MODEL``. The packaged schemas use a small subset of JSON Schema 2020-12 (listed in
:data:`KEYWORDS`); this module decides validity for that subset, with ftcal's strict integers (a JSON
2.0 is no integer). It only decides: a document it finds invalid, or a schema with any other keyword,
goes to jsonschema, which finds the error and words the message (:func:`ftcal.files.model_json.check_document`).
"""

from __future__ import annotations

import re

KEYWORDS = frozenset({
    "$schema", "title", "description", "$defs", "$ref", "type", "const", "enum", "required", "properties",
    "additionalProperties", "items", "minItems", "maxItems", "minimum", "maximum", "exclusiveMinimum",
    "exclusiveMaximum", "pattern", "minLength", "maxLength", "if", "then", "else",
})


class Unsupported(Exception):
    """The schema uses a keyword (or a reference) outside the subset: ask jsonschema."""


def is_valid(schema: dict, document) -> bool:
    """Whether ``document`` is valid under ``schema`` (its ``$defs`` resolve ``#/$defs/NAME`` references).

    Raises
    ------
    Unsupported
        The schema needs more than the subset.
    """
    return _valid(schema, document, schema)


def _valid(node, value, root) -> bool:
    if node is True or node is False:
        return node
    unknown = set(node) - KEYWORDS
    if unknown:
        raise Unsupported(", ".join(sorted(unknown)))
    if "$ref" in node:
        ref = node["$ref"]
        if not ref.startswith("#/$defs/") or ref[8:] not in root.get("$defs", {}):
            raise Unsupported(ref)
        if not _valid(root["$defs"][ref[8:]], value, root):
            return False
    if "type" in node:
        kinds = node["type"] if isinstance(node["type"], list) else [node["type"]]
        if not any(_is_type(value, kind) for kind in kinds):
            return False
    if "const" in node and not _equal(value, node["const"]):
        return False
    if "enum" in node and not any(_equal(value, option) for option in node["enum"]):
        return False
    if _is_type(value, "number") and not _number_ok(node, value):
        return False
    if isinstance(value, str) and not _string_ok(node, value):
        return False
    if isinstance(value, list) and not _array_ok(node, value, root):
        return False
    if isinstance(value, dict) and not _object_ok(node, value, root):
        return False
    if "if" in node:
        branch = node.get("then") if _valid(node["if"], value, root) else node.get("else")
        if branch is not None and not _valid(branch, value, root):
            return False
    return True


def _is_type(value, kind: str) -> bool:
    if kind == "object":
        return isinstance(value, dict)
    if kind == "array":
        return isinstance(value, list)
    if kind == "string":
        return isinstance(value, str)
    if kind == "boolean":
        return isinstance(value, bool)
    if kind == "null":
        return value is None
    if kind == "integer":
        return isinstance(value, int) and not isinstance(value, bool)
    if kind == "number":
        return isinstance(value, (int, float)) and not isinstance(value, bool)
    raise Unsupported(f"type {kind!r}")


def _equal(a, b) -> bool:
    """JSON equality: booleans are not numbers, 1 equals 1.0, containers compare item by item."""
    if isinstance(a, bool) or isinstance(b, bool):
        return isinstance(a, bool) and isinstance(b, bool) and a == b
    if isinstance(a, list) and isinstance(b, list):
        return len(a) == len(b) and all(_equal(x, y) for x, y in zip(a, b))
    if isinstance(a, dict) and isinstance(b, dict):
        return a.keys() == b.keys() and all(_equal(a[k], b[k]) for k in a)
    if isinstance(a, (list, dict)) or isinstance(b, (list, dict)):
        return False
    if isinstance(a, (int, float)) and isinstance(b, (int, float)):
        return a == b
    return type(a) is type(b) and a == b


def _number_ok(node, value) -> bool:
    return not (("minimum" in node and value < node["minimum"]) or ("maximum" in node and value > node["maximum"])
                or ("exclusiveMinimum" in node and value <= node["exclusiveMinimum"])
                or ("exclusiveMaximum" in node and value >= node["exclusiveMaximum"]))


def _string_ok(node, value) -> bool:
    if "minLength" in node and len(value) < node["minLength"]:
        return False
    if "maxLength" in node and len(value) > node["maxLength"]:
        return False
    return "pattern" not in node or re.search(node["pattern"], value) is not None


def _array_ok(node, value, root) -> bool:
    if "minItems" in node and len(value) < node["minItems"]:
        return False
    if "maxItems" in node and len(value) > node["maxItems"]:
        return False
    return "items" not in node or all(_valid(node["items"], item, root) for item in value)


def _object_ok(node, value, root) -> bool:
    if any(key not in value for key in node.get("required", ())):
        return False
    properties = node.get("properties", {})
    for key, item in value.items():
        if key in properties:
            if not _valid(properties[key], item, root):
                return False
        elif "additionalProperties" in node and not _valid(node["additionalProperties"], item, root):
            return False
    return True
