"""The identified payload and bias, as stored in ``payload.json`` and used by compensation."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .identify import PayloadFit


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

    @classmethod
    def from_fit(cls, fit: PayloadFit, *, gravity: float, frame: str | None, reaction: bool,
                 wrench_columns: tuple[str, ...]) -> "PayloadParameters":
        return cls(fit.mass, fit.com, fit.force_bias, fit.torque_bias, gravity, frame, reaction, fit.inertia,
                   dict(fit.stderr),
                   {"n_samples": fit.n_samples, "residual_rms": fit.residual_rms,
                    "condition_number": fit.condition_number, "wrench_columns": list(wrench_columns)})

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
