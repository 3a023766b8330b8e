"""A sensor bias that drifts during the recording: affine in time, or a random walk.

Two time models join the constant bias of :mod:`ftcal.payload.identify`:

* ``linear``: the bias is affine in time (and optionally in temperature). These
  are six extra regressor columns per covariate, fitted exactly by least squares
  on the per-axis statistics (:func:`covariates`, then ``identify_from_statistics``).
* ``random-walk``: the six biases are independent random walks, estimated jointly
  with the mass and first moment as a linear-Gaussian state-space model. The fit
  runs on **per-block averages**: the recording is cut into at most
  :data:`~ftcal.core.limits.DRIFT_BLOCKS` contiguous blocks of equal sample
  count, and each block's mean wrench, gravity and time is one observation.
  The regressor is affine in gravity, so block means lose nothing of the static
  part; the walk is resolved to one block. Cost O(N) for the averages, then
  O(blocks) per likelihood, memory O(blocks).

  State-space model, axis j, block k::

      y_kj = X_kj β + d_kj + v_kj,   d_(k+1)j = d_kj + w_kj,   d_1j = 0
      v_kj ~ N(0, r_j n̄ / n_k),      w_kj ~ N(0, q_j Δt_k)

  β = [m, m·c, bias at the first block, temperature coefficients] enters as
  constant states (the augmented Kalman filter of de Jong 1991): one scalar
  filter per axis runs over the data column and every regressor column, and
  generalised least squares on its innovations gives β, its covariance and the
  likelihood. The walk-to-noise ratio q_j / r_j of each axis is chosen by
  restricted maximum likelihood on a grid (r_j concentrated out), then β is
  estimated jointly over the six axes: the standard errors of mass and centre
  of mass come from this model. A Rauch–Tung–Striebel smoother gives the bias
  trajectory.

``auto`` compares the three models by BIC on the block averages and takes a
richer model only when it wins by more than :data:`BIC_MARGIN` (strong
evidence); otherwise the simpler one.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..runtime.errors import FtcalError, ParameterError
from .regressor import STATIC_PARAMETERS

SECONDS_PER_HOUR = 3600.0
# A richer bias model must lower the BIC by more than this ("very strong" evidence, Kass & Raftery).
BIC_MARGIN = 10.0
# Knots of a random-walk trajectory kept in the payload file.
MAX_KNOTS = 500
_GRID = 25  # walk-to-noise ratios tried per axis, log-spaced (then refined once)
# A block moves when its gravity's spread (RMS about its mean) exceeds this fraction of |g| (about 0.06°).
MOVING_SPREAD = 1e-3
# Smallest residual sum of squares of an axis, relative to its innovations' (rounding level, with margin).
RSS_FLOOR = 1e-10


@dataclass(frozen=True)
class BiasDrift:
    """How the bias moves, as stored in the payload file and applied by compensation.

    Attributes
    ----------
    model : {"none", "linear", "random-walk"}
    time_column : str or None
        The data's time column (s) the knots refer to.
    time_start, time_end : float or None
        The identification recording's first and last time, s.
    knot_times : ndarray of shape (K,) or None
        Times of the bias trajectory, s; between knots the bias is interpolated
        linearly (exact for ``linear``), outside ``[time_start, time_end]`` the
        nearest end is held.
    knot_bias : ndarray of shape (K, 6) or None
        The bias at the knots, N and N·m, at the reference temperature.
    temperature_column : str or None
    temperature_reference : float or None
    temperature_coefficients : ndarray of shape (6,) or None
        Bias change per unit of temperature.
    selection : str
        Why this model (``auto``), in words.
    walk_variance : ndarray of shape (6,) or None
        ``random-walk``: the walk's variance per hour (N²/h, (N·m)²/h), as identified; the live
        calibrator's bias tracker (:mod:`ftcal.live.tracker`) reads it.
    noise_variance : ndarray of shape (6,) or None
        ``random-walk``: the per-sample noise variance (N², (N·m)²): the identified variance of a time
        block's mean times the block's mean sample count (exact for white noise).
    block_samples : float or None
        ``random-walk``: the time blocks' mean sample count.
    sample_variance : ndarray of shape (6,) or None
        ``random-walk``: the per-sample variance about the bias within the still holds (N², (N·m)²): white
        noise plus a Gauss-Markov wander fitted to the holds (:func:`within_hold_noise`), what
        the live tracker sees at its update rate. None in files written before it (as are the next four).
    wander_variance, wander_tau : ndarray of shape (6,) or None
        ``random-walk``: that wander's variance and time constant (s).
    block_seconds, hold_seconds : float or None
        ``random-walk``: the time blocks' mean length, s, and the mean length of the still holds
        ``sample_variance`` was measured on, s.
    hold_walk_variance : ndarray of shape (6,) or None
        ``random-walk``: the walk's variance per hour fitted beside the white noise and the wander to the holds
        (:func:`within_hold_noise`: within them and between their means); ``walk_variance``, fitted on block
        means with white block noise, also holds a wander slower than a block. None in older files.
    """

    model: str = "none"
    time_column: str | None = None
    time_start: float | None = None
    time_end: float | None = None
    knot_times: np.ndarray | None = None
    knot_bias: np.ndarray | None = None
    temperature_column: str | None = None
    temperature_reference: float | None = None
    temperature_coefficients: np.ndarray | None = None
    selection: str = ""
    walk_variance: np.ndarray | None = None
    noise_variance: np.ndarray | None = None
    block_samples: float | None = None
    sample_variance: np.ndarray | None = None
    wander_variance: np.ndarray | None = None
    wander_tau: np.ndarray | None = None
    block_seconds: float | None = None
    hold_seconds: float | None = None
    hold_walk_variance: np.ndarray | None = None

    def bias(self, constant: np.ndarray, time: np.ndarray | None, temperature: np.ndarray | None,
             source: str = "data") -> np.ndarray:
        """The bias of every sample, shape (N, 6).

        Parameters
        ----------
        constant : (6,) the bias to use without knots (time-free models)
        time : (N,) s, needed when there are knots
        temperature : (N,), needed with temperature coefficients
        source : names the data in the warning

        Warns
        -----
        OutOfRangeWarning
            Once, when samples lie outside the identification recording (the nearest end is held).
        """
        import warnings

        from ..runtime.errors import OutOfRangeWarning

        n = len(time) if time is not None else len(temperature) if temperature is not None else 0
        out = np.broadcast_to(np.asarray(constant, dtype=float), (n, 6)).copy()
        if self.knot_times is not None:
            out = np.column_stack([np.interp(time, self.knot_times, self.knot_bias[:, j]) for j in range(6)])
            outside = int(np.count_nonzero((time < self.time_start) | (time > self.time_end)))
            if outside:
                warnings.warn(f"{source}: {outside} sample(s) lie outside the identification recording "
                              f"({self.time_column} {self.time_start:g} to {self.time_end:g} s); the bias "
                              "there is held at the nearest end of its trajectory.", OutOfRangeWarning, stacklevel=2)
        if self.temperature_coefficients is not None:
            out += np.outer(temperature - self.temperature_reference, self.temperature_coefficients)
        return out


def check_time(time: np.ndarray, column: str, source: str) -> None:
    """Refuse a time column that does not strictly increase.

    Raises
    ------
    FtcalError
        Naming the file, the column and the first offending row.
    """
    from ..data.holds import check_seconds

    steps = np.diff(time)
    bad = np.flatnonzero(~(steps > 0))
    if bad.size:
        raise FtcalError(f"{source}: time column {column!r} does not increase at row {bad[0] + 1} "
                         f"({float(time[bad[0]]):g} then {float(time[bad[0] + 1]):g}); sort the rows by time.")
    check_seconds(np.asarray(time, dtype=float), column, source)


def check_temperature(temperature: np.ndarray, column: str) -> None:
    """Refuse a constant temperature column (no temperature coefficient can be fitted)."""
    if np.ptp(temperature) == 0.0:
        raise ParameterError("temperature", f"{{temperature}} {column}: the column is constant ({temperature[0]:g}); "
                             "the bias cannot be fitted against it (leave {temperature} out).")


def covariates(hours: np.ndarray | None, temperature: np.ndarray | None) -> tuple[np.ndarray | None, tuple[str, ...]]:
    """Covariate columns of the bias and their names (``time`` in h, ``temperature`` about its mean).

    Returns
    -------
    (ndarray of shape (n_samples, k) or None, names)
    """
    cols, names = [], []
    if hours is not None:
        cols.append(hours)
        names.append("time")
    if temperature is not None:
        cols.append(temperature)
        names.append("temperature")
    return (np.column_stack(cols) if cols else None), tuple(names)


@dataclass(frozen=True)
class Blocks:
    """Per-block averages of a recording (contiguous, equal sample counts up to one)."""

    hours: np.ndarray  # (B,) mean time since the first sample, h
    count: np.ndarray  # (B,)
    gravity: np.ndarray  # (B, 3)
    wrench: np.ndarray  # (B, 6)
    temperature: np.ndarray | None  # (B,) about the recording's mean, or None
    moving: np.ndarray | None = None  # (B,) bool: gravity turns within the block (a move, or a hold's edge)
    starts: np.ndarray | None = None  # (B,) first sample of each block

    def of_samples(self, n_samples: int) -> np.ndarray:
        """The block of each sample, shape (n_samples,)."""
        return np.searchsorted(self.starts, np.arange(n_samples), side="right") - 1

    def observed(self) -> np.ndarray:
        """Blocks the state-space models fit (the others only carry the walk across): the still ones.

        A block whose gravity turns inside it mixes a move (sensor lag, dynamics, a clock offset between
        the wrench and the orientation) into one observation, and a walk that follows the bias from block
        to block takes its mass from exactly those changes: a lag of a tenth of a second biased the mass
        by several standard errors in simulation. When fewer than a fifth of the blocks are still (a recording
        without holds), all are used.
        """
        if self.moving is None or 5 * np.count_nonzero(~self.moving) < len(self.moving):
            return np.ones(len(self.count), bool)
        return ~self.moving


def block_means(hours: np.ndarray, gravity: np.ndarray, wrench: np.ndarray, temperature: np.ndarray | None = None,
                max_blocks: int | None = None) -> Blocks:
    """Average a recording over at most ``max_blocks`` contiguous blocks of equal sample count.

    A block lasts at least :data:`~ftcal.core.limits.DRIFT_BLOCK_SECONDS` (at the
    median sampling interval): noise correlated over less than that averages out
    inside a block, slower wandering is drift.

    Parameters
    ----------
    hours : (N,) time since the first sample, h, increasing
    gravity : (N, 3) gravity in sensor axes, m/s²
    wrench : (N, 6) readings, N and N·m
    temperature : (N,) or None, about its mean
    max_blocks : default :data:`~ftcal.core.limits.DRIFT_BLOCKS`

    Returns
    -------
    Blocks
    """
    from ..core.limits import DRIFT_BLOCK_SECONDS, DRIFT_BLOCKS

    n = len(hours)
    step = float(np.median(np.diff(hours))) * SECONDS_PER_HOUR if n > 1 else 1.0
    per_block = max(1, int(np.ceil(DRIFT_BLOCK_SECONDS / step)) if step > 0 else 1)
    b = max(1, min(n // per_block, max_blocks or DRIFT_BLOCKS))
    starts = np.linspace(0, n, b + 1).astype(np.int64)[:-1]
    count = np.diff(np.r_[starts, n]).astype(float)

    def mean(a):
        return np.add.reduceat(a, starts, axis=0) / (count if a.ndim == 1 else count[:, None])

    mean_gravity = mean(gravity)
    spread = np.sqrt(np.maximum(np.sum(mean(gravity ** 2) - mean_gravity ** 2, axis=1), 0.0))
    scale = float(np.median(np.linalg.norm(mean_gravity, axis=1))) if n else 0.0
    # Turning beyond the still blocks' own spread (sensor noise in an IMU's gravity) and beyond ~0.06°.
    turning = spread > max(MOVING_SPREAD * scale, 4.0 * float(np.median(spread)) if n else 0.0)
    # The blocks beside a turn too: a sensor's filter or a clock offset carries the move into them.
    moving = turning.copy()
    moving[1:] |= turning[:-1]
    moving[:-1] |= turning[1:]
    return Blocks(mean(hours), count, mean_gravity, mean(wrench), None if temperature is None else mean(temperature),
                  moving, starts)


@dataclass(frozen=True)
class HoldNoise:
    """The noise of the still holds at the sample rate (:func:`within_hold_noise`), per axis.

    Attributes
    ----------
    white : (6,) white (and quantisation) variance per sample
    wander : (6,) variance of a first-order Gauss-Markov wander
    tau : (6,) its time constant, s
    walk : (6,) walk variance per hour fitted beside the wander (within the holds and between their means)
    hold_seconds : mean length of the holds, s
    spread : (6,) variance about each hold's mean (walk and wander within the hold included)
    """

    white: np.ndarray
    wander: np.ndarray
    tau: np.ndarray
    walk: np.ndarray
    hold_seconds: float
    spread: np.ndarray

    @property
    def sample_variance(self) -> np.ndarray:
        """What the live tracker's innovations see per sample about the bias: white + wander; where the wander
        dominates, never less than the plain variance about the holds' means (a hold a few τ long hides part of
        the wander's plateau from the variogram, whose fit then gives it to the walk). Not where white noise
        dominates: there the spread holds the walk within a hold, and an r that large makes the tracker lag."""
        return np.where(self.wander > self.white, np.maximum(self.white + self.wander, self.spread),
                        self.white + self.wander)


def _nonnegative_least_squares(a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, float]:
    """``min ‖a x − b‖`` over ``x ≥ 0`` for a few columns, exactly, by trying every support.

    The optimum is the unconstrained least-squares solution on its own support (KKT), so the best
    non-negative one among the ``2^p − 1`` supports is it; for the variogram's three columns that is
    seven small solves, and ``ftcal payload`` keeps away from SciPy's import.

    Returns
    -------
    (x, residual norm), as ``scipy.optimize.nnls`` returns them
    """
    p = a.shape[1]
    best = (np.zeros(p), float(np.linalg.norm(b)))
    for mask in range(1, 2 ** p):
        support = [k for k in range(p) if mask >> k & 1]
        x_s = np.linalg.lstsq(a[:, support], b, rcond=None)[0]
        if np.all(x_s >= 0.0):
            x = np.zeros(p)
            x[support] = x_s
            norm = float(np.linalg.norm(a @ x - b))
            if norm < best[1]:
                best = (x, norm)
    return best


# Hold pairs whose means the wander fit compares: each hold with up to this many following holds (O(holds) work).
PAIR_NEIGHBOURS = 64
# The within-hold fit keeps a wander only when white noise plus a walk fail its χ² test at this probability.
WANDER_PROBABILITY = 0.999
_TAU_GRID = 31  # wander time constants tried, log-spaced from one sample to the median hold


def _chi2_quantile(probability: float, dof: int) -> float:
    """χ² quantile by the Wilson-Hilferty cube (Johnson, Kotz & Balakrishnan 1994, eq. 18.24); ``payload`` keeps
    away from SciPy's import. Within 1 % of the exact one from 10 degrees of freedom at 0.999."""
    from statistics import NormalDist

    z = NormalDist().inv_cdf(probability)
    k = max(int(dof), 1)
    return float(k * (1.0 - 2.0 / (9.0 * k) + z * np.sqrt(2.0 / (9.0 * k))) ** 3)


