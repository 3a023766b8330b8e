"""The live calibrator's per-sample step in C99 (``ftcal convert MODEL --to c-runtime -o NAME.h``).

One header, generated with the model and the tool library: the calibration (the evaluator of
:func:`ftcal.files.c_code.static_predict_function`), the tool's gravity wrench, the gated
random-walk bias filter of :mod:`ftcal.live.tracker` with the drift test of :mod:`ftcal.live.drift`
(a fixed ring of :data:`DRIFT_SNAPSHOTS` snapshots) and the health flags of
:mod:`ftcal.live.health`, with the semantics of :class:`ftcal.live.LiveCalibrator` fed one sample
at a time with ``raw=`` and ``gravity=`` (the motion test on the gravity direction, or the
caller's ``static``). Its numbers are those of the Python calibrator built from the same model
and payload files with its defaults (noise from the first tool file's residuals, walk from the
first random-walk drift, ``check --accept``'s default thresholds); the configuration fields of
the state struct can be changed after ``NAME_init``.

Fixed-size state, no allocation, no library beyond ``<math.h>`` and ``<string.h>``; every
function is ``static`` so the header can be included by one or several translation units.
Names and units from the files reach the C only through :mod:`ftcal.files.c_text`.

Identification in place (:mod:`ftcal.live.c_identify`): ``NAME_start_identification`` and
``NAME_finish_identification`` keep up to ``NAME_MAX_HOLDS`` static holds
(:data:`~ftcal.core.limits.C_RUNTIME_MAX_HOLDS`; later holds are left out and counted) and identify the
tool as :meth:`LiveCalibrator.finish_identification` does.

The tool library grows at run time as Python's does: a tool identified in place joins it under the
name given to ``NAME_start_identification`` (copied into a fixed slot of at most
:data:`~ftcal.core.limits.C_RUNTIME_MAX_TOOL_NAME` bytes; :data:`~ftcal.core.limits.C_RUNTIME_MAX_TOOLS`
slots), replacing a tool of that name (same index) or taking the next index, so indices follow
Python's ``list(live.tools)``; ``NAME_find_tool`` looks a name up. Flags have names and Python's
reasons as text (:mod:`ftcal.live.c_health`). Tool switches, identifications, re-tares and flags raised or
cleared go into an event log, a ring of ``NAME_MAX_EVENTS`` events with Python's texts
(:mod:`ftcal.live.c_events`).

What the C does not do (the Python calibrator does): warnings as text, the ``silent``
flag (a transport's), a separate temperature input (the model's temperature input is used),
quaternion or joint motion signals (the gravity direction is the motion signal, as with
``gravity=``), state files. The motion history holds the newest
``NAME_HISTORY`` samples (default 1024: ≥ 10 kHz over the 0.1 s window); at a higher rate the
rate is measured over the span the history holds.
"""

from __future__ import annotations

import hashlib
import math
from pathlib import Path

import numpy as np

from ..check.accept import Thresholds
from ..core.excitation import SPAN_RELATIVE_FLOOR, span_limit
from ..core.limits import (C_RUNTIME_MAX_EVENTS, C_RUNTIME_MAX_HOLDS, C_RUNTIME_MAX_TOOL_NAME, C_RUNTIME_MAX_TOOLS,
                           LIVE_MIN_HOLDS, MAX_CELL_MAGNITUDE)
from ..core.ranges import RANGE_TOLERANCE
from ..data.holds import HOLD_WINDOW_S, MIN_ANGULAR_RATE, MIN_HOLD_S
from ..data.signals import SATURATION_RUN, STUCK_RUN
from ..files.c_code import static_predict_function
from ..files.c_text import c_comment, c_identifier, c_string, printable_ascii
from ..files.model_json import ModelFile, ftcal_version
from ..files.targets import ConvertOptions, Written
from ..runtime.atomic import write_text_atomic
from ..runtime.errors import FtcalError
from .c_consistency import selfcheck_fields, selfcheck_text
from .c_events import describe_event_text, event_fields, event_types, log_text
from .c_health import describe_text, flag_events_text, reason_fields
from .c_identify import TOOL_STATUS, _array, _num, collect_text, finish_text, state_fields
from .calibrator import (GATE_PROBABILITY, NO_TOOL, RETARE_VARIANCE, UNEXPLAINED_SECONDS, UNEXPLAINED_SIGMA,
                         tracker_defaults)
from .drift import FALSE_ALARM, LAGS_S, SNAPSHOT_S
from .health import BIT, DEAD_RUN, FLAGS, LOAD_STEPS
from .tracker import HOLDOFF_S, MIN_FAIL_S, gate_chi2

DEFAULT_NAME = "ftcal_runtime"
HISTORY = 1024
# Snapshots the drift test's ring holds: snapshots are at least SNAPSHOT_S apart, so once the ring holds this many,
# its second oldest is more than max(LAGS_S) old and the oldest can never be the newest one a lag needs.
DRIFT_SNAPSHOTS = math.ceil(max(LAGS_S) / SNAPSHOT_S) + 2


