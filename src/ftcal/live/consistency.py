"""The tracker checks itself: covariance matching of r, and re-acquisition of a bias it lost.

The bias filter (:mod:`ftcal.live.tracker`) is right only while its model is: noise r and walk q as identified.
Real sensors drift faster after a warm-up or on another day, and their noise wanders. Two checks, run at the
drift test's snapshot times (every :data:`ftcal.live.drift.SNAPSHOT_S`), so that a block and single samples
see them at the same samples:

**Noise: innovation-based covariance matching** (Mehra, "Approaches to adaptive filtering", IEEE TAC 17(5), 1972;
as in Akhlaghi, Zhou & Huang, "Adaptive adjustment of noise covariance in Kalman filter for dynamic state
estimation", IEEE PES GM 2017). Over a window of :data:`WINDOW_S` s the static samples that updated the bias give
``r̂_j = mean(e_j²) − mean(P⁻_j)`` (E e e = P⁻ + r for a consistent filter; the gated-out samples, contacts,
are left out). When the window's normalised innovation squared (NIS, mean ``Σ e²/S`` against its χ² expectation 6)
or its share of static samples gated (expected 1 − gate probability, 0.1 %) says the filter is inconsistent,
r goes to r̂, bounded to [r₀, :data:`R_MAX` r₀] (r₀: the one rule's, what the data showed: never below it), and an
event ``tracker adapted`` says so with the NIS and the gated share. When r is too small, r̂ is at least half the
mean squared difference of consecutive static samples (``2 r`` for white noise, whatever the gate did; each clipped
at :data:`DIFF_CAP` r₀): an r far too small gates nearly every sample, and the few that update are the small ones.

**Walk: lock-out and re-acquisition by orientation diversity.** A sensor whose bias moved faster than q allows
(or that the drift test sent back) fails the gate on every static sample: the bias stops updating. After
:data:`LOCK_S` s of static samples without an update an event ``tracker locked_out`` says so (never silent). A
held contact looks the same within one pose, but not across poses: a bias is constant in the sensor frame
while the tool's gravity direction changes; a contact with the world turns with it. So when a hold most of
whose static samples did not update the bias ends, its mean residual ``z = w − tool`` is kept; when a later such hold, at
least :data:`MIN_TURN_DEG` away in gravity direction and :data:`MIN_HOLD_S` long, shows the same mean residual
(a contact fixed in the world changes in the sensor frame by at least 2 |F| sin(θ/2) over a turn θ; the force and
the torque residual must each change by less than :data:`TURN_SHARE` of that for an offset of its size, or by less
than 3 σ of the two means, each mean's variance ``r max(1/n, CORRELATION_S/T)`` plus the walk between them), the
residual is bias: the bias takes the new hold's mean, q rises to cover the move it
missed (``q_j ≥ Δb_j² / Δt``, bounded to [q₀, :data:`Q_MAX` q₀]), the drift test's snapshots restart, and an
event ``tracker reacquired`` says by how much. A contact held through a change of pose (the same force in the
sensor frame in two orientations: a contact that moves with the tool) cannot be told from bias.

**Walk: covariance matching over the moves** (Mehra 1972's innovation-based matching, applied where the model says
the walk shows: after a gap in updates). Between two holds a random-walk bias moves by ``N(0, q Δt)``. At the first
static sample of a hold, ``d = z − ref`` (ref: the filter's bias after the last static sample when it updated,
variance P, else that sample's own z, variance r) has ``E d_j² = P_j + q_j Δt + r_j = S_j``. Each of the last
:data:`WALK_KEEP` hold starts whose walk share ``w = mean_j q_j Δt / S_j`` is at least :data:`MIN_WALK_SHARE` gives
``λ = 1 + (mean_j d_j² / S_j / CHI2_6_MEDIAN − 1) / w``; the median of at least :data:`MIN_WALK_STARTS` (a contact
held across one move does not move it) beyond :data:`WALK_FACTOR` either way sets q to λ q within [q₀, Q_MAX q₀]
(event ``tracker adapted``). The bias' variance takes the walk it missed since its last update, and the drift test's
last rollback, when the bias has not updated since and its χ² under the new q is within the drift threshold, is
undone (event ``tracker undone``): it was judged with a q the data have shown too small.
"""

