"""Generated C99 evaluators (``ftcal convert MODEL --to c``): ``NAME.h`` and ``NAME.c``.

The code evaluates the model exactly as :meth:`ftcal.core.model.CalibrationModel.predict`
does, in the model's normalized basis with its own coefficients (printed with
``%.17g``, so every double round-trips): inputs are normalized, each monomial
is its parent monomial times one normalized input (the folded product of
:class:`ftcal.core.features.MonomialEvaluator`, one multiply per term), and each
output accumulates its nonzero coefficients times the monomials, term by
term, into :data:`PARTIAL_SUMS` partial sums added pairwise at the end.
Exact zeros (LASSO) emit no code. The result equals ``predict`` to rounding;
only the order of the sums differs.

Static models also get ``NAME_predict_batch(n, u, y)``: the same monomials and coefficients over
blocks of :data:`BATCH_BLOCK` samples in structure-of-arrays form, small table-driven loops whose
multiply-adds the compiler vectorises across the block's samples (``benchmarks/bench_c.py``
measures it against the scalar entry point and a vectorised floor).

The code is straight-line C: no allocation, no library calls, no headers
beyond its own, one monomial array on the stack; it compiles with
``-std=c99 -Wall -Wextra -Werror -pedantic`` and from C++ (``extern "C"``).

ARX models get a state struct, ``NAME_init`` and ``NAME_step`` for free-run
prediction, the deployment mode: ``NAME_init(&s, u0, y0)`` with the first input
sample and the measured first output (or ``NULL`` for the steady state of
``u0``, as ``predict`` does without measured outputs), then ``NAME_step`` for
every sample, the first included.

``single_precision`` generates ``float`` code for static models;
:func:`float_error` measures what it loses against the double model by
evaluating the generated operations in numpy ``float32`` (IEEE single
precision, the same operations in the same order).
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..core.conversion import sample_training_box
from ..core.model import CalibrationModel
from ..core.ranges import RANGE_TOLERANCE
from ..runtime.atomic import write_texts_atomic
from ..runtime.errors import FtcalError, ParameterError
from .c_text import c_comment, c_identifier, c_string, described
from .model_json import ModelFile, ftcal_version
from .targets import ConvertOptions, Written

DEFAULT_NAME = "ftcal_model"
# Independent partial sums per output of a static model: four addition chains the CPU overlaps
# (measured faster than one chain or eight at degrees 4 and 5, benchmarks/cases.py c_predict).
PARTIAL_SUMS = 4
# Samples per block of the batch evaluator: a multiple of every vector width (2, 4, 8 doubles).
BATCH_BLOCK = 8


@dataclass(frozen=True)
class GeneratedC:
    """The two files of a generated evaluator."""

    name: str
    header: str
    source: str


def check_finite(model: CalibrationModel) -> None:
    """Raise :class:`FtcalError` unless coefficients and normalizations are all finite."""
    inn, out = model.input_normalization_, model.output_normalization_
    for what, values in (("coefficients", model.coef_), ("input normalization", np.r_[inn.offset, inn.scale]),
                         ("output normalization", np.r_[out.offset, out.scale])):
        if not np.all(np.isfinite(values)):
            raise FtcalError(f"The model's {what} are not all finite (NaN or inf); refusing to generate code.")


class _Literals:
    """C literals for one precision: doubles with ``%.17g``, floats rounded to float with ``%.9g``."""

    def __init__(self, single: bool):
        self.single = single
        self.real = "float" if single else "double"

    def value(self, x: float) -> float:
        """The number the literal denotes (what the C code computes with)."""
        return float(np.float32(x)) if self.single else float(x)

    def __call__(self, x: float) -> str:
        text = format(self.value(x), ".9g" if self.single else ".17g")
        if not any(ch in text for ch in ".en"):
            text += ".0"  # an integer literal would be int, and "1f" is not C
        return text + ("f" if self.single else "")


@dataclass(frozen=True)
class _Plan:
    """What the code computes, independent of how it is printed."""

    parents: list[tuple[int, int]]  # monomial t >= nu: (parent monomial, input factor)
    # (column kind, lag or output lag, index, output, coefficient) of every nonzero coefficient:
    # kind "u": input monomial `index` at lag; kind "y": past output `index` at lag; kind "1": offset.
    terms: list[tuple[str, int, int, int, float]]


def _plan(model: CalibrationModel) -> _Plan:
    layout = model.layout_
    basis = layout.basis
    combos = basis.combinations[:-1]
    index = {c: t for t, c in enumerate(combos)}
    # Monomial (i, rest...) = x_i · monomial(rest): the evaluator's first-factor recursion.
    parents = [(index[c[1:]], c[0]) for c in combos[basis.n_inputs:]]
    exps, lags = layout.exponent_rows()
    term_of = {tuple(e): t for t, e in enumerate(basis.exponents[:-1].tolist())}
    ny = layout.n_outputs
    columns = []
    for c in range(layout.n_features):
        if c == layout.n_features - 1:
            columns.append(("1", 0, 0))
        elif lags[c] < 0:
            columns.append(("y", c // ny + 1, c % ny))
        else:
            columns.append(("u", int(lags[c]), term_of[tuple(exps[c].tolist())]))
    # Term-major order: the outputs' sums interleave, which keeps several additions in flight.
    order = sorted(range(layout.n_features), key=lambda c: (columns[c][0] != "1", columns[c][1], columns[c][2]))
    terms = [(*columns[c], k, float(model.coef_[c, k]))
             for c in order for k in range(ny) if model.coef_[c, k] != 0.0]
    return _Plan(parents, terms)


def generate_c(model: CalibrationModel, *, name: str = DEFAULT_NAME, single_precision: bool = False,
               sha256: str | None = None, source_name: str | None = None,
               input_units=None, output_units=None) -> GeneratedC:
    """The header and source of a C99 evaluator of ``model``.

    Parameters
    ----------
    model : fitted CalibrationModel (static or ARX)
    name : C identifier prefixing the files, functions and macros (macros upper-cased)
    single_precision : generate ``float`` code (static models only)
    sha256 : digest of the model file, recorded in the header comment
    source_name : the model file's name, recorded in the header comment
    input_units, output_units : sequences of str or None, recorded in the header comment

    Returns
    -------
    GeneratedC

    Raises
    ------
    FtcalError
        ``name`` is not a C identifier, the model has non-finite numbers, or
        ``single_precision`` is asked for an ARX model.
    """
    model._check_fitted()
    c_identifier(name)
    check_finite(model)
    layout = model.layout_
    if single_precision and not layout.is_static:
        raise ParameterError('single_precision', "{single_precision} is for static models; an ARX model's free run feeds its rounding back "
                         "into every later sample, so generate it in double precision.")
    lit = _Literals(single_precision)
    plan = _plan(model)
    macro = name.upper()
    comment = _header_comment(model, name, single_precision, sha256, source_name, input_units, output_units)
    header = _header(model, name, macro, lit, comment)
    body = [comment, f'#include "{name}.h"', "",
            _string_array(f"{name}_input_names", f"{macro}_N_INPUTS", model.input_names_),
            _string_array(f"{name}_output_names", f"{macro}_N_OUTPUTS", model.output_names_), "",
            _in_range(model, name, lit), ""]
    n_monomials = layout.basis.n_terms - 1
    if layout.is_static:
        body += _static_predict(model, plan, lit, f"void {name}_predict")
        body += ["", *_batch_predict(model, plan, lit, name, macro)]
    else:
        body += _arx_functions(model, name, macro, plan, lit, n_monomials)
    return GeneratedC(name, header, "\n".join(body) + "\n")


def _static_predict(model: CalibrationModel, plan: _Plan, lit: _Literals, signature: str) -> list[str]:
    """Lines of a static model's one-sample evaluator ``signature(const real *u, real *y)``."""
    inn = model.input_normalization_
    inv_scale = 1.0 / inn.scale  # predict multiplies by the inverse scale
    nu, ny = len(model.input_names_), len(model.output_names_)
    lines = [f"{signature}(const {lit.real} *u, {lit.real} *y)", "{",
             f"    {lit.real} m[{model.layout_.basis.n_terms - 1}];"]
    lines += [f"    {lit.real} {', '.join(f'a{k}_{j} = 0' for j in range(PARTIAL_SUMS))};" for k in range(ny)]
    lines += [f"    m[{i}] = (u[{i}] - {lit(inn.offset[i])}) * {lit(inv_scale[i])};" for i in range(nu)]
    lines += _accumulate(plan, lit, nu)
    lines += [f"    y[{k}] = {_pairwise([f'a{k}_{j}' for j in range(PARTIAL_SUMS)], lambda a, b: f'({a} + {b})')};"
              for k in range(ny)]
    lines.append("}")
    return lines


