"""Identification in place in the generated C runtime (``NAME_start_identification`` / ``NAME_finish_identification``).

The reference is :meth:`ftcal.live.LiveCalibrator.finish_identification` (the batch estimator of
``ftcal payload`` on the collected holds) fed the same samples with the same calls; the C must agree
to 1e-9 (mass, COM, bias, their standard errors, residuals, variance inflation) and exactly (status,
weighting, jackknife blocks, hold counts, flags). The simulation's truth checks both: the tool's mass,
COM and the sensor's bias lie within their standard errors of the truth, and once the tool is mounted
the compensated force in every hold is noise (the tool's m·g is removed). Degenerate poses are
refused where hand computation says the regressor loses rank.
"""

from __future__ import annotations

import ctypes
import warnings

import numpy as np
import pytest

from ftcal.live import LiveCalibrator
from ftcal.live.c_identify import STATUS
from ftcal.live.c_runtime import generate_c_runtime
from ftcal.payload.identify import identify_from_statistics
from ftcal.runtime.errors import FtcalError, UndeterminedWarning
from ftcal.sim.live_scenario import LiveScenario, Tool, simulate_live

from test_c_runtime import CC, FIELDS, STEP_AND_STORE, compare, compile_driver, gauge_model, pointer, python_replay

pytestmark = pytest.mark.skipif(CC is None, reason="no C compiler `cc`")
FIT = 44  # per finish: mass, com 3, bias 6, se (mass, com 3, bias 6), rms 6, vif 10, 8 counts
DRILL = Tool(2.1, (0.02, 0.01, 0.09))
PARAMETERS = ("m", "mcx", "mcy", "mcz", "Fx_bias", "Fy_bias", "Fz_bias", "Tx_bias", "Ty_bias", "Tz_bias")

DRIVER = r"""
#include <string.h>
#include "rt.h"
/* action[k] before sample k: 0 nothing, 1 start identifying, 2 finish and mount, 3 finish without mounting,
   4 finish on a copy of the state and adopt the tool, mounted (as a controller does outside its real-time loop) */
int replay(int n, const double *t, const double *u, const double *g, const int *override, const int *action,
           int tool, double *out, double *fits, int *status)
{
    rt_state s;
    rt_output o;
    rt_tool_fit f;
    rt_tool_se e;
    static rt_state copy;
    int k, j, done = 0;
    if (rt_init(&s, tool)) return -2;
    for (k = 0; k < n; ++k) {
        if (action[k] == 1 && rt_start_identification(&s, "drill")) return -4;
        else if (action[k] >= 2) {
            double *x = fits + 44 * done;
            if (action[k] == 4) {
                copy = s;
                status[done] = rt_finish_identification(&copy, &f, &e, 0);
                if (status[done] == 0 && rt_adopt_identification(&s, &f, &e, 1)) return -3;
            } else {
                status[done] = rt_finish_identification(&s, &f, &e, action[k] == 2);
            }
            x[0] = f.mass;
            for (j = 0; j < 3; ++j) x[1 + j] = f.com[j];
            for (j = 0; j < 6; ++j) x[4 + j] = f.bias[j];
            x[10] = e.mass;
            for (j = 0; j < 3; ++j) x[11 + j] = e.com[j];
            for (j = 0; j < 6; ++j) x[14 + j] = e.bias[j];
            for (j = 0; j < 6; ++j) x[20 + j] = f.residual_rms[j];
            for (j = 0; j < 10; ++j) x[26 + j] = f.variance_inflation[j];
            x[36] = f.poorly_excited;
            x[37] = f.undetermined;
            x[38] = f.weighted;
            x[39] = f.jackknife_blocks;
            x[40] = f.n_holds;
            x[41] = (double)f.n_samples;
            x[42] = (double)f.holds_dropped;
            x[43] = f.held;
            done += 1;
        }
""" + STEP_AND_STORE + r"""    }
    return s.tool;
}

/* A tool that is not one (mass 0, a COM or a standard error not finite) is not adopted, and nothing changes;
   the identified tool cannot be mounted before there is one. */
int adopt_refuses(void)
{
    rt_state s, before;
    rt_tool_fit f;
    rt_tool_se e;
    int refused;
    rt_init(&s, 0);
    rt_start_identification(&s, "drill");
    before = s;
    memset(&f, 0, sizeof f);
    memset(&e, 0, sizeof e);
    refused = rt_adopt_identification(&s, &f, &e, 1) == -1 && rt_set_tool(&s, RT_N_TOOLS) == -1;
    f.mass = 1.0;
    f.com[2] = HUGE_VAL;
    refused = refused && rt_adopt_identification(&s, &f, &e, 1) == -1;
    f.com[2] = 0.05;
    e.bias[4] = HUGE_VAL;
    refused = refused && rt_adopt_identification(&s, &f, &e, 1) == -1;
    return refused && memcmp(&s, &before, sizeof s) == 0;
}
"""


