/*
 * ftcal.live._core: the live step's C core (csrc/ftcal_live.h) as a CPython extension.
 *
 * The same source `ftcal convert --to c-runtime` ships, compiled here with the prefix ftcal_core and maximum
 * sizes (the configuration says how many inputs, channels and tools there are). The model is evaluated by
 * Python's kernels; the core takes the raw channels, the wrench they give and gravity per sample. One call steps a
 * whole block (the GIL released), so a block of samples costs one Python call.
 *
 * Python side: ftcal.live.core (the configuration is ftcal.live.c_runtime.core_config's dict). Optional: without
 * a C compiler the build skips it and ftcal.live.core says how to build it.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>

#include <stddef.h>

#define FTCAL_CORE_N_INPUTS 32
#define FTCAL_CORE_N_CHANNELS 32
#define FTCAL_CORE_N_TOOLS 32
#define FTCAL_CORE_MAX_ADDED_TOOLS 1
#define FTCAL_CORE_MAX_TOOLS (FTCAL_CORE_N_TOOLS + FTCAL_CORE_MAX_ADDED_TOOLS)
#define FTCAL_CORE_MAX_TOOL_NAME 63
#define FTCAL_CORE_MAX_HOLDS 32
#define FTCAL_CORE_MIN_HOLDS 3
#define FTCAL_CORE_MAX_MAGNITUDE 1e100
#define FTCAL_CORE_HISTORY 1024
#define FTCAL_CORE_DRIFT_LAGS 4
#define FTCAL_CORE_N_FLAGS 8
#define FTCAL_CORE_MAX_EVENTS 256
/* run() pauses when fewer than this many slots are left (a sample logs at most 8 flag events and 6 of the tracker)
   so that Python reads every event (take_events) before the ring would overwrite one */
#define EVENTS_PER_SAMPLE 16
/* the codes: ftcal.live.core checks them against the Python constants (health.BIT, c_events, c_identify) */
#define FTCAL_CORE_FLAG_SATURATED 1u
#define FTCAL_CORE_FLAG_STUCK 2u
#define FTCAL_CORE_FLAG_DEAD 4u
#define FTCAL_CORE_FLAG_OUT_OF_RANGE 8u
#define FTCAL_CORE_FLAG_TEMPERATURE 16u
#define FTCAL_CORE_FLAG_CONTACT 32u
#define FTCAL_CORE_FLAG_UNEXPLAINED 64u
#define FTCAL_CORE_FLAG_SILENT 128u
#define FTCAL_CORE_EVENT_TOOL_SWITCHED 1
#define FTCAL_CORE_EVENT_TOOL_IDENTIFYING 2
#define FTCAL_CORE_EVENT_TOOL_IDENTIFIED 3
#define FTCAL_CORE_EVENT_RETARE 4
#define FTCAL_CORE_EVENT_FLAG_RAISED 5
#define FTCAL_CORE_EVENT_FLAG_CLEARED 6
#define FTCAL_CORE_EVENT_ROLLBACK 7
#define FTCAL_CORE_EVENT_TRACKER_ADAPTED 8
#define FTCAL_CORE_EVENT_TRACKER_LOCKED_OUT 9
#define FTCAL_CORE_EVENT_TRACKER_REACQUIRED 10
#define FTCAL_CORE_EVENT_TRACKER_UNDONE 11
#define FTCAL_CORE_ID_OK (0)
#define FTCAL_CORE_ID_NOT_IDENTIFYING (-1)
#define FTCAL_CORE_ID_TOO_FEW_HOLDS (-2)
#define FTCAL_CORE_ID_MASS_UNDETERMINED (-3)
#define FTCAL_CORE_ID_SINGULAR (-4)
#define FTCAL_CORE_TOOL_OK (0)
#define FTCAL_CORE_TOOL_NO_NAME (-5)
#define FTCAL_CORE_TOOL_NAME_TOO_LONG (-6)
#define FTCAL_CORE_TOOL_NAME_RESERVED (-7)
#define FTCAL_CORE_TOOL_LIBRARY_FULL (-8)

#define FTCAL_LIVE_PREFIX ftcal_core
#define FTCAL_LIVE_MACRO FTCAL_CORE
#define FTCAL_LIVE_NO_TEXT
#include "ftcal_live.h"

/* The configuration's numeric fields, by name: (offset, kind, rows, columns) with the C's row stride. */
enum { REAL = 0, INT = 1, LONG = 2 };
typedef struct {
    const char *name;
    size_t offset;
    int kind;
    Py_ssize_t rows, columns, stride;   /* a scalar is 1 x 1; columns -1: n_inputs (a square of the inputs) */
} Field;

