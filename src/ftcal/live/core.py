"""The live step's C core from Python: the extension ``ftcal.live._core`` around ``csrc/ftcal_live.h``.

The same C that ``ftcal convert --to c-runtime`` ships (:mod:`ftcal.live.c_runtime`), with the same
configuration (:func:`~ftcal.live.c_runtime.core_config`; :func:`calibrator_config` for
:class:`~ftcal.live.LiveCalibrator`, which runs on it), so Python and C run one step. In blocks the model is
evaluated by Python's kernels (``model.predict``); one sample at a time :meth:`LiveCore.step_raw` evaluates a
polynomial model in the same C call. The core takes the raw channels, their wrench and gravity per sample, a whole
block in one call (motion test on the gravity direction, or ``static``; the gated Kalman filter, the drift test,
the self-check and the health flags), and logs its events as codes and numbers (:meth:`LiveCore.run_wrench`
returns them; the calibrator formats the texts).

The extension is built at install where a C compiler is there (``setup.py``); without it :func:`require_core`
raises one :class:`~ftcal.runtime.errors.FtcalError` saying how to build it.
"""

from __future__ import annotations

import importlib

import numpy as np

from ..runtime.errors import FtcalError

try:  # the extension by its full name (``from . import _core`` reads as an import of the package ftcal.live itself)
    _core = importlib.import_module("ftcal.live._core")
except ImportError:  # built at install where a C compiler is available
    _core = None

MISSING = ("the live calibrator's compiled core (ftcal.live._core) is not built: reinstall ftcal on a machine with a "
           "C compiler (`make install`, or `python setup.py build_ext --inplace` in a source tree)")
FIELDS = 27  # per sample: calibrated, compensated, bias, bias_std (6 each), chi2, static + 2 updated, flags


def require_core():
    """The extension module, checked against the Python constants its sizes mirror.

    Raises
    ------
    FtcalError
        It is not built, or built from another version's sources.
    """
    if _core is None:
        raise FtcalError(MISSING + ".")
    from ..core.limits import C_RUNTIME_MAX_HOLDS
    from .c_limits import CORE_LIMITS

    # the rings' sizes come from the header's text (c_limits): a build of another version's header differs
    if ({name: getattr(_core, name, None) for name in CORE_LIMITS}, _core.MAX_HOLDS,
            hasattr(_core.Core, "take_events") and hasattr(_core, "set_sample_type")) != (CORE_LIMITS,
                                                                                         C_RUNTIME_MAX_HOLDS, True):
        raise FtcalError("ftcal.live._core was built from other sources than this ftcal; " + MISSING[MISSING.index(
            "reinstall"):] + ".")
    return _core


def calibrator_config(model, temperature_range, **settings) -> dict:
    """The core's configuration for :class:`~ftcal.live.LiveCalibrator`: ``core_config`` of ``model`` (None: the
    wrench itself) with one tool slot (the mounted tool's terms, :meth:`LiveCore.mount`), the calibrator's settings,
    and one input more: the temperature the health test reads (a given one, the model's temperature input, or none),
    outside the range and span tests.

    Parameters
    ----------
    model : CalibrationModel or None
    temperature_range : (low, high) °C or None (no temperature flag)
    **settings : configuration fields to set (``noise_variance``, ``walk_variance``, ``gate_chi2``, ...)

    Returns
    -------
    dict
    """
    from .c_runtime import core_config

    config = core_config(model, {})
    nu = config["n_inputs"]
    config["n_inputs"] = nu + 1
    config["input_low"] = np.r_[config["input_low"], -np.inf]
    config["input_high"] = np.r_[config["input_high"], np.inf]
    if config["has_span"]:  # the temperature column: a zero row and column, not kept (no distance, no off-span part)
        vectors = np.zeros((nu + 1, nu + 1))
        vectors[:nu, :nu] = config["span_vectors"]
        config.update(span_mean=np.r_[config["span_mean"], 0.0], span_unit=np.r_[config["span_unit"], 1.0],
                      span_values=np.r_[config["span_values"], 1.0], span_vectors=vectors,
                      span_kept=np.r_[config["span_kept"], 0])
    else:  # the extension takes every field
        config.update(span_mean=np.zeros(nu + 1), span_unit=np.ones(nu + 1), span_values=np.ones(nu + 1),
                      span_vectors=np.zeros((nu + 1, nu + 1)), span_kept=np.zeros(nu + 1, int), span_off=0.0,
                      span_limit=0.0)
    low, high = (0.0, 0.0) if temperature_range is None else (float(v) for v in temperature_range)
    config.update(temperature=-1 if temperature_range is None else nu, temperature_low=low, temperature_high=high)
    config.update(settings)
    return config


