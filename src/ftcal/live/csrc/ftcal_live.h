/* ftcal_live.h: the live calibrator's step in C99, one hand-written source for every path.

   What it does, per sample: the motion test on the gravity direction, the gated random-walk bias Kalman filter
   (ftcal.live.tracker's model), the drift test (ftcal.live.drift), the self-check (ftcal_live_selfcheck.h,
   ftcal.live.consistency), the health flags (ftcal.live.health), the event log and the identification of a tool
   in place (ftcal.payload.identify's estimator on fixed 10 x 10 matrices). The calibration itself (raw channels to
   a wrench) is not here: the caller evaluates the model and passes the wrench.

   Used two ways, the same text both times:
   - `ftcal convert MODEL --to c-runtime -o NAME.h` writes this file into NAME.h after the model's generated
     evaluator, the public macros (NAME_N_INPUTS, NAME_FLAG_*, ...) and a data-only configuration initializer, so
     that every function below is NAME_... (FTL_(step) is NAME_core_step);
   - the CPython extension ftcal.live._core compiles it with its own prefix and maximum sizes; LiveCalibrator
     then runs on it.

   Before the include the includer defines FTCAL_LIVE_PREFIX (the C identifier prefixing every symbol) and
   FTCAL_LIVE_MACRO (the same upper-cased, prefixing every macro), and the size macros PREFIX_N_INPUTS,
   PREFIX_N_CHANNELS, PREFIX_N_TOOLS, PREFIX_MAX_ADDED_TOOLS, PREFIX_MAX_TOOLS, PREFIX_MAX_TOOL_NAME,
   PREFIX_MAX_HOLDS, PREFIX_MIN_HOLDS, PREFIX_MAX_MAGNITUDE, PREFIX_HISTORY,
   PREFIX_DRIFT_LAGS, PREFIX_N_FLAGS, PREFIX_MAX_EVENTS, and the codes
   PREFIX_FLAG_*, PREFIX_EVENT_*, PREFIX_TOOL_*, PREFIX_ID_* (the generated header emits them from the Python
   constants they mirror); for the texts also PREFIX_FLAG_NAMES, PREFIX_EVENT_KIND_NAMES and a function PREFIX_input_name(int). Sizes are maxima: the configuration (FTL_(config)) says how many inputs, channels and compiled-in tools
   there are. FTCAL_LIVE_REAL (default double; the generated header sets it from NAME_REAL) is the type of the
   filter's numbers: a float build defines it as float (times, the configuration and the identification's moments
   stay double). FTCAL_LIVE_NO_TEXT (from NAME_NO_TEXT) leaves out the texts (and snprintf).

   C99 and C++ (17, 20), fixed-size state, no allocation, no library beyond <math.h>, <string.h>, <stdint.h> (and
   <stdio.h> for the texts); every function is static, so the file can be included by several translation units
   and once per prefix in one. No text of a file reaches it as code: names arrive as data in the configuration. */

#include <math.h>
#include <stdint.h>
#include <string.h>

/* The sizes of the core's own rings, declared once here (not by the includer): Python reads them from this text
   (ftcal.live.c_limits; the generated header's NAME_DRIFT_SNAPSHOTS, NAME_SC_KEEP_HOLDS, NAME_SC_WALK_KEEP name them)
   and the extension exports them (ftcal.live.core.require_core checks a build against this text). */
#ifndef FTCAL_LIVE_DRIFT_SNAPSHOTS
#define FTCAL_LIVE_DRIFT_SNAPSHOTS 258   /* the drift test's snapshots: ceil(64 s / 0.25 s) + 2 (ftcal.live.drift) */
#define FTCAL_LIVE_SC_KEEP_HOLDS 4       /* locked holds the self-check keeps */
#define FTCAL_LIVE_SC_WALK_KEEP 12       /* hold starts the walk matching keeps */
#endif

#if !defined(FTCAL_LIVE_PREFIX) || !defined(FTCAL_LIVE_MACRO)
#error "define FTCAL_LIVE_PREFIX and FTCAL_LIVE_MACRO before including ftcal_live.h"
#endif

#define FTL_CAT2(a, b) a##_##b
#define FTL_CAT(a, b) FTL_CAT2(a, b)
#define FTL_(x) FTL_CAT(FTCAL_LIVE_PREFIX, x)    /* a function or type: PREFIX_x */
#define FTL_M(x) FTL_CAT(FTCAL_LIVE_MACRO, x)    /* a macro: MACRO_x */

#if defined(__GNUC__)
#define FTL_RARE __attribute__((noinline, cold))   /* off the step's path: run on transitions only */
#else
#define FTL_RARE
#endif

#ifndef FTCAL_LIVE_REAL
#define FTCAL_LIVE_REAL double
#endif
typedef FTCAL_LIVE_REAL FTL_(real);   /* the filter's numbers: double, or float for a float build */

/* ----- configuration: what the model, the tool files and ftcal's methods fix (filled once, data only) ----- */
typedef struct {
    int n_inputs, n_channels;        /* the model's inputs; the sensor channels among them (temperature excluded) */
    int n_tools;                     /* compiled-in tools (0 is "none") */
    int channels[FTL_M(N_CHANNELS)]; /* the input index of each channel */
    double channel_range[FTL_M(N_CHANNELS)][2];   /* the training range: beyond it, flat, a channel is saturated */
    double input_low[FTL_M(N_INPUTS)], input_high[FTL_M(N_INPUTS)];   /* the training range with its tolerance */
    int temperature;                 /* the temperature input, or -1 */
    double temperature_low, temperature_high;
    /* the inputs' span (ftcal.core.excitation.span_distance): has_span 0 for none */
    int has_span;
    double span_mean[FTL_M(N_INPUTS)], span_unit[FTL_M(N_INPUTS)], span_values[FTL_M(N_INPUTS)];
    double span_vectors[FTL_M(N_INPUTS)][FTL_M(N_INPUTS)];
    int span_kept[FTL_M(N_INPUTS)];
    double span_off, span_limit;     /* off-span component beyond span_off, or distance beyond span_limit */
    /* the compiled-in tools: NAME_init copies them into the state's library */
    double tool_mass[FTL_M(N_TOOLS)], tool_mc[FTL_M(N_TOOLS)][3], tool_sign[FTL_M(N_TOOLS)];
    const char *tool_names[FTL_M(N_TOOLS)];   /* as given */
    const char *tool_reprs[FTL_M(N_TOOLS)];   /* Python's repr of each, for the texts */
    /* the defaults NAME_init puts into the state's settings (LiveCalibrator's) */
    double noise_variance[6], walk_variance[6], accept_limit[6];
    double gate_chi2, drift_chi2, gate_probability, unexplained_sigma, unexplained_seconds;
    double motion_window, min_rate, min_hold, retare_variance;
    double holdoff;                  /* s after a static sample failed the gate without updates (ftcal.live.tracker) */
    double min_fail_s;               /* ... once a run of failures lasted this long (a contact, not chance) */
    /* the drift test (ftcal.live.drift) */
    double snapshot_s, lags[FTL_M(DRIFT_LAGS)];
    /* health (ftcal.live.health, ftcal.data.signals) */
    long stuck_run, dead_run, saturation_run;
    double load_steps;
    /* the self-check (ftcal.live.consistency) */
    double sc_lock_s, sc_min_hold_s, sc_min_turn_deg, sc_turn_share, sc_correlation_s, sc_window_s;
    long sc_min_window_samples;
    double sc_r_max, sc_q_max, sc_nis_factor, sc_gated_factor;
    double sc_diff_cap;              /* a squared difference of consecutive static samples is clipped at this x r0 */
    long sc_min_walk_starts;         /* the walk matching: hold starts needed, */
    double sc_min_walk_share, sc_walk_factor, sc_chi2_6_median;   /* walk share of a start, factor, median chi2_6/6 */
    /* identification in place (ftcal.payload.identify) */
    double rank_relative, rounding_column, null_row, canonical_tie, weighting_tie, refit_condition, excitation_limit;
    double id_maps[6][10][4];        /* axis i's regressor row is id_maps[i] (g, 1) */
    double t_scale[FTL_M(MAX_HOLDS)];   /* the jackknife's t scaling by blocks - 1 */
    /* texts (the Python templates' fixed words that live in constants) */
    const char *no_tool, *out_of_range_text, *retare_warning, *plus_minus;
    /* the wander's low-frequency density 2 s^2 tau (ftcal.live.defaults.tracker_wander), 0: white noise */
    double wander_density[6];
} FTL_(config);

/* ----- the event log: a ring of MAX_EVENTS events in the state ----- */
typedef struct {
    double time;             /* s: the sample's; for a call between samples the last sample's (NAN before the first) */
    unsigned long sample;    /* samples stepped before it: a flag's event is sample number `sample`, from 0 */
    int kind;                /* EVENT_* */
    unsigned flag;           /* FLAG_RAISED, FLAG_CLEARED: the flag's bit (FLAG_*) */
    int tool_from, tool_to;  /* TOOL_SWITCHED: the tools; TOOL_IDENTIFIED: the new tool's index (both);
                                TOOL_IDENTIFYING:
                                the index of a library tool of that name, else -1 (both); others: the tool mounted */
    long count;              /* STUCK, DEAD raised: the run length; TOOL_IDENTIFIED: the holds */
    double value[9];         /* the text's numbers: SATURATED (ADC limits used, low, high); TEMPERATURE (temperature);
                                CONTACT (chi2, gate); UNEXPLAINED (sigma, seconds, duration, innovation[6]);
                                TOOL_IDENTIFIED (mass, its standard error) */
    unsigned char channels[FTL_M(N_CHANNELS)];   /* SATURATED, STUCK, DEAD raised: the channels flagged */
    char tool_name[FTL_M(MAX_TOOL_NAME) + 1];    /* TOOL_IDENTIFYING, TOOL_IDENTIFIED: the tool's name */
    double extra[6];         /* TRACKER_ADAPTED: the new noise (count 0) or walk (count: the moves matched) variances;
                                TRACKER_REACQUIRED: the walk variances after it */
} FTL_(event);