def _batch_predict(model: CalibrationModel, plan: _Plan, lit: _Literals, name: str, macro: str) -> list[str]:
    """``NAME_predict_batch``: blocks of :data:`BATCH_BLOCK` samples, structure of arrays, table-driven loops.

    Per block: the normalized inputs and every monomial (parent times one input, as in
    ``NAME_predict``) go into ``m[monomial][sample]``, each a loop along the block's samples; then one
    loop over the monomials with a nonzero coefficient adds ``coefficient × m[t][s]`` into one
    accumulator per output and sample, named scalars the compiler keeps in (vector) registers.
    The code is a few small loops over ``static const`` tables, so it compiles in a fraction of a
    second at any degree. A last partial block repeats its last sample in the unused lanes.
    """
    inn = model.input_normalization_
    nu, ny = len(model.input_names_), len(model.output_names_)
    real, block = lit.real, BATCH_BLOCK
    n_monomials = model.layout_.basis.n_terms - 1
    constant, rows = [0.0] * ny, {}
    for kind, _, t, k, c in plan.terms:
        if kind == "1":
            constant[k] = c
        else:
            rows.setdefault(t, [0.0] * ny)[k] = c
    order = sorted(rows)
    tables = [f"static const {real} {name}_batch_offset[{nu}] = {{{', '.join(lit(v) for v in inn.offset)}}};",
              f"static const {real} {name}_batch_inv_scale[{nu}] = {{{', '.join(lit(v) for v in 1.0 / inn.scale)}}};"]
    if plan.parents:
        tables += [f"static const int {name}_batch_parent[{len(plan.parents)}][2] = "
                   f"{{{', '.join(f'{{{p}, {f}}}' for p, f in plan.parents)}}};"]
    if order:
        tables += [f"static const int {name}_batch_row[{len(order)}] = {{{', '.join(map(str, order))}}};",
                   f"static const {real} {name}_batch_coef[{len(order)}][{ny}] = "
                   f"{{{', '.join('{' + ', '.join(lit(c) for c in rows[t]) + '}' for t in order)}}};"]
    lines = [f"#ifndef {macro}_NO_BATCH", *tables, "",
             f"static void {name}_predict_block(long count, const {real} *u, {real} *y)", "{",
             f"    {real} m[{n_monomials}][{block}];"]
    lines += [f"    {real} {', '.join(f'a{k}_{j} = {lit(constant[k])}' for j in range(block))};" for k in range(ny)]
    lines += ["    long s;", "    int t, i;",
              f"    for (s = 0; s < {block}; ++s)", f"        for (i = 0; i < {nu}; ++i)",
              f"            m[i][s] = (u[(s < count ? s : count - 1) * {nu} + i] - {name}_batch_offset[i])"
              f" * {name}_batch_inv_scale[i];"]
    if plan.parents:
        # Every load before any store: the compiler then packs each group into vectors without having to
        # prove that the monomial's row is not one of its factors' rows.
        lines += [f"    for (t = {nu}; t < {n_monomials}; ++t) {{",
                  f"        const {real} *parent = m[{name}_batch_parent[t - {nu}][0]];",
                  f"        const {real} *factor = m[{name}_batch_parent[t - {nu}][1]];",
                  f"        {real} {', '.join(f'p{j} = parent[{j}]' for j in range(block))};",
                  f"        {real} {', '.join(f'f{j} = factor[{j}]' for j in range(block))};"]
        lines += [f"        m[t][{j}] = p{j} * f{j};" for j in range(block)]
        lines.append("    }")
    if order:
        lines += [f"    for (t = 0; t < {len(order)}; ++t) {{", f"        const {real} *x = m[{name}_batch_row[t]];",
                  f"        const {real} *c = {name}_batch_coef[t];"]
        lines += [f"        a{k}_{j} += c[{k}] * x[{j}];" for k in range(ny) for j in range(block)]
        lines.append("    }")
    lines += ["    {", f"        {real} out[{block}][{ny}];"]
    lines += [f"        out[{j}][{k}] = a{k}_{j};" for j in range(block) for k in range(ny)]
    lines += [f"        for (s = 0; s < count; ++s)", f"            for (i = 0; i < {ny}; ++i) y[s * {ny} + i] = out[s][i];",
              "    }"]
    lines += ["}", "",
              f"void {name}_predict_batch(long n, const {real} *u, {real} *y)", "{", "    long start;",
              f"    for (start = 0; start < n; start += {macro}_BATCH_BLOCK)",
              f"        {name}_predict_block(n - start < {macro}_BATCH_BLOCK ? n - start : {macro}_BATCH_BLOCK, "
              f"u + start * {macro}_N_INPUTS, y + start * {macro}_N_OUTPUTS);", "}", f"#endif /* {macro}_NO_BATCH */"]
    return lines