def runtime_parameters(tools: dict) -> dict:
    """Noise and walk variances and the gate, as :class:`~ftcal.live.LiveCalibrator` derives them by default.

    Parameters
    ----------
    tools : name → PayloadParameters, in library order

    Returns
    -------
    dict with ``noise_variance``, ``walk_variance`` (per s), ``accept_limit`` (ndarrays of shape (6,))
    and ``gate_chi2``, ``drift_chi2`` (floats: the contact gate and the drift test's threshold)
    """
    thresholds = Thresholds()
    scale = np.repeat([thresholds.force, thresholds.torque], 3)
    noise, walk = tracker_defaults(tools.values(), thresholds)  # the one rule LiveCalibrator uses
    return {"noise_variance": np.sqrt(noise) ** 2, "walk_variance": walk, "accept_limit": scale,
            "gate_chi2": gate_chi2(GATE_PROBABILITY), "drift_chi2": gate_chi2(1.0 - FALSE_ALARM)}


def _span(model) -> list[str]:
    """C lines computing ``int outside_span`` from ``u`` (:func:`ftcal.core.excitation.span_distance`)."""
    spread = getattr(model, "input_spread_", None)
    if spread is None:
        return ["    (void)u;", "    return 0;"]
    cov = spread.covariance
    std = np.sqrt(np.maximum(np.diag(cov), 0.0))
    unit = np.where(std > 0, std, 1.0)
    corr = cov / unit[:, None] / unit[None, :]
    values, vectors = np.linalg.eigh(0.5 * (corr + corr.T))
    kept = values > SPAN_RELATIVE_FLOOR * max(values.max(), 0.0)
    nu = cov.shape[0]
    lines = [f"    static const double mean[{nu}] = {_array(spread.mean)};",
             f"    static const double unit[{nu}] = {_array(unit)};",
             f"    static const double vectors[{nu}][{nu}] = {{{', '.join(_array(r) for r in vectors.T)}}};",
             f"    static const double values[{nu}] = {_array(values)};",
             f"    static const int kept[{nu}] = {{{', '.join(str(int(k)) for k in kept)}}};",
             f"    double x[{nu}], distance = 0.0, off = 0.0;", "    int i, k;",
             f"    for (i = 0; i < {nu}; ++i) x[i] = (u[i] - mean[i]) / unit[i];",
             f"    for (k = 0; k < {nu}; ++k) {{", "        double p = 0.0;",
             f"        for (i = 0; i < {nu}; ++i) p += x[i] * vectors[k][i];",
             "        if (kept[k]) distance += p * p / values[k];",
             "        else if (fabs(p) > off) off = fabs(p);", "    }",
             f"    if (off > 1e-6 * {_num(math.sqrt(max(values.max(), 1e-300)))}) return 1;",
             f"    return distance > {_num(span_limit(nu))};"]
    return lines


