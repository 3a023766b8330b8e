"""The generated C runtime's drift test (``live.drift`` in C) against the Python live calibrator.

Reference: :class:`ftcal.live.LiveCalibrator` (its own tests hold its drift test to the truth of
simulated ramps) fed the same samples and re-tare. The recording is a still, level sensor with a
gripper, jittered sample times and three slow contacts, held: 0.05 N/s up to 4 N (sent back over the
64 s lag, after the snapshot ring has wrapped), 1 N/s up to 10 N, and the same after a re-tare; the
per-sample χ² gate lets a ramp through, so without the drift test the bias takes the contact and C
and Python diverge.
Every output agrees to 1e-9, the rollbacks happen at the same samples with the event's numbers, and
the simulation's truth checks the C directly: the held contact is reported, not absorbed.
"""

from __future__ import annotations

import ctypes
import re

import numpy as np
import pytest

from ftcal.live import LiveCalibrator
from ftcal.live.c_runtime import DRIFT_SNAPSHOTS, generate_c_runtime
from ftcal.live.drift import LAGS_S, SNAPSHOT_S
from ftcal.live.health import BIT
from ftcal.sim.live_scenario import LiveScenario

from test_c_runtime import (CC, FIELDS, NOISE, STEP_AND_STORE, compare, compile_driver, gauge_model, pointer,
                            python_replay, tool_payload)

pytestmark = pytest.mark.skipif(CC is None, reason="no C compiler `cc`")
DOWN = np.array([0.0, 0.0, -9.81])
RATE = 200.0
RETARE_AT = 188.0
# (start s, axis, N/s, peak N, release s): the contacts, each held at its peak until its release
RAMPS = ((70.0, 2, 0.05, 4.0, 160.0), (165.0, 0, 1.0, 10.0, 185.0), (190.0, 1, -1.0, 10.0, 210.0))
END = 210.0
BIAS = np.array([0.3, -0.2, 0.1, 0.01, 0.0, -0.01])
# N/√h, N·m/√h: the UR wrist sensor's drift; with the default walk (1 N/√h) the gate itself catches a 1 N/s ramp
WALK = [3.0, 3.0, 3.0, 0.3, 0.3, 0.3]

DRIVER = r"""
#include "rt.h"
/* walk: the walk variances (per s). retare[k]: re-tare before sample k. no_drift: the drift test off (threshold infinite), to show it matters.
   rollbacks[k]: the rollback count after sample k; last[4]: the last rollback's time, lag, chi2, moved. */
int replay(int n, const double *t, const double *u, const double *g, const int *override, const int *retare,
           const double *walk, int no_drift, double *out, long *rollbacks, double *last)
{
    rt_state s;
    rt_output o;
    int k, j;
    if (rt_init(&s, 1)) return -2;
    for (j = 0; j < 6; ++j) s.walk_variance[j] = walk[j];
    rt_enable_self_check(&s);   /* its bounds follow the walk given, as LiveCalibrator(walk_std=...) */
    if (no_drift) s.drift_chi2 = HUGE_VAL;
    s.holdoff = 0.0;   /* the drift test alone: the hold-off (which stops a fast ramp at the gate) off */
    for (k = 0; k < n; ++k) {
        if (retare[k]) rt_retare(&s);
""" + STEP_AND_STORE + r"""        rollbacks[k] = (long)s.rollbacks;
    }
    last[0] = s.rollback_time;
    last[1] = s.rollback_lag;
    last[2] = s.rollback_chi2;
    last[3] = s.rollback_moved;
    return s.drift_count >= 1 && s.drift_count <= RT_DRIFT_SNAPSHOTS ? 0 : -3;
}
"""


def ramp_recording(seed=3):
    """Jittered 250 Hz samples of a still, level sensor with the gripper, a constant bias, the noise of the tool
    file, and the contacts of RAMPS."""
    rng = np.random.default_rng(seed)
    steps = rng.uniform(0.8, 1.2, size=int(END * RATE)) / RATE
    t = np.cumsum(steps)
    t = t[t < END]
    gripper = LiveScenario().tools["gripper"]
    m, c = gripper.mass, np.asarray(gripper.com)
    contact = np.zeros((t.size, 6))
    for start, axis, slope, peak, release in RAMPS:
        contact[:, axis] += np.where((t >= start) & (t < release), np.clip((t - start) * slope, -peak, peak), 0.0)
    wrench = np.r_[m * DOWN, m * np.cross(c, DOWN)] + BIAS + contact + rng.normal(size=(t.size, 6)) * NOISE
    return t, wrench, contact


