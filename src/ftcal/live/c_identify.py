"""Identification in place for the generated C runtime (:mod:`ftcal.live.c_runtime`).

The C of :meth:`ftcal.live.LiveCalibrator.start_identification` / ``finish_identification``: while
identifying, each static hold's moments ``Σ z zᵀ`` of ``z = (g, 1, w)`` (gravity in sensor axes, the
calibrated wrench) go into a fixed array of :data:`~ftcal.core.limits.C_RUNTIME_MAX_HOLDS` holds; the
bias filter and the contact and unexplained flags pause, as in Python. ``NAME_finish_identification``
then runs what :func:`ftcal.payload.identify.identify_payload` runs for that call (static parameters
θ = [m, m·c, force bias, torque bias], ``weighting="auto"``, the holds as clusters, no
cross-validation), on fixed-size 10 × 10 matrices:

- the rank test of :func:`~ftcal.payload.identify.find_undetermined` (eigenvalues of the equilibrated
  Gram by cyclic Jacobi, the same threshold and floor): the mass undetermined is refused as in Python;
  other undetermined parameters are named in a bit mask, and as many as the null space has dimensions
  are held at zero in Python's order (``_choose_held``: COM first, then torque, then force biases,
  largest pivot), the others estimated on the remaining columns; their standard errors are NaN;
- OLS or per-axis WLS chosen by held-out error over the holds (``_choose_weighting``), the refits
  with ``_refit``'s condition-number test (1e12);
- the grouped-jackknife covariance over the holds, t-scaled (``robust_covariance``), else the
  classical one; variance inflation factors; the COM's standard error by the delta method.

Every number of the method (thresholds, the t quantiles, the regressor's maps) is emitted from the
Python constants it mirrors; nothing from a file reaches this C.
"""

from __future__ import annotations

import math

import numpy as np

from ..core.directions import CANONICAL_TIE
from ..core.jackknife import t_scale
from ..payload.accumulate import _static_maps
from ..payload.identify import _REFIT_CONDITION, EXCITATION_LIMIT, NULL_ROW, ROUNDING_COLUMN, WEIGHTING_TIE
from ..runtime.errors import FtcalError

# find_undetermined's null-eigenvalue threshold, relative to the largest (Spectrum.rank_threshold for p = 10).
RANK_RELATIVE = float(np.finfo(float).eps * max(10, 10) * 10)

# Status codes of NAME_finish_identification (the C's #defines; tests and docs read them here).
STATUS = {"OK": 0, "NOT_IDENTIFYING": -1, "TOO_FEW_HOLDS": -2, "MASS_UNDETERMINED": -3, "SINGULAR": -4}
# Return codes of the tool library (NAME_start_identification, NAME_adopt_identification), NAME_TOOL_* in the C.
TOOL_STATUS = {"OK": 0, "NO_NAME": -5, "NAME_TOO_LONG": -6, "NAME_RESERVED": -7, "LIBRARY_FULL": -8}


def _num(x: float) -> str:
    """A double literal that round-trips; infinities as ``HUGE_VAL``."""
    x = float(x)
    if math.isnan(x):
        raise FtcalError("the model has a NaN where a number is needed; refusing to generate code.")
    if math.isinf(x):
        return "HUGE_VAL" if x > 0 else "(-HUGE_VAL)"
    text = format(x, ".17g")
    return text if any(ch in text for ch in ".en") else text + ".0"


def _array(values) -> str:
    return "{" + ", ".join(_num(v) for v in np.ravel(values)) + "}"


def state_fields(macro: str) -> str:
    """The identification fields of the state struct."""
    return f"""    /* identification in place (NAME_start_identification / NAME_finish_identification) */
    int identifying, in_hold;    /* in_hold: 0 moving, 1 collecting into the last hold, 2 a hold past the limit */
    int n_holds;
    unsigned long holds_dropped; /* holds past {macro}_MAX_HOLDS, left out of the identification */
    long hold_samples[{macro}_MAX_HOLDS];
    double hold_moments[{macro}_MAX_HOLDS][10][10];   /* sum of z z^T, z = (g, 1, w); upper triangle */
    double hold_gravity_max;     /* max |g component| over the collected samples */
    char identifying_name[{macro}_MAX_TOOL_NAME + 1];   /* the tool being identified */"""


