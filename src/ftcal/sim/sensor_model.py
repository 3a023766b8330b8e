"""A configurable six-axis F/T sensor for ``ftcal simulate`` and the closed loop, with its truth as JSON.

Where :class:`ftcal.sim.sensor.StrainGaugeSensor` draws the paper's sensor from a few
magnitudes, this model exposes every part of the signal chain as a named parameter, so a
user can describe *their* sensor (and its mistakes) and score each pipeline step against
the truth file. For a true wrench ``w`` (N, N m, in the declared sensor frame) at time
``t`` (s) and sensor temperature ``T`` (°C):

1. mounting mistake (what ``ftcal check`` should find): ``w`` as the sensor really sees it,
   :data:`MISTAKES` — ``sign`` (reaction instead of action), ``swap-xy`` (x and y channels
   exchanged), ``rotate-z:DEG`` (sensor turned DEG about its z axis against the URDF);
2. linear part: gauge signals ``s = C · (w / full_scale)`` with ``C = I + crosstalk·R``
   (``R`` dense, zero diagonal);
3. nonlinearity: ``s + quadratic ⊙ s|s| + cubic ⊙ s³`` (per channel; compression and
   tension differ, the flexure stiffens);
4. temperature: gain ``× (1 + gain_tc ⊙ (T − T_ref))``, zero ``+ offset_tc ⊙ (T − T_ref)``;
5. bias: ``offset + ramp · t + random walk`` (``walk`` per √s), full-scale units;
6. ADC: ``counts = 2^(bits−1) · s``, Gaussian noise (``noise`` counts), rounding, clipping at
   ``± saturation · 2^(bits−1)`` counts.

The *true matrix* ``K = diag(full_scale) · C⁻¹ / 2^(bits−1)`` maps counts back to the
wrench when steps 1 and 3–6 are off: ``w = K · counts`` (quantisation aside). The *factory
matrix* is what a workbench calibration identifies (affine least squares on noise-free
counts of loads within ``workbench_force``/``workbench_torque`` at ``T_ref``, bias at its
start value): the ``wrench`` channels a driver publishes are ``W · counts + b``.
"""

from __future__ import annotations

import json
import math
from dataclasses import asdict, dataclass, field, fields, replace

import numpy as np

from ..core.limits import SIMULATE_CHANNELS as CHANNELS
from ..core.limits import SIMULATE_MISTAKES as MISTAKES
from ..runtime.errors import FtcalError

ADC_BITS = 16