#define F(field, kind, rows, columns, stride) {#field, offsetof(ftcal_core_config, field), kind, rows, columns, stride}
#define NI FTCAL_CORE_N_INPUTS
#define NC FTCAL_CORE_N_CHANNELS
#define NT FTCAL_CORE_N_TOOLS
static const Field FIELDS[] = {
    F(n_inputs, INT, 1, 1, 1), F(n_channels, INT, 1, 1, 1), F(n_tools, INT, 1, 1, 1),
    F(channels, INT, 1, NC, NC), F(channel_range, REAL, NC, 2, 2),
    F(input_low, REAL, 1, NI, NI), F(input_high, REAL, 1, NI, NI),
    F(temperature, INT, 1, 1, 1), F(temperature_low, REAL, 1, 1, 1), F(temperature_high, REAL, 1, 1, 1),
    F(has_span, INT, 1, 1, 1), F(span_mean, REAL, 1, NI, NI), F(span_unit, REAL, 1, NI, NI),
    F(span_values, REAL, 1, NI, NI), F(span_vectors, REAL, NI, -1, NI), F(span_kept, INT, 1, NI, NI),
    F(span_off, REAL, 1, 1, 1), F(span_limit, REAL, 1, 1, 1),
    F(tool_mass, REAL, 1, NT, NT), F(tool_mc, REAL, NT, 3, 3), F(tool_sign, REAL, 1, NT, NT),
    F(noise_variance, REAL, 1, 6, 6), F(walk_variance, REAL, 1, 6, 6), F(accept_limit, REAL, 1, 6, 6),
    F(gate_chi2, REAL, 1, 1, 1), F(drift_chi2, REAL, 1, 1, 1), F(gate_probability, REAL, 1, 1, 1),
    F(unexplained_sigma, REAL, 1, 1, 1), F(unexplained_seconds, REAL, 1, 1, 1), F(motion_window, REAL, 1, 1, 1),
    F(min_rate, REAL, 1, 1, 1), F(min_hold, REAL, 1, 1, 1), F(retare_variance, REAL, 1, 1, 1),
    F(holdoff, REAL, 1, 1, 1), F(min_fail_s, REAL, 1, 1, 1), F(snapshot_s, REAL, 1, 1, 1),
    F(lags, REAL, 1, FTCAL_CORE_DRIFT_LAGS, FTCAL_CORE_DRIFT_LAGS),
    F(stuck_run, LONG, 1, 1, 1), F(dead_run, LONG, 1, 1, 1), F(saturation_run, LONG, 1, 1, 1),
    F(load_steps, REAL, 1, 1, 1),
    F(sc_lock_s, REAL, 1, 1, 1), F(sc_min_hold_s, REAL, 1, 1, 1), F(sc_min_turn_deg, REAL, 1, 1, 1),
    F(sc_turn_share, REAL, 1, 1, 1), F(sc_correlation_s, REAL, 1, 1, 1), F(sc_window_s, REAL, 1, 1, 1),
    F(sc_min_window_samples, LONG, 1, 1, 1), F(sc_r_max, REAL, 1, 1, 1), F(sc_q_max, REAL, 1, 1, 1),
    F(sc_nis_factor, REAL, 1, 1, 1), F(sc_gated_factor, REAL, 1, 1, 1), F(sc_diff_cap, REAL, 1, 1, 1),
    F(sc_min_walk_starts, LONG, 1, 1, 1), F(sc_min_walk_share, REAL, 1, 1, 1), F(sc_walk_factor, REAL, 1, 1, 1),
    F(sc_chi2_6_median, REAL, 1, 1, 1),
    F(rank_relative, REAL, 1, 1, 1), F(rounding_column, REAL, 1, 1, 1), F(null_row, REAL, 1, 1, 1),
    F(canonical_tie, REAL, 1, 1, 1), F(weighting_tie, REAL, 1, 1, 1), F(refit_condition, REAL, 1, 1, 1),
    F(excitation_limit, REAL, 1, 1, 1), F(id_maps, REAL, 60, 4, 4),
    F(t_scale, REAL, 1, FTCAL_CORE_MAX_HOLDS, FTCAL_CORE_MAX_HOLDS),
    F(wander_density, REAL, 1, 6, 6),
};
#undef F

/* The settings of the state (the fields NAME_init sets from the configuration and the caller may change). */
typedef struct {
    const char *name;
    size_t offset;
    int count;
} Setting;

#define S(field, count) {#field, offsetof(ftcal_core_state, field), count}
static const Setting SETTINGS[] = {
    S(noise_variance, 6), S(walk_variance, 6), S(gate_chi2, 1), S(drift_chi2, 1), S(accept_limit, 6),
    S(unexplained_sigma, 1), S(unexplained_seconds, 1), S(motion_window, 1), S(min_rate, 1), S(min_hold, 1),
    S(adc_low, 1), S(adc_high, 1), S(bias, 6), S(variance, 6), S(tool_mass, NT), S(tool_sign, NT), S(holdoff, 1),
    S(wander_density, 6),
};
#undef S

typedef struct {
    PyObject_HEAD
    ftcal_core_state *state;
    /* the calibration model for step_raw (set_model): a monomial basis evaluated by a table, as ftcal.core's kernels
       read it (ftcal.core.kernels.step_table); n_terms 0: none */
    Py_ssize_t n_model_inputs, n_terms, n_steps;
    double *offset, *inv_scale, *coef, *terms;   /* coef: (6, n_terms) row-major; terms: n_terms */
    int64_t *steps;                                /* (n_steps, 4): input, source row, destination row, rows */
} Core;

static void free_model(Core *self)
{
    PyMem_Free(self->offset);   /* one block: offset, inv_scale, coef, terms */
    PyMem_Free(self->steps);
    self->offset = self->inv_scale = self->coef = self->terms = NULL;
    self->steps = NULL;
    self->n_terms = self->n_steps = self->n_model_inputs = 0;
}

/* One field of the configuration from a sequence of numbers (flattened, row-major, rows x columns at most). */
static int set_field(ftcal_core_config *config, const Field *f, PyObject *value)
{
    PyObject *seq = PySequence_Fast(value, f->name);
    Py_ssize_t n, k, cols;
    char *base = (char *)config + f->offset;
    if (!seq) {
        return -1;
    }
    n = PySequence_Fast_GET_SIZE(seq);
    cols = f->columns > 0 ? f->columns : config->n_inputs;
    if (n > f->rows * cols) {
        PyErr_Format(PyExc_ValueError, "configuration field %s: %zd values, at most %zd", f->name, n,
                     f->rows * cols);
        Py_DECREF(seq);
        return -1;
    }
    for (k = 0; k < n; ++k) {
        PyObject *item = PySequence_Fast_GET_ITEM(seq, k);
        Py_ssize_t at = (k / cols) * f->stride + k % cols;
        if (f->kind == REAL) {
            double x = PyFloat_AsDouble(item);
            if (x == -1.0 && PyErr_Occurred()) {
                Py_DECREF(seq);
                return -1;
            }
            ((double *)base)[at] = x;
        } else {
            long x = PyLong_AsLong(item);
            if (x == -1 && PyErr_Occurred()) {
                Py_DECREF(seq);
                return -1;
            }
            if (f->kind == INT) {
                ((int *)base)[at] = (int)x;
            } else {
                ((long *)base)[at] = x;
            }
        }
    }
    Py_DECREF(seq);
    return 0;
}

