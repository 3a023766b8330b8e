"""The generated C runtime's tool library (named slots that grow at run time) and its flags as text.

References: :class:`ftcal.live.LiveCalibrator` fed the same samples and the same calls (identify a
tool under a new name, identify one under a compiled-in name, switch by name, re-tare): the C agrees
to 1e-9 on every output and its tool indices follow Python's ``list(live.tools)``; Python's
``LiveSample.flags`` (the one-line reason of each flag) is the reference for
``NAME_describe_flags`` on replays that raise every flag the C has; Python's ``repr`` for the
quoting of tool names; hand-written byte strings for the names read back from the C.
"""

from __future__ import annotations

import ctypes
import subprocess

import numpy as np
import pytest

from ftcal.core.limits import C_RUNTIME_MAX_TOOL_NAME, C_RUNTIME_MAX_TOOLS
from ftcal.data.signals import STUCK_RUN
from ftcal.live import LiveCalibrator
from ftcal.live.c_identify import STATUS, TOOL_STATUS
from ftcal.live.c_runtime import generate_c_runtime
from ftcal.live.health import BIT, DEAD_RUN, FLAGS
from ftcal.payload.parameters import PayloadParameters
from ftcal.runtime.errors import FtcalError
from ftcal.sim.live_scenario import LiveScenario, Tool, simulate_live

from test_c_runtime import CC, FIELDS, STEP_AND_STORE, compare, gauge_model, pointer, python_replay, tool_payload

pytestmark = pytest.mark.skipif(CC is None, reason="no C compiler `cc`")
DRILL = Tool(2.1, (0.02, 0.01, 0.09))
# Quotes, a backslash, a comment's end and start, a newline, trigraphs (??= is #, ??/ a backslash), a tab.
HOSTILE = 'x"*/ int evil; /*??/\n??=define ??( \\ \'q\'\t'
# (time, C action (code, name), Python action): identify a tool in place under a hostile name and mount it, identify
# "drill" again under a compiled-in name, switch by name, re-tare with the tool kept.
LIBRARY_SCRIPT = [(0.5, (1, HOSTILE), lambda c: c.start_identification(HOSTILE)),
                  (14.5, (2, None), lambda c: c.finish_identification(mount=True)),
                  (14.6, (1, "drill"), lambda c: c.start_identification("drill")),
                  (29.5, (3, None), lambda c: c.finish_identification(mount=False)),
                  (30.2, (4, "none"), lambda c: c.switch_tool("none")),
                  (30.4, (5, None), lambda c: c.retare()),
                  (33.2, (4, "drill"), lambda c: c.switch_tool("drill")),
                  (33.4, (5, None), lambda c: c.retare()),
                  (36.2, (4, HOSTILE), lambda c: c.switch_tool(HOSTILE))]
TEXT = 1 << 20