from __future__ import annotations

from .c_limits import SC_KEEP_HOLDS, SC_WALK_KEEP

import math

# s of static samples without a bias update after which the tracker says it is locked out.
LOCK_S = 2.0
# A hold must be this long (s) for its mean to re-acquire the bias.
MIN_HOLD_S = 1.0
# Two holds must differ by at least this in gravity direction (degrees) for their means to tell bias from contact.
MIN_TURN_DEG = 20.0
# Locked holds kept to compare a new one with (a contact hold between two bias holds does not hide them).
KEEP_HOLDS = SC_KEEP_HOLDS  # declared once, in the C core (csrc/ftcal_live.h)
# A bias may change between the holds by at most this share of what a world-fixed contact of its size would.
TURN_SHARE = 0.5
# A hold mean's variance is r / n for white noise; a wander correlated over this long (s) counts once per this.
CORRELATION_S = 1.0
# Window of the covariance matching, s (of checks), and its smallest number of updating samples.
WINDOW_S = 10.0
MIN_WINDOW_SAMPLES = 100
# r adapts within [r0, R_MAX r0]; q within [q0, Q_MAX q0] (a tenfold std).
R_MAX = 25.0
Q_MAX = 100.0
# Walk matching: hold starts kept, fewest to decide, the smallest walk share of a hold start's innovation variance
# for it to count (below it the walk is not seen over the move, e.g. under a wander), and the factor q must be off
# by before it adapts (either way).
WALK_KEEP = SC_WALK_KEEP  # declared once, in the C core (csrc/ftcal_live.h)
MIN_WALK_STARTS = 2
MIN_WALK_SHARE = 0.3
WALK_FACTOR = 1.6
# Median of χ² with 6 degrees of freedom over 6 (scipy.special.chdtri(6, 0.5) / 6).
CHI2_6_MEDIAN = 0.8913534
# r is also matched to the differences of consecutive static samples (2 r for white noise, whatever the gate did:
# a too-small r gates most samples, and the few that update are the small ones); each squared difference is
# clipped at this many r0 (a contact's edge is one large difference).
DIFF_CAP = 4.0 * R_MAX
# r adapts when the NIS mean is beyond this factor of its expectation (either way), or the gated share this
# many times the expected 1 - gate probability (and above 1 %).
NIS_FACTOR = 1.5
GATED_FACTOR = 5.0


