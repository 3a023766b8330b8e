/*
 * ftcal._moments: the sufficient statistics of a static polynomial model, compiled.
 *
 * The same sums as the numpy path of ftcal/statistics.py (MomentPlan), computed
 * tile by tile: a tile of samples has its monomials evaluated into a buffer that
 * stays in the core's cache, and every product the statistics need is taken
 * from that buffer with register-blocked loops. numpy cannot fuse these steps,
 * and its per-call overhead forbids cache-sized tiles.
 *
 * Optional: when it cannot be built, ftcal uses the numpy path (same layout).
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

/* All statistics of samples [start, start + count): terms and targets of the tile are in buf, ybuf. */
static inline __attribute__((always_inline)) void tile_statistics(
    const Problem *pb, Py_ssize_t start, Py_ssize_t count, Py_ssize_t width, double *buf, double *ybuf,
    const double **colptr, const double **yptr)
{
    const Py_ssize_t nu = pb->n_inputs, ny = pb->n_outputs, p = pb->n_terms;
    /* Degree-1 rows are the inputs; padding samples are zeros, so they add nothing below. */
    transpose_padded(pb->u + start * nu, nu, count, width, buf);
    transpose_padded(pb->y + start * ny, ny, count, width, ybuf);
    for (Py_ssize_t s = 0; s < pb->n_steps; s++) {
        const int64_t *step = pb->steps + 4 * s;
        const double *x = buf + step[0] * width;
        for (int64_t r = 0; r < step[3]; r++) {
            const double *src = buf + (step[1] + r) * width;
            double *dst = buf + (step[2] + r) * width;
            for (Py_ssize_t t = 0; t < width; t++)
                dst[t] = src[t] * x[t];
        }
    }
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

static inline __attribute__((always_inline)) void run(const Problem *pb, double *buf, double *ybuf,
                                                      const double **colptr, const double **yptr,
                                                      Py_ssize_t width)
{
    for (Py_ssize_t start = 0; start < pb->m; start += width) {
        Py_ssize_t count = pb->m - start < width ? pb->m - start : width;
        tile_statistics(pb, start, count, width, buf, ybuf, colptr, yptr);
    }
}

#if (defined(__x86_64__) || defined(__i386__)) && (defined(__GNUC__) || defined(__clang__))
#define HAVE_AVX2_VERSION 1
__attribute__((target("avx2,fma"))) static void run_avx2(const Problem *pb, double *buf, double *ybuf,
                                                         const double **colptr, const double **yptr,
                                                         Py_ssize_t width)
{
    run(pb, buf, ybuf, colptr, yptr, width);
}
#endif

static void run_portable(const Problem *pb, double *buf, double *ybuf, const double **colptr,
                         const double **yptr, Py_ssize_t width)
{
    run(pb, buf, ybuf, colptr, yptr, width);
}

static int use_avx2(void)
{
#ifdef HAVE_AVX2_VERSION
    __builtin_cpu_init();
    return __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma");
#else
    return 0;
#endif
}

/* One argument buffer, checked: C-contiguous, the item format and at least `need` items. */
static int take_buffer(PyObject *obj, Py_buffer *view, int writable, char kind, Py_ssize_t need, const char *name)
{
    int flags = PyBUF_C_CONTIGUOUS | PyBUF_FORMAT | (writable ? PyBUF_WRITABLE : 0);
    if (PyObject_GetBuffer(obj, view, flags) < 0)
        return -1;
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

PyDoc_STRVAR(accumulate_doc,
"accumulate(u, y, n_terms, steps, blocks, columns, moments, cross, maxabs)\n"
"\n"
"Add the statistics of the samples u (m, n_inputs) and targets y (m, n_outputs)\n"
"into moments, cross (n_terms, n_outputs) and maxabs, as ftcal.statistics.MomentPlan\n"
"lays them out. Runs without the GIL.");

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
    PyObject *result = NULL;
    Problem pb;
    memset(&pb, 0, sizeof pb);
    /* Shapes: u and y must be 2-D; the plan's tables are checked against n_terms below. */
    if (take_buffer(objs[0], &views[0], 0, 'd', 0, "u") < 0)
        goto done;
    taken = 1;
    if (take_buffer(objs[1], &views[1], 0, 'd', 0, "y") < 0)
        goto done;
    taken = 2;
    if (views[0].ndim != 2 || views[1].ndim != 2 || views[0].shape[0] != views[1].shape[0] || n_terms < 2) {
        PyErr_SetString(PyExc_ValueError, "u and y must be 2-D with the same rows; n_terms >= 2");
        goto done;
    }
    pb.m = views[0].shape[0];
    pb.n_inputs = views[0].shape[1];
    pb.n_outputs = views[1].shape[1];
    pb.n_terms = n_terms;
    const char *names[6] = {"steps", "blocks", "columns", "moments", "cross", "maxabs"};
    for (int i = 2; i < 8; i++) {
        char kind = i < 5 ? 'q' : 'd';
        Py_ssize_t need = i == 6 ? n_terms * pb.n_outputs : i == 7 ? n_terms : i == 5 ? n_terms : 0;
        if (take_buffer(objs[i], &views[i], i >= 5, kind, need, names[i - 2]) < 0)
            goto done;
        taken = i + 1;
    }
    pb.u = views[0].buf;
    pb.y = views[1].buf;
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
    if (pb.n_inputs > n_terms - 1) {
        PyErr_SetString(PyExc_ValueError, "more inputs than terms");
        goto done;
    }
    for (Py_ssize_t s = 0; s < pb.n_steps; s++) {
        const int64_t *st = pb.steps + 4 * s;
        if (st[0] < 0 || st[0] >= pb.n_inputs || st[1] < 0 || st[2] < 0 || st[3] < 0 ||
            st[1] + st[3] > n_terms - 1 || st[2] + st[3] > n_terms - 1) {
            PyErr_SetString(PyExc_ValueError, "a step of the plan is outside the terms");
            goto done;
        }
    }
    for (Py_ssize_t c = 0; c < pb.n_columns; c++) {
        if (pb.columns[c] < 0 || pb.columns[c] >= n_terms) {
            PyErr_SetString(PyExc_ValueError, "a column of the plan is outside the terms");
            goto done;
        }
    }
    for (Py_ssize_t b = 0; b < pb.n_blocks; b++) {
        const int64_t *bl = pb.blocks + 4 * b;
        if (bl[0] < 0 || bl[1] < 0 || bl[2] < 0 || bl[0] + bl[1] > n_terms || bl[2] > pb.n_columns ||
            bl[3] < 0 || bl[3] + bl[1] * bl[2] > n_moments) {
            PyErr_SetString(PyExc_ValueError, "a block of the plan is outside the moments");
            goto done;
        }
    }
    Py_ssize_t width = (TILE_DOUBLES / n_terms) / 8 * 8;
    width = width < 8 ? 8 : width > MAX_TILE ? MAX_TILE : width;
    double *buf = aligned_alloc(64, sizeof(double) * (size_t)(n_terms + pb.n_outputs) * width);
    const double **ptrs = malloc(sizeof(double *) * (size_t)(pb.n_columns + pb.n_outputs + 1));
    if (buf == NULL || ptrs == NULL) {
        free(buf);
        free(ptrs);
        PyErr_NoMemory();
        goto done;
    }
    double *ybuf = buf + n_terms * width;
    const double **colptr = ptrs, **yptr = ptrs + pb.n_columns;
    for (Py_ssize_t c = 0; c < pb.n_columns; c++)
        colptr[c] = buf + pb.columns[c] * width;
    for (Py_ssize_t k = 0; k < pb.n_outputs; k++)
        yptr[k] = ybuf + k * width;
    static int avx2 = -1;
    if (avx2 < 0)
        avx2 = use_avx2();
    Py_BEGIN_ALLOW_THREADS
#ifdef HAVE_AVX2_VERSION
    if (avx2)
        run_avx2(&pb, buf, ybuf, colptr, yptr, width);
    else
#endif
        run_portable(&pb, buf, ybuf, colptr, yptr, width);
    Py_END_ALLOW_THREADS
    free(buf);
    free(ptrs);
    Py_INCREF(Py_None);
    result = Py_None;
done:
    for (int i = 0; i < taken; i++)
        if (views[i].obj != NULL)
            PyBuffer_Release(&views[i]);
    return result;
}

static PyMethodDef methods[] = {
    {"accumulate", accumulate, METH_VARARGS, accumulate_doc},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module = {
    .m_base = PyModuleDef_HEAD_INIT,
    .m_name = "ftcal._moments",
    .m_doc = "Compiled statistics kernel of static polynomial models (see ftcal.statistics).",
    .m_size = -1,
    .m_methods = methods,
};

PyMODINIT_FUNC PyInit__moments(void)
{
    return PyModule_Create(&module);
}
