"""Re-taring held-out recordings as users do: each recording's offset read at its first static hold.

A sensor is tared on the robot before use: at a still pose, its reading is set to the wrench it should
read there (gravity compensation's expected wrench). A held-out recording of a new session carries that
session's offset, which no calibration fitted on earlier sessions can know; comparing models (or a
model with the vendor's matrix) without the re-tare users do would score the offset, not the
calibration. :func:`tare_offsets` gives the offset each row has removed:

* ``first-hold``: every recording (a ``segment`` label, else a file) tared at its first static hold;
* ``per-file``: one tare per file, at its first static hold (a session tared once);
* ``none``: nothing removed.

The holds are found by :func:`ftcal.data.holds.find_holds` from the direction of the *reference* force
(the expected wrench: a tool at rest weighs along gravity, and the reference changes only when the
robot moves), over the ``time`` column, or rows at :data:`~ftcal.core.limits.HOLD_SAMPLE_RATE` without
one; a ``hold`` column (``ftcal dataset``'s) is used as it is.
"""

from __future__ import annotations

import numpy as np

from ..core.limits import TARE_MODES
from ..runtime.errors import FtcalError


def check_tare(tare: str, where: str = "tare") -> str:
    """``tare`` if it is one of :data:`TARE_MODES`, else a one-line FtcalError naming ``where``."""
    if tare not in TARE_MODES:
        raise FtcalError(f"{where}: {tare!r} is not one of {', '.join(TARE_MODES)}.")
    return tare


def first_holds(reference: np.ndarray, recordings: np.ndarray, time: np.ndarray | None = None,
                hold: np.ndarray | None = None, where: str = "data") -> dict:
    """The rows of each recording's first static hold: {recording label: (first row, last row + 1)}.

    Parameters
    ----------
    reference : ndarray of shape (n, >= 3), the reference wrench (its first three columns: the force)
    recordings : ndarray of shape (n,), the recording of each row (holds never span two)
    time : s, or None (rows at HOLD_SAMPLE_RATE)
    hold : a hold column (-1 moving, 0, 1, ... per hold), used instead of finding them
    where : the file, for messages

    Returns
    -------
    dict; recordings without a static hold are missing from it
    """
    from ..core.limits import HOLD_SAMPLE_RATE
    from .holds import find_holds

    labels = np.asarray(recordings)
    if hold is None:
        clock = np.arange(labels.size) / HOLD_SAMPLE_RATE if time is None else np.asarray(time, float)
        with np.errstate(invalid="ignore", divide="ignore"):  # a zero reference force has no direction: moving
            hold = find_holds(clock, gravity=np.asarray(reference, float)[:, :3], segments=labels, where=where).hold
    hold = np.asarray(hold)
    edges = np.flatnonzero(np.diff(np.r_[-1, hold, -1]) != 0) if hold.size else np.array([0])
    out: dict = {}
    for a, b in zip(edges[:-1], edges[1:]):
        if hold[a] >= 0 and labels[a] not in out:
            # a run of one hold number inside one recording
            same = np.flatnonzero(labels[a:b] != labels[a])
            out[labels[a]] = (int(a), int(a + same[0]) if same.size else int(b))
    return out


def tare_offsets(errors: list[np.ndarray], reference: np.ndarray, recordings: np.ndarray, files: np.ndarray,
                 tare: str, *, time: np.ndarray | None = None, hold: np.ndarray | None = None,
                 notes: list[str] | None = None) -> list[np.ndarray]:
    """The offset each row of each prediction loses to a re-tare: its mean error at its recording's first hold.

    Parameters
    ----------
    errors : predictions minus reference, each of shape (n, n_outputs) (a model's, a baseline's): each is
        tared at the same holds, by its own offset
    reference : ndarray of shape (n, n_outputs), the reference wrench
    recordings, files : ndarray of shape (n,), each row's recording and file
    tare : one of :data:`TARE_MODES`
    time, hold : as :func:`first_holds` (rows of all files one after the other)
    notes : recordings left untared (no static hold) are said here

    Returns
    -------
    list of ndarray of shape (n, n_outputs): the offsets (zeros with ``none``)
    """
    check_tare(tare)
    errors = [np.asarray(e, float) for e in errors]
    offsets = [np.zeros_like(e) for e in errors]
    if tare == "none":
        return offsets
    recordings, files = np.asarray(recordings), np.asarray(files)
    # Holds are found per recording (never spanning two, nor two files); per-file takes the file's first.
    keys = np.array([f"{f}\x00{r}" for f, r in zip(files, recordings)], dtype=object)
    holds = first_holds(reference, keys, time, hold)
    if tare == "per-file":
        firsts = {}
        for key in dict.fromkeys(keys.tolist()):
            if key in holds:
                firsts.setdefault(key.split("\x00")[0], holds[key])
        keys = np.array([str(f) for f in files], dtype=object)
        holds = firsts
    untared = []
    for key in dict.fromkeys(keys.tolist()):
        rows = keys == key
        if key not in holds:
            untared.append(str(key).replace("\x00", " recording "))
            continue
        a, b = holds[key]
        for error, offset in zip(errors, offsets):
            offset[rows] = error[a:b].mean(axis=0)
    if untared and notes is not None:
        notes.append(f"tare {tare}: no static hold in {', '.join(untared[:3])}"
                     + (f" and {len(untared) - 3} more" if len(untared) > 3 else "") + ": left untared")
    return offsets
