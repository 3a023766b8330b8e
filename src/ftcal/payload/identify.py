"""Payload and bias identification by (weighted) linear least squares on summed statistics.

Model (ftcal sign convention, see :mod:`ftcal.payload.regressor`): the wrench
read by the sensor is ``Y θ`` with θ = [m, m·c, force bias, torque bias] for
static poses, or the ten inertial parameters plus the six biases with
``dynamic``. Forces (N) and torques (N·m) have different noise, so the fit is
two-step feasible weighted least squares: an unweighted fit gives each axis'
residual variance σ², then every axis is weighted by 1/σ². The covariance of
θ is then the textbook ``(Σ_axis AᵀA / σ²)⁻¹``, the centre of mass's standard
error follows by the delta method from c = (m·c) / m.

Excitation: a parameter the poses cannot separate from the others has a large
variance inflation factor ``VIF_j = (G⁻¹)_jj G_jj`` on the weighted Gram G
(1 for an orthogonal design). Above :data:`EXCITATION_LIMIT` ftcal warns,
naming the parameter and the kind of pose that would excite it; a Gram of
deficient rank is an error.
"""

from __future__ import annotations

import warnings
from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

from ..core.solvers.base import Conditioning, Spectrum
from ..runtime.errors import FtcalError, IllPosedFitWarning
from .accumulate import AxisStatistics
from .regressor import DYNAMIC_PARAMETERS, STATIC_PARAMETERS, inertia_about_com, inertia_matrix

AXES = ("Fx", "Fy", "Fz", "Tx", "Ty", "Tz")
# VIF above this (standard errors inflated more than 10×) means the poses hardly excite a parameter.
EXCITATION_LIMIT = 100.0

_GRAVITY_HINT = ("add poses that tilt the sensor so gravity points along different sensor axes "
                 "(tool down, sideways, up)")
_HINTS = {
    "m": _GRAVITY_HINT,
    "Fx_bias": _GRAVITY_HINT, "Fy_bias": _GRAVITY_HINT, "Fz_bias": _GRAVITY_HINT,
    "mcx": "add poses where gravity changes along the sensor's y or z axis (turn the sensor about x)",
    "mcy": "add poses where gravity changes along the sensor's x or z axis (turn the sensor about y)",
    "mcz": "add poses where gravity changes along the sensor's x or y axis (turn the sensor about z "
           "while it is tilted)",
    "Tx_bias": _GRAVITY_HINT, "Ty_bias": _GRAVITY_HINT, "Tz_bias": _GRAVITY_HINT,
    "Ixx": "add motions with angular velocity/acceleration about the sensor's x axis",
    "Iyy": "add motions with angular velocity/acceleration about the sensor's y axis",
    "Izz": "add motions with angular velocity/acceleration about the sensor's z axis",
    "Ixy": "add motions rotating about the sensor's x and y axes",
    "Ixz": "add motions rotating about the sensor's x and z axes",
    "Iyz": "add motions rotating about the sensor's y and z axes",
}
# |mass| below this many standard errors is not distinguishable from zero.
SIGNIFICANT_STDERR = 2.0
# Readable names for messages.
LABELS = {"m": "mass", "mcx": "com x", "mcy": "com y", "mcz": "com z",
          "Fx_bias": "force bias x", "Fy_bias": "force bias y", "Fz_bias": "force bias z",
          "Tx_bias": "torque bias x", "Ty_bias": "torque bias y", "Tz_bias": "torque bias z"}


@dataclass(frozen=True)
class GroupResidual:
    """Cross-validated residual of one held-out group (``rms`` None: not identifiable without it)."""

    group: str
    n_samples: int
    rms: np.ndarray | None  # shape (6,), N and N·m


