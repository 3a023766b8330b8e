"""The event log of the C core (``csrc/ftcal_live.h``, its event-log sections): kinds and texts as data.

:class:`ftcal.live.LiveCalibrator` logs ``(time, flag, kind, reason)`` tuples in ``events``: tool
switched, identifying, identified, re-tare, a flag raised or cleared, the drift test's rollback and the
self-check's adaptations, lock-outs, re-acquisitions and undone rollbacks. The C keeps the same events in a
ring of ``NAME_MAX_EVENTS`` fixed-size structs in its state (:data:`~ftcal.core.limits.C_RUNTIME_MAX_EVENTS`
unless the user defines ``NAME_MAX_EVENTS`` before the include): no allocation; past it the oldest is
overwritten and counted (``NAME_events_dropped``). An event holds the numbers its text needs (tool
indices, the flag's channels, run length, temperature, χ², the unexplained run, the identified mass), so
``NAME_describe_event`` gives Python's reason for it however long after; the step writes one only on a
sample whose flags change (``NAME_flag_events`` in the core).

Python-only events (the C has no way to cause them): ``("tool", "added")`` (a payload file added at run
time), the ``silent`` flag's (a transport's) and ``("state", "resumed")`` (state files).
"""

from __future__ import annotations

from ..files.c_text import c_string
from .defaults import RETARE_WARNING

# name of the C constant NAME_EVENT_<name> → (its value, Python's ``flag`` field or None for the flag's name,
# Python's ``kind``)
EVENT_KINDS = {"TOOL_SWITCHED": (1, "tool", "switched"), "TOOL_IDENTIFYING": (2, "tool", "identifying"),
               "TOOL_IDENTIFIED": (3, "tool", "identified"), "RETARE": (4, "bias", "retare"),
               "FLAG_RAISED": (5, None, "raised"), "FLAG_CLEARED": (6, None, "cleared"),
               "ROLLBACK": (7, "bias", "rollback"), "TRACKER_ADAPTED": (8, "tracker", "adapted"),
               "TRACKER_LOCKED_OUT": (9, "tracker", "locked_out"), "TRACKER_REACQUIRED": (10, "tracker", "reacquired"),
               "TRACKER_UNDONE": (11, "tracker", "undone")}
# Python's (flag, kind) of the events the C does not log ("silent": both kinds).
PYTHON_ONLY = (("tool", "added"), ("silent", "raised"), ("silent", "cleared"), ("state", "resumed"))
# Python's (flag, kind) of the events the C counts in its state instead of logging: none since the core logs the
# drift test's rollbacks and the self-check's adaptations, lock-outs, re-acquisitions and undone rollbacks with
# their numbers (it also counts them: rollbacks, sc_adaptations, ... with the last one's time).
COUNTED = ()


def event_macros(macro: str, max_events: int) -> str:
    """The kinds, their names (``NAME_event_kind_name``'s table) and the ring's size (before the core)."""
    kinds = "\n".join(f"#define {macro}_EVENT_{key} {code}" for key, (code, _, _) in EVENT_KINDS.items())
    names = ", ".join(c_string(kind) for _, (_, _, kind) in sorted(EVENT_KINDS.items(), key=lambda i: i[1][0]))
    return f"""/* the event log: a ring of {macro}_MAX_EVENTS events in the state (define it before the include) */
{kinds}
#define {macro}_EVENT_KIND_NAMES {names}
#ifndef {macro}_MAX_EVENTS
#define {macro}_MAX_EVENTS {max_events}
#endif
#if {macro}_MAX_EVENTS < 1
#error "{macro}_MAX_EVENTS must be at least 1"
#endif"""


def events_config() -> dict:
    """The texts of the events that live in Python constants (the core's configuration)."""
    return {"retare_warning": " is raised: " + RETARE_WARNING, "plus_minus": " ± "}