static int Core_init(Core *self, PyObject *args, PyObject *kwargs)
{
    static char *keywords[] = {"config", "tool", NULL};
    PyObject *dict;
    int tool = 0;
    size_t i;
    ftcal_core_config config;
    if (!PyArg_ParseTupleAndKeywords(args, kwargs, "O!|i", keywords, &PyDict_Type, &dict, &tool)) {
        return -1;
    }
    memset(&config, 0, sizeof config);
    for (i = 0; i < sizeof FIELDS / sizeof FIELDS[0]; ++i) {
        PyObject *value = PyDict_GetItemString(dict, FIELDS[i].name), *list;
        int rc;
        if (!value) {
            PyErr_Format(PyExc_KeyError, "the configuration has no %s", FIELDS[i].name);
            return -1;
        }
        list = PyObject_CallMethod(value, "tolist", NULL);   /* flat numpy arrays, numpy scalars */
        if (!list) {
            PyErr_Clear();
            list = value;
            Py_INCREF(list);
        }
        if (!PyList_Check(list) && !PyTuple_Check(list)) {
            PyObject *one = PyTuple_Pack(1, list);
            Py_DECREF(list);
            list = one;
            if (!list) {
                return -1;
            }
        }
        rc = set_field(&config, &FIELDS[i], list);
        Py_DECREF(list);
        if (rc) {
            return -1;
        }
    }
    if (config.n_inputs < 1 || config.n_inputs > FTCAL_CORE_N_INPUTS || config.n_channels < 1
        || config.n_channels > FTCAL_CORE_N_CHANNELS || config.n_tools < 1 || config.n_tools > FTCAL_CORE_N_TOOLS) {
        PyErr_Format(PyExc_ValueError, "the core takes 1 to %d inputs and channels and 1 to %d tools",
                     FTCAL_CORE_N_INPUTS, FTCAL_CORE_N_TOOLS);
        return -1;
    }
    if (!self->state) {
        self->state = (ftcal_core_state *)PyMem_Calloc(1, sizeof *self->state);
        if (!self->state) {
            PyErr_NoMemory();
            return -1;
        }
    }
    if (ftcal_core_core_init(self->state, &config, tool)) {
        PyErr_Format(PyExc_ValueError, "tool index %d is not in the configuration's %d tools", tool, config.n_tools);
        return -1;
    }
    return 0;
}

static void Core_dealloc(Core *self)
{
    free_model(self);
    PyMem_Free(self->state);
    Py_TYPE(self)->tp_free((PyObject *)self);
}

/* run(time, u, w, gravity, override, out) -> (samples stepped k, refused): k < n with refused 0 when the event ring
   needs reading (take_events, then run the rest), refused 1 when sample k was refused (state as before it) */
static PyObject *Core_run(Core *self, PyObject *args)
{
    Py_buffer t, u, w, g, o, out;
    Py_ssize_t n, k = 0, ni = self->state->cfg.n_inputs;
    int bad = 0, refused = 0;
    if (!PyArg_ParseTuple(args, "y*y*y*y*y*w*", &t, &u, &w, &g, &o, &out)) {
        return NULL;
    }
    n = t.len / (Py_ssize_t)sizeof(double);
    if (u.len != n * ni * (Py_ssize_t)sizeof(double) || w.len != n * 6 * (Py_ssize_t)sizeof(double)
        || g.len != n * 3 * (Py_ssize_t)sizeof(double) || o.len != n * (Py_ssize_t)sizeof(int32_t)
        || out.len != n * 27 * (Py_ssize_t)sizeof(double)) {
        bad = 1;
    } else {
        const double *tp = (const double *)t.buf, *up = (const double *)u.buf, *wp = (const double *)w.buf;
        const double *gp = (const double *)g.buf;
        const int32_t *op = (const int32_t *)o.buf;
        double *r = (double *)out.buf;
        Py_BEGIN_ALLOW_THREADS
        for (k = 0; k < n; ++k) {
            ftcal_core_output x;
            int j;
            if (self->state->events_count > FTCAL_CORE_MAX_EVENTS - EVENTS_PER_SAMPLE) {
                break;
            }
            if (ftcal_core_core_step(self->state, tp[k], up + ni * k, wp + 6 * k, gp + 3 * k, op[k], &x)) {
                refused = 1;
                break;
            }
            for (j = 0; j < 6; ++j) {
                r[27 * k + j] = x.calibrated[j];
                r[27 * k + 6 + j] = x.compensated[j];
                r[27 * k + 12 + j] = x.bias[j];
                r[27 * k + 18 + j] = x.bias_std[j];
            }
            r[27 * k + 24] = x.chi2;
            r[27 * k + 25] = x.is_static + 2 * x.updated;
            r[27 * k + 26] = x.flags;
        }
        Py_END_ALLOW_THREADS
    }
    PyBuffer_Release(&t);
    PyBuffer_Release(&u);
    PyBuffer_Release(&w);
    PyBuffer_Release(&g);
    PyBuffer_Release(&o);
    PyBuffer_Release(&out);
    if (bad) {
        PyErr_SetString(PyExc_ValueError, "run: buffers of n samples: time, u (n x n_inputs), w (n x 6), "
                                          "gravity (n x 3) float64, override int32, out (n x 27) float64");
        return NULL;
    }
    return Py_BuildValue("(ni)", k, refused);
}

/* n doubles from a C-contiguous float64 buffer (a numpy row) or a sequence of numbers; -1 with an exception set */
static int read_doubles(PyObject *obj, Py_ssize_t n, double *dst)
{
    Py_buffer b;
    PyObject *seq;
    Py_ssize_t k;
    if (PyObject_CheckBuffer(obj) && PyObject_GetBuffer(obj, &b, PyBUF_C_CONTIGUOUS | PyBUF_FORMAT) == 0) {
        int ok = b.len == n * (Py_ssize_t)sizeof(double) && b.format && strcmp(b.format, "d") == 0;
        if (ok) {
            memcpy(dst, b.buf, (size_t)n * sizeof(double));
        }
        PyBuffer_Release(&b);
        if (ok) {
            return 0;
        }
    }
    PyErr_Clear();
    seq = PySequence_Fast(obj, "a sequence of numbers");
    if (!seq) {
        return -1;
    }
    if (PySequence_Fast_GET_SIZE(seq) != n) {
        Py_DECREF(seq);
        PyErr_Format(PyExc_ValueError, "%zd numbers expected", n);
        return -1;
    }
    for (k = 0; k < n; ++k) {
        dst[k] = PyFloat_AsDouble(PySequence_Fast_GET_ITEM(seq, k));
        if (dst[k] == -1.0 && PyErr_Occurred()) {
            Py_DECREF(seq);
            return -1;
        }
    }
    Py_DECREF(seq);
    return 0;
}

/* One sample's output in run()'s 27 columns. */
static void write_output(const ftcal_core_output *x, double *r)
{
    int j;
    for (j = 0; j < 6; ++j) {
        r[j] = x->calibrated[j];
        r[6 + j] = x->compensated[j];
        r[12 + j] = x->bias[j];
        r[18 + j] = x->bias_std[j];
    }
    r[24] = x->chi2;
    r[25] = x->is_static + 2 * x->updated;
    r[26] = x->flags;
}