typedef struct {
    /* settings: NAME_init sets the defaults; change them after init if needed */
    FTL_(real) noise_variance[6];    /* r: per-sample noise variance of the calibrated wrench */
    FTL_(real) walk_variance[6];     /* q: bias random-walk variance per second */
    FTL_(real) gate_chi2;            /* contact gate, chi2 quantile with 6 dof */
    FTL_(real) drift_chi2;           /* drift test: chi2 (6 dof) beyond which the bias moved faster than the walk */
    FTL_(real) accept_limit[6];      /* check --accept thresholds, N and N m */
    FTL_(real) unexplained_sigma;
    double unexplained_seconds;
    double motion_window, min_rate, min_hold;   /* s, rad/s, s */
    int use_adc_limits;          /* 1: saturated means a channel at adc_low/adc_high */
    FTL_(real) adc_low, adc_high;
    /* state */
    int tool;
    /* the tool library: 0 .. N_TOOLS-1 compiled in (copied by NAME_init), then the tools identified in place */
    int n_tools;
    FTL_(real) tool_mass[FTL_M(MAX_TOOLS)], tool_mc[FTL_M(MAX_TOOLS)][3], tool_sign[FTL_M(MAX_TOOLS)];
    char tool_names[FTL_M(MAX_ADDED_TOOLS)][FTL_M(MAX_TOOL_NAME) + 1];
    FTL_(real) bias[6], variance[6];
    int has_time;
    double last_time, last_moving;
    int history_start, history_count;
    double history_time[FTL_M(HISTORY)];
    FTL_(real) history_direction[FTL_M(HISTORY)][3];
    int has_last;
    FTL_(real) last_raw[FTL_M(N_CHANNELS)];
    long run[FTL_M(N_CHANNELS)];
    /* a load change since each channel's run began (ftcal.live.health.LoadChange): another channel moved by more
       than cfg.load_steps of its quantisation steps (its smallest change seen, HUGE_VAL before one) */
    FTL_(real) channel_step[FTL_M(N_CHANNELS)], channel_ref[FTL_M(N_CHANNELS)][FTL_M(N_CHANNELS)];
    int channel_moved[FTL_M(N_CHANNELS)];
    int exceeding;
    double exceed_start;
    unsigned flags;
    unsigned long samples, updates, contacts, retares, switches;
    /* the drift test (ftcal.live.drift): snapshots of bias and variance, oldest at drift_start, times increasing */
    double drift_due;            /* the next snapshot is taken at the first sample at or after this time */
    int drift_start, drift_count;
    double drift_time[FTCAL_LIVE_DRIFT_SNAPSHOTS];
    FTL_(real) drift_bias[FTCAL_LIVE_DRIFT_SNAPSHOTS][6];
    FTL_(real) drift_variance[FTCAL_LIVE_DRIFT_SNAPSHOTS][6];
    double last_fail, fail_start;   /* the hold-off: the last failed static sample and the start of its run */
    int fail_previous;              /* the previous sample failed */
    double holdoff;              /* s after it without updates (LiveCalibrator(holdoff=...)), 0: off */
    unsigned long rollbacks;     /* the bias sent back by the drift test (Python's "rollback" events) */
    double rollback_time, rollback_lag;
    FTL_(real) rollback_chi2, rollback_moved;   /* the last one: the event's numbers */
    /* the self-check (ftcal_live_selfcheck.h, ftcal.live.consistency; s->self_check = 1 to run it) */
    int self_check;
    FTL_(real) sc_noise0[6], sc_walk0[6], sc_expected_gated;
    int sc_has_window, sc_has_update, sc_announced, sc_in_hold, sc_n_previous;
    double sc_window_start, sc_last_update;
    FTL_(real) sc_nis, sc_e2[6], sc_pred[6];
    unsigned long sc_static, sc_gated, sc_updated;
    long sc_hold_n, sc_hold_missed;
    FTL_(real) sc_hold_z[6], sc_hold_dir[3];
    double sc_hold_start, sc_hold_last;
    FTL_(real) sc_prev_mean[FTCAL_LIVE_SC_KEEP_HOLDS][6], sc_prev_dir[FTCAL_LIVE_SC_KEEP_HOLDS][3];
    double sc_prev_seconds[FTCAL_LIVE_SC_KEEP_HOLDS], sc_prev_end[FTCAL_LIVE_SC_KEEP_HOLDS];
    long sc_prev_n[FTCAL_LIVE_SC_KEEP_HOLDS];
    /* r matched to the differences of consecutive static samples (clipped sums over the window, their count) */
    FTL_(real) sc_diff[6], sc_last_z[6];
    unsigned long sc_pairs;
    /* walk matching over hold starts: the last static sample (bias after it, or z when it did not update) */
    int sc_has_ref, sc_ref_updated, sc_n_starts, sc_new_start, sc_start_updated[FTCAL_LIVE_SC_WALK_KEEP], sc_rb_has;
    FTL_(real) sc_ref[6], sc_ref_var[6];
    double sc_ref_time;
    FTL_(real) sc_start_change[FTCAL_LIVE_SC_WALK_KEEP][6], sc_start_var[FTCAL_LIVE_SC_WALK_KEEP][6];
    double sc_start_gap[FTCAL_LIVE_SC_WALK_KEEP];
    /* the drift test's last rollback (DriftCheck.last_rollback): time, state before it, the snapshot, span */
    double sc_rb_time, sc_rb_span;
    FTL_(real) sc_rb_bias[6], sc_rb_var[6], sc_rb_b0[6], sc_rb_p0[6];
    unsigned long sc_adaptations, sc_lockouts, sc_reacquisitions, sc_undone;
    double sc_last_adapted, sc_last_lockout, sc_last_reacquired, sc_last_undone;
    /* identification in place (NAME_start_identification / NAME_finish_identification) */
    int identifying, in_hold;    /* in_hold: 0 moving, 1 collecting into the last hold, 2 a hold past the limit */
    int n_holds;
    unsigned long holds_dropped; /* holds past MAX_HOLDS, left out of the identification */
    long hold_samples[FTL_M(MAX_HOLDS)];
    double hold_moments[FTL_M(MAX_HOLDS)][10][10];   /* sum of z z^T, z = (g, 1, w); upper triangle */
    double hold_gravity_max;     /* max |g component| over the collected samples */
    char identifying_name[FTL_M(MAX_TOOL_NAME) + 1];   /* the tool being identified */
    /* each flag's event as it was last raised (NAME_describe_flags) */
    unsigned raised_ever;        /* flags raised at least once */
    FTL_(event) last_raised[FTL_M(N_FLAGS)];
    /* the event log (NAME_event_count, NAME_get_event, NAME_clear_events) */
    int events_start, events_count;
    unsigned long events_dropped;   /* events overwritten when the ring was full */
    FTL_(event) events[FTL_M(MAX_EVENTS)];
    /* the configuration the state was initialised with (a copy: the state is self-contained plain data) */
    FTL_(config) cfg;
    /* setting: the wander's density D (N^2 s): the update takes r + D / dt, the gate r (ftcal.live.tracker) */
    FTL_(real) wander_density[6];
} FTL_(state);

typedef struct {
    FTL_(real) calibrated[6];    /* the model's wrench */
    FTL_(real) compensated[6];   /* calibrated - tool - bias (the contact wrench) */
    FTL_(real) bias[6], bias_std[6];   /* after the sample */
    FTL_(real) chi2;             /* innovation chi2, 6 dof */
    int is_static, updated;
    unsigned flags;          /* FLAG_* bits */
} FTL_(output);

/* ----- the inputs' span and the start ----- */

/* 1 when the raw inputs u lie outside the span of the training inputs (ftcal.core.excitation.span_distance):
   off the subspace they fill, or beyond span_limit in the standardised eigen-coordinates; 0 inside (or no span). */
static inline int FTL_(outside_span)(const FTL_(config) *c, const FTL_(real) *u)
{
    double x[FTL_M(N_INPUTS)], distance = 0.0, off = 0.0;
    int i, k, nu = c->n_inputs;
    if (!c->has_span) {
        return 0;
    }
    for (i = 0; i < nu; ++i) {
        x[i] = (u[i] - c->span_mean[i]) / c->span_unit[i];
    }
    for (k = 0; k < nu; ++k) {
        double p = 0.0;
        for (i = 0; i < nu; ++i) {
            p += x[i] * c->span_vectors[k][i];
        }
        if (c->span_kept[k]) {
            distance += p * p / c->span_values[k];
        } else if (fabs(p) > off) {
            off = fabs(p);
        }
    }
    if (off > c->span_off) {
        return 1;
    }
    return distance > c->span_limit;
}

/* Start from configuration `config` (copied into the state) with tool `tool` mounted and the bias unknown (the first
   static, contact-free samples set it). Returns 0, or -1 for a tool index outside 0 .. config->n_tools - 1. */
static inline int FTL_(core_init)(FTL_(state) *s, const FTL_(config) *config, int tool)
{
    int j;
    if (tool < 0 || tool >= config->n_tools || config->n_tools > FTL_M(N_TOOLS)) {
        return -1;
    }
    memset(s, 0, sizeof *s);
    s->cfg = *config;
    for (j = 0; j < 6; ++j) {
        s->noise_variance[j] = config->noise_variance[j];
        s->walk_variance[j] = config->walk_variance[j];
        s->wander_density[j] = config->wander_density[j];
        s->accept_limit[j] = config->accept_limit[j];
        s->bias[j] = 0.0;
        s->variance[j] = config->retare_variance * config->noise_variance[j];
    }
    s->gate_chi2 = config->gate_chi2;
    s->drift_chi2 = config->drift_chi2;
    s->drift_due = -HUGE_VAL;
    s->last_fail = -HUGE_VAL;   /* NO_FAILURE */
    s->fail_start = HUGE_VAL;
    s->fail_previous = 0;
    s->holdoff = config->holdoff;
    s->unexplained_sigma = config->unexplained_sigma;
    s->unexplained_seconds = config->unexplained_seconds;
    s->motion_window = config->motion_window;
    s->min_rate = config->min_rate;
    s->min_hold = config->min_hold;
    s->last_moving = -HUGE_VAL;
    s->tool = tool;
    s->n_tools = config->n_tools;
    for (j = 0; j < config->n_tools; ++j) {
        s->tool_mass[j] = config->tool_mass[j];
        s->tool_mc[j][0] = config->tool_mc[j][0];   /* assigned, not copied: the state's may be float */
        s->tool_mc[j][1] = config->tool_mc[j][1];
        s->tool_mc[j][2] = config->tool_mc[j][2];
        s->tool_sign[j] = config->tool_sign[j];
    }
    /* the self-check on, as LiveCalibrator's default (NAME_enable_self_check again after changing noise_variance or
       walk_variance: its bounds; s->self_check = 0 for fixed q and r) */
    memcpy(s->sc_noise0, s->noise_variance, sizeof s->sc_noise0);
    memcpy(s->sc_walk0, s->walk_variance, sizeof s->sc_walk0);
    s->sc_expected_gated = 1.0 - config->gate_probability;
    s->self_check = 1;
    return 0;
}

/* ----- the event log ----- */

/* Append an event; a full ring overwrites its oldest and counts it. */
static FTL_RARE void FTL_(log_event)(FTL_(state) *s, const FTL_(event) *ev)
{
    if (s->events_count == FTL_M(MAX_EVENTS)) {
        s->events_start = (s->events_start + 1) % FTL_M(MAX_EVENTS);
        s->events_count -= 1;
        s->events_dropped += 1;
    }
    s->events[(s->events_start + s->events_count) % FTL_M(MAX_EVENTS)] = *ev;
    s->events_count += 1;
}

/* An event of a call between samples (switch, re-tare, identification): the last sample's time, the samples so far. */
static inline void FTL_(call_event)(FTL_(state) *s, int kind, int tool_from, int tool_to, FTL_(event) *ev)
{
    memset(ev, 0, sizeof *ev);
    ev->time = s->has_time ? s->last_time : NAN;
    ev->sample = s->samples;
    ev->kind = kind;
    ev->tool_from = tool_from;
    ev->tool_to = tool_to;
}

/* An event of the tracker at the sample at `time` (the drift test's rollback, the self-check's): the numbers of its
   text in value[] (ROLLBACK: lag, chi2, moved; TRACKER_ADAPTED: NIS (NAN when too few updates), updates, pairs,
   share gated, expected share, or the walk's factor; TRACKER_LOCKED_OUT: idle s; TRACKER_REACQUIRED: ratio, turn
   in degrees, the largest move; TRACKER_UNDONE: the rollback's time) and extra[]. */
static FTL_RARE void FTL_(tracker_event)(FTL_(state) *s, int kind, double time, long count, const double *value,
                                         int n_value, const FTL_(real) *extra)
{
    FTL_(event) ev;
    int j;
    memset(&ev, 0, sizeof ev);
    ev.time = time;
    ev.sample = s->samples;
    ev.kind = kind;
    ev.tool_from = ev.tool_to = s->tool;
    ev.count = count;
    for (j = 0; j < n_value; ++j) { ev.value[j] = value[j]; }
    for (j = 0; extra && j < 6; ++j) { ev.extra[j] = extra[j]; }
    FTL_(log_event)(s, &ev);
}

/* Events kept, 0 .. FTL_M(MAX_EVENTS). */
static inline int FTL_(event_count)(const FTL_(state) *s)
{
    return s->events_count;
}

/* Copy event `i` (0 = the oldest kept) into *ev: 0, or -1 (*ev untouched) for i outside 0 .. count - 1. */
static inline int FTL_(get_event)(const FTL_(state) *s, int i, FTL_(event) *ev)
{
    if (i < 0 || i >= s->events_count) { return -1; }
    *ev = s->events[(s->events_start + i) % FTL_M(MAX_EVENTS)];
    return 0;
}

/* Events overwritten since init or the last NAME_clear_events because the ring was full. */
static inline unsigned long FTL_(events_dropped)(const FTL_(state) *s)
{
    return s->events_dropped;
}

/* Empty the log (and zero the dropped count): e.g. after reading every event. */
static inline void FTL_(clear_events)(FTL_(state) *s)
{
    s->events_start = 0;
    s->events_count = 0;
    s->events_dropped = 0;
}

/* The name of tool `tool`: 0 is "none", then the payload files' in the order given, then the tools identified in
   place (in the order they were first added); 0 (a null pointer) for an index not in the library. */
static inline const char *FTL_(tool_name)(const FTL_(state) *s, int tool)
{
    int compiled = s->cfg.n_tools;
    if (tool >= 0 && tool < compiled) {
        return s->cfg.tool_names[tool];
    }
    return tool >= compiled && tool < s->n_tools ? s->tool_names[tool - compiled] : 0;
}