def generate_c_runtime(model, tools: dict, *, name: str = DEFAULT_NAME, sha256: str | None = None,
                       source_name: str | None = None, tool_sources=None,
                       max_holds: int = C_RUNTIME_MAX_HOLDS) -> str:
    """The C99 header of the live step for ``model`` and the tool library ``tools``.

    Parameters
    ----------
    model : fitted static polynomial CalibrationModel with six outputs
    tools : mapping name → PayloadParameters (the library; ``"none"`` is added as tool 0)
    name : C identifier prefixing every symbol (macros upper-cased)
    sha256, source_name : the model file's digest and name, for the header comment
    tool_sources : sequence of str or None, the payload files' names, for the header comment
    max_holds : static holds an identification in place keeps (``NAME_MAX_HOLDS``; holds past it are left out)

    Returns
    -------
    str

    Raises
    ------
    FtcalError
        ``name`` is not a C identifier, the model is not static or has not six outputs, or a number is not finite.
    """
    from ..report.runs import temperature_column

    c_identifier(name)
    if not isinstance(max_holds, int) or not LIVE_MIN_HOLDS <= max_holds <= C_RUNTIME_MAX_HOLDS:
        raise FtcalError(f"max_holds must be an int in [{LIVE_MIN_HOLDS}, {C_RUNTIME_MAX_HOLDS}]; got {max_holds!r}.")
    if len(model.output_names_) != 6:
        raise FtcalError(f"--to c-runtime: the model has {len(model.output_names_)} outputs; a wrench needs 6.")
    predict = static_predict_function(model, f"static inline void {name}_calibrate")
    params = runtime_parameters(tools)
    macro, nu = name.upper(), len(model.input_names_)
    t_col = temperature_column(model.input_names_)
    channels = [j for j in range(nu) if j != t_col]
    nc = len(channels)
    if nc == 0:
        raise FtcalError("--to c-runtime: the model's only input is a temperature; the step needs sensor channels.")
    rng = np.asarray(model.input_range_, float)
    slack = RANGE_TOLERANCE * np.maximum(rng[:, 1] - rng[:, 0], 1.0)
    span_lines = _span(model)
    names = [NO_TOOL, *tools]
    for tool in tools:
        if not isinstance(tool, str) or not tool or tool == NO_TOOL or "\0" in tool:
            raise FtcalError(f"--to c-runtime: tool {printable_ascii(repr(tool))[:80]} needs a name other than "
                             f"{NO_TOOL!r}, without NUL characters.")
        size = len(tool.encode("utf-8", "surrogatepass"))
        if size > C_RUNTIME_MAX_TOOL_NAME:  # a longer literal may not compile (C99 guarantees 4095 bytes)
            raise FtcalError(f"--to c-runtime: tool {printable_ascii(repr(tool))[:80]} has a name of {size} bytes; at "
                             f"most {C_RUNTIME_MAX_TOOL_NAME} (UTF-8), as for a name given at run time.")
    mass = [0.0] + [float(p.mass) for p in tools.values()]
    mc = [[0.0] * 3] + [list(p.mass * np.asarray(p.com, dtype=float)) for p in tools.values()]
    sign = [1.0] + [-1.0 if p.reaction else 1.0 for p in tools.values()]
    for what, values in (("tool masses", mass), ("tool centres of mass", mc), ("noise", params["noise_variance"]),
                         ("walk", params["walk_variance"])):
        if not np.all(np.isfinite(np.asarray(values, float))):
            raise FtcalError(f"--to c-runtime: the {what} are not all finite; refusing to generate code.")
    sources = list(tool_sources or [None] * len(tools))
    comment = c_comment([
        f"{name}: ftcal live step (calibration, tool compensation, bias Kalman filter, health flags),",
        f"degree {model.layout_.basis.degree}, {nu} inputs. Generated by ftcal {ftcal_version()}; do not edit.",
        f"model file: {source_name or 'unknown'}" + (f", sha256 {sha256}" if sha256 else ""),
        f"inputs (u): {', '.join(model.input_names_)}",
        f"outputs: {', '.join(model.output_names_)}",
        *[f"tool {i + 1}: {tool}" + (f" from {src}" if src else "") for i, (tool, src) in enumerate(zip(tools, sources))],
        "Include in one or more translation units; needs -lm. See docs/live.md."])
    bits = "\n".join(f"#define {macro}_FLAG_{flag.upper()} {bit}u" for flag, bit in BIT.items())
    tool_status = "\n".join(f"#define {macro}_TOOL_{key} ({value})" for key, value in TOOL_STATUS.items())
    temp_line = ("    (void)u;" if t_col is None else
                 f"    if (!(u[{t_col}] >= {_num(rng[t_col, 0])} && u[{t_col}] <= {_num(rng[t_col, 1])})) "
                 f"flags |= {macro}_FLAG_TEMPERATURE;")
    text = f"""{comment}
#ifndef {macro}_H
#define {macro}_H

#include <math.h>
#include <string.h>

#ifdef __cplusplus
extern "C" {{
#endif

#if defined(__GNUC__)
#define {macro}_RARE __attribute__((noinline, cold))   /* off the step's path: run on transitions only */
#else
#define {macro}_RARE
#endif

#define {macro}_N_INPUTS {nu}
#define {macro}_N_TOOLS {len(names)}
#define {macro}_N_CHANNELS {nc}
#define {macro}_MAX_HOLDS {max_holds}   /* holds an identification in place keeps; later ones are left out */
#define {macro}_MIN_HOLDS {LIVE_MIN_HOLDS}
#define {macro}_MAX_ADDED_TOOLS {C_RUNTIME_MAX_TOOLS}   /* tools identified in place under new names */
#define {macro}_MAX_TOOLS ({macro}_N_TOOLS + {macro}_MAX_ADDED_TOOLS)
#define {macro}_MAX_TOOL_NAME {C_RUNTIME_MAX_TOOL_NAME}   /* bytes of a run-time tool name, without the NUL */
#define {macro}_MAX_MAGNITUDE {MAX_CELL_MAGNITUDE!r}   /* larger inputs are refused, as in Python: squares overflow */
{tool_status}
#ifndef {macro}_HISTORY
#define {macro}_HISTORY {HISTORY}
#endif
#define {macro}_DRIFT_SNAPSHOTS {DRIFT_SNAPSHOTS}   /* the drift test's ring: {_num(max(LAGS_S))} s of snapshots {_num(SNAPSHOT_S)} s apart */
#define {macro}_DRIFT_LAGS {len(LAGS_S)}
{bits}
#define {macro}_N_FLAGS {len(FLAGS)}

static inline const char *{name}_input_name(int input)
{{
    static const char *const names[{macro}_N_INPUTS] = {{{', '.join(c_string(t) for t in model.input_names_)}}};
    return input >= 0 && input < {macro}_N_INPUTS ? names[input] : 0;
}}

/* The compiled-in tools: NAME_init copies them into the state's library. */
static const double {name}_tool_mass[{macro}_N_TOOLS] = {_array(mass)};
static const double {name}_tool_mc[{macro}_N_TOOLS][3] = {{{', '.join(_array(r) for r in mc)}}};
static const double {name}_tool_sign[{macro}_N_TOOLS] = {_array(sign)};
static const int {name}_channels[{macro}_N_CHANNELS] = {{{', '.join(map(str, channels))}}};
/* the channels' training range: beyond it, flat for {SATURATION_RUN} samples, a channel is saturated */
static const double {name}_channel_range[{macro}_N_CHANNELS][2] = {{{', '.join(_array(rng[c]) for c in channels)}}};

{event_types(macro, name, C_RUNTIME_MAX_EVENTS)}
typedef struct {{
    /* configuration: NAME_init sets the generated defaults; change them after init if needed */
    double noise_variance[6];    /* r: per-sample noise variance of the calibrated wrench */
    double walk_variance[6];     /* q: bias random-walk variance per second */
    double gate_chi2;            /* contact gate, chi2 quantile with 6 dof */
    double drift_chi2;           /* drift test: chi2 (6 dof) beyond which the bias moved faster than the walk */
    double accept_limit[6];      /* check --accept thresholds, N and N m */
    double unexplained_sigma, unexplained_seconds;
    double motion_window, min_rate, min_hold;   /* s, rad/s, s */
    int use_adc_limits;          /* 1: saturated means a channel at adc_low/adc_high */
    double adc_low, adc_high;
    /* state */
    int tool;
    /* the tool library: 0 .. N_TOOLS-1 compiled in (copied by NAME_init), then the tools identified in place */
    int n_tools;
    double tool_mass[{macro}_MAX_TOOLS], tool_mc[{macro}_MAX_TOOLS][3], tool_sign[{macro}_MAX_TOOLS];
    char tool_names[{macro}_MAX_ADDED_TOOLS][{macro}_MAX_TOOL_NAME + 1];
    double bias[6], variance[6];
    int has_time;
    double last_time, last_moving;
    int history_start, history_count;
    double history_time[{macro}_HISTORY], history_direction[{macro}_HISTORY][3];
    int has_last;
    double last_raw[{macro}_N_CHANNELS];
    long run[{macro}_N_CHANNELS];
    /* a load change since each channel's run began (ftcal.live.health.LoadChange): another channel moved by more
       than {LOAD_STEPS:g} of its quantisation steps (its smallest change seen, HUGE_VAL before one) */
    double channel_step[{macro}_N_CHANNELS], channel_ref[{macro}_N_CHANNELS][{macro}_N_CHANNELS];
    int channel_moved[{macro}_N_CHANNELS];
    int exceeding;
    double exceed_start;
    unsigned flags;
    unsigned long samples, updates, contacts, retares, switches;
    /* the drift test (ftcal.live.drift): snapshots of bias and variance, oldest at drift_start, times increasing */
    double drift_due;            /* the next snapshot is taken at the first sample at or after this time */
    int drift_start, drift_count;
    double drift_time[{macro}_DRIFT_SNAPSHOTS], drift_bias[{macro}_DRIFT_SNAPSHOTS][6];
    double drift_variance[{macro}_DRIFT_SNAPSHOTS][6];
    double last_fail, fail_start;   /* the hold-off: the last failed static sample and the start of its run */
    int fail_previous;              /* the previous sample failed */
    double holdoff;              /* s after it without updates (LiveCalibrator(holdoff=...)), 0: off */
    unsigned long rollbacks;     /* the bias sent back by the drift test (Python's "rollback" events) */
    double rollback_time, rollback_lag, rollback_chi2, rollback_moved;   /* the last one: the event's numbers */
{selfcheck_fields(macro)}
{state_fields(macro)}
{reason_fields(macro, name)}
{event_fields(macro, name)}
}} {name}_state;

typedef struct {{
    double calibrated[6];    /* the model's wrench */
    double compensated[6];   /* calibrated - tool - bias (the contact wrench) */
    double bias[6], bias_std[6];   /* after the sample */
    double chi2;             /* innovation chi2, 6 dof */
    int is_static, updated;
    unsigned flags;          /* {macro}_FLAG_* bits */
}} {name}_output;

{predict}

static inline int {name}_outside_span(const double *u)
{{
{chr(10).join(span_lines)}
}}

/* Start with tool `tool` mounted and the bias unknown (the first static, contact-free samples set it).
   Returns 0, or -1 for a tool index outside 0 .. N_TOOLS-1. */
static inline int {name}_init({name}_state *s, int tool)
{{
    static const double noise[6] = {_array(params['noise_variance'])};
    static const double walk[6] = {_array(params['walk_variance'])};
    static const double limit[6] = {_array(params['accept_limit'])};
    int j;
    if (tool < 0 || tool >= {macro}_N_TOOLS) return -1;
    memset(s, 0, sizeof *s);
    for (j = 0; j < 6; ++j) {{
        s->noise_variance[j] = noise[j];
        s->walk_variance[j] = walk[j];
        s->accept_limit[j] = limit[j];
        s->bias[j] = 0.0;
        s->variance[j] = {_num(RETARE_VARIANCE)} * noise[j];
    }}
    s->gate_chi2 = {_num(params['gate_chi2'])};
    s->drift_chi2 = {_num(params['drift_chi2'])};
    s->drift_due = -HUGE_VAL;
    s->last_fail = -HUGE_VAL;   /* NO_FAILURE */
    s->fail_start = HUGE_VAL;
    s->fail_previous = 0;
    s->holdoff = {_num(HOLDOFF_S)};
    s->unexplained_sigma = {_num(UNEXPLAINED_SIGMA)};
    s->unexplained_seconds = {_num(UNEXPLAINED_SECONDS)};
    s->motion_window = {_num(HOLD_WINDOW_S)};
    s->min_rate = {_num(MIN_ANGULAR_RATE)};
    s->min_hold = {_num(MIN_HOLD_S)};
    s->last_moving = -HUGE_VAL;
    s->tool = tool;
    s->n_tools = {macro}_N_TOOLS;
    for (j = 0; j < {macro}_N_TOOLS; ++j) {{
        s->tool_mass[j] = {name}_tool_mass[j];
        memcpy(s->tool_mc[j], {name}_tool_mc[j], sizeof s->tool_mc[j]);
        s->tool_sign[j] = {name}_tool_sign[j];
    }}
    /* the self-check on, as LiveCalibrator's default (NAME_enable_self_check again after changing noise_variance or
       walk_variance: its bounds; s->self_check = 0 for fixed q and r) */
    memcpy(s->sc_noise0, s->noise_variance, sizeof s->sc_noise0);
    memcpy(s->sc_walk0, s->walk_variance, sizeof s->sc_walk0);
    s->sc_expected_gated = {_num(1.0)} - {_num(GATE_PROBABILITY)};
    s->self_check = 1;
    return 0;
}}
{log_text(name, macro)}
/* The name of tool `tool`: 0 is "none", then the payload files' in the order given, then the tools identified in
   place (in the order they were first added); 0 (a null pointer) for an index not in the library. */
static inline const char *{name}_tool_name(const {name}_state *s, int tool)
{{
    static const char *const names[{macro}_N_TOOLS] = {{{', '.join(c_string(t) for t in names)}}};
    if (tool >= 0 && tool < {macro}_N_TOOLS) return names[tool];
    return tool >= {macro}_N_TOOLS && tool < s->n_tools ? s->tool_names[tool - {macro}_N_TOOLS] : 0;
}}

/* The index of the tool named `tool_name` (compared byte for byte), or -1 (none by that name, or a null pointer). */
static inline int {name}_find_tool(const {name}_state *s, const char *tool_name)
{{
    int i;
    if (!tool_name) return -1;
    for (i = 0; i < s->n_tools; ++i) if (strcmp({name}_tool_name(s, i), tool_name) == 0) return i;
    return -1;
}}

/* Whether a tool may be identified as `tool_name`: {macro}_TOOL_OK or the reason it may not
   (NAME_start_identification lists them). Reads at most {macro}_MAX_TOOL_NAME + 1 bytes of the name. */
static inline int {name}_check_new_tool(const {name}_state *s, const char *tool_name)
{{
    int n = 0;
    if (!tool_name || !tool_name[0]) return {macro}_TOOL_NO_NAME;
    while (n <= {macro}_MAX_TOOL_NAME && tool_name[n]) ++n;
    if (n > {macro}_MAX_TOOL_NAME) return {macro}_TOOL_NAME_TOO_LONG;
    if (strcmp(tool_name, {c_string(NO_TOOL)}) == 0) return {macro}_TOOL_NAME_RESERVED;
    if ({name}_find_tool(s, tool_name) < 0 && s->n_tools == {macro}_MAX_TOOLS) return {macro}_TOOL_LIBRARY_FULL;
    return {macro}_TOOL_OK;
}}

/* Mount another tool of the library instantly (switch_tool; by name: NAME_find_tool); the bias (the sensor's) is
   kept. Returns 0, or -1 for an index not in the library (0 .. s->n_tools - 1). */
static inline int {name}_set_tool({name}_state *s, int tool)
{{
    {name}_event ev;
    if (tool < 0 || tool >= s->n_tools) return -1;
    {name}_call_event(s, {macro}_EVENT_TOOL_SWITCHED, s->tool, tool, &ev);
    {name}_log_event(s, &ev);
    s->tool = tool;
    s->switches += 1;
    return 0;
}}

/* Forget the drift test's snapshots (the bias was set on purpose: a re-tare, a tool identified and mounted). */
static inline void {name}_drift_reset({name}_state *s)
{{
    s->drift_start = 0;
    s->drift_count = 0;
    s->drift_due = -HUGE_VAL;
    s->sc_rb_has = 0;   /* DriftCheck.reset: the last rollback forgotten */
}}

/* The drift test after the sample at `time` (ftcal.live.drift.DriftCheck.check, same order and arithmetic): compare
   the bias with the newest snapshot at least 64, 16, 4, 1 s old; on the first lag whose chi2 is beyond drift_chi2
   with some axis moved beyond accept_limit, bias and variance go back to that snapshot's, predicted since, and the
   snapshots restart from there (returns 1); else the state is a new snapshot (returns 0). */
static inline int {name}_drift_check({name}_state *s, double time)
{{
    static const double lags[{macro}_DRIFT_LAGS] = {_array(LAGS_S)};
    int i, j, low, high, middle, slot;
    s->drift_due = time + {_num(SNAPSHOT_S)};
    for (i = 0; i < {macro}_DRIFT_LAGS; ++i) {{
        double cutoff = time - lags[i], span, chi2 = 0.0, moved = 0.0;
        const double *b0, *p0;
        int beyond = 0;
        low = 0;   /* bisect_right: low = the snapshots at or before cutoff */
        high = s->drift_count;
        while (low < high) {{
            middle = (low + high) / 2;
            if (cutoff < s->drift_time[(s->drift_start + middle) % {macro}_DRIFT_SNAPSHOTS]) high = middle;
            else low = middle + 1;
        }}
        if (low == 0) continue;
        slot = (s->drift_start + low - 1) % {macro}_DRIFT_SNAPSHOTS;
        b0 = s->drift_bias[slot];
        p0 = s->drift_variance[slot];
        span = time - s->drift_time[slot];
        for (j = 0; j < 6; ++j)
            chi2 += (s->bias[j] - b0[j]) * (s->bias[j] - b0[j]) / (s->walk_variance[j] * span + s->variance[j] + p0[j]);
        if (!(chi2 > s->drift_chi2)) continue;
        for (j = 0; j < 6; ++j) if (fabs(s->bias[j] - b0[j]) > s->accept_limit[j]) beyond = 1;
        if (!beyond) continue;
        for (j = 0; j < 6; ++j) if (fabs(s->bias[j] - b0[j]) > moved) moved = fabs(s->bias[j] - b0[j]);
        s->sc_rb_has = 1;   /* DriftCheck.last_rollback: the self-check may undo it */
        s->sc_rb_time = time;
        s->sc_rb_span = span;
        memcpy(s->sc_rb_bias, s->bias, sizeof s->bias);
        memcpy(s->sc_rb_var, s->variance, sizeof s->variance);
        memcpy(s->sc_rb_b0, b0, sizeof s->sc_rb_b0);
        memcpy(s->sc_rb_p0, p0, sizeof s->sc_rb_p0);
        for (j = 0; j < 6; ++j) {{   /* back to the snapshot, its variance predicted since; it is the only one left */
            s->bias[j] = b0[j];
            s->variance[j] = p0[j] + s->walk_variance[j] * span;
        }}
        s->drift_start = 0;
        s->drift_count = 1;
        s->drift_time[0] = time;
        memcpy(s->drift_bias[0], s->bias, sizeof s->bias);
        memcpy(s->drift_variance[0], s->variance, sizeof s->variance);
        s->rollbacks += 1;
        s->rollback_time = time;
        s->rollback_lag = span;
        s->rollback_chi2 = chi2;
        s->rollback_moved = moved;
        return 1;
    }}
    if (s->drift_count == {macro}_DRIFT_SNAPSHOTS) {{   /* full: the oldest is never needed again */
        s->drift_start = (s->drift_start + 1) % {macro}_DRIFT_SNAPSHOTS;
        s->drift_count -= 1;
    }}
    slot = (s->drift_start + s->drift_count) % {macro}_DRIFT_SNAPSHOTS;
    s->drift_time[slot] = time;
    memcpy(s->drift_bias[slot], s->bias, sizeof s->bias);
    memcpy(s->drift_variance[slot], s->variance, sizeof s->variance);
    s->drift_count += 1;
    return 0;
}}

{selfcheck_text(name, macro)}
/* Re-tare, tool kept, in any pose: the bias forgets its value; the next static samples set it.
   Returns the flags of {macro}_FLAG_CONTACT and {macro}_FLAG_UNEXPLAINED raised now, 0 if none: if a contact
   raised them, the next static samples take it into the bias (the event's text warns, as LiveCalibrator.retare). */
static inline int {name}_retare({name}_state *s)
{{
    {name}_event ev;
    int j;
    {name}_call_event(s, {macro}_EVENT_RETARE, s->tool, s->tool, &ev);
    ev.flag = s->flags & ({macro}_FLAG_CONTACT | {macro}_FLAG_UNEXPLAINED);
    {name}_log_event(s, &ev);
    for (j = 0; j < 6; ++j)
        if (s->variance[j] < {_num(RETARE_VARIANCE)} * s->noise_variance[j])
            s->variance[j] = {_num(RETARE_VARIANCE)} * s->noise_variance[j];
    {name}_drift_reset(s);
    {name}_sc_reset(s);
    s->last_fail = -HUGE_VAL;   /* NO_FAILURE */
    s->fail_start = HUGE_VAL;
    s->fail_previous = 0;
    s->retares += 1;
    return ev.flag;
}}

/* Motion test on the gravity direction: sets *still and *moving (ftcal.live.motion). */
static inline void {name}_motion({name}_state *s, double time, const double *direction, int *still, int *moving)
{{
    double cutoff = time - s->motion_window, rate = HUGE_VAL;
    int last;
    while (s->history_count >= 2 &&
           s->history_time[(s->history_start + 1) % {macro}_HISTORY] <= cutoff) {{
        s->history_start = (s->history_start + 1) % {macro}_HISTORY;
        s->history_count -= 1;
    }}
    if (s->history_count >= 1 && (s->history_time[s->history_start] <= cutoff
                                  || s->history_count == {macro}_HISTORY)) {{
        const double *y = s->history_direction[s->history_start];
        double cx = direction[1] * y[2] - direction[2] * y[1];
        double cy = direction[2] * y[0] - direction[0] * y[2];
        double cz = direction[0] * y[1] - direction[1] * y[0];
        double angle = atan2(sqrt(cx * cx + cy * cy + cz * cz),
                             direction[0] * y[0] + direction[1] * y[1] + direction[2] * y[2]);
        rate = angle / (time - s->history_time[s->history_start]);
    }}
    if (s->history_count == {macro}_HISTORY) {{   /* full: the oldest goes */
        s->history_start = (s->history_start + 1) % {macro}_HISTORY;
        s->history_count -= 1;
    }}
    last = (s->history_start + s->history_count) % {macro}_HISTORY;
    s->history_time[last] = time;
    memcpy(s->history_direction[last], direction, 3 * sizeof(double));
    s->history_count += 1;
    *still = rate < s->min_rate;
    if (!*still) s->last_moving = time;
    *moving = rate < HUGE_VAL && !*still;
    *still = *still && (time - s->last_moving >= s->min_hold);
}}

{collect_text(name, macro)}{flag_events_text(name, macro, t_col)}
/* One sample: time in s (strictly increasing), u[N_INPUTS] the raw channels, gravity[3] in sensor axes
   (m/s^2, any nonzero length for the direction), static_override -1 (motion test), 0 or 1.
   Returns 0, or -1 (state untouched, out not written) for input that is not finite or beyond
   MAX_MAGNITUDE (a calibrated wrench too), time that does not increase or a zero gravity vector. */
static inline int {name}_step({name}_state *s, double time, const double *u, const double *gravity, int static_override,
                       {name}_output *out)
{{
    double w[6], z[6], e[6], tool[6], direction[3], norm, dt, chi2 = 0.0, predicted[6], innovation_var[6];
    const double *mc = s->tool_mc[s->tool];
    double m = s->tool_mass[s->tool], sign = s->tool_sign[s->tool];
    int j, still, moving, gate, beyond = 0;
    unsigned flags = 0;
    if (!isfinite(time) || (s->has_time && !(time > s->last_time))) return -1;
    for (j = 0; j < {macro}_N_INPUTS; ++j) if (!(fabs(u[j]) <= {macro}_MAX_MAGNITUDE)) return -1;
    for (j = 0; j < 3; ++j) if (!(fabs(gravity[j]) <= {macro}_MAX_MAGNITUDE)) return -1;
    norm = sqrt(gravity[0] * gravity[0] + gravity[1] * gravity[1] + gravity[2] * gravity[2]);
    if (norm == 0.0) return -1;
    {name}_calibrate(u, w);
    for (j = 0; j < 6; ++j) if (!(fabs(w[j]) <= {macro}_MAX_MAGNITUDE)) return -1;
    for (j = 0; j < 3; ++j) direction[j] = gravity[j] / norm;
    if (static_override >= 0) {{
        still = static_override != 0;
        moving = !still;
    }} else {{
        {name}_motion(s, time, direction, &still, &moving);
    }}
    if (s->identifying) {name}_collect(s, still, gravity, w);
    /* the tool's gravity wrench: F = m g, T = (m c) x g, negated for a reaction payload */
    tool[0] = sign * (m * gravity[0]);
    tool[1] = sign * (m * gravity[1]);
    tool[2] = sign * (m * gravity[2]);
    tool[3] = sign * (mc[1] * gravity[2] - mc[2] * gravity[1]);
    tool[4] = sign * (mc[2] * gravity[0] - mc[0] * gravity[2]);
    tool[5] = sign * (mc[0] * gravity[1] - mc[1] * gravity[0]);
    dt = s->has_time ? time - s->last_time : 0.0;
    for (j = 0; j < 6; ++j) {{
        z[j] = w[j] - tool[j];
        predicted[j] = s->variance[j] + s->walk_variance[j] * dt;
        innovation_var[j] = predicted[j] + s->noise_variance[j];
        e[j] = z[j] - s->bias[j];
        chi2 += e[j] * (e[j] / innovation_var[j]);
    }}
    /* the hold-off (ftcal.live.tracker.HOLDOFF_S): no update within it after a static sample failed the gate */
    gate = still && !s->identifying && chi2 < s->gate_chi2
           && !(s->last_fail - s->fail_start >= {_num(MIN_FAIL_S)} && time - s->last_fail < s->holdoff);
    if (still && !s->identifying && !(chi2 < s->gate_chi2)) {{   /* a run of failures: its start and last sample */
        if (!s->fail_previous) s->fail_start = time;
        s->last_fail = time;
        s->fail_previous = 1;
    }} else {{
        s->fail_previous = 0;
    }}
    for (j = 0; j < 6; ++j) {{
        out->calibrated[j] = w[j];
        out->compensated[j] = e[j];
        if (gate) {{   /* Kalman update: gain P-/(P- + r) */
            double gain = predicted[j] / innovation_var[j];
            s->bias[j] = (1.0 - gain) * s->bias[j] + gain * z[j];
            s->variance[j] = s->noise_variance[j] * predicted[j] / innovation_var[j];
        }} else {{     /* prediction only: a contact is never absorbed */
            s->variance[j] = predicted[j];
        }}
        if (!s->identifying
            && fabs(e[j]) > fmax(s->unexplained_sigma * sqrt(innovation_var[j]), s->accept_limit[j])) beyond = 1;
    }}
    {{
        int due = time >= s->drift_due, still_now = still && !s->identifying;
        if (due) {name}_drift_check(s, time);   /* a slow contact the gate let through goes back */
        if (s->self_check) {{   /* ftcal.live.consistency, at the drift test's snapshot times */
            {name}_sc_observe(s, time, still_now, gate, still_now && !gate && chi2 >= s->gate_chi2, z, e, predicted,
                              innovation_var, direction);
            if (due) {name}_sc_check(s, time);
        }}
    }}
    for (j = 0; j < 6; ++j) {{
        out->bias[j] = s->bias[j];
        out->bias_std[j] = sqrt(s->variance[j]);
    }}
    /* health: run lengths of identical values per channel (temperature excluded) */
    for (j = 0; j < {macro}_N_CHANNELS; ++j) {{
        double x = u[{name}_channels[j]];
        s->run[j] = (s->has_last && x == s->last_raw[j]) ? s->run[j] + 1 : 1;
        if (!s->has_last) s->channel_step[j] = HUGE_VAL;
        else if (x != s->last_raw[j] && fabs(x - s->last_raw[j]) < s->channel_step[j]) s->channel_step[j] = fabs(x - s->last_raw[j]);
    }}
    for (j = 0; j < {macro}_N_CHANNELS; ++j) {{
        int k;
        if (s->run[j] == 1) {{   /* the value changed: a new run, measured from here */
            for (k = 0; k < {macro}_N_CHANNELS; ++k) s->channel_ref[j][k] = u[{name}_channels[k]];
            s->channel_moved[j] = 0;
        }} else if (!s->channel_moved[j]) {{
            for (k = 0; k < {macro}_N_CHANNELS; ++k)
                if (k != j && fabs(u[{name}_channels[k]] - s->channel_ref[j][k]) > {_num(LOAD_STEPS)} * s->channel_step[k])
                    s->channel_moved[j] = 1;
        }}
    }}
    for (j = 0; j < {macro}_N_CHANNELS; ++j) {{
        double x = u[{name}_channels[j]], low, high;
        int stuck, outside;
        stuck = s->run[j] >= {STUCK_RUN} && s->channel_moved[j];
        if (stuck && s->run[j] >= {DEAD_RUN}) flags |= {macro}_FLAG_DEAD;
        else if (stuck) flags |= {macro}_FLAG_STUCK;
        if (s->use_adc_limits) {{
            if (x <= s->adc_low || x >= s->adc_high) flags |= {macro}_FLAG_SATURATED;
        }} else {{
            low = {name}_channel_range[j][0];
            high = {name}_channel_range[j][1];
            outside = x < low || x > high;
            if (outside && s->run[j] >= {SATURATION_RUN}) flags |= {macro}_FLAG_SATURATED;
        }}
    }}
    for (j = 0; j < {macro}_N_CHANNELS; ++j) s->last_raw[j] = u[{name}_channels[j]];
    s->has_last = 1;
    {{
        static const double low[{macro}_N_INPUTS] = {_array(rng[:, 0] - slack)};
        static const double high[{macro}_N_INPUTS] = {_array(rng[:, 1] + slack)};
        int outside = 0;
        for (j = 0; j < {macro}_N_INPUTS; ++j) if (u[j] < low[j] || u[j] > high[j]) outside = 1;
        if (outside || {name}_outside_span(u)) flags |= {macro}_FLAG_OUT_OF_RANGE;
    }}
{temp_line}
    if (still && !gate && chi2 >= s->gate_chi2 && !s->identifying) flags |= {macro}_FLAG_CONTACT;
    if (beyond) {{
        if (!s->exceeding) {{
            s->exceeding = 1;
            s->exceed_start = time;
        }}
        if (time - s->exceed_start >= s->unexplained_seconds) flags |= {macro}_FLAG_UNEXPLAINED;
    }} else {{
        s->exceeding = 0;
    }}
    if (flags != s->flags) {name}_flag_events(s, flags, time, time - s->exceed_start, u, e, chi2, moving);
    if ((flags & {macro}_FLAG_CONTACT) && !(s->flags & {macro}_FLAG_CONTACT)) s->contacts += 1;
    s->flags = flags;
    s->updates += (unsigned long)gate;
    s->samples += 1;
    s->has_time = 1;
    s->last_time = time;
    out->chi2 = chi2;
    out->is_static = still;
    out->updated = gate;
    out->flags = flags;
    return 0;
}}

{finish_text(name, macro, max_holds)}{describe_text(name, macro, [repr(t) for t in names],
                                             None if t_col is None else tuple(rng[t_col]))}{describe_event_text(name, macro)}
#ifdef __cplusplus
}}
#endif

#endif /* {macro}_H */
"""
    return text