DRIVER = r"""
#include <string.h>
#include "rt.h"
static rt_state last;

/* action[k] before sample k: 1 start identifying name[k], 2 finish and mount, 3 finish without mounting,
   4 mount the tool named name[k], 5 re-tare. codes[2k]: the action's return code, codes[2k + 1]: the index
   NAME_find_tool gave (action 4). text: "k<TAB>reasons<LF>" at each sample whose flags differ from the last. */
int replay(int n, const double *t, const double *u, const double *g, const int *override, const int *action,
           const char *const *name, int tool, int adc, double adc_low, double adc_high, double *out, int *codes,
           char *text, long text_len)
{
    static rt_state s;
    rt_output o;
    rt_tool_fit f;
    rt_tool_se e;
    long used = 0;
    unsigned previous = 0;
    int k, j;
    if (rt_init(&s, tool)) return -2;
    s.use_adc_limits = adc;
    s.adc_low = adc_low;
    s.adc_high = adc_high;
    for (k = 0; k < n; ++k) {
        int *code = codes + 2 * k;
        if (action[k] == 1) code[0] = rt_start_identification(&s, name[k]);
        else if (action[k] == 2 || action[k] == 3) code[0] = rt_finish_identification(&s, &f, &e, action[k] == 2);
        else if (action[k] == 4) {
            code[1] = rt_find_tool(&s, name[k]);
            code[0] = rt_set_tool(&s, code[1]);
        } else if (action[k] == 5) rt_retare(&s);
""" + STEP_AND_STORE + r"""        if (o.flags != previous && o.flags) {
            char head[32];
            size_t need;
            int m = snprintf(head, sizeof head, "%d\t", k);
            if (used + m + 2 >= text_len) return -3;
            memcpy(text + used, head, (size_t)m);
            used += m;
            need = rt_describe_flags(&s, o.flags, text + used, (size_t)(text_len - used));
            if (used + (long)need + 2 >= text_len) return -3;
            used += (long)need;
            text[used++] = '\n';
            text[used] = '\0';
        }
        previous = o.flags;
    }
    last = s;
    return s.tool;
}

int n_tools(void) { return last.n_tools; }
void counters(double *out)   /* LiveCalibrator.counters' order */
{
    out[0] = (double)last.samples;
    out[1] = (double)last.updates;
    out[2] = (double)last.contacts;
    out[3] = (double)last.retares;
    out[4] = (double)last.switches;
}
const char *tool_name(int i) { return rt_tool_name(&last, i); }
int find_tool(const char *tool_name) { return rt_find_tool(&last, tool_name); }

/* The C's quoting of a tool named `tool_name` at run time (identified in place, adopted with a made-up fit). */
int quoted(const char *tool_name, char *buf, long len)
{
    static rt_state s;
    rt_tool_fit f;
    rt_tool_se e;
    size_t at = 0;
    memset(&f, 0, sizeof f);
    memset(&e, 0, sizeof e);
    f.mass = 1.0;
    rt_init(&s, 0);
    if (rt_start_identification(&s, tool_name) || rt_adopt_identification(&s, &f, &e, 1)) return -1;
    rt_text_tool(&s, buf, (size_t)len, &at, s.tool);
    if ((long)at >= len) return -2;
    buf[at] = '\0';
    return (int)at;
}

/* Fill the library with tools t0, t1, ... by start + adopt; codes[i] is the i-th start's return code. */
int fill(int count, int *codes)
{
    static rt_state s;
    rt_tool_fit f;
    rt_tool_se e;
    char tool_name[16];
    int i;
    memset(&f, 0, sizeof f);
    memset(&e, 0, sizeof e);
    f.mass = 2.0;
    rt_init(&s, 0);
    for (i = 0; i < count; ++i) {
        snprintf(tool_name, sizeof tool_name, "t%d", i);
        codes[i] = rt_start_identification(&s, tool_name);
        if (codes[i] == 0 && rt_adopt_identification(&s, &f, &e, 0)) return -1;
    }
    last = s;
    return s.n_tools;
}

/* start_identification's code for a name, on the library `fill` left; the state is unchanged when it refuses. */
int start_code(const char *tool_name)
{
    rt_state s = last;
    int code = rt_start_identification(&s, tool_name);
    if (code && memcmp(&s, &last, sizeof s)) return 99;
    return code;
}

/* describe_flags into a buffer of `len` bytes (buf may be 0 when len is 0); returns the length it needs. */
long describe(unsigned mask, char *buf, long len)
{
    return (long)rt_describe_flags(&last, mask, buf, (size_t)len);
}

const char *flag_name(unsigned bit) { return rt_flag_name(bit); }

/* The event log `replay` (or `fill`) left: event i (0 = the oldest kept), its text, the count, the dropped. */
int event_count(void) { return rt_event_count(&last); }
unsigned long events_dropped(void) { return rt_events_dropped(&last); }
void clear_events(void) { rt_clear_events(&last); }
const char *event_kind_name(int kind) { return rt_event_kind_name(kind); }
int get_event(int i, double *time, long *fields)   /* fields: sample, kind, flag, tool_from, tool_to */
{
    rt_event ev;
    if (rt_get_event(&last, i, &ev)) return -1;
    *time = ev.time;
    fields[0] = (long)ev.sample;
    fields[1] = ev.kind;
    fields[2] = (long)ev.flag;
    fields[3] = ev.tool_from;
    fields[4] = ev.tool_to;
    return 0;
}
long describe_event(int i, char *buf, long len)
{
    rt_event ev;
    if (rt_get_event(&last, i, &ev)) return -1;
    return (long)rt_describe_event(&last, &ev, buf, (size_t)len);
}
"""


