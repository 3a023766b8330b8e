"""The live calibrator: calibration model + tool library + gated bias tracker + health, one sample or one block at a time.

See docs/live.md for the model, its gates and what each flag means. In short, for each sample:

1. the calibrated wrench ``w``: the model's prediction from the raw channels (or the wrench given);
2. gravity in sensor axes from an orientation quaternion, a gravity vector or an accelerometer (IMU);
3. the tool's gravity wrench ``Y(g) θ_tool`` (:func:`ftcal.payload.regressor.static_regressor`);
4. ``z = w − tool``; the bias tracker (the C core, :mod:`ftcal.live.core`) updates on static samples whose
   innovation passes the χ² gate, and only predicts on the others;
5. the compensated wrench is the innovation ``z − bias`` (the bias before the sample);
6. health flags (:mod:`ftcal.live.health`).

:meth:`LiveCalibrator.run` takes a block of samples and computes exactly what :meth:`LiveCalibrator.step`
computes one at a time: both run the one C core (``csrc/ftcal_live.h``, the extension ``ftcal.live._core``) that
``convert --to c-runtime`` ships; Python keeps the configuration, the gravity sources, files and texts.
"""

from __future__ import annotations

import json
import math
from collections import deque
from collections.abc import Mapping
from dataclasses import dataclass, field
from operator import itemgetter
from pathlib import Path

import numpy as np

from ..check.accept import Thresholds
from ..core.limits import LIVE_MIN_HOLDS, MAX_CELL_MAGNITUDE
from ..data.holds import HOLD_WINDOW_S, MIN_ANGULAR_RATE, MIN_HOLD_S
from ..data.signals import SATURATION_RUN
from ..files.state_json import check_state_envelope, model_digest, state_envelope
from ..payload.kinematics import QUATERNION_NORM_TOLERANCE, STANDARD_GRAVITY, gravity_from_quaternions
from ..payload.parameters import PayloadParameters
from ..runtime.errors import FtcalError
from .health import BIT, FLAGS, names_of
from .motion import MotionDetector
from .consistency import (Q_MAX, R_MAX, locked_out_text, noise_adapted_text, reacquired_text, undone_text,
                          walk_adapted_text)
from .defaults import (DEFAULT_NOISE_FRACTION, DEFAULT_WALK_FRACTION, GATE_PROBABILITY, NO_TOOL, OUT_OF_RANGE_TEXT,
                       RETARE_VARIANCE, RETARE_WARNING, SECONDS_PER_HOUR, UNEXPLAINED_SECONDS, UNEXPLAINED_SIGMA,
                       tracker_defaults, tracker_wander)
from .drift import FALSE_ALARM
from .core import FIELDS, require_core
from .tracker import HOLDOFF_S, gate_chi2

# Events kept in memory (a long run keeps memory flat; the state file keeps the counters).
MAX_EVENTS = 1000


@dataclass(frozen=True)
class SelfCheckBounds:
    """The self-check's reference r₀ (per sample) and q₀ (per s): it adapts r within [r₀, 25 r₀], q within
    [q₀, 100 q₀] (:mod:`ftcal.live.consistency`)."""

    noise0: list
    walk0: list


@dataclass
class LiveResult:
    """What the calibrator returns for a block of n samples.

    Attributes
    ----------
    time : ndarray of shape (n,), s
    calibrated : ndarray of shape (n, 6), the model's wrench (or the wrench given), N and N·m
    compensated : ndarray of shape (n, 6), calibrated − tool − bias (the contact wrench)
    bias, bias_std : ndarray of shape (n, 6), the bias estimate after each sample and its standard deviation
    static : ndarray of bool, shape (n,), the sample was static
    updated : ndarray of bool, shape (n,), the sample updated the bias
    chi2 : ndarray of shape (n,), the innovation's χ² (6 dof)
    flags : ndarray of uint16, shape (n,), health flags (bits of :data:`ftcal.live.health.BIT`)
    tool : the tool in use for the block
    events : flags raised or cleared in the block, as (time, flag, "raised" | "cleared", reason)
    """

    time: np.ndarray
    calibrated: np.ndarray
    compensated: np.ndarray
    bias: np.ndarray
    bias_std: np.ndarray
    static: np.ndarray
    updated: np.ndarray
    chi2: np.ndarray
    flags: np.ndarray
    tool: str
    events: list = field(default_factory=list)

    @property
    def n_samples(self) -> int:
        return self.time.size


def _views(index: int):
    """A LiveSample's array field ``index`` (0 calibrated .. 3 bias_std): a view of the core's 24 numbers, made when
    read (a step builds none of them), or the array given."""
    def get(self) -> np.ndarray:
        values = tuple.__getitem__(self, 5)
        if isinstance(values, bytearray):
            return np.frombuffer(values, float, 6, 48 * index)
        return values[index]

    return property(get)


class LiveSample(tuple):
    """One sample's result (:meth:`LiveCalibrator.step`), immutable.

    Attributes
    ----------
    time : s
    calibrated, compensated, bias, bias_std : ndarray of shape (6,)
    static, updated : bool
    flags : dict flag name → one-line reason, for the flags raised on this sample
    tool : str
    """

    # a tuple: made in one call (a step's cost is mostly Python's; a dataclass's nine setattrs were a sixth of it)
    __slots__ = ()

    def __new__(cls, time, calibrated, compensated, bias, bias_std, static, updated, flags, tool):
        return tuple.__new__(cls, (time, static, updated, flags, tool, (calibrated, compensated, bias, bias_std)))

    time = property(itemgetter(0))
    static = property(itemgetter(1))
    updated = property(itemgetter(2))
    flags = property(itemgetter(3))
    tool = property(itemgetter(4))
    calibrated, compensated, bias, bias_std = (_views(k) for k in range(4))

    def __getnewargs__(self) -> tuple:  # pickle and copy: the constructor's arguments, not the tuple's items
        return (self.time, self.calibrated, self.compensated, self.bias, self.bias_std, self.static, self.updated,
                self.flags, self.tool)

    def __repr__(self) -> str:
        return (f"LiveSample(time={self.time!r}, calibrated={self.calibrated!r}, compensated={self.compensated!r}, "
                f"bias={self.bias!r}, bias_std={self.bias_std!r}, static={self.static!r}, updated={self.updated!r}, "
                f"flags={self.flags!r}, tool={self.tool!r})")


def tool_wrench(payload: PayloadParameters | None, gravity: np.ndarray) -> np.ndarray:
    """The gravity wrench a tool puts on the sensor, in the readings' sign, bias excluded, shape (n, 6).

    ``F = m g``, ``T = (m c) × g`` (ftcal's convention, :mod:`ftcal.payload.regressor`), negated for a
    payload identified from ``reaction`` readings.
    """
    out = np.zeros((gravity.shape[0], 6))
    if payload is None:
        return out
    m, mc = payload.mass, payload.mass * np.asarray(payload.com, dtype=float)
    out[:, :3] = m * gravity
    gx, gy, gz = gravity[:, 0], gravity[:, 1], gravity[:, 2]
    out[:, 3], out[:, 4], out[:, 5] = mc[1] * gz - mc[2] * gy, mc[2] * gx - mc[0] * gz, mc[0] * gy - mc[1] * gx
    return -out if payload.reaction else out


