"""Contact wrench: the reading minus the bias minus the payload's gravity (and inertial) wrench."""

from __future__ import annotations

import warnings

import numpy as np

from ..core.limits import UNDETERMINED_EFFECT
from ..runtime.errors import UndeterminedWarning
from .identify import describe_parameters
from .kinematics import Kinematics
from .parameters import PayloadParameters
from .regressor import dynamic_regressor, inertial_regressor, static_regressor

CHUNK_SAMPLES = 65_536  # bounds the (chunk, 6, 10) regressor block


def payload_wrench(payload: PayloadParameters, kinematics: Kinematics, chunk: int = CHUNK_SAMPLES) -> np.ndarray:
    """Wrench the payload puts on the sensor, bias excluded (ftcal sign convention).

    Parameters
    ----------
    payload : PayloadParameters
    kinematics : Kinematics
        Static (gravity only) or with ω, α and proper acceleration; the
        inertial terms need ``payload.inertia``.

    Returns
    -------
    ndarray of shape (n_samples, 6), N and N·m
    """
    pi = payload.inertial_parameters()
    out = np.empty((kinematics.n_samples, 6))
    for start in range(0, kinematics.n_samples, chunk):
        rows = kinematics.rows(start, min(start + chunk, kinematics.n_samples))
        y = inertial_regressor(rows.proper(), rows.angular_velocity, rows.angular_acceleration)
        out[start:start + rows.n_samples] = y @ pi
    return out


def undetermined_samples(payload: PayloadParameters, kinematics: Kinematics, chunk: int = CHUNK_SAMPLES) -> int:
    """How many samples lie outside the span of the identification poses, where the payload's
    undetermined parameters act on the wrench (0 when the poses determined everything).

    A direction v of :attr:`PayloadParameters.undetermined` leaves the wrench of every identification
    pose unchanged (``Y v = 0``). A sample counts when ``‖Y v‖`` exceeds
    :data:`~ftcal.core.limits.UNDETERMINED_EFFECT` of v's size, mass and first moment weighted by g
    (for the centre of mass along an axis: gravity tilted more than ~0.6° off that axis).

    Parameters
    ----------
    payload : PayloadParameters
    kinematics : Kinematics of the samples

    Returns
    -------
    int
    """
    undetermined = payload.undetermined
    if undetermined is None:
        return 0
    names = undetermined.names
    scale = np.array([payload.gravity if n in ("m", "mcx", "mcy", "mcz") else 1.0 for n in names])
    directions = undetermined.directions / np.linalg.norm(undetermined.directions * scale[:, None], axis=0)
    count = 0
    for start in range(0, kinematics.n_samples, chunk):
        rows = kinematics.rows(start, min(start + chunk, kinematics.n_samples))
        y = static_regressor(rows.gravity) if len(names) == 10 else \
            dynamic_regressor(rows.proper(), rows.angular_velocity, rows.angular_acceleration)
        effect = np.linalg.norm(y @ directions, axis=1)  # (rows, directions)
        count += int(np.count_nonzero(np.any(effect > UNDETERMINED_EFFECT, axis=1)))
    return count


def warn_undetermined(payload: PayloadParameters, n_outside: int, n_samples: int, source: str) -> None:
    """Warn once that ``n_outside`` of ``n_samples`` use parameters the identification did not determine."""
    if n_outside:
        warnings.warn(f"{source}: {n_outside} of {n_samples} sample(s) lie outside the span of the payload's "
                      f"identification poses, where its compensation uses parameters the poses did not "
                      f"determine ({describe_parameters(payload.undetermined.parameters)}); the contact wrench there "
                      f"is not reliable. {payload.undetermined.message}", UndeterminedWarning, stacklevel=3)


def contact_wrench(measured: np.ndarray, payload: PayloadParameters, kinematics: Kinematics,
                   time: np.ndarray | None = None, temperature: np.ndarray | None = None,
                   source: str = "data", warn: bool = True) -> np.ndarray:
    """``measured − bias − payload wrench``, in the sign convention of ``measured``.

    Parameters
    ----------
    measured : ndarray of shape (n_samples, 6)
        Wrench read by the sensor (or calibrated from its raw channels), N and N·m.
    payload : PayloadParameters
        With ``reaction`` set, readings have the opposite sign to ftcal's
        convention; the result keeps the readings' sign.
    kinematics : Kinematics
    time, temperature : ndarray of shape (n_samples,) or None
        Needed when the payload's bias drifts with time or temperature
        (:class:`~ftcal.payload.drift.BiasDrift`): each sample gets the bias
        of its time; outside the identification recording the nearest end is held.
    source : names the data in warnings
    warn : warn when samples lie where the payload's undetermined parameters act
        (:func:`undetermined_samples`); off when the caller warns once for several tables

    Returns
    -------
    ndarray of shape (n_samples, 6)
    """
    if warn:
        warn_undetermined(payload, undetermined_samples(payload, kinematics), kinematics.n_samples, source)
    sign = -1.0 if payload.reaction else 1.0
    bias = payload.bias_of(time, temperature, measured.shape[0], source)
    return measured - sign * (bias + payload_wrench(payload, kinematics))
