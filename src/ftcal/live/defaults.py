"""The run time's settings and the one rule for their defaults, shared by :class:`ftcal.live.LiveCalibrator`, the
C core's configuration (:mod:`ftcal.live.core`) and ``convert --to c-runtime`` (:mod:`ftcal.live.c_runtime`), so every
path starts with the same noise, walk and wander from the same payload files, and the texts the C repeats.
"""

from __future__ import annotations

import numpy as np

from ..check.accept import Thresholds
from ..payload.parameters import PayloadParameters

NO_TOOL = "none"
# What a re-tare while contact or unexplained is raised risks (its event's text and retare()'s warning; the C says it too).
RETARE_WARNING = "if a contact caused it, it becomes the bias (re-tare again free of contact)"
# Gate: a static sample whose innovation has a χ² (6 dof) beyond this quantile is a contact.
GATE_PROBABILITY = 0.999
# Unexplained wrench: beyond this many σ ...
UNEXPLAINED_SIGMA = 5.0
# ... for longer than this, s.
UNEXPLAINED_SECONDS = 0.5
# Without a payload file or an override: noise and walk standard deviations as fractions of
# ``check --accept``'s thresholds (per sample, and per √h).
DEFAULT_NOISE_FRACTION = 0.1
DEFAULT_WALK_FRACTION = 1.0
# Variance that re-taring gives the bias (in units of the noise variance): the next static samples set it.
RETARE_VARIANCE = 1e8
SECONDS_PER_HOUR = 3600.0
OUT_OF_RANGE_TEXT = "inputs outside the calibration's training range or span"


def _walk_from_file(payload: PayloadParameters) -> np.ndarray | None:
    """Walk variance per second that ``payload --bias-drift random-walk`` identified (the file's
    ``drift.random_walk``), else None.

    On the axes where the file stores a wander (``wander_variance`` > 0) and the walk fitted beside it
    (``hold_walk_variance``, :func:`ftcal.payload.drift.within_hold_noise`), that walk: the block-level fit
    assumes white block noise, so a wander slower than a block moves its block means as a walk would (a 0.25 N
    wander of τ 2 s made a 3 N/√h walk 7-10 N/√h), and a tracker that walks with the wander takes a touch into
    the bias. Files with a wander but not that walk: the share of the block-level walk a wander of variance s²
    fakes over blocks of B s, about 2 s² (1 − exp(−B/τ)) / B per s, is taken out. Both floored at a hundredth of
    the block-level walk: a walk faster than that is the self-check's to find (:mod:`ftcal.live.consistency`).
    """
    drift = payload.drift
    if drift is None or drift.model != "random-walk" or drift.walk_variance is None:
        return None
    walk = np.asarray(drift.walk_variance, dtype=float) / SECONDS_PER_HOUR
    if drift.wander_variance is not None and drift.wander_tau is not None:
        wander = np.asarray(drift.wander_variance, float)
        if drift.hold_walk_variance is not None:
            beside = np.asarray(drift.hold_walk_variance, float) / SECONDS_PER_HOUR
            return np.where(wander > 0, np.maximum(beside, 0.01 * walk), walk)
        if drift.block_seconds:
            tau = np.asarray(drift.wander_tau, float)
            block = float(drift.block_seconds)
            apparent = np.where(tau > 0, 2.0 * wander * -np.expm1(-block / np.where(tau > 0, tau, 1.0)) / block, 0.0)
            walk = np.maximum(walk - apparent, 0.01 * walk)
    return walk


def _noise_from_file(payload: PayloadParameters) -> np.ndarray | None:
    """Per-sample noise variance the tracker sees, from what ``payload --bias-drift random-walk`` stored, else None.

    ``sample_variance`` when the file has it: white noise plus the wander, fitted to the within-hold
    variogram at the sample rate (:func:`ftcal.payload.drift.within_hold_noise`). The block-mean noise
    times the block's sample count is exact for white noise only: a wander slower than a sample makes it
    too small when the blocks follow the wander (a real sensor: 5-17x below the residual) and too large
    when they average it (a 0.25 N wander of τ 2 s in 1-s blocks: up to 0.6 N). Files written before
    ``sample_variance``: the larger of it and the fit's residual RMS² (which holds the wander too).
    """
    drift = payload.drift
    if drift is None or drift.model != "random-walk" or drift.noise_variance is None:
        return None
    if drift.sample_variance is not None:
        return np.asarray(drift.sample_variance, dtype=float)
    shown = np.asarray(payload.fit["residual_rms"], float) ** 2 if "residual_rms" in payload.fit else np.zeros(6)
    return np.maximum(np.asarray(drift.noise_variance, dtype=float), shown)


