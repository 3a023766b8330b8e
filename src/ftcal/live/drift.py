"""The drift test: has the tracked bias moved faster than the random walk allows?

The χ² gate of :mod:`ftcal.live.tracker` judges one sample at a time, so a contact that builds up
slowly (a ramp of 1 N/s) never fails it: the filter follows the ramp with a lag of a few σ and
takes the whole contact into the bias. The random-walk model says more: over ``L`` seconds the
bias moves by ``N(0, q L)`` per axis. Every :data:`SNAPSHOT_S` the test compares the bias with
the bias ``L`` s before (``L`` in :data:`LAGS_S`, the newest snapshot at least that old)::

    χ²_drift = Σ_j (b_j(t) − b_j(t − L))² / (q_j L + P_j(t) + P_j(t − L))

(the two estimates' variances added: their positive correlation only makes the test more
cautious). Beyond the 1 − :data:`FALSE_ALARM` quantile of χ² with 6 degrees of freedom (38.3 at
1e-6), *and* with some axis moved beyond ``check --accept``'s threshold (1 N, 0.1 N·m: as for the
``unexplained`` flag, a move the user accepts as calibration error is not worth undoing, and a walk
the filter underestimates must not keep rolling the bias back), the bias and its variance go back to
that snapshot's, predicted since (``P + q L``), as if no sample in between had updated them; from
there the χ² gate sees the contact again and flags it. A ramp slower than about
max(6.19 √(q L), threshold) / L for the longest lag stays within the walk (docs/live.md).
"""

from __future__ import annotations

import bisect
import math

# A snapshot of the bias is taken at the first sample this long after the previous one.
SNAPSHOT_S = 0.25
# Lags compared at each snapshot, s (the longest first: a rollback goes as far back as a lag that fails).
LAGS_S = (64.0, 16.0, 4.0, 1.0)
# Chance that the bias of a sensor that follows the random walk fails one comparison.
FALSE_ALARM = 1e-6


class DriftCheck:
    """Snapshots of the bias every :data:`SNAPSHOT_S` and the comparison over :data:`LAGS_S` (module docstring).

    Parameters
    ----------
    threshold : χ² (6 dof) beyond which the bias moved faster than the walk allows
    """

    def __init__(self, threshold: float) -> None:
        self.threshold = threshold
        self.times: list = []  # snapshot times, increasing, reaching back at least max(LAGS_S)
        self.states: list = []  # (bias, variance) at those times
        self.next_due = -math.inf
        self.last_rollback = None

    def reset(self) -> None:
        """Forget the snapshots (the bias was set on purpose: re-tare, a tool identified, a resumed state)."""
        self.times, self.states = [], []
        self.next_due = -math.inf
        # the last rollback: (time, bias and variance before it, the snapshot's bias and variance, span) or None
        self.last_rollback = None

    def check(self, time: float, bias: list, variance: list, walk: list, limit: list) -> tuple | None:
        """Snapshot the state after the sample at ``time`` (due: ``time >= next_due``) and compare; ``walk``: q per
        axis, ``limit``: the acceptance thresholds per axis.

        Returns
        -------
        None, or (bias, variance, lag, chi2, moved) to go back to: plain-float lists of the snapshot's bias and its
        variance predicted to ``time``, the lag that failed (s), its χ² and the largest |move| per axis
        """
        self.next_due = time + SNAPSHOT_S
        for lag in LAGS_S:
            k = bisect.bisect_right(self.times, time - lag) - 1  # the newest snapshot at least `lag` old
            if k < 0:
                continue
            t0, (b0, p0) = self.times[k], self.states[k]
            span = time - t0
            chi2 = sum([(b - c) * (b - c) / (q * span + p + r)
                        for b, c, q, p, r in zip(bias, b0, walk, variance, p0)])
            if chi2 > self.threshold and any([abs(b - c) > a for b, c, a in zip(bias, b0, limit)]):
                back = (list(b0), [r + q * span for r, q in zip(p0, walk)], span, chi2,
                        max(abs(b - c) for b, c in zip(bias, b0)))
                self.last_rollback = (time, list(bias), list(variance), list(b0), list(p0), span)
                self.times, self.states = [time], [(tuple(back[0]), tuple(back[1]))]
                return back
        self.times.append(time)
        self.states.append((tuple(bias), tuple(variance)))
        if len(self.times) > 64 and self.times[64] <= time - max(LAGS_S):  # never needed again: drop, 64 at a time
            del self.times[:64], self.states[:64]
        return None
