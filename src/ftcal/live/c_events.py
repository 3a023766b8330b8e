"""The event log of the generated C runtime (:mod:`ftcal.live.c_runtime`).

:class:`ftcal.live.LiveCalibrator` logs ``(time, flag, kind, reason)`` tuples in ``events``: tool
switched, identifying, identified, re-tare, a flag raised or cleared. The C keeps the same events in a
ring of ``NAME_MAX_EVENTS`` fixed-size structs in its state (:data:`~ftcal.core.limits.C_RUNTIME_MAX_EVENTS`
unless the user defines ``NAME_MAX_EVENTS`` before the include): no allocation; past it the oldest is
overwritten and counted (``NAME_events_dropped``). An event holds the numbers its text needs (tool
indices, the flag's channels, run length, temperature, χ², the unexplained run, the identified mass), so
``NAME_describe_event`` gives Python's reason for it however long after; the step writes one only on a
sample whose flags change (:func:`ftcal.live.c_health.flag_events_text`).

Python-only events (the C has no way to cause them): ``("tool", "added")`` (a payload file added at run
time), the ``silent`` flag's (a transport's) and ``("state", "resumed")`` (state files).
"""

from __future__ import annotations

from ..files.c_text import c_string
from .calibrator import RETARE_WARNING

# name of the C constant NAME_EVENT_<name> → (its value, Python's ``flag`` field or None for the flag's name,
# Python's ``kind``)
EVENT_KINDS = {"TOOL_SWITCHED": (1, "tool", "switched"), "TOOL_IDENTIFYING": (2, "tool", "identifying"),
               "TOOL_IDENTIFIED": (3, "tool", "identified"), "RETARE": (4, "bias", "retare"),
               "FLAG_RAISED": (5, None, "raised"), "FLAG_CLEARED": (6, None, "cleared")}
# Python's (flag, kind) of the events the C does not log ("silent": both kinds).
PYTHON_ONLY = (("tool", "added"), ("silent", "raised"), ("silent", "cleared"), ("state", "resumed"))
# Python's (flag, kind) of the events the C counts in its state instead of logging (rollbacks; the self-check's
# sc_adaptations, sc_lockouts, sc_reacquisitions, each with the last one's time).
COUNTED = (("bias", "rollback"), ("tracker", "adapted"), ("tracker", "locked_out"), ("tracker", "reacquired"))


def event_types(macro: str, name: str, max_events: int) -> str:
    """The kinds, the ring's size and the event struct (before the state struct)."""
    kinds = "\n".join(f"#define {macro}_EVENT_{key} {code}" for key, (code, _, _) in EVENT_KINDS.items())
    return f"""/* ----- the event log: a ring of NAME_MAX_EVENTS events in the state (define it before the include) ----- */
{kinds}
#ifndef {macro}_MAX_EVENTS
#define {macro}_MAX_EVENTS {max_events}
#endif
#if {macro}_MAX_EVENTS < 1
#error "{macro}_MAX_EVENTS must be at least 1"
#endif

typedef struct {{
    double time;             /* s: the sample's; for a call between samples the last sample's (NAN before the first) */
    unsigned long sample;    /* samples stepped before it: a flag's event is sample number `sample`, from 0 */
    int kind;                /* {macro}_EVENT_* */
    unsigned flag;           /* FLAG_RAISED, FLAG_CLEARED: the flag's bit ({macro}_FLAG_*) */
    int tool_from, tool_to;  /* TOOL_SWITCHED: the tools; TOOL_IDENTIFIED: the new tool's index (both); TOOL_IDENTIFYING:
                                the index of a library tool of that name, else -1 (both); others: the tool mounted */
    long count;              /* STUCK, DEAD raised: the run length; TOOL_IDENTIFIED: the holds */
    double value[9];         /* the text's numbers: SATURATED (ADC limits used, low, high); TEMPERATURE (temperature);
                                CONTACT (chi2, gate); UNEXPLAINED (sigma, seconds, duration, innovation[6]);
                                TOOL_IDENTIFIED (mass, its standard error) */
    unsigned char channels[{macro}_N_CHANNELS];   /* SATURATED, STUCK, DEAD raised: the channels flagged */
    char tool_name[{macro}_MAX_TOOL_NAME + 1];    /* TOOL_IDENTIFYING, TOOL_IDENTIFIED: the tool's name */
}} {name}_event;
"""


def event_fields(macro: str, name: str) -> str:
    """The ring's fields of the state struct."""
    return f"""    /* the event log (NAME_event_count, NAME_get_event, NAME_clear_events) */
    int events_start, events_count;
    unsigned long events_dropped;   /* events overwritten when the ring was full */
    {name}_event events[{macro}_MAX_EVENTS];"""


