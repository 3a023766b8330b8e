"""Simulated recordings like three kinds of real third-party F/T data (issue 44), with their truth.

Each generator simulates the *physics* of a sensor, not ftcal's model: the raw channels are a
cross-coupled, saturating response of the true wrench that no polynomial of finite degree
reproduces, read through coloured noise, gain errors and a quantising converter, against a
reference wrench mis-measured by a constant per load case (a weight's mass, a lever arm, a
tilt). The splits are the ones real calibrations are judged on: whole load cases, one
orientation, one load level, random tenths, whole load directions.

- :func:`optical_sensor`: 8 photodiodes behind knife-edge shutters on a compliant structure
  (Gaussian-beam occlusion, an erfc curve per channel), 47 load cases of hung weights in 6
  orientations, LED gain drifting between load cases, AR(1) noise, a 12-bit converter.
- :func:`bench_plate`: a six-bridge plate (:class:`~ftcal.sim.sensor.StrainGaugeSensor`:
  flexure stiffening, half-bridge asymmetry, amplifier saturation, thermal drift) loaded at 12
  points and directions at 5 load levels, one averaged row per load (60 rows).
- :func:`fingertip_sensor`: a soft fingertip with a magnet in its elastomer and 8 Hall sensors
  (dipole field, Hertzian normal stiffening, shear stiffness growing with the normal load,
  saturating Hall outputs), 19 load directions x 22 magnitudes, one row per load (418 rows).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.signal import lfilter
from scipy.special import erfc
from scipy.spatial.transform import Rotation

from ..core.dataset import DEFAULT_OUTPUTS, Dataset
from ..core.select import grouped_folds
from ..runtime.checks import check_choice, check_float, check_int
from ..runtime.errors import FtcalError
from .sensor import SensorParams, StrainGaugeSensor, temperature_drift

GRAVITY = 9.81
SPLITS = ("cases", "orientation", "level", "tenths", "direction")


@dataclass(frozen=True, eq=False)
class RealLikeTable:
    """One simulated recording: raw channels, the reference the lab wrote down and the true wrench.

    Attributes
    ----------
    name : str
        ``"optical"``, ``"plate"`` or ``"fingertip"``.
    inputs : ndarray of shape (n_samples, n_channels)
        The raw channels as logged (converter codes or volts).
    reference : ndarray of shape (n_samples, 6)
        The reference wrench (N, N·m): the truth plus the per-load-case reference error.
    truth : ndarray of shape (n_samples, 6)
        The wrench the sensor really carried.
    groups : ndarray of str, shape (n_samples,)
        The load case of each sample (what grouped validation holds out whole).
    labels : dict of str -> ndarray of str
        Coarser labels of each sample a split may hold out whole (``orientation``, ``level``,
        ``direction``).
    input_names : tuple of str
    """

    name: str
    inputs: np.ndarray
    reference: np.ndarray
    truth: np.ndarray
    groups: np.ndarray
    labels: dict = field(default_factory=dict)
    input_names: tuple = ()

    @property
    def n_samples(self) -> int:
        return int(self.inputs.shape[0])

    def dataset(self, rows: np.ndarray | None = None) -> Dataset:
        """The rows (a boolean mask; all when None) as a grouped :class:`~ftcal.core.dataset.Dataset`."""
        keep = np.ones(self.n_samples, bool) if rows is None else np.asarray(rows, bool)
        return Dataset.from_arrays(self.inputs[keep], self.reference[keep], input_names=self.input_names,
                                   output_names=DEFAULT_OUTPUTS, groups=self.groups[keep])


def held_out_masks(table: RealLikeTable, split: str, n_folds: int = 5, seed: int = 0) -> list[np.ndarray]:
    """The held-out rows of each fold of ``split``, as boolean masks (each row in exactly one).

    Parameters
    ----------
    table : RealLikeTable
    split : {"cases", "orientation", "level", "tenths", "direction"}
        ``cases``: ``n_folds`` folds of whole load cases (:func:`~ftcal.core.select.grouped_folds`);
        ``orientation``/``level``: one fold per orientation / load level; ``tenths``: ten folds of
        random rows (``seed``); ``direction``: ``n_folds`` folds of whole load directions.
    n_folds : int >= 2
    seed : int

    Returns
    -------
    list of ndarray of bool, shape (n_samples,)
    """
    check_choice(split, "split", "held_out_masks", SPLITS)
    n_folds = check_int(n_folds, "n_folds", "held_out_masks", 2)
    if split == "cases":
        return grouped_folds(table.groups, n_folds, seed=seed)
    if split == "tenths":
        order = np.random.default_rng(seed).permutation(table.n_samples)
        fold = np.empty(table.n_samples, int)
        fold[order] = np.arange(table.n_samples) % 10
        return [fold == f for f in range(10)]
    if split not in table.labels:
        raise FtcalError(f"split {split!r}: the {table.name} table has no {split} labels; it has "
                         f"{', '.join(('cases', 'tenths', *table.labels))}.")
    labels = table.labels[split]
    if split == "direction":
        return grouped_folds(labels, n_folds, seed=seed)
    return [labels == value for value in np.unique(labels)]


# ----------------------------------------------------------------------------- shared pieces of the world
def ar1_noise(rng: np.random.Generator, shape: tuple[int, int], std: np.ndarray | float,
              correlation: float) -> np.ndarray:
    """Coloured (AR(1)) noise along the first axis with stationary standard deviation ``std``.

    Parameters
    ----------
    rng : numpy.random.Generator
    shape : (n_samples, n_channels)
    std : float or ndarray of shape (n_channels,)
    correlation : float in [0, 1), the lag-one correlation

    Returns
    -------
    ndarray of shape ``shape``
    """
    white = rng.standard_normal(shape) * np.sqrt(1.0 - correlation ** 2)
    start = rng.standard_normal((1, shape[1]))  # started in its stationary state
    return lfilter([1.0], [1.0, -correlation], white, axis=0, zi=correlation * start)[0] * std


def quantise(values: np.ndarray, low: float, high: float, bits: int) -> np.ndarray:
    """Codes of a ``bits``-bit converter over [low, high] (rounded, clipped), as floats."""
    step = (high - low) / 2 ** bits
    return np.clip(np.rint((values - low) / step), 0, 2 ** bits - 1)


def gravity_wrench(mass: np.ndarray, gravity_direction: np.ndarray, lever: np.ndarray) -> np.ndarray:
    """Statics of a hung weight: ``F = m g d``, ``T = r × F`` (N, N·m), one row per load case."""
    force = GRAVITY * mass[:, None] * gravity_direction
    return np.c_[force, np.cross(lever, force)]


def _per_case(values: np.ndarray, per: int) -> np.ndarray:
    return np.repeat(values, per, axis=0)


# ----------------------------------------------------------------------------- the optical sensor
def optical_sensor(seed: int = 0, n_cases: int = 47, n_orientations: int = 6, per_case: int = 20,
                   nonlinearity: float = 1.0, reference_error: float = 1.0, noise: float = 1.0,
                   bits: int = 12) -> RealLikeTable:
    """An optical six-axis sensor with 8 photodiode channels, calibrated with hung weights.

    A compliant structure moves 8 knife-edge shutters across Gaussian LED beams: shutter ``c``
    moves ``d_c = (S · w / full_scale)_c`` beam widths (``S`` dense, 8 x 6, each channel sensing
    several axes) from an operating point ``d0_c`` on the slope of its curve, and its photodiode
    reads ``I_c = I0_c + (0.5 · erfc((d0_c + k d_c) / √2) − I0_c) / k`` of the LED's power, with
    ``I0_c = 0.5 · erfc(d0_c / √2)`` and ``k = nonlinearity`` (→ 0: the tangent line; 1: loads reach
    the curve's knees). The LED powers drift between
    load cases (a slow random walk, 0.05 % a case), the channels carry AR(1) noise (lag-one
    correlation 0.9) and a ``bits``-bit converter reads them.

    Load cases: in each of ``n_orientations`` tilts of the sensor a loading tool hangs a weight
    (0.3-4 kg, plus the tool's 0.2 kg) from one of 9 hooks; the reference uses the nominal mass,
    hook and tilt, the truth the real ones (mass 0.3 %, hook 1 mm, tilt 0.4 degrees, times
    ``reference_error``).

    Parameters
    ----------
    seed : int
        The recording (loads, errors, noise); the sensor itself is the same for every seed.
    n_cases, n_orientations, per_case : int
        Load cases, orientations they are spread over, samples per load case.
    nonlinearity, reference_error, noise : float >= 0
        Scales of the curves' reach, the reference errors and the noise (1: the nominal sensor).
    bits : int
        Converter resolution.

    Returns
    -------
    RealLikeTable
        Inputs ``o1..o8`` (converter codes), labels ``orientation``.
    """
    owner = "optical_sensor"
    n_cases = check_int(n_cases, "n_cases", owner, 2)
    n_orientations = check_int(n_orientations, "n_orientations", owner, 1, n_cases)
    per_case = check_int(per_case, "per_case", owner, 1)
    for name, value in (("nonlinearity", nonlinearity), ("reference_error", reference_error), ("noise", noise)):
        check_float(value, name, owner, 0.0)
    bits = check_int(bits, "bits", owner, 4, 24)
    law = np.random.default_rng(4401)  # the sensor
    full_scale = np.array([150.0, 150.0, 150.0, 10.0, 10.0, 10.0])
    sensing = law.normal(0.0, 0.5, (8, 6)) + 0.8 * np.eye(8, 6) + 0.8 * np.eye(8, 6, -2)
    operating = law.uniform(-0.6, 0.6, 8)
    hooks = np.array([[0, 0, 0.04], [0.06, 0, 0.04], [-0.06, 0, 0.04], [0, 0.06, 0.04], [0, -0.06, 0.04],
                      [0.04, 0.04, 0.08], [-0.04, -0.04, 0.08], [0.04, -0.04, 0.02], [-0.04, 0.04, 0.02]])
    rng = np.random.default_rng(seed)
    tilts = Rotation.random(n_orientations, random_state=rng.integers(2 ** 31))
    directions = tilts.inv().apply([0.0, 0.0, -1.0])  # gravity in the sensor frame
    orientation = np.arange(n_cases) % n_orientations
    mass = rng.uniform(0.3, 4.0, n_cases) + 0.2
    hook = hooks[rng.integers(len(hooks), size=n_cases)]
    nominal = gravity_wrench(mass, directions[orientation], hook)
    e = reference_error
    tilt_error = Rotation.from_rotvec(np.deg2rad(0.4 * e) * rng.standard_normal((n_cases, 3)))
    true = gravity_wrench(mass * (1 + 0.003 * e * rng.standard_normal(n_cases)),
                          tilt_error.apply(directions[orientation]), hook + 0.001 * e * rng.standard_normal((n_cases, 3)))
    truth, reference = _per_case(true, per_case), _per_case(nominal, per_case)
    shift = (truth / full_scale) @ sensing.T
    # The curve's reach scaled by k about the operating point, its slope there kept (k -> 0: the tangent)
    k = max(nonlinearity, 1e-6)
    rest = 0.5 * erfc(operating / np.sqrt(2.0))
    intensity = rest + (0.5 * erfc((operating + k * shift) / np.sqrt(2.0)) - rest) / k
    led = 1.0 + np.cumsum(0.0005 * noise * rng.standard_normal((n_cases, 8)), axis=0)
    light = intensity * _per_case(led, per_case) + ar1_noise(rng, intensity.shape, 2e-4 * noise, 0.9)
    codes = quantise(light, -0.05, 1.05, bits)
    groups = np.repeat([f"case{g:02d}" for g in range(n_cases)], per_case)
    return RealLikeTable("optical", codes, reference, truth, groups,
                         {"orientation": _per_case(np.array([f"o{o}" for o in orientation]), per_case)},
                         tuple(f"o{i}" for i in range(1, 9)))


# ----------------------------------------------------------------------------- the bench plate
PLATE_PARAMS = SensorParams(force_full_scale=1000.0, torque_full_scale=100.0, coupling=0.2, stiffening=0.3,
                            creep=0.0, asymmetry=0.05, offset=0.05, drift=0.01, saturation=1.2, noise_counts=30.0,
                            workbench_force=150.0, workbench_torque=15.0, workbench_samples=200)


def bench_plate(seed: int = 0, levels: tuple = (100.0, 200.0, 300.0, 400.0, 500.0), n_points: int = 12,
                samples_per_load: int = 50, reference_error: float = 1.0,
                params: SensorParams = PLATE_PARAMS) -> RealLikeTable:
    """A six-bridge bench plate loaded at ``n_points`` points and directions at each load level.

    The channels are the 16-bit codes of :class:`~ftcal.sim.sensor.StrainGaugeSensor` (flexure
    stiffening, half-bridge asymmetry, amplifier saturation, thermal zero drift; ``params``) averaged
    over ``samples_per_load`` samples of one hold, the plate warming by 3 °C over the session. A load
    of level ``L`` pushes at a point ``r`` 30 mm above the plate's centre within ±0.12 m, along a
    direction within 35 degrees of −z (the first point straight down), so ``T = r × F``; the reference
    uses the nominal level, point and direction, the truth the real ones (0.2 %, 1.5 mm, 0.5 degrees,
    times ``reference_error``).

    Parameters
    ----------
    seed : int
        The loads, errors and noise; the plate is the same for every seed.
    levels : tuple of float
        Load levels, N.
    n_points : int
        Load points (each with its direction) per level.
    samples_per_load, reference_error : the hold's length and the reference errors' scale
    params : SensorParams

    Returns
    -------
    RealLikeTable
        Inputs ``u1..u6`` (averaged codes), one row and one load case per load, labels ``level``.
    """
    owner = "bench_plate"
    n_points = check_int(n_points, "n_points", owner, 1)
    samples_per_load = check_int(samples_per_load, "samples_per_load", owner, 1)
    check_float(reference_error, "reference_error", owner, 0.0)
    levels = np.asarray(levels, dtype=np.float64)
    if levels.ndim != 1 or levels.size < 1 or not np.all(levels > 0):
        raise FtcalError(f"levels must be positive loads in N; got {levels.tolist()}.")
    plate = StrainGaugeSensor.create(params, seed=4402)
    rng = np.random.default_rng(seed)
    point = np.c_[rng.uniform(-0.12, 0.12, (n_points, 2)), np.full(n_points, 0.03)]
    tilt = np.deg2rad(rng.uniform(0.0, 35.0, n_points))
    tilt[0] = 0.0
    azimuth = rng.uniform(0.0, 2 * np.pi, n_points)
    direction = np.c_[np.sin(tilt) * np.cos(azimuth), np.sin(tilt) * np.sin(azimuth), -np.cos(tilt)]
    n = levels.size * n_points
    level, where = np.repeat(levels, n_points), np.tile(np.arange(n_points), levels.size)
    e = reference_error

    def wrench(magnitude, points, directions):
        force = magnitude[:, None] * directions
        return np.c_[force, np.cross(points, force)]

    reference = wrench(level, point[where], direction[where])
    wobble = Rotation.from_rotvec(np.deg2rad(0.5 * e) * rng.standard_normal((n, 3)))
    truth = wrench(level * (1 + 0.002 * e * rng.standard_normal(n)),
                   point[where] + 0.0015 * e * rng.standard_normal((n, 3)), wobble.apply(direction[where]))
    order = rng.permutation(n)  # the loads in the order they were applied
    temperature = np.empty(n)
    temperature[order] = temperature_drift(np.arange(n) * 60.0, 25.0, 28.0, time_constant=1800.0)
    hold = np.repeat(truth, samples_per_load, axis=0)
    codes = plate.adc_counts(hold, np.repeat(temperature, samples_per_load), rng).astype(np.float64)
    rows = codes.reshape(n, samples_per_load, 6).mean(axis=1)
    groups = np.array([f"load{i:02d}" for i in range(n)])
    return RealLikeTable("plate", rows, reference, truth, groups,
                         {"level": np.array([f"{v:g}N" for v in level])}, tuple(f"u{i}" for i in range(1, 7)))


# ----------------------------------------------------------------------------- the fingertip
def fingertip_sensor(seed: int = 0, n_directions: int = 19, per_direction: int = 22, nonlinearity: float = 1.0,
                     reference_error: float = 1.0, noise: float = 1.0) -> RealLikeTable:
    """A soft fingertip: a magnet in an elastomer dome read by 8 Hall sensors, pressed from many directions.

    Mechanics (hysteresis-free, strongly nonlinear and direction-dependent): for a push of normal
    component ``Fn = −Fz ≥ 0`` the magnet sinks ``δz = −c_n Fn^(2/3)`` (Hertzian contact); shear moves
    it ``δxy = c_t F_xy / (1 + Fn/F0)^(1/3)`` (the contact patch, and so the shear stiffness, grows with
    the push); torque tilts it ``θ = c_r T_xy / (1 + Fn/F0)^(1/3)``. Each Hall sensor, 4.5 mm around
    and 3 mm below the magnet, reads the dipole field's component along its axis (4 vertical, 4
    radial), and its amplifier saturates: ``v = 1.65 + 1.4 tanh(field / field_0)`` V, read by a
    12-bit converter over 0-3.3 V with AR(1) noise. ``nonlinearity`` scales the displacements (0.3:
    nearly linear; 1: the nominal dome).

    Loads: ``n_directions`` load directions (a contact point on the dome, up to 45 degrees off its
    apex, pushed within 25 degrees of its inward normal), each at ``per_direction`` magnitudes from
    0.2 to 6 N; ``T = r × F`` about the sensor's base. The reference is a commercial sensor's
    reading: the truth plus an error drawn per load (0.5 % gain, 0.02 N and 0.3 N·mm offsets, times
    ``reference_error``).

    Parameters
    ----------
    seed : int
        The loads, errors and noise; the fingertip is the same for every seed.
    n_directions, per_direction : int
    nonlinearity, reference_error, noise : float >= 0

    Returns
    -------
    RealLikeTable
        Inputs ``v1..v8`` (volts), one row per load; a load case is one press (a direction's ramp), so
        ``groups`` are the load directions, also labelled ``direction``.
    """
    owner = "fingertip_sensor"
    n_directions = check_int(n_directions, "n_directions", owner, 1)
    per_direction = check_int(per_direction, "per_direction", owner, 1)
    for name, value in (("nonlinearity", nonlinearity), ("reference_error", reference_error), ("noise", noise)):
        check_float(value, name, owner, 0.0)
    law = np.random.default_rng(4403)
    angle = np.arange(4) * np.pi / 2 + law.normal(0.0, 0.05, 4)
    ring = np.c_[4.5 * np.cos(angle), 4.5 * np.sin(angle), np.full(4, -3.0)]
    hall = np.vstack([ring, np.c_[ring[:, :2] * 1.1, ring[:, 2]]])  # mm from the magnet at rest
    axis = np.vstack([np.tile([0.0, 0.0, 1.0], (4, 1)), np.c_[np.cos(angle), np.sin(angle), np.zeros(4)]])
    rng = np.random.default_rng(seed)
    polar, azimuth = np.deg2rad(rng.uniform(0, 45, n_directions)), rng.uniform(0, 2 * np.pi, n_directions)
    normal = np.c_[np.sin(polar) * np.cos(azimuth), np.sin(polar) * np.sin(azimuth), np.cos(polar)]
    contact = np.array([0.0, 0.0, 0.012]) + 0.010 * normal  # m: a 10 mm dome 12 mm above the base
    tilt = Rotation.from_rotvec(np.deg2rad(25) * np.sqrt(rng.uniform(0, 1, n_directions))[:, None]
                                * _unit_perpendicular(rng, normal))
    push = tilt.apply(-normal)
    magnitude = np.tile(np.linspace(0.2, 6.0, per_direction), n_directions) * rng.uniform(0.95, 1.05,
                                                                                        n_directions * per_direction)
    which = np.repeat(np.arange(n_directions), per_direction)
    force = magnitude[:, None] * push[which]
    truth = np.c_[force, np.cross(contact[which], force)]
    n = truth.shape[0]
    e = reference_error
    reference = truth * (1 + 0.005 * e * rng.standard_normal((n, 6))) \
        + e * np.r_[0.02, 0.02, 0.02, 3e-4, 3e-4, 3e-4] * rng.standard_normal((n, 6))
    pushing = np.maximum(-truth[:, 2], 0.0)
    soften = (1.0 + pushing / 1.5) ** (-1.0 / 3.0)
    k = nonlinearity
    shift = np.c_[k * 0.35 * truth[:, :2] * soften[:, None], -k * 0.55 * pushing ** (2.0 / 3.0)]  # mm
    turn = np.c_[k * 8.0 * truth[:, 3:5] * soften[:, None], np.zeros(n)]  # rad per N·m
    moment = Rotation.from_rotvec(turn).apply([0.0, 0.0, 1.0])
    field = np.empty((n, 8))
    for c in range(8):
        r = hall[c] - shift
        distance = np.linalg.norm(r, axis=1, keepdims=True)
        rhat = r / distance
        b = (3 * np.sum(moment * rhat, axis=1, keepdims=True) * rhat - moment) / distance ** 3
        field[:, c] = b @ axis[c]
    volts = 1.65 + 1.4 * np.tanh(field / 0.012) + ar1_noise(rng, field.shape, 0.002 * noise, 0.8)
    codes = quantise(volts, 0.0, 3.3, 12) * (3.3 / 4096)
    # A load case is one press: a direction's ramp of magnitudes, recorded in one go
    direction = np.array([f"d{d:02d}" for d in which])
    return RealLikeTable("fingertip", codes, reference, truth, direction, {"direction": direction},
                         tuple(f"v{i}" for i in range(1, 9)))


def _unit_perpendicular(rng: np.random.Generator, vectors: np.ndarray) -> np.ndarray:
    """A random unit vector perpendicular to each row of ``vectors``."""
    draw = rng.standard_normal(vectors.shape)
    draw -= np.sum(draw * vectors, axis=1, keepdims=True) * vectors
    return draw / np.linalg.norm(draw, axis=1, keepdims=True)


SIMULATORS = {"optical": optical_sensor, "plate": bench_plate, "fingertip": fingertip_sensor}


def simulate_table(name: str, seed: int = 0, **options) -> RealLikeTable:
    """One of :data:`SIMULATORS` by name (``optical``, ``plate``, ``fingertip``) with its options."""
    check_choice(name, "name", "simulate_table", tuple(SIMULATORS))
    return SIMULATORS[name](seed=seed, **options)


__all__ = ["RealLikeTable", "SPLITS", "SIMULATORS", "ar1_noise", "bench_plate", "fingertip_sensor",
           "gravity_wrench", "held_out_masks", "optical_sensor", "quantise", "simulate_table"]