def tracker_defaults(payloads, thresholds: Thresholds | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The bias tracker's default noise variance r (per sample) and walk variance q (per s): the one rule every
    path uses (:class:`LiveCalibrator` and ``convert --to c-runtime``, :func:`ftcal.live.c_runtime.runtime_parameters`).

    r: from the first payload whose random-walk drift stores a noise (:func:`_noise_from_file`: the
    per-sample variance the data show within the holds), else the first one's ``fit.residual_rms``², else
    (:data:`DEFAULT_NOISE_FRACTION` × the acceptance thresholds)². q: the first stored walk variance, else an
    older random-walk file's knot trajectory, else (:data:`DEFAULT_WALK_FRACTION` × the thresholds)² per h.

    Parameters
    ----------
    payloads : iterable of PayloadParameters (None entries are skipped), in library order
    thresholds : ``check --accept``'s (default 1 N, 0.1 N·m)

    Returns
    -------
    (noise variance (6,), walk variance per s (6,))
    """
    thresholds = thresholds or Thresholds()
    scale = np.repeat([thresholds.force, thresholds.torque], 3)
    files = [p for p in payloads if p is not None]
    noise = next((v for v in map(_noise_from_file, files) if v is not None), None)
    if noise is None:
        noise = next((np.asarray(p.fit["residual_rms"], float) ** 2 for p in files if "residual_rms" in p.fit),
                     (DEFAULT_NOISE_FRACTION * scale) ** 2)
    walk = next((w for w in [*map(_walk_from_file, files), *map(_walk_from_knots, files)] if w is not None),
                (DEFAULT_WALK_FRACTION * scale) ** 2 / SECONDS_PER_HOUR)
    return np.maximum(np.asarray(noise, float), 1e-24), np.asarray(walk, float)


def _wander_from_file(payload: PayloadParameters) -> np.ndarray | None:
    """The wander's low-frequency density ``2 s² τ`` (N²·s, (N·m)²·s) a random-walk payload file stores
    (``wander_variance``, ``wander_tau``: :func:`ftcal.payload.drift.within_hold_noise`), else None."""
    drift = payload.drift
    if drift is None or drift.model != "random-walk" or drift.wander_variance is None or drift.wander_tau is None:
        return None
    return 2.0 * np.asarray(drift.wander_variance, float) * np.asarray(drift.wander_tau, float)


def tracker_wander(payloads) -> np.ndarray:
    """The tracker's default wander density ``D`` (N²·s per axis; the update takes ``r + D / Δt``), by the rule of
    :func:`tracker_defaults`: the first payload whose random-walk drift stores a wander, else zero (white noise).

    Parameters
    ----------
    payloads : iterable of PayloadParameters (None entries are skipped), in library order

    Returns
    -------
    ndarray of shape (6,)
    """
    files = [p for p in payloads if p is not None]
    found = next((v for v in map(_noise_from_file, files) if v is not None), None)
    if found is None:  # the noise came from elsewhere: no wander goes with it
        return np.zeros(6)
    first = next(p for p in files if _noise_from_file(p) is not None)
    density = _wander_from_file(first)
    return np.zeros(6) if density is None else np.maximum(density, 0.0)


def _walk_from_knots(payload: PayloadParameters) -> np.ndarray | None:
    """Walk variance per second from a random-walk payload's bias trajectory (its quadratic variation), for
    files written before the payload file stored the walk variance.

    The trajectory is the offline smoother's, which is smoother than the walk itself, so this
    underestimates the walk; it is the default only when no walk is given.
    """
    drift = payload.drift
    if drift is None or drift.model != "random-walk" or drift.knot_times is None or len(drift.knot_times) < 3:
        return None
    steps = np.diff(drift.knot_bias, axis=0)
    duration = float(drift.knot_times[-1] - drift.knot_times[0])
    return np.sum(steps ** 2, axis=0) / duration if duration > 0 else None