def build(tmp_path, header: str):
    lib = compile_driver(tmp_path, header, DRIVER)
    lib.replay.restype = lib.adopt_refuses.restype = ctypes.c_int
    return lib


def replay_c(lib, time, u, gravity, override, action):
    """The C over the samples; returns (per-sample outputs, fits, statuses, the tool mounted at the end)."""
    n = time.size
    finishes = int(np.sum(action >= 2))
    out, fits, status = np.zeros((n, FIELDS)), np.zeros((max(finishes, 1), FIT)), np.zeros(max(finishes, 1), np.int32)
    arrays = [np.ascontiguousarray(x, dtype=float) for x in (time, u, gravity)]
    ints = [np.ascontiguousarray(x, dtype=np.int32) for x in (override, action)]
    tool = lib.replay(n, *(pointer(a) for a in arrays), *(pointer(a, ctypes.c_int) for a in ints), 0, pointer(out),
                      pointer(fits), pointer(status, ctypes.c_int))
    assert tool >= 0, tool
    return out, fits[:finishes], status[:finishes], tool


def recording(poses: int, seed: int):
    """A drill held still in ``poses`` random orientations (2 s each, 1 s moves), constant bias, 250 Hz."""
    s = LiveScenario(duration=3.0 * poses - 1.0, rate=250.0, hold_s=2.0, move_s=1.0, walk=(0.0, 0.0),
                     ramp=(0.0, 0.0), tools={"drill": DRILL}, seed=seed)
    rec = simulate_live(s)
    model, mix = gauge_model(1)
    u = np.column_stack([rec.wrench @ mix.T, np.full(rec.time.size, 30.0)])
    return rec, model, u


class Finishes:
    """Python's side of each finish: the payload (or the refusal), and the batch fit on the same holds."""

    def __init__(self):
        self.results = []

    def __call__(self, mount: bool):
        def act(live: LiveCalibrator):
            holds = list(live.identifying.holds)
            try:
                payload = live.finish_identification(mount=mount)
            except FtcalError as exc:
                self.results.append((None, None, str(exc)))
                return
            total = holds[0]
            for h in holds[1:]:
                total = total + h
            fit = identify_from_statistics({"tool": total}, clusters=holds, cross_validate=False)
            self.results.append((payload, fit, len(holds)))
        return act


