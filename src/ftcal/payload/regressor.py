"""Linear regressors of the wrench a rigid payload puts on a six-axis F/T sensor.

Conventions
-----------
* The wrench is the one READ by the sensor: the wrench the payload (child
  side) applies on the sensor (parent side), in sensor axes, torque about the
  sensor-frame origin — the convention of :mod:`ftcal.robot.expected` and of
  ROS force_torque_tools. A mass ``m`` at rest adds ``m · g_s`` to the force
  and ``c × m · g_s`` to the torque, ``g_s`` the gravity vector in sensor axes
  and ``c`` the centre of mass.
* Kinematics of the sensor frame, in sensor axes: proper acceleration
  ``a_p = a − g`` (what an accelerometer at the sensor origin reads; at rest
  ``a_p = −g_s``), angular velocity ``ω`` and angular acceleration ``α``.
* Inertial parameters (the standard ten, linear in the wrench)::

      π = [m, m·cx, m·cy, m·cz, Ixx, Ixy, Ixz, Iyy, Iyz, Izz]

  with the inertia tensor taken about the SENSOR-FRAME ORIGIN, in sensor axes
  (``I_O = I_C + m(|c|² 1 − c cᵀ)``; :func:`inertia_about_com` converts).

Newton–Euler for the payload then gives the reading::

    F = −m a_p − (α× + ω×ω×) (m c)
    T = a_p × (m c) − I_O α − ω × (I_O ω)

which is ``Y π`` with :func:`inertial_regressor`. A constant sensor bias adds
six more unknowns ``b = [force bias, torque bias]``; :func:`static_regressor`
is the 6 × 10 regressor of ``[m, m·c, force bias, torque bias]`` for static
poses (only gravity).
"""

from __future__ import annotations

import numpy as np

INERTIAL_PARAMETERS = ("m", "mcx", "mcy", "mcz", "Ixx", "Ixy", "Ixz", "Iyy", "Iyz", "Izz")
BIAS_PARAMETERS = ("Fx_bias", "Fy_bias", "Fz_bias", "Tx_bias", "Ty_bias", "Tz_bias")
STATIC_PARAMETERS = INERTIAL_PARAMETERS[:4] + BIAS_PARAMETERS
DYNAMIC_PARAMETERS = INERTIAL_PARAMETERS + BIAS_PARAMETERS


def _skew_into(out: np.ndarray, v: np.ndarray, sign: float = 1.0) -> None:
    """Write ``sign · [v]×`` (the matrix of ``v × ·``) into ``out`` of shape (N, 3, 3)."""
    x, y, z = v[:, 0], v[:, 1], v[:, 2]
    out[:, 0, 0] = out[:, 1, 1] = out[:, 2, 2] = 0.0
    out[:, 0, 1], out[:, 0, 2] = -sign * z, sign * y
    out[:, 1, 0], out[:, 1, 2] = sign * z, -sign * x
    out[:, 2, 0], out[:, 2, 1] = -sign * y, sign * x


def skew(v: np.ndarray) -> np.ndarray:
    """Cross-product matrices ``[v]×`` with ``[v]× w = v × w``.

    Parameters
    ----------
    v : ndarray of shape (n_samples, 3)

    Returns
    -------
    ndarray of shape (n_samples, 3, 3)
    """
    v = np.asarray(v, dtype=float).reshape(-1, 3)
    out = np.empty((v.shape[0], 3, 3))
    _skew_into(out, v)
    return out


def _inertia_operator(v: np.ndarray) -> np.ndarray:
    """``L(v)`` of shape (N, 3, 6) with ``I v = L(v) [Ixx, Ixy, Ixz, Iyy, Iyz, Izz]``."""
    x, y, z = v[:, 0], v[:, 1], v[:, 2]
    out = np.zeros((v.shape[0], 3, 6))
    out[:, 0, 0], out[:, 0, 1], out[:, 0, 2] = x, y, z
    out[:, 1, 1], out[:, 1, 3], out[:, 1, 4] = x, y, z
    out[:, 2, 2], out[:, 2, 4], out[:, 2, 5] = x, y, z
    return out