def static_predict_function(model: CalibrationModel, signature: str) -> str:
    """C99 text of a double-precision evaluator of a static ``model``, for embedding in other generated code.

    Parameters
    ----------
    model : fitted static CalibrationModel with finite numbers
    signature : everything before the parameter list, e.g. ``"static void ft_calibrate"`` (generated
        by the caller from checked identifiers, never from file text)

    Returns
    -------
    str
        The function ``signature(const double *u, double *y)``, the same operations as ``NAME_predict``
        of :func:`generate_c`.
    """
    model._check_fitted()
    check_finite(model)
    if not model.layout_.is_static:
        raise FtcalError("this export takes static models (no ARX lags).")
    return "\n".join(_static_predict(model, _plan(model), _Literals(False), signature))


def _pairwise(parts: list, add):
    """Sum ``parts`` as a balanced tree, ``add`` combining two: ((p0 + p1) + (p2 + p3)) for four."""
    while len(parts) > 1:
        parts = [add(parts[i], parts[i + 1]) if i + 1 < len(parts) else parts[i] for i in range(0, len(parts), 2)]
    return parts[0]


def _header_comment(model, name, single, sha256, source_name, input_units, output_units) -> str:
    layout = model.layout_

    kind = f"degree {layout.basis.degree}" + ("" if layout.is_static else f", ARX na={layout.na} nb={layout.nb}")
    lines = [f"{name}: ftcal calibration model, {kind}, {np.count_nonzero(model.coef_)} nonzero coefficients,",
             f"{'single' if single else 'double'} precision. Generated by ftcal {ftcal_version()}; do not edit.",
             f"model file: {source_name or 'unknown'}" + (f", sha256 {sha256}" if sha256 else ""),
             f"inputs (u): {described(model.input_names_, input_units)}",
             f"outputs (y): {described(model.output_names_, output_units)}"]
    return c_comment(lines)  # names and units come from the model file: never code


