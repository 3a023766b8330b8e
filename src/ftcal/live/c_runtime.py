"""The live calibrator's per-sample step in C99 (``ftcal convert MODEL --to c-runtime -o NAME.h``).

The step is hand-written C, the core ``csrc/ftcal_live.h`` (its self-check section
``csrc/ftcal_live_selfcheck.h``), package data shared with the extension :mod:`ftcal.live.core`. This module
generates only what depends on the model and the tools: the evaluator, the public macros, the configuration as
data (:func:`core_config`, written as ``NAME_default_config``: numbers and string literals) and the wrappers
``NAME_init`` and ``NAME_step``; the header it writes holds the core's text with the prefix ``NAME``.

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

Fixed-size state, no allocation, no library beyond ``<math.h>``, ``<stdint.h>`` and ``<string.h>``; every
function is ``static`` so the header can be included by one or several translation units (and headers of
other prefixes beside it). ``-DNAME_REAL=float`` is a float build of the step.
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
reasons as text (the core's text section; constants in :mod:`ftcal.live.c_health`). Tool switches, identifications, re-tares and flags raised or
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
from ..files.c_code import static_predict_function
from ..files.c_text import c_comment, c_identifier, c_string, printable_ascii
from ..files.model_json import ModelFile, ftcal_version
from ..files.targets import ConvertOptions, Written
from ..runtime.atomic import write_text_atomic
from ..runtime.errors import FtcalError, ParameterError
from .c_consistency import selfcheck_config, selfcheck_macros
from .c_limits import DRIFT_SNAPSHOTS
from .c_events import event_macros, events_config
from .c_health import health_config, health_macros
from .c_identify import _array, _num, identify_config, status_macros
from .defaults import (GATE_PROBABILITY, NO_TOOL, RETARE_VARIANCE, UNEXPLAINED_SECONDS, UNEXPLAINED_SIGMA,
                         tracker_defaults, tracker_wander)
from .drift import FALSE_ALARM, LAGS_S, SNAPSHOT_S
from .tracker import HOLDOFF_S, MIN_FAIL_S, gate_chi2

DEFAULT_NAME = "ftcal_runtime"
HISTORY = 1024
# DRIFT_SNAPSHOTS, the snapshots the drift test's ring holds, is declared once, in the core's text (c_limits):
# snapshots are at least SNAPSHOT_S apart, so once the ring holds ceil(max(LAGS_S) / SNAPSHOT_S) + 2, its second
# oldest is more than max(LAGS_S) old and the oldest can never be the newest one a lag needs (test_c_runtime_drift).


def runtime_parameters(tools: dict) -> dict:
    """Noise and walk variances and the gate, as :class:`~ftcal.live.LiveCalibrator` derives them by default.

    Parameters
    ----------
    tools : name → PayloadParameters, in library order

    Returns
    -------
    dict with ``noise_variance``, ``walk_variance`` (per s), ``wander_density`` (N²·s: the update's r is
    r + D / Δt), ``accept_limit`` (ndarrays of shape (6,))
    and ``gate_chi2``, ``drift_chi2`` (floats: the contact gate and the drift test's threshold)
    """
    thresholds = Thresholds()
    scale = np.repeat([thresholds.force, thresholds.torque], 3)
    noise, walk = tracker_defaults(tools.values(), thresholds)  # the one rule LiveCalibrator uses
    return {"noise_variance": np.sqrt(noise) ** 2, "walk_variance": walk,
            "wander_density": tracker_wander(tools.values()), "accept_limit": scale,
            "gate_chi2": gate_chi2(GATE_PROBABILITY), "drift_chi2": gate_chi2(1.0 - FALSE_ALARM)}


CORE_DIR = Path(__file__).parent / "csrc"
CORE = "ftcal_live.h"  # the core; it includes its self-check section:
SELFCHECK = "ftcal_live_selfcheck.h"


def core_text() -> str:
    """The C core as one text: ``csrc/ftcal_live.h`` with its self-check section ``csrc/ftcal_live_selfcheck.h`` in
    place of the ``#include`` (the generated header is one file)."""
    core = (CORE_DIR / CORE).read_text(encoding="utf-8")
    section = (CORE_DIR / SELFCHECK).read_text(encoding="utf-8")
    include = f'#include "{SELFCHECK}"\n'
    if core.count(include) != 1:
        raise FtcalError(f"the C core {CORE} does not include {SELFCHECK} exactly once; the installation is damaged.")
    return core.replace(include, section)


def _span_config(model, nu: int) -> dict:
    """The span test's configuration (:func:`ftcal.core.excitation.span_distance`): ``has_span`` 0 without one."""
    spread = getattr(model, "input_spread_", None)
    if spread is None:
        return {"has_span": 0}
    cov = spread.covariance
    std = np.sqrt(np.maximum(np.diag(cov), 0.0))
    unit = np.where(std > 0, std, 1.0)
    corr = cov / unit[:, None] / unit[None, :]
    values, vectors = np.linalg.eigh(0.5 * (corr + corr.T))
    kept = values > SPAN_RELATIVE_FLOOR * max(values.max(), 0.0)
    return {"has_span": 1, "span_mean": np.asarray(spread.mean, float), "span_unit": unit, "span_values": values,
            "span_vectors": vectors.T, "span_kept": kept.astype(int),
            "span_off": 1e-6 * math.sqrt(max(values.max(), 1e-300)), "span_limit": span_limit(nu)}


def core_config(model, tools: dict, *, max_holds: int = C_RUNTIME_MAX_HOLDS) -> dict:
    """The core's configuration (``FTL_(config)`` of ``csrc/ftcal_live.h``) for ``model`` and ``tools``: data only.

    Parameters
    ----------
    model : fitted static polynomial CalibrationModel with six outputs (its inputs, ranges and span), or None: the
        inputs are the wrench itself (six channels without a range)
    tools : mapping name → PayloadParameters (the library; ``"none"`` is tool 0)
    max_holds : the holds an identification keeps

    Returns
    -------
    dict field → int, float, str or ndarray (strings are C data, never code)

    Raises
    ------
    FtcalError
        The model's only input is a temperature, or a tool's number is not finite.
    """
    from ..report.runs import temperature_column

    if model is None:  # the wrench itself (LiveCalibrator without a model): six channels, no range, no span
        nu, t_col, channels = 6, None, list(range(6))
        rng, slack = np.tile([-np.inf, np.inf], (6, 1)), np.zeros(6)
    else:
        nu = len(model.input_names_)
        t_col = temperature_column(model.input_names_)
        channels = [j for j in range(nu) if j != t_col]
        if not channels:
            raise ParameterError("to", "{to} c-runtime: the model's only input is a temperature; the step needs "
                                       "sensor channels.")
        rng = np.asarray(model.input_range_, float)
        slack = RANGE_TOLERANCE * np.maximum(rng[:, 1] - rng[:, 0], 1.0)
    params = runtime_parameters(tools)
    names = [NO_TOOL, *tools]
    mass = [0.0] + [float(p.mass) for p in tools.values()]
    mc = [[0.0] * 3] + [list(p.mass * np.asarray(p.com, dtype=float)) for p in tools.values()]
    sign = [1.0] + [-1.0 if p.reaction else 1.0 for p in tools.values()]
    for what, values in (("tool masses", mass), ("tool centres of mass", mc), ("noise", params["noise_variance"]),
                         ("walk", params["walk_variance"]), ("wander", params["wander_density"])):
        if not np.all(np.isfinite(np.asarray(values, float))):
            raise ParameterError("to", f"{{to}} c-runtime: the {what} are not all finite; refusing to generate code.")
    config = {"n_inputs": nu, "n_channels": len(channels), "n_tools": len(names), "channels": np.array(channels),
              "channel_range": rng[channels], "input_low": rng[:, 0] - slack, "input_high": rng[:, 1] + slack,
              "temperature": -1 if t_col is None else int(t_col),
              "temperature_low": 0.0 if t_col is None else rng[t_col, 0],
              "temperature_high": 0.0 if t_col is None else rng[t_col, 1],
              **({"has_span": 0} if model is None else _span_config(model, nu)),
              "tool_mass": np.array(mass), "tool_mc": np.array(mc), "tool_sign": np.array(sign),
              "tool_names": names, "tool_reprs": [repr(t) for t in names],
              "noise_variance": params["noise_variance"], "walk_variance": params["walk_variance"],
              "accept_limit": params["accept_limit"], "gate_chi2": params["gate_chi2"],
              "drift_chi2": params["drift_chi2"], "gate_probability": GATE_PROBABILITY,
              "unexplained_sigma": UNEXPLAINED_SIGMA, "unexplained_seconds": UNEXPLAINED_SECONDS,
              "motion_window": HOLD_WINDOW_S, "min_rate": MIN_ANGULAR_RATE, "min_hold": MIN_HOLD_S,
              "retare_variance": RETARE_VARIANCE, "holdoff": HOLDOFF_S, "min_fail_s": MIN_FAIL_S,
              "snapshot_s": SNAPSHOT_S, "lags": np.array(LAGS_S),
              **health_config(), **selfcheck_config(), **identify_config(max_holds), **events_config(),
              "no_tool": NO_TOOL, "wander_density": params["wander_density"]}
    return config


def _config_function(name: str, config: dict) -> str:
    """``NAME_default_config``: the configuration as assignments of numbers and string literals (data only)."""
    lines = [f"/* The configuration of this model and tool library (numbers and strings only; {name}_init copies it",
             "   into the state). */",
             f"static inline void {name}_default_config({name}_config *c)", "{",
             "    memset(c, 0, sizeof *c);"]
    for field, value in config.items():
        if isinstance(value, str):
            lines.append(f"    c->{field} = {c_string(value)};")
        elif isinstance(value, list) and value and isinstance(value[0], str):
            lines += [f"    c->{field}[{i}] = {c_string(v)};" for i, v in enumerate(value)]
        elif isinstance(value, (int, np.integer)) and not isinstance(value, bool):
            lines.append(f"    c->{field} = {int(value)};")
        elif np.ndim(value) == 0:
            lines.append(f"    c->{field} = {_num(value)};")
        else:
            a = np.asarray(value)
            kind = "int" if a.dtype.kind in "iub" else "double"
            text = ", ".join(str(int(x)) for x in a.ravel()) if kind == "int" else _array(a)[1:-1]
            lines += ["    {", f"        static const {kind} v[{a.size}] = {{{text}}};",
                      f"        memcpy(c->{field}, v, sizeof v);", "    }"]
    return "\n".join([*lines, "}"])


def generate_c_runtime(model, tools: dict, *, name: str = DEFAULT_NAME, sha256: str | None = None,
                       source_name: str | None = None, tool_sources=None,
                       max_holds: int = C_RUNTIME_MAX_HOLDS) -> str:
    """The C99 header of the live step for ``model`` and the tool library ``tools``.

    The header is the model's generated evaluator, the public macros, a data-only configuration
    (``NAME_default_config``), the hand-written core ``csrc/ftcal_live.h`` (with the prefix ``name``) and two thin
    wrappers: ``NAME_init`` (the configuration into the state) and ``NAME_step`` (the evaluator, then the core's step).

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
    c_identifier(name)
    if not isinstance(max_holds, int) or not LIVE_MIN_HOLDS <= max_holds <= C_RUNTIME_MAX_HOLDS:
        raise FtcalError(f"max_holds must be an int in [{LIVE_MIN_HOLDS}, {C_RUNTIME_MAX_HOLDS}]; got {max_holds!r}.")
    if len(model.output_names_) != 6:
        raise ParameterError("to", f"{{to}} c-runtime: the model has {len(model.output_names_)} outputs; "
                                   "a wrench needs 6.")
    predict = static_predict_function(model, f"static inline void {name}_calibrate")
    macro, nu = name.upper(), len(model.input_names_)
    for tool in tools:
        if not isinstance(tool, str) or not tool or tool == NO_TOOL or "\0" in tool:
            raise ParameterError("to", f"{{to}} c-runtime: tool {printable_ascii(repr(tool))[:80]} needs a name "
                                 f"other than {NO_TOOL!r}, without NUL characters.")
        size = len(tool.encode("utf-8", "surrogatepass"))
        if size > C_RUNTIME_MAX_TOOL_NAME:  # a longer literal may not compile (C99 guarantees 4095 bytes)
            raise ParameterError("to", f"{{to}} c-runtime: tool {printable_ascii(repr(tool))[:80]} has a name "
                                 f"of {size} bytes; at most {C_RUNTIME_MAX_TOOL_NAME} (UTF-8), as for a name given at "
                                 "run time.")
    config = core_config(model, tools, max_holds=max_holds)
    sources = list(tool_sources or [None] * len(tools))
    comment = c_comment([
        f"{name}: ftcal live step (calibration, tool compensation, bias Kalman filter, health flags),",
        f"degree {model.layout_.basis.degree}, {nu} inputs. Generated by ftcal {ftcal_version()}; do not edit.",
        f"model file: {source_name or 'unknown'}" + (f", sha256 {sha256}" if sha256 else ""),
        f"inputs (u): {', '.join(model.input_names_)}",
        f"outputs: {', '.join(model.output_names_)}",
        *[f"tool {i + 1}: {tool}" + (f" from {src}" if src else "") for i, (tool, src) in enumerate(zip(tools, sources))],
        "The step itself is ftcal's C core (ftcal_live.h, below); this file adds the model's evaluator, its",
        "configuration as data and the wrappers NAME_init and NAME_step.",
        "Include in one or more translation units; needs -lm. See docs/live.md."])
    text = f"""{comment}
#ifndef {macro}_H
#define {macro}_H

#include <math.h>
#include <stdint.h>
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
#define {macro}_N_TOOLS {config['n_tools']}
#define {macro}_N_CHANNELS {config['n_channels']}
#define {macro}_MAX_HOLDS {max_holds}   /* holds an identification in place keeps; later ones are left out */
#define {macro}_MIN_HOLDS {LIVE_MIN_HOLDS}
#define {macro}_MAX_ADDED_TOOLS {C_RUNTIME_MAX_TOOLS}   /* tools identified in place under new names */
#define {macro}_MAX_TOOLS ({macro}_N_TOOLS + {macro}_MAX_ADDED_TOOLS)
#define {macro}_MAX_TOOL_NAME {C_RUNTIME_MAX_TOOL_NAME}   /* bytes of a run-time tool name, without the NUL */
#define {macro}_MAX_MAGNITUDE {MAX_CELL_MAGNITUDE!r}   /* larger inputs are refused, as in Python: squares overflow */
{status_macros(macro)}
#ifndef {macro}_HISTORY
#define {macro}_HISTORY {HISTORY}
#endif
#define {macro}_DRIFT_SNAPSHOTS FTCAL_LIVE_DRIFT_SNAPSHOTS   /* {DRIFT_SNAPSHOTS}: the drift test's ring: {_num(max(LAGS_S))} s of snapshots {_num(SNAPSHOT_S)} s apart */
#define {macro}_DRIFT_LAGS {len(LAGS_S)}
{selfcheck_macros(macro)}
{health_macros(macro)}
{event_macros(macro, C_RUNTIME_MAX_EVENTS)}

static inline const char *{name}_input_name(int input)
{{
    static const char *const names[{macro}_N_INPUTS] = {{{', '.join(c_string(t) for t in model.input_names_)}}};
    return input >= 0 && input < {macro}_N_INPUTS ? names[input] : 0;
}}

{predict}

/* ----- the core: ftcal_live.h, as shipped with ftcal {ftcal_version()} ----- */
#define FTCAL_LIVE_PREFIX {name}
#define FTCAL_LIVE_MACRO {macro}
#ifdef {macro}_NO_TEXT
#define FTCAL_LIVE_NO_TEXT
#endif
#ifdef {macro}_REAL   /* e.g. -D{macro}_REAL=float: a float build of the step (times and identification stay double) */
#define FTCAL_LIVE_REAL {macro}_REAL
#endif
{core_text()}
#undef FTCAL_LIVE_REAL
#undef FTCAL_LIVE_NO_TEXT
#undef FTCAL_LIVE_PREFIX
#undef FTCAL_LIVE_MACRO
/* ----- end of the core ----- */

{_config_function(name, config)}

/* Start with tool `tool` mounted and the bias unknown (the first static, contact-free samples set it).
   Returns 0, or -1 for a tool index outside 0 .. N_TOOLS-1. */
static inline int {name}_init({name}_state *s, int tool)
{{
    {name}_config c;
    {name}_default_config(&c);
    return {name}_core_init(s, &c, tool);
}}

/* One sample: time in s (strictly increasing), u[N_INPUTS] the raw channels, gravity[3] in sensor axes
   (m/s^2, any nonzero length for the direction), static_override -1 (motion test), 0 or 1.
   Returns 0, or -1 (state untouched, out not written) for input that is not finite or beyond
   MAX_MAGNITUDE (a calibrated wrench too), time that does not increase or a zero gravity vector. */
static inline int {name}_step({name}_state *s, double time, const {name}_real *u, const {name}_real *gravity,
                              int static_override, {name}_output *out)
{{
#ifdef {macro}_REAL   /* the evaluator is double: the raw channels in, the wrench out */
    double ud[{macro}_N_INPUTS], wd[6];
    {name}_real w[6];
    int j;
    for (j = 0; j < {macro}_N_INPUTS; ++j) {{
        ud[j] = u[j];
    }}
    {name}_calibrate(ud, wd);
    for (j = 0; j < 6; ++j) {{
        w[j] = ({name}_real)wd[j];
    }}
#else
    double w[6];
    {name}_calibrate(u, w);
#endif
    return {name}_core_step(s, time, u, w, gravity, static_override, out);
}}

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
        raise ParameterError("to", "{to} c-runtime takes a static polynomial model (no ARX lags).")
    tools, files = {}, []
    for spec in options.get("payload_files", []) or []:
        tool, sep, path = str(spec).partition("=")
        if not sep:
            tool, path = Path(spec).stem, spec
        if not tool or tool == NO_TOOL:
            raise ParameterError("payload_files", f"{{payload_files}} {spec}: a tool needs a name other than "
                                                  f"{NO_TOOL!r}.")
        if tool in tools:
            raise ParameterError("payload_files", f"{{payload_files}} {spec}: the name {tool!r} is taken; give each "
                                 "tool its own name (NAME=FILE).")
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
