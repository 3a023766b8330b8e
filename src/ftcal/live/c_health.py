"""Health flags as text in the generated C runtime (:mod:`ftcal.live.c_runtime`).

``NAME_flag_name(bit)`` gives a flag's name and ``NAME_describe_flags(s, mask, buf, len)`` the one-line
reasons :class:`ftcal.live.LiveCalibrator` gives for the same flags (``LiveSample.flags``, the
``raised`` events): the reason a flag was last raised with, its numbers (channels, run lengths,
temperature, χ², the tool, the innovation) taken when it was raised, as Python keeps them
(``reason_of``), joined by ``"; "`` in bit order; a flag never raised is its name. The step stores
those numbers only on a sample whose flags change, as the flag's ``raised`` event (logged, and kept as the
flag's last raised; :mod:`ftcal.live.c_events`), so the usual sample pays one test.

The reasons' fixed words are written here after the Python templates of :mod:`ftcal.live.calibrator`
(``tests/live/test_c_runtime_library.py`` holds the two texts equal); names from files reach the C only
as string literals (:func:`ftcal.files.c_text.c_string`): the compiled-in tools' ``repr`` is Python's,
emitted as literals; a tool named at run time is quoted by the C as Python's ``repr`` quotes it, exactly
for ASCII (quote choice, ``\\\\``, ``\\n``, ``\\t``, ``\\r``, ``\\xNN``), for U+0080 to U+00A0 and
U+00AD; other non-ASCII bytes are copied (Python escapes the non-printable ones among them, e.g. U+202E).
"""

from __future__ import annotations

from ..data.signals import SATURATION_RUN, STUCK_RUN
from ..files.c_text import c_string
from .c_identify import _num
from .calibrator import OUT_OF_RANGE_TEXT
from .health import DEAD_RUN, FLAGS


def reason_fields(macro: str, name: str) -> str:
    """The state struct's fields that keep each flag's event as last raised."""
    return f"""    /* each flag's event as it was last raised (NAME_describe_flags) */
    unsigned raised_ever;        /* flags raised at least once */
    {name}_event last_raised[{macro}_N_FLAGS];"""


def flag_events_text(name: str, macro: str, t_col: int | None) -> str:
    """``NAME_flag_events``: the step calls it on a sample whose flags change (before NAME_step)."""
    temperature = "0.0" if t_col is None else f"u[{t_col}]"
    return f"""
/* The events of a sample whose flags change, in bit order (LiveCalibrator's order): a cleared flag, or a raised one
   with the numbers of its reason (kept as the flag's last raised, for NAME_describe_flags, and logged). Called by
   NAME_step after the run lengths are updated; the flagged channels are found again here, so that the usual sample
   stores nothing. */
static {macro}_RARE void {name}_flag_events({name}_state *s, unsigned flags, double time, double duration,
                                           const double *u, const double *e, double chi2, int moving)
{{
    unsigned changed = flags ^ s->flags;
    int i, j;
    (void)moving;   /* stuck needs a load change (s->channel_moved), not motion alone */
    for (i = 0; i < {macro}_N_FLAGS; ++i) {{
        unsigned bit = 1u << i;
        {name}_event ev;
        if (!(changed & bit)) continue;
        memset(&ev, 0, sizeof ev);
        ev.time = time;
        ev.sample = s->samples;
        ev.flag = bit;
        ev.tool_from = ev.tool_to = s->tool;
        ev.kind = flags & bit ? {macro}_EVENT_FLAG_RAISED : {macro}_EVENT_FLAG_CLEARED;
        if (bit == {macro}_FLAG_SATURATED && (flags & bit)) {{
            for (j = 0; j < {macro}_N_CHANNELS; ++j) {{
                double x = u[{name}_channels[j]];
                ev.channels[j] = s->use_adc_limits ? x <= s->adc_low || x >= s->adc_high
                    : (x < {name}_channel_range[j][0] || x > {name}_channel_range[j][1]) && s->run[j] >= {SATURATION_RUN};
            }}
            ev.value[0] = s->use_adc_limits;
            ev.value[1] = s->adc_low;
            ev.value[2] = s->adc_high;
        }} else if ((bit == {macro}_FLAG_STUCK || bit == {macro}_FLAG_DEAD) && (flags & bit)) {{
            for (j = 0; j < {macro}_N_CHANNELS; ++j) {{
                int stuck = s->run[j] >= {STUCK_RUN} && s->channel_moved[j];   /* a load change since its run began */
                ev.channels[j] = bit == {macro}_FLAG_DEAD ? stuck && s->run[j] >= {DEAD_RUN}
                                                          : stuck && s->run[j] < {DEAD_RUN};
                if (ev.channels[j] && s->run[j] > ev.count) ev.count = s->run[j];
            }}
        }} else if (bit == {macro}_FLAG_TEMPERATURE) {{
            ev.value[0] = {temperature};
        }} else if (bit == {macro}_FLAG_CONTACT) {{
            ev.value[0] = chi2;
            ev.value[1] = s->gate_chi2;
        }} else if (bit == {macro}_FLAG_UNEXPLAINED) {{
            ev.value[0] = s->unexplained_sigma;
            ev.value[1] = s->unexplained_seconds;
            ev.value[2] = duration;
            for (j = 0; j < 6; ++j) ev.value[3 + j] = e[j];
        }}
        if (flags & bit) {{
            s->raised_ever |= bit;
            s->last_raised[i] = ev;
        }}
        {name}_log_event(s, &ev);
    }}
}}
"""


