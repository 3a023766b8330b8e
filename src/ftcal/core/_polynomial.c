/*
 * ftcal._polynomial: compiled kernels of static polynomial models (see ftcal/kernels.py).
 *
 * accumulate: the sufficient statistics of a fit, the same sums as the numpy
 * path of ftcal/statistics.py (MomentPlan). predict: coefficients times the
 * terms of normalized inputs, as FeatureCombination in ftcal/features.py.
 * Both work tile by tile: a tile of samples has its monomials evaluated into
 * a buffer that stays in the core's cache, and every product is taken from
 * that buffer with register-blocked loops. numpy cannot fuse these steps, and
 * its per-call overhead forbids cache-sized tiles.
 *
 * Optional: when it cannot be built, ftcal uses its numpy paths.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>

#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

/* Four doubles; GCC and Clang lower it to AVX2 or to pairs of SSE2 registers. */
typedef double v4 __attribute__((vector_size(32)));
typedef int64_t m4 __attribute__((vector_size(32)));  /* lane masks and bit patterns of a v4 */

#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic ignored "-Wpsabi"  /* v4 only crosses always-inline calls: no ABI involved */
#endif

/* The buffer of one tile holds about this many doubles (512 KiB: half an L2). */
#define TILE_DOUBLES 65536
#define MAX_TILE 256
#define PREDICT_TILE 64 /* prediction reads each term row once per 8 samples: a smaller tile */

/* The statistics of a block of samples (accumulate). */
typedef struct {
    const double *u;        /* (m, n_inputs), normalized inputs */
    const double *y;        /* (m, n_outputs) */
    Py_ssize_t m, n_inputs, n_outputs, n_terms;
    const int64_t *steps;   /* (n_steps, 4): input, source row, destination row, rows */
    Py_ssize_t n_steps;
    const int64_t *blocks;  /* (n_blocks, 4): first row, rows, columns, offset in moments */
    Py_ssize_t n_blocks;
    const int64_t *columns; /* rows of the terms that serve as block columns, in order */
    Py_ssize_t n_columns;
    double *moments, *cross, *maxabs;
} Problem;

/* The predictions of a block of samples (predict). */
typedef struct {
    const double *u;                 /* (m, n_inputs), raw inputs */
    const double *offset, *inv_scale; /* (n_inputs,): normalized = (u - offset) * inv_scale */
    const double *coef;              /* (n_outputs, n_terms) */
    Py_ssize_t m, n_inputs, n_outputs, n_terms;
    const int64_t *steps;
    Py_ssize_t n_steps;
    double *out;                     /* (m, n_outputs) */
} Prediction;

static inline __attribute__((always_inline)) v4 load4(const double *p)
{
    v4 x;
    memcpy(&x, p, sizeof x);
    return x;
}

static inline __attribute__((always_inline)) double sum4(v4 x)
{
    return (x[0] + x[1]) + (x[2] + x[3]);
}

/* out[a * ld + b] += sum_t rows[a][t] * cols[b][t] for an MR x NR tile; rows are tile rows apart. */
#define PRODUCT_TILE(MR, NR)                                                                        \
    static inline __attribute__((always_inline)) void tile_##MR##x##NR(                              \
        const double *rows, Py_ssize_t width, const double *const *cols, double *out, Py_ssize_t ld) \
    {                                                                                                \
        v4 acc[MR][NR];                                                                              \
        for (int a = 0; a < MR; a++)                                                                 \
            for (int b = 0; b < NR; b++)                                                             \
                acc[a][b] = (v4){0.0, 0.0, 0.0, 0.0};                                                \
        for (Py_ssize_t t = 0; t < width; t += 4) {                                                  \
            v4 c[NR];                                                                                \
            for (int b = 0; b < NR; b++)                                                             \
                c[b] = load4(cols[b] + t);                                                           \
            for (int a = 0; a < MR; a++) {                                                           \
                v4 r = load4(rows + a * width + t);                                                  \
                for (int b = 0; b < NR; b++)                                                         \
                    acc[a][b] += r * c[b];                                                           \
            }                                                                                        \
        }                                                                                            \
        for (int a = 0; a < MR; a++)                                                                 \
            for (int b = 0; b < NR; b++)                                                             \
                out[a * ld + b] += sum4(acc[a][b]);                                                  \
    }