def _header(model, name, macro, lit, comment) -> str:
    real = lit.real
    guard = f"{macro}_H"
    lines = [comment, f"#ifndef {guard}", f"#define {guard}", "",
             "#ifdef __cplusplus", 'extern "C" {', "#endif", "",
             f"#define {macro}_N_INPUTS {len(model.input_names_)}",
             f"#define {macro}_N_OUTPUTS {len(model.output_names_)}", "",
             f"extern const char *const {name}_input_names[{macro}_N_INPUTS];",
             f"extern const char *const {name}_output_names[{macro}_N_OUTPUTS];", "",
             "/* 1 if every input lies in the training range, else 0 (NaN counts as outside). */",
             f"int {name}_in_range(const {real} *u);", ""]
    layout = model.layout_
    if layout.is_static:
        lines += [f"/* y[{macro}_N_OUTPUTS] from u[{macro}_N_INPUTS]. */",
                  f"void {name}_predict(const {real} *u, {real} *y);", "",
                  f"/* Samples per block of the batch evaluator (its vectorised loop's trip count). */",
                  f"#define {macro}_BATCH_BLOCK {BATCH_BLOCK}",
                  f"/* n samples at once: u[n][{macro}_N_INPUTS] to y[n][{macro}_N_OUTPUTS], row by row, the same",
                  "   numbers as n calls of predict up to rounding; the compiler vectorises it across samples.",
                  f"   Define {macro}_NO_BATCH when compiling NAME.c to leave it out (it keeps a block of",
                  f"   monomials, {BATCH_BLOCK} x the monomial count of reals, on the stack). */",
                  f"void {name}_predict_batch(long n, const {real} *u, {real} *y);"]
    else:
        members = []
        if layout.nb:
            members.append(f"    double m[{layout.nb}][{layout.basis.n_terms - 1}]; "
                           "/* monomials of the normalized inputs at k-1, k-2, ... */")
        if layout.na:
            members.append(f"    double y[{layout.na}][{macro}_N_OUTPUTS]; /* normalized outputs at k-1, k-2, ... */")
        lines += [f"/* Free-run state of the ARX model (na={layout.na}, nb={layout.nb}). */",
                  "typedef struct {", *members, f"}} {name}_state;", "",
                  "/* Start a free run at the first sample: u0 is that input, y0 its measured output, or NULL",
                  "   for the steady-state output of a constant u0. Then call step for every sample, u0 included. */",
                  f"void {name}_init({name}_state *s, const double *u0, const double *y0);",
                  f"/* y[{macro}_N_OUTPUTS] for the next input sample u[{macro}_N_INPUTS]. */",
                  f"void {name}_step({name}_state *s, const double *u, double *y);"]
    lines += ["", "#ifdef __cplusplus", "}", "#endif", "", f"#endif /* {guard} */"]
    return "\n".join(lines) + "\n"