def build(tmp_path, header: str):
    lib = compile_driver(tmp_path, header, DRIVER)
    lib.replay.restype = ctypes.c_int
    return lib


def replay_c(lib, t, u, gravity, retare, walk, no_drift):
    n = t.size
    out, rollbacks, last = np.zeros((n, FIELDS)), np.zeros(n, np.int64), np.zeros(4)
    arrays = [np.ascontiguousarray(x, dtype=float) for x in (t, u, gravity)]
    ints = [np.ascontiguousarray(x, dtype=np.int32) for x in (np.full(n, -1), retare)]
    walk = np.ascontiguousarray(walk, dtype=float)
    rc = lib.replay(n, *(pointer(a) for a in arrays), *(pointer(a, ctypes.c_int) for a in ints), pointer(walk),
                    int(no_drift),
                    pointer(out), pointer(rollbacks, ctypes.c_long), pointer(last))
    assert rc == 0
    return out, rollbacks, last


def test_the_snapshot_ring_holds_the_longest_lag():
    """Snapshots at least SNAPSHOT_S apart: with the ring full, its second oldest is more than max(LAGS_S) old."""
    assert (DRIFT_SNAPSHOTS - 2) * SNAPSHOT_S >= max(LAGS_S) and (DRIFT_SNAPSHOTS - 3) * SNAPSHOT_S < max(LAGS_S)


def test_c_drift_test_rolls_back_a_ramp_contact_as_the_python_calibrator(tmp_path):
    model, mix = gauge_model(3)
    tools = {"gripper": tool_payload(LiveScenario().tools["gripper"])}
    lib = build(tmp_path, generate_c_runtime(model, tools, name="rt"))
    t, wrench, contact = ramp_recording()
    n = t.size
    u = np.column_stack([wrench @ mix.T, np.full(n, 30.0)])
    gravity = np.tile(DOWN, (n, 1))
    retare_index = int(np.searchsorted(t, RETARE_AT))
    retare = np.zeros(n, int)
    retare[retare_index] = 1
    live = LiveCalibrator(model, tools=tools, tool="gripper", walk_std=WALK, holdoff=0.0)
    out, rollbacks, last = replay_c(lib, t, u, gravity, retare, live.walk_variance, no_drift=False)
    ref = python_replay(live, t, u, gravity, None, {retare_index: lambda c: c.retare()})
    compare(out, ref)
    # The rollbacks: at the same samples as Python's events, and the last one's numbers are its text's.
    events = [e for e in live.events if e[2] == "rollback"]
    for start, _, slope, peak, _ in RAMPS:  # Python rolled back during each ramp
        assert any(start < e[0] < start + peak / abs(slope) for e in events), start
    steps_with_rollback = t[np.flatnonzero(np.diff(np.r_[0, rollbacks]))]
    np.testing.assert_array_equal(steps_with_rollback, [e[0] for e in events])
    assert last[0] == events[-1][0]
    numbers = re.search(r"moved up to (\S+) in (\S+) s, .*\(chi2 (\S+), 6 dof\)", events[-1][3]).groups()
    assert numbers == (f"{last[3]:.3g}", f"{last[1]:.3g}", f"{last[2]:.3g}")
    # One rollback goes back over the longest lag, from a ring that has wrapped (more than 64.5 s of snapshots).
    lags = [float(re.search(r" in (\S+) s,", e[3]).group(1)) for e in events]
    assert any(lag >= max(LAGS_S) for lag in lags) and events[0][0] > DRIFT_SNAPSHOTS * SNAPSHOT_S
    # Truth: the held contacts are reported in the C's compensated wrench and flagged, the bias stays the sensor's.
    for start, axis, slope, peak, _ in RAMPS:
        held = (np.abs(contact[:, axis]) >= peak) & (t > start + peak / abs(slope) + 1.0)
        assert held.sum() > 1000
        np.testing.assert_allclose(out[held, 6 + axis], contact[held, axis], atol=0.5)
        assert np.all(out[held, 26].astype(int) & BIT["unexplained"])
        np.testing.assert_allclose(out[held, 12 + axis], BIAS[axis], atol=0.5)
    # Without the drift test the C takes the ramp into the bias: the recording needs the port.
    plain, none, _ = replay_c(lib, t, u, gravity, retare, live.walk_variance, no_drift=True)
    assert none[-1] == 0
    start, axis, slope, peak, _ = RAMPS[0]
    held = (np.abs(contact[:, axis]) >= peak) & (t > start + peak / abs(slope) + 1.0)
    assert np.min(np.abs(plain[held, 12 + axis] - BIAS[axis])) > 0.5 * peak
    with pytest.raises(AssertionError):
        compare(plain, ref)