def build(tmp_path, header: str, defines=()):
    """Compile the driver against ``header`` (``defines``: ``-D`` options, e.g. ``RT_MAX_EVENTS=5``)."""
    (tmp_path / "rt.h").write_text(header)
    (tmp_path / "driver.c").write_text("#include <stdio.h>\n" + DRIVER)
    library = tmp_path / "driver.so"
    done = subprocess.run([CC, "-O2", "-std=c99", "-Wall", "-Wextra", "-Werror", "-pedantic", "-shared", "-fPIC",
                           *(f"-D{d}" for d in defines), "driver.c", "-o", str(library), "-lm"], cwd=tmp_path,
                          capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    lib = ctypes.CDLL(str(library))
    for f in ("replay", "n_tools", "find_tool", "quoted", "fill", "start_code", "event_count", "get_event"):
        getattr(lib, f).restype = ctypes.c_int
    lib.describe.restype = lib.describe_event.restype = ctypes.c_long
    lib.events_dropped.restype = ctypes.c_ulong
    lib.tool_name.restype = lib.flag_name.restype = lib.event_kind_name.restype = ctypes.c_char_p
    return lib


def c_replay(lib, time, u, gravity, actions, tool, adc=None):
    """The C over the samples with ``actions`` {k: (code, name)}; (outputs, codes, {k: text}, final tool)."""
    n = time.size
    out, codes = np.zeros((n, FIELDS)), np.zeros((n, 2), np.int32)
    action = np.zeros(n, np.int32)
    names = (ctypes.c_char_p * n)()
    for k, (code, name) in actions.items():
        action[k] = code
        names[k] = None if name is None else name.encode()
    text = ctypes.create_string_buffer(TEXT)
    arrays = [np.ascontiguousarray(x, dtype=float) for x in (time, u, gravity)]
    override = np.full(n, -1, np.int32)
    low, high = adc if adc is not None else (0.0, 0.0)
    tool = lib.replay(n, *(pointer(a) for a in arrays), pointer(override, ctypes.c_int),
                      pointer(action, ctypes.c_int), names, tool, int(adc is not None), ctypes.c_double(low),
                      ctypes.c_double(high), pointer(out), pointer(codes, ctypes.c_int), text, ctypes.c_long(TEXT))
    assert tool >= 0, tool
    lines = text.value.decode().split("\n")[:-1] if text.value else []
    reasons = {}
    for line in lines:
        k, _, reason = line.partition("\t")
        reasons[int(k)] = reason
    return out, codes, reasons, tool


def python_texts(live: LiveCalibrator, time, u, gravity, actions):
    """Python's reasons, one sample at a time (``step``), at each sample whose flags differ from the last."""
    texts, previous = {}, {}
    for k in range(time.size):
        if k in actions:
            actions[k](live)
        flags = live.step(time[k], raw=u[k], gravity=gravity[k]).flags
        if flags and flags.keys() != previous.keys():
            texts[k] = "; ".join(flags.values())
        previous = flags
    return texts


def assert_same_texts(c_texts, py_texts, flags):
    """The C's text at every change of flags equals Python's; the Python text names what the flags say."""
    assert c_texts.keys() == py_texts.keys()
    for k, text in py_texts.items():
        assert c_texts[k] == text, (k, c_texts[k], text)
        assert len(text.split("; ")) >= bin(int(flags[k])).count("1")


def test_a_library_grown_at_run_time_replays_as_python(tmp_path):
    """Identify the drill under a hostile new name (mounted), then under the compiled-in name ``drill`` (replacing
    a wrong drill, not mounted), switch by name to ``none``, ``drill`` and the new name with re-tares, and a
    10 N contact: every output as Python's, the indices Python's order, the contact's reason with the tool's repr."""
    s = LiveScenario(duration=44.0, rate=250.0, hold_s=2.0, move_s=1.0, walk=(0.0, 0.0), ramp=(0.0, 0.0),
                     tools={"drill": DRILL}, contacts=((39.3, 1.5, 10.0),), seed=7)
    rec = simulate_live(s)
    model, mix = gauge_model(1)
    u = np.column_stack([rec.wrench @ mix.T, np.full(rec.time.size, 30.0)])
    wrong = PayloadParameters(1.0, np.zeros(3), np.zeros(3), np.zeros(3), 9.81,
                              fit={"residual_rms": np.r_[np.full(3, 0.05), np.full(3, 0.004)]})
    tools = {"gripper": tool_payload(LiveScenario().tools["gripper"]), "drill": wrong}
    lib = build(tmp_path, generate_c_runtime(model, tools, name="rt"))
    script = LIBRARY_SCRIPT
    at = {when: int(np.searchsorted(rec.time, when)) for when, _, _ in script}
    out, codes, c_texts, tool = c_replay(lib, rec.time, u, rec.gravity, {at[w]: a for w, a, _ in script}, 2)
    live = LiveCalibrator(model, tools=tools, tool="drill")
    ref = python_replay(live, rec.time, u, rec.gravity, None, {at[w]: f for w, _, f in script})
    compare(out, ref)
    order = list(live.tools)
    assert order == ["none", "gripper", "drill", HOSTILE] and live.tool == HOSTILE and tool == 3
    assert live.counters["switches"] == 4 and live.counters["retares"] == 2 and live.counters["contacts"] >= 1
    counters = np.zeros(5)
    lib.counters(pointer(counters))
    assert counters.tolist() == [live.counters[k] for k in ("samples", "updates", "contacts", "retares", "switches")]
    assert codes[[at[w] for w, _, _ in script], 0].tolist() == [0] * len(script)
    assert [codes[at[w], 1] for w in (30.2, 33.2, 36.2)] == [order.index(n) for n in ("none", "drill", HOSTILE)]
    assert lib.n_tools() == 4 and [lib.tool_name(i) for i in range(4)] == [n.encode() for n in order]
    assert lib.find_tool(HOSTILE.encode()) == 3 and lib.find_tool(b"drill") == 2 and lib.find_tool(b"x") == -1
    # The replay did what it claims: the drill identified twice (its m g removed in later holds), updates after
    # each re-tare, and the contact flagged while held, its reason naming the mounted tool as Python's repr does.
    later = rec.holding & (rec.time > 36.5) & (np.abs(rec.contact[:, :3]).max(axis=1) == 0.0)
    assert later.sum() > 200 and np.all(np.abs(out[later, 6:9].mean(axis=0)) < 0.05)
    assert ref["updated"][at[30.4]:at[33.2]].any() and ref["updated"][at[33.4]:at[36.2]].any()
    contact = (np.abs(rec.contact[:, :3]).max(axis=1) > 5.0) & rec.holding
    assert contact.sum() > 100 and np.mean(ref["flags"][contact] & BIT["contact"] != 0) > 0.95
    on = (ref["flags"] & BIT["contact"]) != 0
    raised = np.flatnonzero(on[1:] & ~on[:-1] & (rec.time[1:] > 39.0)) + 1
    assert raised.size and f"wrench the tool {HOSTILE!r} and the bias" in c_texts[int(raised[0])]
    py_texts = python_texts(LiveCalibrator(model, tools=tools, tool="drill"), rec.time, u, rec.gravity,
                            {at[w]: f for w, _, f in script})
    assert_same_texts(c_texts, py_texts, ref["flags"])


@pytest.mark.parametrize("adc", [None, (-500.0, 500.0)])
def test_every_flag_is_described_as_python_describes_it(tmp_path, adc):
    """A replay with a held contact (contact, unexplained), a pinned gauge (saturated, out of range), a gauge frozen
    for DEAD_RUN samples (stuck, then dead) and a temperature excursion, with hostile compiled-in tool names."""
    s = LiveScenario(duration=40.0, rate=250.0, hold_s=3.0, move_s=1.0, walk=(3.0, 0.3), ramp=(20.0, 1.0),
                     contacts=((9.3, 2.0, 10.0),), swaps=((24.0, "drill"),), seed=5)
    rec = simulate_live(s)
    model, mix = gauge_model(1)
    names = {"gripper": HOSTILE, "drill": "caf\u00e9 \u202e'\""}
    tools = {names[n]: tool_payload(t) for n, t in s.tools.items()}
    lib = build(tmp_path, generate_c_runtime(model, tools, name="rt"))
    n = rec.time.size
    temperature = np.where(rec.time < 33.0, 30.0, 50.0)  # beyond the model's 20-45 °C from 33 s on
    u = np.column_stack([rec.wrench @ mix.T + 0.01 * (temperature[:, None] - 30.0), temperature])
    u[1000:1100, 0] = 1e3  # gauge 1 pinned beyond the range and the ADC limits
    freeze = int(0.5 * n)
    u[freeze:freeze + DEAD_RUN + 100, 3] = u[freeze, 3]  # gauge 4 frozen: stuck, then dead
    swap = int(np.searchsorted(rec.time, 24.0))
    out, _, c_texts, _ = c_replay(lib, rec.time, u, rec.gravity, {swap: (4, names["drill"])}, 1, adc)
    live = LiveCalibrator(model, tools=tools, tool=HOSTILE, adc_limits=adc)
    ref = python_replay(live, rec.time, u, rec.gravity, None, {swap: lambda c: c.switch_tool(names["drill"])})
    compare(out, ref)
    for flag in FLAGS[:-1]:  # every flag but the transports' silent
        assert np.any(ref["flags"] & BIT[flag]), flag
    assert np.all(ref["flags"][freeze + STUCK_RUN:freeze + DEAD_RUN - 1] & BIT["stuck"])
    stepped = LiveCalibrator(model, tools=tools, tool=HOSTILE, adc_limits=adc)
    py_texts = python_texts(stepped, rec.time, u, rec.gravity, {swap: lambda c: c.switch_tool(names["drill"])})
    assert_same_texts(c_texts, py_texts, ref["flags"])
    joined = "\n".join(c_texts.values())
    for fragment in (f"the tool {HOSTILE!r}", "channel g4 dead: one value for 2000 samples",
                     f"channel g4 stuck: one value for {STUCK_RUN} samples", "temperature 50 outside",
                     "at the ADC limits -500/500)" if adc else "flat for >= 20 samples"):
        assert fragment in joined, fragment
    # Each flag alone, after the replay: the reason it was last raised with (reason_of), its name if never raised.
    buf = ctypes.create_string_buffer(4096)
    for flag in FLAGS:
        lib.describe(BIT[flag], buf, 4096)
        assert buf.value.decode() == stepped.reason_of(flag)
        assert lib.flag_name(BIT[flag]) == flag.encode()
    assert lib.flag_name(0) is None and lib.flag_name(BIT["stuck"] | BIT["dead"]) is None
    assert lib.flag_name(1 << len(FLAGS)) is None


@pytest.fixture(scope="module")
def toolless_lib(tmp_path_factory):
    """The driver over a degree-1 gauge model with no compiled-in tool, compiled once for the tests that only call
    ``fill``/``describe`` (which start from ``fill``'s fresh state) or ``quoted`` (its own state, initialised per call)."""
    model, _ = gauge_model(1)
    return build(tmp_path_factory.mktemp("toolless"), generate_c_runtime(model, {}, name="rt"))


def test_describe_flags_is_snprintf_style(toolless_lib):
    lib = toolless_lib
    lib.fill(0, pointer(np.zeros(1, np.int32), ctypes.c_int))
    full = "saturated; contact; silent"  # never raised: each flag's name, in bit order; other bits skipped
    mask = BIT["silent"] | BIT["contact"] | BIT["saturated"] | (1 << 20)
    assert lib.describe(mask, None, 0) == len(full)
    for size in (1, 2, 10, len(full), len(full) + 1, 200):
        buf = ctypes.create_string_buffer(b"#" * (size + 4), size + 4)
        assert lib.describe(mask, buf, size) == len(full)
        text = full[:size - 1]
        assert buf.raw[:len(text) + 1] == (text + "\0").encode()  # always NUL-terminated, within size
        assert buf.raw[len(text) + 1:] == b"#" * (size + 3 - len(text))  # and nothing written past the NUL
    assert lib.describe(0, ctypes.create_string_buffer(4), 4) == 0


def test_run_time_names_are_checked_and_the_library_has_fixed_size(tmp_path):
    model, _ = gauge_model(1)
    lib = build(tmp_path, generate_c_runtime(model, {"gripper": tool_payload(LiveScenario().tools["gripper"])},
                                             name="rt"))
    codes = np.zeros(C_RUNTIME_MAX_TOOLS + 1, np.int32)
    assert lib.fill(C_RUNTIME_MAX_TOOLS + 1, pointer(codes, ctypes.c_int)) == 2 + C_RUNTIME_MAX_TOOLS
    assert codes.tolist() == [0] * C_RUNTIME_MAX_TOOLS + [TOOL_STATUS["LIBRARY_FULL"]]
    assert [lib.find_tool(f"t{i}".encode()) for i in range(C_RUNTIME_MAX_TOOLS + 1)] == \
        [*range(2, 2 + C_RUNTIME_MAX_TOOLS), -1]
    # Full: a name the library has may be identified again (it replaces that tool), a new one may not.
    for name, code in ((b"t3", 0), (b"gripper", 0), (b"t99", TOOL_STATUS["LIBRARY_FULL"]),
                       (b"", TOOL_STATUS["NO_NAME"]), (None, TOOL_STATUS["NO_NAME"]),
                       (b"none", TOOL_STATUS["NAME_RESERVED"]),
                       (b"a" * (C_RUNTIME_MAX_TOOL_NAME + 1), TOOL_STATUS["NAME_TOO_LONG"]),
                       (b"a" * (C_RUNTIME_MAX_TOOL_NAME + 500), TOOL_STATUS["NAME_TOO_LONG"])):
        assert lib.start_code(name) == code, name
    lib.fill(1, pointer(codes, ctypes.c_int))  # room again: the longest name fits, exactly
    assert lib.start_code(b"a" * C_RUNTIME_MAX_TOOL_NAME) == 0
    # The status codes do not collide with the identification's.
    assert not set(TOOL_STATUS.values()) - {0} & set(STATUS.values())
    # Python refuses the same names (Python has no length or count limit).
    live = LiveCalibrator(model)
    for bad in ("", "none"):
        with pytest.raises(FtcalError, match="a tool needs a name other than 'none'"):
            live.start_identification(bad)


@pytest.mark.parametrize("name", ["plain", "it's", 'say "hi"', "both ' and \"", "back\\slash", "tab\tnl\ncr\r",
                                  "\x01\x1f\x7f", HOSTILE, "caf\u00e9", "nb\u00a0sp\u00ad\u0085", "??=??/"])
def test_a_run_time_name_is_read_back_and_quoted_as_python_quotes_it(toolless_lib, name):
    lib = toolless_lib
    buf = ctypes.create_string_buffer(512)
    assert lib.quoted(name.encode(), buf, 512) > 0
    assert buf.value.decode() == repr(name)


def test_compiled_in_hostile_names_are_string_literals_read_back_exactly(tmp_path):
    names = [HOSTILE, "*/ #include <stdlib.h> /*", "??=??(??)??<??>??'??!??-", "\\", '"', "\u202e\u00e9\U0001f600",
             "a\rb\fc\vd"]
    model, _ = gauge_model(1)
    payload = tool_payload(LiveScenario().tools["gripper"])
    header = generate_c_runtime(model, {n: payload for n in names}, name="rt")
    lib = build(tmp_path, header)
    lib.fill(0, pointer(np.zeros(1, np.int32), ctypes.c_int))
    assert [lib.tool_name(i) for i in range(len(names) + 1)] == [n.encode() for n in ["none", *names]]
    assert [lib.find_tool(n.encode()) for n in names] == list(range(1, len(names) + 1))
    for bad in ("a\0b", "", "none"):
        with pytest.raises(FtcalError, match="needs a name other than 'none'"):
            generate_c_runtime(model, {bad: payload}, name="rt")
