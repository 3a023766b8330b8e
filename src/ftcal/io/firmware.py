"""The iCub strain-board calibration matrix file (docs/formats.md §2), for affine models only.

The board computes ``wrench_i = FS_i · Σ_j Cs_ij · raw_j / 32767`` from the six
raw channels in signed 16-bit ADC counts, with ``Cs`` stored in Q1.15. So the
model's first six inputs must be those ADC counts, and its affine map
``C`` (wrench per count) becomes ``FS_i = ceil(32767 · Σ_j |C_ij|)`` and
``Cs = diag(1/FS) · C · 32767``, which keeps every row of ``Cs`` within
``Σ_j |Cs_ij| ≤ 1``. The matrix has no offset term.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .._checks import check_safe_name
from ..conversion import affine_part
from ..errors import FtcalError, FtcalWarning
from ..model import CalibrationModel
from .atomic import write_text_atomic

N_CHANNELS = 6
Q15_ONE = 32768  # Q1.15: value × 2^15
BOARD_SCALE = 32767  # the board divides by 32767, not 32768
FULL_SCALE_MAX = 65535  # full scales are 16-bit unsigned on the board
TARGET = "The iCub firmware calibration matrix"


@dataclass(frozen=True)
class FirmwareMatrix:
    """Q1.15 matrix entries (6, 6) as signed integers and the six full scales."""

    q15: np.ndarray
    full_scale: np.ndarray

    def effective_matrix(self) -> np.ndarray:
        """The wrench-per-count matrix the board applies, shape (6, 6)."""
        return self.full_scale[:, None] * (self.q15 / Q15_ONE) / BOARD_SCALE

    def text(self) -> str:
        """The file content: 36 hex entries, ``1``, six full scales; CRLF line ends."""
        lines = [f"{int(q) & 0xFFFF:04X}" for q in self.q15.ravel()]
        lines.append("1")
        lines += [str(int(fs)) for fs in self.full_scale]
        return "".join(line + "\r\n" for line in lines)


def firmware_filename(serial: str) -> str:
    """``matrix_<serial>.txt``, the name the board tools expect.

    Raises
    ------
    FtcalError
        ``serial`` is not 1 to 64 letters, digits, ``-``, ``_`` or ``.`` (not starting with ``.``):
        a name used in a path must not lead out of the output folder.
    """
    check_safe_name(serial, "--serial")
    return f"matrix_{serial}.txt"


def firmware_matrix(model: CalibrationModel) -> FirmwareMatrix:
    """Quantize a six-channel affine model; raise :class:`FtcalError` if it cannot be expressed.

    Warns (:class:`FtcalWarning`) when the model has a nonzero offset, which the
    matrix cannot hold.
    """
    model._check_fitted()
    nu, ny = len(model.input_names_), len(model.output_names_)
    if ny != N_CHANNELS or nu < N_CHANNELS:
        raise FtcalError(f"{TARGET} maps 6 raw channels to 6 wrench components; this model has "
                         f"{nu} inputs and {ny} outputs.")
    c, offset = affine_part(model, N_CHANNELS, TARGET)
    full_scale = []
    for i, row in enumerate(c):
        name = model.output_names_[i]
        fs = math.ceil(BOARD_SCALE * float(np.sum(np.abs(row))))
        if fs == 0:
            raise FtcalError(f"{TARGET}: output {name!r} does not depend on any raw channel (all "
                             "coefficients are zero), so it has no full scale.")
        # Rounding an entry within 2^-16 of +1 would give 32768, outside Q1.15; one more
        # count of full scale moves it back into range.
        while np.any(np.rint(row * BOARD_SCALE / fs * Q15_ONE) > Q15_ONE - 1):
            fs += 1
        if fs > FULL_SCALE_MAX:
            raise FtcalError(
                f"{TARGET}: output {name!r} needs full scale {fs}, above the board's 16-bit limit "
                f"{FULL_SCALE_MAX}; its gains are too large for raw inputs in signed 16-bit ADC counts.")
        full_scale.append(fs)
    fs_array = np.array(full_scale, dtype=np.int64)
    q15 = np.rint(c * BOARD_SCALE / fs_array[:, None] * Q15_ONE).astype(np.int64)
    if np.any(offset != 0):
        warnings.warn(
            f"{TARGET} has no offset term; the model's offset (largest |value| {np.max(np.abs(offset)):.4g} "
            f"on {model.output_names_[int(np.argmax(np.abs(offset)))]!r}) is not exported. "
            "Remove it on the robot (sensor tare or wholeBodyDynamics offset).",
            FtcalWarning, stacklevel=2)
    return FirmwareMatrix(q15, fs_array)


def write_firmware_matrix(model: CalibrationModel, path: str | Path) -> None:
    """Write the firmware matrix file of ``model`` to ``path`` (name it with :func:`firmware_filename`)."""
    write_text_atomic(path, firmware_matrix(model).text(), newline="")