def collect_text(name: str, macro: str) -> str:
    """The C that starts an identification and collects its holds (before NAME_step, which calls it)."""
    return f"""
/* ----- identification in place: collecting the holds ----- */

/* Start collecting static holds for the tool `tool_name` (the previous collection is dropped). While identifying,
   the bias is not updated and the contact and unexplained flags are not raised (the tool is unknown). On success
   the tool joins the library under that name: a name the library has is replaced (it keeps its index, and if it
   is mounted the new tool is), a new one takes the next slot. Returns {macro}_TOOL_OK (0), or, nothing changed:
   {macro}_TOOL_NO_NAME (a null pointer or an empty name), {macro}_TOOL_NAME_TOO_LONG (more than
   {macro}_MAX_TOOL_NAME bytes), {macro}_TOOL_NAME_RESERVED ("none", tool 0), {macro}_TOOL_LIBRARY_FULL (a new name
   and {macro}_MAX_ADDED_TOOLS tools added already). */
static inline int {name}_start_identification({name}_state *s, const char *tool_name)
{{
    int status = {name}_check_new_tool(s, tool_name), index;
    {name}_event ev;
    if (status) return status;
    index = {name}_find_tool(s, tool_name);   /* -1 for a new name */
    {name}_call_event(s, {macro}_EVENT_TOOL_IDENTIFYING, index, index, &ev);
    memcpy(ev.tool_name, tool_name, strlen(tool_name) + 1);
    {name}_log_event(s, &ev);
    memcpy(s->identifying_name, tool_name, strlen(tool_name) + 1);
    s->identifying = 1;
    s->in_hold = 0;
    s->n_holds = 0;
    s->holds_dropped = 0;
    s->hold_gravity_max = 0.0;
    return {macro}_TOOL_OK;
}}

/* End the collection without a tool (the bias filter and the flags resume). */
static inline void {name}_stop_identification({name}_state *s)
{{
    s->identifying = 0;
    s->in_hold = 0;
}}

/* One sample of the identification: called by NAME_step. */
static inline void {name}_collect({name}_state *s, int still, const double *g, const double *w)
{{
    double z[10], (*m)[10];
    int j, k;
    if (!still) {{
        s->in_hold = 0;
        return;
    }}
    if (!s->in_hold) {{
        if (s->n_holds == {macro}_MAX_HOLDS) {{
            s->in_hold = 2;
            s->holds_dropped += 1;
        }} else {{
            s->in_hold = 1;
            memset(s->hold_moments[s->n_holds], 0, sizeof s->hold_moments[0]);
            s->hold_samples[s->n_holds] = 0;
            s->n_holds += 1;
        }}
    }}
    if (s->in_hold != 1) return;
    for (j = 0; j < 3; ++j) {{
        z[j] = g[j];
        if (fabs(g[j]) > s->hold_gravity_max) s->hold_gravity_max = fabs(g[j]);
    }}
    z[3] = 1.0;
    for (j = 0; j < 6; ++j) z[4 + j] = w[j];
    m = s->hold_moments[s->n_holds - 1];
    for (j = 0; j < 10; ++j)
        for (k = j; k < 10; ++k) m[j][k] += z[j] * z[k];
    s->hold_samples[s->n_holds - 1] += 1;
}}

"""


