"""A simulated six-axis strain-gauge F/T sensor, as the robot logger sees it.

The signal chain, for a true wrench ``w`` (N, Nm) at sensor temperature ``T`` (°C):

1. normalise: ``x = w / full_scale`` (design full scale per axis);
2. load-dependent stiffness: ``x / sqrt(1 + stiffening·‖x‖²)`` (the flexure stiffens
   under load);
3. strains: ``ε = C x`` with a dense cross-coupling matrix ``C = I + coupling·R``;
4. creep: ``ε`` relaxes towards its first-order low-pass (time constant ``creep_time``)
   by a fraction ``creep`` -- the only dynamic effect, and what ARX terms can absorb;
5. gauge factor: ``ε · exp(sensitivity_tc_i · (T − T_ref))`` (semiconductor gauges lose
   sensitivity as they warm);
6. half-bridge: ``z + asymmetry_i · z · tanh(z)`` (tension and compression differ; about
   ``asymmetry_i · z²`` near zero, without the pole of a resistance ratio);
7. zero offset and its thermal drift: ``+ offset_i + drift_i · (exp((T − T_ref)/drift_scale) − 1)``;
8. amplifier saturation: ``saturation · tanh(v / saturation)``;
9. noise (Gaussian, in ADC counts), 16-bit ADC over [−1, 1) full scale with clipping;
10. firmware: the board outputs ``W · counts + b`` where ``(W, b)`` is the affine
    calibration identified on a workbench at ``workbench_temperature`` with loads within
    ``workbench_force`` / ``workbench_torque`` (what iCub's strain boards do).

Steps 2, 5, 6, 7 and 8 are not polynomials, so no finite-degree polynomial in the logged
channels reproduces the wrench exactly; they are small near the workbench range and grow
with load and temperature, so an in-situ affine fit is off by several newtons at 10 kg.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.signal import lfilter

from ..runtime.checks import check_float, check_int
from ..runtime.errors import FtcalError

ADC_BITS = 16


@dataclass(frozen=True)
class SensorParams:
    """Physical magnitudes of a simulated sensor (the per-channel details are drawn from them).

    Attributes
    ----------
    force_full_scale, torque_full_scale : load (N, Nm) that drives a gauge to ADC full scale
    coupling : std of the off-diagonal cross-coupling entries, relative to the diagonal
    stiffening : relative stiffness gain at full-scale load (step 2)
    creep, creep_time : creep fraction and its time constant in s (step 4)
    sensitivity_tc, sensitivity_tc_spread : mean and spread of the gauge sensitivity
        temperature coefficients, 1/°C (step 5)
    asymmetry : std of the half-bridge asymmetries (step 6), full-scale units
    offset : std of the zero offsets, full-scale units
    drift, drift_scale : std of the thermal zero drift amplitudes (full-scale units) and
        its temperature scale in °C (step 7)
    saturation : amplifier saturation level in full-scale units (step 8); above 1 the
        ADC clips first
    noise_counts : standard deviation of the noise, ADC counts
    reference_temperature : T_ref, °C
    workbench_force, workbench_torque, workbench_temperature, workbench_samples :
        the off-situ affine calibration's load box (N, Nm), temperature (°C) and size
    """

    force_full_scale: float = 250.0
    torque_full_scale: float = 50.0
    coupling: float = 0.25
    stiffening: float = 0.8
    creep: float = 0.06
    creep_time: float = 8.0
    sensitivity_tc: float = -2.5e-3
    sensitivity_tc_spread: float = 0.5e-3
    asymmetry: float = 0.1
    offset: float = 0.05
    drift: float = 0.02
    drift_scale: float = 20.0
    saturation: float = 0.9
    noise_counts: float = 40.0
    reference_temperature: float = 25.0
    workbench_force: float = 60.0
    workbench_torque: float = 8.0
    workbench_temperature: float = 25.0
    workbench_samples: int = 2000

    def __post_init__(self) -> None:
        owner = "SensorParams"
        for name in ("force_full_scale", "torque_full_scale", "creep_time", "drift_scale",
                     "saturation", "workbench_force", "workbench_torque"):
            check_float(getattr(self, name), name, owner, 0.0, low_inclusive=False)
        for name in ("coupling", "stiffening", "creep", "sensitivity_tc_spread", "asymmetry",
                     "offset", "drift", "noise_counts"):
            check_float(getattr(self, name), name, owner, 0.0)
        for name in ("sensitivity_tc", "reference_temperature", "workbench_temperature"):
            check_float(getattr(self, name), name, owner, -np.inf)
        check_int(self.workbench_samples, "workbench_samples", owner, 7)

    @property
    def full_scale(self) -> np.ndarray:
        """Full-scale load per axis (Fx Fy Fz in N, Tx Ty Tz in Nm), shape (6,)."""
        return np.repeat([self.force_full_scale, self.torque_full_scale], 3)


@dataclass(frozen=True, eq=False)
class StrainGaugeSensor:
    """One simulated sensor: parameters plus the per-channel values drawn from them.

    Build it with :meth:`create`; the arrays are fixed for the sensor's life.

    Attributes
    ----------
    params : SensorParams
    coupling_matrix : ndarray of shape (6, 6), normalised load → gauge strain
    sensitivity_tc, asymmetry, offset, drift : ndarrays of shape (6,), per gauge channel
    workbench_matrix : ndarray of shape (6, 6), ADC counts → wrench (firmware calibration)
    workbench_offset : ndarray of shape (6,)
    """

    params: SensorParams
    coupling_matrix: np.ndarray
    sensitivity_tc: np.ndarray
    asymmetry: np.ndarray
    offset: np.ndarray
    drift: np.ndarray
    workbench_matrix: np.ndarray
    workbench_offset: np.ndarray

    @classmethod
    def create(cls, params: SensorParams | None = None, seed: int = 0) -> "StrainGaugeSensor":
        """Draw a sensor from ``params`` with ``numpy.random.default_rng(seed)``.

        The firmware calibration is identified here, by least squares on noise-free ADC
        counts of random workbench loads.
        """
        p = SensorParams() if params is None else params
        rng = np.random.default_rng(seed)
        coupling = np.eye(6) + p.coupling * rng.standard_normal((6, 6)) * (1 - np.eye(6))
        tc = p.sensitivity_tc + p.sensitivity_tc_spread * rng.standard_normal(6)
        draft = cls(p, coupling, tc, p.asymmetry * rng.standard_normal(6),
                    p.offset * rng.standard_normal(6), p.drift * rng.standard_normal(6),
                    np.eye(6), np.zeros(6))
        box = np.repeat([p.workbench_force, p.workbench_torque], 3)
        loads = rng.uniform(-box, box, size=(p.workbench_samples, 6))
        temps = np.full(p.workbench_samples, p.workbench_temperature)
        counts = draft.adc_counts(loads, temps).astype(np.float64)
        design = np.column_stack([counts, np.ones(len(counts))])
        solution = np.linalg.lstsq(design, loads, rcond=None)[0]
        return cls(p, coupling, tc, draft.asymmetry, draft.offset, draft.drift,
                   solution[:6].T.copy(), solution[6].copy())

    def analog(self, wrench: np.ndarray, temperature: np.ndarray,
               sample_rate: float | None = None) -> np.ndarray:
        """Noise-free amplifier outputs (steps 1–8), in ADC full-scale units.

        Parameters
        ----------
        wrench : ndarray of shape (n_samples, 6), true Fx Fy Fz (N) Tx Ty Tz (Nm)
        temperature : ndarray of shape (n_samples,), sensor temperature in °C
        sample_rate : Hz of consecutive samples (one recording); None skips creep

        Returns
        -------
        ndarray of shape (n_samples, 6)
        """
        w, temp = _check_inputs(wrench, temperature)
        p = self.params
        x = w / p.full_scale
        x = x / np.sqrt(1.0 + p.stiffening * np.sum(x * x, axis=1, keepdims=True))
        strain = x @ self.coupling_matrix.T
        if sample_rate is not None and p.creep > 0 and len(strain):
            strain = self._creep(strain, check_float(sample_rate, "sample_rate", "analog", 0.0, False))
        dt = (temp - p.reference_temperature)[:, None]
        z = strain * np.exp(self.sensitivity_tc * dt)
        v = z + self.asymmetry * z * np.tanh(z)
        v = v + self.offset + self.drift * np.expm1(dt / p.drift_scale)
        return p.saturation * np.tanh(v / p.saturation)

    def adc_counts(self, wrench: np.ndarray, temperature: np.ndarray,
                   rng: np.random.Generator | None = None,
                   sample_rate: float | None = None) -> np.ndarray:
        """16-bit ADC readings (steps 1–9); ``rng=None`` means no noise.

        The ADC maps [−1, 1) full scale onto [−32768, 32767] (step 2/2**16) and clips.

        Returns
        -------
        ndarray of shape (n_samples, 6), int32
        """
        v = self.analog(wrench, temperature, sample_rate)
        step = 2.0 / 2**ADC_BITS
        codes = v / step
        if rng is not None:
            codes = codes + self.params.noise_counts * rng.standard_normal(codes.shape)
        low, high = -(2 ** (ADC_BITS - 1)), 2 ** (ADC_BITS - 1) - 1
        return np.clip(np.rint(codes), low, high).astype(np.int32)

    def firmware_output(self, counts: np.ndarray) -> np.ndarray:
        """The board's workbench-calibrated output for ADC ``counts`` (n_samples, 6)."""
        return np.asarray(counts, dtype=np.float64) @ self.workbench_matrix.T + self.workbench_offset

    def measure(self, wrench: np.ndarray, temperature: np.ndarray,
                rng: np.random.Generator | None = None,
                sample_rate: float | None = None) -> np.ndarray:
        """The raw channels u1..u6 the robot logger stores (roughly N and Nm).

        Returns
        -------
        ndarray of shape (n_samples, 6)
        """
        return self.firmware_output(self.adc_counts(wrench, temperature, rng, sample_rate))

    def _creep(self, strain: np.ndarray, sample_rate: float) -> np.ndarray:
        # Discrete first-order low-pass started at rest on the first sample; the blend keeps
        # the static gain at 1, so only transients after load changes differ.
        a = np.exp(-1.0 / (self.params.creep_time * sample_rate))
        lagged = lfilter([1 - a], [1, -a], strain, axis=0, zi=a * strain[:1])[0]
        c = self.params.creep
        return (strain + c * lagged) / (1 + c)