def _mean_variance(length: np.ndarray, tau: float) -> np.ndarray:
    """Variance of the mean over ``length`` s of a unit-variance first-order Gauss-Markov process."""
    x = length / tau
    return 2.0 * (x - 1.0 + np.exp(-x)) / np.maximum(x * x, 1e-300)


def within_hold_noise(residual: np.ndarray, time_s: np.ndarray, blocks: Blocks) -> HoldNoise | None:
    """White noise, a Gauss-Markov wander and a walk fitted to the holds: within them and between their means.

    A hold is a run of contiguous still blocks (:meth:`Blocks.observed`), split where the time steps
    by more than twice the median step (a recording of holds only). Per axis, with white noise of
    variance ``w`` per sample, a first-order Gauss-Markov wander of variance ``s²`` and time constant τ,
    and a random walk of variance ``q`` per s, two sets of moments are fitted together:

    * the empirical semivariogram within the holds, ``γ(L) = ½ mean (x_(i+L) − x_i)²`` at lags of 1, 2,
      4, ... samples (up to half the median hold)::

          γ(L) = w + s² (1 − exp(−L Δ / τ)) + q L Δ / 2

    * the semivariance of the means of two holds i < j (lengths T, gap G between them), averaged over
      pairs in log-spaced bins of G::

          ½ E (m_j − m_i)² = w (1/n_i + 1/n_j) / 2 + s² (V(T_i) + V(T_j) − 2 C_ij) / 2
                             + q (T_i / 3 + T_j / 3 + G) / 2

      with ``V(T) = 2 (τ/T)² (T/τ − 1 + exp(−T/τ))`` the variance of a T-long mean of the unit wander
      and ``C_ij = τ² / (T_i T_j) (1 − exp(−T_i/τ)) (1 − exp(−T_j/τ)) exp(−G/τ)`` the two means' covariance.

    Holds a few τ long cannot tell a wander from a walk by their variogram alone (its curvature is all
    that differs); between holds the wander's share stops growing after a few τ and the walk's keeps
    growing with the gap, which separates them -- the variance of means against averaging time and
    separation that the Allan variance uses (IEEE Std 952-1997, Annex C) and the Gauss-Markov and walk
    autocovariances of Gelb, *Applied Optimal Estimation* (1974), table 4.4-1. The model is linear in
    ``(w, s², q)`` for a given τ: non-negative least squares (relative errors) on a log grid of τ up to the
    median hold's length (a slower wander is drift: one recording cannot tell it from a walk).

    Parameters
    ----------
    residual : (N, 6) readings minus the identified static wrench (the bias trajectory not removed)
    time_s : (N,) time, s
    blocks : the recording's time blocks

    Returns
    -------
    HoldNoise, or None when no hold has 8 samples
    """
    observed = blocks.observed()
    ends = np.r_[blocks.starts[1:], residual.shape[0]]
    edges = np.flatnonzero(np.diff(np.r_[0, observed.astype(np.int8), 0]))
    step = float(np.median(np.diff(time_s))) if len(time_s) > 1 else 0.0
    holds = []
    for a, b in zip(edges[::2], edges[1::2]):
        lo, hi = int(blocks.starts[a]), int(ends[b - 1])
        gaps = lo + 1 + np.flatnonzero(np.diff(time_s[lo:hi]) > 2.0 * step)
        cuts = np.r_[lo, gaps, hi]
        holds += [(c, d) for c, d in zip(cuts[:-1], cuts[1:]) if d - c >= 8]
    if not holds or not step > 0:
        return None
    squares, dof = np.zeros(6), 0
    for c, d in holds:  # the plain within-hold variance about each hold's mean: what the data show at least
        part = residual[c:d] - residual[c:d].mean(axis=0)
        squares += np.einsum("ij,ij->j", part, part)
        dof += d - c - 1
    spread = squares / dof
    lengths = np.array([d - c for c, d in holds])
    longest = int(np.median(lengths)) // 2
    lags = 2 ** np.arange(int(np.log2(max(longest, 1))) + 1)
    gamma = np.zeros((len(lags), 6))
    counts = np.zeros(len(lags))
    for i, lag in enumerate(lags):
        total, count = np.zeros(6), 0
        for c, d in holds:
            if d - c > lag:
                diff = residual[c + lag:d] - residual[c:d - lag]
                total += np.einsum("ij,ij->j", diff, diff)
                count += diff.shape[0]
        gamma[i] = 0.5 * total / max(count, 1)
        counts[i] = max(count, 1)
    lag_s = lags * step
    # Rows weighted by their relative standard errors, about sqrt(2 L / M) for M differences at lag L (the
    # differences are correlated over about L samples), sqrt(2 / n) for a bin of n roughly independent pairs
    precision = np.sqrt(counts / (2.0 * lags))
    pairs = _hold_pairs(residual, time_s, holds, step)
    if pairs is not None:
        precision = np.r_[precision, np.sqrt(pairs[4] / 2.0)]
    best, plain = [None] * 6, [None] * 6
    # τ up to the median hold: a wander slower than a hold moves the bias from hold to hold as a walk does, and
    # over one recording the two cannot be told apart (a walk's semivariance levels off by chance); it is drift.
    for tau in np.geomspace(step, max(float(np.median(lengths)) * step, 2.0 * step), _TAU_GRID):
        design = np.column_stack([np.ones(len(lags)), 1.0 - np.exp(-lag_s / tau), lag_s / 2.0])
        target = gamma
        if pairs is not None:
            white, wander_of, walk, semi, _ = pairs
            design = np.vstack([design, np.column_stack([white, wander_of(tau), walk])])
            target = np.vstack([gamma, semi])
        for j in range(6):
            weight = precision / np.maximum(target[:, j], 1e-300)
            coef, error = _nonnegative_least_squares(design * weight[:, None], target[:, j] * weight)
            if best[j] is None or error < best[j][0] - 1e-12:
                best[j] = (error, coef, tau)
            if plain[j] is None:  # white noise and walk only (the wander's column unused: τ plays no part)
                plain[j] = _nonnegative_least_squares((design * weight[:, None])[:, [0, 2]], target[:, j] * weight)
    # A wander only where white noise and a walk alone are rejected: the weighted residual is about χ² with
    # rows − 2 degrees of freedom (a hold's own walk makes a wander of τ near the hold look 2-6 χ² units better).
    limit = _chi2_quantile(WANDER_PROBABILITY, len(target) - 2)
    for j in range(6):
        if plain[j][1] ** 2 <= limit:
            best[j] = (plain[j][1], np.array([plain[j][0][0], 0.0, plain[j][0][1]]), 0.0)
    white = np.array([b[1][0] for b in best])
    wander = np.array([b[1][1] for b in best])
    tau = np.array([b[2] if b[1][1] > 0 else 0.0 for b in best])
    walk = np.array([b[1][2] for b in best]) * SECONDS_PER_HOUR
    return HoldNoise(white, wander, tau, walk, float(np.mean(lengths)) * step, spread)


