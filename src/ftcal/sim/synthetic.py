"""Robot-free synthetic calibration datasets (the demo, tests and benchmarks).

A lumped arm hangs from the sensor: the upper arm runs along the sensor's +z axis to an
elbow at ``ELBOW`` (m), the forearm (with the load support) leaves the elbow at an angle
that changes over time, and the arm's orientation moves smoothly so that gravity sweeps
about a quarter of a sphere in the sensor frame. The true wrench is

    f = (m_arm + m_load) · g_s,   τ = c_arm × (m_arm g_s) + c_load × (m_load g_s)

with ``g_s`` gravity in the sensor frame (quasi-static: slow motion, no inertial terms).
At 10 kg this spans about the ranges of the paper's Table I (forces up to ~125 N,
torques up to ~30 Nm).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence

import numpy as np

from ..core.dataset import DEFAULT_INPUTS, DEFAULT_OUTPUTS, Dataset, concatenate
from ..runtime.checks import check_float, check_int
from ..runtime.errors import FtcalError
from .sensor import StrainGaugeSensor, temperature_drift

GRAVITY = 9.81
ARM_MASS = 2.0  # kg: upper arm, forearm and the empty load support together
ELBOW = np.array([0.0, 0.0, 0.16])  # m, in the sensor frame
ARM_COM = np.array([0.005, -0.01, 0.09])  # m, lumped arm centre of mass, sensor frame
LOAD_ARM = 0.10  # m from the elbow to the load along the forearm
SAMPLE_RATE = 100.0  # Hz, the robot logger's rate

# Gravity direction d = (cos b cos a, −cos b sin a, sin b): a spans a bit more than a
# quadrant and b most of the meridian, i.e. roughly a quarter of the sphere.
AZIMUTH = np.deg2rad([-15.0, 105.0])
ELEVATION = np.deg2rad([-75.0, 75.0])
ELBOW_ANGLE = np.deg2rad([15.0, 100.0])


def load_case_name(load_kg: float) -> str:
    """The group label of a load case, e.g. ``l5kg`` or ``l0.5kg``."""
    return f"l{load_kg:g}kg"


def arm_wrench(gravity_dir: np.ndarray, elbow_angle: np.ndarray, load_kg: float) -> np.ndarray:
    """True wrench at the sensor of the lumped arm carrying ``load_kg``.

    Parameters
    ----------
    gravity_dir : ndarray of shape (n_samples, 3), unit gravity direction in the sensor frame
    elbow_angle : ndarray of shape (n_samples,), rad; the forearm leaves the elbow at this
        angle from +z, in the x–z plane
    load_kg : payload mass on the forearm support

    Returns
    -------
    ndarray of shape (n_samples, 6): Fx Fy Fz (N), Tx Ty Tz (Nm)
    """
    g = GRAVITY * np.asarray(gravity_dir, dtype=np.float64)
    theta = np.asarray(elbow_angle, dtype=np.float64)
    c_load = ELBOW + LOAD_ARM * np.column_stack([np.sin(theta), np.zeros_like(theta), np.cos(theta)])
    force = (ARM_MASS + load_kg) * g
    torque = ARM_MASS * np.cross(ARM_COM, g) + load_kg * np.cross(c_load, g)
    return np.hstack([force, torque])


def smooth_path(waypoints: np.ndarray, n_samples: int, move_s: float, hold_s: float,
                sample_rate: float = SAMPLE_RATE) -> np.ndarray:
    """Minimum-jerk moves between ``waypoints``, each followed by a hold.

    Parameters
    ----------
    waypoints : ndarray of shape (n_waypoints, n_dims); the path starts at the first
    n_samples : samples to return, at ``sample_rate`` Hz; the path holds the last waypoint
        once it runs out of them

    Returns
    -------
    ndarray of shape (n_samples, n_dims)
    """
    wp = np.asarray(waypoints, dtype=np.float64)
    t = np.arange(n_samples) / sample_rate
    period = move_s + hold_s
    k = np.minimum((t // period).astype(np.int64), len(wp) - 2)
    s = np.clip((t - k * period) / move_s, 0.0, 1.0)
    blend = s**3 * (10 - 15 * s + 6 * s * s)
    return wp[k] + blend[:, None] * (wp[k + 1] - wp[k])


def synthetic_recording(sensor: StrainGaugeSensor, load_kg: float, start_temperature: float,
                        n_samples: int, rng: np.random.Generator,
                        sample_rate: float = SAMPLE_RATE) -> tuple[np.ndarray, np.ndarray]:
    """One recording: random smooth arm motion with ``load_kg``, slowly drifting temperature.

    Returns
    -------
    inputs : ndarray of shape (n_samples, 7), raw channels u1..u6 and temperature T
    outputs : ndarray of shape (n_samples, 6), true wrench Fx..Tz
    """
    move_s, hold_s = rng.uniform(2.0, 4.0), rng.uniform(0.5, 2.0)
    n_wp = int(np.ceil(n_samples / (sample_rate * (move_s + hold_s)))) + 2
    lows = np.array([AZIMUTH[0], ELEVATION[0], ELBOW_ANGLE[0]])
    highs = np.array([AZIMUTH[1], ELEVATION[1], ELBOW_ANGLE[1]])
    path = smooth_path(rng.uniform(lows, highs, size=(n_wp, 3)), n_samples, move_s, hold_s,
                       sample_rate)
    a, b = path[:, 0], path[:, 1]
    direction = np.column_stack([np.cos(b) * np.cos(a), -np.cos(b) * np.sin(a), np.sin(b)])
    wrench = arm_wrench(direction, path[:, 2], load_kg)
    time = np.arange(n_samples) / sample_rate
    temperature = temperature_drift(time, start_temperature, start_temperature + rng.uniform(-2.0, 4.0))
    raw = sensor.measure(wrench, temperature, rng, sample_rate)
    return np.column_stack([raw, temperature]), wrench


def synthetic_recordings(n_recordings: int = 14, samples_per_recording: int = 6000,
                         loads_kg: Sequence[float] = (0, 1, 2, 5, 7, 9, 10),
                         temperatures: Sequence[float] = (25.0, 32.0, 38.0, 43.0),
                         seed: int = 0, sensor: StrainGaugeSensor | None = None) -> Dataset:
    """Simulated recordings of one sensor with loads hung on a moving forearm.

    Recording ``i`` carries ``loads_kg[i % n_loads]`` and starts at
    ``temperatures[(i // n_loads) % n_temperatures]`` °C, so every load meets every
    temperature once there are ``n_loads · n_temperatures`` recordings.

    Parameters
    ----------
    sensor : the simulated sensor; default ``StrainGaugeSensor.create(seed=seed)``

    Returns
    -------
    Dataset with inputs u1..u6, T (n_samples = n_recordings · samples_per_recording),
    outputs Fx..Tz (the true wrench), one segment per recording, groups = load-case names
    (``"l5kg"``), sources ``"synthetic-000"``, ...
    """
    n_rec = check_int(n_recordings, "n_recordings", "synthetic_recordings", 1)
    n = check_int(samples_per_recording, "samples_per_recording", "synthetic_recordings", 2)
    loads = [check_float(m, "loads_kg", "synthetic_recordings", 0.0) for m in loads_kg]
    temps = [check_float(t, "temperatures", "synthetic_recordings", -np.inf) for t in temperatures]
    if not loads or not temps:
        raise FtcalError("synthetic_recordings needs at least one load and one temperature.")
    sensor = StrainGaugeSensor.create(seed=seed) if sensor is None else sensor
    rngs = np.random.default_rng(seed).spawn(n_rec)
    parts = []
    for i, rng in enumerate(rngs):
        load = loads[i % len(loads)]
        inputs, outputs = synthetic_recording(sensor, load, temps[(i // len(loads)) % len(temps)], n, rng)
        parts.append(Dataset.from_arrays(inputs, outputs, input_names=DEFAULT_INPUTS,
                                         output_names=DEFAULT_OUTPUTS,
                                         segments=np.zeros(n, dtype=np.int64),
                                         groups=np.full(n, load_case_name(load), dtype=object)))
    data = concatenate(parts)
    return dataclasses.replace(data, sources=tuple(f"synthetic-{i:03d}" for i in range(n_rec)))
