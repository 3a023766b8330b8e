"""Calibration with an unknown load: a payload's inertial parameters and the calibration from one dataset.

The expected wrench is linear in the inertial parameters ``pi`` of a payload on
a link (:func:`ftcal.robot.kinematics.payload_regressor` gives ``Y``, 6 × k per
sample): ``w = w_known + Y pi``, with ``w_known`` the expected wrench of
everything known (robot links, known payloads).

Why not one linear least-squares problem ``min ||A(u) theta - (w_known + Y pi)||²``?
Because the sensor noise sits in ``u``, inside the regressor: shrinking the
targets (a negative mass cancelling the known links) shrinks ``theta`` and with
it the noise's share of the residual, so that estimate collapses towards
``w ≈ 0`` as soon as the noise is realistic (tested: at the simulated iCub
sensor's noise it returns minus the forearm's mass). ftcal therefore estimates
``pi`` from the sensor's direction of causality, where the noise is additive::

    u = B (w_known + Y pi) + c [+ d T] + e

(raw channels ``u``, any further inputs such as temperature ``T`` enter
linearly) and maximises the Gaussian likelihood with an unknown noise
covariance: ``pi`` minimises ``log det`` of the residual moment matrix, with
``B, c, d`` eliminated in closed form (variable projection). Everything comes
from the moment matrix of ``[w_known, Y, 1, T, u]``, accumulated chunk by chunk
(k ≤ 10, so it is at most 77 × 77); the N × p regressor is never built. The
calibration model (any degree) is then fitted by the usual streaming least
squares to the completed targets ``w_known + Y pi``.

Standard errors: the grouped jackknife over
:data:`~ftcal.core.limits.ROBUST_CLUSTERS` contiguous blocks of samples (sample
order, which is time within each recording), t-scaled
(:mod:`ftcal.core.jackknife`). Each leave-one-block-out refit subtracts the
block's moment matrix from the total and restarts the search from the estimate,
so it costs no pass over the data. The curvature of the profile likelihood
assumes independent samples; consecutive samples of a slow trajectory, a
drifting bias and a systematic pose order make it several times too small in
simulation (tests/data/test_unknown_load_coverage.py), so it is only kept for
comparison (``curvature_stderr``).

Scale. ``B`` absorbs any common scale of the wrench, so ``pi`` is identifiable
only when the known wrench is not itself that of a body rigidly fixed to the
payload's link: the robot's own links beyond the sensor that move relative to
that link (a hand beyond wrist joints) fix the scale. Otherwise (a tool on a
wrist sensor with nothing else beyond) give the mass (``payload_mass``).

The standard errors assume an affine sensor: nonlinearity, creep or
temperature-dependent gains that the model lacks bias the estimate beyond
them (on the demo's simulated sensor, markedly); prefer a known mass.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, replace

import numpy as np

from ..core.dataset import Dataset
from ..core.directions import order_by_size
from ..core.jackknife import block_edges, jackknife_covariance
from ..core.limits import ROBUST_CLUSTERS
from ..runtime.errors import FtcalError, IllPosedFitWarning, IllPosedParameterWarning, ParameterError
from .regressor import INERTIAL_PARAMETERS

# Relative eigenvalue of the (scaled) likelihood curvature below which a direction is unidentifiable.
RANK_TOLERANCE = 1e-9
N_CHANNELS = 6
CHUNK = 65536


def payload_column(link: str, output: str, parameter: str) -> str:
    """Dataset column holding Y[output, parameter] of the payload on ``link``, e.g. ``Y_r_forearm_Fx_m``."""
    return f"Y_{link}_{output}_{parameter}"


@dataclass(frozen=True)
class PayloadEstimate:
    """Inertial parameters of a payload estimated from calibration data.

    Attributes
    ----------
    link : link the payload is fixed to (parameters in its coordinates)
    parameters : names, from ``ftcal.payload.regressor.INERTIAL_PARAMETERS``
        (mass kg, first moments m·c kg m, inertia about the link origin kg m²)
    values, stderr : ndarray of shape (k,); a fixed mass has stderr 0. ``stderr`` is
        t-scaled: ``values ± 1.96 stderr`` is a 95 % interval
    stderr_kind : how ``stderr`` was found, in words
    curvature_stderr : ndarray of shape (k,), from the likelihood curvature (assumes
        independent samples; too small when they are correlated; kept for comparison)
    """

    link: str
    parameters: tuple[str, ...]
    values: np.ndarray
    stderr: np.ndarray
    stderr_kind: str = "likelihood curvature (assumes independent samples)"
    curvature_stderr: np.ndarray | None = None

    @property
    def mass(self) -> float:
        return float(self.values[0])

    @property
    def com(self) -> np.ndarray:
        """Centre of mass in link coordinates, m."""
        return self.values[1:4] / self.values[0]

    def com_stderr(self) -> np.ndarray:
        """First-order standard error of the centre of mass (m), from those of m·c and m."""
        m, mc = self.values[0], self.values[1:4]
        return np.sqrt((self.stderr[1:4] / m) ** 2 + (mc * self.stderr[0] / m**2) ** 2)

    def lines(self) -> list[str]:
        """Human-readable report lines."""
        out = [f"payload on {self.link} (link coordinates; ± 1.96 standard errors is a 95 % interval):"]
        for name, value, err in zip(self.parameters, self.values, self.stderr):
            out.append(f"  {name:<4} {value: .6g}" + (" (fixed)" if err == 0 else f" ± {err:.3g}"))
        com, err = self.com, self.com_stderr()
        out.append("  COM  " + ", ".join(f"{c: .5g} ± {e:.2g}" for c, e in zip(com, err)) + " m")
        out.append(f"  standard errors: {self.stderr_kind}")
        if self.curvature_stderr is not None and self.curvature_stderr is not self.stderr:
            out.append("  (the likelihood curvature, which assumes independent samples, would say ± "
                       + ", ".join(f"{name} {e:.3g}" for name, e in zip(self.parameters, self.curvature_stderr)
                                   if e > 0) + ")")
        return out


def estimate_payload(data: Dataset, payload: np.ndarray, link: str, *,
                     payload_mass: float | None = None) -> PayloadEstimate:
    """Inertial parameters of an unknown payload from raw readings and the known expected wrench.

    Parameters
    ----------
    data : Dataset; its first six inputs are the raw channels (further inputs, e.g. ``T``,
        enter the sensor model linearly); its outputs are the known parts' expected wrench (N, 6)
    payload : ndarray of shape (n_samples, 6, k), the payload regressor Y with k = 4
        (static: m, m·c) or 10 (all :data:`INERTIAL_PARAMETERS`)
    link : the payload's link (for messages and the report)
    payload_mass : known mass in kg, or None to estimate it too

    Returns
    -------
    PayloadEstimate

    Raises
    ------
    FtcalError : shapes that do not match, too few samples, or a payload direction the
        data cannot identify (the message names it and says what to do).

    Warns
    -----
    IllPosedFitWarning
        Fewer than :data:`~ftcal.core.limits.ROBUST_CLUSTERS` blocks could be left out
        (too few samples), a parameter with a standard error larger than itself, or a
        mass that is not positive.
    """
    u, w = data.inputs, data.outputs
    y = np.asarray(payload, dtype=np.float64)
    if w is None or w.shape[1] != 6 or u.shape[1] < N_CHANNELS:
        raise FtcalError("Estimating a payload needs six raw channels as the first inputs and the six "
                         "expected-wrench outputs Fx..Tz.")
    if y.ndim != 3 or y.shape[:2] != (u.shape[0], 6) or y.shape[2] not in (4, len(INERTIAL_PARAMETERS)):
        raise FtcalError(f"The payload regressor must have shape (n_samples, 6, 4 or 10); got {y.shape}.")
    if not np.isfinite(y).all():
        raise FtcalError("The payload regressor columns contain non-finite values.")
    k = y.shape[2]
    names = INERTIAL_PARAMETERS[:k]
    free = np.arange(k) if payload_mass is None else np.arange(1, k)
    if payload_mass is not None and not (np.isfinite(payload_mass) and payload_mass > 0):
        raise ParameterError('payload_mass', f"{{payload_mass}} must be a finite number > 0 kg; got {payload_mass!r}.")
    n, extra = u.shape[0], u.shape[1] - N_CHANNELS
    kf = len(free)
    if n <= 6 + 1 + extra + kf:
        raise FtcalError(f"Too few samples ({n}) to estimate {kf} payload parameters with the sensor model.")
    edges = block_edges(n, ROBUST_CLUSTERS)
    blocks, scale = _moments(u, w, y, payload_mass, edges)
    moments = blocks.sum(axis=0)
    if payload_mass is None and _known_is_a_payload(moments, kf):
        raise ParameterError("payload_mass", _unidentifiable_message(link, ["m"], True))
    criterion = _criterion(moments, n, kf, extra)
    result = _search(criterion, np.zeros(kf))
    with np.errstate(invalid="ignore", over="ignore"):
        hessian = _hessian(criterion, result.x)
    if not (np.isfinite(result.x).all() and np.isfinite(hessian).all()):
        raise ParameterError("payload_mass", _unidentifiable_message(link, [names[j] for j in free[:2]],
                                                                     payload_mass is None))
    # Negative log-likelihood = (n / 2) · criterion + const: its curvature gives the covariance.
    d = np.sqrt(np.clip(np.abs(np.diag(hessian)), 1e-300, None))
    eig, vecs = np.linalg.eigh(hessian / np.outer(d, d))
    if eig[0] <= RANK_TOLERANCE * eig[-1]:
        worst = [names[free[j]] for j in order_by_size(vecs[:, 0])[:2]]
        raise ParameterError("payload_mass", _unidentifiable_message(link, worst, payload_mass is None))
    covariance = np.linalg.inv(hessian / np.outer(d, d)) / np.outer(d, d) * (2.0 / n)
    refits = _leave_blocks_out(blocks, np.diff(edges), kf, extra, result.x, hessian)
    jackknife = jackknife_covariance(refits)
    values, stderr, curvature = np.zeros(k), np.zeros(k), np.zeros(k)
    values[free] = result.x / scale
    curvature[free] = np.sqrt(np.clip(np.diag(covariance), 0.0, None)) / scale
    if jackknife is None:
        stderr, kind = curvature, "likelihood curvature (assumes independent samples)"
    else:
        stderr[free] = np.sqrt(np.clip(np.diag(jackknife), 0.0, None)) / scale
        kind = f"grouped jackknife over {len(refits)} contiguous blocks of samples (sample order: time in each recording)"
    if len(refits) < ROBUST_CLUSTERS:
        consequence = "rough" if jackknife is not None else \
            "from the likelihood curvature, too small when the samples are correlated"
        warnings.warn(f"Payload on {link}: only {len(refits)} of the {ROBUST_CLUSTERS} contiguous blocks of "
                      f"samples can be left out ({n} samples); the standard errors are {consequence}; record "
                      "more samples or poses.", IllPosedFitWarning, stacklevel=2)
    if payload_mass is not None:
        values[0] = payload_mass
    vague = [names[j] for j in free if stderr[j] > abs(values[j])]
    if vague:
        warnings.warn(f"Payload on {link}: {', '.join(vague)} poorly determined (standard error larger than the "
                      f"value); record poses that turn {link} about other axes relative to gravity, or that move "
                      "the robot's own links beyond the sensor relative to it.", IllPosedFitWarning, stacklevel=2)
    if values[0] <= 0:
        warnings.warn(IllPosedParameterWarning("payload_mass", f"The estimated payload mass on {link} is "
                                               f"{values[0]:.4g} kg (not positive): the data do not determine it; "
                                               "give {payload_mass} or record more varied poses."), stacklevel=2)
    return PayloadEstimate(link, names, values, stderr, kind, curvature)


def _criterion(moments: np.ndarray, n: int, kf: int, extra: int):
    """f(π scaled) = log det of the residual moments of u after the best affine fit to the completed wrench,
    with its gradient (so the search converges where the criterion is flat: a finite-difference
    gradient stalls there, far from the minimum, on the leave-one-block-out refits).

    With Z = A T(π) the completed design and R = P⊥X the residual of the channels X,
    dS = −(B̂ᵀ dZᵀ R + Rᵀ dZ B̂), so ∂f/∂π_j = −2 tr(S⁻¹ Rᵀ A E_j B̂) with
    Rᵀ A = (AᵀX)ᵀ − B̂ᵀ Tᵀ AᵀA.
    """
    width = 6 * (1 + kf)
    lead_width = width + 1 + extra
    lead, cross_all, target = moments[:lead_width, :lead_width], moments[:lead_width, lead_width:], \
        moments[lead_width:, lead_width:]

    # T(π) = T₀ + Σ_j π_j E_j maps [w_known, Y, 1, extra] to [completed wrench, 1, extra].
    fixed = np.zeros((lead_width, 6 + 1 + extra))
    fixed[:6, :6] = np.eye(6)
    fixed[width:, 6:] = np.eye(1 + extra)
    directions = np.zeros((kf, lead_width, 6 + 1 + extra))
    for j in range(kf):
        directions[j, 6 * (j + 1):6 * (j + 2), :6] = np.eye(6)

    def criterion(theta: np.ndarray) -> tuple[float, np.ndarray]:
        t = fixed + np.tensordot(theta, directions, 1)
        gram = t.T @ lead @ t
        cross = t.T @ cross_all
        try:
            coefficients = np.linalg.solve(gram, cross)
        except np.linalg.LinAlgError:  # at the start (no payload) the known wrench may vanish
            coefficients = np.linalg.pinv(gram, rcond=1e-12, hermitian=True) @ cross
        residual = target - cross.T @ coefficients
        sign, logdet = np.linalg.slogdet(residual / n)
        if sign <= 0:
            return np.nan, np.full(len(theta), np.nan)
        k = np.linalg.solve(residual, cross_all.T - coefficients.T @ t.T @ lead)  # S⁻¹ Rᵀ A
        gradient = np.array([-2.0 * np.trace(k[:, 6 * (j + 1):6 * (j + 2)] @ coefficients[:6])
                             for j in range(len(theta))])
        return float(logdet), gradient

    return criterion


def _search(criterion, start: np.ndarray):
    """The criterion's minimum by BFGS with the analytic gradient."""
    from scipy.optimize import minimize

    with np.errstate(invalid="ignore", over="ignore"):
        return minimize(criterion, start, jac=True, method="BFGS", options={"gtol": 1e-10, "maxiter": 1000})


