"""wholeBodyDynamics configuration groups (docs/formats.md §3), for affine models with optional temperature.

wholeBodyDynamics corrects each sensor's (already board-calibrated) wrench ``w`` as

    C · w − offset + k · (T − T_ref)

with ``C`` from ``FT_SECONDARY_CALIBRATION``, ``(k, T_ref)`` from
``FT_TEMPERATURE_COEFFICIENTS`` and ``offset`` from ``FT_OFFSET`` (applied when
the pre-estimated offset is in use). A model ``y = C u + k T + o`` with the six
wrench channels ``u`` and an optional seventh, temperature input maps onto it
with ``offset = −(o + k · T_ref)``.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from ..core.conversion import affine_part
from ..core.model import CalibrationModel
from ..runtime.atomic import write_text_atomic
from ..runtime.errors import FtcalError
from .c_text import printable_ascii

N_CHANNELS = 6
TARGET = "The wholeBodyDynamics configuration"
_SENSOR_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")


def format_wbd(model: CalibrationModel, sensor: str, *, reference_temperature: float | None = None) -> str:
    """The three groups for ``sensor`` (e.g. ``r_arm_ft_sensor``) as XML text.

    ``reference_temperature`` defaults to the middle of the training temperature
    range (0 if unknown); it changes the stored offset, not the correction.
    The temperature group is written only for models with a temperature input.
    """
    model._check_fitted()
    if not _SENSOR_NAME.fullmatch(sensor):
        raise FtcalError(f"The sensor name {sensor!r} is not a valid wholeBodyDynamics parameter name "
                         "(letters, digits and underscores, such as r_arm_ft_sensor).")
    nu, ny = len(model.input_names_), len(model.output_names_)
    if ny != N_CHANNELS or nu not in (N_CHANNELS, N_CHANNELS + 1):
        raise FtcalError(f"{TARGET} maps 6 wrench channels (plus an optional temperature input) to 6 outputs; "
                         f"this model has {nu} inputs and {ny} outputs.")
    matrix, offset = affine_part(model, nu, TARGET)
    groups = [("FT_SECONDARY_CALIBRATION", matrix[:, :N_CHANNELS].ravel())]
    if nu > N_CHANNELS:
        k = matrix[:, N_CHANNELS]
        t_ref = reference_temperature if reference_temperature is not None else _mid_range(model)
        groups.append(("FT_TEMPERATURE_COEFFICIENTS", np.r_[k, t_ref]))
        offset = offset + k * t_ref
    groups.append(("FT_OFFSET", -offset))
    comment = (f"ftcal: affine calibration of {sensor} "
               f"(inputs {', '.join(model.input_names_)}; outputs {', '.join(model.output_names_)})")
    lines = [f"<!-- {xml_comment_text(comment)} -->"]  # the names come from the model file
    for name, values in groups:
        lines += [f'<group name="{name}">',
                  f'    <param name="{sensor}">({",".join(repr(float(v)) for v in values)})</param>',
                  "</group>"]
    return "\n".join(lines) + "\n"


def xml_comment_text(text: str) -> str:
    """``text`` made safe inside ``<!-- ... -->``: printable ASCII, no ``--``, not ending in ``-``."""
    safe = re.sub(r"-(?=-)", "- ", printable_ascii(text))
    return safe + " " if safe.endswith("-") else safe


def _mid_range(model: CalibrationModel) -> float:
    low, high = model.input_range_[N_CHANNELS]
    return float((low + high) / 2) if np.isfinite(low) and np.isfinite(high) else 0.0


def write_wbd(model: CalibrationModel, path: str | Path, sensor: str, *,
              reference_temperature: float | None = None) -> None:
    """Write the wholeBodyDynamics groups of ``model`` for ``sensor`` to ``path``."""
    write_text_atomic(path, format_wbd(model, sensor, reference_temperature=reference_temperature))
