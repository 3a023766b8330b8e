"""Fingerprints of training segments, to notice evaluation data that the model was trained on.

``ftcal fit`` stores one fingerprint per training segment in the model file: its number
of rows, a 64-bit hash of its first row and the sha256 of all its values (inputs then
outputs, float64). :func:`find_training_segments` looks for each fingerprinted segment
as a contiguous block anywhere in other data, however that data is split into files or
segments, so evaluating on a file that contains training recordings is detected.
"""

from __future__ import annotations

import hashlib
import warnings

import numpy as np

from ..runtime.errors import FtcalWarning
from .dataset import Dataset

# Checking more candidate positions than this per segment only costs time on degenerate data.
MAX_CANDIDATES = 1000
_MIX = np.uint64(0x9E3779B97F4A7C15)


def _values(data: Dataset) -> np.ndarray:
    parts = [data.inputs] + ([data.outputs] if data.outputs is not None else [])
    return np.ascontiguousarray(np.concatenate(parts, axis=1), dtype="<f8")


def row_hashes(values: np.ndarray) -> np.ndarray:
    """A 64-bit hash per row of a float64 array (n, k), ndarray of uint64 of shape (n,)."""
    bits = values.view(np.uint64).reshape(values.shape)
    h = np.zeros(values.shape[0], dtype=np.uint64)
    for j in range(bits.shape[1]):  # integer arithmetic wraps modulo 2**64, as a hash wants
        h = (h ^ bits[:, j]) * _MIX
        h ^= h >> np.uint64(29)
    return h


def _digest(block: np.ndarray) -> str:
    return hashlib.sha256(np.ascontiguousarray(block, dtype="<f8").tobytes()).hexdigest()


def segment_fingerprints(data: Dataset) -> list[dict]:
    """One ``{"rows", "first_row", "sha256"}`` per segment of ``data`` (inputs then outputs)."""
    values = _values(data)
    heads = row_hashes(values)
    return [{"rows": b - a, "first_row": f"{int(heads[a]):016x}", "sha256": _digest(values[a:b])}
            for a, b in data.segment_bounds()]


def find_training_segments(data: Dataset, fingerprints: list[dict]) -> list[int]:
    """Indices of the ``fingerprints`` whose segment appears, whole and contiguous, in ``data``."""
    if not fingerprints or data.n_samples == 0:
        return []
    values = _values(data)
    hashes = row_hashes(values)
    found = []
    for index, fp in enumerate(fingerprints):
        head, rows = np.uint64(int(fp["first_row"], 16)), int(fp["rows"])
        starts = np.flatnonzero(hashes == head)[:MAX_CANDIDATES]
        if any(p + rows <= len(values) and _digest(values[p:p + rows]) == fp["sha256"] for p in starts):
            found.append(index)
    return found


def warn_if_trained_on(data: Dataset, fingerprints: list[dict] | tuple[dict, ...], model_name: str) -> int:
    """Warn when ``data`` contains training segments of the model; returns how many it contains."""
    found = find_training_segments(data, list(fingerprints))
    warn_training_segments(found, fingerprints, model_name)
    return len(found)


def warn_training_segments(found: list[int], fingerprints: list[dict] | tuple[dict, ...], model_name: str) -> None:
    """The warning of :func:`warn_if_trained_on`, for the indices ``found`` of ``fingerprints``."""
    if found:
        rows = sum(int(fingerprints[i]["rows"]) for i in found)
        warnings.warn(f"the evaluation data contains {len(found)} of the {len(fingerprints)} training segments of "
                      f"{model_name} ({rows} samples): these metrics are not held-out; evaluate on recordings "
                      "the model was not fitted on.", FtcalWarning, stacklevel=3)