/* The index of the tool named `tool_name` (compared byte for byte), or -1 (none by that name, or a null pointer). */
static inline int FTL_(find_tool)(const FTL_(state) *s, const char *tool_name)
{
    int i;
    if (!tool_name) { return -1; }
    for (i = 0; i < s->n_tools; ++i) { if (strcmp(FTL_(tool_name)(s, i), tool_name) == 0) { return i; } }
    return -1;
}

/* Whether a tool may be identified as `tool_name`: FTL_M(TOOL_OK) or the reason it may not
   (NAME_start_identification lists them). Reads at most FTL_M(MAX_TOOL_NAME) + 1 bytes of the name. */
static inline int FTL_(check_new_tool)(const FTL_(state) *s, const char *tool_name)
{
    int n = 0;
    if (!tool_name || !tool_name[0]) { return FTL_M(TOOL_NO_NAME); }
    while (n <= FTL_M(MAX_TOOL_NAME) && tool_name[n]) { ++n; }
    if (n > FTL_M(MAX_TOOL_NAME)) { return FTL_M(TOOL_NAME_TOO_LONG); }
    if (strcmp(tool_name, s->cfg.no_tool) == 0) { return FTL_M(TOOL_NAME_RESERVED); }
    if (FTL_(find_tool)(s, tool_name) < 0 && s->n_tools == FTL_M(MAX_TOOLS)) { return FTL_M(TOOL_LIBRARY_FULL); }
    return FTL_M(TOOL_OK);
}

/* Mount another tool of the library instantly (switch_tool; by name: NAME_find_tool); the bias (the sensor's) is
   kept. Returns 0, or -1 for an index not in the library (0 .. s->n_tools - 1). */
static inline int FTL_(set_tool)(FTL_(state) *s, int tool)
{
    FTL_(event) ev;
    if (tool < 0 || tool >= s->n_tools) { return -1; }
    FTL_(call_event)(s, FTL_M(EVENT_TOOL_SWITCHED), s->tool, tool, &ev);
    FTL_(log_event)(s, &ev);
    s->tool = tool;
    s->switches += 1;
    return 0;
}

/* Forget the drift test's snapshots (the bias was set on purpose: a re-tare, a tool identified and mounted). */
static inline void FTL_(drift_reset)(FTL_(state) *s)
{
    s->drift_start = 0;
    s->drift_count = 0;
    s->drift_due = -HUGE_VAL;
    s->sc_rb_has = 0;   /* DriftCheck.reset: the last rollback forgotten */
}

/* The drift test after the sample at `time` (ftcal.live.drift.DriftCheck.check, same order and arithmetic): compare
   the bias with the newest snapshot at least 64, 16, 4, 1 s old; on the first lag whose chi2 is beyond drift_chi2
   with some axis moved beyond accept_limit, bias and variance go back to that snapshot's, predicted since, and the
   snapshots restart from there (returns 1); else the state is a new snapshot (returns 0). */
static inline int FTL_(drift_check)(FTL_(state) *s, double time)
{
    const double *lags = s->cfg.lags;
    int i, j, low, high, middle, slot;
    s->drift_due = time + s->cfg.snapshot_s;
    for (i = 0; i < FTL_M(DRIFT_LAGS); ++i) {
        double cutoff = time - lags[i], span;
        FTL_(real) chi2 = 0.0, moved = 0.0;
        const FTL_(real) *b0, *p0;
        int beyond = 0;
        low = 0;   /* bisect_right: low = the snapshots at or before cutoff */
        high = s->drift_count;
        while (low < high) {
            middle = (low + high) / 2;
            if (cutoff < s->drift_time[(s->drift_start + middle) % FTCAL_LIVE_DRIFT_SNAPSHOTS]) { high = middle; }
            else { low = middle + 1; }
        }
        if (low == 0) { continue; }
        slot = (s->drift_start + low - 1) % FTCAL_LIVE_DRIFT_SNAPSHOTS;
        b0 = s->drift_bias[slot];
        p0 = s->drift_variance[slot];
        span = time - s->drift_time[slot];
        for (j = 0; j < 6; ++j) {
            chi2 += (s->bias[j] - b0[j]) * (s->bias[j] - b0[j]) / (s->walk_variance[j] * span + s->variance[j] + p0[j]);
        }
        if (!(chi2 > s->drift_chi2)) { continue; }
        for (j = 0; j < 6; ++j) { if (fabs(s->bias[j] - b0[j]) > s->accept_limit[j]) { beyond = 1; } }
        if (!beyond) { continue; }
        for (j = 0; j < 6; ++j) { if (fabs(s->bias[j] - b0[j]) > moved) { moved = fabs(s->bias[j] - b0[j]); } }
        s->sc_rb_has = 1;   /* DriftCheck.last_rollback: the self-check may undo it */
        s->sc_rb_time = time;
        s->sc_rb_span = span;
        memcpy(s->sc_rb_bias, s->bias, sizeof s->sc_rb_bias);
        memcpy(s->sc_rb_var, s->variance, sizeof s->sc_rb_var);
        memcpy(s->sc_rb_b0, b0, sizeof s->sc_rb_b0);
        memcpy(s->sc_rb_p0, p0, sizeof s->sc_rb_p0);
        for (j = 0; j < 6; ++j) {   /* back to the snapshot, its variance predicted since; it is the only one left */
            s->bias[j] = b0[j];
            s->variance[j] = p0[j] + s->walk_variance[j] * span;
        }
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
        {
            double numbers[3];
            numbers[0] = span;
            numbers[1] = chi2;
            numbers[2] = moved;
            FTL_(tracker_event)(s, FTL_M(EVENT_ROLLBACK), time, 0, numbers, 3, 0);
        }
        return 1;
    }
    if (s->drift_count == FTCAL_LIVE_DRIFT_SNAPSHOTS) {   /* full: the oldest is never needed again */
        s->drift_start = (s->drift_start + 1) % FTCAL_LIVE_DRIFT_SNAPSHOTS;
        s->drift_count -= 1;
    }
    slot = (s->drift_start + s->drift_count) % FTCAL_LIVE_DRIFT_SNAPSHOTS;
    s->drift_time[slot] = time;
    memcpy(s->drift_bias[slot], s->bias, sizeof s->bias);
    memcpy(s->drift_variance[slot], s->variance, sizeof s->variance);
    s->drift_count += 1;
    return 0;
}

#include "ftcal_live_selfcheck.h"

/* Re-tare, tool kept, in any pose: the bias forgets its value; the next static samples set it.
   Returns the flags of FTL_M(FLAG_CONTACT) and FTL_M(FLAG_UNEXPLAINED) raised now, 0 if none: if a contact
   raised them, the next static samples take it into the bias (the event's text warns, as LiveCalibrator.retare). */
static inline int FTL_(retare)(FTL_(state) *s)
{
    FTL_(event) ev;
    int j;
    FTL_(call_event)(s, FTL_M(EVENT_RETARE), s->tool, s->tool, &ev);
    ev.flag = s->flags & (FTL_M(FLAG_CONTACT) | FTL_M(FLAG_UNEXPLAINED));
    FTL_(log_event)(s, &ev);
    for (j = 0; j < 6; ++j) {
        if (s->variance[j] < s->cfg.retare_variance * s->noise_variance[j]) {
            s->variance[j] = s->cfg.retare_variance * s->noise_variance[j];
        }
    }
    FTL_(drift_reset)(s);
    FTL_(sc_reset)(s);
    s->last_fail = -HUGE_VAL;   /* NO_FAILURE */
    s->fail_start = HUGE_VAL;
    s->fail_previous = 0;
    s->retares += 1;
    return ev.flag;
}

/* The drift test, the self-check and the hold-off start afresh (the bias was set on purpose: a state resumed, a tool
   identified and mounted); bias and variance are kept. */
static inline void FTL_(restart_checks)(FTL_(state) *s)
{
    FTL_(drift_reset)(s);
    FTL_(sc_reset)(s);
    s->last_fail = -HUGE_VAL;   /* NO_FAILURE */
    s->fail_start = HUGE_VAL;
    s->fail_previous = 0;
}

/* Take the next sample at any time, as after a restart of the publisher's clock: the motion test starts without
   history, the unexplained-wrench timer and the checks restart; bias, variance, tool and counts are kept. */
static inline void FTL_(restart_clock)(FTL_(state) *s)
{
    s->has_time = 0;
    s->history_start = s->history_count = 0;
    s->last_moving = -HUGE_VAL;
    s->exceeding = 0;
    FTL_(restart_checks)(s);
}

/* Motion test on the gravity direction: sets *still and *moving (ftcal.live.motion). */
static inline void FTL_(motion)(FTL_(state) *s, double time, const FTL_(real) *direction, int *still, int *moving)
{
    double cutoff = time - s->motion_window, rate = HUGE_VAL;
    int last;
    while (s->history_count >= 2 &&
           s->history_time[(s->history_start + 1) % FTL_M(HISTORY)] <= cutoff) {
        s->history_start = (s->history_start + 1) % FTL_M(HISTORY);
        s->history_count -= 1;
    }
    if (s->history_count >= 1 && (s->history_time[s->history_start] <= cutoff
                                  || s->history_count == FTL_M(HISTORY))) {
        const FTL_(real) *y = s->history_direction[s->history_start];
        FTL_(real) cx = direction[1] * y[2] - direction[2] * y[1];
        FTL_(real) cy = direction[2] * y[0] - direction[0] * y[2];
        FTL_(real) cz = direction[0] * y[1] - direction[1] * y[0];
        FTL_(real) angle = atan2(sqrt(cx * cx + cy * cy + cz * cz),
                             direction[0] * y[0] + direction[1] * y[1] + direction[2] * y[2]);
        rate = angle / (time - s->history_time[s->history_start]);
    }
    if (s->history_count == FTL_M(HISTORY)) {   /* full: the oldest goes */
        s->history_start = (s->history_start + 1) % FTL_M(HISTORY);
        s->history_count -= 1;
    }
    last = (s->history_start + s->history_count) % FTL_M(HISTORY);
    s->history_time[last] = time;
    memcpy(s->history_direction[last], direction, 3 * sizeof(FTL_(real)));
    s->history_count += 1;
    *still = rate < s->min_rate;
    if (!*still) { s->last_moving = time; }
    *moving = rate < HUGE_VAL && !*still;
    *still = *still && (time - s->last_moving >= s->min_hold);
}

/* ----- identification in place: collecting the holds ----- */

/* Start collecting static holds for the tool `tool_name` (the previous collection is dropped). While identifying,
   the bias is not updated and the contact and unexplained flags are not raised (the tool is unknown). On success
   the tool joins the library under that name: a name the library has is replaced (it keeps its index, and if it
   is mounted the new tool is), a new one takes the next slot. Returns FTL_M(TOOL_OK) (0), or, nothing changed:
   FTL_M(TOOL_NO_NAME) (a null pointer or an empty name), FTL_M(TOOL_NAME_TOO_LONG) (more than
   FTL_M(MAX_TOOL_NAME) bytes), FTL_M(TOOL_NAME_RESERVED) ("none", tool 0), FTL_M(TOOL_LIBRARY_FULL) (a new name
   and FTL_M(MAX_ADDED_TOOLS) tools added already). */
static inline int FTL_(start_identification)(FTL_(state) *s, const char *tool_name)
{
    int status = FTL_(check_new_tool)(s, tool_name), index;
    FTL_(event) ev;
    if (status) { return status; }
    index = FTL_(find_tool)(s, tool_name);   /* -1 for a new name */
    FTL_(call_event)(s, FTL_M(EVENT_TOOL_IDENTIFYING), index, index, &ev);
    memcpy(ev.tool_name, tool_name, strlen(tool_name) + 1);
    FTL_(log_event)(s, &ev);
    memcpy(s->identifying_name, tool_name, strlen(tool_name) + 1);
    s->identifying = 1;
    s->in_hold = 0;
    s->n_holds = 0;
    s->holds_dropped = 0;
    s->hold_gravity_max = 0.0;
    return FTL_M(TOOL_OK);
}

/* End the collection without a tool (the bias filter and the flags resume). */
static inline void FTL_(stop_identification)(FTL_(state) *s)
{
    s->identifying = 0;
    s->in_hold = 0;
}