PRODUCT_TILE(4, 3)
PRODUCT_TILE(4, 1)
PRODUCT_TILE(1, 3)
PRODUCT_TILE(1, 1)

/* out (n_rows, n_cols), row stride ld) += rows . cols^T over one tile of samples. */
static inline __attribute__((always_inline)) void block_products(
    const double *rows, Py_ssize_t n_rows, const double *const *cols, Py_ssize_t n_cols, Py_ssize_t width,
    double *out, Py_ssize_t ld)
{
    Py_ssize_t i = 0;
    for (; i + 4 <= n_rows; i += 4) {
        Py_ssize_t j = 0;
        for (; j + 3 <= n_cols; j += 3)
            tile_4x3(rows + i * width, width, cols + j, out + i * ld + j, ld);
        for (; j < n_cols; j++)
            tile_4x1(rows + i * width, width, cols + j, out + i * ld + j, ld);
    }
    for (; i < n_rows; i++) {
        Py_ssize_t j = 0;
        for (; j + 3 <= n_cols; j += 3)
            tile_1x3(rows + i * width, width, cols + j, out + i * ld + j, ld);
        for (; j < n_cols; j++)
            tile_1x1(rows + i * width, width, cols + j, out + i * ld + j, ld);
    }
}

/* rows (n_columns, width) = the transpose of `count` rows of the row-major table (.., n_columns), zero-padded. */
static inline __attribute__((always_inline)) void transpose_padded(
    const double *table, Py_ssize_t n_columns, Py_ssize_t count, Py_ssize_t width, double *rows)
{
    for (Py_ssize_t j = 0; j < n_columns; j++) {
        double *row = rows + j * width;
        for (Py_ssize_t t = 0; t < count; t++)
            row[t] = table[t * n_columns + j];
        for (Py_ssize_t t = count; t < width; t++)
            row[t] = 0.0;
    }
}

/* Terms of degree >= 2 from the degree-1 rows: row destination + r = row source + r times input row. */
static inline __attribute__((always_inline)) void evaluate_terms(const int64_t *steps, Py_ssize_t n_steps,
                                                                 Py_ssize_t width, double *buf)
{
    for (Py_ssize_t s = 0; s < n_steps; s++) {
        const int64_t *step = steps + 4 * s;
        const double *x = buf + step[0] * width;
        for (int64_t r = 0; r < step[3]; r++) {
            const double *src = buf + (step[1] + r) * width;
            double *dst = buf + (step[2] + r) * width;
            for (Py_ssize_t t = 0; t < width; t++)
                dst[t] = src[t] * x[t];
        }
    }
}

/* All statistics of samples [start, start + count): terms and targets of the tile are in buf, ybuf. */
static inline __attribute__((always_inline)) void tile_statistics(
    const Problem *pb, Py_ssize_t start, Py_ssize_t count, Py_ssize_t width, double *buf, double *ybuf,
    const double **colptr, const double **yptr)
{
    const Py_ssize_t nu = pb->n_inputs, ny = pb->n_outputs, p = pb->n_terms;
    /* Degree-1 rows are the inputs; padding samples are zeros, so they add nothing below. */
    transpose_padded(pb->u + start * nu, nu, count, width, buf);
    transpose_padded(pb->y + start * ny, ny, count, width, ybuf);
    evaluate_terms(pb->steps, pb->n_steps, width, buf);
    /* The offset (last row) is 1 for real samples only: its column sum counts them. */
    double *offset = buf + (p - 1) * width;
    for (Py_ssize_t t = 0; t < width; t++)
        offset[t] = t < count ? 1.0 : 0.0;
    for (Py_ssize_t i = 0; i < p; i++) {
        const double *row = buf + i * width;
        v4 s = {0.0, 0.0, 0.0, 0.0}, hi = {0.0, 0.0, 0.0, 0.0};
        for (Py_ssize_t t = 0; t < width; t += 4) {
            v4 x = load4(row + t);
            m4 bits = (m4)x & (m4){INT64_MAX, INT64_MAX, INT64_MAX, INT64_MAX};  /* |x|: sign bit cleared */
            m4 larger = (m4)((v4)bits > hi);
            hi = (v4)((bits & larger) | ((m4)hi & ~larger));
            s += x;
        }
        pb->moments[i] += sum4(s);
        double top = fmax(fmax(hi[0], hi[1]), fmax(hi[2], hi[3]));
        if (top > pb->maxabs[i])
            pb->maxabs[i] = top;
    }
    block_products(buf, p, yptr, ny, width, pb->cross, ny);
    for (Py_ssize_t b = 0; b < pb->n_blocks; b++) {
        const int64_t *block = pb->blocks + 4 * b;
        block_products(buf + block[0] * width, block[1], colptr, block[2], width, pb->moments + block[3], block[2]);
    }
}

