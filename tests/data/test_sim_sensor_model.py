"""The configurable sensor of `ftcal simulate`: its channels invert to the truth, its mistakes are the named ones.

References: the true matrix inverted by hand (K · counts = w when the nonlinear, thermal, bias and noise
parts are off, within half an ADC count per channel), rotations composed with scipy, the variance of a
random walk (walk² · Δt per step), and JSON round trips.
"""

import dataclasses
import json

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from ftcal.runtime.errors import FtcalError
from ftcal.sim.sensor_model import SensorModel, SensorSpec, spec_from_json

LINEAR = SensorSpec(quadratic=0.0, cubic=0.0, gain_tc=0.0, gain_tc_spread=0.0, offset_tc=0.0, ramp=0.0, walk=0.0,
                    noise=0.0)


def wrenches(n, seed=0):
    rng = np.random.default_rng(seed)
    return rng.uniform(-1, 1, (n, 6)) * np.array([120, 120, 120, 10, 10, 10])


def test_linear_channels_invert_to_the_truth_with_the_true_matrix():
    sensor = LINEAR.draw(seed=4)
    w = wrenches(500)
    counts = sensor.counts(w, np.full(500, 40.0))  # temperature has no effect when its coefficients are 0
    recovered = (counts - sensor.offset * sensor.counts_per_full_scale) @ sensor.true_matrix.T
    # Rounding moves each channel by at most half a count; the matrix spreads that over the axes.
    bound = 0.5 * np.abs(sensor.true_matrix).sum(axis=1) + 1e-9
    assert np.all(np.abs(recovered - w) <= bound)
    # and the matrix is not the identity in disguise: the channels mix the axes
    assert np.abs(sensor.true_matrix - np.diag(np.diag(sensor.true_matrix))).max() > 1e-3


def test_nonlinear_sensor_departs_from_the_true_matrix_more_at_high_load():
    sensor = SensorSpec(noise=0.0, walk=0.0, ramp=0.0).draw(seed=1)
    temps = np.full(400, sensor.spec.reference_temperature)
    errors = []
    for scale in (0.1, 1.0):
        w = wrenches(400, 2) * scale
        counts = sensor.counts(w, temps, quantize=False)
        recovered = (counts - sensor.offset * sensor.counts_per_full_scale) @ sensor.true_matrix.T
        errors.append(np.sqrt(np.mean((recovered - w)[:, :3] ** 2)))
    # s|s| and s³ terms: relative error grows with the load
    assert errors[1] / 1.0 > 3 * errors[0] / 0.1


def test_mounting_mistakes():
    w = wrenches(50, 3)
    base = LINEAR.draw(seed=2)
    sign = dataclasses.replace(base, mistake="sign")
    np.testing.assert_array_equal(sign.mounted(w), -w)
    swap = dataclasses.replace(base, mistake="swap-xy")
    np.testing.assert_array_equal(swap.mounted(w)[:, [0, 1, 3, 4]], w[:, [1, 0, 4, 3]])
    turned = dataclasses.replace(base, mistake="rotate-z", mistake_deg=90.0)
    # a sensor turned +90° about z sees a vector v as R(90°)ᵀ v
    r = Rotation.from_euler("z", 90, degrees=True).inv()
    np.testing.assert_allclose(turned.mounted(w)[:, :3], r.apply(w[:, :3]), atol=1e-12)
    np.testing.assert_allclose(turned.mounted(w)[:, 3:], r.apply(w[:, 3:]), atol=1e-12)
    with pytest.raises(FtcalError, match="rotate-z needs an angle"):
        SensorSpec().draw(0, "rotate-z", 0.0)
    with pytest.raises(FtcalError, match="choose one of"):
        SensorSpec().draw(0, "upside-down")


def test_random_walk_has_the_stated_variance_and_the_ramp_its_slope():
    spec = dataclasses.replace(LINEAR, walk=1e-4, ramp=1e-5)
    sensor = spec.draw(seed=5)
    t = np.arange(200_001) * 0.01
    bias = sensor.bias(t, np.random.default_rng(0))
    steps = np.diff(bias - np.outer(t, sensor.ramp), axis=0)
    np.testing.assert_allclose(steps.var(axis=0), 1e-8 * 0.01, rtol=0.02)
    np.testing.assert_allclose(sensor.bias(t, None)[-1] - sensor.offset, sensor.ramp * t[-1], rtol=1e-12)


def test_factory_matrix_reads_workbench_loads_well_and_large_loads_worse():
    sensor = SensorSpec(noise=0.0, walk=0.0, ramp=0.0).draw(seed=6)
    temps = np.full(300, sensor.spec.reference_temperature)
    small = wrenches(300, 7) * 0.4  # inside the 60 N / 6 N m workbench box
    large = wrenches(300, 8) * 1.8
    err = [np.abs(sensor.factory_wrench(sensor.counts(w, temps, quantize=False)) - w)[:, :3].max()
           for w in (small, large)]
    assert err[0] < 1.0 < err[1]


def test_saturation_clips_at_the_stated_fraction_of_the_adc_range():
    sensor = dataclasses.replace(LINEAR, saturation=0.5).draw(seed=0)
    counts = sensor.counts(np.full((1, 6), 1e4), np.array([25.0]))
    assert np.all(np.abs(counts) <= 0.5 * 2 ** 15)
    assert np.all(np.abs(counts) >= 0.5 * 2 ** 15 - 1)


def test_json_round_trip_gives_the_same_counts():
    sensor = SensorSpec().draw(seed=9, mistake="rotate-z", mistake_deg=-30.0)
    text = json.dumps(sensor.to_dict())
    again = SensorModel.from_dict(json.loads(text))
    w, temps = wrenches(100, 10), np.linspace(20, 45, 100)
    t = np.arange(100) * 0.01
    a = sensor.counts(w, temps, sensor.bias(t, np.random.default_rng(1)), np.random.default_rng(2))
    b = again.counts(w, temps, again.bias(t, np.random.default_rng(1)), np.random.default_rng(2))
    np.testing.assert_array_equal(a, b)
    np.testing.assert_array_equal(sensor.factory_matrix, again.factory_matrix)
    assert spec_from_json(json.dumps({"sensor": sensor.to_dict()}), "x") == sensor.spec


@pytest.mark.parametrize("text, message", [
    ('{"noise": -1}', "'noise' must be >= 0"),
    ('{"bogus": 1}', "unknown sensor parameter"),
    ('{"crosstalk": 2}', "at most 0.5"),
    ("[1, 2]", "expected a JSON object"),
    ("{", "not JSON"),
])
def test_bad_sensor_parameters_are_one_line_errors(text, message):
    with pytest.raises(FtcalError, match=message):
        spec_from_json(text, "--sensor-file x.json")
