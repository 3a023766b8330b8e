"""Payload and bias identification by linear least squares on summed statistics.

Model (ftcal sign convention, see :mod:`ftcal.payload.regressor`): the wrench
read by the sensor is ``Y θ`` with θ = [m, m·c, force bias, torque bias] for
static poses, or the ten inertial parameters plus the six biases with
``dynamic``; covariates the bias is affine in (time, temperature) add six
coefficients each (:mod:`ftcal.payload.drift`).

Weighting: plain least squares (OLS) unless held-out evidence says otherwise.
``weighting="auto"`` scores OLS and two-step per-axis weighted least squares
(each axis weighted by 1/σ² of its OLS residual) on held-out contiguous
blocks (the ``clusters``, else the groups) and keeps the weighting only when
it predicts held-out forces and torques no worse than OLS (1 % ties; per axis on
average and on the force and torque error norms) and one of them better.

Standard errors: with ``clusters`` (contiguous time blocks or poses) the
covariance is the grouped jackknife over the clusters (cluster-robust, CR3),
which stays honest when the residuals are correlated in time or the noise
model is wrong (with ``coarser``, each standard error raised to the jackknife's
over longer contiguous runs of clusters where larger: errors correlated over
several clusters, such as a drift that follows the pose order); it is scaled by
``(t_{G−1, 0.975} / z_{0.975})²`` so that ±1.96 standard errors is a 95 %
interval with G − 1 degrees of freedom. Without clusters it is the classical
per-axis-heteroscedastic covariance. The centre of mass's standard error
follows by the delta method from c = (m·c) / m.

Excitation: a parameter the poses cannot separate from the others has a large
variance inflation factor ``VIF_j = (G⁻¹)_jj G_jj`` on the weighted Gram G
(1 for an orthogonal design). Above :data:`EXCITATION_LIMIT` ftcal warns,
naming the parameter and the kind of pose that would excite it.

Rank-deficient poses (e.g. every pose keeps the sensor's z axis vertical, so the
centre of mass along z never acts on the sensor): the null space of the
equilibrated Gram gives the parameter combinations the poses do not determine
(:class:`Undetermined`). Every parameter with a component in it is reported
undetermined (no estimate, no standard error); to pick one solution, as many of
them as the null space has dimensions are held at zero, centre-of-mass
components first (the COM on the sensor's origin along that axis), then biases.
The others are estimated on the remaining columns, with the same standard
errors as a full fit (estimable combinations do not depend on that choice).
When the mass itself (or a drift coefficient) is undetermined there is nothing
to identify: that is an error.
"""

from __future__ import annotations

import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from ..core.directions import CANONICAL_TIE, canonical_sign
from ..core.jackknife import UNDETERMINED_ERROR, Widened, merged_partitions, widest_covariance
from ..core.limits import PAYLOAD_WEIGHTINGS
from ..core.precision import SCORE, settle
from ..core.solvers.base import Conditioning
from ..core.statistics import SufficientStatistics
from ..runtime.deprecation import deprecated_alias
from ..runtime.errors import FtcalError, ParameterError, IllPosedFitWarning, IllPosedParameterWarning, UndeterminedWarning
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
_COVARIATE_HINT = ("revisit early poses late in the recording (a pose order that follows time, or temperature, "
                   "confounds the drift with the gravity wrench)")
# Held-out error ratios within this fraction of 1 are ties (no evidence for or against weighting).
WEIGHTING_TIE = 0.01
# |mass| below this many standard errors is not distinguishable from zero.
SIGNIFICANT_STDERR = 2.0
# Readable names for messages.
LABELS = {"m": "mass", "mcx": "com x", "mcy": "com y", "mcz": "com z",
          "Fx_bias": "force bias x", "Fy_bias": "force bias y", "Fz_bias": "force bias z",
          "Tx_bias": "torque bias x", "Ty_bias": "torque bias y", "Tz_bias": "torque bias z"}


# A parameter whose row of the (orthonormal, equilibrated) null basis exceeds this has a component
# in an undetermined direction; rounding leaves ~eps / (smallest kept eigenvalue) in determined rows.
NULL_ROW = 1e-6
# A regressor column whose entries all stay below this fraction of its kind's scale is rounding, not data.
ROUNDING_COLUMN = 1e-9
# Which undetermined parameters are held at zero first: the centre of mass (its component along a
# direction gravity never crosses), then the inertia, torque and force biases. The mass is never held.
_HOLD_ORDER = (("mcx", "mcy", "mcz"), ("Ixx", "Ixy", "Ixz", "Iyy", "Iyz", "Izz"),
               ("Tx_bias", "Ty_bias", "Tz_bias"), ("Fx_bias", "Fy_bias", "Fz_bias"))


