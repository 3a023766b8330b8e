"""Calibration with an unknown load: the calibration and a payload's inertial parameters in one fit.

The expected wrench is linear in the inertial parameters ``pi`` of a payload on
a link (:func:`ftcal.robot.kinematics.payload_regressor` gives ``Y``, 6 × k per
sample), and a static calibration model is linear in its coefficients
``theta_i`` (one column per output i). One linear least-squares problem fits
both::

    min  sum_i  w_i || A theta_i - (w_known_i + Y_i pi) ||²

with ``A`` the monomial regressor of the raw inputs, ``w_known`` the expected
wrench of everything known (robot links, known payloads) and ``w_i`` a weight
per output axis (the inverse of its residual variance, from a first unweighted
pass: forces and torques have different units and noise).

It runs on sufficient statistics only: ``AᵀA`` (moments), ``Aᵀ[w_known, Y]``
(one pass of :func:`ftcal.statistics.static_statistics` with ``Y``'s columns as
extra targets) and the small ``YᵢᵀYᵢ`` and ``Yᵢᵀw_known_i`` blocks; the N × p
regressor is never built. Eliminating ``theta`` leaves a k × k system for ``pi``
(a Schur complement).

Scale. A calibration scales each output freely, so the problem has a solution
for ``pi`` only when the known wrench is not itself the wrench of a body rigidly
fixed to the payload's link: the robot's own links beyond the sensor that move
relative to that link (hand and fingers beyond a wrist, a forearm beyond an
elbow) fix the scale. Otherwise (e.g. a tool on a wrist sensor with nothing else
beyond) the mass trades against the force gains; give the mass
(``payload_mass``, weigh the part) and the rest is estimated.

Standard errors assume independent residuals; consecutive samples of a slow
trajectory are correlated, so treat them as lower bounds.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np

from .dataset import Dataset
from .errors import FtcalError, IllPosedFitWarning
from .features import MonomialBasis, RegressorLayout
from .normalization import MODES, normalization_from_range
from .payload.regressor import INERTIAL_PARAMETERS
from .statistics import static_statistics

# Relative eigenvalue of the scaled payload system below which a direction counts as unidentifiable.
RANK_TOLERANCE = 1e-10


def payload_column(link: str, output: str, parameter: str) -> str:
    """Dataset column holding Y[output, parameter] of the payload on ``link``, e.g. ``Y_r_forearm_Fx_m``."""
    return f"Y_{link}_{output}_{parameter}"


@dataclass(frozen=True)
class PayloadEstimate:
    """Inertial parameters of a payload fitted together with a calibration.

    Attributes
    ----------
    link : link the payload is fixed to (parameters in its coordinates)
    parameters : names, from ``ftcal.payload.regressor.INERTIAL_PARAMETERS``
        (mass kg, first moments m·c kg m, inertia about the link origin kg m²)
    values, stderr : ndarray of shape (k,); a fixed mass has stderr 0
    """

    link: str
    parameters: tuple[str, ...]
    values: np.ndarray
    stderr: np.ndarray

    @property
    def mass(self) -> float:
        return float(self.values[0])

    @property
    def com(self) -> np.ndarray:
        """Centre of mass in link coordinates, m."""
        return self.values[1:4] / self.values[0]

    def com_stderr(self, covariance_free: bool = True) -> np.ndarray:
        """First-order standard error of the centre of mass (m), from those of m·c and m."""
        m, mc = self.values[0], self.values[1:4]
        return np.sqrt((self.stderr[1:4] / m) ** 2 + (mc * self.stderr[0] / m**2) ** 2)

    def lines(self) -> list[str]:
        """Human-readable report lines."""
        out = [f"payload on {self.link} (estimated with the calibration; link coordinates):"]
        for name, value, err in zip(self.parameters, self.values, self.stderr):
            out.append(f"  {name:<4} {value: .6g}" + (" (fixed)" if err == 0 else f" ± {err:.3g}"))
        com, err = self.com, self.com_stderr()
        out.append("  COM  " + ", ".join(f"{c: .5g} ± {e:.2g}" for c, e in zip(com, err)) + " m")
        return out


def fit_with_payload(data: Dataset, payload: np.ndarray, link: str, *, degree: int = 1,
                     normalization: str = "center", payload_mass: float | None = None):
    """Fit a static calibration model and a payload's inertial parameters together.

    Parameters
    ----------
    data : Dataset whose outputs are the expected wrench of the known parts (N, 6)
    payload : ndarray of shape (n_samples, 6, k), the payload regressor Y with k = 4
        (static: m, m·c) or 10 (all :data:`INERTIAL_PARAMETERS`)
    link : the payload's link (for the report)
    degree : polynomial degree of the calibration model (static, no ARX)
    normalization : input normalization of the model ("center" or "maxabs")
    payload_mass : known mass in kg, or None to estimate it too

    Returns
    -------
    (CalibrationModel, PayloadEstimate)

    Raises
    ------
    FtcalError : shapes that do not match, too few samples, or a payload direction the
        data cannot identify (the message names it and says what to do).
    """
    from .model import model_from_fitted

    u, w = data.inputs, data.outputs
    y = np.asarray(payload, dtype=np.float64)
    if w is None or w.shape[1] != 6:
        raise FtcalError("Fitting a payload needs the six expected-wrench outputs Fx..Tz.")
    if y.ndim != 3 or y.shape[:2] != (u.shape[0], 6) or y.shape[2] not in (4, 10):
        raise FtcalError(f"The payload regressor must have shape (n_samples, 6, 4 or 10); got {y.shape}.")
    if not np.isfinite(y).all():
        raise FtcalError("The payload regressor columns contain non-finite values.")
    k = y.shape[2]
    names = INERTIAL_PARAMETERS[:k]
    known = w.copy()
    free = np.arange(k)
    if payload_mass is not None:
        if not (np.isfinite(payload_mass) and payload_mass > 0):
            raise FtcalError(f"--payload-mass must be a finite number > 0 kg; got {payload_mass!r}.")
        known += y[:, :, 0] * payload_mass
        free = free[1:]
    yf = np.ascontiguousarray(y[:, :, free])
    kf = len(free)
    mode = normalization if normalization in MODES else "center"
    layout = RegressorLayout(MonomialBasis(u.shape[1], degree), 6, 0, 0)
    p = layout.n_features
    n = u.shape[0]
    if n * 6 <= 6 * p + kf:
        raise FtcalError(f"Too few samples ({n}) for {p} coefficients per output and {kf} payload parameters.")
    in_norm = normalization_from_range(u.min(axis=0), u.max(axis=0), mode)
    out_norm = normalization_from_range(known.min(axis=0), known.max(axis=0), "center")
    targets = np.concatenate([known, yf.reshape(n, 6 * kf)], axis=1)
    stats = static_statistics(layout.basis, in_norm.apply(u), targets)
    gram, cross = stats.gram, stats.cross
    a_w = cross[:, :6]                                   # Aᵀ w_i, (p, 6)
    a_y = cross[:, 6:].reshape(p, 6, kf)                 # Aᵀ Y_i, (p, 6, kf)
    yy = np.zeros((6, kf, kf))
    yw = np.zeros((6, kf))
    for start in range(0, n, 65536):                     # small k × k blocks, chunk by chunk
        block, wk = yf[start:start + 65536], known[start:start + 65536]
        yy += np.einsum("nik,nil->ikl", block, block)
        yw += np.einsum("nik,ni->ik", block, wk)
    ww = np.einsum("ni,ni->i", known, known)
    scale = stats.column_maxabs.copy()
    scale[scale == 0] = 1.0
    gram_pinv = np.linalg.pinv(gram / np.outer(scale, scale), rcond=1e-13, hermitian=True) / np.outer(scale, scale)
    reduced = np.stack([yy[i] - a_y[:, i].T @ gram_pinv @ a_y[:, i] for i in range(6)])
    rhs = np.stack([a_y[:, i].T @ gram_pinv @ a_w[:, i] - yw[i] for i in range(6)])

    def solve(weights: np.ndarray):
        system = np.einsum("i,ikl->kl", weights, reduced)
        vector = np.einsum("i,ik->k", weights, rhs)
        d = np.sqrt(np.clip(np.diag(system), 1e-300, None))
        scaled = system / np.outer(d, d)
        eig, vecs = np.linalg.eigh(scaled)
        if eig[0] <= RANK_TOLERANCE * eig[-1]:
            worst = [names[free[j]] for j in np.argsort(-np.abs(vecs[:, 0]))[:2]]
            raise FtcalError(_unidentifiable_message(link, worst, payload_mass is None))
        cov_unit = np.linalg.inv(scaled) / np.outer(d, d)
        pi = cov_unit @ vector
        theta = gram_pinv @ (a_w + np.einsum("pik,k->pi", a_y, pi))
        rss = np.array([theta[:, i] @ gram @ theta[:, i] + ww[i] + pi @ yy[i] @ pi
                        - 2 * theta[:, i] @ a_w[:, i] - 2 * theta[:, i] @ a_y[:, i] @ pi + 2 * yw[i] @ pi
                        for i in range(6)])
        return pi, theta, np.clip(rss, 0.0, None), cov_unit, eig[-1] / max(eig[0], 1e-300)

    _, _, rss, _, _ = solve(np.ones(6))
    variance = np.maximum(rss / (n - p), 1e-300)
    pi, theta, rss, cov_unit, condition = solve(1.0 / variance)
    dof = 6 * (n - p) - kf
    factor = float(np.sum(rss / variance) / dof)
    stderr_free = np.sqrt(np.diag(cov_unit) * factor)
    values = np.zeros(k)
    stderr = np.zeros(k)
    values[free], stderr[free] = pi, stderr_free
    if payload_mass is not None:
        values[0] = payload_mass
    if values[0] <= 0:
        warnings.warn(f"The estimated payload mass on {link} is {values[0]:.4g} kg (not positive): the data "
                      "do not determine it; give --payload-mass or record more varied poses.",
                      IllPosedFitWarning, stacklevel=2)
    model = model_from_fitted(degree=degree, na=0, nb=0, normalization=mode, coef=theta,
                              input_normalization=in_norm, output_normalization=out_norm,
                              input_names=data.input_names, output_names=data.output_names,
                              input_range=np.c_[u.min(axis=0), u.max(axis=0)],
                              output_range=np.c_[known.min(axis=0), known.max(axis=0)],
                              n_samples_fit=n, rank=int(np.linalg.matrix_rank(gram / np.outer(scale, scale))),
                              condition_number=float(np.linalg.cond(gram / np.outer(scale, scale))),
                              solver_info={"name": "lstsq", "lambda": None, "payload_link": link,
                                           "payload_condition_number": float(condition)})
    total = w + np.einsum("nik,k->ni", y, values)
    model.training_metrics_ = model.score(Dataset(u, total, data.input_names, data.output_names,
                                                  data.segments, data.groups), warn_out_of_range=False)
    return model, PayloadEstimate(link, names, values, stderr)


def _unidentifiable_message(link: str, parameters: list[str], mass_free: bool) -> str:
    advice = "record poses that move them" + (", or give the payload's mass with --payload-mass KG" if mass_free else "")
    return (f"The payload on {link} cannot be separated from the calibration: {' and '.join(parameters)} trade "
            f"against the calibration's gains. The scale comes from the robot's own links beyond the sensor "
            f"that move relative to {link} (e.g. a hand beyond wrist joints); {advice}.")