/* One sample of the identification: called by NAME_step. */
static inline void FTL_(collect)(FTL_(state) *s, int still, const FTL_(real) *g, const FTL_(real) *w)
{
    double z[10], (*m)[10];   /* the moments stay double in a float build: the estimator needs them */
    int j, k;
    if (!still) {
        s->in_hold = 0;
        return;
    }
    if (!s->in_hold) {
        if (s->n_holds == FTL_M(MAX_HOLDS)) {
            s->in_hold = 2;
            s->holds_dropped += 1;
        } else {
            s->in_hold = 1;
            memset(s->hold_moments[s->n_holds], 0, sizeof s->hold_moments[0]);
            s->hold_samples[s->n_holds] = 0;
            s->n_holds += 1;
        }
    }
    if (s->in_hold != 1) { return; }
    for (j = 0; j < 3; ++j) {
        z[j] = g[j];
        if (fabs(g[j]) > s->hold_gravity_max) { s->hold_gravity_max = fabs(g[j]); }
    }
    z[3] = 1.0;
    for (j = 0; j < 6; ++j) { z[4 + j] = w[j]; }
    m = s->hold_moments[s->n_holds - 1];
    for (j = 0; j < 10; ++j) {
        for (k = j; k < 10; ++k) { m[j][k] += z[j] * z[k]; }
    }
    s->hold_samples[s->n_holds - 1] += 1;
}



/* The events of a sample whose flags change, in bit order (LiveCalibrator's order): a cleared flag, or a raised one
   with the numbers of its reason (kept as the flag's last raised, for NAME_describe_flags, and logged). Called by
   NAME_step after the run lengths are updated; the flagged channels are found again here, so that the usual sample
   stores nothing. */
static FTL_RARE void FTL_(flag_events)(FTL_(state) *s, unsigned flags, double time, double duration,
                                           const FTL_(real) *u, const FTL_(real) *e, FTL_(real) chi2, int moving)
{
    unsigned changed = flags ^ s->flags;
    int i, j;
    (void)moving;   /* stuck needs a load change (s->channel_moved), not motion alone */
    for (i = 0; i < FTL_M(N_FLAGS); ++i) {
        unsigned bit = 1u << i;
        FTL_(event) ev;
        if (!(changed & bit)) { continue; }
        memset(&ev, 0, sizeof ev);
        ev.time = time;
        ev.sample = s->samples;
        ev.flag = bit;
        ev.tool_from = ev.tool_to = s->tool;
        ev.kind = flags & bit ? FTL_M(EVENT_FLAG_RAISED) : FTL_M(EVENT_FLAG_CLEARED);
        if (bit == FTL_M(FLAG_SATURATED) && (flags & bit)) {
            for (j = 0; j < s->cfg.n_channels; ++j) {
                FTL_(real) x = u[s->cfg.channels[j]];
                ev.channels[j] = s->use_adc_limits ? x <= s->adc_low || x >= s->adc_high
                    : (x < s->cfg.channel_range[j][0] || x > s->cfg.channel_range[j][1])
                      && s->run[j] >= s->cfg.saturation_run && s->channel_moved[j];
            }
            ev.value[0] = s->use_adc_limits;
            ev.value[1] = s->adc_low;
            ev.value[2] = s->adc_high;
        } else if ((bit == FTL_M(FLAG_STUCK) || bit == FTL_M(FLAG_DEAD)) && (flags & bit)) {
            for (j = 0; j < s->cfg.n_channels; ++j) {
                /* stuck: a load change since its run began */
                int stuck = s->run[j] >= s->cfg.stuck_run && s->channel_moved[j];
                ev.channels[j] = bit == FTL_M(FLAG_DEAD) ? stuck && s->run[j] >= s->cfg.dead_run
                                                          : stuck && s->run[j] < s->cfg.dead_run;
                if (ev.channels[j] && s->run[j] > ev.count) { ev.count = s->run[j]; }
            }
        } else if (bit == FTL_M(FLAG_TEMPERATURE)) {
            ev.value[0] = s->cfg.temperature >= 0 ? u[s->cfg.temperature] : 0.0;
        } else if (bit == FTL_M(FLAG_CONTACT)) {
            ev.value[0] = chi2;
            ev.value[1] = s->gate_chi2;
        } else if (bit == FTL_M(FLAG_UNEXPLAINED)) {
            ev.value[0] = s->unexplained_sigma;
            ev.value[1] = s->unexplained_seconds;
            ev.value[2] = duration;
            for (j = 0; j < 6; ++j) { ev.value[3 + j] = e[j]; }
        }
        if (flags & bit) {
            s->raised_ever |= bit;
            s->last_raised[i] = ev;
        }
        FTL_(log_event)(s, &ev);
    }
}

/* One sample: time in s (strictly increasing), u[cfg.n_inputs] the raw channels, w[6] the wrench the model gives
   for them (the caller evaluates the calibration), gravity[3] in sensor axes (m/s^2, any nonzero length for the
   direction), static_override -1 (motion test), 0 or 1.
   Returns 0, or -1 (state untouched, out not written) for input that is not finite or beyond
   MAX_MAGNITUDE (the wrench too), time that does not increase or a zero gravity vector. */
static inline int FTL_(core_step)(FTL_(state) *s, double time, const FTL_(real) *u, const FTL_(real) *w,
                                  const FTL_(real) *gravity, int static_override, FTL_(output) *out)
{
    FTL_(real) z[6], e[6], tool[6], direction[3], norm, dt, chi2 = 0.0, predicted[6], innovation_var[6];
    const FTL_(real) *mc = s->tool_mc[s->tool];
    FTL_(real) m = s->tool_mass[s->tool], sign = s->tool_sign[s->tool];
    int j, still, moving, gate, beyond = 0;
    unsigned flags = 0;
    if (!isfinite(time) || (s->has_time && !(time > s->last_time))) { return -1; }
    for (j = 0; j < s->cfg.n_inputs; ++j) { if (!(fabs(u[j]) <= FTL_M(MAX_MAGNITUDE))) { return -1; } }
    for (j = 0; j < 3; ++j) { if (!(fabs(gravity[j]) <= FTL_M(MAX_MAGNITUDE))) { return -1; } }
    norm = sqrt(gravity[0] * gravity[0] + gravity[1] * gravity[1] + gravity[2] * gravity[2]);
    if (norm == 0.0) { return -1; }
    for (j = 0; j < 6; ++j) { if (!(fabs(w[j]) <= FTL_M(MAX_MAGNITUDE))) { return -1; } }
    for (j = 0; j < 3; ++j) { direction[j] = gravity[j] / norm; }
    if (static_override >= 0) {
        still = static_override != 0;
        moving = !still;
    } else {
        FTL_(motion)(s, time, direction, &still, &moving);
    }
    if (s->identifying) { FTL_(collect)(s, still, gravity, w); }
    /* the tool's gravity wrench: F = m g, T = (m c) x g, negated for a reaction payload */
    tool[0] = sign * (m * gravity[0]);
    tool[1] = sign * (m * gravity[1]);
    tool[2] = sign * (m * gravity[2]);
    tool[3] = sign * (mc[1] * gravity[2] - mc[2] * gravity[1]);
    tool[4] = sign * (mc[2] * gravity[0] - mc[0] * gravity[2]);
    tool[5] = sign * (mc[0] * gravity[1] - mc[1] * gravity[0]);
    dt = s->has_time ? time - s->last_time : 0.0;
    for (j = 0; j < 6; ++j) {
        z[j] = w[j] - tool[j];
        predicted[j] = s->variance[j] + s->walk_variance[j] * dt;
        innovation_var[j] = predicted[j] + s->noise_variance[j];
        e[j] = z[j] - s->bias[j];
        chi2 += e[j] * (e[j] / innovation_var[j]);
    }
    /* the hold-off (ftcal.live.tracker.HOLDOFF_S): no update within it after a static sample failed the gate */
    gate = still && !s->identifying && chi2 < s->gate_chi2
           && !(s->last_fail - s->fail_start >= s->cfg.min_fail_s && time - s->last_fail < s->holdoff);
    if (still && !s->identifying && !(chi2 < s->gate_chi2)) {   /* a run of failures: its start and last sample */
        if (!s->fail_previous) { s->fail_start = time; }
        s->last_fail = time;
        s->fail_previous = 1;
    } else {
        s->fail_previous = 0;
    }
    for (j = 0; j < 6; ++j) {
        out->calibrated[j] = w[j];
        out->compensated[j] = e[j];
        if (gate) {   /* Kalman update: gain P-/(P- + r_u), r_u = r + D / dt (a wander's density), the gate's r */
            FTL_(real) r_u = s->noise_variance[j], total = innovation_var[j], gain;
            if (dt > 0.0 && s->wander_density[j] > 0.0) {
                r_u = s->noise_variance[j] + s->wander_density[j] / dt;
                total = predicted[j] + r_u;
            }
            gain = predicted[j] / total;
            s->bias[j] = (1.0 - gain) * s->bias[j] + gain * z[j];
            s->variance[j] = r_u * predicted[j] / total;
        } else {     /* prediction only: a contact is never absorbed */
            s->variance[j] = predicted[j];
        }
        if (!s->identifying
            && fabs(e[j]) > fmax(s->unexplained_sigma * sqrt(innovation_var[j]), s->accept_limit[j])) { beyond = 1; }
    }
    {
        int due = time >= s->drift_due, still_now = still && !s->identifying;
        if (due) { FTL_(drift_check)(s, time); }   /* a slow contact the gate let through goes back */
        if (s->self_check) {   /* ftcal.live.consistency, at the drift test's snapshot times */
            FTL_(sc_observe)(s, time, still_now, gate, still_now && !gate && chi2 >= s->gate_chi2, z, e, predicted,
                              innovation_var, direction);
            if (due) { FTL_(sc_check)(s, time); }
        }
    }
    for (j = 0; j < 6; ++j) {
        out->bias[j] = s->bias[j];
        out->bias_std[j] = sqrt(s->variance[j]);
    }
    /* health: run lengths of identical values per channel (temperature excluded) */
    for (j = 0; j < s->cfg.n_channels; ++j) {
        FTL_(real) x = u[s->cfg.channels[j]];
        s->run[j] = (s->has_last && x == s->last_raw[j]) ? s->run[j] + 1 : 1;
        if (!s->has_last) { s->channel_step[j] = HUGE_VAL; }
        else if (x != s->last_raw[j] && fabs(x - s->last_raw[j]) < s->channel_step[j]) {
            s->channel_step[j] = fabs(x - s->last_raw[j]);
        }
    }
    for (j = 0; j < s->cfg.n_channels; ++j) {
        int k;
        if (s->run[j] == 1) {   /* the value changed: a new run, measured from here */
            for (k = 0; k < s->cfg.n_channels; ++k) { s->channel_ref[j][k] = u[s->cfg.channels[k]]; }
            s->channel_moved[j] = 0;
        } else if (!s->channel_moved[j]) {
            for (k = 0; k < s->cfg.n_channels; ++k) {
                if (k != j
                    && fabs(u[s->cfg.channels[k]] - s->channel_ref[j][k]) > s->cfg.load_steps * s->channel_step[k]) {
                    s->channel_moved[j] = 1;
                }
            }
        }
    }
    for (j = 0; j < s->cfg.n_channels; ++j) {
        FTL_(real) x = u[s->cfg.channels[j]], low, high;
        int stuck, outside;
        stuck = s->run[j] >= s->cfg.stuck_run && s->channel_moved[j];
        if (stuck && s->run[j] >= s->cfg.dead_run) { flags |= FTL_M(FLAG_DEAD); }
        else if (stuck) { flags |= FTL_M(FLAG_STUCK); }
        if (s->use_adc_limits) {
            if (x <= s->adc_low || x >= s->adc_high) { flags |= FTL_M(FLAG_SATURATED); }
        } else {
            low = s->cfg.channel_range[j][0];
            high = s->cfg.channel_range[j][1];
            outside = x < low || x > high;
            /* flat outside the training range while a load change should have moved it (a clipped channel); a
               quantised sensor at rest holds one count outside the range without being saturated */
            if (outside && s->run[j] >= s->cfg.saturation_run && s->channel_moved[j]) { flags |= FTL_M(FLAG_SATURATED); }
        }
    }
    for (j = 0; j < s->cfg.n_channels; ++j) { s->last_raw[j] = u[s->cfg.channels[j]]; }
    s->has_last = 1;
    {
        int outside = 0;
        for (j = 0; j < s->cfg.n_inputs; ++j) {
            if (u[j] < s->cfg.input_low[j] || u[j] > s->cfg.input_high[j]) {
                outside = 1;
            }
        }
        if (outside || FTL_(outside_span)(&s->cfg, u)) { flags |= FTL_M(FLAG_OUT_OF_RANGE); }
    }
    if (s->cfg.temperature >= 0
        && !(u[s->cfg.temperature] >= s->cfg.temperature_low && u[s->cfg.temperature] <= s->cfg.temperature_high)) {
        flags |= FTL_M(FLAG_TEMPERATURE);
    }
    if (still && !gate && chi2 >= s->gate_chi2 && !s->identifying) { flags |= FTL_M(FLAG_CONTACT); }
    if (beyond) {
        if (!s->exceeding) {
            s->exceeding = 1;
            s->exceed_start = time;
        }
        if (time - s->exceed_start >= s->unexplained_seconds) { flags |= FTL_M(FLAG_UNEXPLAINED); }
    } else {
        s->exceeding = 0;
    }
    if (flags != s->flags) { FTL_(flag_events)(s, flags, time, time - s->exceed_start, u, e, chi2, moving); }
    if ((flags & FTL_M(FLAG_CONTACT)) && !(s->flags & FTL_M(FLAG_CONTACT))) { s->contacts += 1; }
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
}