def _hold_pairs(residual, time_s, holds, step):
    """The hold-mean rows of :func:`within_hold_noise`: per bin of gaps, the mean of the white and walk design
    columns, a function of τ giving the wander's, the mean semivariance (B, 6) and the bin's independent pairs
    (its pairs, at most the recording's span over the bin's mean gap and hold: a walk correlates pairs that
    overlap); None for fewer than 3 holds."""
    if len(holds) < 3:
        return None
    means = np.array([residual[c:d].mean(axis=0) for c, d in holds])
    count = np.array([d - c for c, d in holds], float)
    seconds = count * step
    first = np.array([time_s[c] for c, _ in holds])
    last = np.array([time_s[d - 1] for _, d in holds]) + step
    i, j = [], []
    for k in range(1, min(PAIR_NEIGHBOURS, len(holds) - 1) + 1):
        i.append(np.arange(len(holds) - k))
        j.append(np.arange(k, len(holds)))
    i, j = np.concatenate(i), np.concatenate(j)
    gap = np.maximum(first[j] - last[i], 0.0)
    edges = np.unique(np.geomspace(max(gap.min(), step), gap.max() + step, 13))
    which = np.clip(np.searchsorted(edges, gap, side="right") - 1, 0, len(edges) - 2)
    used, size = np.unique(which, return_counts=True)
    used = used[size >= 3]  # a bin of one or two pairs says little
    if used.size == 0:
        return None
    keep = np.isin(which, used)
    i, j, gap, which = i[keep], j[keep], gap[keep], which[keep]
    at = np.searchsorted(used, which)
    size = np.bincount(at, minlength=len(used)).astype(float)

    def members(values):  # the mean over each bin's pairs (of a column, or of each of several)
        if values.ndim == 2:
            return np.column_stack([members(v) for v in values.T])
        return np.bincount(at, weights=values, minlength=len(used)) / size

    semi = members(0.5 * (means[j] - means[i]) ** 2)
    white = members(0.5 * (1.0 / count[i] + 1.0 / count[j]))
    walk = members(0.5 * (seconds[i] / 3.0 + seconds[j] / 3.0 + gap))

    def wander_of(tau):
        both = (tau * tau / (seconds[i] * seconds[j]) * -np.expm1(-seconds[i] / tau) * -np.expm1(-seconds[j] / tau)
                * np.exp(-gap / tau))
        return members(0.5 * (_mean_variance(seconds[i], tau) + _mean_variance(seconds[j], tau)) - both)

    span = float(last[-1] - first[0])
    independent = np.minimum(size, span / members(gap + 0.5 * (seconds[i] + seconds[j])))
    return white, wander_of, walk, semi, np.maximum(independent, 1.0)


