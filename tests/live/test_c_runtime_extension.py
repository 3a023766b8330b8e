"""The live step's C core as the extension ``ftcal.live._core`` (the source ``convert --to c-runtime`` ships):
block for block the numbers of the Python calibrator to 1e-9, on a recording with drift, a contact, a tool swap,
a re-tare and a frozen gauge; and one clear line when it is not built."""

from __future__ import annotations

import shutil

import numpy as np
import pytest

import ftcal.live.core as live_core
from ftcal.live import LiveCalibrator
from ftcal.live.health import BIT
from ftcal.runtime.errors import FtcalError
from test_c_runtime import gauge_model, python_replay, tool_payload

pytestmark = pytest.mark.skipif(shutil.which("cc") is None, reason="no C compiler: the extension is not built")


def as_fields(r: dict) -> np.ndarray:
    """The core's outputs in the C runtime tests' 27 columns (test_c_runtime.compare)."""
    return np.column_stack([r["calibrated"], r["compensated"], r["bias"], r["bias_std"], r["chi2"],
                            r["static"].astype(int) + 2 * r["updated"].astype(int), r["flags"]])


def test_the_extension_steps_blocks_as_the_python_calibrator(scenario_c):
    from test_c_runtime import compare

    s, rec = scenario_c
    model, mix = gauge_model(3)
    tools = {name: tool_payload(tool) for name, tool in s.tools.items()}
    n = rec.time.size
    temperature = np.where(rec.time < 33.0, 30.0, 50.0)  # beyond the model's 20-45 °C from 33 s on
    u = np.column_stack([rec.wrench @ mix.T + 0.01 * (temperature[:, None] - 30.0), temperature])
    u[n // 2:n // 2 + 300, 3] = u[n // 2, 3]  # gauge 4 freezes while the others move
    swap, retare = int(np.searchsorted(rec.time, 24.0)), int(np.searchsorted(rec.time, 30.5))
    core = live_core.LiveCore(model, tools, tool=1)
    parts = []
    for a, b, action in ((0, swap, None), (swap, retare, lambda: core.set_tool(2)), (retare, n, core.retare)):
        if action is not None:
            action()
        for c in range(a, b, 997):  # blocks of any size continue the state
            parts.append(as_fields(core.run(rec.time[c:min(c + 997, b)], u[c:min(c + 997, b)],
                                            rec.gravity[c:min(c + 997, b)])))
    out = np.concatenate(parts)
    live = LiveCalibrator(model, tools=tools, tool="gripper")
    ref = python_replay(live, rec.time, u, rec.gravity, None,
                        {swap: lambda c: c.switch_tool("drill"), retare: lambda c: c.retare()})
    compare(out, ref)
    counters = core.counters()
    assert [counters[k] for k in ("samples", "updates", "contacts", "retares", "switches")] == \
        [live.counters[k] for k in ("samples", "updates", "contacts", "retares", "switches")]
    for flag in ("contact", "stuck", "temperature"):
        assert np.any(ref["flags"] & BIT[flag]), flag
    # Truth: the held 10 N contact is flagged while the robot holds still.
    held = (np.abs(rec.contact[:, :3]).max(axis=1) > 5.0) & rec.holding
    assert held.sum() > 100 and np.mean(out[held, 26].astype(int) & BIT["contact"] != 0) > 0.95


def test_a_refused_sample_stops_the_block_there(scenario_c):
    s, rec = scenario_c
    model, mix = gauge_model(1)
    core = live_core.LiveCore(model, {}, tool=0)
    u = np.column_stack([rec.wrench[:50] @ mix.T, np.full(50, 30.0)])
    time = rec.time[:50].copy()
    time[20] = time[19]  # time that does not increase
    with pytest.raises(FtcalError, match="sample 20 of the block was refused"):
        core.run(time, u, rec.gravity[:50])
    assert core.counters()["samples"] == 20


def test_without_the_extension_one_line_says_how_to_build_it(monkeypatch):
    monkeypatch.setattr(live_core, "_core", None)
    with pytest.raises(FtcalError, match=r"not built: reinstall ftcal on a machine with a C compiler") as err:
        live_core.require_core()
    assert "\n" not in str(err.value)
    with pytest.raises(FtcalError, match=r"not built: reinstall ftcal") as err:  # the calibrator runs on it
        LiveCalibrator()
    assert "\n" not in str(err.value)


@pytest.fixture(scope="module")
def scenario_c():
    from ftcal.sim.live_scenario import LiveScenario, simulate_live

    s = LiveScenario(duration=40.0, rate=250.0, hold_s=3.0, move_s=1.0, walk=(3.0, 0.3), ramp=(20.0, 1.0),
                     contacts=((9.3, 2.0, 10.0),), swaps=((24.0, "drill"),), seed=5)
    return s, simulate_live(s)


def test_the_model_evaluated_in_the_core_s_call_is_the_model_s_prediction(scenario_c):
    """``LiveCore.set_model`` + ``step_raw`` (the table of ftcal.core's kernels, evaluated in C per sample) against
    ``model.predict`` (the compiled block kernel, or numpy), degree 3 with a temperature input, inputs beyond the
    training range included."""
    s, rec = scenario_c
    model, mix = gauge_model(3)
    n = 400
    u = np.column_stack([rec.wrench[:n] @ mix.T * 1.5, np.linspace(10.0, 60.0, n)])  # also outside the range
    core = live_core.LiveCore(model, {}, tool=0)
    assert core.set_model(model)
    out = np.empty(live_core.FIELDS)
    got = []
    for k in range(n):
        assert core.step_raw(rec.time[k], u[k], rec.gravity[k], -1, out) >= 0
        got.append(out[0:6].copy())
    expected = model.predict(u, warn_out_of_range=False)
    np.testing.assert_allclose(got, expected, rtol=1e-12, atol=1e-12 * np.abs(expected).max())