/* step(time, u, w, gravity, override, out) -> events logged (0 usually), or -1: refused, state as before. One sample
   with the least Python around it: u (n_inputs), w (6), gravity (3) numpy rows or sequences; out a float64 buffer of
   27 (run()'s columns). */
static PyObject *Core_step(Core *self, PyObject *const *args, Py_ssize_t nargs)
{
    double time, u[FTCAL_CORE_N_INPUTS], w[6], g[3];
    long override;
    Py_buffer out;
    ftcal_core_output x;
    int rc;
    if (nargs != 6) {
        PyErr_SetString(PyExc_TypeError, "step(time, u, w, gravity, override, out)");
        return NULL;
    }
    time = PyFloat_AsDouble(args[0]);
    override = PyLong_AsLong(args[4]);
    if (PyErr_Occurred() || read_doubles(args[1], self->state->cfg.n_inputs, u) || read_doubles(args[2], 6, w)
        || read_doubles(args[3], 3, g)) {
        return NULL;
    }
    if (PyObject_GetBuffer(args[5], &out, PyBUF_WRITABLE | PyBUF_C_CONTIGUOUS) < 0) {
        return NULL;
    }
    if (out.len != 27 * (Py_ssize_t)sizeof(double)) {
        PyBuffer_Release(&out);
        PyErr_SetString(PyExc_ValueError, "step: out takes 27 float64");
        return NULL;
    }
    rc = ftcal_core_core_step(self->state, time, u, w, g, (int)override, &x);
    if (rc == 0) {
        write_output(&x, (double *)out.buf);
    }
    PyBuffer_Release(&out);
    return PyLong_FromLong(rc ? -1 : self->state->events_count);
}

/* set_model(offset, inv_scale, coef, steps): the model step_raw evaluates. offset, inv_scale: float64 (n_inputs,) of
   the input normalisation; coef: float64 (6, n_terms), the last term the constant; steps: int64 (n_steps, 4). */
static PyObject *Core_set_model(Core *self, PyObject *args)
{
    Py_buffer o, v, c, st;
    Py_ssize_t nu, p, ns, k;
    int bad = 0;
    if (!PyArg_ParseTuple(args, "y*y*y*y*", &o, &v, &c, &st)) {
        return NULL;
    }
    nu = o.len / (Py_ssize_t)sizeof(double);
    p = c.len / (Py_ssize_t)sizeof(double) / 6;
    ns = st.len / (Py_ssize_t)(4 * sizeof(int64_t));
    if (v.len != o.len || c.len != 6 * p * (Py_ssize_t)sizeof(double) || nu < 1 || nu >= self->state->cfg.n_inputs + 1
        || p <= nu) {
        bad = 1;
    }
    for (k = 0; !bad && k < ns; ++k) {   /* every row read and written inside the terms, the constant excluded */
        const int64_t *x = (const int64_t *)st.buf + 4 * k;
        if (x[0] < 0 || x[0] >= nu || x[3] < 0 || x[1] < 0 || x[1] + x[3] > p - 1 || x[2] < nu || x[2] + x[3] > p - 1) {
            bad = 1;
        }
    }
    if (!bad) {
        free_model(self);
        self->offset = (double *)PyMem_Malloc((size_t)(2 * nu + 7 * p) * sizeof(double));
        self->steps = (int64_t *)PyMem_Malloc((size_t)(4 * ns + 1) * sizeof(int64_t));
        if (!self->offset || !self->steps) {
            free_model(self);
            bad = 2;
        } else {
            self->inv_scale = self->offset + nu;
            self->coef = self->inv_scale + nu;
            self->terms = self->coef + 6 * p;
            memcpy(self->offset, o.buf, (size_t)nu * sizeof(double));
            memcpy(self->inv_scale, v.buf, (size_t)nu * sizeof(double));
            memcpy(self->coef, c.buf, (size_t)(6 * p) * sizeof(double));
            memcpy(self->steps, st.buf, (size_t)(4 * ns) * sizeof(int64_t));
            self->n_model_inputs = nu;
            self->n_terms = p;
            self->n_steps = ns;
        }
    }
    PyBuffer_Release(&o);
    PyBuffer_Release(&v);
    PyBuffer_Release(&c);
    PyBuffer_Release(&st);
    if (bad == 2) {
        return PyErr_NoMemory();
    }
    if (bad) {
        PyErr_SetString(PyExc_ValueError, "set_model: offset, inv_scale (n_inputs), coef (6 x n_terms), steps "
                                          "(n_steps x 4) within the terms");
        return NULL;
    }
    Py_RETURN_NONE;
}

/* The model's wrench for the raw inputs u (set_model's table): the normalised inputs, each step's products, the
   constant, then the coefficients' sums in term order (ftcal.core's predict kernel's arithmetic on one row). */
static void evaluate_model(Core *self, const double *u, double *w)
{
    Py_ssize_t i, s, p = self->n_terms;
    double *x = self->terms;
    for (i = 0; i < self->n_model_inputs; ++i) {
        x[i] = (u[i] - self->offset[i]) * self->inv_scale[i];
    }
    for (s = 0; s < self->n_steps; ++s) {
        const int64_t *st = self->steps + 4 * s;
        double xi = x[st[0]];
        int64_t r;
        for (r = 0; r < st[3]; ++r) {
            x[st[2] + r] = x[st[1] + r] * xi;
        }
    }
    x[p - 1] = 1.0;
    {   /* the six sums side by side: each adds its terms in term order as one sum alone would (the same numbers),
           but six independent chains instead of one chain of 6p dependent additions (about 4x faster) */
        const double *c0 = self->coef, *c1 = c0 + p, *c2 = c1 + p, *c3 = c2 + p, *c4 = c3 + p, *c5 = c4 + p;
        double s0 = 0.0, s1 = 0.0, s2 = 0.0, s3 = 0.0, s4 = 0.0, s5 = 0.0;
        for (i = 0; i < p; ++i) {
            double xi = x[i];
            s0 += c0[i] * xi;
            s1 += c1[i] * xi;
            s2 += c2[i] * xi;
            s3 += c3[i] * xi;
            s4 += c4[i] * xi;
            s5 += c5[i] * xi;
        }
        w[0] = s0; w[1] = s1; w[2] = s2; w[3] = s3; w[4] = s4; w[5] = s5;
    }
}

/* step_raw(time, u, gravity, override, out): step() with the wrench of set_model's model for u (the core's inputs;
   the model reads the first of them) evaluated in the same call. Returns as step(). */