def beside_wander(fit: StateSpaceFit, blocks: Blocks, within: HoldNoise, temperature: bool) -> np.ndarray:
    """The random-walk fit's bias trajectory smoothed again where the holds show a wander: with the walk fitted
    beside it (:attr:`HoldNoise.walk`) and a block-mean noise that holds it (``w / n + s² V(B)``, V the variance of
    a B-s mean of the unit wander), so that the bias does not follow the wander (it is noise, not bias: a bias
    following it takes a second-long touch in too). β stays the fit's. Axes without a wander keep theirs.

    Returns
    -------
    ndarray of shape (B, 6)
    """
    wander = within.wander > 0
    if fit.kind != "random-walk" or not np.any(wander):
        return fit.trajectory
    x = _design(blocks, False, temperature)
    steps = np.r_[0.0, np.diff(blocks.hours)]
    noise = blocks.count.mean() / blocks.count
    observed = blocks.observed()
    if np.count_nonzero(observed) <= 10:
        observed = np.ones(len(blocks.count), bool)
    seconds = float(np.mean(np.diff(blocks.hours))) * SECONDS_PER_HOUR if len(blocks.hours) > 1 else 1.0
    tau = np.where(within.tau > 0, within.tau, 1.0)
    block_noise = within.white / blocks.count.mean() + within.wander * _mean_variance(np.full(6, seconds), tau)
    block_noise = np.maximum(block_noise, fit.noise_variance)  # never below what the block means showed
    ratio = np.where(wander, within.walk / np.maximum(block_noise, 1e-300), fit.walk_variance / fit.noise_variance)
    ratio = np.maximum(ratio, 1e-12)  # a walk, however slow (the smoother's p stays positive)
    trajectory, _ = _smooth(fit.theta, x, blocks, ratio, steps, noise, False, observed)
    return np.where(wander[None], trajectory, fit.trajectory)