def log_text(name: str, macro: str) -> str:
    """The ring's functions: log (the runtime's), count, get, clear, dropped (after NAME_init)."""
    return f"""
/* ----- the event log ----- */

/* Append an event; a full ring overwrites its oldest and counts it. */
static {macro}_RARE void {name}_log_event({name}_state *s, const {name}_event *ev)
{{
    if (s->events_count == {macro}_MAX_EVENTS) {{
        s->events_start = (s->events_start + 1) % {macro}_MAX_EVENTS;
        s->events_count -= 1;
        s->events_dropped += 1;
    }}
    s->events[(s->events_start + s->events_count) % {macro}_MAX_EVENTS] = *ev;
    s->events_count += 1;
}}

/* An event of a call between samples (switch, re-tare, identification): the last sample's time, the samples so far. */
static inline void {name}_call_event({name}_state *s, int kind, int tool_from, int tool_to, {name}_event *ev)
{{
    memset(ev, 0, sizeof *ev);
    ev->time = s->has_time ? s->last_time : NAN;
    ev->sample = s->samples;
    ev->kind = kind;
    ev->tool_from = tool_from;
    ev->tool_to = tool_to;
}}

/* Events kept, 0 .. {macro}_MAX_EVENTS. */
static inline int {name}_event_count(const {name}_state *s)
{{
    return s->events_count;
}}

/* Copy event `i` (0 = the oldest kept) into *ev: 0, or -1 (*ev untouched) for i outside 0 .. count - 1. */
static inline int {name}_get_event(const {name}_state *s, int i, {name}_event *ev)
{{
    if (i < 0 || i >= s->events_count) return -1;
    *ev = s->events[(s->events_start + i) % {macro}_MAX_EVENTS];
    return 0;
}}

/* Events overwritten since init or the last NAME_clear_events because the ring was full. */
static inline unsigned long {name}_events_dropped(const {name}_state *s)
{{
    return s->events_dropped;
}}

/* Empty the log (and zero the dropped count): e.g. after reading every event. */
static inline void {name}_clear_events({name}_state *s)
{{
    s->events_start = 0;
    s->events_count = 0;
    s->events_dropped = 0;
}}
"""


def describe_event_text(name: str, macro: str) -> str:
    """``NAME_event_kind_name`` and ``NAME_describe_event`` (after NAME_describe_flags; left out with NAME_NO_TEXT)."""
    kinds = ", ".join(c_string(kind) for _, (_, _, kind) in sorted(EVENT_KINDS.items(), key=lambda i: i[1][0]))
    return f"""
#ifndef {macro}_NO_TEXT
/* The kind of an event as LiveCalibrator's events spell it ("switched", "identifying", "identified", "retare",
   "raised", "cleared"); 0 for a value that is no {macro}_EVENT_*. */
static inline const char *{name}_event_kind_name(int kind)
{{
    static const char *const names[] = {{{kinds}}};
    return kind >= 1 && kind <= (int)(sizeof names / sizeof names[0]) ? names[kind - 1] : 0;
}}

/* The event's one-line text, as LiveCalibrator's reason for it (the fourth field of its events); an event of a
   kind that is no {macro}_EVENT_* gives "". snprintf-style: at most len - 1 bytes and a NUL (nothing when len is
   0; buf may then be 0); returns the length the whole text needs, without the NUL. */
static inline size_t {name}_describe_event(const {name}_state *s, const {name}_event *ev, char *buf, size_t len)
{{
    size_t at = 0;
    const char *flag = {name}_flag_name(ev->flag);
    switch (ev->kind) {{
    case {macro}_EVENT_TOOL_SWITCHED:
        {name}_text_str(buf, len, &at, "tool ");
        {name}_text_tool(s, buf, len, &at, ev->tool_from);
        {name}_text_str(buf, len, &at, " -> ");
        {name}_text_tool(s, buf, len, &at, ev->tool_to);
        break;
    case {macro}_EVENT_TOOL_IDENTIFYING:
        {name}_text_str(buf, len, &at, "identifying tool ");
        if (ev->tool_to >= 0 && ev->tool_to < {macro}_N_TOOLS) {name}_text_tool(s, buf, len, &at, ev->tool_to);
        else {name}_text_quoted(buf, len, &at, ev->tool_name);
        {name}_text_str(buf, len, &at, ": hold the sensor still in varied poses");
        break;
    case {macro}_EVENT_TOOL_IDENTIFIED:
        {name}_text_str(buf, len, &at, "tool ");
        {name}_text_tool(s, buf, len, &at, ev->tool_to);
        {name}_text_str(buf, len, &at, " identified from ");
        {name}_text_long(buf, len, &at, ev->count);
        {name}_text_str(buf, len, &at, " holds: ");
        {name}_text_num(buf, len, &at, "%.4g", ev->value[0]);
        {name}_text_str(buf, len, &at, {c_string(" ± ")});
        {name}_text_num(buf, len, &at, "%.2g", ev->value[1]);
        {name}_text_str(buf, len, &at, " kg");
        break;
    case {macro}_EVENT_RETARE:
        {name}_text_str(buf, len, &at, "re-tare with tool ");
        {name}_text_tool(s, buf, len, &at, ev->tool_from);
        {name}_text_str(buf, len, &at, " kept: the next static samples set the bias");
        if (ev->flag & ({macro}_FLAG_CONTACT | {macro}_FLAG_UNEXPLAINED)) {{  /* the flags raised at the re-tare */
            {name}_text_str(buf, len, &at, "; re-tare while ");
            if (ev->flag & {macro}_FLAG_CONTACT) {name}_text_str(buf, len, &at, "contact");
            if ((ev->flag & {macro}_FLAG_CONTACT) && (ev->flag & {macro}_FLAG_UNEXPLAINED))
                {name}_text_str(buf, len, &at, " and ");
            if (ev->flag & {macro}_FLAG_UNEXPLAINED) {name}_text_str(buf, len, &at, "unexplained");
            {name}_text_str(buf, len, &at, {c_string(" is raised: " + RETARE_WARNING)});
        }}
        break;
    case {macro}_EVENT_FLAG_RAISED:
        if (flag) {name}_text_reason(s, ev, buf, len, &at);
        break;
    case {macro}_EVENT_FLAG_CLEARED:
        if (flag) {{
            {name}_text_str(buf, len, &at, flag);
            {name}_text_str(buf, len, &at, " cleared");
        }}
        break;
    default:
        break;
    }}
    if (len > 0) buf[at < len ? at : len - 1] = '\\0';
    return at;
}}
#endif /* {macro}_NO_TEXT */
"""