static inline __attribute__((always_inline)) void run_statistics(const Problem *pb, double *buf, double *ybuf,
                                                                 const double **colptr, const double **yptr,
                                                                 Py_ssize_t width)
{
    for (Py_ssize_t start = 0; start < pb->m; start += width) {
        Py_ssize_t count = pb->m - start < width ? pb->m - start : width;
        tile_statistics(pb, start, count, width, buf, ybuf, colptr, yptr);
    }
}

/* out rows [t0, t0 + 8) of outputs [k, k + KR): coefficients times the tile's terms. */
#define OUTPUT_TILE(KR)                                                                                  \
    static inline __attribute__((always_inline)) void outputs_##KR(const Prediction *pr, const double *buf, \
                                                                   Py_ssize_t width, Py_ssize_t t0,     \
                                                                   Py_ssize_t k, double *out8)          \
    {                                                                                                    \
        v4 acc[KR][2];                                                                                   \
        for (int a = 0; a < KR; a++)                                                                     \
            acc[a][0] = acc[a][1] = (v4){0.0, 0.0, 0.0, 0.0};                                            \
        for (Py_ssize_t i = 0; i < pr->n_terms; i++) {                                                   \
            v4 lo = load4(buf + i * width + t0), hi = load4(buf + i * width + t0 + 4);                   \
            for (int a = 0; a < KR; a++) {                                                               \
                double c = pr->coef[(k + a) * pr->n_terms + i];                                          \
                v4 cv = {c, c, c, c};                                                                    \
                acc[a][0] += lo * cv;                                                                    \
                acc[a][1] += hi * cv;                                                                    \
            }                                                                                            \
        }                                                                                                \
        for (int a = 0; a < KR; a++)                                                                     \
            for (int t = 0; t < 8; t++)                                                                  \
                out8[a * 8 + t] = acc[a][t / 4][t % 4];                                                  \
    }

OUTPUT_TILE(3)
OUTPUT_TILE(1)

static inline __attribute__((always_inline)) void tile_prediction(const Prediction *pr, Py_ssize_t start,
                                                                  Py_ssize_t count, Py_ssize_t width, double *buf)
{
    const Py_ssize_t nu = pr->n_inputs, ny = pr->n_outputs, p = pr->n_terms;
    transpose_padded(pr->u + start * nu, nu, count, width, buf);
    for (Py_ssize_t j = 0; j < nu; j++) {
        double *row = buf + j * width;
        for (Py_ssize_t t = 0; t < width; t++)
            row[t] = (row[t] - pr->offset[j]) * pr->inv_scale[j];
    }
    evaluate_terms(pr->steps, pr->n_steps, width, buf);
    double *offset = buf + (p - 1) * width;
    for (Py_ssize_t t = 0; t < width; t++)
        offset[t] = 1.0;
    double out8[3 * 8];
    for (Py_ssize_t t0 = 0; t0 < count; t0 += 8) {
        Py_ssize_t rows = count - t0 < 8 ? count - t0 : 8;
        for (Py_ssize_t k = 0, kr; k < ny; k += kr) {
            kr = ny - k >= 3 ? 3 : 1;  /* outputs three at a time, the rest one at a time */
            if (kr == 3)
                outputs_3(pr, buf, width, t0, k, out8);
            else
                outputs_1(pr, buf, width, t0, k, out8);
            for (Py_ssize_t a = 0; a < kr; a++)
                for (Py_ssize_t t = 0; t < rows; t++)
                    pr->out[(start + t0 + t) * ny + k + a] = out8[a * 8 + t];
        }
    }
}

static inline __attribute__((always_inline)) void run_prediction(const Prediction *pr, double *buf, Py_ssize_t width)
{
    for (Py_ssize_t start = 0; start < pr->m; start += width) {
        Py_ssize_t count = pr->m - start < width ? pr->m - start : width;
        tile_prediction(pr, start, count, width, buf);
    }
}