def _string_array(symbol: str, size: str, names) -> str:
    return f"const char *const {symbol}[{size}] = {{{', '.join(c_string(n) for n in names)}}};"


def _in_range(model, name, lit) -> str:
    """The training box with predict's slack, as literal bounds per finite side."""
    low, high = model.input_range_[:, 0], model.input_range_[:, 1]
    slack = RANGE_TOLERANCE * np.maximum(high - low, 1.0)
    checks = []
    for i in range(len(low)):
        parts = []
        # the bound with its slack: an infinite one (an open side, or slack from one) checks nothing, as in predict
        lower, upper = float(low[i] - slack[i]), float(high[i] + slack[i])
        if np.isfinite(lower):
            parts.append(f"u[{i}] >= {format(lower, '.17g')}")
        if np.isfinite(upper):
            parts.append(f"u[{i}] <= {format(upper, '.17g')}")
        if parts:
            checks.append(f"    if (!({' && '.join(parts)})) return 0;")
    lines = [f"int {name}_in_range(const {lit.real} *u)", "{"]
    lines += checks or ["    (void)u;"]
    return "\n".join(lines + ["    return 1;", "}"])


def _accumulate(plan: _Plan, lit: _Literals, nu: int) -> list[str]:
    """Static model: monomials (parent × input) interleaved with the accumulations that use them."""
    lines, computed = [], nu
    used = {}  # terms per output so far: term i of output k goes to partial sum i % PARTIAL_SUMS

    def compute_up_to(t: int) -> None:
        nonlocal computed
        while computed <= t:
            parent, factor = plan.parents[computed - nu]
            lines.append(f"    m[{computed}] = m[{parent}] * m[{factor}];")
            computed += 1

    for kind, _, t, k, c in plan.terms:
        j = used.get(k, 0) % PARTIAL_SUMS
        used[k] = used.get(k, 0) + 1
        if kind == "1":
            lines.append(f"    a{k}_{j} += {lit(c)};")
        else:
            compute_up_to(t)
            lines.append(f"    a{k}_{j} += {lit(c)} * m[{t}];")
    compute_up_to(nu + len(plan.parents) - 1)  # monomials whose own coefficients are all zero
    return lines


