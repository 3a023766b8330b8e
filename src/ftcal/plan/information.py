"""Information matrices of a pose: what one (configuration, load) adds to a fit.

Each candidate pose contributes ``Yᵀ Y`` to the information matrix, ``Y`` of
shape (rows, parameters):

* calibration of degree D: the inputs of a calibration are the sensor's
  readings, close to an affine function of the wrench, and every output axis
  is fitted on the same monomials. So one row per pose: the degree-D monomials
  of the expected wrench, plus the constant. The span of those monomials is
  the same for any affine map of the wrench, so no sensor model is needed;
  the wrench is only centred and scaled (forces and torques separately) to keep
  the numbers near 1.
* payload: the static regressor of :mod:`ftcal.payload.regressor`, six rows
  (Fx..Tz weighted by 1 / noise) over the six biases, shared by all loads, and
  the mass and first moments of each load (what is beyond the sensor with
  that load mounted).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..core.features import MonomialBasis
from ..payload.regressor import static_regressor
from ..runtime.errors import FtcalError

# Prior information (a ridge) relative to the average information of one candidate:
# keeps the log-determinant finite while a direction is still unexcited.
RIDGE = 1e-6
# A wrench spread (N or N m) below this is rounding error: the wrench does not change.
SMALLEST_SPREAD = 1e-9
# Eigenvalues below this fraction of the largest count as not excited at all.
RANK_TOLERANCE = 1e-9
BIAS_NAMES = ("Fx_bias", "Fy_bias", "Fz_bias", "Tx_bias", "Ty_bias", "Tz_bias")


@dataclass(frozen=True)
class WrenchScaling:
    """Centre (6,) and scale (6,) of the expected wrench: z = (w − centre) / scale."""

    centre: np.ndarray
    scale: np.ndarray

    @classmethod
    def of(cls, wrench: np.ndarray) -> "WrenchScaling":
        """From wrenches of shape (n, 6): mean per axis, one RMS spread for forces and one for torques."""
        w = np.asarray(wrench, dtype=float).reshape(-1, 6)
        centre = w.mean(axis=0)
        spread = np.sqrt(((w - centre) ** 2).reshape(-1, 2, 3).mean(axis=(0, 2)))
        if not spread.max() > SMALLEST_SPREAD:
            raise FtcalError("nothing is identifiable: the expected wrench is the same at every candidate "
                             "pose and load (no mass beyond the sensor, or no joint that turns it); "
                             "add a load or free a joint.")
        spread = np.where(spread > 1e-9 * spread.max(), spread, spread.max())
        return cls(centre, np.repeat(spread, 3))


def calibration_rows(wrench: np.ndarray, degree: int, scaling: WrenchScaling) -> np.ndarray:
    """Rows of a degree-``degree`` calibration, ndarray of shape (n, 1, n_terms).

    wrench : ndarray of shape (n, 6), expected Fx..Tz
    """
    z = (np.asarray(wrench, dtype=float).reshape(-1, 6) - scaling.centre) / scaling.scale
    return MonomialBasis(6, degree).evaluate(z)[:, None, :]


def payload_parameter_names(n_loads: int) -> tuple[str, ...]:
    """Biases, then m, m·cx, m·cy, m·cz of each load (``m[k]``, ``mcx[k]`` …)."""
    per_load = tuple(f"{name}[{k}]" for k in range(n_loads) for name in ("m", "mcx", "mcy", "mcz"))
    return BIAS_NAMES + per_load


def payload_rows(gravity: np.ndarray, load: np.ndarray, n_loads: int, noise: tuple[float, float]) -> np.ndarray:
    """Rows of bias + per-load mass and first moments, ndarray of shape (n, 6, 6 + 4 n_loads).

    Parameters
    ----------
    gravity : ndarray of shape (n, 3), gravity in sensor axes, m/s²
    load : ndarray of shape (n,), the load index of each pose
    n_loads : number of loads
    noise : (force, torque) standard deviation per pose, N and N m; rows are divided by it
    """
    g = np.asarray(gravity, dtype=float).reshape(-1, 3)
    static = static_regressor(g)  # columns m, m·c (3), force bias (3), torque bias (3)
    n = g.shape[0]
    rows = np.zeros((n, 6, 6 + 4 * n_loads))
    rows[:, :, :6] = static[:, :, 4:]
    block = 6 + 4 * np.asarray(load, dtype=np.int64)
    for j in range(4):
        rows[np.arange(n), :, block + j] = static[:, :, j]
    rows /= np.repeat(np.asarray(noise, dtype=float), 3)[None, :, None]
    return rows


def payload_blocks(n_loads: int, noise: tuple[float, float]) -> np.ndarray:
    """:func:`payload_rows` as blocks over the features (1, gx, gy, gz), shape (n_loads, 4, 6, 6 + 4 n_loads).

    The rows of a pose with gravity g and load l are ``Σ_a x_a · blocks[l, a]`` with x = (1, g).
    """
    points = np.vstack([np.zeros(3), np.eye(3)])
    out = np.empty((n_loads, 4, 6, 6 + 4 * n_loads))
    for load in range(n_loads):
        rows = payload_rows(points, np.full(4, load), n_loads, noise)
        out[load, 0] = rows[0]
        out[load, 1:] = rows[1:] - rows[0]
    return out


def information(rows: np.ndarray) -> np.ndarray:
    """Σ Yᵀ Y over poses, rows of shape (n, r, p) → (p, p)."""
    flat = rows.reshape(-1, rows.shape[-1])
    total = np.zeros((flat.shape[1], flat.shape[1]))
    for a in range(0, flat.shape[0], 4096):  # blocks: a signal is acted upon between them
        total += flat[a:a + 4096].T @ flat[a:a + 4096]
    return total


def prior(rows: np.ndarray) -> np.ndarray:
    """The ridge prior information (p, p): :data:`RIDGE` times one average candidate's information per parameter."""
    p = rows.shape[-1]
    per_candidate = float(np.einsum("nrp,nrp->", rows, rows)) / max(rows.shape[0], 1) / p
    return RIDGE * max(per_candidate, 1e-300) * np.eye(p)


def log_det(matrix: np.ndarray) -> float:
    """log det of a symmetric positive definite matrix (−inf if it is not)."""
    sign, value = np.linalg.slogdet(matrix)
    return float(value) if sign > 0 else -np.inf


def excited_rank(total: np.ndarray) -> int:
    """Number of directions an information matrix excites (eigenvalues above :data:`RANK_TOLERANCE` of the largest)."""
    eig = np.linalg.eigvalsh(0.5 * (total + total.T))
    return int(np.sum(eig > RANK_TOLERANCE * max(eig.max(), 0.0))) if eig.max() > 0 else 0


def undetermined(total: np.ndarray, names: tuple[str, ...]) -> list[str]:
    """Parameters with a sizeable share of an unexcited direction of ``total`` (equilibrated)."""
    d = np.sqrt(np.maximum(np.diag(total), 1e-300))
    eig, vec = np.linalg.eigh(total / d[:, None] / d[None, :])
    null = vec[:, eig <= RANK_TOLERANCE * max(eig.max(), 1e-300)]
    weight = (null ** 2).sum(axis=1)
    return [n for n, w in zip(names, weight) if w > 0.1]