/* Each kernel twice: for CPUs with AVX2 and FMA, chosen at run time, and for any CPU. */
#if (defined(__x86_64__) || defined(__i386__)) && (defined(__GNUC__) || defined(__clang__))
#define HAVE_AVX2_VERSION 1
__attribute__((target("avx2,fma"))) static void statistics_avx2(const Problem *pb, double *buf, double *ybuf,
                                                                const double **colptr, const double **yptr,
                                                                Py_ssize_t width)
{
    run_statistics(pb, buf, ybuf, colptr, yptr, width);
}

__attribute__((target("avx2,fma"))) static void prediction_avx2(const Prediction *pr, double *buf, Py_ssize_t width)
{
    run_prediction(pr, buf, width);
}
#endif

static void statistics_portable(const Problem *pb, double *buf, double *ybuf, const double **colptr,
                                const double **yptr, Py_ssize_t width)
{
    run_statistics(pb, buf, ybuf, colptr, yptr, width);
}

static void prediction_portable(const Prediction *pr, double *buf, Py_ssize_t width)
{
    run_prediction(pr, buf, width);
}

static int avx2_available = -1; /* set once, holding the GIL */

static int use_avx2(void)
{
#ifdef HAVE_AVX2_VERSION
    if (avx2_available < 0) {
        __builtin_cpu_init();
        avx2_available = __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma");
    }
    return avx2_available;
#else
    return 0;
#endif
}

/* One argument buffer, checked: C-contiguous, the item format and at least `need` items. */
static int take_buffer(PyObject *obj, Py_buffer *view, int writable, char kind, Py_ssize_t need, const char *name)
{
    int flags = PyBUF_C_CONTIGUOUS | PyBUF_FORMAT | (writable ? PyBUF_WRITABLE : 0);
    if (PyObject_GetBuffer(obj, view, flags) < 0) {
        view->obj = NULL;
        PyErr_Clear();  /* numpy's own message does not say which argument */
        PyErr_Format(PyExc_ValueError, "%s: expected a C-contiguous%s %s array", name,
                     writable ? ", writable (not read-only)" : "", kind == 'd' ? "float64" : "int64");
        return -1;
    }
    const char *format = view->format ? view->format : "B";
    if (*format == '<' || *format == '=' || *format == '@')
        format++;
    int ok = kind == 'd' ? (view->itemsize == 8 && *format == 'd')
                         : (view->itemsize == 8 && (*format == 'q' || *format == 'l'));
    if (!ok || view->len / view->itemsize < need) {
        PyErr_Format(PyExc_ValueError, "%s: expected at least %zd C-contiguous %s values", name, need,
                     kind == 'd' ? "float64" : "int64");
        PyBuffer_Release(view);
        view->obj = NULL;
        return -1;
    }
    return 0;
}

static void release_buffers(Py_buffer *views, int n)
{
    for (int i = 0; i < n; i++)
        if (views[i].obj != NULL)
            PyBuffer_Release(&views[i]);
}

/* Every step reads and writes rows of the terms (the offset, last, excluded) and multiplies by an input. */
static int check_steps(const int64_t *steps, Py_ssize_t n_steps, Py_ssize_t n_inputs, Py_ssize_t n_terms)
{
    if (n_inputs < 1 || n_inputs > n_terms - 1) {
        PyErr_SetString(PyExc_ValueError, "the inputs must be at least one and fewer than the terms");
        return -1;
    }
    for (Py_ssize_t s = 0; s < n_steps; s++) {
        const int64_t *st = steps + 4 * s;
        if (st[0] < 0 || st[0] >= n_inputs || st[1] < 0 || st[2] < n_inputs || st[3] < 0 ||
            st[1] + st[3] > n_terms - 1 || st[2] + st[3] > n_terms - 1) {
            PyErr_SetString(PyExc_ValueError, "a step of the plan is outside the terms");
            return -1;
        }
    }
    return 0;
}

/* Samples per tile, a multiple of 8: the terms of a tile fill about TILE_DOUBLES doubles, at most
   `limit` samples, and no more than m needs (a one-sample call allocates a small buffer). */
static Py_ssize_t tile_width(Py_ssize_t n_terms, Py_ssize_t m, Py_ssize_t limit)
{
    Py_ssize_t width = (TILE_DOUBLES / n_terms) / 8 * 8, needed = (m + 7) / 8 * 8;
    width = width > limit ? limit : width;
    width = width > needed ? needed : width;
    return width < 8 ? 8 : width;
}