def describe_text(name: str, macro: str, tool_reprs: list[str], temperature_range: tuple | None) -> str:
    """``NAME_flag_name``, ``NAME_describe_flags`` and their helpers (after NAME_step; left out with NAME_NO_TEXT).

    Parameters
    ----------
    tool_reprs : Python's ``repr`` of each compiled-in tool's name, in tool order
    temperature_range : the model's temperature input range (low, high), or None
    """
    names = ", ".join(c_string(f) for f in FLAGS)
    low, high = ("0.0", "0.0") if temperature_range is None else (_num(temperature_range[0]),
                                                                  _num(temperature_range[1]))
    return f"""
#ifndef {macro}_NO_TEXT
/* ----- flags as text (define {macro}_NO_TEXT before the include to leave this out: it needs snprintf) ----- */
#include <stdio.h>

/* The name of flag `bit` (one of {macro}_FLAG_*), as ftcal.live.health.FLAGS spells it; 0 for anything else. */
static inline const char *{name}_flag_name(unsigned bit)
{{
    static const char *const names[] = {{{names}}};
    unsigned i;
    for (i = 0; i < sizeof names / sizeof names[0]; ++i) if (bit == 1u << i) return names[i];
    return 0;
}}

/* Append n bytes of text at *at, keeping room for the NUL; *at counts what the whole text needs. */
static inline void {name}_text_put(char *buf, size_t len, size_t *at, const char *text, size_t n)
{{
    size_t k;
    for (k = 0; k < n; ++k, ++*at) if (*at + 1 < len) buf[*at] = text[k];
}}

static inline void {name}_text_str(char *buf, size_t len, size_t *at, const char *text)
{{
    {name}_text_put(buf, len, at, text, strlen(text));
}}

/* A number alone, as Python's format(x, spec) writes it for the specs used here (g, .3g, .4g are C's too). */
static inline void {name}_text_num(char *buf, size_t len, size_t *at, const char *format, double x)
{{
    char t[48];
    int n = snprintf(t, sizeof t, format, x);
    {name}_text_put(buf, len, at, t, n > 0 ? (size_t)n : 0);
}}

static inline void {name}_text_long(char *buf, size_t len, size_t *at, long x)
{{
    char t[32];
    int n = snprintf(t, sizeof t, "%ld", x);
    {name}_text_put(buf, len, at, t, n > 0 ? (size_t)n : 0);
}}

/* A name given at run time quoted as Python's repr quotes a str (nothing for a null pointer). */
static inline void {name}_text_quoted(char *buf, size_t len, size_t *at, const char *tool_name)
{{
    const unsigned char *p = (const unsigned char *)tool_name;
    char quote, t[8];
    int single = 0, double_quote = 0;
    if (!p) return;
    for (; *p; ++p) {{
        if (*p == '\\'') single = 1;
        else if (*p == '"') double_quote = 1;
    }}
    quote = single && !double_quote ? '"' : '\\'';
    {name}_text_put(buf, len, at, &quote, 1);
    for (p = (const unsigned char *)tool_name; *p; ++p) {{
        unsigned c = *p;
        if (c == (unsigned char)quote || c == '\\\\') {{
            t[0] = '\\\\';
            t[1] = (char)c;
            {name}_text_put(buf, len, at, t, 2);
        }} else if (c == '\\n') {name}_text_put(buf, len, at, "\\\\n", 2);
        else if (c == '\\r') {name}_text_put(buf, len, at, "\\\\r", 2);
        else if (c == '\\t') {name}_text_put(buf, len, at, "\\\\t", 2);
        else if (c < 0x20u || c == 0x7fu) {{
            snprintf(t, sizeof t, "\\\\x%02x", c);
            {name}_text_put(buf, len, at, t, 4);
        }} else if (c == 0xc2u && ((p[1] >= 0x80u && p[1] <= 0xa0u) || p[1] == 0xadu)) {{   /* not printable */
            snprintf(t, sizeof t, "\\\\x%02x", (unsigned)p[1]);
            {name}_text_put(buf, len, at, t, 4);
            ++p;
        }} else {{
            t[0] = (char)c;
            {name}_text_put(buf, len, at, t, 1);
        }}
    }}
    {name}_text_put(buf, len, at, &quote, 1);
}}

/* A tool's name quoted as Python's repr quotes a str: compiled-in tools from Python itself, run-time names here. */
static inline void {name}_text_tool(const {name}_state *s, char *buf, size_t len, size_t *at, int tool)
{{
    static const char *const reprs[{macro}_N_TOOLS] = {{{', '.join(c_string(r) for r in tool_reprs)}}};
    if (tool >= 0 && tool < {macro}_N_TOOLS) {name}_text_str(buf, len, at, reprs[tool]);
    else {name}_text_quoted(buf, len, at, {name}_tool_name(s, tool));
}}

static inline void {name}_text_channels(char *buf, size_t len, size_t *at, const unsigned char *hit)
{{
    int j, first = 1;
    for (j = 0; j < {macro}_N_CHANNELS; ++j)
        if (hit[j]) {{
            if (!first) {name}_text_str(buf, len, at, ", ");
            {name}_text_str(buf, len, at, {name}_input_name({name}_channels[j]));
            first = 0;
        }}
}}

/* The reason of a flag's `raised` event, as LiveCalibrator words it with the numbers the event keeps. */
static inline void {name}_text_reason(const {name}_state *s, const {name}_event *ev, char *buf, size_t len,
                                      size_t *at)
{{
    unsigned bit = ev->flag;
    int j;
    if (bit == {macro}_FLAG_SATURATED) {{
        {name}_text_str(buf, len, at, "channel ");
        {name}_text_channels(buf, len, at, ev->channels);
        if (ev->value[0] != 0.0) {{
            {name}_text_str(buf, len, at, " saturated (at the ADC limits ");
            {name}_text_num(buf, len, at, "%g", ev->value[1]);
            {name}_text_str(buf, len, at, "/");
            {name}_text_num(buf, len, at, "%g", ev->value[2]);
            {name}_text_str(buf, len, at, ")");
        }} else {{
            {name}_text_str(buf, len, at,
                            " saturated (flat for >= {SATURATION_RUN} samples outside the calibration's range)");
        }}
    }} else if (bit == {macro}_FLAG_STUCK) {{
        {name}_text_str(buf, len, at, "channel ");
        {name}_text_channels(buf, len, at, ev->channels);
        {name}_text_str(buf, len, at, " stuck: one value for ");
        {name}_text_long(buf, len, at, ev->count);
        {name}_text_str(buf, len, at, " samples while the sensor or other channels move");
    }} else if (bit == {macro}_FLAG_DEAD) {{
        {name}_text_str(buf, len, at, "channel ");
        {name}_text_channels(buf, len, at, ev->channels);
        {name}_text_str(buf, len, at, " dead: one value for ");
        {name}_text_long(buf, len, at, ev->count);
        {name}_text_str(buf, len, at, " samples");
    }} else if (bit == {macro}_FLAG_OUT_OF_RANGE) {{
        {name}_text_str(buf, len, at, {c_string(OUT_OF_RANGE_TEXT)});
    }} else if (bit == {macro}_FLAG_TEMPERATURE) {{
        {name}_text_str(buf, len, at, "temperature ");
        {name}_text_num(buf, len, at, "%.4g", ev->value[0]);
        {name}_text_str(buf, len, at, " outside the calibration's ");
        {name}_text_num(buf, len, at, "%.4g", {low});
        {name}_text_str(buf, len, at, " to ");
        {name}_text_num(buf, len, at, "%.4g", {high});
    }} else if (bit == {macro}_FLAG_CONTACT) {{
        {name}_text_str(buf, len, at, "wrench the tool ");
        {name}_text_tool(s, buf, len, at, ev->tool_from);
        {name}_text_str(buf, len, at, " and the bias do not explain (chi2 ");
        {name}_text_num(buf, len, at, "%.3g", ev->value[0]);
        {name}_text_str(buf, len, at, " > ");
        {name}_text_num(buf, len, at, "%.3g", ev->value[1]);
        {name}_text_str(buf, len, at, ", 6 dof); the bias is not updated");
    }} else if (bit == {macro}_FLAG_UNEXPLAINED) {{
        {name}_text_str(buf, len, at, "innovation beyond ");
        {name}_text_num(buf, len, at, "%g", ev->value[0]);
        {name}_text_str(buf, len, at, " sigma and the acceptance thresholds for ");
        {name}_text_num(buf, len, at, "%.3g", ev->value[2]);
        {name}_text_str(buf, len, at, " s (> ");
        {name}_text_num(buf, len, at, "%g", ev->value[1]);
        {name}_text_str(buf, len, at, " s): |compensated| = ");
        for (j = 0; j < 6; ++j) {{
            if (j) {name}_text_str(buf, len, at, ", ");
            {name}_text_num(buf, len, at, "%.3g", fabs(ev->value[3 + j]));
        }}
    }} else {{
        const char *flag = {name}_flag_name(bit);
        if (flag) {name}_text_str(buf, len, at, flag);
    }}
}}

/* The one-line reasons of the flags in `mask` (LiveCalibrator's, with the numbers of the sample that last raised
   each), joined by "; " in bit order; a flag never raised is its name, bits that are no flag are skipped.
   snprintf-style: writes at most len - 1 bytes and a NUL (nothing when len is 0; buf may then be 0) and returns
   the length the whole text needs, without the NUL. */
static inline size_t {name}_describe_flags(const {name}_state *s, unsigned mask, char *buf, size_t len)
{{
    size_t at = 0;
    unsigned i;
    int first = 1;
    for (i = 0; i < 32; ++i) {{
        unsigned bit = 1u << i;
        const char *flag = {name}_flag_name(bit);
        if (!(mask & bit) || !flag) continue;
        if (!first) {name}_text_str(buf, len, &at, "; ");
        first = 0;
        if (!(s->raised_ever & bit)) {name}_text_str(buf, len, &at, flag);
        else {name}_text_reason(s, &s->last_raised[i], buf, len, &at);
    }}
    if (len > 0) buf[at < len ? at : len - 1] = '\\0';
    return at;
}}
#endif /* {macro}_NO_TEXT */
"""