def _design(blocks: Blocks, slope: bool, temperature: bool) -> np.ndarray:
    """X of shape (B, 6, P): static regressor at the block's mean gravity plus covariate columns."""
    from .accumulate import _static_maps

    g1 = np.c_[blocks.gravity, np.ones(len(blocks.count))]
    static = np.einsum("jpi,bi->bjp", _static_maps(), g1)  # (B, 6, 10)
    extra = ([blocks.hours] if slope else []) + ([blocks.temperature] if temperature else [])
    x = np.zeros((len(blocks.count), 6, 10 + 6 * len(extra)))
    x[:, :, :10] = static
    for c, column in enumerate(extra):
        x[:, np.arange(6), 10 + 6 * c + np.arange(6)] = column[:, None]
    return x


def _axis_columns(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Columns of β each axis sees, padded to one width; the pad marks unused slots.

    Returns
    -------
    index : (6, c) int, column of β (0 where padded)
    pad : (6, c) bool
    """
    used = [np.flatnonzero(np.any(x[:, j, :] != 0.0, axis=0)) for j in range(6)]
    width = max(len(u) for u in used)
    index = np.zeros((6, width), np.int64)
    pad = np.ones((6, width), bool)
    for j, u in enumerate(used):
        index[j, :len(u)], pad[j, :len(u)] = u, False
    return index, pad


def _filter(ratio: np.ndarray, steps: np.ndarray, noise: np.ndarray, data: np.ndarray, pad: np.ndarray,
            observed: np.ndarray | None = None):
    """Augmented scalar Kalman filter of d (walk since the first block), r = 1 units.

    Parameters
    ----------
    ratio : (L, 6) walk variance per hour over noise variance, per trial and axis
    steps : (B,) hours between blocks (0 before the first)
    noise : (B,) relative noise variance of each block mean (n̄ / n_k)
    data : (B, 6, 1 + c) the data column then the axis' regressor columns
    pad : (6, c) padded regressor slots
    observed : (B,) or (L, B) bool, or None (all): unobserved blocks only carry the walk forward

    Returns
    -------
    log_f : (L, 6) Σ log F_k
    cross : (L, 6, 1 + c, 1 + c) Σ E Eᵀ / F over the innovations E = [e_y, e_x]
    """
    shape = ratio.shape
    width = data.shape[2]
    p = np.zeros(shape)
    state = np.zeros(shape + (width,))
    log_f = np.zeros(shape)
    cross = np.zeros(shape + (width, width))
    if observed is None:
        observed = np.ones(data.shape[0], bool)
    seen = np.broadcast_to(observed, shape[:1] + (data.shape[0],)).astype(float)  # (L, B)
    if not np.any(ratio):  # no walk: the state stays 0 and F = noise, so the sums need no recursion
        weight = seen / noise[None]  # (L, B)
        cross = np.broadcast_to(np.einsum("lb,bjc,bjd->ljcd", weight, data, data), shape + (width, width)).copy()
        log_f = np.broadcast_to((seen @ np.log(noise))[:, None], shape).copy()
        cross[..., 1:, 1:] += np.einsum("jc,cd->jcd", pad.astype(float), np.eye(width - 1))
        return log_f, cross
    for k in range(data.shape[0]):
        p = p + ratio * steps[k]
        f = p + noise[k]
        e = data[k] - state
        w = seen[:, k, None]  # (L, 1)
        ef = (w / f)[..., None] * e
        cross += ef[..., :, None] * e[..., None, :]
        log_f += w * np.log(f)
        gain = w * p / f
        state = state + gain[..., None] * e
        p = p * (1.0 - gain)
    # Padded slots are all zero: a unit diagonal keeps the Gram invertible without touching the rest.
    cross[..., 1:, 1:] += np.einsum("jc,cd->jcd", pad.astype(float), np.eye(width - 1))
    return log_f, cross


def _reml(log_f: np.ndarray, cross: np.ndarray, n_columns: np.ndarray, n_blocks: int) -> np.ndarray:
    """Restricted log-likelihood (noise variance concentrated out), up to a constant, shape (L, 6)."""
    s, rhs, yy = cross[..., 1:, 1:], cross[..., 1:, 0], cross[..., 0, 0]
    beta = np.linalg.solve(s, rhs[..., None])[..., 0]
    rss = np.maximum(yy - np.einsum("...c,...c->...", rhs, beta), 1e-300)
    dof = n_blocks - n_columns
    return -0.5 * (dof * np.log(rss / dof) + log_f + np.linalg.slogdet(s)[1])


@dataclass(frozen=True)
class StateSpaceFit:
    """A bias model fitted on block averages: β, its covariance, likelihood and the bias trajectory."""

    kind: str  # "none", "linear" or "random-walk"
    names: tuple[str, ...]
    theta: np.ndarray  # (P,)
    covariance: np.ndarray  # (P, P)
    noise_variance: np.ndarray  # (6,) r_j of a block mean of n̄ samples
    walk_variance: np.ndarray  # (6,) q_j per hour (zero without a walk)
    log_likelihood: float
    n_free: int  # estimated numbers (β, noise and walk variances)
    n_observations: int
    trajectory: np.ndarray  # (B, 6) bias at each block (walk and slope, temperature excluded)
    end_stderr: np.ndarray  # (6,) standard error of the bias at the last block
    n_moving: int = 0  # blocks left out of the fit because gravity turns within them (the walk spans them)
    jackknife_stretches: int = 0  # contiguous stretches of the grouped jackknife (0: model covariance only)
    held_out: tuple = ()  # per fold: (θ (P,), trajectory (B, 6)) fitted without it, or None
    jackknife: object = None  # the jackknives over the stretches and runs of them (core.jackknife.Widened)

    @property
    def bic(self) -> float:
        return -2.0 * self.log_likelihood + self.n_free * np.log(self.n_observations)


def fit_state_space(blocks: Blocks, kind: str, temperature: bool = False, held: tuple[str, ...] = (),
                    folds: tuple[np.ndarray, ...] = ()) -> StateSpaceFit:
    """Fit one bias model to block averages: ``none`` and ``linear`` have no walk (q = 0).

    Parameters
    ----------
    blocks : Blocks
    kind : {"none", "linear", "random-walk"}
    temperature : the bias is also affine in the blocks' temperature
    held : static parameters held at zero (the poses do not determine them,
        :class:`~ftcal.payload.identify.Undetermined`); their estimate and covariance are zero
    folds : (B,) bool masks of blocks to hold out in turn (cross-validation groups): each refit
        (walk ratios and noise variances held) is in :attr:`StateSpaceFit.held_out`

    Returns
    -------
    StateSpaceFit

    Raises
    ------
    FtcalError
        Fewer blocks than unknowns, or a rank-deficient design.
    """
    full = _design(blocks, kind == "linear", temperature)
    kept = np.array([j for j in range(full.shape[2]) if j >= 10 or STATIC_PARAMETERS[j] not in held])
    x = full[:, :, kept]
    n_blocks, _, n_beta = x.shape
    index, pad = _axis_columns(x)
    n_columns = (~pad).sum(axis=1)
    if n_blocks <= n_columns.max() + (kind == "random-walk"):
        raise FtcalError(f"{n_blocks} time block(s) cannot fit the {kind} bias model; record more samples.")
    local = np.take_along_axis(x, np.broadcast_to(index, (n_blocks, 6, index.shape[1])), axis=2)
    local[:, pad] = 0.0
    data = np.concatenate([blocks.wrench[:, :, None], local], axis=2)
    steps = np.r_[0.0, np.diff(blocks.hours)]
    noise = blocks.count.mean() / blocks.count
    observed = blocks.observed()
    n_observed = int(np.count_nonzero(observed))
    if n_observed <= n_columns.max() + (kind == "random-walk"):
        observed, n_observed = np.ones(n_blocks, bool), n_blocks  # too few still blocks: every block
    if kind == "random-walk":
        ratio = _choose_ratio(blocks, steps, noise, data, pad, n_columns, observed)
    else:
        ratio = np.zeros(6)
    log_f, cross = _filter(ratio[None], steps, noise, data, pad, observed)
    log_f, cross = log_f[0], cross[0]
    s_loc, rhs_loc, yy = cross[:, 1:, 1:], cross[:, 1:, 0], cross[:, 0, 0]
    beta_loc = np.linalg.solve(s_loc, rhs_loc[..., None])[..., 0]
    # An axis whose walk follows every block (the grid's top ratio) leaves almost no residual; its noise
    # variance is floored relative to the axis's own innovations, else 1/r weighs rounding (gravity's 1e-16
    # along an axis it never loads) by 1e300 and the joint solve breaks down (a mass of -1e30 kg).
    rss = np.maximum(yy - np.einsum("jc,jc->j", rhs_loc, beta_loc), RSS_FLOOR * np.maximum(yy, 1e-300))
    r = rss / (n_observed - n_columns)  # REML noise variance of each axis
    gram, rhs = _joint_normal_equations(s_loc[None], rhs_loc[None], r, index, pad, n_beta)
    gram, rhs = gram[0], rhs[0]
    jacobi = 1.0 / np.sqrt(np.diag(gram))
    scaled = gram * jacobi[:, None] * jacobi[None, :]
    if np.linalg.matrix_rank(scaled) < n_beta:
        raise FtcalError(f"the poses and times leave the {kind} bias model undetermined; add poses that tilt "
                         "the sensor and revisit early poses late in the recording.")
    covariance = np.linalg.inv(scaled) * jacobi[:, None] * jacobi[None, :]
    covariance = 0.5 * (covariance + covariance.T)
    theta = covariance @ rhs
    stretches, widened = 0, None
    if kind == "random-walk":
        covariance, stretches, widened = _with_jackknife(covariance, theta, ratio, steps, noise, data, pad, observed, r,
                                                index, n_beta)
    # Maximum likelihood at β (noise variances re-profiled) for the BIC.
    log_lik = 0.0
    for j in range(6):
        used = ~pad[j]
        b = theta[index[j, used]]
        q = yy[j] - 2.0 * rhs_loc[j, used] @ b + b @ s_loc[j][np.ix_(used, used)] @ b
        r_ml = max(q, 1e-300) / n_observed
        log_lik += -0.5 * (n_observed * np.log(2.0 * np.pi * r_ml) + log_f[j] + n_observed)
    # Back to every parameter: the held ones are zero, without variance.
    theta_full = np.zeros(full.shape[2])
    theta_full[kept] = theta
    covariance_full = np.zeros((full.shape[2],) * 2)
    covariance_full[np.ix_(kept, kept)] = covariance
    theta, covariance, x = theta_full, covariance_full, full
    trajectory, end_var = _smooth(theta, x, blocks, ratio, steps, noise, kind == "linear", observed)
    names = STATIC_PARAMETERS + tuple(f"{a}_{c}" for c in (["time"] if kind == "linear" else [])
                                      + (["temperature"] if temperature else [])
                                      for a in ("Fx", "Fy", "Fz", "Tx", "Ty", "Tz"))
    # Bias at the last block: its filter error and β's error are uncorrelated (augmented filter).
    at_end = _end_gradient(x, ratio, steps, noise, kind, observed)
    end_se = np.sqrt(np.maximum(end_var * r + np.einsum("jp,pq,jq->j", at_end, covariance, at_end), 0.0))
    n_free = n_beta + 6 + (6 if kind == "random-walk" else 0)
    held_out = _refit_without(tuple(folds), theta.size, kept, ratio, steps, noise, data, pad, observed, r, index,
                              x, blocks, kind == "linear")
    return StateSpaceFit(kind, names, theta, covariance, r, ratio * r, float(log_lik), n_free, 6 * n_observed,
                         trajectory, end_se, n_blocks - n_observed, stretches, held_out, widened)


def _refit_without(folds, p, kept, ratio, steps, noise, data, pad, observed, r, index, x, blocks, slope):
    """Per fold, θ (all P parameters) and the smoothed bias trajectory fitted without the blocks the fold
    marks (all folds in one batched filter and smoother pass); None when the rest cannot determine θ."""
    if not folds:
        return ()
    train = observed[None] & ~np.asarray(folds)
    _, cross = _filter(np.broadcast_to(ratio, (len(train), 6)), steps, noise, data, pad, train)
    gram, rhs = _joint_normal_equations(cross[..., 1:, 1:], cross[..., 1:, 0], r, index, pad, len(kept))
    thetas = np.zeros((len(train), p))
    ok = np.zeros(len(train), bool)
    for g in range(len(train)):
        scale = 1.0 / np.sqrt(np.maximum(np.diag(gram[g]), 1e-300))
        scaled = gram[g] * scale[:, None] * scale[None, :]
        if np.any(train[g]) and np.linalg.cond(scaled) <= 1e12:
            thetas[g, kept] = scale * np.linalg.solve(scaled, rhs[g] * scale)
            ok[g] = True
    trajectories, _ = _smooth(thetas, x, blocks, ratio, steps, noise, slope, train)
    return tuple((thetas[g], trajectories[g]) if ok[g] else None for g in range(len(train)))


def _joint_normal_equations(s_loc, rhs_loc, r, index, pad, n_beta):
    """GLS normal equations over the six axes (they share the mass and first moment), for L refits at once.

    ``s_loc`` (L, 6, c, c) and ``rhs_loc`` (L, 6, c) per axis, ``r`` (6,) noise variances; returns
    the Gram (L, P, P) and right-hand side (L, P).
    """
    n = s_loc.shape[0]
    gram = np.zeros((n, n_beta, n_beta))
    rhs = np.zeros((n, n_beta))
    for j in range(6):
        keep = ~pad[j]
        cols = index[j, keep]
        gram[:, cols[:, None], cols[None, :]] += s_loc[:, j][:, keep][:, :, keep] / r[j]
        rhs[:, cols] += rhs_loc[:, j][:, keep] / r[j]
    return gram, rhs


def _with_jackknife(covariance, theta, ratio, steps, noise, data, pad, observed, r, index, n_beta):
    """The model's covariance, each standard error raised to the grouped jackknife's where that is larger.

    The jackknife refits β (walk ratios and noise variances held) without each of
    :data:`~ftcal.core.limits.ROBUST_CLUSTERS` contiguous stretches of the observed
    blocks in turn; the model's own covariance assumes independent block noise, which
    errors constant over a hold (hysteresis, a pose's cable force) or an unmodelled lag
    break. The correlations stay the model's.

    Returns
    -------
    (covariance (P, P), number of stretches left out (0 when too few to leave out), the jackknives'
    :class:`~ftcal.core.jackknife.Widened` or None)
    """
    from ..core.jackknife import COARSER_BLOCKS, block_edges, merged_partitions, widest_covariance
    from ..core.limits import ROBUST_CLUSTERS

    rows = np.flatnonzero(observed)
    edges = block_edges(len(rows), ROBUST_CLUSTERS)
    if len(edges) < 3:
        return covariance, 0, None
    # The finest stretches, then contiguous runs of them (errors correlated over several stretches)
    partitions = [edges] + [edges[merged] for merged in merged_partitions(len(edges) - 1, COARSER_BLOCKS)]
    masks = []
    for cuts in partitions:
        for a, b in zip(cuts[:-1], cuts[1:]):
            mask = observed.copy()
            mask[rows[a:b]] = False
            masks.append(mask)
    masks = np.array(masks)
    _, cross = _filter(np.broadcast_to(ratio, (len(masks), 6)), steps, noise, data, pad, masks)
    gram, rhs = _joint_normal_equations(cross[..., 1:, 1:], cross[..., 1:, 0], r, index, pad, n_beta)
    refits, at = [], 0
    for cuts in partitions:
        refits.append([])
        for g in range(at, at + len(cuts) - 1):
            scale = 1.0 / np.sqrt(np.maximum(np.diag(gram[g]), 1e-300))
            scaled = gram[g] * scale[:, None] * scale[None, :]
            if np.linalg.cond(scaled) < 1e12:  # else this stretch alone identifies something: it cannot be left out
                refits[-1].append(scale * np.linalg.solve(scaled, rhs[g] * scale))
        at += len(cuts) - 1
    widened = widest_covariance(refits)
    if widened is None:
        return covariance, 0, None
    se = np.sqrt(np.maximum(np.diag(covariance), 0.0))
    raise_to = np.sqrt(np.maximum(np.diag(widened.covariance), 0.0))
    factor = np.where(se > 0, np.maximum(1.0, raise_to / np.where(se > 0, se, 1.0)), 1.0)
    return covariance * factor[:, None] * factor[None, :], len(refits[0]), widened


def _choose_ratio(blocks: Blocks, steps, noise, data, pad, n_columns, observed) -> np.ndarray:
    """Walk-to-noise variance ratio of each axis by restricted maximum likelihood on a log grid, refined once."""
    duration = max(blocks.hours[-1] - blocks.hours[0], 1e-12)
    n_blocks = int(np.count_nonzero(observed))
    # Walk variance over the whole recording from 1e-4 to 1e2 × n_blocks times the block noise, and none.
    grid = np.r_[0.0, np.logspace(-4, np.log10(100.0 * n_blocks), _GRID)] / duration
    best = _grid_best(grid[:, None] * np.ones(6), steps, noise, data, pad, n_columns, n_blocks, observed)
    step = np.log(grid[2] / grid[1])
    fine = np.exp(np.log(np.maximum(best, grid[1])) + np.linspace(-step, step, 9)[:, None])
    fine = np.vstack([fine, best[None]])
    return _grid_best(fine, steps, noise, data, pad, n_columns, n_blocks, observed)


def _grid_best(ratios, steps, noise, data, pad, n_columns, n_blocks, observed) -> np.ndarray:
    log_f, cross = _filter(ratios, steps, noise, data, pad, observed)
    ll = _reml(log_f, cross, n_columns, n_blocks)
    return ratios[np.argmax(ll, axis=0), np.arange(6)]


def _smooth(theta, x, blocks, ratio, steps, noise, slope: bool, observed):
    """RTS-smoothed bias at every block (β fixed, temperature term excluded), and the walk's filtered
    variance at the last block (noise variance units).

    ``theta`` (P,) with ``observed`` (B,), or L refits at once: ``theta`` (L, P) with ``observed`` (L, B)
    (then the trajectory is (L, B, 6) and the variance (L, 6)).
    """
    single = np.ndim(theta) == 1
    theta = np.atleast_2d(theta)
    seen = np.broadcast_to(observed, (theta.shape[0], len(steps))).astype(float)
    at = STATIC_PARAMETERS.index("Fx_bias")
    model = theta[:, None, at:at + 6] + (blocks.hours[None, :, None] * theta[:, None, 10:16] if slope else 0.0)
    if not np.any(ratio):  # no walk: the filter never moves (p stays 0)
        out, var = np.broadcast_to(model, (theta.shape[0], len(steps), 6)).copy(), np.zeros((theta.shape[0], 6))
        return (out[0], var[0]) if single else (out, var)
    residual = blocks.wrench[None] - np.einsum("bjp,lp->lbj", x, theta)
    n, n_blocks = theta.shape[0], len(steps)
    pred_p = np.zeros((n_blocks, n, 6))
    filt_p = np.zeros((n_blocks, n, 6))
    filt_d = np.zeros((n_blocks, n, 6))
    p, d = np.zeros((n, 6)), np.zeros((n, 6))
    for k in range(n_blocks):
        p = p + ratio * steps[k]
        pred_p[k] = p
        gain = seen[:, k, None] * p / (p + noise[k])
        d = d + gain * (residual[:, k] - d)
        p = p * (1.0 - gain)
        filt_p[k], filt_d[k] = p, d
    smooth = filt_d.copy()
    for k in range(n_blocks - 2, -1, -1):
        nxt = pred_p[k + 1]
        gain = np.divide(filt_p[k], nxt, out=np.zeros_like(nxt), where=nxt > 0)
        smooth[k] = filt_d[k] + gain * (smooth[k + 1] - filt_d[k])
    out = model + smooth.transpose(1, 0, 2)
    return (out[0], filt_p[-1][0]) if single else (out, filt_p[-1])


def _end_gradient(x, ratio, steps, noise, kind, observed) -> np.ndarray:
    """∂(bias at the last block)/∂β for each axis, shape (6, P): the bias model minus the filter's pull."""
    n_blocks, _, n_beta = x.shape
    at = STATIC_PARAMETERS.index("Fx_bias")
    grad = np.zeros((6, n_beta))
    grad[np.arange(6), at + np.arange(6)] = 1.0
    if kind == "linear":
        grad[np.arange(6), 10 + np.arange(6)] = x[-1, np.arange(6), 10 + np.arange(6)]
    if kind != "random-walk":
        return grad
    # The filtered walk at the end is linear in the data minus X β: d_B = a − Σ_k c_k X_k β.
    p, weight = np.zeros(6), np.zeros((6, n_beta))
    for k in range(n_blocks):
        p = p + ratio * steps[k]
        gain = p / (p + noise[k]) if observed[k] else np.zeros(6)
        weight = weight + gain[:, None] * (x[k] - weight)
        p = p * (1.0 - gain)
    return grad - weight


def choose(fits: dict[str, StateSpaceFit]) -> tuple[str, str]:
    """The bias model with the best BIC, unless a simpler one is within :data:`BIC_MARGIN`.

    Parameters
    ----------
    fits : the candidates keyed by kind, simplest first (``none``, ``linear``, ``random-walk``)

    Returns
    -------
    (kind, reason in words)
    """
    chosen = "none"
    for kind in fits:
        if kind != chosen and fits[kind].bic < fits[chosen].bic - BIC_MARGIN:
            chosen = kind
    base = fits["none"].bic
    scores = ", ".join(f"{k} {f.bic - base:+.1f}" for k, f in fits.items())
    return chosen, (f"BIC on {len(fits['none'].trajectory)} time blocks relative to a constant bias: {scores}; "
                    f"a richer model needs to win by more than {BIC_MARGIN:g}")