PyDoc_STRVAR(accumulate_doc,
"accumulate(u, y, n_terms, steps, blocks, columns, moments, cross, maxabs)\n"
"\n"
"Add the statistics of the normalized samples u (m, n_inputs) and targets y\n"
"(m, n_outputs) into moments, cross (n_terms, n_outputs) and maxabs, as\n"
"ftcal.statistics.MomentPlan lays them out. Runs without the GIL.");

static PyObject *accumulate(PyObject *self, PyObject *args)
{
    (void)self;
    PyObject *objs[8];
    Py_ssize_t n_terms;
    if (!PyArg_ParseTuple(args, "OOnOOOOOO", &objs[0], &objs[1], &n_terms, &objs[2], &objs[3], &objs[4], &objs[5],
                          &objs[6], &objs[7]))
        return NULL;
    Py_buffer views[8];
    int taken = 0;
    Problem pb;
    memset(&pb, 0, sizeof pb);
    const char *names[8] = {"u", "y", "steps", "blocks", "columns", "moments", "cross", "maxabs"};
    if (n_terms < 2) {
        PyErr_SetString(PyExc_ValueError, "n_terms must be at least 2");
        return NULL;
    }
    for (int i = 0; i < 8; i++) {
        char kind = i >= 2 && i < 5 ? 'q' : 'd';
        Py_ssize_t need = i >= 5 && i != 6 ? n_terms : 0;
        if (i == 6)
            need = n_terms * pb.n_outputs;
        if (take_buffer(objs[i], &views[i], i >= 5, kind, need, names[i]) < 0)
            goto fail;
        taken = i + 1;
        if (i == 1) {
            if (views[0].ndim != 2 || views[1].ndim != 2 || views[0].shape[0] != views[1].shape[0]) {
                PyErr_SetString(PyExc_ValueError, "u and y must be 2-D with the same rows");
                goto fail;
            }
            pb.n_outputs = views[1].shape[1];
        }
    }
    pb.u = views[0].buf;
    pb.y = views[1].buf;
    pb.m = views[0].shape[0];
    pb.n_inputs = views[0].shape[1];
    pb.n_terms = n_terms;
    pb.steps = views[2].buf;
    pb.n_steps = views[2].len / 32;
    pb.blocks = views[3].buf;
    pb.n_blocks = views[3].len / 32;
    pb.columns = views[4].buf;
    pb.n_columns = views[4].len / 8;
    pb.moments = views[5].buf;
    pb.cross = views[6].buf;
    pb.maxabs = views[7].buf;
    Py_ssize_t n_moments = views[5].len / 8;
    /* Every row, column and output offset the tables name must lie inside the buffers. */
    if (check_steps(pb.steps, pb.n_steps, pb.n_inputs, n_terms) < 0)
        goto fail;
    for (Py_ssize_t c = 0; c < pb.n_columns; c++) {
        if (pb.columns[c] < 0 || pb.columns[c] >= n_terms) {
            PyErr_SetString(PyExc_ValueError, "a column of the plan is outside the terms");
            goto fail;
        }
    }
    for (Py_ssize_t b = 0; b < pb.n_blocks; b++) {
        const int64_t *bl = pb.blocks + 4 * b;
        if (bl[0] < 0 || bl[1] < 0 || bl[2] < 0 || bl[0] + bl[1] > n_terms || bl[2] > pb.n_columns ||
            bl[3] < 0 || bl[3] + bl[1] * bl[2] > n_moments) {
            PyErr_SetString(PyExc_ValueError, "a block of the plan is outside the moments");
            goto fail;
        }
    }
    Py_ssize_t width = tile_width(n_terms, pb.m, MAX_TILE);
    double *buf = aligned_alloc(64, sizeof(double) * (size_t)(n_terms + pb.n_outputs) * width);
    const double **ptrs = malloc(sizeof(double *) * (size_t)(pb.n_columns + pb.n_outputs + 1));
    if (buf == NULL || ptrs == NULL) {
        free(buf);
        free(ptrs);
        PyErr_NoMemory();
        goto fail;
    }
    double *ybuf = buf + n_terms * width;
    const double **colptr = ptrs, **yptr = ptrs + pb.n_columns;
    for (Py_ssize_t c = 0; c < pb.n_columns; c++)
        colptr[c] = buf + pb.columns[c] * width;
    for (Py_ssize_t k = 0; k < pb.n_outputs; k++)
        yptr[k] = ybuf + k * width;
    int avx2 = use_avx2();
    Py_BEGIN_ALLOW_THREADS
#ifdef HAVE_AVX2_VERSION
    if (avx2)
        statistics_avx2(&pb, buf, ybuf, colptr, yptr, width);
    else
#endif
        statistics_portable(&pb, buf, ybuf, colptr, yptr, width);
    Py_END_ALLOW_THREADS
    (void)avx2;
    free(buf);
    free(ptrs);
    release_buffers(views, taken);
    Py_RETURN_NONE;
fail:
    release_buffers(views, taken);
    return NULL;
}