static PyObject *Core_step_raw(Core *self, PyObject *const *args, Py_ssize_t nargs)
{
    double time, u[FTCAL_CORE_N_INPUTS], w[6], g[3];
    long override;
    Py_buffer out;
    ftcal_core_output x;
    int j, rc;
    if (nargs != 5) {
        PyErr_SetString(PyExc_TypeError, "step_raw(time, u, gravity, override, out)");
        return NULL;
    }
    if (self->n_terms == 0) {
        PyErr_SetString(PyExc_ValueError, "step_raw: no model (set_model)");
        return NULL;
    }
    time = PyFloat_AsDouble(args[0]);
    override = PyLong_AsLong(args[3]);
    if (PyErr_Occurred() || read_doubles(args[1], self->state->cfg.n_inputs, u) || read_doubles(args[2], 3, g)) {
        return NULL;
    }
    for (j = 0; j < self->state->cfg.n_inputs; ++j) {   /* as the core: a refused input evaluates nothing */
        if (!(fabs(u[j]) <= FTCAL_CORE_MAX_MAGNITUDE)) {
            return PyLong_FromLong(-1);
        }
    }
    if (PyObject_GetBuffer(args[4], &out, PyBUF_WRITABLE | PyBUF_C_CONTIGUOUS) < 0) {
        return NULL;
    }
    if (out.len != 27 * (Py_ssize_t)sizeof(double)) {
        PyBuffer_Release(&out);
        PyErr_SetString(PyExc_ValueError, "step_raw: out takes 27 float64");
        return NULL;
    }
    evaluate_model(self, u, w);
    rc = ftcal_core_core_step(self->state, time, u, w, g, (int)override, &x);
    if (rc == 0) {
        write_output(&x, (double *)out.buf);
    }
    PyBuffer_Release(&out);
    return PyLong_FromLong(rc ? -1 : self->state->events_count);
}

/* The type sample() and sample_quaternion() return (LiveSample: a tuple subclass), set once by set_sample_type. */
static PyObject *sample_type = NULL;

static PyObject *set_sample_type(PyObject *Py_UNUSED(module), PyObject *type)
{
    if (!PyType_Check(type) || !PyType_IsSubtype((PyTypeObject *)type, &PyTuple_Type)) {
        PyErr_SetString(PyExc_TypeError, "set_sample_type: a tuple subclass");
        return NULL;
    }
    Py_INCREF(type);
    Py_XSETREF(sample_type, type);
    Py_RETURN_NONE;
}

/* (sample, flags, events logged): sample an instance of sample_type, (time, static, updated, {}, tool, bytearray of
   24 float64: calibrated, compensated, bias, bias_std); the caller fills the dict when flags are raised. */
static PyObject *sample_result(Core *self, double time, const ftcal_core_output *x, PyObject *tool)
{
    PyObject *buf, *sample, *result, *item[5];
    double *r;
    int j;
    if (!sample_type) {
        PyErr_SetString(PyExc_RuntimeError, "sample: set_sample_type first");
        return NULL;
    }
    if (!(buf = PyByteArray_FromStringAndSize(NULL, 24 * (Py_ssize_t)sizeof(double)))) {
        return NULL;
    }
    r = (double *)PyByteArray_AS_STRING(buf);
    for (j = 0; j < 6; ++j) {
        r[j] = x->calibrated[j];
        r[6 + j] = x->compensated[j];
        r[12 + j] = x->bias[j];
        r[18 + j] = x->bias_std[j];
    }
    item[0] = PyFloat_FromDouble(time);
    item[1] = PyBool_FromLong(x->is_static);
    item[2] = PyBool_FromLong(x->updated);
    item[3] = PyDict_New();
    sample = ((PyTypeObject *)sample_type)->tp_alloc((PyTypeObject *)sample_type, 6);
    result = PyTuple_New(3);
    if (!item[0] || !item[3] || !sample || !result) {
        Py_XDECREF(item[0]);
        Py_DECREF(item[1]);
        Py_DECREF(item[2]);
        Py_XDECREF(item[3]);
        Py_XDECREF(sample);
        Py_XDECREF(result);
        Py_DECREF(buf);
        return NULL;
    }
    for (j = 0; j < 4; ++j) {
        PyTuple_SET_ITEM(sample, j, item[j]);
    }
    Py_INCREF(tool);
    PyTuple_SET_ITEM(sample, 4, tool);
    PyTuple_SET_ITEM(sample, 5, buf);
    PyTuple_SET_ITEM(result, 0, sample);
    PyTuple_SET_ITEM(result, 1, PyLong_FromLong((long)x->flags));
    PyTuple_SET_ITEM(result, 2, PyLong_FromLong(self->state->events_count));
    if (!PyTuple_GET_ITEM(result, 1) || !PyTuple_GET_ITEM(result, 2)) {
        Py_DECREF(result);
        return NULL;
    }
    return result;
}

/* sample(time, u, raw, gravity, gravity_sign, last, temperature, fill, override, tool) -> None, or sample_result's
   (sample, flags, events logged). LiveCalibrator.step's common call in one C call: u the n_inputs - 1 raw channels
   (raw true: the wrench of set_model's model for them) or the wrench; gravity (3) times gravity_sign (-1: an
   accelerometer); the core's last input the temperature u[temperature] or, for temperature -1, fill. None, nothing changed, for input it does not take (not numbers, the wrong count,
   not finite, too large, time not after last (None: any), zero gravity): the caller's own path says why. */
