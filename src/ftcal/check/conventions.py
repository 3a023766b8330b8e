"""Sign, frame and mounting conventions from a few static holds with the tool attached.

At rest the sensor reads ``F = m g + b_F`` and ``T = m c × g + b_T`` (ftcal's sign
convention, :mod:`ftcal.payload.regressor`), ``g`` gravity in the sensor frame. If the
data are in another frame, or of the other sign, the forces are ``F = m A g + b_F`` with
``A`` orthogonal: ``A = I`` when all is as declared, ``−I`` for the reaction sign, a
signed permutation for swapped or flipped axes, a rotation when the sensor is turned on
its flange relative to the URDF/tf. With the bias free, the least-squares ``A`` and ``m``
are the orthogonal Procrustes (Wahba) solution on the centred hold means, found in closed
form by one SVD; its determinant tells a mirror (sign, left-handed axes) from a rotation.

Each finding is tested: the likelihood-ratio statistic ``(RSS_declared − RSS_fixed)/σ²``
(σ² from the fixed fit's residual, floored by the holds' own noise) against χ² with 3
degrees of freedom gives its confidence; a rotation is also reported only above
:data:`~ftcal.core.limits.MIN_ROTATION_DEG`. Other checks:

* **base frame**: with full orientations (quaternions), readings rotated back into the
  sensor frame fit far better than as given;
* **compensated**: the force does not depend on the orientation (mass not significant):
  the driver already removes the tool's weight (and, near zero, the bias: a tared stream);
* **zeroed**: one hold reads ≈ 0 while the tool weighs m·g: zeroed there with the tool on;
* **lever**: the centre of mass is implausibly far from the sensor origin
  (:data:`~ftcal.core.limits.MAX_COM_DISTANCE`): the torques are about another point.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..core.limits import (FINDING_CONFIDENCE, HOLD_SAMPLE_RATE, MAX_COM_DISTANCE, MIN_HOLDS, MIN_ROTATION_DEG,
                           MIN_TOOL_MASS)
from ..data.tables import table_label_column
from ..payload.regressor import static_regressor
from ..runtime.errors import FtcalError, ParameterError, FtcalWarning
from ..data.holds import HoldAverages

AXES = ("Fx", "Fy", "Fz", "Tx", "Ty", "Tz")
# Centred gravity directions thinner than this (smallest / largest singular value) lie in a plane:
# a mirror along its normal is then invisible.
PLANAR_RATIO = 0.05
# The centred gravity directions must span at least this much (second singular value / largest).
MIN_SPREAD_RATIO = 0.02
# Base-frame readings: the rotated-back fit must shrink the force residual at least this much.
BASE_FRAME_RSS_RATIO = 4.0
# A hold reads "zero" within this many standard errors of its mean and this fraction of m·g.
ZERO_STDERR = 5.0
ZERO_WEIGHT_FRACTION = 0.02
# A channel whose hold means and hold noise stay below this fraction of its size never changed (rounding only).
CONSTANT_RELATIVE = 1e-12


@dataclass(frozen=True)
class Finding:
    """One convention problem, how sure ftcal is, and how to fix it.

    Attributes
    ----------
    kind : str
        ``no-signal``, ``sign``, ``handedness``, ``permutation``, ``rotation``, ``base-frame``,
        ``compensated``, ``zeroed`` or ``lever``.
    message : what the data show
    fix : the exact change (flag, columns, rotation)
    confidence : float in [0, 1]
    before, after : (force RMS N, torque RMS N·m) of the payload fit over the holds
    rpy : (roll, pitch, yaw) rad of the frame correction, when the fix is a rotation
        (URDF ``<origin rpy>`` of the data's frame in the declared sensor frame)
    wrench : the reordered --inputs columns, when the fix is a column order
    reaction : the fix includes --reaction
    """

    kind: str
    message: str
    fix: str
    confidence: float
    before: tuple[float, float]
    after: tuple[float, float]
    rpy: tuple[float, float, float] | None = None
    wrench: tuple[str, ...] | None = None
    reaction: bool = False


@dataclass(frozen=True)
class ConventionReport:
    """What :func:`check_conventions` found.

    Attributes
    ----------
    holds : HoldAverages
    findings : list of Finding (empty when the recording is as declared)
    force_map : ndarray of shape (3, 3), the fitted ``A`` (``F = m A g + b``)
    mass : float, kg, the best-fit mass with that map
    mass_stderr : float, kg
    residual : (force RMS N, torque RMS N·m) of the declared fit over the holds
    hold_residual, fixed_residual : ndarray of shape (n_holds, 6)
        Payload-fit residual of each hold as declared, and with every fix applied
    notes : caveats (what could not be tested and why)
    """

    holds: HoldAverages
    findings: list[Finding]
    force_map: np.ndarray
    mass: float
    mass_stderr: float
    residual: tuple[float, float]
    hold_residual: np.ndarray
    fixed_residual: np.ndarray
    notes: list[str] = field(default_factory=list)


@dataclass(frozen=True)
class _Procrustes:
    A: np.ndarray
    mass: float
    rss: float
    dof: int


def static_fit(wrench: np.ndarray, gravity: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Least-squares ``[m, m·c, b_F, b_T]`` of static readings, and the residuals.

    Parameters
    ----------
    wrench : ndarray of shape (n, 6)
    gravity : ndarray of shape (n, 3)

    Returns
    -------
    theta : ndarray of shape (10,)
    residual : ndarray of shape (n, 6)
    """
    y = static_regressor(gravity)
    theta = np.linalg.lstsq(y.reshape(-1, y.shape[2]), wrench.reshape(-1), rcond=None)[0]
    return theta, wrench - y @ theta


def residual_rms(residual: np.ndarray) -> tuple[float, float]:
    """(force RMS, torque RMS) of residuals of shape (n, 6)."""
    return (float(np.sqrt(np.mean(residual[:, :3] ** 2))), float(np.sqrt(np.mean(residual[:, 3:] ** 2))))


def procrustes(force: np.ndarray, gravity: np.ndarray, proper: bool = False) -> _Procrustes:
    """Best ``m ≥ 0`` and orthogonal ``A`` (a rotation with ``proper``) for ``F = m A g + b``.

    force, gravity : ndarray of shape (n, 3)
    """
    fc = force - force.mean(axis=0)
    gc = gravity - gravity.mean(axis=0)
    u, s, vt = np.linalg.svd(gc.T @ fc)
    d = np.ones(3)
    if proper and np.linalg.det(vt.T @ u.T) < 0:
        d[2] = -1.0
    a = vt.T @ np.diag(d) @ u.T
    ss = float(np.sum(gc ** 2))
    mass = float(s @ d) / ss if ss > 0 else 0.0
    rss = max(float(np.sum(fc ** 2)) - mass ** 2 * ss, 0.0)
    return _Procrustes(a, mass, rss, 3 * force.shape[0] - 7)


def _fit_with(force: np.ndarray, gravity: np.ndarray, a: np.ndarray) -> tuple[float, float]:
    """(mass ≥ 0, RSS) of ``F = m A g + b`` with ``A`` given."""
    fc = force - force.mean(axis=0)
    gc = (gravity - gravity.mean(axis=0)) @ a.T
    ss = float(np.sum(gc ** 2))
    mass = max(float(np.sum(gc * fc)) / ss, 0.0) if ss > 0 else 0.0
    return mass, float(np.sum((fc - mass * gc) ** 2))


def _confidence(rss_before: float, rss_after: float, sigma2: float, dof: int = 3) -> float:
    return chi2_cdf(max(rss_before - rss_after, 0.0) / sigma2, dof)


def rotation_angle(a: np.ndarray) -> float:
    """Angle of a rotation matrix, degrees."""
    return math.degrees(math.acos(float(np.clip((np.trace(a) - 1.0) / 2.0, -1.0, 1.0))))


def rpy_of(r: np.ndarray) -> tuple[float, float, float]:
    """URDF roll, pitch, yaw (rad) of ``r = Rz(yaw) Ry(pitch) Rx(roll)``."""
    pitch = math.asin(float(np.clip(-r[2, 0], -1.0, 1.0)))
    if abs(math.cos(pitch)) > 1e-9:
        roll = math.atan2(r[2, 1], r[2, 2])
        yaw = math.atan2(r[1, 0], r[0, 0])
    else:  # gimbal lock: put it all in yaw
        roll, yaw = 0.0, math.atan2(-r[0, 1], r[1, 1])
    # −π and π are the same angle: print π.
    return tuple(0.0 if abs(v) < 1e-12 else math.pi if abs(v + math.pi) < 1e-9 else v for v in (roll, pitch, yaw))


def rotation_from_rpy(rpy) -> np.ndarray:
    """``Rz(yaw) Ry(pitch) Rx(roll)`` (URDF ``<origin rpy>``)."""
    r, p, y = rpy
    cr, sr, cp, sp, cy, sy = math.cos(r), math.sin(r), math.cos(p), math.sin(p), math.cos(y), math.sin(y)
    return np.array([[cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
                     [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
                     [-sp, cp * sr, cp * cr]])


def _nearest_signed_permutation(a: np.ndarray) -> np.ndarray:
    p = np.zeros((3, 3))
    rows = set()
    for j in np.argsort(-np.abs(a).max(axis=0)):
        i = max((i for i in range(3) if i not in rows), key=lambda i: abs(a[i, j]))
        p[i, j] = np.sign(a[i, j]) or 1.0
        rows.add(i)
    return p


def _format_rpy(rpy) -> str:
    return (f"rpy=\"{' '.join(f'{v:.6g}' for v in rpy)}\" rad "
            f"({', '.join(f'{math.degrees(v):.2f}°' for v in rpy)})")


def _rms(holds: HoldAverages, sign: float, a: np.ndarray) -> tuple[float, float]:
    return residual_rms(static_fit(sign * holds.wrench, holds.gravity @ a.T)[1])


def check_conventions(holds: HoldAverages, *, wrench_columns=AXES, max_com_distance: float = MAX_COM_DISTANCE,
                      source: str = "data") -> ConventionReport:
    """Infer sign, handedness, axis order, frame rotation, base frame, compensation and lever.

    Parameters
    ----------
    holds : HoldAverages
        Static holds at different orientations with the tool attached.
    wrench_columns : the six wrench column names (to spell a column fix)
    max_com_distance : m, farther centres of mass mean torques about another point
    source : name for error messages

    Returns
    -------
    ConventionReport

    Raises
    ------
    FtcalError
        Fewer than :data:`~ftcal.core.limits.MIN_HOLDS` holds, or holds whose gravity
        directions do not differ enough to tell anything.
    """
    if holds.n_holds < MIN_HOLDS:
        raise FtcalError(f"{source}: {holds.n_holds} static hold(s) found; ftcal check needs at least "
                         f"{MIN_HOLDS} at different orientations (tool at rest, tilted several ways).")
    g_centred = holds.gravity - holds.gravity.mean(axis=0)
    spread = np.linalg.svd(g_centred, compute_uv=False)
    if spread[0] <= 0 or spread[1] < MIN_SPREAD_RATIO * spread[0]:
        raise FtcalError(f"{source}: the {holds.n_holds} static holds have gravity along (nearly) one line in "
                         "the sensor frame; record holds tilted about two different axes.")
    notes: list[str] = []
    planar = spread[2] < PLANAR_RATIO * spread[0]
    if planar:
        notes.append("the holds' gravity directions lie in one plane: a mirror (sign, left-handed axis) "
                     "looks like a 180° rotation about its normal; add a hold tilted out of that plane")
    force_noise2 = float(np.mean(holds.noise[:, :3] ** 2))
    declared_residual = static_fit(holds.wrench, holds.gravity)[1]
    declared = residual_rms(declared_residual)
    findings: list[Finding] = []
    silent = _no_signal(holds, wrench_columns, declared)
    if silent is not None:  # nothing else can be tested on a stream that never changes
        return ConventionReport(holds, [silent], np.eye(3), 0.0, math.inf, declared, declared_residual,
                                declared_residual, notes)
    data = holds

    def sigma2(fit: _Procrustes) -> float:
        return max(fit.rss / max(fit.dof, 1), force_noise2, 1e-300)

    raw = procrustes(holds.wrench[:, :3], holds.gravity, proper=planar)
    if holds.rotation is None:
        notes.append("base-frame readings not tested: give full orientations (quaternion columns)")
    else:
        world = holds.map(wrench=np.concatenate([np.einsum("nji,nj->ni", holds.rotation, holds.wrench[:, :3]),
                                                 np.einsum("nji,nj->ni", holds.rotation, holds.wrench[:, 3:])],
                                                axis=1))
        based = procrustes(world.wrench[:, :3], world.gravity, proper=planar)
        significant = _mass_z(based, world) ** 2 > _chi2_quantile(1)
        if significant and raw.rss > BASE_FRAME_RSS_RATIO * based.rss \
                and _confidence(raw.rss, based.rss, sigma2(based)) >= FINDING_CONFIDENCE:
            after = residual_rms(static_fit(world.wrench, world.gravity)[1])
            findings.append(Finding(
                "base-frame",
                "the wrench is expressed in the world/base frame of the orientation, not in the sensor frame: "
                "rotated back into the sensor frame the readings fit the tool's weight",
                "use the wrench in the sensor's own frame (the driver's sensor-frame topic, or frame_id = the "
                "sensor), or rotate it back: F_sensor = Rᵀ F_base, T_sensor = Rᵀ T_base",
                _confidence(raw.rss, based.rss, sigma2(based)), declared, after))
            data, raw = world, based
    z = _mass_z(raw, data)
    mass_se = raw.mass / z if z else math.inf
    if z ** 2 <= _chi2_quantile(1):
        # Not significant: compensated if the tool is also confidently lighter than MIN_TOOL_MASS.
        light = 1.0 - _normal_sf((MIN_TOOL_MASS - raw.mass) / mass_se) if math.isfinite(mass_se) else 0.0
        if light < FINDING_CONFIDENCE:
            notes.append(f"the force hardly changes with the orientation (mass {raw.mass:.3g} ± {mass_se:.2g} kg): "
                         "too noisy to tell a light tool from a compensated stream; hold the poses longer")
            return ConventionReport(holds, findings, raw.A, raw.mass, mass_se, declared, declared_residual,
                                    declared_residual, notes)
        tared = bool(np.all(np.abs(data.wrench.mean(axis=0)) <= ZERO_STDERR * np.sqrt(
            np.mean(data.noise ** 2, axis=0) + np.var(data.wrench, axis=0))))
        what = ("already tared and gravity-compensated (a contact-wrench stream: about zero in every hold)"
                if tared else "already gravity-compensated, or no tool is attached (a constant offset remains)")
        findings.append(Finding(
            "compensated",
            f"the force does not change with the orientation (fitted mass {raw.mass:.3g} kg, "
            f"{abs(z):.2g} standard errors from 0): the stream looks {what}",
            "record the raw wrench (turn off the driver's zeroing / gravity compensation, e.g. the raw topic) "
            "with the tool attached; ftcal payload cannot identify a tool from this stream",
            light, declared, declared))
        return ConventionReport(holds, findings, raw.A, raw.mass, mass_se, declared, declared_residual,
                                declared_residual, notes)
    sign, a_fix, map_finding = _map_finding(data, raw, sigma2(raw), wrench_columns, declared)
    if map_finding is not None:
        findings.append(map_finding)
    fixed = data.map(wrench=sign * data.wrench, gravity=data.gravity @ a_fix.T)
    theta, residual = static_fit(fixed.wrench, fixed.gravity)
    after = residual_rms(residual)
    findings += _zeroed(fixed, theta, after)
    findings += _lever(fixed, theta, residual, max_com_distance, after)
    return ConventionReport(holds, findings, raw.A, raw.mass, mass_se, declared, declared_residual, residual,
                            notes)


def _chi2_quantile(dof: int) -> float:
    return chi2_quantile(FINDING_CONFIDENCE, dof)


def chi2_cdf(x: float, dof: int) -> float:
    """P(χ² with ``dof`` (integer) degrees of freedom ≤ ``x``), in closed form.

    P(1, x) = erf(√(x/2)), P(2, x) = 1 − e^(−x/2), and P(k + 2, x) = P(k, x) − (x/2)^(k/2) e^(−x/2) / Γ(k/2 + 1):
    one line of the standard library where ``scipy.stats`` would cost most of a second of imports.

    Examples
    --------
    >>> round(chi2_cdf(3.841458820694124, 1), 12)   # the 95 % point of χ²(1) = 1.959964² (normal table)
    0.95
    """
    if x <= 0:
        return 0.0
    half = x / 2.0
    k = 2 - dof % 2
    total = math.erf(math.sqrt(half)) if k == 1 else -math.expm1(-half)
    while k < dof:
        total -= math.exp((k / 2.0) * math.log(half) - half - math.lgamma(k / 2.0 + 1.0))
        k += 2
    return min(max(total, 0.0), 1.0)


def chi2_quantile(probability: float, dof: int) -> float:
    """The ``probability`` quantile of χ² with ``dof`` degrees of freedom (bisection on :func:`chi2_cdf`)."""
    low, high = 0.0, max(1.0, 2.0 * dof)
    while chi2_cdf(high, dof) < probability:
        high *= 2.0
    for _ in range(200):
        middle = 0.5 * (low + high)
        if chi2_cdf(middle, dof) < probability:
            low = middle
        else:
            high = middle
        if high - low <= 1e-13 * high:
            break
    return 0.5 * (low + high)


def _normal_sf(z: float) -> float:
    return 0.5 * math.erfc(z / math.sqrt(2.0))


def _mass_z(fit: _Procrustes, holds: HoldAverages) -> float:
    """Mass over its standard error (σ from the fit, floored by the holds' noise)."""
    gc = holds.gravity - holds.gravity.mean(axis=0)
    s2 = max(fit.rss / max(fit.dof, 1), float(np.mean(holds.noise[:, :3] ** 2)), 1e-300)
    return fit.mass * math.sqrt(float(np.sum(gc ** 2)) / s2)


def _map_finding(holds: HoldAverages, fit: _Procrustes, sigma2: float, columns,
                 declared) -> tuple[float, np.ndarray, Finding | None]:
    """The sign / permutation / handedness / rotation finding of the fitted map, and the fix (sign, A')."""
    force = holds.wrench[:, :3]
    a = fit.A
    sign = float(np.sign(np.linalg.det(a)))
    snapped = _nearest_signed_permutation(a)
    if rotation_angle((sign * snapped).T @ (sign * a)) < MIN_ROTATION_DEG:
        a = snapped  # within mounting tolerance of a 90°/180°/mirror error: give the exact numbers
    proper = sign * a
    angle = rotation_angle(proper)
    _, rss_declared = _fit_with(force, holds.gravity, np.eye(3))
    _, rss_fixed = _fit_with(force, holds.gravity, a)
    confidence = _confidence(rss_declared, rss_fixed, sigma2)
    if confidence < FINDING_CONFIDENCE or (sign > 0 and angle < MIN_ROTATION_DEG):
        return 1.0, np.eye(3), None
    after = _rms(holds, sign, proper)
    rpy = rpy_of(proper.T)
    rotate = (f"the data's frame is the declared sensor frame turned by {_format_rpy(rpy)}: add it as a fixed "
              "joint <origin rpy> from the declared frame to a new link and pass that link as --ft-frame (or "
              "correct the sensor joint's rpy in the URDF; with quaternion columns, compose them on the right "
              "with this rotation)")
    is_permutation = bool(np.all(a >= 0)) and not np.allclose(a, np.eye(3))
    if is_permutation:
        order = [int(np.flatnonzero(a[:, j])[0]) for j in range(3)]
        new = tuple(columns[k] for k in order) + tuple(columns[3 + k] for k in order)
        names = ", ".join(f"column {columns[k]} holds {AXES[j]}" for j, k in enumerate(order) if k != j)
        return sign, proper, Finding(
            "permutation", f"the wrench axes are permuted ({names}; Tx..Tz likewise)",
            f"--inputs {','.join(new)}", confidence, declared, after, wrench=new)
    if sign < 0 and angle < MIN_ROTATION_DEG:
        return sign, proper, Finding(
            "sign", "the sensor reports the reaction: at rest it reads −m·g (the wrench it applies on the tool)",
            "--reaction", confidence, declared, after, reaction=True)
    if sign < 0:
        mirror = np.allclose(np.abs(a), np.eye(3)) and int(np.sum(np.diag(a) < 0)) == 1
        if mirror:
            axis = "xyz"[int(np.flatnonzero(np.diag(a) < 0)[0])]
            what = (f"the data's frame is left-handed: its {axis} axis is reversed (F{axis} and T{axis} have the "
                    "opposite sign)")
        else:
            what = (f"the force axes are a mirror image of the declared ones (det −1): the reaction sign with "
                    f"the frame turned by {angle:.2f}°")
        return sign, proper, Finding(
            "handedness", what, f"--reaction, and {rotate}", confidence, declared, after, rpy=rpy, reaction=True)
    kind = "a 90°-multiple" if np.allclose(np.abs(a), np.round(np.abs(a))) else f"a {angle:.2f}°"
    return sign, proper, Finding(
        "rotation", f"the wrench is in a frame turned by {kind} rotation from the declared sensor frame "
                    f"(fitted angle {angle:.2f}°)", rotate, confidence, declared, after, rpy=rpy)


def _no_signal(holds: HoldAverages, columns, declared) -> Finding | None:
    """A finding when the force channels read one value in every sample of every hold (no noise, no change
    with the orientation): a sensor that is not measuring (unpowered, disconnected, a driver sending a
    default message), whatever the tool. A real gauge's reading always varies between tilted holds."""
    def constant(block: slice) -> bool:
        size = float(np.abs(holds.wrench[:, block]).max(initial=0.0))
        return bool(holds.noise[:, block].max() <= CONSTANT_RELATIVE * size
                    and np.ptp(holds.wrench[:, block], axis=0).max() <= CONSTANT_RELATIVE * size)

    if not constant(slice(0, 3)):
        return None
    force = holds.wrench[0, :3]
    value = "exactly 0" if not force.any() else "one value (" + ", ".join(f"{v:.6g}" for v in force) + " N)"
    return Finding(
        "no-signal",
        f"the force channels {', '.join(map(str, columns[:3]))} read {value} in every sample of all "
        f"{holds.n_holds} holds, with no noise and no change with the orientation"
        + (" (the torque channels too)" if constant(slice(3, 6)) else "")
        + ": the sensor is not measuring (unpowered, disconnected, not started, or a driver publishing a "
        "default message)",
        "check the sensor's power, cable and driver (the raw stream must vary, at least by its noise), then record "
        "the holds again",
        1.0, declared, declared)


def _zeroed(holds: HoldAverages, theta: np.ndarray, after) -> list[Finding]:
    weight = abs(theta[0]) * float(np.linalg.norm(holds.gravity, axis=1).mean())
    norm_f = np.linalg.norm(holds.wrench[:, :3], axis=1)
    norm_t = np.linalg.norm(holds.wrench[:, 3:], axis=1)
    se_f = np.linalg.norm(holds.noise[:, :3], axis=1)
    se_t = np.linalg.norm(holds.noise[:, 3:], axis=1)
    torque_scale = float(np.ptp(holds.wrench[:, 3:], axis=0).max())
    zero = (norm_f <= np.maximum(ZERO_STDERR * se_f, ZERO_WEIGHT_FRACTION * weight)) \
        & (norm_t <= np.maximum(ZERO_STDERR * se_t, ZERO_WEIGHT_FRACTION * torque_scale))
    if not zero.any() or weight <= 0:
        return []
    k = int(np.flatnonzero(zero)[0])
    return [Finding(
        "zeroed",
        f"hold {k + 1} (rows {holds.start[k]}–{holds.stop[k] - 1}) reads ≈ 0 while the tool weighs "
        f"{weight:.3g} N: the stream was zeroed (tared) there with the tool attached, so the bias ftcal "
        f"identifies is the tare offset, not the sensor's",
        "keep the driver's zero fixed while the payload file is in use, and identify the payload again after "
        "every re-zero (or record with zeroing off)",
        # Confidence: that the hold's zero is not the tool being weightless (weight vs the hold's noise).
        1.0 - 2.0 * _normal_sf(weight / max(float(se_f[k]), 1e-300)), after, after)]


def _lever(holds: HoldAverages, theta: np.ndarray, residual: np.ndarray, max_com_distance: float, after) -> list[Finding]:
    mass = theta[0]
    if mass <= 0:
        return []
    com = theta[1:4] / mass
    distance = float(np.linalg.norm(com))
    if distance <= max_com_distance:
        return []
    y = static_regressor(holds.gravity)
    s2 = np.maximum(np.mean(residual ** 2, axis=0), np.mean(holds.noise ** 2, axis=0))
    weights = 1.0 / np.maximum(s2, 1e-300)
    gram = np.einsum("nai,a,naj->ij", y, weights, y)
    cov = np.linalg.pinv(gram)
    # delta method for |m·c / m|
    grad = np.zeros(10)
    grad[1:4] = com / (distance * mass)
    grad[0] = -distance / mass
    se = math.sqrt(max(float(grad @ cov @ grad), 1e-300))
    confidence = 1.0 - _normal_sf((distance - max_com_distance) / se)
    if confidence < FINDING_CONFIDENCE:
        return []
    return [Finding(
        "lever",
        f"the centre of mass comes out at ({', '.join(f'{v:.3g}' for v in com)}) m, {distance:.3g} m from the "
        f"sensor origin (more than {max_com_distance:g} m): the torques look taken about another point "
        "(e.g. a tool centre point set in the driver), which shifts the centre of mass by that lever",
        "report torques about the sensor origin (T_origin = T_point + p × F, p the point in the sensor frame; "
        "e.g. zero the driver's TCP offset); if the tool really is that long, raise --max-com-distance",
        confidence, after, after)]


# A payload fit whose force residual reaches this fraction of the tool's weight is suspect.
WEIGHT_FRACTION_WARNING = 0.1


class ConventionWarning(FtcalWarning):
    """``ftcal payload``'s fit looks like a sign, frame or zeroing mistake."""


def payload_warning(paths, source, fit, g: float, *, wrench=AXES, reaction: bool = False,
                    time: str | None = None, holds: "HoldCollector | None" = None) -> str | None:
    """One line for ``ftcal payload`` when its data look like a convention error, else None.

    Parameters
    ----------
    paths : its tables
    source : its KinematicsSource
    fit : its PayloadFit (mass, residual RMS)
    g : m/s²
    wrench : its --inputs columns (to spell a fix)
    reaction : its --reaction
    time : its --time column (default ``time`` where there is one)
    holds : the :class:`HoldCollector` that saw the tables as the fit read them (then they are
        not read again), or None to read ``paths``
    """
    try:
        averages = (holds.averages() if holds is not None else
                    read_holds(paths, source, wrench=wrench, reaction=reaction, time=time))
        report = check_conventions(averages, wrench_columns=tuple(wrench))
    except FtcalError:
        return None  # no usable static holds (e.g. continuous motion): the fit's own checks apply
    # A negative mass alone is ftcal payload's own error (it offers --reaction).
    findings = [f for f in report.findings if not (f.kind == "sign" and fit.mass < 0)]
    if findings:
        f = findings[0]
        return (f"the data look {f.kind}-wrong: {f.message}; fix: {f.fix} (hold residual {f.before[0]:.3g} N → "
                f"{f.after[0]:.3g} N; ftcal check lists every finding)")
    weight = abs(fit.mass) * g
    force_rms = float(np.sqrt(np.mean(np.asarray(fit.residual_rms)[:3] ** 2)))
    if weight > 0 and force_rms >= WEIGHT_FRACTION_WARNING * weight:
        return (f"the force residual ({force_rms:.3g} N RMS) is of the order of the tool's weight ({weight:.3g} N): "
                "check the sign, frame and zeroing with ftcal check")
    return None


class HoldCollector:
    """The hold averages of the convention check, taken from each table while the payload fit reads it.

    Given as ``select`` to :func:`ftcal.payload.tables.read_payload_tables`, it sees every table's
    frame and gravity once, as the fit reads them, and keeps what :func:`read_holds` would find in
    the same files (same holds, same means), so the check needs no second read of the tables and
    no second gravity computation. It then hands the frame to ``select`` (the fit's own row choice).

    Parameters
    ----------
    source : KinematicsSource of the fit (quaternion columns give the holds' rotations too)
    select : callable or None, the fit's own ``select(frame, kinematics, path)``
    wrench, reaction, time : as :func:`read_holds`
    """

    def __init__(self, source, select=None, *, wrench=("u1", "u2", "u3", "u4", "u5", "u6"), reaction: bool = False,
                 time: str | None = None):
        from ..payload.kinematics import MotionSource

        # As read_holds: holds are static, gravity's source is all that matters (quaternions give rotations).
        self.source = source.gravity if isinstance(source, MotionSource) else source
        self.select = select
        self.wrench, self.reaction, self.time = tuple(wrench), reaction, time
        self.parts: list[HoldAverages] = []
        self.error: FtcalError | None = None  # the first table without usable holds: the check is skipped

    def __call__(self, frame, kinematics, path: str):
        if self.error is None:
            try:
                self.parts.append(_table_holds(frame, str(path), kinematics.gravity, self.source, wrench=self.wrench,
                                               reaction=self.reaction, time=self.time))
            except FtcalError as exc:
                self.error = exc
        return None if self.select is None else self.select(frame, kinematics, path)

    def averages(self) -> HoldAverages:
        """The hold averages of all tables seen, as :func:`read_holds` gives them.

        Raises
        ------
        FtcalError
            A table had no usable hold (what :func:`read_holds` raises), or no table was seen.
        """
        from ..data.holds import concatenate_averages

        if self.error is not None:
            raise self.error
        if not self.parts:
            raise FtcalError("No table was read.")
        return concatenate_averages(self.parts)


def read_holds(paths, source, *, wrench=("u1", "u2", "u3", "u4", "u5", "u6"), group_by: str | None = None,
               reaction: bool = False, time: str | None = None, rate: float = HOLD_SAMPLE_RATE) -> HoldAverages:
    """Static holds of CSV/Parquet recordings and their means (:func:`ftcal.data.holds.find_holds` from
    the gravity direction).

    Parameters
    ----------
    paths : table files
    source : KinematicsSource giving gravity in the declared sensor frame; with quaternion
        columns (``OrientationSource``) the full rotations are kept too (base-frame test)
    wrench : six wrench columns
    group_by : column naming the holds (each label's longest still stretch is its hold)
    reaction : negate the readings (the user declares the reaction sign)
    time : time column, s (default ``time`` where a table has one); holds never span two values of a
        ``segment`` column
    rate : Hz, the sample rate of a table without the time column (its rows are then that far apart)

    Returns
    -------
    HoldAverages

    Raises
    ------
    FtcalError
        A missing column, or a table without a static hold.
    """
    from ..data.holds import concatenate_averages
    from ..data.tables import read_table
    from ..payload.kinematics import MotionSource
    from ..payload.tables import check_wrench_columns

    wrench = check_wrench_columns(wrench, source)
    if isinstance(source, MotionSource):
        source = source.gravity  # holds are static: gravity is all that matters
    parts = []
    for path in paths:
        frame = read_table(path)
        parts.append(_table_holds(frame, str(path), source(frame, str(path)).gravity, source, wrench=wrench,
                                  group_by=group_by, reaction=reaction, time=time, rate=rate))
    return concatenate_averages(parts)


def _table_holds(frame, path: str, gravity: np.ndarray, source, *, wrench, group_by: str | None = None,
                 reaction: bool = False, time: str | None = None, rate: float = HOLD_SAMPLE_RATE) -> HoldAverages:
    """The hold averages of one table already read (:func:`read_holds`'s work on one file), ``gravity``
    its gravity in the sensor frame, shape (n, 3)."""
    from pathlib import Path

    from ..data.holds import MIN_HOLD_S, find_holds, hold_averages
    from ..data.tables import numeric_columns
    from ..payload.kinematics import OrientationSource

    time_column = time or "time"
    measured = (-1.0 if reaction else 1.0) * numeric_columns(frame, wrench, Path(path), "wrench")
    # Quaternion columns give each hold's rotation too (base-frame test), made per hold from its own rows.
    quaternions = (numeric_columns(frame, source.columns, Path(path), "orientation")
                   if isinstance(source, OrientationSource) else None)
    if time_column in frame.columns:
        t = numeric_columns(frame, (time_column,), Path(path), "time")[:, 0]
    elif time is not None:
        raise ParameterError('time', f"{path}: no time column {time!r} ({{time}}); the file has "
                         f"{', '.join(map(str, frame.columns))}.")
    else:
        t = np.arange(len(frame)) / rate
    labels = frame["segment"].to_numpy() if "segment" in frame.columns else None
    group_by = table_label_column(list(frame.columns), group_by)
    if group_by is not None:
        if group_by not in frame.columns:
            raise ParameterError('group_by', f"{path}: no hold column {group_by!r} ({{group_by}}); the file has "
                             f"{', '.join(map(str, frame.columns))}.")
        labels = frame[group_by].astype(str).to_numpy(dtype=object)
    holds = find_holds(t, gravity=gravity, segments=labels, where=str(path), time_column=time_column)
    if group_by is not None:
        holds = holds.longest_per_segment(labels)
    if holds.n_holds == 0:
        raise FtcalError(f"{path}: no static hold found (gravity direction still for {MIN_HOLD_S:g} s or "
                         "more); record the tool at rest in a few orientations.")
    return hold_averages(holds, measured, gravity, quaternions=quaternions)
