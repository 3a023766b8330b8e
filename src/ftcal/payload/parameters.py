"""The identified payload and bias, as stored in ``payload.json`` and used by compensation."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .drift import BiasDrift
from .identify import PayloadFit, Undetermined


@dataclass(frozen=True)
class PayloadParameters:
    """A tool's inertial parameters and the sensor's bias, in the sensor frame.

    Attributes
    ----------
    mass : float, kg
    com : ndarray of shape (3,), m, sensor frame
    force_bias : ndarray of shape (3,), N
    torque_bias : ndarray of shape (3,), N·m
    gravity : float, m/s², magnitude used for the fit
    frame : str or None
        Name of the sensor frame (e.g. the ROS ``header.frame_id``).
    reaction : bool
        True when the sensor reports the opposite sign (the wrench the sensor
        applies on the tool); readings were negated before the fit and
        compensation negates them back.
    inertia : ndarray of shape (3, 3) or None
        kg·m², about the centre of mass, sensor axes (URDF ``<inertial>`` style).
    stderr : dict
        Standard errors with the keys and shapes above (``mass``, ``com``,
        ``force_bias``, ``torque_bias``, and ``inertia`` when known).
    fit : dict
        Diagnostics: ``n_samples``, ``residual_rms`` (6), ``condition_number``,
        ``wrench_columns``.
    drift : BiasDrift or None
        How the bias moves with time and temperature; None (or model ``none``
        without temperature): constant. The bias fields are then its value at
        the end of the identification recording.
    undetermined : Undetermined or None
        What the identification poses did not determine: those parameters hold a
        stated default (the held ones zero), their standard errors are NaN, and
        compensation is right only where the undetermined directions do not act
        (:func:`~ftcal.payload.compensate.undetermined_samples`).
    """

    mass: float
    com: np.ndarray
    force_bias: np.ndarray
    torque_bias: np.ndarray
    gravity: float
    frame: str | None = None
    reaction: bool = False
    inertia: np.ndarray | None = None
    stderr: dict = field(default_factory=dict)
    fit: dict = field(default_factory=dict)
    drift: BiasDrift | None = None
    undetermined: Undetermined | None = None

    @classmethod
    def from_fit(cls, fit: PayloadFit, *, gravity: float, frame: str | None, reaction: bool,
                 wrench_columns: tuple[str, ...], drift: BiasDrift | None = None) -> "PayloadParameters":
        return cls(fit.mass, fit.com, fit.force_bias, fit.torque_bias, gravity, frame, reaction, fit.inertia,
                   {k: v for k, v in fit.stderr.items()},
                   {"n_samples": fit.n_samples, "residual_rms": fit.residual_rms,
                    "condition_number": fit.condition_number, "wrench_columns": list(wrench_columns),
                    "weighting": fit.weighting, "standard_errors": fit.stderr_kind}, drift, fit.undetermined)

    @property
    def needs_time(self) -> bool:
        return self.drift is not None and self.drift.knot_times is not None

    @property
    def needs_temperature(self) -> bool:
        return self.drift is not None and self.drift.temperature_coefficients is not None

    def bias_of(self, time: np.ndarray | None, temperature: np.ndarray | None, n: int,
                source: str = "data") -> np.ndarray:
        """The bias of each of ``n`` samples, shape (n, 6) (constant without a drift model)."""
        if not (self.needs_time or self.needs_temperature):
            return np.broadcast_to(self.bias, (n, 6))
        return self.drift.bias(self.bias, time, temperature, source)

    @property
    def bias(self) -> np.ndarray:
        """Force then torque bias, shape (6,)."""
        return np.r_[self.force_bias, self.torque_bias]

    def inertial_parameters(self) -> np.ndarray:
        """π = [m, m·c, inertia about the sensor origin (xx, xy, xz, yy, yz, zz)], shape (10,).

        Without an identified inertia the tensor is zero (it only matters for rotating payloads).
        """
        c = np.asarray(self.com, dtype=float)
        inertia_com = np.zeros((3, 3)) if self.inertia is None else np.asarray(self.inertia, dtype=float)
        origin = inertia_com + self.mass * (c @ c * np.eye(3) - np.outer(c, c))
        return np.r_[self.mass, self.mass * c, origin[np.triu_indices(3)]]