def assert_same_fit(c, payload, fit, n_holds):
    """The C's fit row against the Python payload and batch fit."""
    close = dict(rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(c[0], payload.mass, **close)
    np.testing.assert_allclose(c[1:4], payload.com, **close)
    np.testing.assert_allclose(c[4:10], payload.bias, **close)
    se = payload.stderr
    np.testing.assert_allclose(c[10:20], np.r_[se["mass"], se["com"], se["force_bias"], se["torque_bias"]], **close)
    np.testing.assert_allclose(c[20:26], payload.fit["residual_rms"], **close)
    np.testing.assert_allclose(c[26:36], fit.variance_inflation, **close)
    assert int(c[36]) == sum(1 << PARAMETERS.index(p) for p in fit.poorly_excited)
    assert int(c[38]) == (fit.weighting == "wls")
    # Python's text counts the holds; the C counts those that could be left out (the jackknife's refits).
    assert fit.stderr_kind == (f"grouped jackknife ({n_holds} contiguous blocks)" if c[39] >= 2 else
                               "classical (no time block can be left out without losing a parameter)")
    assert int(c[39]) <= n_holds
    assert int(c[40]) == n_holds and int(c[41]) == fit.n_samples
    unknown = fit.undetermined
    assert int(c[37]) == (0 if unknown is None else sum(1 << PARAMETERS.index(p) for p in unknown.parameters))
    assert int(c[43]) == (0 if unknown is None else sum(1 << PARAMETERS.index(p) for p in unknown.held))


@pytest.mark.parametrize("finish_action", [2, 4])
def test_a_tool_identified_in_place_matches_python_and_the_truth(tmp_path, finish_action):
    """``finish_action`` 4: the finish runs on a copy of the state, and the tool is adopted (the same result)."""
    rec, model, u = recording(poses=8, seed=3)
    lib = build(tmp_path, generate_c_runtime(model, {}, name="rt"))
    n = rec.time.size
    finish = int(np.searchsorted(rec.time, 20.5))  # during the 7th move (holds at 3k to 3k + 2 s): seven holds
    action = np.zeros(n, int)
    action[0], action[finish] = 1, finish_action
    out, fits, status, tool = replay_c(lib, rec.time, u, rec.gravity, np.full(n, -1), action)
    finishes = Finishes()
    live = LiveCalibrator(model, tool="none")
    ref = python_replay(live, rec.time, u, rec.gravity, None,
                        {0: lambda c: c.start_identification("drill"), finish: finishes(True)})
    payload, fit, n_holds = finishes.results[0]
    assert status.tolist() == [STATUS["OK"]] and n_holds == 7
    assert_same_fit(fits[0], payload, fit, n_holds)
    assert tool == 1 and live.tool == "drill"  # the first slot after the compiled-in tools, mounted
    compare(out, ref)  # every sample, before (no bias updates, no contact flags) and after the mount
    assert not ref["updated"][:finish].any() and ref["updated"][finish:].any()
    # Truth: the simulated drill and bias lie within 4 standard errors of both estimates.
    se = fits[0, 10:20]
    truth = np.r_[DRILL.mass, DRILL.com, rec.bias[0]]
    assert np.all(np.abs(fits[0, :10] - truth) < 4.0 * se), (fits[0, :10] - truth) / se
    assert np.all(se < np.r_[0.01, np.full(3, 0.002), np.full(3, 0.05), np.full(3, 0.005)])  # and they are small
    # Physics: with the tool mounted, the compensated force in each later hold is noise (m g removed).
    later = rec.holding & (np.arange(n) > finish)
    assert later.sum() > 250
    force = out[later, 6:9]
    assert np.all(np.abs(force.mean(axis=0)) < 0.05) and np.all(force.std(axis=0) < 0.1)


def test_too_few_holds_are_refused_and_collecting_goes_on(tmp_path):
    rec, model, u = recording(poses=4, seed=8)
    lib = build(tmp_path, generate_c_runtime(model, {}, name="rt"))
    n = rec.time.size
    early, late = int(np.searchsorted(rec.time, 5.5)), n - 1  # two holds, then four
    action = np.zeros(n, int)
    action[0], action[early], action[late] = 1, 3, 3
    _, fits, status, tool = replay_c(lib, rec.time, u, rec.gravity, np.full(n, -1), action)
    finishes = Finishes()
    live = LiveCalibrator(model, tool="none")
    python_replay(live, rec.time, u, rec.gravity, None, {0: lambda c: c.start_identification("drill"),
                                                         early: finishes(False), late: finishes(False)})
    refused, (payload, fit, n_holds) = finishes.results
    assert refused[0] is None and "2 static hold(s)" in refused[2]
    assert status.tolist() == [STATUS["TOO_FEW_HOLDS"], STATUS["OK"]] and int(fits[0, 40]) == 2
    assert_same_fit(fits[1], payload, fit, n_holds)
    assert n_holds == 4 and tool == 0 and live.tool == "none"  # not mounted


def held_poses(gravity_of_hold, samples=200, rate=250.0, noise=(0.05, 0.05, 0.05, 0.004, 0.004, 0.004)):
    """Holds of ``samples`` static samples at the given gravity vectors, 20 moving samples between them."""
    rng = np.random.default_rng(1)
    rows, static = [], []
    for g in gravity_of_hold:
        rows += [g] * (samples + 20)
        static += [1] * samples + [0] * 20
    g = np.array(rows, float)
    n = g.shape[0]
    mc = DRILL.mass * np.asarray(DRILL.com)
    wrench = np.column_stack([DRILL.mass * g, np.cross(mc, g)]) + [0.5, -0.3, 0.2, 0.01, 0.02, -0.01]
    wrench += rng.normal(size=(n, 6)) * np.asarray(noise)
    return np.arange(n) / rate, g, wrench, np.array(static)


def bits(names) -> int:
    return sum(1 << PARAMETERS.index(p) for p in names)


def degenerate_replay(tmp_path, gravity):
    """The C and Python over holds at the given gravity vectors (static flags given), finishing at the end."""
    time, g, wrench, static = held_poses(gravity)
    model, mix = gauge_model(1)
    u = np.column_stack([wrench @ mix.T, np.full(time.size, 30.0)])
    lib = build(tmp_path, generate_c_runtime(model, {}, name="rt"))
    action = np.zeros(time.size, int)
    action[0], action[-1] = 1, 2
    out, fits, status, tool = replay_c(lib, time, u, g, static, action)
    finishes = Finishes()
    live = LiveCalibrator(model, tool="none")
    ref = python_replay(live, time, u, g, static.astype(bool),
                        {0: lambda c: c.start_identification("drill"), time.size - 1: finishes(True)})
    return out, fits[0], status[0], tool, finishes.results[0], ref


def test_poses_that_leave_the_mass_undetermined_are_refused_by_both(tmp_path):
    # Gravity never changes: m g_z and the z force bias add up; m c_z x g = 0; m c_x, m c_y and the y, x
    # torque biases add up. Involved: m, all of m c, Fz, Tx, Ty biases (Fx, Fy, Tz are determined).
    _, fit, status, tool, (payload, _, refusal), _ = degenerate_replay(tmp_path, [(0.0, 0.0, -9.81)] * 3)
    assert status == STATUS["MASS_UNDETERMINED"] and tool == 0
    assert int(fit[37]) == bits(("m", "mcx", "mcy", "mcz", "Fz_bias", "Tx_bias", "Ty_bias"))
    assert payload is None and "do not determine the mass" in refusal


def test_a_com_component_the_poses_leave_undetermined_is_held_at_zero_by_both(tmp_path):
    # Tool down, up, down: g_z = ±9.81 separates the mass from the z bias, but c_z never meets gravity.
    with pytest.warns(UndeterminedWarning, match="centre of mass"):
        out, fit, status, tool, (payload, batch, n_holds), ref = degenerate_replay(
            tmp_path, [(0.0, 0.0, -9.81), (0.0, 0.0, 9.81), (0.0, 0.0, -9.81)])
    assert status == STATUS["OK"] and tool == 1
    assert payload.undetermined.parameters == ("mcz",) and int(fit[37]) == int(fit[43]) == bits(("mcz",))
    assert fit[3] == 0.0 and np.isnan(fit[13]) and np.isinf(fit[29])  # c_z held at 0, no SE, infinite VIF
    # Leaving out the tool-up hold leaves gravity one way only (mass and z bias confounded): two refits.
    assert int(fit[39]) == 2
    assert_same_fit(fit, payload, batch, n_holds)
    compare(out, ref)


def unit_rows(seed: int, k: int) -> np.ndarray:
    x = np.random.default_rng(seed).normal(size=(k, 3))
    return 9.81 * x / np.linalg.norm(x, axis=1, keepdims=True)


@pytest.mark.parametrize("case, gravity, noise, weighting, blocks", [
    # Fx a hundred times noisier than Fy, Fz: plain least squares lets Fx's noise into the mass, which
    # Fy and Fz of held-out holds then miss; weighting the axes predicts them better (Python keeps it).
    ("weighted", unit_rows(2, 8), (5.0, 0.05, 0.05, 0.004, 0.004, 0.004), "wls", 8),
    # Tool down, up, sideways: full rank, but leaving any hold out leaves two gravity directions, which
    # cannot separate the COM along their difference: no jackknife, classical standard errors.
    ("classical", [(0.0, 0.0, -9.81), (0.0, 0.0, 9.81), (9.81, 0.0, 0.0)], (0.05,) * 3 + (0.004,) * 3, "ols", 0),
])
def test_weighting_and_classical_errors_follow_python(tmp_path, case, gravity, noise, weighting, blocks):
    time, g, wrench, static = held_poses(gravity, noise=noise)
    model, mix = gauge_model(1)
    u = np.column_stack([wrench @ mix.T, np.full(time.size, 30.0)])
    lib = build(tmp_path, generate_c_runtime(model, {}, name="rt"))
    action = np.zeros(time.size, int)
    action[0], action[-1] = 1, 3
    _, fits, status, _ = replay_c(lib, time, u, g, static, action)
    finishes = Finishes()
    python_replay(LiveCalibrator(model, tool="none"), time, u, g, static.astype(bool),
                  {0: lambda c: c.start_identification("drill"), time.size - 1: finishes(False)})
    payload, fit, n_holds = finishes.results[0]
    assert status.tolist() == [STATUS["OK"]] and fit.weighting == weighting and int(fits[0, 39]) == blocks
    assert_same_fit(fits[0], payload, fit, n_holds)


def test_holds_past_the_limit_are_left_out(tmp_path):
    """With room for 4 holds, 6 holds give the tool of the first 4 (Python stopped after them), 2 dropped."""
    rec, model, u = recording(poses=6, seed=11)
    lib = build(tmp_path, generate_c_runtime(model, {}, name="rt", max_holds=4))
    n = rec.time.size
    static = rec.holding.astype(int)
    starts = np.flatnonzero(np.diff(np.r_[0, static]) == 1)
    assert starts.size == 6
    action = np.zeros(n, int)
    action[0], action[-1] = 1, 3
    _, fits, status, _ = replay_c(lib, rec.time, u, rec.gravity, static, action)
    finishes = Finishes()
    python_replay(LiveCalibrator(model, tool="none"), rec.time, u, rec.gravity, static.astype(bool),
                  {0: lambda c: c.start_identification("drill"), int(starts[4]): finishes(False)})
    payload, fit, n_holds = finishes.results[0]
    assert status.tolist() == [STATUS["OK"]] and n_holds == 4
    assert int(fits[0, 40]) == 4 and int(fits[0, 42]) == 2
    assert_same_fit(fits[0], payload, fit, n_holds)


def test_max_holds_is_checked():
    model, _ = gauge_model(1)
    for bad in (2, 10_000, 4.0):
        with pytest.raises(FtcalError, match="max_holds"):
            generate_c_runtime(model, {}, name="rt", max_holds=bad)


def test_a_tool_that_is_not_one_is_not_adopted(tmp_path):
    model, _ = gauge_model(1)
    assert build(tmp_path, generate_c_runtime(model, {}, name="rt")).adopt_refuses() == 1


def test_finish_without_start_is_refused(tmp_path):
    rec, model, u = recording(poses=2, seed=1)
    lib = build(tmp_path, generate_c_runtime(model, {}, name="rt"))
    n = rec.time.size
    action = np.zeros(n, int)
    action[5] = 2
    out, _, status, tool = replay_c(lib, rec.time, u, rec.gravity, np.full(n, -1), action)
    assert status.tolist() == [STATUS["NOT_IDENTIFYING"]] and tool == 0
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(FtcalError, match="no identification in progress"):
            LiveCalibrator(model, tool="none").finish_identification()