/* ----- identification in place: the estimator ----- */

typedef struct {
    double mass;             /* kg */
    double com[3];           /* m, sensor axes */
    double bias[6];          /* the bias during the holds: force (N) then torque (N m) */
    double residual_rms[6];  /* per axis, N and N m */
    double variance_inflation[10];   /* theta order: m, m cx, m cy, m cz, Fx .. Tz bias */
    unsigned poorly_excited; /* bit j: variance inflation of theta_j > s->cfg.excitation_limit (Python warns) */
    unsigned undetermined;   /* bit j: theta_j lies in a direction the poses do not determine */
    unsigned held;           /* bit j: theta_j held at 0 to pick one solution (a subset of undetermined) */
    int weighted;            /* 1: per-axis weighting kept by held-out evidence, 0: plain least squares */
    int jackknife_blocks;    /* grouped-jackknife standard errors: the holds that could be left out; 0: classical */
    int n_holds;
    long n_samples;
    unsigned long holds_dropped;
} FTL_(tool_fit);

typedef struct {
    double mass, com[3], bias[6];   /* standard errors, same units */
} FTL_(tool_se);

/* Weighted Gram sum_i w_i L_i Mzz L_i^T and cross products sum_i w_i L_i Mzw_i of moments M (symmetric). */
static inline void FTL_(id_gram)(const FTL_(config) *cf, double mo[10][10], const double *w, double gram[10][10],
                                 double cross[10])
{
    int i, p, q, a, c;
    memset(gram, 0, 100 * sizeof(double));
    memset(cross, 0, 10 * sizeof(double));
    for (i = 0; i < 6; ++i) {
        const double (*l)[4] = cf->id_maps[i];
        double lm[10][4];
        for (p = 0; p < 10; ++p) {
            for (c = 0; c < 4; ++c) {
                lm[p][c] = 0.0;
                for (a = 0; a < 4; ++a) { lm[p][c] += l[p][a] * mo[a][c]; }
            }
        }
        for (p = 0; p < 10; ++p) {
            double b = 0.0;
            for (q = 0; q < 10; ++q) {
                double v = 0.0;
                for (c = 0; c < 4; ++c) { v += lm[p][c] * l[q][c]; }
                gram[p][q] += w[i] * v;
            }
            for (a = 0; a < 4; ++a) { b += l[p][a] * mo[a][4 + i]; }
            cross[p] += w[i] * b;
        }
    }
}

/* ||A theta - b||^2 of each axis from the moments alone (never below zero). */
static inline void FTL_(id_rss)(const FTL_(config) *cf, double mo[10][10], const double *theta, double *rss)
{
    int i, p, a, c;
    for (i = 0; i < 6; ++i) {
        double r[4], v = mo[4 + i][4 + i];
        for (a = 0; a < 4; ++a) {
            r[a] = 0.0;
            for (p = 0; p < 10; ++p) { r[a] += cf->id_maps[i][p][a] * theta[p]; }
        }
        for (a = 0; a < 4; ++a) {
            v -= 2.0 * r[a] * mo[a][4 + i];
            for (c = 0; c < 4; ++c) { v += r[a] * mo[a][c] * r[c]; }
        }
        rss[i] = v > 0.0 ? v : 0.0;
    }
}

/* Residual variance per axis; each axis carries n of the 6 n - p degrees of freedom (payload.identify). */
static inline void FTL_(id_axis_variance)(const FTL_(config) *cf, double mo[10][10], const double *theta, long n,
                                          int p, double *variance)
{
    double rss[6];
    int i;
    FTL_(id_rss)(cf, mo, theta, rss);
    for (i = 0; i < 6; ++i) {
        double scale = mo[4 + i][4 + i] / (double)n, least;
        least = 1e-24 * (scale > 1.0 ? scale : 1.0);
        variance[i] = rss[i] / ((double)n - (double)p / 6.0);
        if (!(variance[i] >= least)) { variance[i] = least; }
    }
}

/* Eigenvalues (and vectors, as columns) of a symmetric 10 x 10 matrix by cyclic Jacobi rotations. */
static inline void FTL_(id_eigen)(double in[10][10], double values[10], double vectors[10][10])
{
    double a[10][10];
    int i, k, p, q, sweep;
    memcpy(a, in, sizeof a);
    for (i = 0; i < 10; ++i) {
        for (k = 0; k < 10; ++k) { vectors[i][k] = i == k ? 1.0 : 0.0; }
    }
    for (sweep = 0; sweep < 50; ++sweep) {
        double off = 0.0, total = 0.0;
        for (p = 0; p < 10; ++p) {
            for (q = 0; q < 10; ++q) {
                total += a[p][q] * a[p][q];
                if (p != q) { off += a[p][q] * a[p][q]; }
            }
        }
        if (!(off > 1e-32 * total)) { break; }   /* off-diagonal below 1e-16 of the matrix (Frobenius) */
        for (p = 0; p < 9; ++p) {
            for (q = p + 1; q < 10; ++q) {
                double theta, t, c, sn;
                if (a[p][q] == 0.0) { continue; }
                theta = (a[q][q] - a[p][p]) / (2.0 * a[p][q]);
                t = fabs(theta) > 1e150 ? 0.5 / theta
                    : (theta >= 0.0 ? 1.0 : -1.0) / (fabs(theta) + sqrt(theta * theta + 1.0));
                c = 1.0 / sqrt(t * t + 1.0);
                sn = t * c;
                for (k = 0; k < 10; ++k) {
                    double x = a[k][p], y = a[k][q];
                    a[k][p] = c * x - sn * y;
                    a[k][q] = sn * x + c * y;
                }
                for (k = 0; k < 10; ++k) {
                    double x = a[p][k], y = a[q][k];
                    a[p][k] = c * x - sn * y;
                    a[q][k] = sn * x + c * y;
                }
                for (k = 0; k < 10; ++k) {
                    double x = vectors[k][p], y = vectors[k][q];
                    vectors[k][p] = c * x - sn * y;
                    vectors[k][q] = sn * x + c * y;
                }
                a[p][q] = a[q][p] = 0.0;   /* what the rotation makes it, without its rounding */
            }
        }
    }
    for (i = 0; i < 10; ++i) { values[i] = a[i][i]; }
}

/* Cholesky factor (lower) of a symmetric matrix in place; -1 at a pivot that is not positive. */
static inline int FTL_(id_cholesky)(double a[10][10])
{
    int i, j, k;
    for (j = 0; j < 10; ++j) {
        double d = a[j][j];
        for (k = 0; k < j; ++k) { d -= a[j][k] * a[j][k]; }
        if (!(d > 0.0)) { return -1; }
        a[j][j] = sqrt(d);
        for (i = j + 1; i < 10; ++i) {
            double v = a[i][j];
            for (k = 0; k < j; ++k) { v -= a[i][k] * a[j][k]; }
            a[i][j] = v / a[j][j];
        }
    }
    return 0;
}

/* Solve L L^T x = b with the factor of NAME_id_cholesky. */
static inline void FTL_(id_cholesky_solve)(double l[10][10], const double *b, double *x)
{
    int i, k;
    double y[10];
    for (i = 0; i < 10; ++i) {
        y[i] = b[i];
        for (k = 0; k < i; ++k) { y[i] -= l[i][k] * y[k]; }
        y[i] /= l[i][i];
    }
    for (i = 9; i >= 0; --i) {
        x[i] = y[i];
        for (k = i + 1; k < 10; ++k) { x[i] -= l[k][i] * x[k]; }
        x[i] /= l[i][i];
    }
}

/* Equilibrate (unit diagonal), factor, solve gram x = cross; with `check`, refuse a condition number of the
   equilibrated Gram above s->cfg.refit_condition (payload.identify._refit). 0, or -1 (x not written). */
static inline int FTL_(id_solve)(const FTL_(config) *cf, double gram[10][10], const double *cross, double *x, int check)
{
    double scale[10], a[10][10], rhs[10], z[10];
    int i, j;
    for (i = 0; i < 10; ++i) {
        if (!(gram[i][i] > 0.0)) { return -1; }
        scale[i] = 1.0 / sqrt(gram[i][i]);
    }
    for (i = 0; i < 10; ++i) {
        for (j = 0; j < 10; ++j) { a[i][j] = gram[i][j] * scale[i] * scale[j]; }
        rhs[i] = cross[i] * scale[i];
    }
    if (check) {
        double values[10], vectors[10][10], low = HUGE_VAL, high = 0.0;
        FTL_(id_eigen)(a, values, vectors);
        for (i = 0; i < 10; ++i) {
            if (fabs(values[i]) < low) { low = fabs(values[i]); }
            if (fabs(values[i]) > high) { high = fabs(values[i]); }
        }
        if (!(high <= cf->refit_condition * low)) { return -1; }
    }
    if (FTL_(id_cholesky)(a)) { return -1; }
    FTL_(id_cholesky_solve)(a, rhs, z);
    for (i = 0; i < 10; ++i) { x[i] = z[i] * scale[i]; }
    return 0;
}

/* Hold the parameters of `held` (bits) at zero: their rows and columns become the identity's, their
   cross products zero, so the others solve the system without them (payload.identify's take(keep)). */
static inline void FTL_(id_hold_at_zero)(double gram[10][10], double *cross, unsigned held)
{
    int j, k;
    for (j = 0; j < 10; ++j) {
        if (held & (1u << j)) {
            for (k = 0; k < 10; ++k) { gram[j][k] = gram[k][j] = 0.0; }
            gram[j][j] = 1.0;
            cross[j] = 0.0;
        }
    }
}

/* The moments of all holds, or of all but hold `without` (-1: none), made symmetric; returns the samples. */
static inline long FTL_(id_moments)(const FTL_(state) *s, int without, double mo[10][10])
{
    long n = 0;
    int h, j, k;
    memset(mo, 0, 100 * sizeof(double));
    for (h = 0; h < s->n_holds; ++h) {
        if (h == without) { continue; }
        for (j = 0; j < 10; ++j) {
            for (k = j; k < 10; ++k) { mo[j][k] += s->hold_moments[h][j][k]; }
        }
        n += s->hold_samples[h];
    }
    for (j = 0; j < 10; ++j) {
        for (k = 0; k < j; ++k) { mo[j][k] = mo[k][j]; }
    }
    return n;
}

static inline void FTL_(id_hold)(const FTL_(state) *s, int h, double mo[10][10])
{
    int j, k;
    for (j = 0; j < 10; ++j) {
        for (k = j; k < 10; ++k) { mo[j][k] = mo[k][j] = s->hold_moments[h][j][k]; }
    }
}

/* Put a tool identified as `tool_name` into the library (replacing a tool of that name, else in the next slot);
   with `mount`, mount it and give the bias the identified value and variance max(SE^2, noise variance)
   (finish_identification(mount=True)). Returns 0, -1 (nothing changed) for a mass of 0, numbers not finite or an
   infinite standard error (NaN, undetermined, is taken: that bias gets the noise variance), or a NAME_TOOL_* code
   for the name. */
