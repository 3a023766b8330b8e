"""LiveCalibrator (the C core, ``csrc/ftcal_live.h`` through ``ftcal.live._core``) against the scalar Python reference
of ``tests/helpers/live_reference.py`` (plain floats, the Python motion test, drift test and self-check), to 1e-9, on
the truth generator's worlds that break the filter's assumptions (``tests/helpers/live_truth.py``: a walk 3x the
identified, noise 3x, a coloured wander with quantisation, 10-bit-like steps): blocks and single steps alike, and
the drift test's and the self-check's events with the reference's texts."""

from __future__ import annotations

import numpy as np
import pytest

import live_truth as truth
from ftcal.live import LiveCalibrator
from ftcal.live.calibrator import _rollback_text
from live_reference import ReferenceStep


def reference_run(live, payload, rec, self_check=True):
    ref = ReferenceStep(payload, live.noise_std ** 2, live.walk_variance, live._accept_limit, self_check=self_check,
                        density=live.wander_density)
    rows = [ref.step(t, w, g) for t, w, g in zip(rec["time"].tolist(), rec["wrench"].tolist(),
                                                 rec["gravity"].tolist())]
    out = {key: np.array([r[key] for r in rows]) for key in rows[0]}
    texts = [(t, f, k, _rollback_text((None, None, *rest[0])) if k == "rollback" else rest[0])
             for t, f, k, *rest in ref.events]
    return out, texts, ref


@pytest.mark.parametrize("case", ["walk 3x", "noise 3x", "coloured + quantised", "10-bit steps, walk 2x"])
def test_the_core_steps_as_the_scalar_reference(case):
    ident, oper = truth.CASES[case]
    payload = truth.identify(ident)
    rec, _ = truth.operation(oper, duration=120.0)
    live = LiveCalibrator(tools={"tool": payload}, tool="tool")
    expected, texts, ref = reference_run(live, payload, rec)
    n = rec["time"].size
    parts = [live.run(rec["time"][a:a + 777], wrench=rec["wrench"][a:a + 777], gravity=rec["gravity"][a:a + 777])
             for a in range(0, n, 777)]
    for key in ("bias", "bias_std", "compensated", "chi2"):
        got = np.concatenate([getattr(p, key) for p in parts])
        np.testing.assert_allclose(got, expected[key], rtol=1e-9, atol=1e-9, err_msg=key)
    for key in ("static", "updated"):
        np.testing.assert_array_equal(np.concatenate([getattr(p, key) for p in parts]), expected[key], err_msg=key)
    logged = [e for e in live.events if e[1] in ("bias", "tracker") and e[2] != "retare"]
    assert [e[:3] for e in logged] == [e[:3] for e in texts]
    assert [e[3] for e in logged] == [e[3] for e in texts]
    np.testing.assert_allclose(live.noise_std ** 2, ref.noise, rtol=1e-9)
    np.testing.assert_allclose(live.walk_variance, ref.walk, rtol=1e-9)
    # the world did break the assumptions: the filter was tested where it adapts or sends the bias back, and the
    # static samples both updated and gated
    assert expected["updated"].any() and (expected["static"] & ~expected["updated"]).any()
    if case != "coloured + quantised":
        assert texts, "no adaptation, rollback or re-acquisition: the case did not exercise the self-check"
    else:  # the wander the identification found is in the update (r + D / Δt), the reference's as the core's
        assert np.any(live.wander_density > 0)


def test_single_steps_are_the_reference_s_too():
    ident, oper = truth.CASES["walk 3x"]
    payload = truth.identify(ident)
    rec, _ = truth.operation(oper, duration=40.0)
    live = LiveCalibrator(tools={"tool": payload}, tool="tool")
    expected, _, _ = reference_run(live, payload, rec)
    steps = [live.step(t, wrench=w, gravity=g) for t, w, g in zip(rec["time"], rec["wrench"], rec["gravity"])]
    np.testing.assert_allclose([s.bias for s in steps], expected["bias"], rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose([s.compensated for s in steps], expected["compensated"], rtol=1e-9, atol=1e-9)
    np.testing.assert_array_equal([s.updated for s in steps], expected["updated"])