def finish_text(name: str, macro: str, max_holds: int) -> str:
    """The C of ``NAME_finish_identification``, its result types and status codes (after NAME_step)."""
    maps = _static_maps()  # (6, 10, 4): axis i's regressor row is maps[i] @ (g, 1)
    scales = [t_scale(d) for d in range(1, max_holds)]
    status = "\n".join(f"#define {macro}_ID_{key} ({value})" for key, value in STATUS.items())
    return f"""
/* ----- identification in place: the estimator ----- */
{status}

typedef struct {{
    double mass;             /* kg */
    double com[3];           /* m, sensor axes */
    double bias[6];          /* the bias during the holds: force (N) then torque (N m) */
    double residual_rms[6];  /* per axis, N and N m */
    double variance_inflation[10];   /* theta order: m, m cx, m cy, m cz, Fx .. Tz bias */
    unsigned poorly_excited; /* bit j: variance inflation of theta_j > {_num(EXCITATION_LIMIT)} (Python warns) */
    unsigned undetermined;   /* bit j: theta_j lies in a direction the poses do not determine */
    unsigned held;           /* bit j: theta_j held at 0 to pick one solution (a subset of undetermined) */
    int weighted;            /* 1: per-axis weighting kept by held-out evidence, 0: plain least squares */
    int jackknife_blocks;    /* grouped-jackknife standard errors: the holds that could be left out; 0: classical */
    int n_holds;
    long n_samples;
    unsigned long holds_dropped;
}} {name}_tool_fit;

typedef struct {{
    double mass, com[3], bias[6];   /* standard errors, same units */
}} {name}_tool_se;

/* Axis i's static regressor row is L[i] (g, 1): F = m g + f_b, T = (m c) x g + t_b. */
static const double {name}_id_maps[6][10][4] = {{{', '.join('{' + ', '.join(_array(r) for r in axis) + '}'
                                                       for axis in maps)}}};

/* Weighted Gram sum_i w_i L_i Mzz L_i^T and cross products sum_i w_i L_i Mzw_i of moments M (symmetric). */
static inline void {name}_id_gram(double mo[10][10], const double *w, double gram[10][10], double cross[10])
{{
    int i, p, q, a, c;
    memset(gram, 0, 100 * sizeof(double));
    memset(cross, 0, 10 * sizeof(double));
    for (i = 0; i < 6; ++i) {{
        const double (*l)[4] = {name}_id_maps[i];
        double lm[10][4];
        for (p = 0; p < 10; ++p)
            for (c = 0; c < 4; ++c) {{
                lm[p][c] = 0.0;
                for (a = 0; a < 4; ++a) lm[p][c] += l[p][a] * mo[a][c];
            }}
        for (p = 0; p < 10; ++p) {{
            double b = 0.0;
            for (q = 0; q < 10; ++q) {{
                double v = 0.0;
                for (c = 0; c < 4; ++c) v += lm[p][c] * l[q][c];
                gram[p][q] += w[i] * v;
            }}
            for (a = 0; a < 4; ++a) b += l[p][a] * mo[a][4 + i];
            cross[p] += w[i] * b;
        }}
    }}
}}

/* ||A theta - b||^2 of each axis from the moments alone (never below zero). */
static inline void {name}_id_rss(double mo[10][10], const double *theta, double *rss)
{{
    int i, p, a, c;
    for (i = 0; i < 6; ++i) {{
        double r[4], v = mo[4 + i][4 + i];
        for (a = 0; a < 4; ++a) {{
            r[a] = 0.0;
            for (p = 0; p < 10; ++p) r[a] += {name}_id_maps[i][p][a] * theta[p];
        }}
        for (a = 0; a < 4; ++a) {{
            v -= 2.0 * r[a] * mo[a][4 + i];
            for (c = 0; c < 4; ++c) v += r[a] * mo[a][c] * r[c];
        }}
        rss[i] = v > 0.0 ? v : 0.0;
    }}
}}

/* Residual variance per axis; each axis carries n of the 6 n - p degrees of freedom (payload.identify). */
static inline void {name}_id_axis_variance(double mo[10][10], const double *theta, long n, int p, double *variance)
{{
    double rss[6];
    int i;
    {name}_id_rss(mo, theta, rss);
    for (i = 0; i < 6; ++i) {{
        double scale = mo[4 + i][4 + i] / (double)n, least;
        least = 1e-24 * (scale > 1.0 ? scale : 1.0);
        variance[i] = rss[i] / ((double)n - (double)p / 6.0);
        if (!(variance[i] >= least)) variance[i] = least;
    }}
}}

/* Eigenvalues (and vectors, as columns) of a symmetric 10 x 10 matrix by cyclic Jacobi rotations. */
static inline void {name}_id_eigen(double in[10][10], double values[10], double vectors[10][10])
{{
    double a[10][10];
    int i, k, p, q, sweep;
    memcpy(a, in, sizeof a);
    for (i = 0; i < 10; ++i)
        for (k = 0; k < 10; ++k) vectors[i][k] = i == k ? 1.0 : 0.0;
    for (sweep = 0; sweep < 50; ++sweep) {{
        double off = 0.0, total = 0.0;
        for (p = 0; p < 10; ++p)
            for (q = 0; q < 10; ++q) {{
                total += a[p][q] * a[p][q];
                if (p != q) off += a[p][q] * a[p][q];
            }}
        if (!(off > 1e-32 * total)) break;   /* off-diagonal below 1e-16 of the matrix (Frobenius) */
        for (p = 0; p < 9; ++p)
            for (q = p + 1; q < 10; ++q) {{
                double theta, t, c, sn;
                if (a[p][q] == 0.0) continue;
                theta = (a[q][q] - a[p][p]) / (2.0 * a[p][q]);
                t = fabs(theta) > 1e150 ? 0.5 / theta
                    : (theta >= 0.0 ? 1.0 : -1.0) / (fabs(theta) + sqrt(theta * theta + 1.0));
                c = 1.0 / sqrt(t * t + 1.0);
                sn = t * c;
                for (k = 0; k < 10; ++k) {{
                    double x = a[k][p], y = a[k][q];
                    a[k][p] = c * x - sn * y;
                    a[k][q] = sn * x + c * y;
                }}
                for (k = 0; k < 10; ++k) {{
                    double x = a[p][k], y = a[q][k];
                    a[p][k] = c * x - sn * y;
                    a[q][k] = sn * x + c * y;
                }}
                for (k = 0; k < 10; ++k) {{
                    double x = vectors[k][p], y = vectors[k][q];
                    vectors[k][p] = c * x - sn * y;
                    vectors[k][q] = sn * x + c * y;
                }}
                a[p][q] = a[q][p] = 0.0;   /* what the rotation makes it, without its rounding */
            }}
    }}
    for (i = 0; i < 10; ++i) values[i] = a[i][i];
}}

/* Cholesky factor (lower) of a symmetric matrix in place; -1 at a pivot that is not positive. */
static inline int {name}_id_cholesky(double a[10][10])
{{
    int i, j, k;
    for (j = 0; j < 10; ++j) {{
        double d = a[j][j];
        for (k = 0; k < j; ++k) d -= a[j][k] * a[j][k];
        if (!(d > 0.0)) return -1;
        a[j][j] = sqrt(d);
        for (i = j + 1; i < 10; ++i) {{
            double v = a[i][j];
            for (k = 0; k < j; ++k) v -= a[i][k] * a[j][k];
            a[i][j] = v / a[j][j];
        }}
    }}
    return 0;
}}

/* Solve L L^T x = b with the factor of NAME_id_cholesky. */
static inline void {name}_id_cholesky_solve(double l[10][10], const double *b, double *x)
{{
    int i, k;
    double y[10];
    for (i = 0; i < 10; ++i) {{
        y[i] = b[i];
        for (k = 0; k < i; ++k) y[i] -= l[i][k] * y[k];
        y[i] /= l[i][i];
    }}
    for (i = 9; i >= 0; --i) {{
        x[i] = y[i];
        for (k = i + 1; k < 10; ++k) x[i] -= l[k][i] * x[k];
        x[i] /= l[i][i];
    }}
}}

/* Equilibrate (unit diagonal), factor, solve gram x = cross; with `check`, refuse a condition number of the
   equilibrated Gram above {_num(_REFIT_CONDITION)} (payload.identify._refit). 0, or -1 (x not written). */
static inline int {name}_id_solve(double gram[10][10], const double *cross, double *x, int check)
{{
    double scale[10], a[10][10], rhs[10], z[10];
    int i, j;
    for (i = 0; i < 10; ++i) {{
        if (!(gram[i][i] > 0.0)) return -1;
        scale[i] = 1.0 / sqrt(gram[i][i]);
    }}
    for (i = 0; i < 10; ++i) {{
        for (j = 0; j < 10; ++j) a[i][j] = gram[i][j] * scale[i] * scale[j];
        rhs[i] = cross[i] * scale[i];
    }}
    if (check) {{
        double values[10], vectors[10][10], low = HUGE_VAL, high = 0.0;
        {name}_id_eigen(a, values, vectors);
        for (i = 0; i < 10; ++i) {{
            if (fabs(values[i]) < low) low = fabs(values[i]);
            if (fabs(values[i]) > high) high = fabs(values[i]);
        }}
        if (!(high <= {_num(_REFIT_CONDITION)} * low)) return -1;
    }}
    if ({name}_id_cholesky(a)) return -1;
    {name}_id_cholesky_solve(a, rhs, z);
    for (i = 0; i < 10; ++i) x[i] = z[i] * scale[i];
    return 0;
}}

/* Hold the parameters of `held` (bits) at zero: their rows and columns become the identity's, their
   cross products zero, so the others solve the system without them (payload.identify's take(keep)). */
static inline void {name}_id_hold_at_zero(double gram[10][10], double *cross, unsigned held)
{{
    int j, k;
    for (j = 0; j < 10; ++j)
        if (held & (1u << j)) {{
            for (k = 0; k < 10; ++k) gram[j][k] = gram[k][j] = 0.0;
            gram[j][j] = 1.0;
            cross[j] = 0.0;
        }}
}}

/* The moments of all holds, or of all but hold `without` (-1: none), made symmetric; returns the samples. */
static inline long {name}_id_moments(const {name}_state *s, int without, double mo[10][10])
{{
    long n = 0;
    int h, j, k;
    memset(mo, 0, 100 * sizeof(double));
    for (h = 0; h < s->n_holds; ++h) {{
        if (h == without) continue;
        for (j = 0; j < 10; ++j)
            for (k = j; k < 10; ++k) mo[j][k] += s->hold_moments[h][j][k];
        n += s->hold_samples[h];
    }}
    for (j = 0; j < 10; ++j)
        for (k = 0; k < j; ++k) mo[j][k] = mo[k][j];
    return n;
}}

static inline void {name}_id_hold(const {name}_state *s, int h, double mo[10][10])
{{
    int j, k;
    for (j = 0; j < 10; ++j)
        for (k = j; k < 10; ++k) mo[j][k] = mo[k][j] = s->hold_moments[h][j][k];
}}

/* Put a tool identified as `tool_name` into the library (replacing a tool of that name, else in the next slot);
   with `mount`, mount it and give the bias the identified value and variance max(SE^2, noise variance)
   (finish_identification(mount=True)). Returns 0, -1 (nothing changed) for a mass of 0, numbers not finite or an
   infinite standard error (NaN, undetermined, is taken: that bias gets the noise variance), or a NAME_TOOL_* code
   for the name. */
static inline int {name}_add_identified({name}_state *s, const char *tool_name, const {name}_tool_fit *tool,
                                        const {name}_tool_se *se, int mount)
{{
    int j, index, finite = isfinite(tool->mass) && tool->mass != 0.0, status = {name}_check_new_tool(s, tool_name);
    {name}_event ev;
    for (j = 0; j < 3; ++j) finite = finite && isfinite(tool->com[j]) && isfinite(tool->mass * tool->com[j]);
    for (j = 0; j < 6; ++j) finite = finite && isfinite(tool->bias[j]) && !isinf(se->bias[j] * se->bias[j]);
    if (!finite) return -1;
    if (status) return status;
    index = {name}_find_tool(s, tool_name);
    if (index < 0) {{   /* a new name: the next slot */
        index = s->n_tools;
        memcpy(s->tool_names[index - {macro}_N_TOOLS], tool_name, strlen(tool_name) + 1);
        s->n_tools += 1;
    }}
    s->identifying = 0;
    s->in_hold = 0;
    s->tool_mass[index] = tool->mass;
    for (j = 0; j < 3; ++j) s->tool_mc[index][j] = tool->mass * tool->com[j];
    s->tool_sign[index] = 1.0;   /* identified from the readings themselves (reaction=False) */
    {name}_call_event(s, {macro}_EVENT_TOOL_IDENTIFIED, index, index, &ev);
    ev.count = tool->n_holds;
    ev.value[0] = tool->mass;
    ev.value[1] = se->mass;
    memcpy(ev.tool_name, tool_name, strlen(tool_name) + 1);
    {name}_log_event(s, &ev);
    if (mount) {{
        {name}_call_event(s, {macro}_EVENT_TOOL_SWITCHED, s->tool, index, &ev);
        {name}_log_event(s, &ev);
        s->tool = index;
        s->switches += 1;
        for (j = 0; j < 6; ++j) {{
            double v = isnan(se->bias[j]) ? 0.0 : se->bias[j] * se->bias[j];   /* undetermined: the noise's */
            s->bias[j] = tool->bias[j];
            s->variance[j] = v > s->noise_variance[j] ? v : s->noise_variance[j];
        }}
        {name}_drift_reset(s);   /* the bias was set on purpose: the drift test starts again */
        {name}_sc_reset(s);      /* and the self-check */
        s->last_fail = -HUGE_VAL;
        s->fail_start = HUGE_VAL;
        s->fail_previous = 0;
    }}
    return 0;
}}

/* Put the tool of the identification in progress into the library (see NAME_add_identified), as
   NAME_finish_identification does, and end the identification: call it when the finish ran on a copy of the state
   outside the real-time loop (docs/live.md). Returns 0, or -1 (nothing changed) when no identification is in
   progress or for a tool that is not one (NAME_add_identified). */
static inline int {name}_adopt_identification({name}_state *s, const {name}_tool_fit *tool, const {name}_tool_se *se,
                                              int mount)
{{
    if (!s->identifying) return -1;
    return {name}_add_identified(s, s->identifying_name, tool, se, mount);
}}

/* Identify the tool from the holds collected since NAME_start_identification: mass, centre of mass and bias
   with the standard errors of LiveCalibrator.finish_identification (ftcal.payload.identify.identify_payload).
   Holds past {macro}_MAX_HOLDS were left out (out_tool->holds_dropped counts them).
   On success (0) the tool is in the library under the name given to NAME_start_identification (NAME_find_tool
   gives its index); with `mount` it is mounted and the bias takes the
   identified value and variance (as finish_identification(mount=True)). Errors (out_tool may be partly written;
   out_tool->undetermined names the parameters the poses do not determine: on success those held at zero
   (their standard errors NaN) and the others confounded with them; on {macro}_ID_MASS_UNDETERMINED all):
   {macro}_ID_NOT_IDENTIFYING  no identification in progress;
   {macro}_ID_TOO_FEW_HOLDS    fewer than {macro}_MIN_HOLDS holds: still identifying, collect more;
   {macro}_ID_MASS_UNDETERMINED the poses do not determine the mass (Python refuses the same);
   {macro}_ID_SINGULAR         a singular solve or a mass of exactly zero.
   The last two end the identification. Cost: about 1 ms on 32 holds; call it outside a 1 kHz loop (docs/live.md). */
static inline int {name}_finish_identification({name}_state *s, {name}_tool_fit *out_tool, {name}_tool_se *out_se,
                                               int mount)
{{
    static const double t_scale[{macro}_MAX_HOLDS] = {_array([0.0, *scales])};
    static const double ones[6] = {{1.0, 1.0, 1.0, 1.0, 1.0, 1.0}};
    double mo[10][10], part[10][10], gram[10][10], cross[10], theta0[10], theta[10], variance[6], weights[6];
    double jac[10], values[10], vectors[10][10], top = 0.0, row[10], inverse[10][10], factor[10][10];
    double covariance[10][10], refits[{macro}_MAX_HOLDS][10], sse_ols[6], sse_wls[6], rss[6], mass;
    long n;
    int h, i, j, k, null = 0, scored = 0, g = 0, p = 10, added;   /* p: parameters estimated (not held) */
    unsigned held = 0;
    if (!s->identifying) return {macro}_ID_NOT_IDENTIFYING;
    memset(out_tool, 0, sizeof *out_tool);
    memset(out_se, 0, sizeof *out_se);
    out_tool->n_holds = s->n_holds;
    out_tool->holds_dropped = s->holds_dropped;
    if (s->n_holds < {macro}_MIN_HOLDS) return {macro}_ID_TOO_FEW_HOLDS;
    s->identifying = 0;
    s->in_hold = 0;
    n = {name}_id_moments(s, -1, mo);
    out_tool->n_samples = n;
    /* excitation: null space of the equilibrated Gram (payload.identify.find_undetermined) */
    {name}_id_gram(mo, ones, gram, cross);
    for (j = 0; j < 10; ++j) {{
        double unit = j >= 4 ? 1.0 : s->hold_gravity_max;
        double least = {_num(ROUNDING_COLUMN)} * unit, d = gram[j][j];
        least = least * least * (double)n;
        if (least > d) d = least;
        jac[j] = 1.0 / sqrt(d > 0.0 ? d : 1.0);
    }}
    for (j = 0; j < 10; ++j)
        for (k = 0; k < 10; ++k) part[j][k] = gram[j][k] * jac[j] * jac[k];
    {name}_id_eigen(part, values, vectors);
    for (j = 0; j < 10; ++j) if (values[j] > top) top = values[j];
    for (j = 0; j < 10; ++j) row[j] = 0.0;
    for (k = 0; k < 10; ++k)
        if (values[k] <= top * {_num(RANK_RELATIVE)}) {{
            null += 1;
            for (j = 0; j < 10; ++j) row[j] += vectors[j][k] * vectors[j][k];
        }}
    if (null > 0) {{
        /* payload.identify._choose_held: one parameter per null direction, COM first, then torque and force
           biases, the largest pivot (the first of near-equal ones); its row is projected out of the basis */
        static const int groups[3] = {{1, 7, 4}};
        int it, c, cols[10], nc = 0;
        for (j = 0; j < 10; ++j) if (sqrt(row[j]) > {_num(NULL_ROW)}) out_tool->undetermined |= 1u << j;
        if ((out_tool->undetermined & 1u) || null == 10) return {macro}_ID_MASS_UNDETERMINED;
        for (k = 0; k < 10; ++k) if (values[k] <= top * {_num(RANK_RELATIVE)}) cols[nc++] = k;
        for (j = 0; j < 10; ++j)
            for (c = 0; c < nc; ++c) part[j][c] = vectors[j][cols[c]];
        for (it = 0; it < nc; ++it) {{
            int pick = -1, grp;
            double unit[10], length = 0.0;
            for (grp = 0; grp < 3 && pick < 0; ++grp) {{
                double score[3], best = 0.0;
                for (j = 0; j < 3; ++j) {{
                    int q = groups[grp] + j;
                    score[j] = -1.0;
                    if (held & (1u << q)) continue;
                    score[j] = 0.0;
                    for (c = 0; c < nc; ++c) score[j] += part[q][c] * part[q][c];
                    score[j] = sqrt(score[j]);
                    if (score[j] > best) best = score[j];
                }}
                if (best > {_num(NULL_ROW)})
                    for (j = 0; j < 3 && pick < 0; ++j)
                        if (score[j] >= best * (1.0 - {_num(CANONICAL_TIE)})) pick = groups[grp] + j;
            }}
            if (pick < 0) return {macro}_ID_SINGULAR;   /* unreachable: biases alone always have a pivot */
            held |= 1u << pick;
            p -= 1;
            for (c = 0; c < nc; ++c) length += part[pick][c] * part[pick][c];
            length = sqrt(length);
            for (c = 0; c < nc; ++c) unit[c] = part[pick][c] / length;
            for (j = 0; j < 10; ++j) {{
                double dot = 0.0;
                for (c = 0; c < nc; ++c) dot += part[j][c] * unit[c];
                for (c = 0; c < nc; ++c) part[j][c] -= dot * unit[c];
            }}
        }}
        {name}_id_hold_at_zero(gram, cross, held);
        out_tool->held = held;
    }}
    if ({name}_id_solve(gram, cross, theta0, 0)) return {macro}_ID_SINGULAR;
    {name}_id_axis_variance(mo, theta0, n, p, variance);
    /* weighting: per-axis 1/sigma^2 only if it predicts held-out holds no worse, and better somewhere */
    for (i = 0; i < 6; ++i) sse_ols[i] = sse_wls[i] = 0.0;
    for (h = 0; h < s->n_holds; ++h) {{
        double train[10][10], t_ols[10], t_wls[10], v[6], w[6], fold[10][10];
        long m = {name}_id_moments(s, h, train);
        {name}_id_gram(train, ones, gram, cross);
        {name}_id_hold_at_zero(gram, cross, held);
        if ({name}_id_solve(gram, cross, t_ols, 1) || m * 6 - p < 6) continue;
        {name}_id_axis_variance(train, t_ols, m, p, v);
        for (i = 0; i < 6; ++i) w[i] = 1.0 / v[i];
        {name}_id_gram(train, w, gram, cross);
        {name}_id_hold_at_zero(gram, cross, held);
        if ({name}_id_solve(gram, cross, t_wls, 1)) continue;
        {name}_id_hold(s, h, fold);
        {name}_id_rss(fold, t_ols, rss);
        for (i = 0; i < 6; ++i) sse_ols[i] += rss[i];
        {name}_id_rss(fold, t_wls, rss);
        for (i = 0; i < 6; ++i) sse_wls[i] += rss[i];
        scored += 1;
    }}
    if (scored >= 2) {{
        double ratio[2] = {{0.0, 0.0}};
        for (i = 0; i < 6; ++i) ratio[i / 3] += sse_wls[i] / (sse_ols[i] > 1e-300 ? sse_ols[i] : 1e-300) / 3.0;
        out_tool->weighted = fmax(ratio[0], ratio[1]) <= 1.0 + {_num(WEIGHTING_TIE)}
                             && fmin(ratio[0], ratio[1]) < 1.0 - {_num(WEIGHTING_TIE)};
    }}
    for (i = 0; i < 6; ++i) weights[i] = out_tool->weighted ? 1.0 / variance[i] : 1.0;
    {name}_id_gram(mo, weights, gram, cross);
    {name}_id_hold_at_zero(gram, cross, held);
    if ({name}_id_solve(gram, cross, theta, 0)) return {macro}_ID_SINGULAR;
    /* the inverse of the equilibrated weighted Gram: variance inflation, and the classical covariance's bread */
    for (j = 0; j < 10; ++j) jac[j] = 1.0 / sqrt(gram[j][j]);
    for (j = 0; j < 10; ++j)
        for (k = 0; k < 10; ++k) factor[j][k] = gram[j][k] * jac[j] * jac[k];
    if ({name}_id_cholesky(factor)) return {macro}_ID_SINGULAR;
    for (k = 0; k < 10; ++k) {{
        double e[10], col[10];
        for (j = 0; j < 10; ++j) e[j] = j == k ? 1.0 : 0.0;
        {name}_id_cholesky_solve(factor, e, col);
        for (j = 0; j < 10; ++j) inverse[j][k] = col[j];
    }}
    for (j = 0; j < 10; ++j)
        for (k = 0; k < j; ++k) inverse[j][k] = inverse[k][j] = 0.5 * (inverse[j][k] + inverse[k][j]);
    /* grouped jackknife over the holds (payload.identify.robust_covariance) */
    for (h = 0; h < s->n_holds; ++h) {{
        double hold_gram[10][10], hold_cross[10];
        {name}_id_hold(s, h, part);
        {name}_id_gram(part, weights, hold_gram, hold_cross);
        for (j = 0; j < 10; ++j) {{
            hold_cross[j] = cross[j] - hold_cross[j];
            for (k = 0; k < 10; ++k) hold_gram[j][k] = gram[j][k] - hold_gram[j][k];
        }}
        {name}_id_hold_at_zero(hold_gram, hold_cross, held);
        if ({name}_id_solve(hold_gram, hold_cross, refits[g], 1) == 0) g += 1;
    }}
    if (g >= 2) {{
        double mean[10], f = t_scale[g - 1] * t_scale[g - 1] * (double)(g - 1) / (double)g;
        for (j = 0; j < 10; ++j) {{
            mean[j] = 0.0;
            for (h = 0; h < g; ++h) mean[j] += refits[h][j];
            mean[j] /= (double)g;
        }}
        for (j = 0; j < 10; ++j)
            for (k = 0; k < 10; ++k) {{
                double v = 0.0;
                for (h = 0; h < g; ++h) v += (refits[h][j] - mean[j]) * (refits[h][k] - mean[k]);
                covariance[j][k] = f * v;
            }}
        out_tool->jackknife_blocks = g;
    }} else {{   /* classical: bread meat bread, meat = sum_i w_i^2 sigma_i^2 A_i^T A_i */
        double meat[10][10], half[10][10], w2[6];
        {name}_id_axis_variance(mo, theta, n, p, variance);
        for (i = 0; i < 6; ++i) w2[i] = weights[i] * weights[i] * variance[i];
        {name}_id_gram(mo, w2, meat, cross);
        {name}_id_hold_at_zero(meat, cross, held);
        for (j = 0; j < 10; ++j) if (held & (1u << j)) meat[j][j] = 0.0;
        for (j = 0; j < 10; ++j)
            for (k = 0; k < 10; ++k) {{
                double v = 0.0;
                for (i = 0; i < 10; ++i) v += inverse[j][i] * jac[j] * jac[i] * meat[i][k];
                half[j][k] = v;
            }}
        for (j = 0; j < 10; ++j)
            for (k = 0; k < 10; ++k) {{
                double v = 0.0;
                for (i = 0; i < 10; ++i) v += half[j][i] * inverse[i][k] * jac[i] * jac[k];
                covariance[j][k] = v;
            }}
    }}
    for (j = 0; j < 10; ++j)
        for (k = 0; k < j; ++k) covariance[j][k] = covariance[k][j] = 0.5 * (covariance[j][k] + covariance[k][j]);
    /* held: no estimate (infinite inflation); undetermined: said once, not as poorly excited */
    for (j = 0; j < 10; ++j) {{
        out_tool->variance_inflation[j] = held & (1u << j) ? HUGE_VAL : inverse[j][j];
        if (inverse[j][j] > {_num(EXCITATION_LIMIT)} && !(out_tool->undetermined & (1u << j)))
            out_tool->poorly_excited |= 1u << j;
    }}
    {name}_id_rss(mo, theta, rss);
    for (i = 0; i < 6; ++i) out_tool->residual_rms[i] = sqrt(rss[i] / (double)n);
    mass = theta[0];
    if (mass == 0.0) return {macro}_ID_SINGULAR;
    out_tool->mass = mass;
    out_se->mass = sqrt(fmax(covariance[0][0], 0.0));
    for (j = 0; j < 3; ++j) {{   /* c = (m c) / m: dc/dm = -c / m, dc/d(m c) = 1 / m */
        double c = theta[1 + j] / mass, a = -c / mass, b = 1.0 / mass;
        out_tool->com[j] = c;
        out_se->com[j] = sqrt(fmax(a * a * covariance[0][0] + 2.0 * a * b * covariance[0][1 + j]
                                   + b * b * covariance[1 + j][1 + j], 0.0));
    }}
    for (j = 0; j < 6; ++j) {{
        out_tool->bias[j] = theta[4 + j];
        out_se->bias[j] = sqrt(fmax(covariance[4 + j][4 + j], 0.0));
    }}
    for (j = 1; j < 10; ++j)   /* undetermined: no standard error (NaN), as in Python */
        if (out_tool->undetermined & (1u << j)) {{
            if (j < 4) out_se->com[j - 1] = NAN;
            else out_se->bias[j - 4] = NAN;
        }}
    added = {name}_add_identified(s, s->identifying_name, out_tool, out_se, mount);   /* the name was checked */
    return added == -1 ? {macro}_ID_SINGULAR : added;
}}
"""
