"""Health flags of the live calibrator, one bit each, with the run-length state they need across blocks.

=================  ===================================================================================
flag               raised when
=================  ===================================================================================
``saturated``      an input channel sits at the ADC limits given, or holds one value for
                   :data:`~ftcal.data.signals.SATURATION_RUN` samples outside the calibration's range
``stuck``          an input channel holds one value for :data:`~ftcal.data.signals.STUCK_RUN` samples
                   while another channel moved by more than :data:`LOAD_STEPS` of its quantisation steps
                   since (a load change that should have moved it, as ``check`` asks: a channel resting on
                   one ADC value while another flickers by one count is a quiet sensor, not a stuck one)
``dead``           stuck for :data:`DEAD_RUN` samples
``out_of_range``   the inputs lie outside the calibration's training range or span
                   (the model's ``out_of_range``)
``temperature``    the temperature lies outside the calibration's (its temperature input's range)
``contact``        a static sample failed the innovation test: a wrench the tool and bias do not
                   explain; it did not update the bias
``unexplained``    an axis' innovation stayed beyond ``k σ`` and beyond ``check --accept``'s
                   threshold for longer than ``T`` s (static or moving)
``silent``         (transports) no input for longer than the silence timeout
=================  ===================================================================================
"""

from __future__ import annotations

import math

import numpy as np

from ..data.signals import SATURATION_RUN, STUCK_RUN

FLAGS = ("saturated", "stuck", "dead", "out_of_range", "temperature", "contact", "unexplained", "silent")
BIT = {name: 1 << i for i, name in enumerate(FLAGS)}
# A channel stuck this many samples is dead (the offline check calls 90 % of a recording dead).
DEAD_RUN = 10 * STUCK_RUN


# Another channel must move this many of its quantisation steps (its smallest change seen) for a load change
# (``check``'s rule: two steps; its noise term needs the recording's poses, which a live sensor does not give).
LOAD_STEPS = 2.0


def names_of(bits: int) -> list[str]:
    """The flag names set in ``bits``."""
    return [name for name in FLAGS if bits & BIT[name]]


class RunCounter:
    """Length of the current run of identical values of each channel, across blocks and single samples."""

    def __init__(self) -> None:
        self.last: list | None = None  # plain floats: the per-sample path reads them without numpy
        self.run: list | None = None

    def update(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Run lengths (n, c) including each sample, and which channels changed at each sample (n, c)."""
        n, c = x.shape
        if self.last is None or len(self.last) != c:
            self.last, self.run = [np.nan] * c, [0] * c
        previous = np.vstack([np.asarray(self.last, dtype=float)[None], x[:-1]])
        changed = x != previous
        index = np.arange(n)[:, None]
        since = np.maximum.accumulate(np.where(changed, index, -1), axis=0)  # last change at or before k
        run = np.where(since >= 0, index - since + 1, index + 1 + np.asarray(self.run, dtype=np.int64)[None])
        self.last, self.run = x[-1].tolist(), run[-1].tolist()
        return run, changed

    def update_one(self, x: list) -> tuple[list, list]:
        """:meth:`update` for one sample of plain floats: run lengths and changed flags, lists of length c."""
        if self.last is None or len(self.last) != len(x):
            self.last, self.run = [math.nan] * len(x), [0] * len(x)
        changed = [a != b for a, b in zip(x, self.last)]
        self.run = [1 if ch else r + 1 for ch, r in zip(changed, self.run)]
        self.last = list(x)
        return self.run, changed


class LoadChange:
    """Per channel: has another channel moved by more than :data:`LOAD_STEPS` of its quantisation step since this
    channel's value last changed (the run :class:`RunCounter` counts)? Across blocks and single samples.

    A channel's quantisation step is the smallest nonzero change it has shown (inf before its first change).
    """

    def __init__(self) -> None:
        self.step = self.ref = self.moved = self.last = None

    def _start(self, c: int) -> None:
        if self.step is None or len(self.step) != c:
            self.step, self.ref, self.moved, self.last = [math.inf] * c, [None] * c, [False] * c, None

    def update_one(self, x: list, changed: list) -> list:
        """Which channels' runs saw a load change, after the sample ``x`` (``changed``: from RunCounter)."""
        c = len(x)
        self._start(c)
        if self.last is not None:
            self.step = [min(st, abs(a - b)) if a != b else st for st, a, b in zip(self.step, x, self.last)]
        self.last = list(x)
        limit = [LOAD_STEPS * st for st in self.step]
        for j in range(c):
            if changed[j] or self.ref[j] is None:
                self.ref[j], self.moved[j] = list(x), False
            elif not self.moved[j]:
                ref = self.ref[j]
                self.moved[j] = any([o != j and abs(x[o] - ref[o]) > limit[o] for o in range(c)])
        return list(self.moved)

    def update(self, x: np.ndarray, changed: np.ndarray) -> np.ndarray:
        """:meth:`update_one` over a block, shape (n, c) of bool."""
        n, c = x.shape
        self._start(c)
        previous = np.vstack([np.asarray(self.last if self.last is not None else x[0], dtype=float)[None], x[:-1]])
        diff = np.abs(x - previous)
        diff[diff == 0] = np.inf
        step = np.minimum.accumulate(np.vstack([np.asarray(self.step, float)[None], diff]), axis=0)[1:]
        limit = LOAD_STEPS * step
        index = np.arange(n)
        moved = np.zeros((n, c), bool)
        for j in range(c):
            since = np.maximum.accumulate(np.where(changed[:, j], index, -1))
            old = self.ref[j] is not None
            ref = np.where((since >= 0)[:, None], x[np.maximum(since, 0)],
                           np.asarray(self.ref[j] if old else x[0], float)[None])
            exceed = np.abs(x - ref) > limit
            exceed[:, j] = False
            hit = np.maximum.accumulate(np.where(exceed.any(axis=1), index, -1))
            moved[:, j] = np.where(since >= 0, hit > since, (self.moved[j] if old else False) | (hit >= 0))
            last = int(since[-1])
            if last >= 0:
                self.ref[j] = x[last].tolist()
            elif not old:
                self.ref[j] = x[0].tolist()
            self.moved[j] = bool(moved[-1, j])
        self.step, self.last = step[-1].tolist(), x[-1].tolist()
        return moved


class ExceedanceTimer:
    """Time since the current run of exceedances began, across blocks (−inf outside a run)."""

    def __init__(self) -> None:
        self.start = np.nan  # start of the run in progress, or NaN

    def update(self, time: np.ndarray, exceed: np.ndarray) -> np.ndarray:
        n = time.size
        before = np.empty_like(exceed)
        before[0] = not np.isnan(self.start)
        before[1:] = exceed[:-1]
        begins = exceed & ~before
        start_index = np.maximum.accumulate(np.where(begins, np.arange(n), -1))
        start = np.where(start_index >= 0, time[np.maximum(start_index, 0)], self.start)
        duration = np.where(exceed, time - start, -np.inf)
        self.start = float(start[-1]) if exceed[-1] else np.nan
        return duration

    def update_one(self, time: float, exceed: bool) -> float:
        """:meth:`update` for one sample: the run's duration so far, or −inf."""
        if not exceed:
            self.start = math.nan
            return -math.inf
        if math.isnan(self.start):
            self.start = time
        return time - self.start