static inline int FTL_(add_identified)(FTL_(state) *s, const char *tool_name, const FTL_(tool_fit) *tool,
                                        const FTL_(tool_se) *se, int mount)
{
    int j, index, finite = isfinite(tool->mass) && tool->mass != 0.0, status = FTL_(check_new_tool)(s, tool_name);
    FTL_(event) ev;
    for (j = 0; j < 3; ++j) { finite = finite && isfinite(tool->com[j]) && isfinite(tool->mass * tool->com[j]); }
    for (j = 0; j < 6; ++j) { finite = finite && isfinite(tool->bias[j]) && !isinf(se->bias[j] * se->bias[j]); }
    if (!finite) { return -1; }
    if (status) { return status; }
    index = FTL_(find_tool)(s, tool_name);
    if (index < 0) {   /* a new name: the next slot */
        index = s->n_tools;
        memcpy(s->tool_names[index - s->cfg.n_tools], tool_name, strlen(tool_name) + 1);
        s->n_tools += 1;
    }
    s->identifying = 0;
    s->in_hold = 0;
    s->tool_mass[index] = tool->mass;
    for (j = 0; j < 3; ++j) { s->tool_mc[index][j] = tool->mass * tool->com[j]; }
    s->tool_sign[index] = 1.0;   /* identified from the readings themselves (reaction=False) */
    FTL_(call_event)(s, FTL_M(EVENT_TOOL_IDENTIFIED), index, index, &ev);
    ev.count = tool->n_holds;
    ev.value[0] = tool->mass;
    ev.value[1] = se->mass;
    memcpy(ev.tool_name, tool_name, strlen(tool_name) + 1);
    FTL_(log_event)(s, &ev);
    if (mount) {
        FTL_(call_event)(s, FTL_M(EVENT_TOOL_SWITCHED), s->tool, index, &ev);
        FTL_(log_event)(s, &ev);
        s->tool = index;
        s->switches += 1;
        for (j = 0; j < 6; ++j) {
            double v = isnan(se->bias[j]) ? 0.0 : se->bias[j] * se->bias[j];   /* undetermined: the noise's */
            s->bias[j] = tool->bias[j];
            s->variance[j] = v > s->noise_variance[j] ? v : s->noise_variance[j];
        }
        FTL_(drift_reset)(s);   /* the bias was set on purpose: the drift test starts again */
        FTL_(sc_reset)(s);      /* and the self-check */
        s->last_fail = -HUGE_VAL;
        s->fail_start = HUGE_VAL;
        s->fail_previous = 0;
    }
    return 0;
}

/* Put the tool of the identification in progress into the library (see NAME_add_identified), as
   NAME_finish_identification does, and end the identification: call it when the finish ran on a copy of the state
   outside the real-time loop (docs/live.md). Returns 0, or -1 (nothing changed) when no identification is in
   progress or for a tool that is not one (NAME_add_identified). */
static inline int FTL_(adopt_identification)(FTL_(state) *s, const FTL_(tool_fit) *tool, const FTL_(tool_se) *se,
                                              int mount)
{
    if (!s->identifying) { return -1; }
    return FTL_(add_identified)(s, s->identifying_name, tool, se, mount);
}

/* Identify the tool from the holds collected since NAME_start_identification: mass, centre of mass and bias
   with the standard errors of LiveCalibrator.finish_identification (ftcal.payload.identify.identify_from_statistics).
   Holds past FTL_M(MAX_HOLDS) were left out (out_tool->holds_dropped counts them).
   On success (0) the tool is in the library under the name given to NAME_start_identification (NAME_find_tool
   gives its index); with `mount` it is mounted and the bias takes the
   identified value and variance (as finish_identification(mount=True)). Errors (out_tool may be partly written;
   out_tool->undetermined names the parameters the poses do not determine: on success those held at zero
   (their standard errors NaN) and the others confounded with them; on FTL_M(ID_MASS_UNDETERMINED) all):
   FTL_M(ID_NOT_IDENTIFYING)  no identification in progress;
   FTL_M(ID_TOO_FEW_HOLDS)    fewer than FTL_M(MIN_HOLDS) holds: still identifying, collect more;
   FTL_M(ID_MASS_UNDETERMINED) the poses do not determine the mass (Python refuses the same);
   FTL_M(ID_SINGULAR)         a singular solve or a mass of exactly zero.
   The last two end the identification. Cost: about 1 ms on 32 holds; call it outside a 1 kHz loop (docs/live.md). */
static inline int FTL_(finish_identification)(FTL_(state) *s, FTL_(tool_fit) *out_tool, FTL_(tool_se) *out_se,
                                               int mount)
{
    const double *t_scale = s->cfg.t_scale;
    static const double ones[6] = {1.0, 1.0, 1.0, 1.0, 1.0, 1.0};
    double mo[10][10], part[10][10], gram[10][10], cross[10], theta0[10], theta[10], variance[6], weights[6];
    double jac[10], values[10], vectors[10][10], top = 0.0, row[10], inverse[10][10], factor[10][10];
    double covariance[10][10], refits[FTL_M(MAX_HOLDS)][10], sse_ols[6], sse_wls[6], rss[6], mass;
    long n;
    int h, i, j, k, null = 0, scored = 0, g = 0, p = 10, added;   /* p: parameters estimated (not held) */
    unsigned held = 0;
    if (!s->identifying) { return FTL_M(ID_NOT_IDENTIFYING); }
    memset(out_tool, 0, sizeof *out_tool);
    memset(out_se, 0, sizeof *out_se);
    out_tool->n_holds = s->n_holds;
    out_tool->holds_dropped = s->holds_dropped;
    if (s->n_holds < FTL_M(MIN_HOLDS)) { return FTL_M(ID_TOO_FEW_HOLDS); }
    s->identifying = 0;
    s->in_hold = 0;
    n = FTL_(id_moments)(s, -1, mo);
    out_tool->n_samples = n;
    /* excitation: null space of the equilibrated Gram (payload.identify.find_undetermined) */
    FTL_(id_gram)(&s->cfg, mo, ones, gram, cross);
    for (j = 0; j < 10; ++j) {
        double unit = j >= 4 ? 1.0 : s->hold_gravity_max;
        double least = s->cfg.rounding_column * unit, d = gram[j][j];
        least = least * least * (double)n;
        if (least > d) { d = least; }
        jac[j] = 1.0 / sqrt(d > 0.0 ? d : 1.0);
    }
    for (j = 0; j < 10; ++j) {
        for (k = 0; k < 10; ++k) { part[j][k] = gram[j][k] * jac[j] * jac[k]; }
    }
    FTL_(id_eigen)(part, values, vectors);
    for (j = 0; j < 10; ++j) { if (values[j] > top) { top = values[j]; } }
    for (j = 0; j < 10; ++j) { row[j] = 0.0; }
    for (k = 0; k < 10; ++k) {
        if (values[k] <= top * s->cfg.rank_relative) {
            null += 1;
            for (j = 0; j < 10; ++j) { row[j] += vectors[j][k] * vectors[j][k]; }
        }
    }
    if (null > 0) {
        /* payload.identify._choose_held: one parameter per null direction, COM first, then torque and force
           biases, the largest pivot (the first of near-equal ones); its row is projected out of the basis */
        static const int groups[3] = {1, 7, 4};
        int it, c, cols[10], nc = 0;
        for (j = 0; j < 10; ++j) { if (sqrt(row[j]) > s->cfg.null_row) { out_tool->undetermined |= 1u << j; } }
        if ((out_tool->undetermined & 1u) || null == 10) { return FTL_M(ID_MASS_UNDETERMINED); }
        for (k = 0; k < 10; ++k) { if (values[k] <= top * s->cfg.rank_relative) { cols[nc++] = k; } }
        for (j = 0; j < 10; ++j) {
            for (c = 0; c < nc; ++c) { part[j][c] = vectors[j][cols[c]]; }
        }
        for (it = 0; it < nc; ++it) {
            int pick = -1, grp;
            double unit[10], length = 0.0;
            for (grp = 0; grp < 3 && pick < 0; ++grp) {
                double score[3], best = 0.0;
                for (j = 0; j < 3; ++j) {
                    int q = groups[grp] + j;
                    score[j] = -1.0;
                    if (held & (1u << q)) { continue; }
                    score[j] = 0.0;
                    for (c = 0; c < nc; ++c) { score[j] += part[q][c] * part[q][c]; }
                    score[j] = sqrt(score[j]);
                    if (score[j] > best) { best = score[j]; }
                }
                if (best > s->cfg.null_row) {
                    for (j = 0; j < 3 && pick < 0; ++j) {
                        if (score[j] >= best * (1.0 - s->cfg.canonical_tie)) { pick = groups[grp] + j; }
                    }
                }
            }
            if (pick < 0) { return FTL_M(ID_SINGULAR); }   /* unreachable: biases alone always have a pivot */
            held |= 1u << pick;
            p -= 1;
            for (c = 0; c < nc; ++c) { length += part[pick][c] * part[pick][c]; }
            length = sqrt(length);
            for (c = 0; c < nc; ++c) { unit[c] = part[pick][c] / length; }
            for (j = 0; j < 10; ++j) {
                double dot = 0.0;
                for (c = 0; c < nc; ++c) { dot += part[j][c] * unit[c]; }
                for (c = 0; c < nc; ++c) { part[j][c] -= dot * unit[c]; }
            }
        }
        FTL_(id_hold_at_zero)(gram, cross, held);
        out_tool->held = held;
    }
    if (FTL_(id_solve)(&s->cfg, gram, cross, theta0, 0)) { return FTL_M(ID_SINGULAR); }
    FTL_(id_axis_variance)(&s->cfg, mo, theta0, n, p, variance);
    /* weighting: per-axis 1/sigma^2 only if it predicts held-out holds no worse, and better somewhere */
    for (i = 0; i < 6; ++i) { sse_ols[i] = sse_wls[i] = 0.0; }
    for (h = 0; h < s->n_holds; ++h) {
        double train[10][10], t_ols[10], t_wls[10], v[6], w[6], fold[10][10];
        long m = FTL_(id_moments)(s, h, train);
        FTL_(id_gram)(&s->cfg, train, ones, gram, cross);
        FTL_(id_hold_at_zero)(gram, cross, held);
        if (FTL_(id_solve)(&s->cfg, gram, cross, t_ols, 1) || m * 6 - p < 6) { continue; }
        FTL_(id_axis_variance)(&s->cfg, train, t_ols, m, p, v);
        for (i = 0; i < 6; ++i) { w[i] = 1.0 / v[i]; }
        FTL_(id_gram)(&s->cfg, train, w, gram, cross);
        FTL_(id_hold_at_zero)(gram, cross, held);
        if (FTL_(id_solve)(&s->cfg, gram, cross, t_wls, 1)) { continue; }
        FTL_(id_hold)(s, h, fold);
        FTL_(id_rss)(&s->cfg, fold, t_ols, rss);
        for (i = 0; i < 6; ++i) { sse_ols[i] += rss[i]; }
        FTL_(id_rss)(&s->cfg, fold, t_wls, rss);
        for (i = 0; i < 6; ++i) { sse_wls[i] += rss[i]; }
        scored += 1;
    }
    if (scored >= 2) {
        double ratio[2] = {0.0, 0.0}, num[2] = {0.0, 0.0}, den[2] = {0.0, 0.0}, norm[2];
        for (i = 0; i < 6; ++i) { ratio[i / 3] += sse_wls[i] / (sse_ols[i] > 1e-300 ? sse_ols[i] : 1e-300) / 3.0; }
        /* and the force and torque error norms (payload.identify._choose_weighting) */
        for (i = 0; i < 6; ++i) {
            num[i / 3] += sse_wls[i];
            den[i / 3] += sse_ols[i];
        }
        for (i = 0; i < 2; ++i) { norm[i] = num[i] / (den[i] > 1e-300 ? den[i] : 1e-300); }
        out_tool->weighted = fmax(fmax(ratio[0], ratio[1]), fmax(norm[0], norm[1])) <= 1.0 + s->cfg.weighting_tie
                             && fmin(ratio[0], ratio[1]) < 1.0 - s->cfg.weighting_tie;
    }
    for (i = 0; i < 6; ++i) { weights[i] = out_tool->weighted ? 1.0 / variance[i] : 1.0; }
    FTL_(id_gram)(&s->cfg, mo, weights, gram, cross);
    FTL_(id_hold_at_zero)(gram, cross, held);
    if (FTL_(id_solve)(&s->cfg, gram, cross, theta, 0)) { return FTL_M(ID_SINGULAR); }
    /* the inverse of the equilibrated weighted Gram: variance inflation, and the classical covariance's bread */
    for (j = 0; j < 10; ++j) { jac[j] = 1.0 / sqrt(gram[j][j]); }
    for (j = 0; j < 10; ++j) {
        for (k = 0; k < 10; ++k) { factor[j][k] = gram[j][k] * jac[j] * jac[k]; }
    }
    if (FTL_(id_cholesky)(factor)) { return FTL_M(ID_SINGULAR); }
    for (k = 0; k < 10; ++k) {
        double e[10], col[10];
        for (j = 0; j < 10; ++j) { e[j] = j == k ? 1.0 : 0.0; }
        FTL_(id_cholesky_solve)(factor, e, col);
        for (j = 0; j < 10; ++j) { inverse[j][k] = col[j]; }
    }
    for (j = 0; j < 10; ++j) {
        for (k = 0; k < j; ++k) { inverse[j][k] = inverse[k][j] = 0.5 * (inverse[j][k] + inverse[k][j]); }
    }
    /* grouped jackknife over the holds (payload.identify.robust_covariance) */
    for (h = 0; h < s->n_holds; ++h) {
        double hold_gram[10][10], hold_cross[10];
        FTL_(id_hold)(s, h, part);
        FTL_(id_gram)(&s->cfg, part, weights, hold_gram, hold_cross);
        for (j = 0; j < 10; ++j) {
            hold_cross[j] = cross[j] - hold_cross[j];
            for (k = 0; k < 10; ++k) { hold_gram[j][k] = gram[j][k] - hold_gram[j][k]; }
        }
        FTL_(id_hold_at_zero)(hold_gram, hold_cross, held);
        if (FTL_(id_solve)(&s->cfg, hold_gram, hold_cross, refits[g], 1) == 0) { g += 1; }
    }
    if (g >= 2) {
        double mean[10], f = t_scale[g - 1] * t_scale[g - 1] * (double)(g - 1) / (double)g;
        for (j = 0; j < 10; ++j) {
            mean[j] = 0.0;
            for (h = 0; h < g; ++h) { mean[j] += refits[h][j]; }
            mean[j] /= (double)g;
        }
        for (j = 0; j < 10; ++j) {
            for (k = 0; k < 10; ++k) {
                double v = 0.0;
                for (h = 0; h < g; ++h) { v += (refits[h][j] - mean[j]) * (refits[h][k] - mean[k]); }
                covariance[j][k] = f * v;
            }
        }
        out_tool->jackknife_blocks = g;
    } else {   /* classical: bread meat bread, meat = sum_i w_i^2 sigma_i^2 A_i^T A_i */
        double meat[10][10], half[10][10], w2[6];
        FTL_(id_axis_variance)(&s->cfg, mo, theta, n, p, variance);
        for (i = 0; i < 6; ++i) { w2[i] = weights[i] * weights[i] * variance[i]; }
        FTL_(id_gram)(&s->cfg, mo, w2, meat, cross);
        FTL_(id_hold_at_zero)(meat, cross, held);
        for (j = 0; j < 10; ++j) { if (held & (1u << j)) { meat[j][j] = 0.0; } }
        for (j = 0; j < 10; ++j) {
            for (k = 0; k < 10; ++k) {
                double v = 0.0;
                for (i = 0; i < 10; ++i) { v += inverse[j][i] * jac[j] * jac[i] * meat[i][k]; }
                half[j][k] = v;
            }
        }
        for (j = 0; j < 10; ++j) {
            for (k = 0; k < 10; ++k) {
                double v = 0.0;
                for (i = 0; i < 10; ++i) { v += half[j][i] * inverse[i][k] * jac[i] * jac[k]; }
                covariance[j][k] = v;
            }
        }
    }
    for (j = 0; j < 10; ++j) {
        for (k = 0; k < j; ++k) { covariance[j][k] = covariance[k][j] = 0.5 * (covariance[j][k] + covariance[k][j]); }
    }
    /* held: no estimate (infinite inflation); undetermined: said once, not as poorly excited */
    for (j = 0; j < 10; ++j) {
        out_tool->variance_inflation[j] = held & (1u << j) ? HUGE_VAL : inverse[j][j];
        if (inverse[j][j] > s->cfg.excitation_limit && !(out_tool->undetermined & (1u << j))) {
            out_tool->poorly_excited |= 1u << j;
        }
    }
    FTL_(id_rss)(&s->cfg, mo, theta, rss);
    for (i = 0; i < 6; ++i) { out_tool->residual_rms[i] = sqrt(rss[i] / (double)n); }
    mass = theta[0];
    if (mass == 0.0) { return FTL_M(ID_SINGULAR); }
    out_tool->mass = mass;
    out_se->mass = sqrt(fmax(covariance[0][0], 0.0));
    for (j = 0; j < 3; ++j) {   /* c = (m c) / m: dc/dm = -c / m, dc/d(m c) = 1 / m */
        double c = theta[1 + j] / mass, a = -c / mass, b = 1.0 / mass;
        out_tool->com[j] = c;
        out_se->com[j] = sqrt(fmax(a * a * covariance[0][0] + 2.0 * a * b * covariance[0][1 + j]
                                   + b * b * covariance[1 + j][1 + j], 0.0));
    }
    for (j = 0; j < 6; ++j) {
        out_tool->bias[j] = theta[4 + j];
        out_se->bias[j] = sqrt(fmax(covariance[4 + j][4 + j], 0.0));
    }
    for (j = 1; j < 10; ++j) {   /* undetermined: no standard error (NaN), as in Python */
        if (out_tool->undetermined & (1u << j)) {
            if (j < 4) { out_se->com[j - 1] = NAN; }
            else { out_se->bias[j - 4] = NAN; }
        }
    }
    added = FTL_(add_identified)(s, s->identifying_name, out_tool, out_se, mount);   /* the name was checked */
    return added == -1 ? FTL_M(ID_SINGULAR) : added;
}


