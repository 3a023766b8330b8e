"""The live state file's envelope (``ftcal live --state``): its format and version, and the digest of the
calibration model it was written for, from the same canonical-JSON digest as model and payload files
(:func:`ftcal.files.json_document.digest`).

The fields inside (bias, covariance, tool, counters) are the live calibrator's, checked one by one by
:meth:`ftcal.live.calibrator.LiveCalibrator.load_state`.
"""

from __future__ import annotations

from ..runtime.errors import FtcalError
from .json_document import digest

STATE_FORMAT = "ftcal-live-state"
# 1.1: the model digest is json_document.digest (1.0 hashed json.dumps(default=repr)), so a 1.0 file's digest
# cannot be checked against any model and is refused by name rather than as "another model".
STATE_VERSION = "1.1"
EARLIER_VERSIONS = ("1.0",)


def state_envelope() -> dict:
    """The fields every live state file starts with."""
    return {"format": STATE_FORMAT, "format_version": STATE_VERSION}


def check_state_envelope(doc, source) -> None:
    """Refuse what is not a live state file of this version, in one line naming ``source``."""
    if isinstance(doc, dict) and doc.get("format") == STATE_FORMAT and doc.get("format_version") in EARLIER_VERSIONS:
        raise FtcalError(f"{source}: a live state file of an earlier ftcal ({STATE_FORMAT} {doc['format_version']}), "
                         f"whose model check this version cannot verify; move it away and start without it "
                         f"(the bias is re-identified from the first holds).")
    if not isinstance(doc, dict) or doc.get("format") != STATE_FORMAT or doc.get("format_version") != STATE_VERSION:
        raise FtcalError(f"{source}: not a live state file ({STATE_FORMAT} {STATE_VERSION}).")


def model_digest(model) -> str | None:
    """sha256 of a calibration model's inputs, outputs and model-file fields (None without a model).

    The canonical JSON of :func:`~ftcal.files.json_document.digest` (non-finite numbers as null, as the
    model file writes them): a state is never resumed with a bias that belongs to another model.
    """
    if model is None:
        return None
    from .model_json import jsonable

    return digest(jsonable({"inputs": list(model.input_names_), "outputs": list(model.output_names_),
                            "model": model.to_document()}))
