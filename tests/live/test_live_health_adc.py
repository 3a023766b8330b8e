"""``stuck``/``dead`` on a real ADC: only when a load change should have moved the channel (quantisation-aware,
as ``check`` asks). A 10-bit sensor at rest holds one count on a quiet channel while another flickers by one
count: that is not stuck (it was flagged on 45 % of samples); a channel frozen while the others swing by many
counts is."""

from __future__ import annotations

import numpy as np

from ftcal.live import LiveCalibrator
from ftcal.live.health import BIT

DOWN = [0.0, 0.0, -9.81]


def counts(n, seed=0, frozen_from=None):
    """Six 10-bit channels (counts, one count 0.05 N), the sensor still, a slow load swing from n // 2 on;
    channel 0 very quiet (it rests on one count), channel 1 flickering by one count; channel 2 frozen from
    ``frozen_from`` on."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) / 200.0
    load = np.where(t > t[n // 2], 40.0 * np.sin(2 * np.pi * 0.2 * (t - t[n // 2])), 0.0)  # counts
    level = np.array([512.2, 500.5, 480.0, 530.0, 470.0, 520.0])
    noise = rng.normal(size=(n, 6)) * np.array([0.05, 0.3, 0.3, 0.3, 0.3, 0.3])
    x = np.round(level + noise + load[:, None] * np.array([0.3, -0.4, 1.0, 0.5, -0.5, 1.0]))
    if frozen_from is not None:
        x[frozen_from:, 2] = x[frozen_from, 2]
    return t, x


def flags_of(t, x, block):
    live = LiveCalibrator(noise_std=np.full(6, 0.05))
    w = x * 0.05
    if block:
        return live.run(t, wrench=w, gravity=np.tile(DOWN, (t.size, 1))).flags
    return np.array([sum(BIT[f] for f in live.step(a, wrench=b, gravity=DOWN).flags) for a, b in zip(t, w)])


def test_a_quiet_channel_on_one_count_beside_a_flickering_one_is_not_stuck():
    t, x = counts(4000)
    quiet = t < t[2000]
    assert np.max(np.ptp(x[quiet][:, 0:1], axis=0)) <= 1 and np.ptp(x[quiet, 1]) >= 1  # the 10-bit picture
    flags = flags_of(t, x, block=True)
    assert not np.any(flags[quiet] & (BIT["stuck"] | BIT["dead"]))


def test_a_frozen_channel_under_a_load_swing_is_stuck_and_blocks_agree_with_steps():
    t, x = counts(4000, frozen_from=2200)
    block, steps = flags_of(t, x, block=True), flags_of(t, x, block=False)
    np.testing.assert_array_equal(block, steps)
    stuck = (block & (BIT["stuck"] | BIT["dead"])) != 0
    assert not stuck[:2200].any()
    # the others swing by tens of counts within the 200 samples after the freeze: stuck from then on
    assert stuck[2200 + 200 + 50:].mean() > 0.95


def counts_model():
    """A linear calibration of six 10-bit channels (one count 0.05 N) fitted on loaded counts 600 to 900 only."""
    from ftcal.core.dataset import Dataset
    from ftcal.core.model import CalibrationModel

    rng = np.random.default_rng(3)
    x = np.round(rng.uniform(600.0, 900.0, size=(3000, 6)))
    return CalibrationModel(1).fit(Dataset.from_arrays(x, (x - 512.0) * 0.05))


def test_a_10_bit_sensor_at_rest_below_the_training_range_is_not_saturated():
    """At rest (counts near 500, below the 600-900 the calibration saw) a quiet channel holds one count for hundreds
    of samples: out of range, but no clipping (no load change moved the others); a channel pinned at the ADC's rail
    (1023) while the load swings is saturated."""
    model = counts_model()
    t, x = counts(4000)
    live = LiveCalibrator(model, noise_std=np.full(6, 0.05))
    quiet = t < t[2000]
    x[2500:, 5] = 1023.0  # channel 6 clipped at the rail during the swing
    flags = live.run(t, raw=x, gravity=np.tile(DOWN, (t.size, 1))).flags
    assert np.all(flags[quiet] & BIT["out_of_range"])  # the rest is outside the training range ...
    assert not np.any(flags[quiet] & BIT["saturated"])  # ... and not clipping
    assert np.mean(flags[2600:] & BIT["saturated"] != 0) > 0.95
    steps = LiveCalibrator(model, noise_std=np.full(6, 0.05))
    one = [sum(BIT[f] for f in steps.step(a, raw=b, gravity=DOWN).flags) for a, b in zip(t[:600], x[:600])]
    np.testing.assert_array_equal(one, flags[:600])
