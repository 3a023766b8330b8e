"""The Zenoh node's own logic without a network: its diagnostics (ROS diagnostic_updater's convention: a period, and
at once on a flag change) never lose a flag that came and went between two messages, and its peer configuration."""

from __future__ import annotations

import json

import numpy as np

from ftcal.core.limits import LIVE_DIAGNOSTICS_MIN_INTERVAL_S, LIVE_DIAGNOSTICS_PERIOD_S
from ftcal.live import LiveCalibrator
from ftcal.live.cdr import encode_stamped
from ftcal.live.health import BIT
from ftcal.live.zenoh_node import LiveNode, ZenohOptions

NOISE = np.r_[np.full(3, 0.05), np.full(3, 0.004)]


class Sample:
    """What a Zenoh subscriber hands its callback: ``sample.payload.to_bytes()``."""

    def __init__(self, data: bytes) -> None:
        self.payload, self.data = self, data

    def to_bytes(self) -> bytes:
        return self.data


class Sink:
    def __init__(self) -> None:
        self.messages: list = []

    def put(self, payload, **_) -> None:
        self.messages.append(payload)


def node_with_sinks() -> LiveNode:
    node = LiveNode(LiveCalibrator(noise_std=NOISE), ZenohOptions(), echo=lambda *a, **k: None)
    node.publishers = {name: Sink() for name in ("calibrated", "compensated", "diagnostics")}
    return node


def test_a_contact_of_one_sample_reaches_the_next_diagnostics():
    node = node_with_sinks()
    rng = np.random.default_rng(3)
    rate, n = 1000, 1000  # 1 s still at 1 kHz: the bias is set, the motion test passes
    for k in range(n + 5):
        row = rng.normal(size=6) * NOISE + [0.0, 0.0, -11.8, 0.0, 0.0, 0.0]
        if k == n:
            row[0] += 10.0  # 200 σ on one sample: far beyond the χ² gate (22.5 for 6 dof at 0.999)
        node._on_wrench(Sample(encode_stamped(1_000_000_000 + k * 1_000_000_000 // rate, "ft", row.tolist())))
        if k == n - 1:
            node._diagnostics()  # a message just before the contact: nothing raised in it counts below
    assert len(node.publishers["compensated"].messages) == n + 5
    message = json.loads(node._diagnostics_message())
    assert "contact" not in message["flags"]  # the contact lasted one sample and is over
    assert "contact" in message["raised"]  # but this message reports it
    assert message["counters"]["contacts"] >= 1
    assert json.loads(node._diagnostics_message())["raised"] == {}  # reported once


def test_the_diagnostics_rates_are_ros_diagnostic_updaters():
    # diagnostic_updater's default period is 1 s (its diagnostic_updater.period parameter); flag changes force a message,
    # at most this many a second.
    assert LIVE_DIAGNOSTICS_PERIOD_S == 1.0
    assert 1.0 / LIVE_DIAGNOSTICS_MIN_INTERVAL_S <= 20


class FakeClock:
    """Simulated time for the node's main loop: ``wait`` advances the clock instead of sleeping, and, like the
    subscriber callback, flips the ``contact`` flag every ``flip_every`` s (and wakes the loop) when asked to."""

    def __init__(self, node: LiveNode, flip_every: float | None) -> None:
        self.now, self.node, self.flip_every = 0.0, node, flip_every
        self.next_flip = flip_every if flip_every is not None else float("inf")

    def monotonic(self) -> float:
        return self.now

    def wait(self, timeout: float) -> bool:
        if self.now + timeout < self.next_flip:
            self.now += timeout
            return False
        self.now = self.next_flip
        self.next_flip += self.flip_every
        before = self.node.live.flags_now
        self.node.live.flags_now ^= BIT["contact"]
        self.node.raised |= self.node.live.flags_now & ~before
        self.node.last_message = self.now
        return True

    def clear(self) -> None:
        pass


def diagnostics_in(seconds: float, flip_every: float | None, monkeypatch) -> int:
    import types

    from ftcal.live import node_core

    node = node_with_sinks()
    node.options = ZenohOptions(duration=seconds, silence=1e9)
    clock = FakeClock(node, flip_every)
    monkeypatch.setattr(node_core, "time", types.SimpleNamespace(monotonic=clock.monotonic))
    node.wake = clock
    node._loop()
    return len(node.publishers["diagnostics"].messages)


def test_diagnostics_every_period_when_nothing_changes(monkeypatch):
    # t = 0 (the first), then one per period: 0, 1, 2, 3 within 3.5 s
    assert LIVE_DIAGNOSTICS_PERIOD_S == 1.0
    assert diagnostics_in(3.5, None, monkeypatch) == 4


def test_diagnostics_are_capped_when_a_flag_flickers(monkeypatch):
    # the contact flag flips every millisecond for 2 s: one message per minimum interval (0.05 s), not 2,000
    count = diagnostics_in(2.0, 0.001, monkeypatch)
    assert 2.0 / LIVE_DIAGNOSTICS_MIN_INTERVAL_S <= count <= 2.0 / LIVE_DIAGNOSTICS_MIN_INTERVAL_S + 1
