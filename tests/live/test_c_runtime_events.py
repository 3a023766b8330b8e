"""The generated C runtime's event log against :class:`ftcal.live.LiveCalibrator`'s ``events``.

Reference: the Python calibrator fed the same samples and calls (a re-tare before the first sample, a
tool identified in place under a new name and mounted, one identified under a compiled-in name, switches by
name, re-tares, a frozen gauge, a held contact, a temperature excursion): its events, less the kinds the C
cannot cause (:data:`ftcal.live.c_events.PYTHON_ONLY`), are the C's in order (time, flag, kind, text), the
C's tool indices are Python's ``list(live.tools)``; a ring of 5 keeps the last 5 and counts the others.
Hand counts for the ring without text (``NAME_NO_TEXT``).
"""

from __future__ import annotations

import ctypes
import math
import subprocess

import numpy as np
import pytest

from ftcal.core.limits import C_RUNTIME_MAX_EVENTS
from ftcal.live import LiveCalibrator
from ftcal.live.c_events import COUNTED, EVENT_KINDS, PYTHON_ONLY
from ftcal.live.c_runtime import generate_c_runtime
from ftcal.payload.parameters import PayloadParameters
from ftcal.sim.live_scenario import LiveScenario, simulate_live

from test_c_runtime import CC, compare, gauge_model, pointer, python_replay, tool_payload
from test_c_runtime_library import DRILL, HOSTILE, LIBRARY_SCRIPT, build, c_replay

pytestmark = pytest.mark.skipif(CC is None, reason="no C compiler `cc`")
BY_CODE = {code: (flag, kind) for code, flag, kind in EVENT_KINDS.values()}


@pytest.fixture(scope="module")
def replay():
    """The scripted replay: the model, header, samples, the C's actions and Python's reference (outputs, events)."""
    s = LiveScenario(duration=44.0, rate=250.0, hold_s=2.0, move_s=1.0, walk=(0.0, 0.0), ramp=(0.0, 0.0),
                     tools={"drill": DRILL}, contacts=((39.3, 1.5, 10.0),), seed=7)
    rec = simulate_live(s)
    model, mix = gauge_model(1)
    temperature = np.where((rec.time > 41.5) & (rec.time < 42.5), 50.0, 30.0)  # beyond the model's 20-45 °C
    u = np.column_stack([rec.wrench @ mix.T, temperature])
    frozen = int(np.searchsorted(rec.time, 31.0))
    u[frozen:frozen + 300, 3] = u[frozen, 3]  # gauge 4 stuck while the others move
    wrong = PayloadParameters(1.0, np.zeros(3), np.zeros(3), np.zeros(3), 9.81,
                              fit={"residual_rms": np.r_[np.full(3, 0.05), np.full(3, 0.004)]})
    tools = {"gripper": tool_payload(LiveScenario().tools["gripper"]), "drill": wrong}
    header = generate_c_runtime(model, tools, name="rt")
    # a re-tare before the first sample (no time yet: NaN), then the tool library's script
    script = [(0.0, (5, None), lambda c: c.retare()), *LIBRARY_SCRIPT]
    python_only = [(43.0, lambda c: c.add_tool("spare", wrong)), (43.1, lambda c: c.set_silent(True, "no data"))]
    at = {when: int(np.searchsorted(rec.time, when)) for when in [w for w, _, _ in script] + [w for w, _ in python_only]}
    live = LiveCalibrator(model, tools=tools, tool="drill")
    ref = python_replay(live, rec.time, u, rec.gravity, None,
                        {at[w]: f for w, _, f in script} | {at[w]: f for w, f in python_only})
    actions = {at[w]: a for w, a, _ in script}
    return dict(rec=rec, u=u, header=header, actions=actions, ref=ref, live=live,
                calls={at[w] for w, _, _ in script})


def c_events(lib, tools: list[str]):
    """The C's kept events as (time, flag, kind, text) and their sample, tool_from, tool_to."""
    events, extra = [], []
    fields = np.zeros(5, np.int64)
    time = ctypes.c_double()
    buf = ctypes.create_string_buffer(4096)
    for i in range(lib.event_count()):
        assert lib.get_event(i, ctypes.byref(time), pointer(fields, ctypes.c_long)) == 0
        need = lib.describe_event(i, buf, 4096)
        assert need == len(buf.value) < 4096
        sample, code, flag, tool_from, tool_to = (int(v) for v in fields)
        subject, kind = BY_CODE[code]
        assert lib.event_kind_name(code).decode() == kind
        events.append((time.value, subject or lib.flag_name(flag).decode(), kind, buf.value.decode()))
        extra.append((sample, tools[tool_from] if tool_from >= 0 else None, tools[tool_to] if tool_to >= 0 else None))
    assert lib.get_event(lib.event_count(), ctypes.byref(time), pointer(fields, ctypes.c_long)) == -1
    return events, extra


def same(c, py):
    """Event tuples equal, times NaN where both are (a call before the first sample)."""
    assert len(c) == len(py)
    for a, b in zip(c, py):
        assert (math.isnan(a[0]) and math.isnan(b[0])) or a[0] == b[0], (a, b)
        assert a[1:] == b[1:], (a, b)


def python_events(live):
    kept = [e for e in live.events if (e[1], e[2]) not in PYTHON_ONLY + COUNTED]  # the C counts those
    assert len(live.events) < 1000  # Python's deque kept every event: the reference is complete
    return kept, [e for e in live.events if (e[1], e[2]) in PYTHON_ONLY]


