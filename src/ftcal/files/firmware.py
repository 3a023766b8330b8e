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

from ..core.conversion import affine_part
from ..core.model import CalibrationModel
from ..runtime.atomic import write_text_atomic
from ..runtime.checks import check_safe_name
from ..runtime.errors import FtcalError, FtcalWarning

N_CHANNELS = 6
Q15_ONE = 32768  # Q1.15: value × 2^15
BOARD_SCALE = 32767  # the board divides by 32767, not 32768
FULL_SCALE_MAX = 65535  # full scales are 16-bit unsigned on the board
TARGET = "The iCub firmware calibration matrix"
ADC_RANGE = (-32768, 32767)  # signed 16-bit counts, what the board reads
COUNT_UNITS = frozenset({"count", "counts", "adc", "adc counts", "lsb"})
# What to do instead, ending every refusal that comes from the model's inputs.
FIT_INSTEAD = ("Fit a degree-1 model on the six raw ADC-count channels only (after `make demo`: "
               "`ftcal fit ftcal-demo/train-adc.parquet --inputs u1,u2,u3,u4,u5,u6 -o affine-adc.json`), "
               "or export a model of the board's wrench output (and temperature) as target wbd.")


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
    check_safe_name(serial, "serial")
    return f"matrix_{serial}.txt"


def check_adc_inputs(model: CalibrationModel, input_units=None) -> None:
    """Refuse a model whose six channels cannot be the board's signed 16-bit ADC counts.

    Evidence against: a recorded unit that is not a count, or a training range
    outside [−32768, 32767]. (A model file without units and ranges cannot be
    told apart; it is taken at its word.)
    """
    names = model.input_names_[:N_CHANNELS]
    units = list(input_units or ())[:N_CHANNELS]
    wrong = [f"{n} [{u}]" for n, u in zip(names, units) if u is not None and u.strip().lower() not in COUNT_UNITS]
    if wrong:
        raise FtcalError(f"{TARGET} multiplies raw signed 16-bit ADC counts; this model's inputs are in other "
                         f"units ({', '.join(wrong)}). {FIT_INSTEAD}")
    low, high = model.input_range_[:N_CHANNELS, 0], model.input_range_[:N_CHANNELS, 1]
    outside = [f"{n} [{lo:.6g}, {hi:.6g}]" for n, lo, hi in zip(names, low, high)
               if np.isfinite(lo) and np.isfinite(hi) and (lo < ADC_RANGE[0] or hi > ADC_RANGE[1])]
    if outside:
        raise FtcalError(f"{TARGET} multiplies raw signed 16-bit ADC counts in [{ADC_RANGE[0]}, {ADC_RANGE[1]}]; "
                         f"this model was trained on {', '.join(outside)}. {FIT_INSTEAD}")


def firmware_matrix(model: CalibrationModel, input_units=None) -> FirmwareMatrix:
    """Quantize a six-channel affine model; raise :class:`FtcalError` if it cannot be expressed.

    Parameters
    ----------
    model : fitted CalibrationModel, degree 1 in its first six inputs (ADC counts)
    input_units : sequence of str or None, the model file's input units (checked to be counts)

    Warns (:class:`FtcalWarning`) when the model has a nonzero offset, which the
    matrix cannot hold.
    """
    model._check_fitted()
    nu, ny = len(model.input_names_), len(model.output_names_)
    if ny != N_CHANNELS or nu < N_CHANNELS:
        raise FtcalError(f"{TARGET} maps 6 raw channels to 6 wrench components; this model has "
                         f"{nu} inputs and {ny} outputs. {FIT_INSTEAD}")
    check_adc_inputs(model, input_units)
    c, offset = affine_part(model, N_CHANNELS, TARGET, FIT_INSTEAD)
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


def write_firmware_matrix(model: CalibrationModel, path: str | Path, input_units=None) -> None:
    """Write the firmware matrix file of ``model`` to ``path`` (name it with :func:`firmware_filename`)."""
    write_text_atomic(path, firmware_matrix(model, input_units).text(), newline="")
