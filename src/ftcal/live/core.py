"""The live step's C core from Python: the extension ``ftcal.live._core`` around ``csrc/ftcal_live.h``.

The same C that ``ftcal convert --to c-runtime`` ships (:mod:`ftcal.live.c_runtime`), with the same
configuration (:func:`~ftcal.live.c_runtime.core_config`), so Python and C run one step. The model is
evaluated by Python's kernels (``model.predict``); the core takes the raw channels, their wrench and gravity
per sample, a whole block in one call (motion test on the gravity direction, or ``static``; the gated Kalman
filter, the drift test, the self-check and the health flags).

The extension is built at install where a C compiler is there (``setup.py``); without it :func:`require_core`
raises one :class:`~ftcal.runtime.errors.FtcalError` saying how to build it.
"""

from __future__ import annotations

import numpy as np

from ..runtime.errors import FtcalError

try:
    from . import _core
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
    from .c_consistency import KEEP_HOLDS, WALK_KEEP
    from .c_runtime import DRIFT_SNAPSHOTS

    if (getattr(_core, "SC_WALK_KEEP", None), _core.DRIFT_SNAPSHOTS, _core.SC_KEEP_HOLDS, _core.MAX_HOLDS) != (
            WALK_KEEP, DRIFT_SNAPSHOTS, KEEP_HOLDS, C_RUNTIME_MAX_HOLDS):
        raise FtcalError("ftcal.live._core was built from other sources than this ftcal; " + MISSING[MISSING.index(
            "reinstall"):] + ".")
    return _core


class LiveCore:
    """One live step state in C for ``model`` and the tool library ``tools`` (``convert --to c-runtime``'s).

    Parameters
    ----------
    model : fitted static polynomial CalibrationModel with six outputs
    tools : mapping name → PayloadParameters, in library order (``"none"`` is tool 0)
    tool : index of the tool mounted at the start (0 none, 1.. ``tools`` in order)
    """

    def __init__(self, model, tools: dict, tool: int = 0) -> None:
        from .c_runtime import core_config

        module = require_core()
        self.model = model
        self.n_inputs = len(model.input_names_)
        config = {k: np.ravel(v) if isinstance(v, np.ndarray) else v  # row-major: the C's rows (at most its sizes)
                  for k, v in core_config(model, tools).items()}
        self._core = module.Core(config, tool)

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
        t = np.ascontiguousarray(time, dtype=float).reshape(-1)
        n = t.size
        u = np.ascontiguousarray(raw, dtype=float).reshape(n, self.n_inputs)
        w = np.ascontiguousarray(self.model.predict(u, warn_out_of_range=False), dtype=float)
        g = np.ascontiguousarray(gravity, dtype=float).reshape(n, 3)
        override = (np.full(n, -1, np.int32) if static is None
                    else np.ascontiguousarray(np.asarray(static, bool), dtype=np.int32))
        out = np.empty((n, FIELDS))
        done = self._core.run(t, u, w, g, override, out)
        if done < n:
            raise FtcalError(f"sample {done} of the block was refused (not finite, too large, time not increasing "
                             "or zero gravity); the samples before it were stepped.")
        code = out[:, 25].astype(int)
        return {"calibrated": out[:, 0:6], "compensated": out[:, 6:12], "bias": out[:, 12:18],
                "bias_std": out[:, 18:24], "chi2": out[:, 24], "static": (code & 1).astype(bool),
                "updated": (code >> 1).astype(bool), "flags": out[:, 26].astype(np.uint16)}

    def retare(self) -> int:
        """Re-tare, tool kept; returns the contact flags raised now (0 if none)."""
        return self._core.retare()

    def set_tool(self, tool: int) -> None:
        """Mount tool ``tool`` (its index in the library)."""
        self._core.set_tool(tool)

    def counters(self) -> dict:
        """The state's counts: samples, updates, contacts, retares, switches, rollbacks, the self-check's."""
        return self._core.counters()

    def setting(self, name: str) -> np.ndarray:
        """A setting or the bias state (``noise_variance``, ``walk_variance``, ``bias``, ``variance``, ...)."""
        return np.array(self._core.get(name))