def _arx_functions(model, name, macro, plan, lit, n_monomials) -> list[str]:
    layout = model.layout_
    nu, ny, na, nb = len(model.input_names_), len(model.output_names_), layout.na, layout.nb
    inn, out = model.input_normalization_, model.output_normalization_
    steady_offset, steady_matrix = _steady_state_map(model)
    state = f"{name}_state"
    lines = ["/* Normalized inputs and their monomials (each a parent monomial times one input). */",
             "static void monomials(const double *u, double *m)", "{"]
    lines += [f"    m[{i}] = (u[{i}] - {lit(inn.offset[i])}) / {lit(inn.scale[i])};" for i in range(nu)]
    lines += [f"    m[{t}] = m[{p}] * m[{i}];" for t, (p, i) in enumerate(plan.parents, start=nu)]
    lines += ["}", "",
              "/* Offset plus every input term: lag 0 from m0, lag j from the state. */",
              f"static void exogenous(const double *m0, const {state} *s, double *y)", "{"]
    lines += [f"    double a{k} = 0;" for k in range(ny)]
    if not nb:
        lines.append("    (void)s;")
    body = []
    for kind, j, t, k, c in plan.terms:
        if kind == "1":
            body.append(f"    a{k} += {lit(c)};")
        elif kind == "u":
            body.append(f"    a{k} += {lit(c)} * {'m0' if j == 0 else f's->m[{j - 1}]'}[{t}];")
    lines += body + [f"    y[{k}] = a{k};" for k in range(ny)] + ["}", ""]
    # init
    lines += [f"void {name}_init({state} *s, const double *u0, const double *y0)", "{",
              f"    double m0[{n_monomials}];", f"    double v[{macro}_N_OUTPUTS];", "    int j, k;",
              "    monomials(u0, m0);"]
    if nb:
        lines += [f"    for (j = 0; j < {nb}; ++j)", f"        for (k = 0; k < {n_monomials}; ++k)",
                  "            s->m[j][k] = m0[k];"]
    lines += ["    if (y0 != 0) {", f"        for (k = 0; k < {macro}_N_OUTPUTS; ++k) v[k] = y0[k];",
              "    } else {", f"        double g[{macro}_N_OUTPUTS];", "        exogenous(m0, s, g);"]
    for k in range(ny):
        terms = " + ".join(f"{lit(steady_matrix[k, l])} * g[{l}]" for l in range(ny))
        lines.append(f"        v[{k}] = {lit(steady_offset[k])} + {terms};")
    lines.append("    }")
    if na:
        lines += [f"    for (j = 0; j < {na}; ++j) {{"]
        lines += [f"        s->y[j][{k}] = (v[{k}] - {lit(out.offset[k])}) / {lit(out.scale[k])};" for k in range(ny)]
        lines.append("    }")
    else:
        lines.append("    (void)v;")
    lines += ["}", ""]
    # step
    lines += [f"void {name}_step({state} *s, const double *u, double *y)", "{",
              f"    double m0[{n_monomials}];", f"    double v[{macro}_N_OUTPUTS];", "    int j, k;",
              "    monomials(u, m0);", "    exogenous(m0, s, v);"]
    # Past outputs last, lag by lag, as predict's free run adds them.
    for j in range(1, na + 1):
        for k in range(ny):
            entries = [(t, c) for kind, lag, t, kk, c in plan.terms if kind == "y" and lag == j and kk == k]
            if entries:
                terms = " + ".join(f"{lit(c)} * s->y[{j - 1}][{t}]" for t, c in entries)
                lines.append(f"    v[{k}] += {terms};")
    if nb:
        lines += [f"    for (j = {nb - 1}; j > 0; --j)", f"        for (k = 0; k < {n_monomials}; ++k)",
                  "            s->m[j][k] = s->m[j - 1][k];",
                  f"    for (k = 0; k < {n_monomials}; ++k) s->m[0][k] = m0[k];"]
    if na:
        lines += [f"    for (j = {na - 1}; j > 0; --j)", f"        for (k = 0; k < {macro}_N_OUTPUTS; ++k)",
                  "            s->y[j][k] = s->y[j - 1][k];"]
        lines += [f"    s->y[0][{k}] = (v[{k}] - {lit(out.offset[k])}) / {lit(out.scale[k])};" for k in range(ny)]
    lines += [f"    for (k = 0; k < {macro}_N_OUTPUTS; ++k) y[k] = v[k];", "}"]
    return lines