@dataclass(frozen=True)
class Undetermined:
    """Parameter combinations the poses do not determine, and how one solution was picked.

    Attributes
    ----------
    names : parameter names of θ that ``directions`` refer to (static or dynamic set, no covariates)
    parameters : the parameters with a component in an undetermined direction (not determined)
    held : the parameters held at zero to pick one solution (a subset of ``parameters``)
    directions : ndarray of shape (len(names), k)
        Basis of the regressor's null space in θ units, scaled so that ``directions[held] = I``:
        adding any combination of the columns to θ leaves every recorded pose's wrench unchanged.
    rank : rank of the regressor (``len(names) − k``)
    message : what is not determined and what to record, in words
    """

    names: tuple[str, ...]
    parameters: tuple[str, ...]
    held: tuple[str, ...]
    directions: np.ndarray
    rank: int
    message: str


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
    weighting: str = "ols"  # "ols" or "wls" (per-axis 1/σ²)
    weighting_evidence: str = ""  # why, in words
    stderr_kind: str = "classical"  # "classical", "cluster-robust (G blocks)" or "state-space"
    covariates: dict = field(default_factory=dict)  # name -> (coefficients (6,), stderr (6,)) per unit
    undetermined: Undetermined | None = None  # what the poses do not determine (None: everything is)

    @property
    def dynamic(self) -> bool:
        return self.inertia is not None


