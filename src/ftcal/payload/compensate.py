"""Contact wrench: the reading minus the bias minus the payload's gravity (and inertial) wrench."""

from __future__ import annotations

import numpy as np

from .kinematics import Kinematics
from .parameters import PayloadParameters
from .regressor import inertial_regressor

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


def contact_wrench(measured: np.ndarray, payload: PayloadParameters, kinematics: Kinematics,
                   time: np.ndarray | None = None, temperature: np.ndarray | None = None,
                   source: str = "data") -> np.ndarray:
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

    Returns
    -------
    ndarray of shape (n_samples, 6)
    """
    sign = -1.0 if payload.reaction else 1.0
    bias = payload.bias_of(time, temperature, measured.shape[0], source)
    return measured - sign * (bias + payload_wrench(payload, kinematics))