def temperature_drift(time: np.ndarray, start: float, target: float,
                      time_constant: float = 600.0) -> np.ndarray:
    """Sensor temperature that relaxes from ``start`` towards ``target`` (°C).

    ``T(t) = target + (start − target)·exp(−(t − t0)/time_constant)`` with ``t0 = time[0]``:
    Newtonian warming by the motors (or cooling), slow against one recording.

    Parameters
    ----------
    time : ndarray of shape (n_samples,), s, non-decreasing

    Returns
    -------
    ndarray of shape (n_samples,)
    """
    t = np.asarray(time, dtype=np.float64)
    tau = check_float(time_constant, "time_constant", "temperature_drift", 0.0, low_inclusive=False)
    if t.ndim != 1:
        raise FtcalError(f"time must be a 1-D array; got shape {t.shape}.")
    if t.size == 0:
        return t.copy()
    return target + (start - target) * np.exp(-(t - t[0]) / tau)


def _check_inputs(wrench: np.ndarray, temperature: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    w = np.asarray(wrench, dtype=np.float64)
    temp = np.asarray(temperature, dtype=np.float64)
    if w.ndim != 2 or w.shape[1] != 6:
        raise FtcalError(f"wrench must have shape (n_samples, 6); got {w.shape}.")
    if temp.shape != (w.shape[0],):
        raise FtcalError(f"temperature must have shape ({w.shape[0]},); got {temp.shape}.")
    return w, temp