static PyObject *Core_sample(Core *self, PyObject *const *args, Py_ssize_t nargs)
{
    double time, u[FTCAL_CORE_N_INPUTS], w[6], g[3], sign, fill;
    long raw, temperature, override;
    ftcal_core_output x;
    int j, n;
    if (nargs != 10) {
        PyErr_SetString(PyExc_TypeError, "sample(time, u, raw, gravity, gravity_sign, last, temperature, fill, "
                                         "override, tool)");
        return NULL;
    }
    n = self->state->cfg.n_inputs - 1;
    time = PyFloat_AsDouble(args[0]);
    raw = PyLong_AsLong(args[2]);
    sign = PyFloat_AsDouble(args[4]);
    temperature = PyLong_AsLong(args[6]);
    fill = PyFloat_AsDouble(args[7]);
    override = PyLong_AsLong(args[8]);
    if (PyErr_Occurred() || (raw && self->n_terms == 0) || (!raw && (n != 6 || temperature >= 0))
        || temperature >= n || read_doubles(args[1], n, u) || read_doubles(args[3], 3, g)) {
        PyErr_Clear();
        Py_RETURN_NONE;
    }
    if (args[5] != Py_None) {
        double last = PyFloat_AsDouble(args[5]);
        if (PyErr_Occurred()) {
            PyErr_Clear();
            Py_RETURN_NONE;
        }
        if (!(time > last)) {
            Py_RETURN_NONE;
        }
    }
    u[n] = temperature >= 0 ? u[temperature] : fill;
    for (j = 0; j < 3; ++j) {
        g[j] *= sign;
    }
    if (raw) {
        for (j = 0; j <= n; ++j) {   /* as the core: a refused input evaluates nothing */
            if (!(fabs(u[j]) <= FTCAL_CORE_MAX_MAGNITUDE)) {
                Py_RETURN_NONE;
            }
        }
        evaluate_model(self, u, w);
    } else {
        memcpy(w, u, sizeof w);
    }
    if (ftcal_core_core_step(self->state, time, u, w, g, (int)override, &x)) {
        Py_RETURN_NONE;
    }
    return sample_result(self, time, &x, args[9]);
}

/* sample_quaternion(time, wrench, quaternion, last, fill, gravity_magnitude, tolerance, motion, tool) -> as sample().
   LiveCalibrator.step's call with a wrench and an orientation quaternion (x y z w, sensor to world, world z up):
   the quaternion normalised (None beyond tolerance of unit length) and gravity from it in the Python path's
   arithmetic; when the core would take the sample, the motion test motion(time, "quaternion", unit quaternion) ->
   (static, moving) decides static, then the step (the temperature input: fill). */
static PyObject *Core_sample_quaternion(Core *self, PyObject *const *args, Py_ssize_t nargs)
{
    static PyObject *kind = NULL;
    double time, u[FTCAL_CORE_N_INPUTS], q[4], g[3], norm, gm, fill, tolerance;
    ftcal_core_output x;
    PyObject *decision;
    int j, still;
    if (nargs != 9) {
        PyErr_SetString(PyExc_TypeError, "sample_quaternion(time, wrench, quaternion, last, fill, gravity_magnitude, "
                                         "tolerance, motion, tool)");
        return NULL;
    }
    if (!kind && !(kind = PyUnicode_InternFromString("quaternion"))) {
        return NULL;
    }
    time = PyFloat_AsDouble(args[0]);
    fill = PyFloat_AsDouble(args[4]);
    gm = -PyFloat_AsDouble(args[5]);
    tolerance = PyFloat_AsDouble(args[6]);
    if (PyErr_Occurred() || self->state->cfg.n_inputs != 7 || read_doubles(args[1], 6, u)
        || read_doubles(args[2], 4, q)) {
        PyErr_Clear();
        Py_RETURN_NONE;
    }
    if (args[3] != Py_None) {
        double last = PyFloat_AsDouble(args[3]);
        if (PyErr_Occurred()) {
            PyErr_Clear();
            Py_RETURN_NONE;
        }
        if (!(time > last)) {
            Py_RETURN_NONE;
        }
    }
    norm = sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
    if (!(fabs(norm - 1.0) <= tolerance)) {
        Py_RETURN_NONE;
    }
    for (j = 0; j < 4; ++j) {
        q[j] = q[j] / norm;
    }
    g[0] = gm * (2.0 * (q[0] * q[2] - q[3] * q[1]));
    g[1] = gm * (2.0 * (q[1] * q[2] + q[3] * q[0]));
    g[2] = gm * (1.0 - 2.0 * (q[0] * q[0] + q[1] * q[1]));
    u[6] = fill;
    /* what the core would refuse, before the motion test keeps the sample (its history then as the Python path's) */
    for (j = 0; j < 7; ++j) {
        if (!(fabs(u[j]) <= FTCAL_CORE_MAX_MAGNITUDE)) {
            Py_RETURN_NONE;
        }
    }
    if (!isfinite(time)) {
        Py_RETURN_NONE;
    }
    decision = PyObject_CallFunction(args[7], "dO(dddd)", time, kind, q[0], q[1], q[2], q[3]);
    if (!decision) {
        return NULL;
    }
    still = PyTuple_Check(decision) && PyTuple_GET_SIZE(decision) >= 1 ? PyObject_IsTrue(PyTuple_GET_ITEM(decision, 0))
                                                                         : -1;
    Py_DECREF(decision);
    if (still < 0) {
        if (!PyErr_Occurred()) {
            PyErr_SetString(PyExc_TypeError, "sample_quaternion: motion must return (static, moving)");
        }
        return NULL;
    }
    if (ftcal_core_core_step(self->state, time, u, u, g, still, &x)) {
        Py_RETURN_NONE;
    }
    return sample_result(self, time, &x, args[8]);
}

/* take_events() -> list of (kind, time, sample, flag, count, channels, value, extra): the events logged since the
   last call (oldest first), the ring emptied */
static PyObject *Core_take_events(Core *self, PyObject *Py_UNUSED(ignored))
{
    ftcal_core_state *s = self->state;
    PyObject *list = PyList_New(s->events_count);
    int i, j;
    if (!list) {
        return NULL;
    }
    for (i = 0; i < s->events_count; ++i) {
        const ftcal_core_event *ev = &s->events[(s->events_start + i) % FTCAL_CORE_MAX_EVENTS];
        PyObject *channels = PyTuple_New(s->cfg.n_channels), *value = PyTuple_New(9), *extra = PyTuple_New(6), *item;
        if (!channels || !value || !extra) {
            Py_XDECREF(channels);
            Py_XDECREF(value);
            Py_XDECREF(extra);
            Py_DECREF(list);
            return NULL;
        }
        for (j = 0; j < s->cfg.n_channels; ++j) {
            PyTuple_SET_ITEM(channels, j, PyBool_FromLong(ev->channels[j]));
        }
        for (j = 0; j < 9; ++j) {
            PyTuple_SET_ITEM(value, j, PyFloat_FromDouble(ev->value[j]));
        }
        for (j = 0; j < 6; ++j) {
            PyTuple_SET_ITEM(extra, j, PyFloat_FromDouble(ev->extra[j]));
        }
        item = Py_BuildValue("(idkIlNNN)", ev->kind, ev->time, ev->sample, ev->flag, ev->count, channels, value,
                             extra);
        if (!item) {
            Py_DECREF(list);
            return NULL;
        }
        PyList_SET_ITEM(list, i, item);
    }
    ftcal_core_clear_events(s);
    return list;
}