def inertial_regressor(proper_acceleration: np.ndarray, angular_velocity: np.ndarray | None = None,
                       angular_acceleration: np.ndarray | None = None) -> np.ndarray:
    """Regressor ``Y`` of the 10 inertial parameters: reading = ``Y @ π`` (+ bias).

    Parameters
    ----------
    proper_acceleration : ndarray of shape (n_samples, 3)
        ``a − g`` of the sensor-frame origin in sensor axes, m/s² (an
        accelerometer's reading; ``−g_s`` at rest).
    angular_velocity : ndarray of shape (n_samples, 3) or None
        ω of the sensor frame in sensor axes, rad/s; None means zero.
    angular_acceleration : ndarray of shape (n_samples, 3) or None
        α = dω/dt in sensor axes, rad/s²; None means zero.

    Returns
    -------
    ndarray of shape (n_samples, 6, 10)
        Rows Fx, Fy, Fz, Tx, Ty, Tz (N, N·m); columns :data:`INERTIAL_PARAMETERS`.
    """
    a = np.asarray(proper_acceleration, dtype=float).reshape(-1, 3)
    n = a.shape[0]
    y = np.zeros((n, 6, 10))
    y[:, 0, 0], y[:, 1, 0], y[:, 2, 0] = -a[:, 0], -a[:, 1], -a[:, 2]
    _skew_into(y[:, 3:, 1:4], a)  # T ∋ a_p × (m c)
    w = None if angular_velocity is None else np.asarray(angular_velocity, dtype=float).reshape(-1, 3)
    alpha = None if angular_acceleration is None else np.asarray(angular_acceleration, dtype=float).reshape(-1, 3)
    if w is None and alpha is None:
        return y
    # F ∋ −(α× + ω×ω×)(m c);  T ∋ −(L(α) + ω× L(ω)) I
    first = np.zeros((n, 3, 3))
    second = np.zeros((n, 3, 6))
    if alpha is not None:
        first += skew(alpha)
        second += _inertia_operator(alpha)
    if w is not None:
        w_cross = skew(w)
        first += w_cross @ w_cross
        second += w_cross @ _inertia_operator(w)
    y[:, :3, 1:4] = -first
    y[:, 3:, 4:] = -second
    return y


def static_regressor(gravity: np.ndarray) -> np.ndarray:
    """Regressor of ``[m, m·cx, m·cy, m·cz, force bias (3), torque bias (3)]`` for static poses.

    Parameters
    ----------
    gravity : ndarray of shape (n_samples, 3)
        Gravity vector in sensor axes, m/s² (e.g. (0, 0, −9.81) when the
        sensor's z axis points up).

    Returns
    -------
    ndarray of shape (n_samples, 6, 10)
        Reading = ``Y @ θ``: ``F = m g + f_b``, ``T = (m c) × g + t_b``.
    """
    g = np.asarray(gravity, dtype=float).reshape(-1, 3)
    y = np.zeros((g.shape[0], 6, 10))
    y[:, 0, 0], y[:, 1, 0], y[:, 2, 0] = g[:, 0], g[:, 1], g[:, 2]
    _skew_into(y[:, 3:, 1:4], g, sign=-1.0)  # (m c) × g = −[g]× (m c)
    y[:, 0, 4] = y[:, 1, 5] = y[:, 2, 6] = y[:, 3, 7] = y[:, 4, 8] = y[:, 5, 9] = 1.0
    return y


def dynamic_regressor(proper_acceleration: np.ndarray, angular_velocity: np.ndarray | None = None,
                      angular_acceleration: np.ndarray | None = None) -> np.ndarray:
    """Regressor of the 10 inertial parameters followed by the 6 biases.

    Parameters are those of :func:`inertial_regressor`.

    Returns
    -------
    ndarray of shape (n_samples, 6, 16)
        Columns :data:`DYNAMIC_PARAMETERS`.
    """
    inertial = inertial_regressor(proper_acceleration, angular_velocity, angular_acceleration)
    y = np.zeros((inertial.shape[0], 6, 16))
    y[:, :, :10] = inertial
    y[:, :, 10:] = np.eye(6)
    return y


def inertia_about_com(mass: float, com: np.ndarray, inertia_origin: np.ndarray) -> np.ndarray:
    """Inertia tensor about the centre of mass from the one about the sensor origin.

    Parameters
    ----------
    mass : float, kg
    com : ndarray of shape (3,), m, sensor frame
    inertia_origin : ndarray of shape (3, 3), kg·m², about the sensor-frame origin

    Returns
    -------
    ndarray of shape (3, 3), kg·m² (parallel-axis theorem, ``I_C = I_O − m(|c|² 1 − c cᵀ)``)
    """
    c = np.asarray(com, dtype=float)
    return np.asarray(inertia_origin, dtype=float) - mass * (c @ c * np.eye(3) - np.outer(c, c))


def inertia_matrix(parameters: np.ndarray) -> np.ndarray:
    """The symmetric 3 × 3 tensor from ``[Ixx, Ixy, Ixz, Iyy, Iyz, Izz]``.

    Parameters
    ----------
    parameters : ndarray of shape (6,)

    Returns
    -------
    ndarray of shape (3, 3)
    """
    xx, xy, xz, yy, yz, zz = np.asarray(parameters, dtype=float)
    return np.array([[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]])