def write_c_runtime(source: ModelFile, output: Path, options: ConvertOptions) -> Written:
    """Registry writer: the header ``output`` (``--payload-file [NAME=]TOOL.json``, repeatable, for the tools).

    The C prefix is ``--name``, else the header's file name when it is a C identifier
    (``ft_runtime.h``: ``ft_runtime_step``), else :data:`DEFAULT_NAME`.
    """
    from ..files.payload_json import load_payload

    default = output.name[:-2] if output.name.endswith(".h") else DEFAULT_NAME
    try:  # the prefix follows the file's name (ft_runtime.h: ft_runtime_step) when that is a C identifier
        default = c_identifier(default)
    except FtcalError:
        default = DEFAULT_NAME
    name = c_identifier(options.get("name", default))
    if getattr(source.model, "family", "polynomial") != "polynomial" or not source.model.layout_.is_static:
        raise FtcalError("--to c-runtime takes a static polynomial model (no ARX lags).")
    tools, files = {}, []
    for spec in options.get("payload_files", []) or []:
        tool, sep, path = str(spec).partition("=")
        if not sep:
            tool, path = Path(spec).stem, spec
        if not tool or tool == NO_TOOL:
            raise FtcalError(f"--payload-file {spec}: a tool needs a name other than {NO_TOOL!r}.")
        if tool in tools:
            raise FtcalError(f"--payload-file {spec}: the name {tool!r} is taken; give each tool its own name "
                             "(NAME=FILE).")
        if Path(path).resolve() == output.resolve():
            raise FtcalError(f"-o {output} is the input file {path}; choose another output path.")
        tools[tool] = load_payload(path)
        files.append(Path(path).name)
    sha256 = hashlib.sha256(options.input_path.read_bytes()).hexdigest()
    text = generate_c_runtime(source.model, tools, name=name, sha256=sha256, source_name=options.input_path.name,
                              tool_sources=files)
    write_text_atomic(output, text)
    library = (f"{len(tools) + 1} tools (none, {', '.join(tools)})" if tools else
               "1 tool (none); add tools with --payload-file")
    return Written((output,), (f"{name}_init / {name}_step / {name}_set_tool / {name}_find_tool / {name}_retare / "
                               f"{name}_start_identification / {name}_finish_identification / "
                               f"{name}_describe_flags / {name}_event_count / {name}_get_event / "
                               f"{name}_describe_event / {name}_clear_events; {library}",))