/* mount(mass, mc, sign): the mounted tool's gravity terms (Python keeps the library: the core one slot) */
static PyObject *Core_mount(Core *self, PyObject *args)
{
    double mass, mc0, mc1, mc2, sign;
    ftcal_core_state *s = self->state;
    if (!PyArg_ParseTuple(args, "d(ddd)d", &mass, &mc0, &mc1, &mc2, &sign)) {
        return NULL;
    }
    s->tool_mass[s->tool] = mass;
    s->tool_mc[s->tool][0] = mc0;
    s->tool_mc[s->tool][1] = mc1;
    s->tool_mc[s->tool][2] = mc2;
    s->tool_sign[s->tool] = sign;
    Py_RETURN_NONE;
}

/* identifying(on): bias updates and the contact and unexplained flags pause (Python collects the holds) */
static PyObject *Core_identifying(Core *self, PyObject *args)
{
    int on;
    if (!PyArg_ParseTuple(args, "p", &on)) {
        return NULL;
    }
    self->state->identifying = on;
    self->state->in_hold = 0;
    self->state->n_holds = 0;
    Py_RETURN_NONE;
}

/* adc_limits(low, high) or adc_limits(None): saturated at the ADC limits, or beyond the training range */
static PyObject *Core_adc_limits(Core *self, PyObject *args)
{
    double low = 0.0, high = 0.0;
    PyObject *first;
    if (PyTuple_GET_SIZE(args) == 1 && (first = PyTuple_GET_ITEM(args, 0)) == Py_None) {
        self->state->use_adc_limits = 0;
        Py_RETURN_NONE;
    }
    if (!PyArg_ParseTuple(args, "dd", &low, &high)) {
        return NULL;
    }
    self->state->use_adc_limits = 1;
    self->state->adc_low = low;
    self->state->adc_high = high;
    Py_RETURN_NONE;
}

static PyObject *Core_restart_checks(Core *self, PyObject *Py_UNUSED(ignored))
{
    ftcal_core_restart_checks(self->state);
    Py_RETURN_NONE;
}

/* set_clock(time) or set_clock(None): the time of the last sample (a state resumed), or none */
static PyObject *Core_set_clock(Core *self, PyObject *args)
{
    PyObject *value;
    double time;
    if (!PyArg_ParseTuple(args, "O", &value)) {
        return NULL;
    }
    if (value == Py_None) {
        self->state->has_time = 0;
        Py_RETURN_NONE;
    }
    time = PyFloat_AsDouble(value);
    if (time == -1.0 && PyErr_Occurred()) {
        return NULL;
    }
    self->state->has_time = 1;
    self->state->last_time = time;
    Py_RETURN_NONE;
}

static PyObject *Core_restart_clock(Core *self, PyObject *Py_UNUSED(ignored))
{
    ftcal_core_restart_clock(self->state);
    Py_RETURN_NONE;
}

/* state() -> bytes: the whole state (plain data, its configuration included); set_state(bytes) puts one back */
static PyObject *Core_state(Core *self, PyObject *Py_UNUSED(ignored))
{
    return PyBytes_FromStringAndSize((const char *)self->state, (Py_ssize_t)sizeof *self->state);
}

static PyObject *Core_set_state(Core *self, PyObject *args)
{
    Py_buffer b;
    if (!PyArg_ParseTuple(args, "y*", &b)) {
        return NULL;
    }
    if (b.len != (Py_ssize_t)sizeof *self->state) {
        PyBuffer_Release(&b);
        PyErr_Format(PyExc_ValueError, "set_state: %zd bytes, the state has %zd", b.len,
                     (Py_ssize_t)sizeof *self->state);
        return NULL;
    }
    memcpy(self->state, b.buf, sizeof *self->state);
    PyBuffer_Release(&b);
    Py_RETURN_NONE;
}

static const Setting *find_setting(const char *name)
{
    size_t i;
    for (i = 0; i < sizeof SETTINGS / sizeof SETTINGS[0]; ++i) {
        if (strcmp(SETTINGS[i].name, name) == 0) {
            return &SETTINGS[i];
        }
    }
    PyErr_Format(PyExc_KeyError, "no setting %s", name);
    return NULL;
}

/* get(name) -> tuple of floats: a setting of the state */
static PyObject *Core_get(Core *self, PyObject *args)
{
    const char *name;
    const Setting *s;
    PyObject *result;
    int i;
    if (!PyArg_ParseTuple(args, "s", &name) || !(s = find_setting(name))) {
        return NULL;
    }
    result = PyTuple_New(s->count);
    for (i = 0; result && i < s->count; ++i) {
        PyTuple_SET_ITEM(result, i, PyFloat_FromDouble(((double *)((char *)self->state + s->offset))[i]));
    }
    return result;
}

/* set(name, values): a setting of the state (as many values as it has) */
static PyObject *Core_set(Core *self, PyObject *args)
{
    const char *name;
    const Setting *s;
    PyObject *values, *seq;
    int i;
    if (!PyArg_ParseTuple(args, "sO", &name, &values) || !(s = find_setting(name))) {
        return NULL;
    }
    seq = PySequence_Fast(values, "set: a sequence of numbers");
    if (!seq) {
        return NULL;
    }
    if (PySequence_Fast_GET_SIZE(seq) != s->count) {
        PyErr_Format(PyExc_ValueError, "setting %s takes %d values", name, s->count);
        Py_DECREF(seq);
        return NULL;
    }
    for (i = 0; i < s->count; ++i) {
        double x = PyFloat_AsDouble(PySequence_Fast_GET_ITEM(seq, i));
        if (x == -1.0 && PyErr_Occurred()) {
            Py_DECREF(seq);
            return NULL;
        }
        ((double *)((char *)self->state + s->offset))[i] = x;
    }
    Py_DECREF(seq);
    Py_RETURN_NONE;
}

static PyObject *Core_retare(Core *self, PyObject *Py_UNUSED(ignored))
{
    return PyLong_FromLong(ftcal_core_retare(self->state));
}

static PyObject *Core_set_tool(Core *self, PyObject *args)
{
    int tool;
    if (!PyArg_ParseTuple(args, "i", &tool)) {
        return NULL;
    }
    if (ftcal_core_set_tool(self->state, tool)) {
        PyErr_Format(PyExc_ValueError, "tool index %d is not in the library", tool);
        return NULL;
    }
    Py_RETURN_NONE;
}