def _leave_blocks_out(blocks: np.ndarray, counts: np.ndarray, kf: int, extra: int,
                      start: np.ndarray, hessian: np.ndarray) -> list[np.ndarray]:
    """The estimate (scaled) without each block in turn: its moments subtracted from the total.

    Each refit takes Newton steps from the estimate with the full data's curvature
    (one block changes it by about its share of the samples, so the steps converge
    fast); a refit whose steps do not settle goes to the full search. A block whose
    removal leaves too few samples or an undetermined payload is skipped.
    """
    total, n = blocks.sum(axis=0), int(counts.sum())
    refits = []
    for block, count in zip(blocks, counts):
        if n - count <= 6 + 1 + extra + kf:
            continue
        criterion = _criterion(total - block, n - count, kf, extra)
        x = _newton(criterion, start, hessian, n - count)
        if x is None:
            result = _search(criterion, start)
            x = result.x if np.isfinite(result.fun) else None
        if x is not None and np.isfinite(x).all():
            refits.append(x)
    return refits


def _newton(criterion, start: np.ndarray, hessian: np.ndarray, n: int, steps: int = 50) -> np.ndarray | None:
    """Minimum of ``criterion`` by fixed-curvature Newton steps from ``start``; None if they do not settle.

    Converged when a step is below 10⁻⁶ of a (curvature) standard error: the log-likelihood
    is ``n / 2`` times the criterion, so a step's size in standard errors is √(n/2 · sᵀHs).
    """
    x = start.copy()
    for _ in range(steps):
        value, gradient = criterion(x)
        if not np.isfinite(value):
            return None
        step = np.linalg.solve(hessian, gradient)
        x = x - step
        if 0.5 * n * step @ hessian @ step <= 1e-12:
            return x
    return None