#ifndef FTCAL_LIVE_NO_TEXT
/* ----- flags as text (NAME_NO_TEXT leaves this out: it needs snprintf) ----- */
#include <stdio.h>

/* The name of flag `bit` (one of FTL_M(FLAG_)*), as ftcal.live.health.FLAGS spells it; 0 for anything else. */
static inline const char *FTL_(flag_name)(unsigned bit)
{
    static const char *const names[] = {FTL_M(FLAG_NAMES)};
    unsigned i;
    for (i = 0; i < sizeof names / sizeof names[0]; ++i) { if (bit == 1u << i) { return names[i]; } }
    return 0;
}

/* Append n bytes of text at *at, keeping room for the NUL; *at counts what the whole text needs. */
static inline void FTL_(text_put)(char *buf, size_t len, size_t *at, const char *text, size_t n)
{
    size_t k;
    for (k = 0; k < n; ++k, ++*at) { if (*at + 1 < len) { buf[*at] = text[k]; } }
}

static inline void FTL_(text_str)(char *buf, size_t len, size_t *at, const char *text)
{
    FTL_(text_put)(buf, len, at, text, strlen(text));
}

/* A number alone, as Python's format(x, spec) writes it for the specs used here (g, .3g, .4g are C's too). */
static inline void FTL_(text_num)(char *buf, size_t len, size_t *at, const char *format, double x)
{
    char t[48];
    int n = snprintf(t, sizeof t, format, x);
    FTL_(text_put)(buf, len, at, t, n > 0 ? (size_t)n : 0);
}

static inline void FTL_(text_long)(char *buf, size_t len, size_t *at, long x)
{
    char t[32];
    int n = snprintf(t, sizeof t, "%ld", x);
    FTL_(text_put)(buf, len, at, t, n > 0 ? (size_t)n : 0);
}

/* A name given at run time quoted as Python's repr quotes a str (nothing for a null pointer). */
static inline void FTL_(text_quoted)(char *buf, size_t len, size_t *at, const char *tool_name)
{
    const unsigned char *p = (const unsigned char *)tool_name;
    char quote, t[8];
    int single = 0, double_quote = 0;
    if (!p) { return; }
    for (; *p; ++p) {
        if (*p == '\'') { single = 1; }
        else if (*p == '"') { double_quote = 1; }
    }
    quote = single && !double_quote ? '"' : '\'';
    FTL_(text_put)(buf, len, at, &quote, 1);
    for (p = (const unsigned char *)tool_name; *p; ++p) {
        unsigned c = *p;
        if (c == (unsigned char)quote || c == '\\') {
            t[0] = '\\';
            t[1] = (char)c;
            FTL_(text_put)(buf, len, at, t, 2);
        } else if (c == '\n') { FTL_(text_put)(buf, len, at, "\\n", 2); }
        else if (c == '\r') { FTL_(text_put)(buf, len, at, "\\r", 2); }
        else if (c == '\t') { FTL_(text_put)(buf, len, at, "\\t", 2); }
        else if (c < 0x20u || c == 0x7fu) {
            snprintf(t, sizeof t, "\\x%02x", c);
            FTL_(text_put)(buf, len, at, t, 4);
        } else if (c == 0xc2u && ((p[1] >= 0x80u && p[1] <= 0xa0u) || p[1] == 0xadu)) {   /* not printable */
            snprintf(t, sizeof t, "\\x%02x", (unsigned)p[1]);
            FTL_(text_put)(buf, len, at, t, 4);
            ++p;
        } else {
            t[0] = (char)c;
            FTL_(text_put)(buf, len, at, t, 1);
        }
    }
    FTL_(text_put)(buf, len, at, &quote, 1);
}

/* A tool's name quoted as Python's repr quotes a str: compiled-in tools from Python itself, run-time names here. */
static inline void FTL_(text_tool)(const FTL_(state) *s, char *buf, size_t len, size_t *at, int tool)
{
    if (tool >= 0 && tool < s->cfg.n_tools) { FTL_(text_str)(buf, len, at, s->cfg.tool_reprs[tool]); }
    else { FTL_(text_quoted)(buf, len, at, FTL_(tool_name)(s, tool)); }
}

static inline void FTL_(text_channels)(const FTL_(state) *s, char *buf, size_t len, size_t *at,
                                        const unsigned char *hit)
{
    int j, first = 1;
    for (j = 0; j < s->cfg.n_channels; ++j) {
        if (hit[j]) {
            if (!first) { FTL_(text_str)(buf, len, at, ", "); }
            FTL_(text_str)(buf, len, at, FTL_(input_name)(s->cfg.channels[j]));
            first = 0;
        }
    }
}

/* The reason of a flag's `raised` event, as LiveCalibrator words it with the numbers the event keeps. */
static inline void FTL_(text_reason)(const FTL_(state) *s, const FTL_(event) *ev, char *buf, size_t len,
                                      size_t *at)
{
    unsigned bit = ev->flag;
    int j;
    if (bit == FTL_M(FLAG_SATURATED)) {
        FTL_(text_str)(buf, len, at, "channel ");
        FTL_(text_channels)(s, buf, len, at, ev->channels);
        if (ev->value[0] != 0.0) {
            FTL_(text_str)(buf, len, at, " saturated (at the ADC limits ");
            FTL_(text_num)(buf, len, at, "%g", ev->value[1]);
            FTL_(text_str)(buf, len, at, "/");
            FTL_(text_num)(buf, len, at, "%g", ev->value[2]);
            FTL_(text_str)(buf, len, at, ")");
        } else {
            FTL_(text_str)(buf, len, at, " saturated (flat for >= ");
        FTL_(text_long)(buf, len, at, s->cfg.saturation_run);
        FTL_(text_str)(buf, len, at, " samples outside the calibration's range)");
        }
    } else if (bit == FTL_M(FLAG_STUCK)) {
        FTL_(text_str)(buf, len, at, "channel ");
        FTL_(text_channels)(s, buf, len, at, ev->channels);
        FTL_(text_str)(buf, len, at, " stuck: one value for ");
        FTL_(text_long)(buf, len, at, ev->count);
        FTL_(text_str)(buf, len, at, " samples while the sensor or other channels move");
    } else if (bit == FTL_M(FLAG_DEAD)) {
        FTL_(text_str)(buf, len, at, "channel ");
        FTL_(text_channels)(s, buf, len, at, ev->channels);
        FTL_(text_str)(buf, len, at, " dead: one value for ");
        FTL_(text_long)(buf, len, at, ev->count);
        FTL_(text_str)(buf, len, at, " samples");
    } else if (bit == FTL_M(FLAG_OUT_OF_RANGE)) {
        FTL_(text_str)(buf, len, at, s->cfg.out_of_range_text);
    } else if (bit == FTL_M(FLAG_TEMPERATURE)) {
        FTL_(text_str)(buf, len, at, "temperature ");
        FTL_(text_num)(buf, len, at, "%.4g", ev->value[0]);
        FTL_(text_str)(buf, len, at, " outside the calibration's ");
        FTL_(text_num)(buf, len, at, "%.4g", s->cfg.temperature_low);
        FTL_(text_str)(buf, len, at, " to ");
        FTL_(text_num)(buf, len, at, "%.4g", s->cfg.temperature_high);
    } else if (bit == FTL_M(FLAG_CONTACT)) {
        FTL_(text_str)(buf, len, at, "wrench the tool ");
        FTL_(text_tool)(s, buf, len, at, ev->tool_from);
        FTL_(text_str)(buf, len, at, " and the bias do not explain (chi2 ");
        FTL_(text_num)(buf, len, at, "%.3g", ev->value[0]);
        FTL_(text_str)(buf, len, at, " > ");
        FTL_(text_num)(buf, len, at, "%.3g", ev->value[1]);
        FTL_(text_str)(buf, len, at, ", 6 dof); the bias is not updated");
    } else if (bit == FTL_M(FLAG_UNEXPLAINED)) {
        FTL_(text_str)(buf, len, at, "innovation beyond ");
        FTL_(text_num)(buf, len, at, "%g", ev->value[0]);
        FTL_(text_str)(buf, len, at, " sigma and the acceptance thresholds for ");
        FTL_(text_num)(buf, len, at, "%.3g", ev->value[2]);
        FTL_(text_str)(buf, len, at, " s (> ");
        FTL_(text_num)(buf, len, at, "%g", ev->value[1]);
        FTL_(text_str)(buf, len, at, " s): |compensated| = ");
        for (j = 0; j < 6; ++j) {
            if (j) { FTL_(text_str)(buf, len, at, ", "); }
            FTL_(text_num)(buf, len, at, "%.3g", fabs(ev->value[3 + j]));
        }
    } else {
        const char *flag = FTL_(flag_name)(bit);
        if (flag) { FTL_(text_str)(buf, len, at, flag); }
    }
}

