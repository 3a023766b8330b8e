"""A scalar Python reference of the live step's tracker: the oracle the C core is held to (tests/live).

One sample at a time in plain floats, written from docs/live.md and the Python classes of ftcal.live (the motion
test :class:`~ftcal.live.motion.MotionDetector`, the drift test :class:`~ftcal.live.drift.DriftCheck`, the
self-check :class:`~ftcal.live.consistency.SelfCheck`): the tool's gravity wrench, the gated Kalman update of the
random-walk bias with the hold-off, the drift test's rollback at its snapshot times and the self-check's r and q
adaptation and re-acquisition. No numpy, no C: an independent second implementation of the same step.
"""

from __future__ import annotations

import math

from ftcal.data.holds import HOLD_WINDOW_S, MIN_ANGULAR_RATE, MIN_HOLD_S
from ftcal.live.calibrator import RETARE_VARIANCE
from ftcal.live.consistency import SelfCheck
from ftcal.live.drift import FALSE_ALARM, DriftCheck
from ftcal.live.motion import MotionDetector
from ftcal.live.tracker import HOLDOFF_S, MIN_FAIL_S, gate_chi2


class ReferenceStep:
    """The tracker of ``LiveCalibrator(tools={...: payload}, tool=..., noise_std=√noise, walk_std=...)`` on
    ``wrench=`` and ``gravity=`` samples.

    Parameters
    ----------
    payload : PayloadParameters or None, the tool mounted
    noise : six per-sample noise variances r
    walk : six walk variances per s, q
    limit : the acceptance thresholds (N, N·m) per axis
    gate_probability : the contact gate's χ² quantile
    self_check : the self-check adapts r and q (``LiveCalibrator(self_check=...)``)
    holdoff : s
    density : six wander densities D (N²·s; the update takes r + D / Δt, the gate r), None: white noise
    """

    def __init__(self, payload, noise, walk, limit, gate_probability=0.999, self_check=True, holdoff=HOLDOFF_S,
                 density=None):
        if payload is None:
            self.mass, self.mc, self.sign = 0.0, (0.0, 0.0, 0.0), 1.0
        else:
            self.mass = float(payload.mass)
            self.mc = tuple(self.mass * float(c) for c in payload.com)
            self.sign = -1.0 if payload.reaction else 1.0
        self.noise, self.walk, self.limit = [float(r) for r in noise], [float(q) for q in walk], list(limit)
        self.threshold = gate_chi2(gate_probability)
        self.bias, self.variance = [0.0] * 6, [RETARE_VARIANCE * r for r in self.noise]
        self.drift = DriftCheck(gate_chi2(1.0 - FALSE_ALARM))
        self.check = SelfCheck(list(self.noise), list(self.walk), self.threshold, gate_probability) if self_check \
            else None
        self.motion = MotionDetector(HOLD_WINDOW_S, MIN_ANGULAR_RATE, MIN_HOLD_S)
        self.holdoff = holdoff
        self.density = [0.0] * 6 if density is None else [float(d) for d in density]
        self.failure = (-math.inf, math.inf, False)
        self.last = None
        self.events = []  # (time, flag, kind, text) of the drift test and the self-check

    def step(self, t: float, w, g) -> dict:
        """One sample: wrench ``w`` (6), gravity ``g`` (3) in sensor axes."""
        still, _ = self.motion.static_one(t, "direction", tuple(g))
        m, (m0, m1, m2), sign = self.mass, self.mc, self.sign
        gx, gy, gz = g
        tool = (m * gx, m * gy, m * gz, m1 * gz - m2 * gy, m2 * gx - m0 * gz, m0 * gy - m1 * gx)
        z = [a - sign * b for a, b in zip(w, tool)]
        dt = 0.0 if self.last is None else t - self.last
        bias, variance, noise, walk = self.bias, self.variance, self.noise, self.walk
        predicted = [p + q * dt for p, q in zip(variance, walk)]
        s = [p + r for p, r in zip(predicted, noise)]
        e = [a - b for a, b in zip(z, bias)]
        chi2 = sum([x * (x / v) for x, v in zip(e, s)])
        last_fail, fail_start, previous = self.failure
        held = last_fail - fail_start >= MIN_FAIL_S and t - last_fail < self.holdoff
        updated = still and chi2 < self.threshold and not held
        if still and not chi2 < self.threshold:
            self.failure = (t, fail_start if previous else t, True)
        elif previous:
            self.failure = (last_fail, fail_start, False)
        if updated:
            r_u = [r + d / dt if dt > 0.0 and d > 0.0 else r for r, d in zip(noise, self.density)]
            total = [p + r for p, r in zip(predicted, r_u)]
            gain = [p / v for p, v in zip(predicted, total)]
            bias = [(1.0 - k) * b + k * c for k, b, c in zip(gain, bias, z)]
            variance = [p * r / v for p, r, v in zip(predicted, r_u, total)]
        else:
            variance = predicted
        due = t >= self.drift.next_due
        if due:
            back = self.drift.check(t, bias, variance, walk, self.limit)
            if back is not None:
                bias, variance = back[0], back[1]
                self.events.append((t, "bias", "rollback", back[2:]))  # lag, chi2, moved
        if self.check is not None:
            size = math.sqrt(gx * gx + gy * gy + gz * gz)
            self.check.observe_one(t, still, updated, still and not updated and chi2 >= self.threshold, z, e,
                                   predicted, s, (gx / size, gy / size, gz / size), bias, variance)
            if due:
                events, new_noise, new_walk, acquired = self.check.check(t, bias, list(noise), list(walk),
                                                                         list(variance), self.drift)
                self.events += [(t, "tracker", kind, text) for kind, text in events]
                if new_noise is not None:  # kept as a standard deviation, as LiveCalibrator.noise_std
                    self.noise = [math.sqrt(r) ** 2 for r in new_noise]
                if new_walk is not None:
                    self.walk = list(new_walk)
                if acquired is not None:
                    bias, variance = list(acquired[0]), list(acquired[1])
                    self.drift.reset()
        self.bias, self.variance, self.last = bias, variance, t
        return {"bias": bias, "bias_std": [math.sqrt(p) for p in variance], "compensated": e, "chi2": chi2,
                "static": still, "updated": updated}
