r"""Health flags in the C core (``csrc/ftcal_live.h``): their bits, names and constants as data.

The step's flags, their ``raised``/``cleared`` events and ``NAME_describe_flags``' one-line reasons (the reasons
:class:`ftcal.live.LiveCalibrator` gives: the reason a flag was last raised with, its numbers taken when it was
raised, joined by ``"; "`` in bit order; a flag never raised is its name) are hand-written C in the core. Their
fixed words are written there after the Python templates of :mod:`ftcal.live.calibrator`
(``tests/live/test_c_runtime_library.py`` holds the two texts equal); the words that live in Python constants, the flag
names and the run lengths reach the C as data (:func:`health_macros`, :func:`health_config`). Names from files
reach the C only as string literals (:func:`ftcal.files.c_text.c_string`): the compiled-in tools' ``repr`` is
Python's; a tool named at run time is quoted by the C as Python's ``repr`` quotes it, exactly for ASCII (quote
choice, ``\\``, ``\n``, ``\t``, ``\r``, ``\xNN``), for U+0080 to U+00A0 and U+00AD; other non-ASCII bytes are
copied (Python escapes the non-printable ones among them, e.g. U+202E).
"""

from __future__ import annotations

from ..data.signals import SATURATION_RUN, STUCK_RUN
from ..files.c_text import c_string
from .defaults import OUT_OF_RANGE_TEXT
from .health import BIT, DEAD_RUN, FLAGS, LOAD_STEPS


def health_macros(macro: str) -> str:
    """The flags' bits, their count and their names (``NAME_flag_name``'s table)."""
    bits = [f"#define {macro}_FLAG_{flag.upper()} {bit}u" for flag, bit in BIT.items()]
    return "\n".join([*bits, f"#define {macro}_N_FLAGS {len(FLAGS)}",
                      f"#define {macro}_FLAG_NAMES {', '.join(c_string(f) for f in FLAGS)}"])


def health_config() -> dict:
    """The health fields of the core's configuration (``FTL_(config)``)."""
    return {"stuck_run": int(STUCK_RUN), "dead_run": int(DEAD_RUN), "saturation_run": int(SATURATION_RUN),
            "load_steps": LOAD_STEPS, "out_of_range_text": OUT_OF_RANGE_TEXT}