@dataclass(frozen=True)
class SensorSpec:
    """The magnitudes a sensor is drawn from (JSON-friendly; units in the field comments).

    Parameters are checked in :meth:`check`; :meth:`draw` turns them into a
    :class:`SensorModel` with ``numpy.random.default_rng(seed)``.
    """

    force_full_scale: float = 250.0      # N at ADC full scale
    torque_full_scale: float = 25.0      # N m at ADC full scale
    crosstalk: float = 0.15              # std of C's off-diagonal entries
    quadratic: float = 0.06              # std of the per-channel s|s| coefficients
    cubic: float = 0.08                  # std of the per-channel s³ coefficients (negative mean: stiffening)
    gain_tc: float = -1.5e-3             # mean gauge gain change per °C
    gain_tc_spread: float = 0.5e-3       # its spread between channels, 1/°C
    offset_tc: float = 2e-4              # std of the zero's temperature coefficients, full scale per °C
    offset: float = 0.02                 # std of the initial zero offsets, full scale
    ramp: float = 2e-6                   # std of the bias ramps, full scale per s
    walk: float = 2e-5                   # random-walk std per √s, full scale
    noise: float = 8.0                   # counts
    saturation: float = 0.95             # clip level, fraction of the ADC range
    bits: int = ADC_BITS
    reference_temperature: float = 25.0  # °C
    workbench_force: float = 60.0        # N, factory calibration load box
    workbench_torque: float = 6.0        # N m

    def check(self) -> "SensorSpec":
        """Return ``self`` if every field is finite and in range; FtcalError naming the field otherwise."""
        for f in fields(self):
            value = getattr(self, f.name)
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
                raise FtcalError(f"sensor parameter {f.name!r} must be a finite number; got {value!r}.")
        positive = ("force_full_scale", "torque_full_scale", "saturation", "workbench_force", "workbench_torque")
        for name in positive:
            if getattr(self, name) <= 0:
                raise FtcalError(f"sensor parameter {name!r} must be > 0; got {getattr(self, name)!r}.")
        for name in ("crosstalk", "quadratic", "cubic", "gain_tc_spread", "offset_tc", "offset", "ramp", "walk",
                     "noise"):
            if getattr(self, name) < 0:
                raise FtcalError(f"sensor parameter {name!r} must be >= 0; got {getattr(self, name)!r}.")
        if self.crosstalk > 0.5:
            raise FtcalError(f"sensor parameter 'crosstalk' must be at most 0.5; got {self.crosstalk!r}.")
        if self.saturation > 1:
            raise FtcalError(f"sensor parameter 'saturation' must be at most 1; got {self.saturation!r}.")
        if not (isinstance(self.bits, int) and 8 <= self.bits <= 32):
            raise FtcalError(f"sensor parameter 'bits' must be a whole number in [8, 32]; got {self.bits!r}.")
        return self

    @property
    def full_scale(self) -> np.ndarray:
        """Full-scale load per axis (N, N m), shape (6,)."""
        return np.repeat([self.force_full_scale, self.torque_full_scale], 3)

    def draw(self, seed: int = 0, mistake: str = "none", mistake_deg: float = 0.0) -> "SensorModel":
        """A sensor drawn from these magnitudes with ``numpy.random.default_rng(seed)``."""
        self.check()
        check_mistake(mistake, mistake_deg)
        rng = np.random.default_rng([seed, 7])
        coupling = np.eye(6) + self.crosstalk * rng.standard_normal((6, 6)) * (1 - np.eye(6))
        draft = SensorModel(
            spec=self, coupling=coupling,
            quadratic=self.quadratic * rng.standard_normal(6),
            cubic=-np.abs(self.cubic * rng.standard_normal(6)),
            gain_tc=self.gain_tc + self.gain_tc_spread * rng.standard_normal(6),
            offset_tc=self.offset_tc * rng.standard_normal(6),
            offset=self.offset * rng.standard_normal(6),
            ramp=self.ramp * rng.standard_normal(6),
            mistake=mistake, mistake_deg=float(mistake_deg))
        box = np.repeat([self.workbench_force, self.workbench_torque], 3)
        loads = rng.uniform(-box, box, size=(2000, 6))
        counts = draft.counts(loads, np.full(len(loads), self.reference_temperature), quantize=False,
                              ignore_mistake=True)
        design = np.column_stack([counts, np.ones(len(counts))])
        solution = np.linalg.lstsq(design, loads, rcond=None)[0]
        return replace(draft, factory_matrix=solution[:6].T.copy(), factory_offset=solution[6].copy())


def check_mistake(mistake: str, degrees: float = 0.0) -> None:
    if mistake not in MISTAKES:
        raise FtcalError(f"mounting mistake {mistake!r}: choose one of {', '.join(MISTAKES)}.")
    if not math.isfinite(degrees) or (mistake == "rotate-z" and not 0 < abs(degrees) <= 180):
        raise FtcalError(f"rotate-z needs an angle in (0, 180] degrees in magnitude; got {degrees!r}.")


