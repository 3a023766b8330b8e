"""ftcal while the robot runs: the live calibrator, its replay and Zenoh transports, its persisted state.

Owns :class:`LiveCalibrator` (calibration model + tool library + gated random-walk bias tracker +
health flags, one sample or one block at a time), replaying recordings through it
(:mod:`ftcal.live.replay`), serving it over Zenoh (:mod:`ftcal.live.zenoh_node`), and the same
per-sample step generated as C99 (:mod:`ftcal.live.c_runtime`, the ``convert --to c-runtime``
writer, which ``files.targets`` names by string).
May import ``check``, ``plan``, ``insitu``, ``report``, ``files``, ``robot``, ``payload``, ``data``,
``core`` and ``runtime``; ``sim`` and ``cli`` import it.
"""

from __future__ import annotations

__all__ = ["LiveCalibrator", "LiveResult", "LiveSample"]


def __getattr__(name: str):
    if name in __all__:
        from . import calibrator

        return getattr(calibrator, name)
    raise AttributeError(f"module 'ftcal.live' has no attribute {name!r}")