PyDoc_STRVAR(predict_doc,
"predict(u, offset, inv_scale, coef, steps, out)\n"
"\n"
"out (m, n_outputs) = coef (n_outputs, n_terms) times the terms of the inputs\n"
"u (m, n_inputs) normalized as (u - offset) * inv_scale, the terms in the\n"
"order of ftcal.features.MonomialBasis (offset last). Runs without the GIL.");

static PyObject *predict(PyObject *self, PyObject *args)
{
    (void)self;
    PyObject *objs[6];
    if (!PyArg_ParseTuple(args, "OOOOOO", &objs[0], &objs[1], &objs[2], &objs[3], &objs[4], &objs[5]))
        return NULL;
    Py_buffer views[6];
    int taken = 0;
    Prediction pr;
    memset(&pr, 0, sizeof pr);
    const char *names[6] = {"u", "offset", "inv_scale", "coef", "steps", "out"};
    for (int i = 0; i < 6; i++) {
        Py_ssize_t need = i == 1 || i == 2 ? pr.n_inputs : i == 5 ? pr.m * pr.n_outputs : 0;
        if (take_buffer(objs[i], &views[i], i == 5, i == 4 ? 'q' : 'd', need, names[i]) < 0)
            goto fail;
        taken = i + 1;
        if (i == 0) {
            if (views[0].ndim != 2) {
                PyErr_SetString(PyExc_ValueError, "u must be 2-D");
                goto fail;
            }
            pr.m = views[0].shape[0];
            pr.n_inputs = views[0].shape[1];
        } else if (i == 3) {
            if (views[3].ndim != 2 || views[3].shape[1] < 2) {
                PyErr_SetString(PyExc_ValueError, "coef must be 2-D with at least 2 terms");
                goto fail;
            }
            pr.n_outputs = views[3].shape[0];
            pr.n_terms = views[3].shape[1];
        }
    }
    pr.u = views[0].buf;
    pr.offset = views[1].buf;
    pr.inv_scale = views[2].buf;
    pr.coef = views[3].buf;
    pr.steps = views[4].buf;
    pr.n_steps = views[4].len / 32;
    pr.out = views[5].buf;
    if (check_steps(pr.steps, pr.n_steps, pr.n_inputs, pr.n_terms) < 0)
        goto fail;
    Py_ssize_t width = tile_width(pr.n_terms, pr.m, PREDICT_TILE);
    double *buf = aligned_alloc(64, sizeof(double) * (size_t)pr.n_terms * width);
    if (buf == NULL) {
        PyErr_NoMemory();
        goto fail;
    }
    int avx2 = use_avx2();
    Py_BEGIN_ALLOW_THREADS
#ifdef HAVE_AVX2_VERSION
    if (avx2)
        prediction_avx2(&pr, buf, width);
    else
#endif
        prediction_portable(&pr, buf, width);
    Py_END_ALLOW_THREADS
    (void)avx2;
    free(buf);
    release_buffers(views, taken);
    Py_RETURN_NONE;
fail:
    release_buffers(views, taken);
    return NULL;
}

static PyMethodDef methods[] = {
    {"accumulate", accumulate, METH_VARARGS, accumulate_doc},
    {"predict", predict, METH_VARARGS, predict_doc},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module = {
    .m_base = PyModuleDef_HEAD_INIT,
    .m_name = "ftcal._polynomial",
    .m_doc = "Compiled kernels of static polynomial models (see ftcal.kernels).",
    .m_size = -1,
    .m_methods = methods,
};

PyMODINIT_FUNC PyInit__polynomial(void)
{
    return PyModule_Create(&module);
}