def _known_is_a_payload(moments: np.ndarray, kf: int, tolerance: float = 1e-8) -> bool:
    """True if the known wrench is (nearly) a payload on the link: then any common scale fits."""
    known = moments[:6, :6].trace()
    cols = [slice(6 * (j + 1), 6 * (j + 2)) for j in range(kf)]
    h = np.array([[np.trace(moments[a, b]) for b in cols] for a in cols])
    v = np.array([np.trace(moments[:6, a]) for a in cols])
    left = known - v @ np.linalg.pinv(h, rcond=1e-12, hermitian=True) @ v
    return bool(left <= tolerance * known) or known == 0


def _moments(u: np.ndarray, w: np.ndarray, y: np.ndarray, payload_mass: float | None, edges: np.ndarray):
    """Moment matrices of [w_known, Y columns (scaled), 1, extra inputs, channels] per contiguous block.

    Each payload parameter is scaled so that its regressor columns have the size of the
    known wrench (a well-conditioned search); returns the (blocks, width, width) moments,
    which add up to those of all samples, and those scales.
    """
    known = w if payload_mass is None else w + y[:, :, 0] * payload_mass
    columns = y if payload_mass is None else y[:, :, 1:]
    size = np.sqrt(np.mean(known**2)) or 1.0
    scale = np.sqrt(np.mean(columns**2, axis=(0, 1))) / size
    scale[scale == 0] = 1.0
    extra = u[:, N_CHANNELS:]
    width = 6 * (1 + columns.shape[2]) + 1 + extra.shape[1] + N_CHANNELS
    moments = np.zeros((len(edges) - 1, width, width))
    for b, (first, last) in enumerate(zip(edges[:-1], edges[1:])):
        for start in range(first, last, CHUNK):
            stop = min(start + CHUNK, last)
            block = columns[start:stop] / scale
            z = np.concatenate([known[start:stop], block.transpose(0, 2, 1).reshape(stop - start, -1),
                                np.ones((stop - start, 1)), extra[start:stop], u[start:stop, :N_CHANNELS]], axis=1)
            moments[b] += z.T @ z
    return moments, scale