class SelfCheck:
    """Accumulates what the checks need per sample and decides at the snapshot times (module docstring).

    Parameters
    ----------
    noise, walk : the one rule's r₀ and q₀ per axis (lists of 6 floats; q per s)
    gate : the contact gate's χ² threshold (6 dof); gate_probability its quantile
    """

    def __init__(self, noise: list, walk: list, gate: float, gate_probability: float) -> None:
        self.noise0, self.walk0 = list(noise), list(walk)
        self.gate, self.expected_gated = gate, 1.0 - gate_probability
        self.reset(None)

    def reset(self, time: float | None) -> None:
        """Forget the holds and the window (a re-tare, a resumed state, a tool identified, a clock restart)."""
        self.window_start = time
        self.n_static = self.n_gated = self.n_updated = 0
        self.nis = 0.0
        self.e2 = [0.0] * 6
        self.pred = [0.0] * 6
        self.diff, self.n_pairs, self.last_z = [0.0] * 6, 0, None
        self.last_update = time
        self.locked_announced = False
        self.hold = None  # [n, Σz (6), Σ direction (3), start time, last time]
        self.ref = None  # the last static sample: (bias after it and its variance, or z and None when it did not update; time)
        self.starts = []  # hold starts, oldest first: (squared change per axis, the reference's variance or None, gap s)
        self.new_start = False
        self.previous = []  # (mean z, unit direction, n, seconds, end time) of the last locked holds, newest last

    # ----- per sample, and a block's samples between two checks ------------------------------------------------
    def observe_one(self, t, still, updated, gated, z, e, predicted, s, direction, bias, variance) -> None:
        """One sample: ``bias``, ``variance`` the filter's after the sample (before a rollback)."""
        if self.last_update is None:
            self.last_update = t
        if still:
            self.n_static += 1
            self.n_gated += gated
            if updated:
                self.n_updated += 1
                self.nis += sum([a * a / b for a, b in zip(e, s)])
                self.e2 = [a + b * b for a, b in zip(self.e2, e)]
                self.pred = [a + b for a, b in zip(self.pred, predicted)]
            if self.hold is not None:  # the previous sample was static too: a difference
                self.n_pairs += 1
                self.diff = [a + min((b - c) * (b - c), DIFF_CAP * r0)
                             for a, b, c, r0 in zip(self.diff, z, self.last_z, self.noise0)]
            self.last_z = z
            if self.hold is None:
                self._start(t, z)
                self.hold = [0, [0.0] * 6, [0.0] * 3, t, t, 0]
            self.ref = (bias, variance, t) if updated else (z, None, t)
            h = self.hold
            h[0] += 1
            h[5] += not updated
            h[1] = [a + b for a, b in zip(h[1], z)]
            h[2] = [a + b for a, b in zip(h[2], direction)]
            h[4] = t
            if updated:
                self.last_update = t
        elif self.hold is not None:
            self._end_hold()

    def observe_block(self, t, still, updated, gated, z, e, predicted, s, direction, bias, variance) -> None:
        """:meth:`observe_one` over arrays of samples (numpy), the same sums (in another order)."""
        import numpy as np

        n = t.size
        if n == 0:
            return
        if self.last_update is None:
            self.last_update = float(t[0])
        up = still & updated
        self.n_static += int(still.sum())
        self.n_gated += int((still & gated).sum())
        self.n_updated += int(up.sum())
        if up.any():
            self.nis += float(np.sum(e[up] ** 2 / s[up]))
            self.e2 = [a + b for a, b in zip(self.e2, np.sum(e[up] ** 2, axis=0).tolist())]
            self.pred = [a + b for a, b in zip(self.pred, np.sum(predicted[up], axis=0).tolist())]
        edges = np.flatnonzero(np.diff(np.r_[0, still.astype(np.int8), 0]))
        pos = 0
        for a, b in zip(edges[::2].tolist(), edges[1::2].tolist()):
            if a > pos and self.hold is not None:
                self._end_hold()
            cap = DIFF_CAP * np.asarray(self.noise0)
            steps = np.diff(z[a:b], axis=0)
            if self.hold is not None:
                steps = np.vstack([z[a] - np.asarray(self.last_z), steps])
            if steps.shape[0]:
                self.n_pairs += steps.shape[0]
                self.diff = [x + y for x, y in zip(self.diff, np.minimum(steps * steps, cap).sum(axis=0).tolist())]
            self.last_z = z[b - 1].tolist()
            if self.hold is None:
                self._start(float(t[a]), z[a].tolist())
                self.hold = [0, [0.0] * 6, [0.0] * 3, float(t[a]), float(t[a]), 0]
            last = b - 1
            self.ref = ((bias[last].tolist(), variance[last].tolist(), float(t[last])) if up[last]
                        else (z[last].tolist(), None, float(t[last])))
            self._add(t[a:b], z[a:b], direction[a:b])
            self.hold[5] += int(b - a - np.count_nonzero(up[a:b]))
            done = np.flatnonzero(up[a:b])
            if done.size:
                self.last_update = float(t[a + done[-1]])
            pos = b
        if pos < n and self.hold is not None:
            self._end_hold()

    def _start(self, t: float, z: list) -> None:
        """A hold starts: keep its first residual's change since the last static sample (the walk over the move)."""
        if self.ref is None:
            return
        ref, variance, time = self.ref
        self.starts = [*self.starts[1 - WALK_KEEP:], ([(a - b) * (a - b) for a, b in zip(z, ref)], variance, t - time)]
        self.new_start = True

    def _match_walk(self, noise: list, walk: list) -> tuple | None:
        """q by covariance matching over the last hold starts (module docstring): (new q, λ, starts used) or None."""
        factors = []
        for change, ref, gap in self.starts:
            ref = noise if ref is None else ref
            total = [v + q * gap + r for v, q, r in zip(ref, walk, noise)]
            share = sum([q * gap / s for q, s in zip(walk, total)]) / 6.0
            if share >= MIN_WALK_SHARE:
                rho = sum([c / s for c, s in zip(change, total)]) / 6.0
                factors.append(1.0 + (rho / CHI2_6_MEDIAN - 1.0) / share)
        if len(factors) < MIN_WALK_STARTS:
            return None
        factors.sort()
        m = len(factors)
        lam = 0.5 * (factors[(m - 1) // 2] + factors[m // 2])
        if 1.0 / WALK_FACTOR < lam < WALK_FACTOR:
            return None
        proposal = [min(max(lam * q, q0), Q_MAX * q0) for q, q0 in zip(walk, self.walk0)]
        if not any(abs(p - q) > 1e-3 * q for p, q in zip(proposal, walk)):
            return None
        return proposal, lam, m

    def _add(self, t, z, direction) -> None:
        h = self.hold
        h[0] += t.size
        h[1] = [a + b for a, b in zip(h[1], z.sum(axis=0).tolist())]
        h[2] = [a + b for a, b in zip(h[2], direction.sum(axis=0).tolist())]
        h[4] = float(t[-1])

    def _end_hold(self) -> None:
        n, sz, sd, start, end, missed = self.hold
        self.hold = None
        locked = 2 * missed > n  # most of its samples did not update the bias
        if locked and end - start >= MIN_HOLD_S:
            norm = math.sqrt(sum(d * d for d in sd)) or 1.0
            self.previous = [*self.previous[1 - KEEP_HOLDS:], ([v / n for v in sz], [d / norm for d in sd], n,
                                                               end - start, end)]
        elif not locked:
            self.previous = []

    def _alike(self, p, mean, direction, n, seconds, time, bias, noise, walk):
        """(turn in degrees, change over offset) when the locked hold ``p`` and the current one show the same
        residual in two orientations, else None (module docstring)."""
        turn = math.degrees(math.acos(max(-1.0, min(1.0, sum(a * b for a, b in zip(p[1], direction))))))
        if turn < MIN_TURN_DEG:
            return None
        gap = time - p[4]
        spread = [r * (max(1.0 / n, CORRELATION_S / seconds) + max(1.0 / p[2], CORRELATION_S / p[3])) + q * gap
                  for r, q in zip(noise, walk)]
        # A contact fixed in the world turns with the tool: over a turn θ its sensor-frame change is 2 |F| sin(θ/2)
        # at least (the rotation is at least the gravity direction's). Bias: the change is at most a share of that
        # for an offset of its size, or within the noise of the two means (3 σ), force and torque apart.
        limit = 2.0 * math.sin(math.radians(turn) / 2.0) * TURN_SHARE
        ratio = 0.0
        for axes in ((0, 1, 2), (3, 4, 5)):
            change = math.sqrt(sum((mean[j] - p[0][j]) ** 2 for j in axes))
            offset = math.sqrt(sum((mean[j] - bias[j]) ** 2 for j in axes))
            if change > max(limit * offset, 3.0 * math.sqrt(sum(spread[j] for j in axes))):
                return None
            ratio = max(ratio, change / max(offset, 1e-300))
        return turn, ratio

    # ----- at a snapshot time --------------------------------------------------------------------------------
    def check(self, time: float, bias: list, noise: list, walk: list, variance: list, drift=None) -> tuple:
        """After the drift test at ``time``, with the filter's state then and the drift test
        (:class:`~ftcal.live.drift.DriftCheck`: its last rollback is undone when a walk matched since explains it).

        Returns
        -------
        (events, new_noise or None, new_walk or None, (bias, variance) or None): events as (kind, text)
        """
        events, new_noise, new_walk, new_bias = [], None, None, None
        if self.window_start is None:
            self.window_start = time
        if time - self.window_start >= WINDOW_S:
            updates, pairs = self.n_updated >= MIN_WINDOW_SAMPLES, self.n_pairs >= MIN_WINDOW_SAMPLES
            if updates or pairs:
                nis = self.nis / self.n_updated if updates else math.nan
                share = self.n_gated / max(self.n_static, 1)
                too_high = (updates and nis > NIS_FACTOR * 6.0) or (
                    share > GATED_FACTOR * self.expected_gated and share > 0.01)
                too_low = updates and nis < 6.0 / NIS_FACTOR
                if too_high or too_low:
                    matched = ([max(a / self.n_updated - p / self.n_updated, 0.0) for a, p in zip(self.e2, self.pred)]
                               if updates else [0.0] * 6)
                    if too_high and pairs:
                        matched = [max(m, d / self.n_pairs / 2.0) for m, d in zip(matched, self.diff)]
                    proposal = [min(max(m, r0), R_MAX * r0) for m, r0 in zip(matched, self.noise0)]
                    if too_high:
                        proposal = [max(p, r) for p, r in zip(proposal, noise)]
                    else:
                        proposal = [min(p, r) for p, r in zip(proposal, noise)]
                    if any(abs(p - r) > 1e-3 * r for p, r in zip(proposal, noise)):
                        new_noise = proposal
                        events.append(("adapted", noise_adapted_text(nis, self.n_updated, self.n_pairs, share,
                                                                     self.expected_gated, proposal)))
            self.window_start = time
            self.n_static = self.n_gated = self.n_updated = 0
            self.nis = 0.0
            self.e2, self.pred = [0.0] * 6, [0.0] * 6
            self.diff, self.n_pairs = [0.0] * 6, 0
        if self.new_start:
            self.new_start = False
            matched = self._match_walk(new_noise or noise, walk)
            if matched is not None:
                new_walk, lam, m = matched
                back = None if drift is None else drift.last_rollback
                if (back is not None and self.last_update is not None and self.last_update <= back[0]
                        and sum([(b - c) * (b - c) / (q * back[5] + p + v) for b, c, q, p, v in
                                 zip(back[1], back[3], new_walk, back[2], back[4])]) <= drift.threshold):
                    # no update since a rollback the matched walk explains: it was the walk, undo it
                    drift.last_rollback = None
                    new_bias = (list(back[1]), [p + q * (time - back[0]) for p, q in zip(back[2], new_walk)])
                    bias = new_bias[0]
                    events.append(("undone", undone_text(back[0])))
                elif self.last_update is not None and time > self.last_update:
                    # the bias walked at the new q since its last update: its variance says so
                    idle = time - self.last_update
                    new_bias = (list(bias), [p + max(a - b, 0.0) * idle for p, a, b in zip(variance, new_walk, walk)])
                walk = new_walk
                events.append(("adapted", walk_adapted_text(m, lam, new_walk)))
        h = self.hold
        if h is None or self.last_update is None or h[4] != time:
            return events, new_noise, new_walk, new_bias
        idle = time - self.last_update
        if idle <= LOCK_S:
            self.locked_announced = False
        elif not self.locked_announced:
            self.locked_announced = True
            events.append(("locked_out", locked_out_text(idle)))
        n, sz, sd, start, _, missed = h
        if not self.previous or time - start < MIN_HOLD_S or 2 * missed <= n:
            return events, new_noise, new_walk, new_bias
        norm = math.sqrt(sum(d * d for d in sd)) or 1.0
        mean = [v / n for v in sz]
        seconds = time - start
        for p in reversed(self.previous):
            found = self._alike(p, mean, [d / norm for d in sd], n, seconds, time, bias, noise, walk)
            if found is not None:
                break
        else:
            return events, new_noise, new_walk, new_bias
        turn, ratio = found
        variance = [r * max(1.0 / n, CORRELATION_S / seconds) for r in noise]
        moved = [a - b for a, b in zip(mean, bias)]
        # the walk it missed, alike on the three force (and the three torque) axes: one move is a poor per-axis sample
        share = [sum(m * m for m in moved[:3]) / 3.0] * 3 + [sum(m * m for m in moved[3:]) / 3.0] * 3
        proposal = [min(max(q, m2 / max(idle + seconds, 1e-9)), Q_MAX * q0)
                    for q, m2, q0 in zip(walk, share, self.walk0)]
        if any(abs(a - b) > 1e-3 * b for a, b in zip(proposal, walk)):
            new_walk = proposal
        new_bias = (mean, variance)
        events.append(("reacquired", reacquired_text(ratio, turn, max(abs(m) for m in moved), new_walk or walk)))
        self.last_update = time
        self.locked_announced = False
        self.previous = []
        self.hold = [0, [0.0] * 6, [0.0] * 3, time, time, 0]
        return events, new_noise, new_walk, new_bias


# ----- the events' texts (SelfCheck's, and LiveCalibrator's from the C core's numbers) --------------------------------
def noise_adapted_text(nis: float, n_updated: int, n_pairs: int, share: float, expected: float, noise) -> str:
    """``tracker adapted`` for r: the window's NIS (NaN: too few updates), its counts, the share gated, the new r."""
    return ((f"NIS mean {nis:.3g} over {n_updated} static samples (expected 6), " if n_updated >= MIN_WINDOW_SAMPLES
             else f"{n_updated} static samples updated (too few for the NIS; r from the differences of "
             f"{n_pairs} consecutive static samples), ") + f"{100 * share:.2g} % "
            f"of static samples gated (expected {100 * expected:.2g} %): noise std "
            + ", ".join(f"{math.sqrt(p):.3g}" for p in noise) + " (covariance matching, within 1 to 5x the identified)")


def walk_adapted_text(moves: int, factor: float, walk) -> str:
    """``tracker adapted`` for q: the moves matched, their median factor, the new q per s."""
    return (f"the residual changed over the last {moves} moves by {factor:.3g}x the walk allowed (median, covariance "
            "matching): walk std now " + ", ".join(f"{math.sqrt(q * 3600.0):.3g}" for q in walk)
            + " per sqrt(h) (within 1 to 10x the identified)")


def undone_text(time: float) -> str:
    """``tracker undone``: the drift test's rollback at ``time`` s."""
    return f"the rollback at {time:.6g} s is within the walk matched since: bias back to before it"


def locked_out_text(idle: float) -> str:
    """``tracker locked_out`` after ``idle`` s of static samples without an update."""
    return (f"no bias update for {idle:.3g} s of static samples: a held contact, or a bias that moved faster "
            "than the walk allows; re-acquired when a hold in another orientation shows the same residual")


def reacquired_text(ratio: float, turn: float, moved: float, walk) -> str:
    """``tracker reacquired``: the holds' change relative to the residual, their turn in degrees, the largest move."""
    return (f"the residual held alike (changed by {100 * ratio:.2g} % of itself) over two holds {turn:.3g} deg "
            f"apart in gravity direction: bias, not contact; bias moved by up to {moved:.3g}, walk std now "
            + ", ".join(f"{math.sqrt(q * 3600.0):.3g}" for q in walk) + " per sqrt(h)")