def test_the_event_log_is_python_s(tmp_path, replay):
    rec, ref, live = replay["rec"], replay["ref"], replay["live"]
    lib = build(tmp_path, replay["header"])
    out, codes, _, _ = c_replay(lib, rec.time, replay["u"], rec.gravity, replay["actions"], 2)
    compare(out, ref)
    assert codes[sorted(replay["calls"]), 0].tolist() == [0] * len(replay["calls"])
    kept, only = python_events(live)
    assert [(e[1], e[2]) for e in only] == [("tool", "added"), ("silent", "raised")]
    events, extra = c_events(lib, list(live.tools))
    assert lib.events_dropped() == max(0, len(kept) - C_RUNTIME_MAX_EVENTS)
    assert len(kept) <= C_RUNTIME_MAX_EVENTS, "the script should fit the default ring"
    same(events, kept)
    # The replay did what it claims: every kind the C logs, and these flags raised and cleared.
    kinds = {(e[1], e[2]) for e in kept}
    for kind in ("switched", "identifying", "identified"):
        assert ("tool", kind) in kinds, kind
    assert ("bias", "retare") in kinds
    for flag in ("contact", "stuck", "temperature"):
        assert {(flag, "raised"), (flag, "cleared")} <= kinds, flag
    # Sample counters: a flag's event is its sample; a call's comes before the sample it was made at.
    for (time, _, kind, text), (sample, tool_from, tool_to) in zip(events, extra):
        if kind in ("raised", "cleared", "rollback", "adapted", "locked_out", "reacquired", "undone"):
            assert time == rec.time[sample]  # the sample's own events (flags, drift test, self-check)
        else:
            assert sample in replay["calls"]
            assert math.isnan(time) if sample == 0 else time == rec.time[sample - 1]
        if kind == "switched":  # the indices are Python's list(live.tools) positions
            assert text == f"tool {tool_from!r} -> {tool_to!r}"
        if kind == "identified":
            assert text.startswith(f"tool {tool_to!r} identified from ")
    assert lib.tool_name(3) == HOSTILE.encode()


def test_a_full_ring_keeps_the_newest_and_counts_the_rest(tmp_path, replay):
    rec = replay["rec"]
    lib = build(tmp_path, replay["header"], defines=["RT_MAX_EVENTS=5"])
    c_replay(lib, rec.time, replay["u"], rec.gravity, replay["actions"], 2)
    kept, _ = python_events(replay["live"])
    events, _ = c_events(lib, list(replay["live"].tools))
    assert lib.event_count() == 5 and lib.events_dropped() == len(kept) - 5
    same(events, kept[-5:])
    lib.clear_events()
    assert lib.event_count() == 0 and lib.events_dropped() == 0


NO_TEXT_DRIVER = r"""
#define RT_NO_TEXT
#define RT_MAX_EVENTS 3
#include "rt.h"
int main(void)
{
    static rt_state s;
    rt_event ev;
    int k;
    if (rt_init(&s, 0) || rt_event_count(&s) != 0) return 1;
    if (rt_set_tool(&s, 7) != -1 || rt_event_count(&s) != 0) return 2;   /* refused: nothing logged */
    for (k = 0; k < 5; ++k) rt_retare(&s);
    if (rt_set_tool(&s, 1) || rt_event_count(&s) != 3 || rt_events_dropped(&s) != 3) return 3;
    if (rt_get_event(&s, 2, &ev) || ev.kind != RT_EVENT_TOOL_SWITCHED || ev.tool_from != 0 || ev.tool_to != 1) return 4;
    if (rt_get_event(&s, 0, &ev) || ev.kind != RT_EVENT_RETARE || ev.sample != 0 || ev.time == ev.time) return 5;
    if (rt_get_event(&s, 3, &ev) != -1 || rt_get_event(&s, -1, &ev) != -1) return 6;
    rt_clear_events(&s);
    if (rt_event_count(&s) != 0 || rt_events_dropped(&s) != 0) return 7;
    return 0;
}
"""


def test_the_ring_without_text(tmp_path):
    """Five re-tares and a switch in a ring of 3: the switch and the last two re-tares kept, three dropped (hand
    count); no stdio needed (``RT_NO_TEXT``)."""
    model, _ = gauge_model(1)
    (tmp_path / "rt.h").write_text(generate_c_runtime(model, {"gripper": tool_payload(DRILL)}, name="rt"))
    (tmp_path / "main.c").write_text(NO_TEXT_DRIVER)
    done = subprocess.run([CC, "-O2", "-std=c99", "-Wall", "-Wextra", "-Werror", "-pedantic", "main.c", "-o",
                           "main", "-lm"], cwd=tmp_path, capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    assert "snprintf" not in subprocess.run(["nm", "-u", "main"], cwd=tmp_path, capture_output=True,
                                            text=True).stdout
    assert subprocess.run([str(tmp_path / "main")]).returncode == 0


def test_describe_event_is_snprintf_style(tmp_path, replay):
    rec = replay["rec"]
    lib = build(tmp_path, replay["header"])
    c_replay(lib, rec.time, replay["u"], rec.gravity, replay["actions"], 2)
    full = c_events(lib, list(replay["live"].tools))[0][1][3]  # "identifying tool '...': hold ..."
    assert full.startswith("identifying tool ")
    raw = full.encode()
    assert lib.describe_event(1, None, 0) == len(raw)
    for size in (1, 2, 10, len(raw), len(raw) + 1):
        buf = ctypes.create_string_buffer(b"#" * (size + 4), size + 4)
        assert lib.describe_event(1, buf, size) == len(raw)
        assert buf.raw[:size] == raw[:size - 1] + b"\0" and buf.raw[size:] == b"#" * 4