/* counters() -> dict: the state's counts (samples, updates, ..., the drift test's and the self-check's) */
static PyObject *Core_counters(Core *self, PyObject *Py_UNUSED(ignored))
{
    const ftcal_core_state *s = self->state;
    return Py_BuildValue("{s:k,s:k,s:k,s:k,s:k,s:k,s:k,s:k,s:k,s:k,s:I,s:i}", "samples", s->samples, "updates",
                         s->updates, "contacts", s->contacts, "retares", s->retares, "switches", s->switches,
                         "rollbacks", s->rollbacks, "adaptations", s->sc_adaptations, "lockouts", s->sc_lockouts,
                         "reacquisitions", s->sc_reacquisitions, "undone", s->sc_undone, "flags", s->flags,
                         "tool", s->tool);
}

static PyObject *Core_set_self_check(Core *self, PyObject *args)
{
    int on;
    if (!PyArg_ParseTuple(args, "p", &on)) {
        return NULL;
    }
    if (on) {
        ftcal_core_enable_self_check(self->state);
    } else {
        self->state->self_check = 0;
    }
    Py_RETURN_NONE;
}

static PyMethodDef Core_methods[] = {
    {"run", (PyCFunction)Core_run, METH_VARARGS, "run(time, u, w, gravity, override, out) -> samples stepped"},
    {"get", (PyCFunction)Core_get, METH_VARARGS, "get(name) -> the setting's values"},
    {"set", (PyCFunction)Core_set, METH_VARARGS, "set(name, values)"},
    {"retare", (PyCFunction)Core_retare, METH_NOARGS, "retare() -> the contact flags raised now"},
    {"set_tool", (PyCFunction)Core_set_tool, METH_VARARGS, "set_tool(index)"},
    {"counters", (PyCFunction)Core_counters, METH_NOARGS, "counters() -> dict"},
    {"set_self_check", (PyCFunction)Core_set_self_check, METH_VARARGS, "set_self_check(on)"},
    {"step", (PyCFunction)(void (*)(void))Core_step, METH_FASTCALL, "step(time, u, w, gravity, override, out)"},
    {"set_model", (PyCFunction)Core_set_model, METH_VARARGS, "set_model(offset, inv_scale, coef, steps)"},
    {"step_raw", (PyCFunction)(void (*)(void))Core_step_raw, METH_FASTCALL, "step_raw(time, u, gravity, override, out)"},
    {"sample", (PyCFunction)(void (*)(void))Core_sample, METH_FASTCALL,
     "sample(time, u, raw, gravity, gravity_sign, last, temperature, fill, override, tool) -> None or (sample, flags, "
     "events)"},
    {"sample_quaternion", (PyCFunction)(void (*)(void))Core_sample_quaternion, METH_FASTCALL,
     "sample_quaternion(time, wrench, quaternion, last, fill, gravity_magnitude, tolerance, motion, tool) -> as "
     "sample"},
    {"take_events", (PyCFunction)Core_take_events, METH_NOARGS, "take_events() -> the events since the last call"},
    {"mount", (PyCFunction)Core_mount, METH_VARARGS, "mount(mass, (mc_x, mc_y, mc_z), sign)"},
    {"identifying", (PyCFunction)Core_identifying, METH_VARARGS, "identifying(on)"},
    {"adc_limits", (PyCFunction)Core_adc_limits, METH_VARARGS, "adc_limits(low, high) or adc_limits(None)"},
    {"restart_checks", (PyCFunction)Core_restart_checks, METH_NOARGS, "restart_checks()"},
    {"restart_clock", (PyCFunction)Core_restart_clock, METH_NOARGS, "restart_clock()"},
    {"set_clock", (PyCFunction)Core_set_clock, METH_VARARGS, "set_clock(time or None)"},
    {"state", (PyCFunction)Core_state, METH_NOARGS, "state() -> bytes"},
    {"set_state", (PyCFunction)Core_set_state, METH_VARARGS, "set_state(bytes)"},
    {NULL, NULL, 0, NULL},
};

static PyTypeObject CoreType = {
    PyVarObject_HEAD_INIT(NULL, 0)
    .tp_name = "ftcal.live._core.Core",
    .tp_doc = "The live step's C core (csrc/ftcal_live.h): Core(config, tool=0), config from core_config().",
    .tp_basicsize = sizeof(Core),
    .tp_flags = Py_TPFLAGS_DEFAULT,
    .tp_new = PyType_GenericNew,
    .tp_init = (initproc)Core_init,
    .tp_dealloc = (destructor)Core_dealloc,
    .tp_methods = Core_methods,
};

static PyMethodDef module_methods[] = {
    {"set_sample_type", set_sample_type, METH_O, "set_sample_type(type): the tuple subclass sample() returns"},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module = {
    .m_base = PyModuleDef_HEAD_INIT,
    .m_name = "ftcal.live._core",
    .m_doc = "The live step's C core (csrc/ftcal_live.h) for ftcal.live.core.",
    .m_size = -1,
    .m_methods = module_methods,
};

PyMODINIT_FUNC PyInit__core(void)
{
    PyObject *m;
    if (PyType_Ready(&CoreType) < 0) {
        return NULL;
    }
    m = PyModule_Create(&module);
    if (!m) {
        return NULL;
    }
    Py_INCREF(&CoreType);
    if (PyModule_AddObject(m, "Core", (PyObject *)&CoreType) < 0
        || PyModule_AddIntConstant(m, "MAX_INPUTS", FTCAL_CORE_N_INPUTS) < 0
        || PyModule_AddIntConstant(m, "MAX_TOOLS", FTCAL_CORE_N_TOOLS) < 0
        || PyModule_AddIntConstant(m, "DRIFT_SNAPSHOTS", FTCAL_LIVE_DRIFT_SNAPSHOTS) < 0
        || PyModule_AddIntConstant(m, "SC_KEEP_HOLDS", FTCAL_LIVE_SC_KEEP_HOLDS) < 0
        || PyModule_AddIntConstant(m, "SC_WALK_KEEP", FTCAL_LIVE_SC_WALK_KEEP) < 0
        || PyModule_AddIntConstant(m, "MAX_HOLDS", FTCAL_CORE_MAX_HOLDS) < 0) {
        Py_DECREF(&CoreType);
        Py_DECREF(m);
        return NULL;
    }
    return m;
}