class LiveCalibrator:
    """Calibrate, compensate the tool and track the sensor's bias while the robot runs.

    Parameters
    ----------
    model : a static calibration model (any registered family, e.g. from
        :func:`ftcal.load_model`) or None when the samples are wrenches already
    tools : mapping of name → :class:`~ftcal.payload.parameters.PayloadParameters` (or a payload-file path);
        the library; ``"none"`` (no tool) is always there
    tool : the tool mounted at the start
    walk_std : ndarray of shape (6,) or None, the bias' random-walk standard deviation per √h (N/√h, N·m/√h);
        default :func:`tracker_defaults` (the walk ``payload --bias-drift random-walk`` identified, less what a
        fitted wander fakes; older files: the knots; else :data:`DEFAULT_WALK_FRACTION` × the thresholds)
    noise_std : ndarray of shape (6,) or None, per-sample noise of the calibrated wrench; default
        :func:`tracker_defaults` (the per-sample variance within the holds the random-walk identification
        stored; older files: the larger of its block noise and the residual RMS²; else the first tool file's
        residual RMS, else :data:`DEFAULT_NOISE_FRACTION` × the thresholds)
    initial_bias, initial_bias_std : ndarray of shape (6,) or None; default unknown (the first static,
        contact-free samples set it, tool compensated)
    gate_probability : the χ² quantile (6 dof) of the contact gate
    unexplained_sigma, unexplained_seconds : the ``unexplained`` flag's k and T
    thresholds : :class:`~ftcal.check.accept.Thresholds` (``check --accept``'s; defaults 1 N, 0.1 N·m)
    adc_limits : (low, high) or None, raw values at or beyond which a channel is saturated
    temperature_range : (low, high) °C or None; default the model's temperature input range
    motion_window, min_rate, min_hold : the static test (:mod:`ftcal.live.motion`)
    gravity_magnitude : m/s², for quaternions
    state_path : JSON file the state is saved to (atomically) and resumed from when it exists
    self_check : the tracker checks itself (:mod:`ftcal.live.consistency`): r by covariance matching within
        [r₀, 25 r₀], a lock-out said in an event, and the bias re-acquired (q raised within [q₀, 100 q₀]) when
        holds in two orientations show the same residual (the C runtime's NAME_init turns its copy on too);
        False: the fixed q and r of the defaults or overrides
    holdoff : s after a run of static samples that failed the gate for 0.1 s or more (a contact) during which no
        sample updates the bias (:data:`ftcal.live.tracker.HOLDOFF_S`, 0.15 s: a contact's release edge, part-way
        down, passes the gate; after a long contact the bias variance is large and one such sample would set the
        bias); 0: off
    robot : gravity from joint positions, e.g. :class:`ftcal.robot.kinematics.SensorGravity` (a URDF, the
        F/T sensor, the joints given); then ``joints`` alone gives gravity (and the motion signal)

    Raises
    ------
    FtcalError
        A setting out of its range, a tool not in the library, a state file refused; or the compiled core
        (``ftcal.live._core``) is not built: one line says how to build it.

    Examples
    --------
    >>> import numpy as np
    >>> from ftcal.live import LiveCalibrator
    >>> live = LiveCalibrator(noise_std=np.full(6, 0.05))
    >>> r = live.run(np.arange(0.0, 2.0, 0.001), wrench=np.tile([1.0, 0, 0, 0, 0, 0], (2000, 1)),
    ...              gravity=np.tile([0.0, 0.0, -9.81], (2000, 1)))
    >>> bool(abs(r.bias[-1, 0] - 1.0) < 1e-3)
    True
    """

    def __init__(self, model=None, tools: Mapping[str, PayloadParameters | str | Path] | None = None, *,
                 tool: str = NO_TOOL, walk_std=None, noise_std=None, initial_bias=None, initial_bias_std=None,
                 gate_probability: float = GATE_PROBABILITY, unexplained_sigma: float = UNEXPLAINED_SIGMA,
                 unexplained_seconds: float = UNEXPLAINED_SECONDS, thresholds: Thresholds | None = None,
                 adc_limits: tuple[float, float] | None = None, temperature_range: tuple[float, float] | None = None,
                 motion_window: float = HOLD_WINDOW_S, min_rate: float = MIN_ANGULAR_RATE,
                 min_hold: float = MIN_HOLD_S, gravity_magnitude: float = STANDARD_GRAVITY,
                 state_path: str | Path | None = None, robot=None, self_check: bool = True,
                 holdoff: float = HOLDOFF_S) -> None:
        if model is not None:
            if not getattr(model, "is_static", True):
                raise FtcalError("the live calibrator takes static models (no ARX lags).")
            if len(model.output_names_) != 6:
                raise FtcalError(f"the calibration model has {len(model.output_names_)} outputs; a wrench needs 6.")
        if not 0.5 < gate_probability < 1.0:
            raise FtcalError(f"gate_probability must be in (0.5, 1); got {gate_probability}.")
        if isinstance(holdoff, bool) or not isinstance(holdoff, (int, float)) or not 0.0 <= holdoff <= 3600.0:
            raise FtcalError(f"holdoff must be a number of seconds in [0, 3600]; got {holdoff!r}.")
        self.holdoff = float(holdoff)
        self._check_settings(unexplained_sigma=unexplained_sigma, unexplained_seconds=unexplained_seconds,
                             adc_limits=adc_limits, temperature_range=temperature_range, motion_window=motion_window,
                             min_rate=min_rate, min_hold=min_hold, gravity_magnitude=gravity_magnitude)
        self.model = model
        self.robot = robot
        self._reasons: dict[str, str] = {}  # flag -> the reason it was last raised with (outlives the event log)
        self.tools: dict[str, PayloadParameters | None] = {NO_TOOL: None}
        self.identified: set[str] = set()  # tools identified in place: the state file carries them
        for name, payload in (tools or {}).items():
            self.add_tool(name, payload, log=False)
        if tool not in self.tools:
            raise FtcalError(f"tool {tool!r} is not in the library ({', '.join(self.tools)}).")
        self.tool = tool
        self.thresholds = thresholds or Thresholds()
        scale = np.repeat([self.thresholds.force, self.thresholds.torque], 3)
        self._accept_limit = scale
        noise_default, walk_default = tracker_defaults(self.tools.values(), self.thresholds)
        noise = (np.maximum(self._vector(noise_std, "noise_std"), 1e-12) if noise_std is not None
                 else np.sqrt(noise_default)) ** 2
        walk = (self._vector(walk_std, "walk_std") ** 2 / SECONDS_PER_HOUR if walk_std is not None
                else walk_default)  # per second
        # the wander's low-frequency density D = 2 s² τ (N²·s): the update's r is r + D / Δt (ftcal.live.tracker)
        wander = tracker_wander(self.tools.values())
        self.threshold = gate_chi2(gate_probability)
        self.unexplained_sigma, self.unexplained_seconds = float(unexplained_sigma), float(unexplained_seconds)
        self.adc_limits = adc_limits
        model_temperature = self._model_temperature()
        self.temperature_range = temperature_range if temperature_range is not None else model_temperature
        self.gravity_magnitude = gravity_magnitude
        self.motion = MotionDetector(motion_window, min_rate, min_hold)  # quaternion and joint motion signals
        self._core = self._make_core(noise, walk, wander, gate_probability, motion_window, min_rate, min_hold)
        # the self-check's bounds r0 and q0 (LiveCalibrator(self_check=False): fixed q and r)
        self.self_check = SelfCheckBounds(noise.tolist(), walk.tolist()) if self_check else None
        if not self_check:
            self._core.set_self_check(False)
        self.flags_now = 0
        self.events: deque = deque(maxlen=MAX_EVENTS)
        self.counters = {"samples": 0, "updates": 0, "contacts": 0, "retares": 0, "switches": 0}
        self.last_time: float | None = None
        self.identifying: _Identification | None = None
        self.state_path = None if state_path is None else Path(state_path)
        self._set_initial_bias(initial_bias, initial_bias_std)
        if self.state_path is not None and self.state_path.exists():
            self.load_state(self.state_path)

    # ----- set-up helpers -------------------------------------------------------------------------
    @staticmethod
    def _vector(value, name: str) -> np.ndarray:
        try:
            v = np.broadcast_to(np.asarray(value, dtype=float), (6,)).copy()
        except (TypeError, ValueError):
            v = np.full(6, np.nan)
        if not np.all(v <= MAX_CELL_MAGNITUDE) or np.any(v < 0):  # NaN fails too; beyond it squares overflow
            raise FtcalError(f"{name} must be six finite numbers >= 0 and at most {MAX_CELL_MAGNITUDE:g}; got "
                             f"{value!r}.")
        return v

    @staticmethod
    def _check_settings(**settings) -> None:
        """The scalar settings: each a finite number in its range (a NaN window or an inverted ADC range would
        run without complaint and mean nothing)."""
        positive = ("unexplained_sigma", "motion_window", "min_rate", "gravity_magnitude")
        for name, value in settings.items():
            if name in ("adc_limits", "temperature_range"):
                if value is None:
                    continue
                try:
                    low, high = (float(v) for v in value)
                except (TypeError, ValueError):
                    low = high = math.nan
                if not (math.isfinite(low) and math.isfinite(high) and (low < high or name == "temperature_range"
                                                                        and low == high)):
                    raise FtcalError(f"{name} must be (low, high), two finite numbers with low "
                                     f"{'<=' if name == 'temperature_range' else '<'} high; got {value!r}.")
                continue
            try:
                x = float(value)
            except (TypeError, ValueError):
                x = math.nan
            if not (math.isfinite(x) and (x > 0 if name in positive else x >= 0)):
                raise FtcalError(f"{name} must be a finite number {'> 0' if name in positive else '>= 0'}; "
                                 f"got {value!r}.")

    def _model_temperature(self):
        """The model's temperature input range (and remember which input it is)."""
        self._temperature_input = None
        if self.model is None:
            return None
        from ..report.runs import temperature_column

        j = self._temperature_input = temperature_column(self.model.input_names_)
        return None if j is None else tuple(float(x) for x in self.model.input_range_[j])

    def _set_initial_bias(self, bias, std) -> None:
        """A given bias (with its std, default the noise's), else unknown: the first static samples set it.

        A payload file's bias is not used: it was the bias during the identification, and the sensor
        has drifted since (a stale bias held with its small standard error would make every sample a
        contact until the walk's variance caught up).
        """
        if bias is not None:
            self.bias = np.broadcast_to(np.asarray(bias, float), (6,)).copy()
            if not np.all(np.abs(self.bias) <= MAX_CELL_MAGNITUDE):
                raise FtcalError(f"initial_bias must be six finite numbers of at most {MAX_CELL_MAGNITUDE:g}.")
            self.variance = (self._vector(std, "initial_bias_std") ** 2 if std is not None
                             else self.noise_std ** 2)
        else:
            self.bias = np.zeros(6)
            self.variance = RETARE_VARIANCE * self.noise_std ** 2

    def _make_core(self, noise, walk, wander, gate_probability, motion_window, min_rate, min_hold):
        """The C core (:class:`~ftcal.live.core.LiveCore`) with this calibrator's settings, the mounted tool in its one
        slot; :func:`~ftcal.live.core.require_core` says in one line when the extension is not built."""
        from .core import LiveCore, calibrator_config

        config = calibrator_config(
            self.model, self.temperature_range, noise_variance=noise, walk_variance=walk, wander_density=wander,
            accept_limit=self._accept_limit, gate_chi2=self.threshold, drift_chi2=gate_chi2(1.0 - FALSE_ALARM),
            gate_probability=float(gate_probability), unexplained_sigma=self.unexplained_sigma,
            unexplained_seconds=self.unexplained_seconds, motion_window=float(motion_window),
            min_rate=float(min_rate), min_hold=float(min_hold), holdoff=self.holdoff,
            retare_variance=RETARE_VARIANCE)
        core = LiveCore(self.model, {}, config=config)
        # step() evaluates a polynomial model in the core's call (the same table as ftcal.core's kernels)
        self._model_in_core = self.model is not None and core.set_model(self.model)
        core.adc_limits(self.adc_limits)
        self._temperature_fill = 0.0 if self.temperature_range is None else float(self.temperature_range[0])
        self._core = core
        # step()'s common call (the core's sample(), which returns a LiveSample; its temperature input: the model's,
        # or -1: the fill)
        require_core().set_sample_type(LiveSample)
        self._sample = (core._core.sample, -1 if self._temperature_input is None else self._temperature_input,
                        self._temperature_fill)
        self._mount()
        return core

    def _mount(self) -> None:
        """The mounted tool's gravity terms into the core."""
        payload = self.tools[self.tool]
        if payload is None:
            self._core.mount(0.0, (0.0, 0.0, 0.0), 1.0)
        else:
            mass = float(payload.mass)
            self._core.mount(mass, mass * np.asarray(payload.com, float), -1.0 if payload.reaction else 1.0)

    # the tracker's state and settings live in the core
    @property
    def bias(self) -> np.ndarray:
        """ndarray of shape (6,): the bias estimate."""
        return self._core.setting("bias")

    @bias.setter
    def bias(self, value) -> None:
        self._core.set("bias", value)

    @property
    def variance(self) -> np.ndarray:
        """ndarray of shape (6,): the bias estimate's variance per axis."""
        return self._core.setting("variance")

    @variance.setter
    def variance(self, value) -> None:
        self._core.set("variance", value)

    @property
    def noise_std(self) -> np.ndarray:
        """ndarray of shape (6,): the per-sample noise standard deviation r½ (adapted by the self-check)."""
        return np.sqrt(self._core.setting("noise_variance"))

    @noise_std.setter
    def noise_std(self, value) -> None:
        self._core.set("noise_variance", np.asarray(value, float) ** 2)

    @property
    def walk_variance(self) -> np.ndarray:
        """ndarray of shape (6,): the bias' walk variance per s, q (adapted by the self-check)."""
        return self._core.setting("walk_variance")

    @walk_variance.setter
    def walk_variance(self, value) -> None:
        self._core.set("walk_variance", value)

    @property
    def wander_density(self) -> np.ndarray:
        """ndarray of shape (6,): the wander's low-frequency density ``D = 2 s² τ`` (N²·s); the update's r is
        ``r + D / Δt`` (:mod:`ftcal.live.tracker`), zero for white noise."""
        return self._core.setting("wander_density")

    @wander_density.setter
    def wander_density(self, value) -> None:
        self._core.set("wander_density", value)

    # ----- the tool library -----------------------------------------------------------------------
    def add_tool(self, name: str, payload: PayloadParameters | str | Path, *, log: bool = True) -> None:
        """Add (or replace) a tool in the library: a payload or a payload file's path."""
        if not isinstance(name, str) or not name or name == NO_TOOL:
            raise FtcalError(f"a tool needs a name other than {NO_TOOL!r}; got {name!r}.")
        if not isinstance(payload, (PayloadParameters, str, Path)):
            raise FtcalError(f"tool {name!r}: give a payload (PayloadParameters) or a payload file's path; got "
                             f"{type(payload).__name__}.")
        if not isinstance(payload, PayloadParameters):
            from ..files.payload_json import load_payload

            payload = load_payload(payload)
        self.tools[name] = payload
        if "_core" in self.__dict__ and name == self.tool:  # the constructor mounts its tool once the core is made
            self._mount()
        if log:
            self._event("tool", "added", f"tool {name!r} added to the library ({payload.mass:.4g} kg)")

    def switch_tool(self, name: str) -> None:
        """Mount another tool of the library, instantly; the bias estimate is kept (it is the sensor's)."""
        if name not in self.tools:
            raise FtcalError(f"tool {name!r} is not in the library ({', '.join(self.tools)}).")
        old, self.tool = self.tool, name
        self._mount()
        self.counters["switches"] += 1
        self._event("tool", "switched", f"tool {old!r} -> {name!r}")

    def retare(self) -> str | None:
        """Re-estimate the bias only, tool kept, in any pose: the bias forgets its value, and the next static
        samples (the sensor must be free of contact) set it.

        Returns
        -------
        str or None
            A warning when the re-tare comes while ``contact`` or ``unexplained`` is raised: if a contact
            caused it, the next static samples take it into the bias (nothing can tell it from a bias
            the calibrator has just forgotten); it is also in the event's text.
        """
        self._core.retare()  # the variance to RETARE_VARIANCE r at least, the checks afresh
        self.counters["retares"] += 1
        raised = [name for name in ("contact", "unexplained") if self.flags_now & BIT[name]]
        warning = f"re-tare while {' and '.join(raised)} is raised: {RETARE_WARNING}" if raised else None
        self._event("bias", "retare", f"re-tare with tool {self.tool!r} kept: the next static samples set the bias"
                    + (f"; {warning}" if warning else ""))
        return warning

    def restart_clock(self, reason: str) -> None:
        """Take the next sample at any time, as after a restart: the motion test starts without history (0.3 s of
        "moving"), the unexplained-wrench timer restarts; bias, variance, tool and counters are kept (a
        transport calls this when its publisher's clock restarted)."""
        self.motion = MotionDetector(self.motion.window, self.motion.min_rate, self.motion.min_hold)
        self._core.restart_clock()
        self.last_time = None
        self._event("clock", "restarted", reason)

    def _restart_checks(self) -> None:
        """The bias was set on purpose (or the clock restarted): the drift test and the self-check start afresh."""
        self._core.restart_checks()

    # ----- identification in place ----------------------------------------------------------------
    def start_identification(self, name: str) -> None:
        """Collect the next static holds to identify a new tool ``name`` (bias updates pause meanwhile)."""
        if not isinstance(name, str) or not name or name == NO_TOOL:
            raise FtcalError(f"a tool needs a name other than {NO_TOOL!r}; got {name!r}.")
        self.identifying = _Identification(name)
        self._core.identifying(True)
        self._event("tool", "identifying", f"identifying tool {name!r}: hold the sensor still in varied poses")

    def finish_identification(self, *, mount: bool = True, save_to: str | Path | None = None) -> PayloadParameters:
        """Identify the tool from the holds collected since :meth:`start_identification`.

        The batch estimator of ``ftcal payload`` (:func:`ftcal.payload.identify.identify_from_statistics`) runs on
        the holds' statistics, with cluster-robust standard errors over the holds and its excitation
        check (its warnings are raised as usual). The tool joins the library; with ``mount`` it is
        mounted and the bias takes the identified value and variance.

        Parameters
        ----------
        mount : mount the new tool
        save_to : payload file to write (atomically), or None

        Returns
        -------
        PayloadParameters

        Raises
        ------
        FtcalError
            Not identifying, or too few holds (at least three) or poses that leave the mass undetermined.
        """
        from ..payload.identify import identify_from_statistics

        job = self.identifying
        if job is None:
            raise FtcalError("no identification in progress (call start_identification first).")
        holds = [h for h in job.holds if h is not None]
        if len(holds) < LIVE_MIN_HOLDS:
            raise FtcalError(f"identifying tool {job.name!r}: {len(holds)} static hold(s) so far; at least "
                             f"{LIVE_MIN_HOLDS} "
                             "in different orientations are needed.")
        self.identifying = None
        self._core.identifying(False)
        total = holds[0]
        for h in holds[1:]:
            total = total + h
        fit = identify_from_statistics({job.name: total}, clusters=holds, cross_validate=False)
        columns = tuple(self.model.output_names_) if self.model is not None else ("Fx", "Fy", "Fz", "Tx", "Ty", "Tz")
        payload = PayloadParameters.from_fit(fit, gravity=self.gravity_magnitude, frame=None, reaction=False,
                                             wrench_columns=columns)
        self.add_tool(job.name, payload, log=False)
        self.identified.add(job.name)
        self._event("tool", "identified", f"tool {job.name!r} identified from {len(holds)} holds: "
                    f"{payload.mass:.4g} ± {payload.stderr['mass']:.2g} kg")
        if save_to is not None:
            from ..files.payload_json import save_payload

            save_payload(payload, save_to, sources=["ftcal live"])
        if mount:
            self.switch_tool(job.name)
            self.bias = payload.bias.astype(float)
            se = np.r_[payload.stderr["force_bias"], payload.stderr["torque_bias"]]
            self.variance = np.maximum(np.nan_to_num(se ** 2, nan=0.0), self.noise_std ** 2)
            self._restart_checks()
        return payload

    # ----- one sample, a block --------------------------------------------------------------------
    def step(self, time: float, *, raw=None, wrench=None, gravity=None, quaternion=None, imu=None,
             joints=None, temperature=None, static=None) -> LiveSample:
        """Process one sample; the arguments are those of :meth:`run` for a single sample (vectors, scalars).

        Returns
        -------
        LiveSample
        """
        if (joints is None and temperature is None and (raw is None) != (wrench is None)
                and (static is None or static is True or static is False) and self.identifying is None):
            # the common calls in one call of the core (conversions, checks, the model, the step; Core.sample); None:
            # the paths below take it (and say why; the core refuses before it changes anything)
            sample, j, fill = self._sample
            if quaternion is None:
                r = None if (gravity is None) == (imu is None) else sample(
                    time, wrench if raw is None else raw, raw is not None, gravity if imu is None else imu,
                    1.0 if imu is None else -1.0, self.last_time, j, fill, -1 if static is None else int(static),
                    self.tool)
            else:  # a wrench (a model's is Python's here) and the Python motion test on the quaternion's angle
                r = None if raw is not None or static is not None or gravity is not None or imu is not None else \
                    self._core._core.sample_quaternion(time, wrench, quaternion, self.last_time, fill,
                                                       self.gravity_magnitude, QUATERNION_NORM_TOLERANCE,
                                                       self.motion.static_one, self.tool)
            if r is not None:
                result, bits, logged = r
                self._core.samples += 1
                self.last_time = result[0]
                counters = self.counters
                counters["samples"] += 1
                counters["updates"] += result[2]
                if logged:
                    events = self._texts(self._core.take_events(), [fill if j < 0 else float(np.ravel(raw)[j])])
                    self._log(events)
                    counters["contacts"] += sum(1 for e in events if e[1] == "contact" and e[2] == "raised")
                self.flags_now = bits | (self.flags_now & _SILENT)
                if bits:
                    result[3].update({name: self._reasons.get(name, name) for name in _NAMES_OF_BITS[bits]})
                return result
        if static is not None and not isinstance(static, (bool, np.bool_)):
            raise FtcalError(f"static must be True, False or None; got {static!r} ({type(static).__name__}).")
        sample = self._step_core(time, raw, wrench, gravity, quaternion, imu, joints, temperature, static)
        if sample is not None:
            return sample

        def one(x, name):
            try:
                return None if x is None else np.asarray(x, dtype=float).reshape(1, -1)
            except (TypeError, ValueError):
                raise FtcalError(f"{name} must be numbers; got {str(x)[:80]!r}.") from None

        r = self.run(one(time, "time").reshape(-1)[:1] if time is not None else one(math.nan, "time")[0],
                     raw=one(raw, "raw"), wrench=one(wrench, "wrench"), gravity=one(gravity, "gravity"),
                     quaternion=one(quaternion, "quaternion"), imu=one(imu, "imu"), joints=one(joints, "joints"),
                     temperature=None if temperature is None else one(temperature, "temperature").reshape(-1)[:1],
                     static=None if static is None else np.array([bool(static)]))
        bits = int(r.flags[0])
        reasons = {e[1]: e[3] for e in r.events if e[2] == "raised"}
        return LiveSample(float(r.time[0]), r.calibrated[0], r.compensated[0], r.bias[0], r.bias_std[0],
                          bool(r.static[0]), bool(r.updated[0]),
                          {name: reasons.get(name, self.reason_of(name)) for name in names_of(bits)}, r.tool)

    def _step_core(self, time, raw, wrench, gravity, quaternion, imu, joints, temperature, static):
        """:meth:`step` as one call of the core with the least Python around it; None when :meth:`run` must take the
        sample (an identification, joints, a temperature given, or input the core refuses: :meth:`run` says why).
        The core refuses before it changes anything, so :meth:`run` meets the state the sample would have met."""
        if (self.identifying is not None or joints is not None or temperature is not None or (raw is None) == (
                wrench is None) or (gravity is not None) + (quaternion is not None) + (imu is not None) != 1):
            return None
        try:
            t = float(time)
            if raw is not None:
                if self.model is None:
                    return None
                u = raw
                # the model evaluated in the core's call; with a quaternion's motion test first, in Python (what
                # the core would refuse is known before the motion test keeps the sample)
                w = None if self._model_in_core and (quaternion is None or static is not None) \
                    else self._row_predict()(raw)
            else:
                u = w = wrench
            override = -1 if static is None else int(bool(static))
            if quaternion is not None:
                qx, qy, qz, qw = quaternion.tolist() if isinstance(quaternion, np.ndarray) else map(float, quaternion)
                norm = math.sqrt(qx * qx + qy * qy + qz * qz + qw * qw)
                if not abs(norm - 1.0) <= QUATERNION_NORM_TOLERANCE:
                    return None
                qx, qy, qz, qw = signal = (qx / norm, qy / norm, qz / norm, qw / norm)
                gm = -self.gravity_magnitude
                g = (gm * (2.0 * (qx * qz - qw * qy)), gm * (2.0 * (qy * qz + qw * qx)),
                     gm * (1.0 - 2.0 * (qx * qx + qy * qy)))
            else:
                g = gravity if gravity is not None else [-float(v) for v in imu]
            if self.last_time is not None and not t > self.last_time:
                return None
            temp = self._temperature_fill if self._temperature_input is None else float(u[self._temperature_input])
            x = [*(u.tolist() if isinstance(u, np.ndarray) else u), temp]
            if quaternion is not None and static is None:  # a quaternion's angle: the Python motion test decides
                # (it keeps the sample: first what the core would refuse, so that run() meets the same state)
                values = [*x, *(w.tolist() if isinstance(w, np.ndarray) else w)]
                if not (math.isfinite(sum(values)) and max(values) <= MAX_CELL_MAGNITUDE
                        and min(values) >= -MAX_CELL_MAGNITUDE):
                    return None
                override = int(self.motion.static_one(t, "quaternion", signal)[0])
            out = np.empty(FIELDS)
            logged = (self._core.step_raw(t, x, g, override, out) if w is None
                      else self._core.step(t, x, w, g, override, out))
        except (TypeError, ValueError):
            return None
        if logged < 0:
            return None
        self.last_time = t
        code, bits = int(out[25]), int(out[26])
        self.counters["samples"] += 1
        self.counters["updates"] += code >> 1
        if logged:
            events = self._texts(self._core.take_events(), [temp])
            self._log(events)
            self.counters["contacts"] += sum(1 for e in events if e[1] == "contact" and e[2] == "raised")
        self.flags_now = bits | (self.flags_now & BIT["silent"])
        return LiveSample(t, out[0:6], out[6:12], out[12:18], out[18:24], bool(code & 1), bool(code >> 1),
                          {name: self._reasons.get(name, name) for name in _NAMES_OF_BITS[bits]} if bits else {},
                          self.tool)

    def _row_predict(self):
        """The model's one-sample predictor (:meth:`CalibrationModel.row_predictor`), made once per model."""
        cached = getattr(self, "_row_predictor", None)
        if cached is None or cached[0] is not self.model:
            one = getattr(self.model, "row_predictor", lambda: None)()
            if one is None:  # a family without one: predict()'s own path
                model = self.model
                one = lambda u: model.predict(np.array([u]), warn_out_of_range=False)[0]  # noqa: E731
            cached = self._row_predictor = (self.model, one)
        return cached[1]

    def run(self, time, *, raw=None, wrench=None, gravity=None, quaternion=None, imu=None, joints=None,
            temperature=None, static=None) -> LiveResult:
        """Process a block of samples, in time order, continuing from the current state.

        Parameters
        ----------
        time : ndarray of shape (n,), s, strictly increasing (and after the previous block)
        raw : ndarray of shape (n, n_inputs), the model's inputs in its order (needs a model)
        wrench : ndarray of shape (n, 6), the wrench itself (without a model)
        gravity : ndarray of shape (n, 3), gravity in sensor axes, m/s²; or
        quaternion : ndarray of shape (n, 4), sensor-to-world orientation, x y z w (world z up); or
        imu : ndarray of shape (n, 3), an accelerometer in sensor axes (gravity = −reading at rest)
        joints : ndarray of shape (n, n_joints) or None, rad: the motion signal when no quaternion is given;
            alone (no gravity, quaternion or imu), gravity too, through ``robot``
        temperature : ndarray of shape (n,) or None, °C (the model's temperature input is used when it has one)
        static : ndarray of bool, shape (n,), or None: overrides the motion test

        Returns
        -------
        LiveResult

        Raises
        ------
        FtcalError
            Missing or misshapen inputs, non-finite values, or time that does not increase.
        """
        t = np.asarray(time, dtype=float).reshape(-1)
        n = t.size
        u, w = self._calibrate(raw, wrench, n)
        g, kind, signal = self._gravity(gravity, quaternion, imu, joints, n)
        if not np.all(np.isfinite(t)) or np.any(np.diff(t) <= 0) or (
                n and self.last_time is not None and t[0] <= self.last_time):
            raise FtcalError("time must be finite and strictly increasing (also across blocks).")
        if n == 0:
            return self._empty()
        if static is not None:
            given = np.asarray(static)
            # bool, or 0/1 integers; never text ('False' is a non-empty string, true as a bool)
            if given.dtype.kind not in "bui" or (given.dtype.kind != "b" and np.any((given != 0) & (given != 1))):
                raise FtcalError(f"static must be booleans (or 0/1); got {given.dtype} values.")
            still = given.astype(bool).reshape(-1)
            if still.size != n:
                raise FtcalError(f"static has {still.size} values for {n} samples.")
            override = still.astype(np.int32)
        elif kind == "direction":
            override = None  # the core's motion test on the gravity direction
        else:  # a quaternion's angle or the fastest joint: the motion test in Python, its decision to the core
            override = self.motion.static(t, kind, signal)[0].astype(np.int32)
        temp = self._temperature(temperature, u, n)
        x = np.empty((n, u.shape[1] + 1))
        x[:, :-1] = u
        x[:, -1] = self._temperature_fill if temp is None else np.where(
            temp >= -MAX_CELL_MAGNITUDE, np.minimum(temp, MAX_CELL_MAGNITUDE), MAX_CELL_MAGNITUDE)  # NaN: outside
        out, core_events = self._core.run_wrench(t, x, w, g, override)
        if self.identifying is not None:
            self.identifying.add(w, g, out["static"])
        logged = self._texts(core_events, temp)
        self._log(logged)  # in the core's order: by sample, the tracker's before the flags'
        flag_events = [e for e in logged if e[2] in ("raised", "cleared")]
        self.flags_now = int(out["flags"][-1]) | (self.flags_now & BIT["silent"])
        self.last_time = float(t[-1])
        self.counters["samples"] += n
        self.counters["updates"] += int(np.count_nonzero(out["updated"]))
        self.counters["contacts"] += sum(1 for e in flag_events if e[1] == "contact" and e[2] == "raised")
        return LiveResult(t, w, out["compensated"], out["bias"], out["bias_std"], out["static"], out["updated"],
                          out["chi2"], out["flags"], self.tool, flag_events)

    def _empty(self) -> LiveResult:
        z6 = np.empty((0, 6))
        return LiveResult(np.empty(0), z6, z6, z6, z6, np.empty(0, bool), np.empty(0, bool), np.empty(0),
                          np.empty(0, np.uint16), self.tool, [])

    def _calibrate(self, raw, wrench, n):
        if (raw is None) == (wrench is None):
            raise FtcalError("give either raw (the model's inputs) or wrench, not both or neither.")
        if raw is not None:
            if self.model is None:
                raise FtcalError("raw channels need a calibration model; give wrench instead.")
            u = np.asarray(raw, dtype=float).reshape(n, -1) if n else np.empty((0, len(self.model.input_names_)))
            if u.shape[1] != len(self.model.input_names_):
                raise FtcalError(f"raw has {u.shape[1]} channels; the model takes {len(self.model.input_names_)} "
                                 f"({', '.join(self.model.input_names_)}).")
            _finite(u, "raw")
            w = np.asarray(self.model.predict(u, warn_out_of_range=False) if n else np.empty((0, 6)), dtype=float)
            _finite(w, "the calibration model's wrench (from raw)")  # a polynomial far outside its range overflows
            return u, w
        w = np.asarray(wrench, dtype=float)
        if w.shape != (n, 6):
            raise FtcalError(f"wrench must have shape ({n}, 6); got {w.shape}.")
        _finite(w, "wrench")
        return w, w

    def _gravity(self, gravity, quaternion, imu, joints, n):
        given = [x is not None for x in (gravity, quaternion, imu)]
        if not any(given) and joints is not None and self.robot is not None:
            q = np.asarray(joints, dtype=float).reshape(n, -1)
            if q.shape[1] != len(self.robot.joints):
                raise FtcalError(f"joints has {q.shape[1]} values per sample; the robot model takes "
                                 f"{len(self.robot.joints)} ({', '.join(self.robot.joints)}).")
            _finite(q, "joints")
            return self.robot(q) if n else np.empty((0, 3)), "joints", q
        if sum(given) != 1:
            raise FtcalError("give exactly one of gravity, quaternion or imu"
                             + (" (or joints alone: the robot model gives gravity)." if self.robot is not None
                                else " (joints give gravity only with a robot model)."))
        if quaternion is not None:
            q = np.asarray(quaternion, dtype=float).reshape(n, 4)
            _finite(q, "quaternion")
            g = gravity_from_quaternions(q, self.gravity_magnitude, source="quaternion")
            kind, signal = "quaternion", q / np.linalg.norm(q, axis=1, keepdims=True)
        else:
            g = np.asarray(gravity if gravity is not None else imu, dtype=float).reshape(n, 3)
            _finite(g, "gravity" if gravity is not None else "imu")
            if imu is not None:
                g = -g
            if np.any(np.linalg.norm(g, axis=1) == 0.0):
                raise FtcalError("gravity (or imu) has a zero vector (or one whose squared length underflows); it "
                                 "gives no direction.")
            kind, signal = "direction", g
        if joints is not None and quaternion is None:
            signal = np.asarray(joints, dtype=float).reshape(n, -1)
            _finite(signal, "joints")
            kind = "joints"
        return g, kind, signal

    def _temperature(self, temperature, u, n) -> np.ndarray | None:
        """The temperature the health test reads: the one given, else the model's temperature input, else None."""
        if temperature is not None:
            temp = np.asarray(temperature, dtype=float).reshape(-1)
            if temp.size != n:
                raise FtcalError(f"temperature has {temp.size} values for {n} samples.")
            return temp
        return None if self._temperature_input is None else u[:, self._temperature_input]

    def _texts(self, core_events, temp) -> list:
        """The core's events of a block as (time, flag, kind, reason), in its order: the flags' raised and cleared
        (flags in bit order) and the tracker's (the drift test's rollbacks, the self-check's)."""
        from .c_events import EVENT_KINDS

        code = {key: value[0] for key, value in EVENT_KINDS.items()}
        flags = tracker = []
        names = self.model.input_names_ if self.model is not None else AXES
        channels = [j for j in range(len(names)) if j != self._temperature_input]

        def listed(mask):
            return ", ".join(names[channels[j]] for j, on in enumerate(mask) if on)

        for kind, k, time, bit, count, mask, value, extra in core_events:
            if kind in (code["FLAG_RAISED"], code["FLAG_CLEARED"]):
                name = FLAGS[bit.bit_length() - 1]
                if kind == code["FLAG_CLEARED"]:
                    flags.append((time, name, "cleared", f"{name} cleared"))
                    continue
                if name == "saturated":
                    text = _saturated_text(listed(mask), self._saturation_why())
                elif name == "stuck":
                    text = _stuck_text(listed(mask), count)
                elif name == "dead":
                    text = _dead_text(listed(mask), count)
                elif name == "out_of_range":
                    text = OUT_OF_RANGE_TEXT
                elif name == "temperature":
                    text = _temperature_text(float(temp[k]), *self.temperature_range)
                elif name == "contact":
                    text = self._contact_text(value[0])
                else:
                    text = self._unexplained_text(value[2], list(value[3:9]))
                flags.append((time, name, "raised", text))
            elif kind == code["ROLLBACK"]:
                tracker.append((time, "bias", "rollback", _rollback_text((None, None, *value[:3]))))
            elif kind == code["TRACKER_ADAPTED"]:
                tracker.append((time, "tracker", "adapted", walk_adapted_text(count, value[0], extra) if count else
                                noise_adapted_text(value[0], int(value[1]), int(value[2]), value[3], value[4], extra)))
            elif kind == code["TRACKER_LOCKED_OUT"]:
                tracker.append((time, "tracker", "locked_out", locked_out_text(value[0])))
            elif kind == code["TRACKER_REACQUIRED"]:
                tracker.append((time, "tracker", "reacquired", reacquired_text(*value[:3], extra)))
            elif kind == code["TRACKER_UNDONE"]:
                tracker.append((time, "tracker", "undone", undone_text(value[0])))
        return flags

    def _saturation_why(self) -> str:
        if self.adc_limits is not None:
            return f"at the ADC limits {self.adc_limits[0]:g}/{self.adc_limits[1]:g}"
        return f"flat for >= {SATURATION_RUN} samples outside the calibration's range" if self.model is not None else ""

    def _contact_text(self, chi2: float) -> str:
        return (f"wrench the tool {self.tool!r} and the bias do not explain (chi2 {chi2:.3g} > {self.threshold:.3g}, "
                "6 dof); the bias is not updated")

    def _unexplained_text(self, duration: float, innovation: list) -> str:
        return (f"innovation beyond {self.unexplained_sigma:g} sigma and the acceptance thresholds for "
                f"{duration:.3g} s (> {self.unexplained_seconds:g} s): |compensated| = "
                + ", ".join(f"{abs(v):.3g}" for v in innovation))

    def reason_of(self, name: str) -> str:
        """The reason logged when flag ``name`` was last raised (its name if none is logged)."""
        return self._reasons.get(name, name)

    def _log(self, events) -> None:
        self.events.extend(events)
        self._reasons.update((e[1], e[3]) for e in events if e[2] == "raised")

    def _event(self, flag: str, kind: str, text: str) -> None:
        self._log([(self.last_time if self.last_time is not None else math.nan, flag, kind, text)])

    def set_silent(self, silent: bool, reason: str = "") -> None:
        """Raise or clear the ``silent`` flag (the transports call this)."""
        if bool(self.flags_now & BIT["silent"]) != silent:
            self.flags_now ^= BIT["silent"]
            self._event("silent", "raised" if silent else "cleared", reason or "silent cleared")

    # ----- status and persistence -----------------------------------------------------------------
    def status(self) -> dict:
        """The state in plain types: bias, its std, tool, tools, flags, counters, time."""
        return {"time": self.last_time, "tool": self.tool, "tools": list(self.tools),
                "bias": self.bias.tolist(), "bias_std": np.sqrt(self.variance).tolist(),
                "flags": names_of(self.flags_now), "counters": dict(self.counters),
                "identifying": None if self.identifying is None else self.identifying.name,
                "holds_collected": 0 if self.identifying is None else len(self.identifying.holds)}

    def state_document(self) -> dict:
        """The persisted state (JSON-ready): bias, covariance, tool, counters, time, and the tools identified in
        place (the others come from their payload files)."""
        from ..files.payload_json import payload_document

        doc = {**state_envelope(), "time": self.last_time,
               "tool": self.tool, "bias": self.bias.tolist(), "variance": self.variance.tolist(),
               "counters": dict(self.counters), "flags": names_of(self.flags_now),
               "tools": {name: payload_document(self.tools[name]) for name in self.identified},
               "model": self.model_fingerprint(),
               # optional (files without them still read): the tracker's r per sample and q per s, as adapted
               "noise_variance": (self.noise_std ** 2).tolist(), "walk_variance": self.walk_variance.tolist()}
        if not all(np.isfinite(doc["bias"])) or not all(np.isfinite(doc["variance"])):
            raise FtcalError("the live state has non-finite values; refusing to save it.")
        return doc

    def save_state(self, path: str | Path | None = None) -> Path:
        """Write the state atomically (to ``path`` or ``state_path``) and return where."""
        from ..runtime.atomic import write_text_atomic

        target = Path(path) if path is not None else self.state_path
        if target is None:
            raise FtcalError("no state file: give a path or state_path.")
        write_text_atomic(target, json.dumps(self.state_document(), indent=1) + "\n")
        return target

    def load_state(self, path: str | Path) -> None:
        """Resume from a state file: bias, covariance, tool (and the tools it carries), counters, time.

        Every field is checked before anything changes: a state that is not what :meth:`save_state` writes
        (wrong types or shapes, non-finite, negative or overflowing numbers, a tool not in the library, a
        state written for another calibration model) is refused in one line naming the file and the field.

        Raises
        ------
        FtcalError
        """
        from ..core.limits import LIVE_MAX_STATE_BYTES, MAX_CELL_MAGNITUDE
        from ..files.payload_json import parse_payload

        from ..runtime.inputs import check_input_file

        # a FIFO would block forever and /dev/zero fill the memory: a regular file of bounded size, as the CLI checks
        path = check_input_file(path, "live state file", max_bytes=LIVE_MAX_STATE_BYTES)
        try:
            with open(path, "rb") as stream:
                raw = stream.read(LIVE_MAX_STATE_BYTES + 1)
            if len(raw) > LIVE_MAX_STATE_BYTES:
                raise FtcalError(f"{path}: more than {LIVE_MAX_STATE_BYTES} bytes, not a live state file.")
            doc = json.loads(raw.decode("utf-8"))
        except (OSError, UnicodeDecodeError, ValueError, RecursionError) as exc:
            # ValueError: JSONDecodeError, and an integer beyond Python's 4300 digits
            why = "nested too deeply" if isinstance(exc, RecursionError) else exc
            raise FtcalError(f"{path}: cannot read the live state ({why}).") from None
        check_state_envelope(doc, path)

        def bad(field: str, what: str):
            return FtcalError(f"{path}: the live state's {field!r} {what}.")

        def number(value, field: str) -> float:
            # JSON true/false are not numbers; NaN and Infinity are what json.loads makes of NaN/Infinity tokens.
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                raise bad(field, f"must be a number; got {type(value).__name__}")
            try:
                x = float(value)
            except OverflowError:  # an integer literal beyond any float (e.g. 1 followed by 400 zeros)
                x = float("inf")
            if not abs(x) <= MAX_CELL_MAGNITUDE:
                raise bad(field, f"must be finite and at most {MAX_CELL_MAGNITUDE:g} in magnitude; got {value!r}")
            return x

        def six(field: str) -> np.ndarray:
            value = doc.get(field)
            if not isinstance(value, list) or len(value) != 6:
                raise bad(field, "must be a list of 6 numbers (one per axis)")
            return np.array([number(v, field) for v in value])

        for key in ("time", "tool", "bias", "variance", "counters", "tools"):
            if key not in doc:
                raise bad(key, "is missing")
        bias, variance = six("bias"), six("variance")
        if np.any(variance < 0):
            raise bad("variance", "must be >= 0 (a variance per axis; the state keeps no cross-covariance)")
        adapted = {}
        for key in ("noise_variance", "walk_variance"):  # optional: the self-check's r and q when saved
            if key in doc:
                adapted[key] = six(key)
                if np.any(adapted[key] <= 0):
                    raise bad(key, "must be > 0 per axis")
        time = None if doc["time"] is None else number(doc["time"], "time")
        counters_doc = doc["counters"]
        if not isinstance(counters_doc, dict):
            raise bad("counters", "must be an object")
        counters = {}
        for key in self.counters:
            value = counters_doc.get(key)
            if isinstance(value, bool) or not isinstance(value, int) or not 0 <= value < 2 ** 63:
                raise bad("counters", f"must hold {key!r} as an integer in [0, 2**63); got {value!r}")
            counters[key] = value
        if not isinstance(doc["tool"], str):
            raise bad("tool", f"must be a tool name; got {doc['tool']!r}")
        tool = doc["tool"]
        if not isinstance(doc["tools"], dict):
            raise bad("tools", "must be an object of tool name -> payload document")
        tools = {}
        for name, d in doc["tools"].items():
            if not name or name == NO_TOOL:
                raise bad("tools", f"names a tool {name!r}; a tool needs a name other than {NO_TOOL!r}")
            try:
                tools[name] = parse_payload(json.dumps(d), f"{path}: tool {name!r}")
            except (TypeError, ValueError, RecursionError) as exc:
                raise bad("tools", f"holds tool {name!r} that is not a payload document ({exc})") from None
        fingerprint = self.model_fingerprint()
        if doc.get("model", fingerprint) != fingerprint:
            raise FtcalError(f"{path}: the live state was written for another calibration model "
                             f"({'none' if doc.get('model') is None else 'sha256 ' + str(doc.get('model'))[:12]}, "
                             f"now {'none' if fingerprint is None else 'sha256 ' + fingerprint[:12]}); its bias is "
                             "that model's. Give that model, or another state file to start afresh.")
        if tool not in self.tools and tool not in tools:
            raise FtcalError(f"{path}: tool {tool!r} is not in the library ({', '.join([*self.tools, *tools])}).")
        for name, payload in tools.items():
            # Identified in place, it replaced any tool of that name before the state was saved: it still does.
            if self.tools.get(name) is not None:
                self._event("tool", "replaced", f"tool {name!r} as identified in place (from {path}), not as its file")
            self.tools[name] = payload
            self.identified.add(name)
        self.bias, self.variance, self.tool, self.counters = bias, variance, tool, counters
        self._mount()
        if self.self_check is not None and adapted:
            # resume with the adapted r and q, within the self-check's bounds of this run's r0 and q0
            sc = self.self_check
            if "noise_variance" in adapted:
                r0 = np.asarray(sc.noise0)
                self.noise_std = np.sqrt(np.clip(adapted["noise_variance"], r0, R_MAX * r0))
            if "walk_variance" in adapted:
                q0 = np.asarray(sc.walk0)
                self.walk_variance = np.clip(adapted["walk_variance"], q0, Q_MAX * q0)
        self.last_time = time
        self._core.set_clock(time)
        self._restart_checks()
        self._event("state", "resumed", f"resumed from {path} at t={self.last_time}")

    def model_fingerprint(self) -> str | None:
        """sha256 of the calibration model's inputs, outputs and model-file fields (None without a model): the state
        file records it, so that a state is never resumed with a bias that belongs to another model."""
        return model_digest(self.model)


