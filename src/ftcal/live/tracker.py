"""The recursive bias tracker: a Kalman filter of the random-walk bias, gated by an innovation test.

Model, axis j (the random-walk model of :mod:`ftcal.payload.drift`, one sample at a time)::

    b_k = b_(k−1) + w_k,   w_k ~ N(0, q_j Δt_k)          (the sensor's bias walks)
    z_k = b_k + v_k,       v_k ~ N(0, r_j)                (z: calibrated wrench − tool's gravity wrench)

A wander (first-order Gauss-Markov, variance s², time constant τ) correlates ``v`` over τ; a filter whose time
constant is much longer than τ sees it as white noise of its low-frequency density ``D = 2 s² τ`` (N²·s). The
update then takes ``r_u = r + D / Δt`` per sample (the white noise whose density matches at the update rate),
the gate and the innovations keep ``S = P⁻ + r`` (what one sample shows): the bias is not pulled along by
the wander and a contact is still judged against one sample's spread. ``D = 0``: the plain filter.

A sample updates the filter only when it is *static* (the caller's motion test), its
innovation ``e = z − b_(k−1)`` passes the χ² test ``Σ_j e_j² / S_j < threshold`` with
``S = P⁻ + r`` (6 degrees of freedom), and it is not within :data:`HOLDOFF_S` s of the end of a run of
failed static samples lasting :data:`MIN_FAIL_S` or more (a contact's release edge stays out). A sample that fails is a contact: it is reported and
the bias is only predicted (``P`` grows by ``q Δt``), so a real contact is never absorbed.

**Blocks with the same math as one sample at a time.** With the update decisions fixed,
the covariance follows a Möbius recursion (a 2 × 2 matrix product per sample) and the bias
an affine one (``b_k = (1 − K_k) b_(k−1) + K_k z_k``); both are prefix scans
(:func:`affine_scan`, :func:`mobius_scan`), log₂ n numpy passes over a block. The decisions
depend on the state, so :func:`track_block` guesses them (every static sample updates, then
a decision persists along a static run), finds the first sample whose gate disagrees, keeps
everything before it and rescans from there. A block of one sample is the per-sample filter;
every :data:`HALVE_EVERY` rescans of a chunk the window scanned halves (down to
:data:`MIN_WINDOW` samples), so a gate that flips often costs short rescans.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

# After a run of static samples that failed the gate for at least MIN_FAIL_S (a contact, not a chance failure), no
# sample updates the bias for HOLDOFF_S s: a contact released over tens of ms passes the gate part-way down its
# edge, and after a long contact the bias variance is large enough that one such sample would set the bias (gain
# near 1) to part of the contact. Chance failures (a bias a few σ off fails now and then) do not hold updates off.
HOLDOFF_S = 0.15
MIN_FAIL_S = 0.1
# (time of the last failed static sample, start of its run of failures, the previous sample failed): none yet
NO_FAILURE = (-np.inf, np.inf, False)
# Samples scanned together: a gate that disagrees with the guess costs a rescan of the rest of a chunk.
CHUNK = 1024
# Every this many rescans of one chunk, the scanned window halves (down to MIN_WINDOW samples): a gate
# that keeps disagreeing with the guesses then costs rescans of short windows, not of the whole chunk.
HALVE_EVERY = 4
MIN_WINDOW = 8


def affine_scan(a: np.ndarray, c: np.ndarray, x0: np.ndarray) -> np.ndarray:
    """All ``x_k = a_k x_(k−1) + c_k`` (k = 0 … n−1) from ``x_(−1) = x0``, by a prefix scan.

    Parameters
    ----------
    a, c : ndarray of shape (n, m)
    x0 : ndarray of shape (m,)

    Returns
    -------
    ndarray of shape (n, m)
    """
    a, c = a.copy(), c.copy()
    shift = 1
    while shift < a.shape[0]:
        c[shift:] = a[shift:] * c[:-shift] + c[shift:]  # right side is evaluated before the assignment
        a[shift:] = a[shift:] * a[:-shift]
        shift *= 2
    return a * x0 + c


def mobius_scan(alpha: np.ndarray, beta: np.ndarray, gamma: np.ndarray, delta: np.ndarray,
                x0: np.ndarray) -> np.ndarray:
    """All ``x_k = (α_k x_(k−1) + β_k) / (γ_k x_(k−1) + δ_k)`` from ``x0``, by a prefix scan.

    Composing two such maps multiplies their matrices ``[[α, β], [γ, δ]]``.

    Parameters
    ----------
    alpha, beta, gamma, delta : ndarray of shape (n, k)
    x0 : ndarray of shape (k,)

    Returns
    -------
    ndarray of shape (n, k)
    """
    a, b, c, d = alpha.copy(), beta.copy(), gamma.copy(), delta.copy()
    shift = 1
    while shift < a.shape[0]:
        a1, b1, c1, d1 = a[shift:], b[shift:], c[shift:], d[shift:]
        a2, b2, c2, d2 = a[:-shift], b[:-shift], c[:-shift], d[:-shift]
        na, nb = a1 * a2 + b1 * c2, a1 * b2 + b1 * d2
        nc, nd = c1 * a2 + d1 * c2, c1 * b2 + d1 * d2
        # A Möbius map does not change when its matrix is scaled: keep the products near 1.
        scale = np.maximum(np.maximum(np.abs(na), np.abs(nb)), np.maximum(np.abs(nc), np.abs(nd)))
        a[shift:], b[shift:], c[shift:], d[shift:] = na / scale, nb / scale, nc / scale, nd / scale
        shift *= 2
    return (a * x0 + b) / (c * x0 + d)


def gate_chi2(probability: float, dof: int = 6) -> float:
    """The innovation gate: the ``probability`` quantile of χ² with ``dof`` degrees of freedom.

    Parameters
    ----------
    probability : float
        Probability that a sample the model explains passes the gate (e.g. 0.999).
    dof : int, optional
        Degrees of freedom (6: the wrench's components).

    Returns
    -------
    float
        The threshold on the squared Mahalanobis norm of the innovation.
    """
    from scipy.special import chdtri  # what scipy.stats.chi2.ppf calls, without scipy.stats' 2 s of imports

    return float(chdtri(dof, 1.0 - probability))


@dataclass
class TrackedBlock:
    """What the tracker did on each sample of a block.

    Attributes
    ----------
    bias : ndarray of shape (n, 6), the estimate after the sample
    variance : ndarray of shape (n, 6), its variance after the sample
    innovation : ndarray of shape (n, 6), ``z − bias before the sample``
    innovation_variance : ndarray of shape (n, 6), ``P⁻ + r``
    chi2 : ndarray of shape (n,), ``Σ e² / S``
    updated : ndarray of bool, shape (n,), the sample updated the bias
    passes : int, scans used (1 when every guessed decision held)
    carry : the hold-off's state after the block (:data:`NO_FAILURE` before any failure)
    """

    bias: np.ndarray
    variance: np.ndarray
    innovation: np.ndarray
    innovation_variance: np.ndarray
    chi2: np.ndarray
    updated: np.ndarray
    passes: int
    carry: tuple = NO_FAILURE


def update_noise(r, density, dt):
    """The update's per-sample noise variance ``r + D / Δt`` (r where ``D`` is 0 or ``Δt`` is not positive)."""
    if density is None or not np.any(density):
        return r
    dt = np.asarray(dt, float)[..., None]
    return np.where((dt > 0) & (density > 0), r + density / np.where(dt > 0, dt, 1.0), r)


def _scan_segment(z, dt, update, b0, p0, q, r, density=None):
    """Bias, variance and innovations over a segment whose update decisions are given."""
    n = z.shape[0]
    walk = q * dt[:, None]  # (n, 6)
    up = np.broadcast_to(update[:, None], (n, 6))
    r_u = update_noise(r, density, dt)  # the update's r (the gate's is r)
    # Update: P ← (P + qΔt) r_u / (P + qΔt + r_u); prediction only: P ← P + qΔt.
    alpha = np.where(up, r_u, 1.0)
    beta = np.where(up, r_u * walk, walk)
    gamma = up.astype(float)
    delta = np.where(up, walk + r_u, 1.0)
    p_after = mobius_scan(alpha, beta, gamma, delta, p0)
    p_before = np.vstack([p0[None], p_after[:-1]])
    predicted = p_before + walk
    s = predicted + r
    gain = np.where(up, predicted / (s if r_u is r else predicted + r_u), 0.0)
    bias = affine_scan(1.0 - gain, gain * z, b0) if n > 1 else ((1.0 - gain) * b0 + gain * z)
    b_before = np.vstack([b0[None], bias[:-1]])
    innovation = z - b_before
    chi2 = np.einsum("ij,ij->i", innovation, innovation / s)
    return bias, p_after, innovation, s, chi2


def failure_runs(t: np.ndarray, failed: np.ndarray, carry: tuple) -> tuple[np.ndarray, np.ndarray]:
    """The hold-off's state before each sample and after the last: the time of the last failed sample before it
    and the start of that failure's run (a run of consecutive failed samples, continued from ``carry``).

    Returns
    -------
    (last, first): arrays of shape (n + 1,); the state after samples ``:k`` is
    ``(last[k], first[k], failed[k − 1])``
    """
    n = t.size
    index = np.arange(n)
    begins = np.maximum.accumulate(np.where(~failed, index, -1)) + 1  # a failed sample's run begins here
    starts = t[np.minimum(begins, n - 1)] if n else t
    if carry[2]:  # the run before the block goes on
        starts = np.where(begins == 0, carry[1], starts)
    newest = np.r_[-1, np.maximum.accumulate(np.where(failed, index, -1))]
    seen = newest >= 0
    at = np.maximum(newest, 0)
    last = np.where(seen, t[at] if n else carry[0], carry[0])
    first = np.where(seen, starts[at] if n else carry[1], carry[1])
    return last, first


def track_block(z: np.ndarray, dt: np.ndarray, static: np.ndarray, bias0: np.ndarray, variance0: np.ndarray,
                walk: np.ndarray, noise: np.ndarray, threshold: float, times: np.ndarray | None = None,
                carry: tuple = NO_FAILURE, holdoff: float = HOLDOFF_S, density=None) -> TrackedBlock:
    """Run the gated bias filter over a block of samples.

    Parameters
    ----------
    z : ndarray of shape (n, 6), calibrated wrench minus the tool's wrench, N and N·m
    dt : ndarray of shape (n,), s since the previous sample (0 for the very first)
    static : ndarray of bool, shape (n,), samples the motion test calls still
    bias0, variance0 : ndarray of shape (6,), the state before the block
    walk : ndarray of shape (6,), walk variance per second, q
    noise : ndarray of shape (6,), per-sample noise variance, r
    threshold : χ² (6 degrees of freedom) above which a sample is a contact
    times : ndarray of shape (n,) or None, the samples' times, for the hold-off (None: no hold-off)
    carry : the hold-off's state before the block (:attr:`TrackedBlock.carry` of the previous one)
    holdoff : s after a run of failed static samples during which no sample updates
    density : ndarray of shape (6,) or None, the wander's low-frequency density ``D = 2 s² τ`` (N²·s): the update
        takes ``r + D / Δt``, the gate ``r`` (None or 0: the plain filter)

    Returns
    -------
    TrackedBlock
    """
    n = z.shape[0]
    out = TrackedBlock(np.empty((n, 6)), np.empty((n, 6)), np.empty((n, 6)), np.empty((n, 6)), np.empty(n),
                       np.zeros(n, bool), 0)
    update = static.copy()
    b, p = np.asarray(bias0, float), np.asarray(variance0, float)
    out.carry = carry
    hold = (times, holdoff) if times is not None else None
    for begin in range(0, n, CHUNK):
        b, p = _track_chunk(z, dt, static, update, b, p, walk, noise, threshold, out, begin, min(begin + CHUNK, n),
                            hold, density)
    return out


def _track_chunk(z, dt, static, update, b, p, walk, noise, threshold, out, start, end, hold=None, density=None):
    """Samples ``start:end`` of :func:`track_block`; returns the state after them."""
    passes = 0
    while start < end:
        stop = min(end, start + max(MIN_WINDOW, CHUNK >> (passes // HALVE_EVERY)))
        seg = slice(start, stop)
        bias, var, e, s, chi2 = _scan_segment(z[seg], dt[seg], update[seg], b, p, walk, noise, density)
        out.passes += 1
        passes += 1
        gate = static[seg] & (chi2 < threshold)
        if hold is not None:  # valid up to the first wrong guess, as the gate
            t = hold[0][seg]
            failed = static[seg] & ~(chi2 < threshold)
            last, first = failure_runs(t, failed, out.carry)
            gate &= ~((last[:-1] - first[:-1] >= MIN_FAIL_S) & (t - last[:-1] < hold[1]))
        wrong = np.flatnonzero(gate != update[seg])
        keep = stop - start if wrong.size == 0 else int(wrong[0])
        if hold is not None and keep:
            out.carry = (float(last[keep]), float(first[keep]), bool(failed[keep - 1]))
        kept = slice(start, start + keep)
        out.bias[kept], out.variance[kept], out.innovation[kept] = bias[:keep], var[:keep], e[:keep]
        out.innovation_variance[kept], out.chi2[kept], out.updated[kept] = s[:keep], chi2[:keep], update[kept]
        if keep:
            b, p = bias[keep - 1], var[keep - 1]
        if wrong.size == 0:
            start = stop
            continue
        at = start + keep
        # The gate at `at` saw the right state; guess its decision holds for the rest of the static run.
        update[at:end] = static[at:end] & gate[keep]
        update[at] = gate[keep]
        start = at
    return b, p
