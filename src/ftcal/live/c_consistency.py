"""The self-check's configuration for the C core: :mod:`ftcal.live.consistency`'s constants as data.

The C itself is hand-written in ``csrc/ftcal_live_selfcheck.h`` (a section of ``csrc/ftcal_live.h``), one function
per step of :class:`~ftcal.live.consistency.SelfCheck` with the same arithmetic in the same order; the bounds,
windows and times it uses are the configuration fields named here, filled from the Python constants.
"""

from __future__ import annotations

from .consistency import (CHI2_6_MEDIAN, CORRELATION_S, DIFF_CAP, GATED_FACTOR, KEEP_HOLDS, LOCK_S, MIN_HOLD_S,
                          MIN_TURN_DEG, MIN_WALK_SHARE, MIN_WALK_STARTS, MIN_WINDOW_SAMPLES, NIS_FACTOR, Q_MAX, R_MAX,
                          TURN_SHARE, WALK_FACTOR, WALK_KEEP, WINDOW_S)


def selfcheck_macros(macro: str) -> str:
    """The self-check's size macros: the locked holds and the hold starts it keeps."""
    return (f"#define {macro}_SC_KEEP_HOLDS FTCAL_LIVE_SC_KEEP_HOLDS   /* {KEEP_HOLDS}: locked holds the self-check keeps */\n"
            f"#define {macro}_SC_WALK_KEEP FTCAL_LIVE_SC_WALK_KEEP   /* {WALK_KEEP}: hold starts the walk matching keeps */")


def selfcheck_config() -> dict:
    """The ``sc_*`` fields of the core's configuration (``FTL_(config)``), from :mod:`ftcal.live.consistency`."""
    return {"sc_lock_s": LOCK_S, "sc_min_hold_s": MIN_HOLD_S, "sc_min_turn_deg": MIN_TURN_DEG,
            "sc_turn_share": TURN_SHARE, "sc_correlation_s": CORRELATION_S, "sc_window_s": WINDOW_S,
            "sc_min_window_samples": int(MIN_WINDOW_SAMPLES), "sc_r_max": R_MAX, "sc_q_max": Q_MAX,
            "sc_nis_factor": NIS_FACTOR, "sc_gated_factor": GATED_FACTOR, "sc_diff_cap": DIFF_CAP,
            "sc_min_walk_starts": int(MIN_WALK_STARTS), "sc_min_walk_share": MIN_WALK_SHARE,
            "sc_walk_factor": WALK_FACTOR, "sc_chi2_6_median": CHI2_6_MEDIAN}