AXES = ("Fx", "Fy", "Fz", "Tx", "Ty", "Tz")
# the flags' names of every combination of their bits (step's result, without a loop over the flags per sample)
_SILENT = BIT["silent"]
_NAMES_OF_BITS = tuple(tuple(name for name in FLAGS if bits & BIT[name]) for bits in range(1 << len(FLAGS)))


def _rollback_text(back: tuple) -> str:
    _, _, lag, chi2, moved = back
    return (f"the bias moved up to {moved:.3g} in {lag:.3g} s, more than the random walk allows (chi2 {chi2:.3g}, 6 dof): "
            "a slow contact or a faster drift; bias and variance back to their values then, predicted since")


def _saturated_text(channels: str, why: str) -> str:
    return f"channel {channels} saturated ({why})"


def _stuck_text(channels: str, run: int) -> str:
    return f"channel {channels} stuck: one value for {run} samples while the sensor or other channels move"


def _dead_text(channels: str, run: int) -> str:
    return f"channel {channels} dead: one value for {run} samples"


def _temperature_text(temperature: float, low: float, high: float) -> str:
    return f"temperature {temperature:.4g} outside the calibration's {low:.4g} to {high:.4g}"


def _finite(x: np.ndarray, name: str) -> None:
    """Refuse a non-finite value, or one beyond :data:`~ftcal.core.limits.MAX_CELL_MAGNITUDE` (its square, and so the
    χ² gate, would overflow: no sensor reads that), naming the sample."""
    ok = np.abs(x) <= MAX_CELL_MAGNITUDE  # NaN fails too
    if not np.all(ok):
        row = int(np.flatnonzero(~np.all(ok.reshape(x.shape[0], -1), axis=1))[0])
        value = x.reshape(x.shape[0], -1)[row][~ok.reshape(x.shape[0], -1)[row]][0]
        what = "a non-finite value" if not np.isfinite(value) else f"{value:g}, beyond {MAX_CELL_MAGNITUDE:g} in magnitude,"
        raise FtcalError(f"{name} has {what} at sample {row}.")


class _Identification:
    """Static holds collected for an in-place tool identification: one AxisStatistics per hold."""

    def __init__(self, name: str) -> None:
        self.name = name
        self.holds: list = []
        self._in_hold = False

    def add(self, wrench: np.ndarray, gravity: np.ndarray, static: np.ndarray) -> None:
        from ..payload.accumulate import payload_statistics
        from ..payload.kinematics import Kinematics

        edges = np.flatnonzero(np.diff(np.r_[0, static.astype(np.int8), 0]))
        for a, b in zip(edges[::2], edges[1::2]):
            stats = payload_statistics(wrench[a:b], Kinematics(gravity[a:b]))
            if a == 0 and self._in_hold and self.holds:
                self.holds[-1] = self.holds[-1] + stats  # the hold goes on from the previous block
            else:
                self.holds.append(stats)
        self._in_hold = bool(static[-1]) if static.size else self._in_hold
