"""The tracker that checks itself (``self_check=True``, the default, :mod:`ftcal.live.consistency`) on simulations that break
its model, with the truth generator of ``tests/helpers/live_truth.py`` (not ftcal's): a walk 3x the identified one, and
2x with a 40 N/h warm-up. Without the self-check the drift test sends the bias back once and it never updates
again (issue 40); with it, a lock-out is said in an event and the bias is re-acquired across orientations."""

from __future__ import annotations

import numpy as np
import pytest

import live_truth as truth
from ftcal.live import LiveCalibrator


@pytest.mark.parametrize("case", ["walk 3x", "walk 2x + warm-up 40 N/h"])
def test_a_lost_bias_is_said_and_re_acquired(case):
    before = truth.run_case(case, self_check=False)
    after = truth.run_case(case)  # the default
    kinds = [e[2] for e in after["events"]]
    assert "locked_out" in kinds and "reacquired" in kinds
    # The freeze: before, nearly every contact-free static sample flagged and the bias off by > 1 N.
    assert before["false_flags"] > 0.9 and before["bias_error"] > 1.0, before
    assert after["false_flags"] < 0.5 * before["false_flags"] and after["bias_error"] < 0.5 * before["bias_error"]
    assert after["contact_flagged"] >= 0.85, after


def test_matched_drift_is_left_alone():
    before = truth.run_case("matched", self_check=False)
    after = truth.run_case("matched")
    assert [e for e in after["events"] if e[2] == "reacquired"] == []
    assert after["free_over_floor"] <= 1.5 and after["false_flags"] <= 0.01 and after["contact_flagged"] >= 0.9
    assert after["absorbed"] <= 0.3
    assert after["free_rms"] <= 1.05 * before["free_rms"]


def test_blocks_and_single_samples_agree_with_the_self_check():
    ident, oper = truth.CASES["walk 3x"]
    payload = truth.identify(ident)
    rec, _ = truth.operation(oper, duration=90.0)
    block = truth.replay(LiveCalibrator(tools={"tool": payload}, tool="tool", self_check=True), rec, 1000)
    one = LiveCalibrator(tools={"tool": payload}, tool="tool", self_check=True)
    steps = truth.replay(one, rec, None)
    assert any(e[2] == "reacquired" for e in one.events)
    np.testing.assert_array_equal(block["flags"], steps["flags"])
    np.testing.assert_allclose(block["bias"], steps["bias"], rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(block["compensated"], steps["compensated"], rtol=1e-9, atol=1e-9)