def _solve(gram: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    return Conditioning.of(gram).solve(rhs[:, None])[:, 0]


def describe_parameters(names) -> str:
    """Parameter names in words, comma-separated (``mcz`` → ``com z``)."""
    return ", ".join(LABELS.get(n, n) for n in names)


def identify_from_statistics(groups: Mapping[str, AxisStatistics], *, cross_validate: bool = True,
                     clusters: Sequence[AxisStatistics] = (), weighting: str = "auto",
                     covariates: Sequence[str] = (), coarser: Sequence[int] = ()) -> PayloadFit:
    """Fit the payload and bias to statistics gathered per validation group.

    Parameters
    ----------
    groups : mapping of group label to AxisStatistics
        From :func:`~ftcal.payload.accumulate.payload_statistics`, all with the
        same parameter set (10 static or 16 dynamic, plus 6 per covariate).
    cross_validate : bool
        Also refit without each group in turn and score it (needs >= 2 groups).
    clusters : sequence of AxisStatistics
        The same samples cut into contiguous blocks (time blocks or poses):
        cluster-robust standard errors and the held-out folds of the weighting
        choice. Empty: classical standard errors, folds are the groups.
    weighting : {"auto", "ols", "wls"}
        Per-axis weighting; ``auto`` keeps it only when held-out evidence chooses it.
    covariates : names of the covariates of the bias (their 6 coefficients each follow the biases)
    coarser : numbers of contiguous runs of ``clusters`` also left out in turn
        (:data:`~ftcal.core.jackknife.COARSER_BLOCKS`); each standard error is the largest of the
        jackknives (:func:`~ftcal.core.jackknife.widest_covariance`). Empty: the clusters' jackknife only.

    Returns
    -------
    PayloadFit

    Raises
    ------
    FtcalError
        Too few samples, or poses that leave the mass (or a covariate coefficient)
        undetermined; the message names what the poses confound and what to record.

    Warns
    -----
    UndeterminedWarning
        Once, when the poses leave some other parameters undetermined (rank-deficient
        regressor): they are held or reported as :attr:`PayloadFit.undetermined`, with the fix.
    IllPosedFitWarning
        For each poorly excited parameter, with the kind of pose to add; and when the coarsest
        jackknife's mass error exceeds the finest one's by more than
        :data:`~ftcal.core.jackknife.UNDETERMINED_ERROR` (the standard error is itself uncertain).
    """
    if weighting not in PAYLOAD_WEIGHTINGS:
        raise FtcalError(f"weighting: {weighting!r} is not one of {', '.join(PAYLOAD_WEIGHTINGS)}.")
    if not groups:
        raise FtcalError("No samples to identify the payload from.")
    total = None
    for stats in groups.values():
        total = stats if total is None else total + stats
    p = total.n_parameters
    base = STATIC_PARAMETERS if p == 10 + 6 * len(covariates) else DYNAMIC_PARAMETERS
    names = base + tuple(f"{axis}_{c}" for c in covariates for axis in AXES)
    n = total.n_samples
    if 6 * n <= p:
        raise FtcalError(f"{n} sample(s) give {6 * n} equations for {p} unknowns; record more poses.")
    undetermined = find_undetermined(total, names, len(base))
    keep = np.arange(p)
    if undetermined is not None:
        warnings.warn(undetermined.message, UndeterminedWarning, stacklevel=2)
        keep = np.array([j for j in range(p) if names[j] not in undetermined.held])
        groups = {label: stats.take(keep) for label, stats in groups.items()}
        clusters = [c.take(keep) for c in clusters]
        total = total.take(keep)
    full_names, full_p = names, p
    names, p = tuple(names[j] for j in keep), len(keep)
    conditioning = Conditioning.of(total.gram())
    theta0 = conditioning.solve(total.cross()[:, None])[:, 0]
    axis_variance = _axis_variance(total, theta0, n, p)
    folds = list(clusters) if len(clusters) > 1 else list(groups.values())
    if weighting == "auto":
        weighting, evidence = _choose_weighting(folds, total, p)
    else:
        evidence = "chosen by the caller"
    weights = np.ones(6) if weighting == "ols" else 1.0 / axis_variance
    wgram = total.gram(weights)
    theta = _solve(wgram, total.cross(weights))
    # Invert the equilibrated Gram (unit diagonal): the columns' units differ by orders of magnitude.
    jacobi = 1.0 / np.sqrt(np.diag(wgram))
    inverse = np.linalg.inv(wgram * jacobi[:, None] * jacobi[None, :])
    inverse = 0.5 * (inverse + inverse.T)
    bread = inverse * jacobi[:, None] * jacobi[None, :]
    widened = robust_covariance(wgram, total.cross(weights), clusters, theta, weights, coarser) \
        if len(clusters) > 1 else None
    covariance = None if widened is None else widened.covariance
    if widened is not None:
        kind = stderr_words(widened, len(clusters))
        warn_uncertain_error(widened, "the mass")
    else:
        variance = _axis_variance(total, theta, n, p)
        meat = total.gram(weights ** 2 * variance)
        covariance = bread @ meat @ bread
        kind = "classical" if len(clusters) < 2 else \
            "classical (no time block can be left out without losing a parameter)"
    covariance = 0.5 * (covariance + covariance.T)
    vif = np.diag(inverse)
    unknown = () if undetermined is None else undetermined.parameters  # said once above, not "hardly excited"
    poorly = tuple(names[j] for j in np.flatnonzero(vif > EXCITATION_LIMIT) if names[j] not in unknown)
    for name in poorly:
        j = names.index(name)
        warnings.warn(f"the poses hardly excite {LABELS.get(name, name)} (standard error inflated "
                      f"{np.sqrt(vif[j]):.0f}x by collinearity): {_HINTS.get(name, _COVARIATE_HINT)}.",
                      IllPosedFitWarning, stacklevel=2)
    rms = np.sqrt(total.residual_sum_of_squares(theta) / n)
    residuals = _cross_validate(groups, total, weights, p) if cross_validate and len(groups) > 1 else ()
    if undetermined is not None:  # back to every parameter: the held ones are zero, without variance
        theta, covariance, vif = _expand(theta, keep, full_p), _expand(covariance, keep, full_p), \
            _expand(vif, keep, full_p, np.inf)
        names, p = full_names, full_p
    fit = _derive(names, theta, covariance, undetermined)
    se = np.sqrt(np.maximum(np.diag(covariance), 0.0))
    found = {c: (theta[10 + 6 * k:16 + 6 * k] if base is STATIC_PARAMETERS else None,
                 se[10 + 6 * k:16 + 6 * k]) for k, c in enumerate(covariates)}
    return PayloadFit(names, theta, covariance, residual_rms=rms, n_samples=n,
                      condition_number=Conditioning.of(wgram).condition_number,
                      variance_inflation=vif, poorly_excited=poorly, cross_validation=residuals,
                      weighting=weighting, weighting_evidence=evidence, stderr_kind=kind,
                      covariates=found, undetermined=undetermined, **fit)


def _expand(values: np.ndarray, keep: np.ndarray, p: int, fill: float = 0.0) -> np.ndarray:
    """A vector or matrix over the kept parameters, put back among all ``p`` (``fill`` elsewhere)."""
    if values.ndim == 1:
        out = np.full(p, fill)
        out[keep] = values
        return out
    out = np.full((p, p), fill)
    out[np.ix_(keep, keep)] = values
    return out


def find_undetermined(total: AxisStatistics, names: tuple[str, ...], n_base: int) -> Undetermined | None:
    """The parameter combinations the regressor leaves undetermined, or None when it has full rank.

    The Gram is equilibrated as usual (unit diagonal), except that a column whose entries are all
    below :data:`ROUNDING_COLUMN` of its kind's scale (gravity for mass, first moment and inertia,
    1 for the biases) is rounding, not data: the centre of mass along a sensor axis that gravity
    never leaves (gravity read from quaternions has ~1e-16 g across it) is not determined.

    Parameters
    ----------
    total : the payload regressor's statistics
    names : the p parameter names (static or dynamic set, then covariate coefficients)
    n_base : how many of them are the static or dynamic set (the rest are covariate coefficients)

    Returns
    -------
    Undetermined or None

    Raises
    ------
    FtcalError
        When the mass or a covariate coefficient is undetermined: nothing to identify a payload from
        (the message names what the poses confound and what to record).
    """
    gram = total.gram()
    maxabs = np.max([a.column_maxabs for a in total.axes], axis=0)
    bias = np.array([name.endswith("_bias") for name in names])
    scale = np.where(bias, 1.0, maxabs[0])  # the mass column holds gravity: the others' scale
    scale[n_base:] = maxabs[n_base:]  # covariates: their own
    diagonal = np.maximum(np.diag(gram), (ROUNDING_COLUMN * scale) ** 2 * total.n_samples)
    jacobi = 1.0 / np.sqrt(np.where(diagonal > 0, diagonal, 1.0))
    values, vectors = np.linalg.eigh(gram * jacobi[:, None] * jacobi[None, :])
    null = values <= values[-1] * np.finfo(float).eps * max(len(names), 10) * 10  # as Spectrum.rank_threshold
    k = int(np.count_nonzero(null))
    if k == 0:
        return None
    basis = vectors[:, null]  # orthonormal, equilibrated metric
    involved = np.linalg.norm(basis, axis=1) > NULL_ROW
    parameters = tuple(names[j] for j in np.flatnonzero(involved))
    rank = len(names) - k
    if "m" in parameters or rank == 0:
        others = [q for q in parameters if q != "m"]
        drift = any(names.index(q) >= n_base for q in parameters)  # the bias's time/temperature terms
        raise FtcalError(f"the poses do not determine the mass (regressor rank {rank} of {len(names)}"
                         + (f"; it is confounded with {describe_parameters(others)}" if others else "")
                         + f"): nothing to identify; {_COVARIATE_HINT if drift else _GRAVITY_HINT}.")
    if any(names.index(q) >= n_base for q in parameters):
        drift = sorted({q.split("_", 1)[1] for q in parameters if names.index(q) >= n_base})
        raise ParameterError('bias_drift', f"the poses leave the bias's {' and '.join(drift)} coefficients undetermined (regressor rank "
                         f"{rank} of {len(names)}): {_COVARIATE_HINT}, or use {{bias_drift}} none.")
    held = _choose_held(basis, names)
    # Directions in θ units, one per held parameter: moving it by 1 and the others along.
    directions = jacobi[:, None] * basis
    directions = directions @ np.linalg.inv(directions[list(held)])
    directions[~involved] = 0.0
    held_names = tuple(names[j] for j in held)
    return Undetermined(names[:n_base], parameters, held_names, directions[:n_base], rank,
                        _undetermined_message(directions[:n_base], names[:n_base], parameters, held_names, rank))


def _choose_held(basis: np.ndarray, names: tuple[str, ...]) -> list[int]:
    """Which parameters to hold at zero, one per null direction, by :data:`_HOLD_ORDER` then largest pivot."""
    remaining = basis.copy()
    held: list[int] = []
    for _ in range(basis.shape[1]):
        for group in _HOLD_ORDER:
            candidates = [j for j, name in enumerate(names) if name in group and j not in held]
            scores = np.linalg.norm(remaining[candidates], axis=1) if candidates else np.zeros(0)
            if scores.size and scores.max() > NULL_ROW:
                # Equal pivots (e.g. COM x and z for gravity moving along (1, 0, −1)) are a tie that rounding
                # would break differently on each machine: take the first of the near-largest instead.
                j = candidates[int(np.flatnonzero(scores >= scores.max() * (1.0 - CANONICAL_TIE))[0])]
                break
        else:  # unreachable: the mass and covariates were refused, biases alone always have a pivot
            raise FtcalError("the undetermined payload parameters could not be separated.")
        held.append(j)
        row = remaining[j] / np.linalg.norm(remaining[j])
        remaining = remaining - np.outer(remaining @ row, row)
    return held


def _direction_words(u: np.ndarray) -> str:
    """A unit vector in sensor axes, in words: an axis when it is one, else its components."""
    k = int(np.argmax(np.abs(u)))
    if abs(u[k]) > 0.999:
        return f"the sensor's {'xyz'[k]} axis"
    return "the sensor direction (" + ", ".join(f"{v:.2f}" for v in canonical_sign(u)) + ")"


def _undetermined_message(directions: np.ndarray, names: tuple[str, ...], parameters: tuple[str, ...],
                          held: tuple[str, ...], rank: int) -> str:
    """What the poses do not determine and the fix, for the warning and the payload file."""
    at = names.index("Fx_bias")
    parts = []
    for c in range(directions.shape[1]):
        v = directions[:, c]
        com = v[1:4]
        if np.linalg.norm(com) > NULL_ROW and np.all(np.abs(v[at:at + 6]) <= NULL_ROW * np.abs(v).max()):
            where = _direction_words(com / np.linalg.norm(com))
            parts.append(f"the centre of mass along {where} is not determined: gravity stays parallel to it in "
                         f"every pose; tilt it by 30° or more from vertical in some poses")
        elif np.linalg.norm(com) > NULL_ROW:
            where = _direction_words(com / np.linalg.norm(com))
            involved = [names[j] for j in np.flatnonzero(np.abs(v) > NULL_ROW * np.abs(v).max()) if j >= at]
            parts.append(f"the centre of mass along {where} is confounded with the {describe_parameters(involved)}: "
                         f"gravity changes only along that direction between the poses; add poses that tilt it "
                         f"by 30° or more")
        else:
            involved = [names[j] for j in np.flatnonzero(np.abs(v) > NULL_ROW * np.abs(v).max())]
            state = "is not determined" if len(involved) == 1 else "are confounded"
            parts.append(f"{describe_parameters(involved)} {state}: {_HINTS.get(involved[0], _GRAVITY_HINT)}")
    return (f"the poses determine {rank} of {len(names)} payload parameter directions; " + "; ".join(parts)
            + f". Not determined: {describe_parameters(parameters)} (reported as undetermined; "
            f"{describe_parameters(held)} held at 0 to pick one solution, so compensation is right only in poses "
            "like the recorded ones).")


def _axis_variance(total: AxisStatistics, theta: np.ndarray, n: int, p: int) -> np.ndarray:
    """Residual variance of each axis; each axis carries n of the 6n − p residual degrees of freedom."""
    variance = total.residual_sum_of_squares(theta) / (n - p / 6)
    scale = np.array([s.target_sq[0] for s in total.axes]) / n
    return np.maximum(variance, 1e-24 * np.maximum(scale, 1.0))  # exact synthetic data: no zero weights


def robust_covariance(wgram: np.ndarray, wcross: np.ndarray, clusters: Sequence[AxisStatistics],
                      theta: np.ndarray, weights: np.ndarray, coarser: Sequence[int] = ()) -> Widened | None:
    """Grouped-jackknife covariance of θ, scaled to the t quantile of G − 1 degrees of freedom.

    ``(G − 1)/G · Σ_c (θ₋c − θ̄)(θ₋c − θ̄)ᵀ`` over the refits without each cluster
    (from the summed statistics, no pass over the data); it is the CR3
    cluster-robust estimate, less optimistic than CR1 with few clusters. With ``coarser``,
    contiguous runs of clusters are left out too and each standard error is the largest
    (:func:`~ftcal.core.jackknife.widest_covariance`): errors correlated over several clusters
    (a drift that follows the pose order) escape the finest jackknife.

    Parameters
    ----------
    wgram, wcross : weighted Gram (p, p) and cross products (p,) of all samples
    clusters : per-cluster statistics (they add up to the total), in time order
    theta : (p,) the estimate
    weights : (6,) per-axis weights of the fit
    coarser : numbers of contiguous runs of clusters to leave out as well

    Returns
    -------
    Widened, or None when fewer than two clusters can be left out
    """
    grams = [c.gram(weights) for c in clusters]
    crosses = [c.cross(weights) for c in clusters]
    partitions = []
    for edges in [np.arange(len(clusters) + 1)] + merged_partitions(len(clusters), coarser):
        refits = []
        for a, b in zip(edges[:-1], edges[1:]):
            refit = _refit(wgram - sum(grams[a:b]), wcross - sum(crosses[a:b]))
            if refit is not None:  # else this run alone identifies something: it cannot be left out
                refits.append(refit)
        partitions.append(refits)
    return widest_covariance(partitions)


def stderr_words(widened: Widened, n_clusters: int) -> str:
    """How a (widened) grouped-jackknife covariance over ``n_clusters`` blocks was made, in words."""
    if len(widened.blocks) == 1:
        return f"grouped jackknife ({n_clusters} contiguous blocks)"
    return (f"grouped jackknife ({n_clusters} contiguous blocks; each error the largest of the jackknives "
            f"over {', '.join(map(str, widened.blocks))} blocks, the mass's {widened.ratio[0]:.2f}x "
            f"from the finest to the coarsest)")


UNCERTAIN_ERROR_TEXT = "the standard error of"  # how the warning of warn_uncertain_error starts


def warn_uncertain_error(widened: Widened, what: str) -> None:
    """Say so when the error grows with the length of the blocks left out: the data cannot determine it."""
    if widened.ratio[0] > UNDETERMINED_ERROR:
        warnings.warn(IllPosedParameterWarning("bias_drift", f"{UNCERTAIN_ERROR_TEXT} {what} grows {widened.ratio[0]:.1f}x from {widened.blocks[0]} to "
                      f"{widened.blocks[-1]} contiguous blocks left out: the errors are correlated over a large part "
                      "of the recording (drift that follows the pose order, slow wander), so the recording holds "
                      f"only a few independent pieces of evidence and the error stated (the largest) is itself "
                      "uncertain; record the poses in a shuffled order, revisit early poses late, or use "
                      "{bias_drift} random-walk."), stacklevel=3)


# An equilibrated Gram above this condition number has lost a direction (float64 keeps ~16 digits).
_REFIT_CONDITION = 1e12


def _refit(gram: np.ndarray, rhs: np.ndarray) -> np.ndarray | None:
    """Least squares from a Gram and cross products; None when the Gram is numerically singular.

    The many refits of the jackknife and the held-out folds use this lighter path
    (equilibrate, condition number, solve) instead of a full spectral analysis.
    """
    diagonal = np.diag(gram)
    if np.any(diagonal <= 0):
        return None
    scale = 1.0 / np.sqrt(diagonal)
    scaled = gram * scale[:, None] * scale[None, :]
    if np.linalg.cond(scaled) > _REFIT_CONDITION:
        return None
    return scale * np.linalg.solve(scaled, rhs * scale)


def _without(total: AxisStatistics, part: AxisStatistics) -> AxisStatistics:
    """The statistics of the samples of ``total`` outside ``part``."""
    return AxisStatistics(tuple(
        SufficientStatistics(a.gram - b.gram, a.cross - b.cross, a.target_sq - b.target_sq,
                             a.target_sum - b.target_sum, a.column_maxabs, a.n_samples - b.n_samples)
        for a, b in zip(total.axes, part.axes)))


def _choose_weighting(folds: list[AxisStatistics], total: AxisStatistics, p: int) -> tuple[str, str]:
    """OLS or per-axis WLS, by held-out force and torque error over the folds (each left out in turn)."""
    if len(folds) < 2:
        return "ols", "one block only: no held-out evidence, plain least squares"
    sse = {"ols": np.zeros(6), "wls": np.zeros(6)}
    scored = 0
    for fold in folds:
        train = _without(total, fold)
        m = train.n_samples
        theta = _refit(train.gram(), train.cross())
        if theta is None or m * 6 - p < 6:
            continue
        weights = 1.0 / _axis_variance(train, theta, m, p)
        wtheta = _refit(train.gram(weights), train.cross(weights))
        if wtheta is None:
            continue
        # RMS stated to SCORE of the fold's readings' RMS per block (core.precision; SCORE² on squares): an
        # exact fit's held-out error is 0 on every CPU, not rounding noise that picks the weighting
        squares = np.array([a.target_sq[0] for a in fold.axes])
        readings = np.repeat([squares[:3].mean(), squares[3:].mean()], 3)
        readings = np.maximum(readings, max(SCORE * squares.mean(), np.finfo(float).tiny))
        for name, estimate in (("ols", theta), ("wls", wtheta)):
            sse[name] += settle(fold.residual_sum_of_squares(estimate) / readings, SCORE ** 2, 1.0) * readings
        scored += 1
    if scored < 2:
        return "ols", "too few identifiable held-out blocks: plain least squares"
    # Each axis' held-out error relative to OLS's, averaged over the force and over the torque axes
    # (a raw sum would be decided by the noisiest axis alone), and the force and torque error norms (what a
    # user measures: weights that down-weight a drifting axis can win the mean and lose the norm).
    with np.errstate(divide="ignore", invalid="ignore"):  # both 0 (exact fits): a tie
        per_axis = np.where(sse["ols"] > 0, sse["wls"] / sse["ols"], np.where(sse["wls"] > 0, np.inf, 1.0))
        norm = [_ratio(sse["wls"][k:k + 3].sum(), sse["ols"][k:k + 3].sum()) for k in (0, 3)]
    ratio = [float(np.mean(per_axis[:3])), float(np.mean(per_axis[3:]))]
    text = (f"held-out error of per-axis weighting vs plain least squares over {scored} blocks: "
            f"forces {ratio[0]:.3f}x (norm {norm[0]:.3f}x), torques {ratio[1]:.3f}x (norm {norm[1]:.3f}x)")
    # Ties (within 1 %) are no evidence; the weighting must not lose on either kind of axis, by either measure.
    if max(ratio + norm) <= 1.0 + WEIGHTING_TIE and min(ratio) < 1.0 - WEIGHTING_TIE:
        return "wls", text + " (weighting kept)"
    return "ols", text + " (plain least squares kept)"


def _ratio(a: float, b: float) -> float:
    """a / b, 1 when both are 0 (a tie), inf when only b is."""
    return float(a / b) if b > 0 else (np.inf if a > 0 else 1.0)


def model_fit(names: tuple[str, ...], theta: np.ndarray, covariance: np.ndarray, *, residual_rms: np.ndarray,
              n_samples: int, stderr_kind: str, covariates: Sequence[str] = (),
              undetermined: Undetermined | None = None) -> PayloadFit:
    """A :class:`PayloadFit` from an estimate and its covariance made elsewhere (the state-space model).

    Parameters
    ----------
    names : parameter names of θ (static, then 6 per covariate)
    theta, covariance : the estimate and its covariance
    residual_rms : (6,) per-sample residual RMS
    n_samples : number of samples
    stderr_kind : how the covariance was estimated, in words
    covariates : names of the covariates
    undetermined : what the poses do not determine (its held parameters have zero estimate and covariance)

    Returns
    -------
    PayloadFit
    """
    se = np.sqrt(np.diag(covariance))
    keep = np.flatnonzero([undetermined is None or n not in undetermined.held for n in names])
    correlation = covariance[np.ix_(keep, keep)] / se[keep, None] / se[None, keep]
    # GLS: the Gram is the inverse covariance, so VIF_j = cov_jj (cov⁻¹)_jj = (corr⁻¹)_jj.
    vif = _expand(np.diag(np.linalg.inv(correlation)), keep, len(names), np.inf)
    found = {c: (theta[10 + 6 * k:16 + 6 * k], se[10 + 6 * k:16 + 6 * k]) for k, c in enumerate(covariates)}
    return PayloadFit(names, theta, covariance, residual_rms=residual_rms, n_samples=n_samples,
                      condition_number=float(np.linalg.cond(correlation)), variance_inflation=vif,
                      poorly_excited=tuple(names[j] for j in keep if vif[j] > EXCITATION_LIMIT),
                      weighting="state-space", weighting_evidence="generalised least squares of the state-space "
                      "model (per-axis noise and walk variances by maximum likelihood)", stderr_kind=stderr_kind,
                      covariates=found, undetermined=undetermined, **_derive(names, theta, covariance, undetermined))


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
        raise ParameterError('reaction', f"the estimated mass is {fit.mass:.6g} ± {se:.2g} kg, negative: the sensor reports the "
                         "opposite sign convention (the wrench it applies on the tool); re-run with {reaction}.")
    if fit.mass <= SIGNIFICANT_STDERR * se:
        raise FtcalError(f"the estimated mass {fit.mass:.6g} ± {se:.2g} kg is not distinguishable from zero: "
                         "no payload to identify (check the wrench columns and the orientation source).")


def _derive(names: tuple[str, ...], theta: np.ndarray, cov: np.ndarray,
            undetermined: Undetermined | None = None) -> dict:
    """Mass, COM, biases, inertia about the COM and their standard errors from θ and cov(θ).

    Standard errors of what ``undetermined`` names are NaN: they have no estimate, only a convention.
    """
    se = np.sqrt(np.maximum(np.diag(cov), 0.0))
    mass, first = theta[0], theta[1:4]
    at = names.index("Fx_bias")
    bias = theta[at:at + 6]
    if mass == 0.0:
        raise FtcalError("the estimated mass is exactly zero; the centre of mass is undefined.")
    com = first / mass
    # c = (m c) / m: ∂c/∂m = −c / m, ∂c/∂(m c) = 1/m.
    jac = np.zeros((3, len(theta)))
    jac[:, 0] = -com / mass
    jac[:, 1:4] = np.eye(3) / mass
    com_se = np.sqrt(np.maximum(np.diag(jac @ cov @ jac.T), 0.0))
    out = {"mass": float(mass), "com": com, "force_bias": bias[:3], "torque_bias": bias[3:], "inertia": None,
           "stderr": {"mass": float(se[0]), "com": com_se, "force_bias": se[at:at + 3],
                      "torque_bias": se[at + 3:at + 6]}}
    if at == 10:
        def about_com(t):
            i_c = inertia_about_com(t[0], t[1:4] / t[0], inertia_matrix(t[4:10]))
            return i_c[np.triu_indices(3)]  # Ixx, Ixy, Ixz, Iyy, Iyz, Izz
        step = 1e-7 * np.maximum(np.abs(theta), 1e-3)
        jac = np.column_stack([(about_com(theta + e) - about_com(theta - e)) / (2 * e[j])
                               for j, e in enumerate(np.diag(step))])
        out["inertia"] = inertia_matrix(about_com(theta))
        out["stderr"]["inertia"] = inertia_matrix(np.sqrt(np.maximum(np.diag(jac @ cov @ jac.T), 0.0)))
    if undetermined is not None:
        fields = undetermined_fields(undetermined.parameters)
        if at == 10 and "com" in fields:  # the inertia about the COM moves with it
            fields["inertia"] = ()
        for key, index in fields.items():
            value = out["stderr"][key]
            if key == "inertia":
                out["stderr"][key] = np.full((3, 3), np.nan)
            else:
                value = np.array(value, dtype=float)
                value[list(index)] = np.nan
                out["stderr"][key] = value
    return out


_FIELDS = {"mcx": ("com", 0), "mcy": ("com", 1), "mcz": ("com", 2),
           "Fx_bias": ("force_bias", 0), "Fy_bias": ("force_bias", 1), "Fz_bias": ("force_bias", 2),
           "Tx_bias": ("torque_bias", 0), "Ty_bias": ("torque_bias", 1), "Tz_bias": ("torque_bias", 2)}


def undetermined_fields(parameters: Sequence[str]) -> dict[str, tuple[int, ...]]:
    """The payload fields (``com``, ``force_bias``, ``torque_bias``, ``inertia``) and components that
    undetermined parameters make undetermined (any inertia parameter: the whole inertia)."""
    out: dict[str, tuple[int, ...]] = {}
    for name in parameters:
        key, j = _FIELDS.get(name, ("inertia", -1))
        out[key] = tuple(sorted(set(out.get(key, ())) | ({j} if j >= 0 else set())))
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


# The old name of identify_from_statistics, which the step ftcal.identify_payload (other arguments) shadowed.
identify_payload = deprecated_alias(identify_from_statistics, "ftcal.payload.identify.identify_payload",
                                    "ftcal.payload.identify.identify_from_statistics")