def _hessian(criterion, x: np.ndarray, step: float = 1e-5) -> np.ndarray:
    """Hessian at ``x`` by central differences of the analytic gradient (parameters scaled to order one)."""
    h = step * np.maximum(1.0, np.abs(x))
    columns = [(criterion(x + e)[1] - criterion(x - e)[1]) / (2 * e.sum()) for e in np.diag(h)]
    out = np.array(columns)
    return 0.5 * (out + out.T)


def fit_with_payload(data: Dataset, payload: np.ndarray, link: str, *, degree: int = 1, solver=None,
                     normalization: str = "center", payload_mass: float | None = None):
    """Estimate the payload (:func:`estimate_payload`), then fit the calibration to the completed wrench.

    Parameters
    ----------
    data, payload, link, payload_mass : as :func:`estimate_payload`
    degree, solver, normalization : of the :class:`~ftcal.core.model.CalibrationModel` (static)

    Returns
    -------
    (CalibrationModel, PayloadEstimate)
    """
    from ..core.model import CalibrationModel

    estimate = estimate_payload(data, payload, link, payload_mass=payload_mass)
    completed = data.outputs + np.einsum("nik,k->ni", np.asarray(payload, dtype=np.float64), estimate.values)
    model = CalibrationModel(degree, solver=solver, normalization=normalization).fit(replace(data, outputs=completed))
    model.solver_info_["payload_link"] = link
    return model, estimate


def _unidentifiable_message(link: str, parameters: list[str], mass_free: bool) -> str:
    advice = "record poses that move them" + (", or give the payload's mass with {payload_mass} KG" if mass_free else "")
    return (f"The payload on {link} cannot be separated from the calibration: {' and '.join(parameters)} trade "
            f"against the calibration's gains. The scale comes from the robot's own links beyond the sensor "
            f"that move relative to {link} (e.g. a hand beyond wrist joints); {advice}.")