@dataclass(frozen=True, eq=False)
class SensorModel:
    """One drawn sensor: per-channel values (arrays of shape (6,) unless stated) and the factory calibration.

    Attributes
    ----------
    spec : SensorSpec
    coupling : ndarray of shape (6, 6), normalised load → gauge signal
    quadratic, cubic, gain_tc, offset_tc, offset, ramp : per channel (see the module docstring)
    mistake, mistake_deg : the mounting mistake
    factory_matrix : ndarray of shape (6, 6), counts → wrench (workbench calibration)
    factory_offset : ndarray of shape (6,), N and N m
    """

    spec: SensorSpec
    coupling: np.ndarray
    quadratic: np.ndarray
    cubic: np.ndarray
    gain_tc: np.ndarray
    offset_tc: np.ndarray
    offset: np.ndarray
    ramp: np.ndarray
    mistake: str = "none"
    mistake_deg: float = 0.0
    factory_matrix: np.ndarray = field(default_factory=lambda: np.eye(6))
    factory_offset: np.ndarray = field(default_factory=lambda: np.zeros(6))

    @property
    def counts_per_full_scale(self) -> float:
        return float(2 ** (self.spec.bits - 1))

    @property
    def true_matrix(self) -> np.ndarray:
        """``K``, counts → wrench of the linear part, ndarray of shape (6, 6)."""
        return np.diag(self.spec.full_scale) @ np.linalg.inv(self.coupling) / self.counts_per_full_scale

    def mounted(self, wrench: np.ndarray) -> np.ndarray:
        """The wrench as the sensor sees it after the mounting mistake, shape (n, 6)."""
        w = np.array(wrench, dtype=np.float64, copy=True)
        if self.mistake == "sign":
            return -w
        if self.mistake == "swap-xy":
            return w[:, [1, 0, 2, 4, 3, 5]]
        if self.mistake == "rotate-z":
            a = np.deg2rad(self.mistake_deg)
            # The sensor is turned by +a about z: a vector reads R(a)ᵀ v in its axes.
            r = np.array([[np.cos(a), np.sin(a), 0.0], [-np.sin(a), np.cos(a), 0.0], [0.0, 0.0, 1.0]])
            return np.hstack([w[:, :3] @ r.T, w[:, 3:] @ r.T])
        return w

    def bias(self, time: np.ndarray, rng: np.random.Generator | None) -> np.ndarray:
        """Bias in full-scale units per sample, shape (n, 6): offset + ramp·t + random walk (``rng`` None: none)."""
        t = np.asarray(time, dtype=np.float64)
        out = self.offset + np.outer(t - (t[0] if t.size else 0.0), self.ramp)
        if rng is not None and self.spec.walk > 0 and t.size > 1:
            steps = rng.standard_normal((t.size - 1, 6)) * (self.spec.walk * np.sqrt(np.diff(t)))[:, None]
            out[1:] += np.cumsum(steps, axis=0)
        return out

    def counts(self, wrench: np.ndarray, temperature: np.ndarray, bias: np.ndarray | None = None,
               rng: np.random.Generator | None = None, quantize: bool = True,
               ignore_mistake: bool = False) -> np.ndarray:
        """ADC counts (steps 1–6), ndarray of shape (n, 6), float (whole numbers when ``quantize``).

        Parameters
        ----------
        wrench : ndarray of shape (n, 6), true wrench in the declared sensor frame
        temperature : ndarray of shape (n,), °C
        bias : ndarray of shape (n, 6) from :meth:`bias`, or None for the initial offset
        rng : noise source; None means no noise
        """
        w = np.asarray(wrench, dtype=np.float64)
        temp = np.asarray(temperature, dtype=np.float64)
        if w.ndim != 2 or w.shape[1] != 6 or temp.shape != (w.shape[0],):
            raise FtcalError(f"wrench must be (n, 6) and temperature (n,); got {w.shape} and {temp.shape}.")
        if not ignore_mistake:
            w = self.mounted(w)
        s = (w / self.spec.full_scale) @ self.coupling.T
        s = s + self.quadratic * s * np.abs(s) + self.cubic * s ** 3
        dt = (temp - self.spec.reference_temperature)[:, None]
        s = s * (1.0 + self.gain_tc * dt) + self.offset_tc * dt
        s = s + (self.offset if bias is None else bias)
        c = s * self.counts_per_full_scale
        if rng is not None and self.spec.noise > 0:
            c = c + self.spec.noise * rng.standard_normal(c.shape)
        if quantize:
            c = np.rint(c)
        limit = np.floor(self.spec.saturation * (self.counts_per_full_scale - 1))
        return np.clip(c, -limit, limit)

    def sample_reader(self, temperature: np.ndarray, bias: np.ndarray, rng: np.random.Generator | None):
        """``read(k, wrench)``: :meth:`counts` of one wrench (1, 6) at sample ``k`` of a recording whose
        temperature (n,), bias (n, 6) and noise are known beforehand, shape (1, 6).

        For a closed loop, where each sample's wrench depends on the ones before: the per-sample parts
        (gain, zero drift, bias, noise) are computed once for all ``n`` samples, so one sample costs the
        load-dependent part only. The same arithmetic in the same order as :meth:`counts`, and the noise
        drawn as one (n, 6) block (the stream of ``n`` draws of (1, 6)) and used in call order, as ``rng``
        would be: the i-th call's counts equal the i-th of successive calls
        ``counts(wrench, temperature[k:k+1], bias[k:k+1], rng)``, bit for bit (at most ``n`` calls).
        """
        temp = np.asarray(temperature, dtype=np.float64)
        bias = np.asarray(bias, dtype=np.float64)
        if temp.ndim != 1 or bias.shape != (temp.size, 6):
            raise FtcalError(f"temperature must be (n,) and bias (n, 6); got {temp.shape} and {bias.shape}.")
        dt = (temp - self.spec.reference_temperature)[:, None]
        gain, zero = 1.0 + self.gain_tc * dt, self.offset_tc * dt
        noise = (self.spec.noise * rng.standard_normal((temp.size, 6)) if rng is not None and self.spec.noise > 0
                 else None)
        full_scale, coupling_t, quadratic, cubic = self.spec.full_scale, self.coupling.T, self.quadratic, self.cubic
        cpfs, limit = self.counts_per_full_scale, np.floor(self.spec.saturation * (self.counts_per_full_scale - 1))
        mounted = self.mounted if self.mistake != "none" else None
        calls = iter(range(temp.size))

        def read(k: int, wrench: np.ndarray) -> np.ndarray:
            w = wrench if mounted is None else mounted(wrench)
            s = (w / full_scale) @ coupling_t
            # in place, each product and sum in counts' order (IEEE products commute, sums are kept in order)
            nonlinear = quadratic * s
            nonlinear *= np.abs(s)
            nonlinear += s
            cube = s ** 3
            cube *= cubic
            nonlinear += cube
            nonlinear *= gain[k]
            nonlinear += zero[k]
            nonlinear += bias[k]
            nonlinear *= cpfs
            i = next(calls)
            if noise is not None:
                nonlinear += noise[i]
            np.rint(nonlinear, out=nonlinear)
            np.maximum(nonlinear, -limit, out=nonlinear)  # np.clip's Python wrapper costs more than the rest
            return np.minimum(nonlinear, limit, out=nonlinear)

        return read

    def factory_wrench(self, counts: np.ndarray) -> np.ndarray:
        """The driver's wrench from counts: ``W · counts + b``, shape (n, 6)."""
        return np.asarray(counts, dtype=np.float64) @ self.factory_matrix.T + self.factory_offset

    def to_dict(self) -> dict:
        """Everything, as JSON-ready lists (the ``sensor`` section of a truth file)."""
        out = {"spec": asdict(self.spec), "mistake": self.mistake, "mistake_deg": self.mistake_deg,
               "true_matrix": self.true_matrix.tolist()}
        for name in ("coupling", "quadratic", "cubic", "gain_tc", "offset_tc", "offset", "ramp", "factory_matrix",
                     "factory_offset"):
            out[name] = np.asarray(getattr(self, name)).tolist()
        return out

    @classmethod
    def from_dict(cls, data: dict, where: str = "sensor") -> "SensorModel":
        """Inverse of :meth:`to_dict` (``true_matrix`` is derived, not read); FtcalError on a bad field."""
        try:
            spec_fields = {f.name for f in fields(SensorSpec)}
            raw_spec = data["spec"]
            unknown = set(raw_spec) - spec_fields
            if unknown:
                raise FtcalError(f"{where}.spec: unknown field(s) {', '.join(sorted(unknown))}.")
            spec = SensorSpec(**raw_spec).check()
            arrays = {}
            for name, shape in (("coupling", (6, 6)), ("factory_matrix", (6, 6)), ("quadratic", (6,)),
                                ("cubic", (6,)), ("gain_tc", (6,)), ("offset_tc", (6,)), ("offset", (6,)),
                                ("ramp", (6,)), ("factory_offset", (6,))):
                value = np.asarray(data[name], dtype=np.float64)
                if value.shape != shape or not np.isfinite(value).all():
                    raise FtcalError(f"{where}.{name}: must be finite numbers of shape {shape}.")
                arrays[name] = value
            mistake, degrees = str(data.get("mistake", "none")), float(data.get("mistake_deg", 0.0))
            check_mistake(mistake, degrees)
        except KeyError as exc:
            raise FtcalError(f"{where}: missing field {exc.args[0]!r}.") from None
        except (TypeError, ValueError) as exc:
            raise FtcalError(f"{where}: bad value ({exc}).") from None
        if abs(np.linalg.det(arrays["coupling"])) < 1e-6:
            raise FtcalError(f"{where}.coupling: the matrix is singular.")
        return cls(spec=spec, mistake=mistake, mistake_deg=degrees, **arrays)


def spec_from_json(text: str, where: str) -> SensorSpec:
    """A :class:`SensorSpec` from a JSON object (a truth file's ``sensor.spec``, or the spec itself)."""
    try:
        data = json.loads(text)
    except json.JSONDecodeError as exc:
        raise FtcalError(f"{where}: not JSON ({exc.msg} at line {exc.lineno}).") from None
    if isinstance(data, dict) and isinstance(data.get("sensor"), dict):
        data = data["sensor"]
    if isinstance(data, dict) and isinstance(data.get("spec"), dict):
        data = data["spec"]
    if not isinstance(data, dict):
        raise FtcalError(f"{where}: expected a JSON object of sensor parameters.")
    known = {f.name for f in fields(SensorSpec)}
    unknown = set(data) - known
    if unknown:
        raise FtcalError(f"{where}: unknown sensor parameter(s) {', '.join(sorted(unknown))}; "
                         f"known: {', '.join(sorted(known))}.")
    try:
        return SensorSpec(**data).check()
    except TypeError as exc:
        raise FtcalError(f"{where}: {exc}.") from None
    except FtcalError as exc:
        raise FtcalError(f"{where}: {exc}") from None
