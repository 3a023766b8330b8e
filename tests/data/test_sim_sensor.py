"""The simulated strain-gauge sensor: ADC, clipping, non-polynomial response, seeding."""

import itertools

import numpy as np
import pytest

from ftcal.runtime.errors import FtcalError
from ftcal.sim.sensor import SensorParams, StrainGaugeSensor, temperature_drift

STEP = 2.0 / 2**16  # ADC spans [-1, 1) full scale with 16 bits


def _random_loads(rng, n):
    # A box like the paper's Table I (N, Nm).
    low = np.array([-30, -120, -113, -4, -5, -12.5])
    high = np.array([124, 34, 114, 27, 25.5, 7])
    return rng.uniform(low, high, size=(n, 6)), rng.uniform(25, 44, size=n)


def test_counts_are_the_quantized_analog_signal():
    sensor = StrainGaugeSensor.create(seed=1)
    w, t = _random_loads(np.random.default_rng(0), 500)
    analog = sensor.analog(w, t)
    counts = sensor.adc_counts(w, t)
    assert counts.dtype == np.int32
    assert np.all(np.abs(counts * STEP - analog) <= STEP / 2 + 1e-12)


def test_adc_clips_at_16_bit_limits():
    # No stiffening and a late amplifier saturation, so the ADC is the first limit.
    params = SensorParams(saturation=50.0, stiffening=0.0, asymmetry=0.0, coupling=0.0)
    sensor = StrainGaugeSensor.create(params, seed=1)
    huge = np.diag([5e3, -5e3, 5e3, -1e3, 1e3, -1e3])  # 20x full scale on each axis
    counts = sensor.adc_counts(huge, np.full(6, 25.0), rng=np.random.default_rng(0))
    assert np.array_equal(np.diag(counts), [32767, -32768, 32767, -32768, 32767, -32768])
    assert np.all(np.abs(counts[~np.eye(6, dtype=bool)]) < 32767)


def test_noise_has_the_requested_spread_in_counts():
    params = SensorParams(noise_counts=25.0)
    sensor = StrainGaugeSensor.create(params, seed=2)
    w = np.tile([10.0, -5.0, 20.0, 1.0, 0.5, -0.2], (20000, 1))
    t = np.full(len(w), 30.0)
    clean = sensor.adc_counts(w, t)
    noisy = sensor.adc_counts(w, t, rng=np.random.default_rng(0))
    spread = (noisy - clean).std(axis=0)
    # Quantization adds variance 1/12 count^2 on top of 25^2.
    assert np.allclose(spread, np.sqrt(25.0**2 + 1 / 12), rtol=0.03)


def test_not_exactly_a_polynomial_of_degree_5():
    sensor = StrainGaugeSensor.create(seed=3)
    w, t = _random_loads(np.random.default_rng(4), 12000)
    counts = sensor.adc_counts(w, t)
    u = sensor.firmware_output(counts)
    # Noise floor: the quantization error, carried to the output.
    floor = np.sqrt(np.mean((u - sensor.firmware_output(sensor.analog(w, t) / STEP)) ** 2, axis=0))
    x = np.column_stack([u / 100, (t - 35) / 10])
    cols = [np.ones(len(x))] + [np.prod(x[:, list(c)], axis=1)
                               for p in range(1, 6)
                               for c in itertools.combinations_with_replacement(range(7), p)]
    a = np.column_stack(cols)
    assert a.shape[1] == 792  # 1 + sum_p C(7+p-1, p), p = 1..5
    coef = np.linalg.lstsq(a, w, rcond=None)[0]
    residual = np.sqrt(np.mean((a @ coef - w) ** 2, axis=0))
    assert np.all(residual[:3] > 5 * floor[:3])


def test_firmware_error_grows_with_load():
    sensor = StrainGaugeSensor.create(seed=5)
    rng = np.random.default_rng(6)
    direction = rng.standard_normal((2000, 3))
    direction /= np.linalg.norm(direction, axis=1, keepdims=True)
    temps = np.full(2000, 25.0)
    errors = {}
    for mass in (1.0, 10.0):
        w = np.hstack([mass * 9.81 * direction, np.zeros((2000, 3))])
        errors[mass] = np.abs(sensor.measure(w, temps)[:, :3] - w[:, :3]).mean()
    # The firmware calibration is affine, fitted within 60 N: a few newtons off at 10 kg.
    assert errors[10.0] > 2 * errors[1.0]
    assert errors[10.0] > 1.0


def test_temperature_changes_the_reading_of_a_fixed_load():
    sensor = StrainGaugeSensor.create(seed=7)
    w = np.tile([60.0, -40.0, 30.0, 5.0, 3.0, -1.0], (2, 1))
    u = sensor.measure(w, np.array([25.0, 44.0]))
    assert np.linalg.norm(u[0, :3] - u[1, :3]) > 1.0  # newtons


def test_creep_keeps_the_static_gain():
    sensor = StrainGaugeSensor.create(seed=8)
    w = np.tile([50.0, 10.0, -20.0, 2.0, -3.0, 1.0], (300, 1))
    t = np.full(300, 30.0)
    assert np.allclose(sensor.analog(w, t, sample_rate=100.0), sensor.analog(w, t))


def test_creep_lags_after_a_step():
    sensor = StrainGaugeSensor.create(seed=8)
    w = np.zeros((3000, 6))
    w[1000:, 0] = 100.0
    t = np.full(3000, 30.0)
    lagging = sensor.analog(w, t, sample_rate=100.0)
    static = sensor.analog(w, t)
    just_after, long_after = 1001, 2999  # 20 s later is 2.5 creep time constants
    gap = np.abs(lagging - static)
    assert gap[just_after].max() > 10 * gap[long_after].max()


def test_seeded_sensors_and_measurements_are_reproducible():
    a, b, c = (StrainGaugeSensor.create(seed=s) for s in (11, 11, 12))
    assert np.array_equal(a.coupling_matrix, b.coupling_matrix)
    assert np.array_equal(a.workbench_matrix, b.workbench_matrix)
    assert not np.array_equal(a.coupling_matrix, c.coupling_matrix)
    w, t = _random_loads(np.random.default_rng(0), 100)
    first = a.measure(w, t, np.random.default_rng(5), 100.0)
    second = b.measure(w, t, np.random.default_rng(5), 100.0)
    assert np.array_equal(first, second)


def test_temperature_drift_follows_newton_cooling():
    time = np.array([0.0, 600.0, 1e6])
    temp = temperature_drift(time, start=30.0, target=40.0, time_constant=600.0)
    assert temp[0] == 30.0
    assert temp[1] == pytest.approx(40.0 - 10.0 * np.exp(-1.0))
    assert temp[2] == pytest.approx(40.0)


def test_bad_parameters_and_shapes_are_rejected():
    with pytest.raises(FtcalError, match="'saturation' parameter of SensorParams"):
        SensorParams(saturation=0.0)
    sensor = StrainGaugeSensor.create(seed=0)
    with pytest.raises(FtcalError, match="wrench must have shape"):
        sensor.measure(np.zeros((3, 5)), np.zeros(3))
    with pytest.raises(FtcalError, match="temperature must have shape"):
        sensor.measure(np.zeros((3, 6)), np.zeros(4))