@dataclass(frozen=True)
class PayloadFit:
    """Identified payload and bias, with uncertainties and fit diagnostics.

    ``com`` and ``inertia`` (about the centre of mass, sensor axes, kg·m²) are
    derived from θ; ``stderr`` has the keys ``mass``, ``com``, ``force_bias``,
    ``torque_bias`` (and ``inertia``) with the shapes of the estimates.
    """

    parameter_names: tuple[str, ...]
    theta: np.ndarray
    covariance: np.ndarray
    mass: float
    com: np.ndarray
    force_bias: np.ndarray
    torque_bias: np.ndarray
    inertia: np.ndarray | None  # (3, 3) about the COM
    stderr: dict
    residual_rms: np.ndarray  # (6,)
    n_samples: int
    condition_number: float
    variance_inflation: np.ndarray  # (p,)
    poorly_excited: tuple[str, ...]
    cross_validation: tuple[GroupResidual, ...] = field(default=())

    @property
    def dynamic(self) -> bool:
        return self.inertia is not None


def _solve(gram: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    return Conditioning.of(gram).solve(rhs[:, None])[:, 0]


def _null_parameters(gram: np.ndarray, names: tuple[str, ...]) -> list[str]:
    spectrum = Spectrum.of(gram)
    weak = spectrum.vectors[:, spectrum.values <= spectrum.rank_threshold()]
    involved = np.abs(weak).max(axis=1) > 0.1 if weak.size else np.zeros(len(names), bool)
    return [names[j] for j in np.flatnonzero(involved)]


def _describe(names) -> str:
    return ", ".join(LABELS.get(n, n) for n in names)


def identify_payload(groups: Mapping[str, AxisStatistics], *, cross_validate: bool = True) -> PayloadFit:
    """Fit the payload and bias to statistics gathered per validation group.

    Parameters
    ----------
    groups : mapping of group label to AxisStatistics
        From :func:`~ftcal.payload.accumulate.payload_statistics`, all with the
        same parameter set (10 static or 16 dynamic).
    cross_validate : bool
        Also refit without each group in turn and score it (needs >= 2 groups).

    Returns
    -------
    PayloadFit

    Raises
    ------
    FtcalError
        Too few samples, or poses that leave some parameter undetermined
        (rank-deficient regressor); the message names the parameters.

    Warns
    -----
    IllPosedFitWarning
        For each poorly excited parameter, with the kind of pose to add.
    """
    if not groups:
        raise FtcalError("No samples to identify the payload from.")
    total = None
    for stats in groups.values():
        total = stats if total is None else total + stats
    p = total.n_parameters
    names = STATIC_PARAMETERS if p == 10 else DYNAMIC_PARAMETERS
    n = total.n_samples
    if 6 * n <= p:
        raise FtcalError(f"{n} sample(s) give {6 * n} equations for {p} unknowns; record more poses.")
    gram = total.gram()
    conditioning = Conditioning.of(gram)
    if conditioning.rank < p:
        missing = _null_parameters(gram, names)
        hints = sorted({_HINTS[m] for m in missing})
        raise FtcalError(f"the poses leave {_describe(missing)} undetermined (regressor rank "
                         f"{conditioning.rank} of {p}): {'; '.join(hints)}.")
    theta0 = conditioning.solve(total.cross()[:, None])[:, 0]
    # Each axis carries n of the 6n − p residual degrees of freedom.
    variance = total.residual_sum_of_squares(theta0) / (n - p / 6)
    scale = np.array([s.target_sq[0] for s in total.axes]) / n
    variance = np.maximum(variance, 1e-24 * np.maximum(scale, 1.0))  # exact synthetic data: no zero weights
    weights = 1.0 / variance
    wgram = total.gram(weights)
    theta = _solve(wgram, total.cross(weights))
    # Invert the equilibrated Gram (unit diagonal): the columns' units differ by orders of magnitude.
    jacobi = 1.0 / np.sqrt(np.diag(wgram))
    inverse = np.linalg.inv(wgram * jacobi[:, None] * jacobi[None, :])
    inverse = 0.5 * (inverse + inverse.T)
    covariance = inverse * jacobi[:, None] * jacobi[None, :]
    vif = np.diag(inverse)
    poorly = tuple(names[j] for j in np.flatnonzero(vif > EXCITATION_LIMIT))
    for name in poorly:
        j = names.index(name)
        warnings.warn(f"the poses hardly excite {LABELS.get(name, name)} (standard error inflated "
                      f"{np.sqrt(vif[j]):.0f}x by collinearity): {_HINTS[name]}.", IllPosedFitWarning,
                      stacklevel=2)
    rms = np.sqrt(total.residual_sum_of_squares(theta) / n)
    fit = _derive(names, theta, covariance)
    residuals = _cross_validate(groups, total, weights, p) if cross_validate and len(groups) > 1 else ()
    return PayloadFit(names, theta, covariance, residual_rms=rms, n_samples=n,
                      condition_number=Conditioning.of(wgram).condition_number,
                      variance_inflation=vif, poorly_excited=poorly, cross_validation=residuals, **fit)


def check_mass_sign(fit: PayloadFit) -> None:
    """Refuse a mass that is negative or not distinguishable from zero.

    Raises
    ------
    FtcalError
        A significantly negative mass means the sensor reports the opposite
        sign convention (the message offers ``--reaction``); a mass within
        :data:`SIGNIFICANT_STDERR` standard errors of zero leaves nothing to identify.
    """
    se = fit.stderr["mass"]
    if fit.mass < 0 and -fit.mass > SIGNIFICANT_STDERR * se:
        raise FtcalError(f"the estimated mass is {fit.mass:.6g} ± {se:.2g} kg, negative: the sensor reports the "
                         "opposite sign convention (the wrench it applies on the tool); re-run with --reaction.")
    if fit.mass <= SIGNIFICANT_STDERR * se:
        raise FtcalError(f"the estimated mass {fit.mass:.6g} ± {se:.2g} kg is not distinguishable from zero: "
                         "no payload to identify (check the wrench columns and the orientation source).")


def _derive(names: tuple[str, ...], theta: np.ndarray, cov: np.ndarray) -> dict:
    """Mass, COM, biases, inertia about the COM and their standard errors from θ and cov(θ)."""
    se = np.sqrt(np.maximum(np.diag(cov), 0.0))
    mass, first = theta[0], theta[1:4]
    bias = theta[-6:]
    if mass == 0.0:
        raise FtcalError("the estimated mass is exactly zero; the centre of mass is undefined.")
    com = first / mass
    # c = (m c) / m: ∂c/∂m = −c / m, ∂c/∂(m c) = 1/m.
    jac = np.zeros((3, len(theta)))
    jac[:, 0] = -com / mass
    jac[:, 1:4] = np.eye(3) / mass
    com_se = np.sqrt(np.maximum(np.diag(jac @ cov @ jac.T), 0.0))
    out = {"mass": float(mass), "com": com, "force_bias": bias[:3], "torque_bias": bias[3:], "inertia": None,
           "stderr": {"mass": float(se[0]), "com": com_se, "force_bias": se[-6:-3], "torque_bias": se[-3:]}}
    if len(names) == 16:
        def about_com(t):
            i_c = inertia_about_com(t[0], t[1:4] / t[0], inertia_matrix(t[4:10]))
            return i_c[np.triu_indices(3)]  # Ixx, Ixy, Ixz, Iyy, Iyz, Izz
        step = 1e-7 * np.maximum(np.abs(theta), 1e-3)
        jac = np.column_stack([(about_com(theta + e) - about_com(theta - e)) / (2 * e[j])
                               for j, e in enumerate(np.diag(step))])
        out["inertia"] = inertia_matrix(about_com(theta))
        out["stderr"]["inertia"] = inertia_matrix(np.sqrt(np.maximum(np.diag(jac @ cov @ jac.T), 0.0)))
    return out


def _cross_validate(groups: Mapping[str, AxisStatistics], total: AxisStatistics, weights: np.ndarray,
                    p: int) -> tuple[GroupResidual, ...]:
    """Leave-one-group-out: refit from the total minus the group, score the group."""
    out = []
    wgram, wcross = total.gram(weights), total.cross(weights)
    for label, stats in groups.items():
        gram = wgram - stats.gram(weights)
        conditioning = Conditioning.of(gram)
        if conditioning.rank < p or 6 * (total.n_samples - stats.n_samples) <= p:
            out.append(GroupResidual(str(label), stats.n_samples, None))
            continue
        theta = conditioning.solve((wcross - stats.cross(weights))[:, None])[:, 0]
        rms = np.sqrt(stats.residual_sum_of_squares(theta) / stats.n_samples)
        out.append(GroupResidual(str(label), stats.n_samples, rms))
    return tuple(out)
