"""LiveCalibrator.step's one-call paths (the core's ``sample``: raw or wrench with gravity or an accelerometer;
``sample_quaternion``: a wrench with an orientation quaternion, its conversions in C) against the other ways in:
the scalar Python reference of ``tests/helpers/live_reference.py`` (an accelerometer's reading is minus gravity) and
``run`` in blocks (numpy's quaternion conversion and motion test; ``model.predict`` for raw channels), on simulated
recordings with a contact; the LiveSample they return is immutable and its arrays are the sample's."""

from __future__ import annotations

import copy
import pickle

import numpy as np
import pytest

import live_truth as truth
from ftcal.core.dataset import Dataset
from ftcal.core.model import CalibrationModel
from ftcal.live import LiveCalibrator, LiveSample
from ftcal.payload.parameters import PayloadParameters
from ftcal.sim.live_scenario import LiveScenario, simulate_live
from live_reference import ReferenceStep


def test_an_accelerometer_steps_as_the_reference_given_gravity():
    ident, oper = truth.CASES["noise 3x"]
    payload = truth.identify(ident)
    rec, _ = truth.operation(oper, duration=40.0)
    live = LiveCalibrator(tools={"tool": payload}, tool="tool")
    ref = ReferenceStep(payload, live.noise_std ** 2, live.walk_variance, live._accept_limit,
                        density=live.wander_density)
    for t, w, g in zip(rec["time"], rec["wrench"], rec["gravity"]):
        got = live.step(t, wrench=w, imu=-g)
        want = ref.step(float(t), w.tolist(), g.tolist())
        np.testing.assert_allclose(got.bias, want["bias"], rtol=1e-9, atol=1e-9)
        np.testing.assert_allclose(got.compensated, want["compensated"], rtol=1e-9, atol=1e-9)
        assert got.updated == want["updated"]
    assert live.counters["samples"] == rec["time"].size


def _scenario():
    rec = simulate_live(LiveScenario(duration=60.0, rate=200.0, contacts=((30.5, 5.0, 10.0),), seed=3))
    tool = LiveScenario().tools["gripper"]
    payload = PayloadParameters(tool.mass, np.asarray(tool.com), np.zeros(3), np.zeros(3), 9.81,
                                fit={"residual_rms": np.r_[np.full(3, 0.05), np.full(3, 0.004)]})
    return rec, {"gripper": payload}


def _same(steps, block, keys=("calibrated", "compensated", "bias", "bias_std")):
    for key in keys:
        np.testing.assert_allclose(np.array([getattr(s, key) for s in steps]), getattr(block, key), rtol=1e-9,
                                   atol=1e-9, err_msg=key)
    np.testing.assert_array_equal([s.static for s in steps], block.static)
    np.testing.assert_array_equal([s.updated for s in steps], block.updated)


def test_a_quaternion_steps_as_run_takes_it_in_blocks():
    rec, tools = _scenario()
    steps_live, run_live = (LiveCalibrator(tools=tools, tool="gripper", walk_std=[3, 3, 3, .3, .3, .3])
                            for _ in range(2))
    steps = [steps_live.step(t, wrench=w, quaternion=q) for t, w, q in zip(rec.time, rec.wrench, rec.quaternion)]
    blocks = [run_live.run(rec.time[a:a + 997], wrench=rec.wrench[a:a + 997], quaternion=rec.quaternion[a:a + 997])
              for a in range(0, rec.time.size, 997)]
    block = type(blocks[0])(*(np.concatenate([getattr(b, f) for b in blocks]) if f not in ("tool", "events")
                              else getattr(blocks[0], f) for f in blocks[0].__dataclass_fields__))
    np.testing.assert_allclose([s.calibrated for s in steps], rec.wrench, rtol=0, atol=0)
    _same(steps, block)
    assert 0 < np.count_nonzero(block.static) < rec.time.size  # the motion test decided both ways
    assert steps_live.counters == run_live.counters and steps_live.counters["contacts"] >= 1
    assert [s.flags for s in steps if s.flags] and all(isinstance(s.flags, dict) for s in steps)


def test_raw_channels_step_as_run_with_the_model_s_predict():
    rec, tools = _scenario()
    rng = np.random.default_rng(5)
    mix = np.eye(6) + 0.05 * rng.normal(size=(6, 6))
    wrench = rng.uniform(-40, 40, size=(4_000, 6)) * np.r_[np.ones(3), np.full(3, 0.1)]
    model = CalibrationModel(3).fit(Dataset.from_arrays(wrench @ mix.T, wrench))
    u = rec.wrench @ mix.T
    steps_live, run_live = (LiveCalibrator(model, tools=tools, tool="gripper") for _ in range(2))
    steps = [steps_live.step(t, raw=x, gravity=g) for t, x, g in zip(rec.time, u, rec.gravity)]
    block = run_live.run(rec.time, raw=u, gravity=rec.gravity)
    np.testing.assert_allclose([s.calibrated for s in steps], model.predict(u), rtol=1e-9, atol=1e-9)
    _same(steps, block, ("compensated", "bias", "bias_std"))
    assert steps_live.counters == run_live.counters


def test_a_model_with_a_temperature_input_steps_a_row_as_a_list_through_contacts():
    rec, tools = _scenario()
    rng = np.random.default_rng(6)
    wrench = rng.uniform(-40, 40, size=(4_000, 6)) * np.r_[np.ones(3), np.full(3, 0.1)]
    temperature = rng.uniform(20.0, 45.0, size=(4_000, 1))
    model = CalibrationModel(2).fit(Dataset.from_arrays(np.hstack([wrench, temperature]), wrench))
    u = np.column_stack([rec.wrench, np.full(rec.time.size, 30.0)])
    rows, lists = (LiveCalibrator(model, tools=tools, tool="gripper") for _ in range(2))
    assert rows._temperature_input == 6
    for t, x, g in zip(rec.time, u, rec.gravity):  # a (1, 7) row: the events' temperature read from it too
        a, b = rows.step(t, raw=x[None, :], gravity=g), lists.step(float(t), raw=x.tolist(), gravity=g.tolist())
        np.testing.assert_array_equal(a.bias, b.bias)
        assert a.flags == b.flags
    assert rows.counters == lists.counters and rows.counters["contacts"] >= 1


def test_the_sample_a_step_returns_is_immutable_and_its_arrays_are_its_own():
    rec, tools = _scenario()
    live = LiveCalibrator(tools=tools, tool="gripper")
    first = live.step(rec.time[0], wrench=rec.wrench[0], gravity=rec.gravity[0])
    second = live.step(rec.time[1], wrench=rec.wrench[1], gravity=rec.gravity[1])
    assert isinstance(first, LiveSample) and first.time == rec.time[0] and first.tool == "gripper"
    np.testing.assert_array_equal(first.calibrated, rec.wrench[0])
    np.testing.assert_array_equal(second.calibrated, rec.wrench[1])
    assert first.bias.shape == first.bias_std.shape == (6,) and isinstance(first.static, bool)
    with pytest.raises(AttributeError):
        first.bias = np.zeros(6)
    for again in (pickle.loads(pickle.dumps(second)), copy.deepcopy(second)):
        assert isinstance(again, LiveSample) and again.time == second.time and again.flags == second.flags
        np.testing.assert_array_equal(again.compensated, second.compensated)