def _steady_state_map(model: CalibrationModel) -> tuple[np.ndarray, np.ndarray]:
    """``(c, M)`` with ``predict``'s steady-state output for exogenous part ``g`` equal to ``c + M g``.

    The model's fixed point is affine in ``g``; reading it off the model's own
    solver keeps one definition of it.
    """
    ny = len(model.output_names_)
    na = model.layout_.na
    feedback = [model.coef_[(j - 1) * ny:j * ny] for j in range(1, na + 1)]
    constant = model._steady_state(np.zeros(ny), feedback)
    matrix = np.column_stack([model._steady_state(e, feedback) - constant for e in np.eye(ny)])
    return constant, matrix


def evaluate_like_c(model: CalibrationModel, u: np.ndarray, *, single_precision: bool = False) -> np.ndarray:
    """The generated static ``predict``'s operations, in numpy, in the C code's order and precision.

    Parameters
    ----------
    model : fitted static CalibrationModel
    u : ndarray of shape (n_samples, n_inputs)

    Returns
    -------
    ndarray of shape (n_samples, n_outputs), float32 when ``single_precision``
    """
    lit = _Literals(single_precision)
    dtype = np.float32 if single_precision else np.float64
    plan = _plan(model)
    inn = model.input_normalization_
    nu, ny = len(model.input_names_), len(model.output_names_)
    constant = np.vectorize(lit.value, otypes=[np.float64])
    x = (np.asarray(u, dtype=dtype) - constant(inn.offset).astype(dtype)) * constant(1.0 / inn.scale).astype(dtype)
    m = [x[:, i] for i in range(nu)]
    for parent, factor in plan.parents:
        m.append(m[parent] * m[factor])
    acc = np.zeros((ny, PARTIAL_SUMS, x.shape[0]), dtype=dtype)
    used = np.zeros(ny, dtype=int)
    for kind, _, t, k, c in plan.terms:
        coefficient = dtype(lit.value(c))
        acc[k, used[k] % PARTIAL_SUMS] += coefficient if kind == "1" else coefficient * m[t]
        used[k] += 1
    return _pairwise(list(acc.transpose(1, 0, 2)), lambda a, b: a + b).T


def float_error(model: CalibrationModel, *, n_points: int = 2000, seed: int = 0) -> tuple[float, float, str]:
    """Largest |float − double| of the single-precision code over the training box.

    The same points as :func:`ftcal.core.conversion.precision_loss` (box corners plus
    uniform samples). Returns ``(absolute error, relative to the output's
    training range, output name)`` for the worst output.
    """
    u = sample_training_box(model, n_points, np.random.default_rng(seed))
    exact = model.predict(u, warn_out_of_range=False)
    diff = np.max(np.abs(evaluate_like_c(model, u, single_precision=True).astype(np.float64) - exact), axis=0)
    span = model.output_range_[:, 1] - model.output_range_[:, 0]
    span = np.where(np.isfinite(span) & (span > 0), span, np.maximum(np.max(np.abs(exact), axis=0), 1.0))
    worst = int(np.argmax(diff / span))
    return float(diff[worst]), float(diff[worst] / span[worst]), model.output_names_[worst]


def write_c(source: ModelFile, output: Path, options: ConvertOptions) -> Written:
    """Registry writer: ``output/NAME.h`` and ``output/NAME.c`` (``output`` created if missing)."""
    name = c_identifier(options.get("name", DEFAULT_NAME))
    single = bool(options.get("single_precision", False))
    sha256 = hashlib.sha256(options.input_path.read_bytes()).hexdigest()
    code = generate_c(source.model, name=name, single_precision=single, sha256=sha256,
                      source_name=options.input_path.name, input_units=source.input_units,
                      output_units=source.output_units)
    notes = []
    if single:
        error, relative, output_name = float_error(source.model)
        notes.append(f"single precision: largest |float - double| {error:.3g} on {output_name!r} "
                     f"({relative:.2g} of its training range) over the training range")
    paths = (output / f"{name}.h", output / f"{name}.c")
    for path in paths:
        if path.resolve() == options.input_path.resolve():
            raise ParameterError(('name', 'output'), f"{path} is the input file; choose another {{name}} or "
                                 "{output} directory.")
    write_texts_atomic({paths[0]: code.header, paths[1]: code.source})  # both files or neither
    return Written(paths, tuple(notes))