class LiveCore:
    """One live step state in C for ``model`` and the tool library ``tools`` (``convert --to c-runtime``'s).

    Parameters
    ----------
    model : fitted static polynomial CalibrationModel with six outputs
    tools : mapping name → PayloadParameters, in library order (``"none"`` is tool 0)
    tool : index of the tool mounted at the start (0 none, 1.. ``tools`` in order)
    config : the configuration (:func:`calibrator_config`) instead of ``core_config(model, tools)``
    """

    def __init__(self, model, tools: dict, tool: int = 0, *, config: dict | None = None) -> None:
        from .c_runtime import core_config

        module = require_core()
        self.model = model
        config = core_config(model, tools) if config is None else config
        self.n_inputs = int(config["n_inputs"])
        config = {k: np.ravel(v) if isinstance(v, np.ndarray) else v  # row-major: the C's rows (at most its sizes)
                  for k, v in config.items()}
        try:
            self._core = module.Core(config, tool)
        except (ValueError, KeyError, TypeError) as exc:
            raise FtcalError(f"the live calibrator's compiled core refuses its configuration ({exc}).") from None
        self.samples = 0  # stepped by the core: an event's sample number minus this is its index in the block

    def run(self, time, raw, gravity, static=None) -> dict:
        """Step a block of samples; the model's wrench from ``model.predict``.

        Parameters
        ----------
        time : ndarray of shape (n,), s, strictly increasing (and after the previous block)
        raw : ndarray of shape (n, n_inputs)
        gravity : ndarray of shape (n, 3), sensor axes
        static : ndarray of bool of shape (n,) or None (the motion test on the gravity direction)

        Returns
        -------
        dict of ndarrays: calibrated, compensated, bias, bias_std (n, 6), chi2 (n,), static, updated (bool), flags

        Raises
        ------
        FtcalError
            A sample the core refuses (not finite, beyond the magnitude limit, time not increasing, zero gravity);
            the samples before it are stepped.
        """
        u = np.ascontiguousarray(raw, dtype=float).reshape(-1, self.n_inputs)
        w = self.model.predict(u, warn_out_of_range=False)
        override = None if static is None else np.asarray(static, bool).astype(np.int32)
        return self.run_wrench(time, u, w, gravity, override)[0]

    def run_wrench(self, time, u, w, gravity, override=None) -> tuple[dict, list]:
        """Step a block whose wrench ``w`` (n, 6) is given; ``override`` int32 (n,): −1 the motion test, 0, 1.

        Returns
        -------
        (outputs as :meth:`run`'s, the events logged as the core's tuples (kind, index in the block, time, flag,
        count, channels, value, extra))
        """
        t = np.ascontiguousarray(time, dtype=float).reshape(-1)
        n = t.size
        u = np.ascontiguousarray(u, dtype=float).reshape(n, self.n_inputs)
        w = np.ascontiguousarray(w, dtype=float).reshape(n, 6)
        g = np.ascontiguousarray(gravity, dtype=float).reshape(n, 3)
        override = (np.full(n, -1, np.int32) if override is None
                    else np.ascontiguousarray(override, dtype=np.int32).reshape(n))
        out = np.empty((n, FIELDS))
        events, done, start = [], 0, self.samples
        while True:  # the core pauses before its event ring could overwrite an event: read them, go on
            stepped, refused = self._core.run(t[done:], u[done:], w[done:], g[done:], override[done:], out[done:])
            done += stepped
            self.samples += stepped
            events += self._take(start)
            if refused:
                raise FtcalError(f"sample {done} of the block was refused (not finite, too large, time not "
                                 "increasing or zero gravity); the samples before it were stepped.")
            if done == n:
                break
        code = out[:, 25].astype(int)
        return ({"calibrated": out[:, 0:6], "compensated": out[:, 6:12], "bias": out[:, 12:18],
                 "bias_std": out[:, 18:24], "chi2": out[:, 24], "static": (code & 1).astype(bool),
                 "updated": (code >> 1).astype(bool), "flags": out[:, 26].astype(np.uint16)}, events)

    def step(self, time: float, u, w, gravity, override: int, out: np.ndarray) -> int:
        """One sample (numpy rows or sequences; ``override`` −1, 0, 1) into ``out`` (27 float64, :meth:`run`'s
        columns): the events it logged (read them with :meth:`take_events`), or −1: refused, nothing changed."""
        logged = self._core.step(time, u, w, gravity, override, out)
        if logged >= 0:
            self.samples += 1
        return logged

    def set_model(self, model) -> bool:
        """Evaluate ``model`` in :meth:`step_raw` (a static polynomial: its monomial table, input normalisation and
        coefficients, as ``ftcal.core``'s kernels read them); False, nothing set, for a model without them."""
        from ..core.kernels import step_table

        try:
            basis = model.layout_.basis
            if not model.layout_.is_static or len(model.output_names_) != 6:
                return False
            steps = step_table(basis.n_inputs, basis.degree)
            coef = np.ascontiguousarray(np.asarray(model.coef_, float).T)
            norm = model.input_normalization_
            offset, inv_scale = np.asarray(norm.offset, float), 1.0 / np.asarray(norm.scale, float)
        except (AttributeError, TypeError, ValueError):
            return False
        if coef.shape != (6, basis.n_terms) or offset.shape != (basis.n_inputs,):
            return False
        self._core.set_model(np.ascontiguousarray(offset), np.ascontiguousarray(inv_scale), coef,
                             np.ascontiguousarray(steps, dtype=np.int64))
        return True

    def step_raw(self, time: float, u, gravity, override: int, out: np.ndarray) -> int:
        """:meth:`step` with the wrench of :meth:`set_model`'s model for ``u`` evaluated in the same C call."""
        logged = self._core.step_raw(time, u, gravity, override, out)
        if logged >= 0:
            self.samples += 1
        return logged

    def take_events(self) -> list:
        """The events of the last :meth:`step` (index 0 is that sample)."""
        return self._take(self.samples - 1)

    def _take(self, start: int) -> list:
        """The core's events since the last call: (kind, index from sample ``start``, time, flag, count, channels,
        value, extra)."""
        return [(kind, sample - start, time, flag, count, channels, value, extra)
                for kind, time, sample, flag, count, channels, value, extra in self._core.take_events()]

    def retare(self) -> int:
        """Re-tare, tool kept; returns the contact flags raised now (0 if none)."""
        flags = self._core.retare()
        self._core.take_events()  # the caller logs its own re-tare event
        return flags

    def set_tool(self, tool: int) -> None:
        """Mount tool ``tool`` (its index in the library)."""
        self._core.set_tool(tool)

    def mount(self, mass: float, mc, sign: float) -> None:
        """The mounted tool's gravity terms: mass, mass × centre of mass (3,), sign (−1 for a reaction payload)."""
        self._core.mount(float(mass), tuple(float(c) for c in mc), float(sign))

    def counters(self) -> dict:
        """The state's counts: samples, updates, contacts, retares, switches, rollbacks, the self-check's."""
        return self._core.counters()

    def setting(self, name: str) -> np.ndarray:
        """A setting or the bias state (``noise_variance``, ``walk_variance``, ``bias``, ``variance``, ...)."""
        return np.array(self._core.get(name))

    def set(self, name: str, values) -> None:
        """Set a setting or the bias state (as many values as :meth:`setting` gives)."""
        self._core.set(name, np.asarray(values, float).reshape(-1).tolist())

    def state(self) -> bytes:
        """The whole state (plain data with its configuration): :meth:`set_state` puts it back."""
        return self._core.state()

    def set_state(self, state: bytes) -> None:
        self._core.set_state(state)

    def identifying(self, on: bool) -> None:
        """Pause (True) or resume the bias updates and the contact and unexplained flags (an identification)."""
        self._core.identifying(bool(on))

    def adc_limits(self, limits) -> None:
        """Saturated at the ADC limits (low, high), or (None) flat beyond the training range."""
        self._core.adc_limits(*(limits if limits is not None else (None,)))

    def restart_checks(self) -> None:
        """The drift test, the self-check and the hold-off start afresh; the bias is kept."""
        self._core.restart_checks()

    def restart_clock(self) -> None:
        """The next sample may come at any time: no motion history, the checks and timers restart."""
        self._core.restart_clock()

    def set_clock(self, time: float | None) -> None:
        """The last sample's time (a state resumed: the next sample's Δt counts from it), or None."""
        self._core.set_clock(time)

    def set_self_check(self, on: bool) -> None:
        self._core.set_self_check(bool(on))