/* The one-line reasons of the flags in `mask` (LiveCalibrator's, with the numbers of the sample that last raised
   each), joined by "; " in bit order; a flag never raised is its name, bits that are no flag are skipped.
   snprintf-style: writes at most len - 1 bytes and a NUL (nothing when len is 0; buf may then be 0) and returns
   the length the whole text needs, without the NUL. */
static inline size_t FTL_(describe_flags)(const FTL_(state) *s, unsigned mask, char *buf, size_t len)
{
    size_t at = 0;
    unsigned i;
    int first = 1;
    for (i = 0; i < 32; ++i) {
        unsigned bit = 1u << i;
        const char *flag = FTL_(flag_name)(bit);
        if (!(mask & bit) || !flag) { continue; }
        if (!first) { FTL_(text_str)(buf, len, &at, "; "); }
        first = 0;
        if (!(s->raised_ever & bit)) { FTL_(text_str)(buf, len, &at, flag); }
        else { FTL_(text_reason)(s, &s->last_raised[i], buf, len, &at); }
    }
    if (len > 0) { buf[at < len ? at : len - 1] = '\0'; }
    return at;
}
#endif /* FTCAL_LIVE_NO_TEXT */


#ifndef FTCAL_LIVE_NO_TEXT
/* Six standard deviations sqrt(v * scale) as "%.3g" joined by ", " (the self-check's texts). */
static inline void FTL_(text_stds)(char *buf, size_t len, size_t *at, const double *v, double scale)
{
    int j;
    for (j = 0; j < 6; ++j) {
        if (j) { FTL_(text_str)(buf, len, at, ", "); }
        FTL_(text_num)(buf, len, at, "%.3g", sqrt(v[j] * scale));
    }
}

/* The kind of an event as LiveCalibrator's events spell it ("switched", "identifying", "identified", "retare",
   "raised", "cleared"); 0 for a value that is no FTL_M(EVENT_)*. */
static inline const char *FTL_(event_kind_name)(int kind)
{
    static const char *const names[] = {FTL_M(EVENT_KIND_NAMES)};
    return kind >= 1 && kind <= (int)(sizeof names / sizeof names[0]) ? names[kind - 1] : 0;
}

/* The event's one-line text, as LiveCalibrator's reason for it (the fourth field of its events); an event of a
   kind that is no FTL_M(EVENT_)* gives "". snprintf-style: at most len - 1 bytes and a NUL (nothing when len is
   0; buf may then be 0); returns the length the whole text needs, without the NUL. */
static inline size_t FTL_(describe_event)(const FTL_(state) *s, const FTL_(event) *ev, char *buf, size_t len)
{
    size_t at = 0;
    const char *flag = FTL_(flag_name)(ev->flag);
    switch (ev->kind) {
    case FTL_M(EVENT_TOOL_SWITCHED):
        FTL_(text_str)(buf, len, &at, "tool ");
        FTL_(text_tool)(s, buf, len, &at, ev->tool_from);
        FTL_(text_str)(buf, len, &at, " -> ");
        FTL_(text_tool)(s, buf, len, &at, ev->tool_to);
        break;
    case FTL_M(EVENT_TOOL_IDENTIFYING):
        FTL_(text_str)(buf, len, &at, "identifying tool ");
        if (ev->tool_to >= 0 && ev->tool_to < s->cfg.n_tools) { FTL_(text_tool)(s, buf, len, &at, ev->tool_to); }
        else { FTL_(text_quoted)(buf, len, &at, ev->tool_name); }
        FTL_(text_str)(buf, len, &at, ": hold the sensor still in varied poses");
        break;
    case FTL_M(EVENT_TOOL_IDENTIFIED):
        FTL_(text_str)(buf, len, &at, "tool ");
        FTL_(text_tool)(s, buf, len, &at, ev->tool_to);
        FTL_(text_str)(buf, len, &at, " identified from ");
        FTL_(text_long)(buf, len, &at, ev->count);
        FTL_(text_str)(buf, len, &at, " holds: ");
        FTL_(text_num)(buf, len, &at, "%.4g", ev->value[0]);
        FTL_(text_str)(buf, len, &at, s->cfg.plus_minus);
        FTL_(text_num)(buf, len, &at, "%.2g", ev->value[1]);
        FTL_(text_str)(buf, len, &at, " kg");
        break;
    case FTL_M(EVENT_RETARE):
        FTL_(text_str)(buf, len, &at, "re-tare with tool ");
        FTL_(text_tool)(s, buf, len, &at, ev->tool_from);
        FTL_(text_str)(buf, len, &at, " kept: the next static samples set the bias");
        if (ev->flag & (FTL_M(FLAG_CONTACT) | FTL_M(FLAG_UNEXPLAINED))) {  /* the flags raised at the re-tare */
            FTL_(text_str)(buf, len, &at, "; re-tare while ");
            if (ev->flag & FTL_M(FLAG_CONTACT)) { FTL_(text_str)(buf, len, &at, "contact"); }
            if ((ev->flag & FTL_M(FLAG_CONTACT)) && (ev->flag & FTL_M(FLAG_UNEXPLAINED))) {
                FTL_(text_str)(buf, len, &at, " and ");
            }
            if (ev->flag & FTL_M(FLAG_UNEXPLAINED)) { FTL_(text_str)(buf, len, &at, "unexplained"); }
            FTL_(text_str)(buf, len, &at, s->cfg.retare_warning);
        }
        break;
    case FTL_M(EVENT_FLAG_RAISED):
        if (flag) { FTL_(text_reason)(s, ev, buf, len, &at); }
        break;
    case FTL_M(EVENT_FLAG_CLEARED):
        if (flag) {
            FTL_(text_str)(buf, len, &at, flag);
            FTL_(text_str)(buf, len, &at, " cleared");
        }
        break;
    case FTL_M(EVENT_ROLLBACK):
        FTL_(text_str)(buf, len, &at, "the bias moved up to ");
        FTL_(text_num)(buf, len, &at, "%.3g", ev->value[2]);
        FTL_(text_str)(buf, len, &at, " in ");
        FTL_(text_num)(buf, len, &at, "%.3g", ev->value[0]);
        FTL_(text_str)(buf, len, &at, " s, more than the random walk allows (chi2 ");
        FTL_(text_num)(buf, len, &at, "%.3g", ev->value[1]);
        FTL_(text_str)(buf, len, &at, ", 6 dof): a slow contact or a faster drift; bias and variance back to their "
                                      "values then, predicted since");
        break;
    case FTL_M(EVENT_TRACKER_ADAPTED):
        if (ev->count > 0) {   /* q matched over the moves */
            FTL_(text_str)(buf, len, &at, "the residual changed over the last ");
            FTL_(text_long)(buf, len, &at, ev->count);
            FTL_(text_str)(buf, len, &at, " moves by ");
            FTL_(text_num)(buf, len, &at, "%.3g", ev->value[0]);
            FTL_(text_str)(buf, len, &at, "x the walk allowed (median, covariance matching): walk std now ");
            FTL_(text_stds)(buf, len, &at, ev->extra, 3600.0);
            FTL_(text_str)(buf, len, &at, " per sqrt(h) (within 1 to 10x the identified)");
        } else {               /* r matched over a window */
            if (ev->value[1] >= (double)s->cfg.sc_min_window_samples) {
                FTL_(text_str)(buf, len, &at, "NIS mean ");
                FTL_(text_num)(buf, len, &at, "%.3g", ev->value[0]);
                FTL_(text_str)(buf, len, &at, " over ");
                FTL_(text_long)(buf, len, &at, (long)ev->value[1]);
                FTL_(text_str)(buf, len, &at, " static samples (expected 6), ");
            } else {
                FTL_(text_long)(buf, len, &at, (long)ev->value[1]);
                FTL_(text_str)(buf, len, &at, " static samples updated (too few for the NIS; r from the differences of ");
                FTL_(text_long)(buf, len, &at, (long)ev->value[2]);
                FTL_(text_str)(buf, len, &at, " consecutive static samples), ");
            }
            FTL_(text_num)(buf, len, &at, "%.2g", 100.0 * ev->value[3]);
            FTL_(text_str)(buf, len, &at, " % of static samples gated (expected ");
            FTL_(text_num)(buf, len, &at, "%.2g", 100.0 * ev->value[4]);
            FTL_(text_str)(buf, len, &at, " %): noise std ");
            FTL_(text_stds)(buf, len, &at, ev->extra, 1.0);
            FTL_(text_str)(buf, len, &at, " (covariance matching, within 1 to 5x the identified)");
        }
        break;
    case FTL_M(EVENT_TRACKER_LOCKED_OUT):
        FTL_(text_str)(buf, len, &at, "no bias update for ");
        FTL_(text_num)(buf, len, &at, "%.3g", ev->value[0]);
        FTL_(text_str)(buf, len, &at, " s of static samples: a held contact, or a bias that moved faster than the walk "
                                      "allows; re-acquired when a hold in another orientation shows the same residual");
        break;
    case FTL_M(EVENT_TRACKER_REACQUIRED):
        FTL_(text_str)(buf, len, &at, "the residual held alike (changed by ");
        FTL_(text_num)(buf, len, &at, "%.2g", 100.0 * ev->value[0]);
        FTL_(text_str)(buf, len, &at, " % of itself) over two holds ");
        FTL_(text_num)(buf, len, &at, "%.3g", ev->value[1]);
        FTL_(text_str)(buf, len, &at, " deg apart in gravity direction: bias, not contact; bias moved by up to ");
        FTL_(text_num)(buf, len, &at, "%.3g", ev->value[2]);
        FTL_(text_str)(buf, len, &at, ", walk std now ");
        FTL_(text_stds)(buf, len, &at, ev->extra, 3600.0);
        FTL_(text_str)(buf, len, &at, " per sqrt(h)");
        break;
    case FTL_M(EVENT_TRACKER_UNDONE):
        FTL_(text_str)(buf, len, &at, "the rollback at ");
        FTL_(text_num)(buf, len, &at, "%.6g", ev->value[0]);
        FTL_(text_str)(buf, len, &at, " s is within the walk matched since: bias back to before it");
        break;
    default:
        break;
    }
    if (len > 0) { buf[at < len ? at : len - 1] = '\0'; }
    return at;
}
#endif /* FTCAL_LIVE_NO_TEXT */


#undef FTL_RARE
#undef FTL_M
#undef FTL_
#undef FTL_CAT
#undef FTL_CAT2
