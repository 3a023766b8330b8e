"""Logs to a fit-ready dataset for one sensor, against hand-computed expected wrenches."""

import numpy as np
import pandas as pd
import pytest
from test_logs_mat import logger_tree, write_v5, write_v73
from test_robot_expected import FOREARM, static_wrench
from test_robot_model import TINY_URDF

from ftcal.core.dataset import DEFAULT_INPUTS, DEFAULT_OUTPUTS
from ftcal.insitu.recordings import InsituOptions, recordings_dataset as build_dataset, write_dataset
from ftcal.robot import RobotModel, load_case_config
from ftcal.runtime.errors import FtcalError, FtcalWarning

RATE = 0.5  # rad/s: the shoulder angle is linear in time, so interpolating it is exact


def expected_at(t, payload=None):
    bodies = [FOREARM] + ([payload] if payload else [])
    return np.array([static_wrench(bodies, RATE * tk) for tk in t])


def make_recording(path, writer, *, payload=None, n_ft=300, t0=10.0, layout="samples_first"):
    """F/T at 100 Hz; joints at ~62 Hz starting a bit later; raw = 100 + 3·wrench + small noise."""
    t_ft = t0 + np.arange(n_ft) * 0.01
    t_q = t0 + 0.013 + np.arange(int(n_ft * 0.6)) * 0.016
    # noise keeps every channel alive (a perfectly constant channel is reported as stuck)
    raw = 100.0 + 3.0 * expected_at(t_ft, payload) + 1e-4 * np.random.default_rng(1).normal(size=(n_ft, 6))
    temp = 30.0 + 0.01 * np.arange(n_ft)
    path.parent.mkdir(parents=True, exist_ok=True)
    tree = logger_tree(raw, temp, np.c_[RATE * t_q], t_ft, t_q, names=("arm_ft_sensor",),
                       joints=["shoulder"], layout=layout)
    writer(path, tree)
    keep = (t_ft >= t_q[0]) & (t_ft <= t_q[-1])
    return t_ft[keep], raw[keep], temp[keep]


@pytest.fixture
def tiny():
    return RobotModel.from_text(TINY_URDF, "tiny.urdf")


@pytest.fixture
def payload_file(tmp_path):
    path = tmp_path / "loads.toml"
    path.write_text('[convention.right]\nframe = "forearm"\ncom = [0.1, 0.0, 0.0]\n')
    return path


NO_FILTER = InsituOptions(savgol_frame=None)


def test_two_load_cases_two_segments(tmp_path, tiny, payload_file):
    a = tmp_path / "l0kg-r0kg" / "grid.mat"
    b = tmp_path / "l0kg-r2kg" / "grid.mat"
    t_a, raw_a, temp_a = make_recording(a, write_v73)
    t_b, raw_b, temp_b = make_recording(b, write_v5, payload=(2.0, np.array([0.1, 0.0, 0.0])),
                                        layout="channels_first")
    ds = build_dataset([a, b], tiny, "arm_ft", load_cases=load_case_config(payload_file), options=NO_FILTER)
    assert ds.input_names == DEFAULT_INPUTS and ds.output_names == DEFAULT_OUTPUTS
    n_a = len(t_a)
    np.testing.assert_array_equal(ds.segments, np.r_[np.zeros(n_a), np.ones(len(t_b))])
    assert list(ds.groups[:1]) + list(ds.groups[-1:]) == ["l0kg-r0kg", "l0kg-r2kg"]
    np.testing.assert_allclose(ds.inputs[:n_a, :6], raw_a)
    np.testing.assert_allclose(ds.inputs[n_a:, 6], temp_b)
    np.testing.assert_allclose(ds.outputs[:n_a], expected_at(t_a), atol=1e-9)
    np.testing.assert_allclose(ds.outputs[n_a:], expected_at(t_b, (2.0, np.array([0.1, 0.0, 0.0]))), atol=1e-9)
    # 2 kg more beyond the sensor: the force norm grows by 2 g
    np.testing.assert_allclose(np.linalg.norm(ds.outputs[n_a:, :3], axis=1), 3.5 * 9.81)
    assert ds.sources == (str(a), str(b))
    # the expected wrenches are cached in the user cache folder, not beside the user's data
    assert not list(tmp_path.rglob("*ftcal-cache*"))


def test_options(tmp_path, tiny):
    rec = tmp_path / "run.mat"
    t, raw, _ = make_recording(rec, write_v73)
    ds = build_dataset([rec], tiny, "arm_ft_sensor",
                       options=InsituOptions(savgol_frame=None, temperature=False, align_first_sample=True,
                                             cache=False))
    assert ds.input_names == DEFAULT_INPUTS[:6]
    np.testing.assert_allclose(ds.inputs[0], ds.outputs[0], atol=1e-9)
    np.testing.assert_allclose(np.diff(ds.inputs, axis=0), np.diff(raw, axis=0), atol=1e-9)
    assert list(set(ds.groups)) == ["run"]
    assert not (tmp_path / "run.mat.ftcal-cache").exists()
    # smoothing on: raw channels here are smooth (sin of a slow angle), so they barely change
    smoothed = build_dataset([rec], tiny, "arm_ft", options=InsituOptions(savgol_frame=31))
    np.testing.assert_allclose(smoothed.inputs[:, :6], raw, atol=1e-3)


def test_stuck_channel_warns(tmp_path, tiny):
    rec = tmp_path / "run.mat"
    t_ft = np.arange(600) * 0.01
    raw = 100.0 + 3.0 * expected_at(t_ft) + np.random.default_rng(0).normal(size=(600, 6))
    raw[100:400, 2] = 100.0  # frozen mid-range (at an extreme it would read as saturated)
    write_v73(rec, logger_tree(raw, np.full(600, 30.0), np.c_[RATE * t_ft], t_ft, t_ft,
                               names=("arm_ft",), joints=["shoulder"]))
    with pytest.warns(FtcalWarning, match="channel u3 looks stuck: 300 samples"):
        build_dataset([rec], tiny, "arm_ft", options=NO_FILTER)


def test_errors(tmp_path, tiny):
    rec = tmp_path / "run.mat"
    make_recording(rec, write_v73)
    with pytest.raises(FtcalError, match="no F/T sensor matching 'l_arm_ft'"):
        build_dataset([rec], tiny, "l_arm_ft")
    other = RobotModel.from_text(TINY_URDF.replace('"shoulder"', '"shoulder_pitch"'), "other.urdf")
    with pytest.raises(FtcalError, match="joint\\(s\\) 'shoulder' not in URDF other.urdf"):
        build_dataset([rec], other, "arm_ft", options=NO_FILTER)
    with pytest.raises(FtcalError, match="both imu"):
        build_dataset([rec], tiny, "arm_ft", options=InsituOptions(imu="x"))
    with pytest.raises(FtcalError, match="No recordings"):
        build_dataset([], tiny, "arm_ft")


@pytest.mark.parametrize("suffix", [".parquet", ".csv"])
def test_write_dataset(tmp_path, tiny, suffix):
    rec = tmp_path / "run.mat"
    make_recording(rec, write_v73, n_ft=120)
    ds = build_dataset([rec, rec], tiny, "arm_ft", options=NO_FILTER)
    out = tmp_path / f"data{suffix}"
    write_dataset(ds, out)
    frame = pd.read_parquet(out) if suffix == ".parquet" else pd.read_csv(out)
    assert list(frame.columns) == [*DEFAULT_INPUTS, *DEFAULT_OUTPUTS, "segment", "load"]
    np.testing.assert_allclose(frame[list(DEFAULT_OUTPUTS)].to_numpy(), ds.outputs)
    assert sorted(set(frame["segment"])) == [0, 1]
    assert set(frame["load"]) == {"run"}
    assert [p.name for p in tmp_path.iterdir() if p.name.startswith(".data")] == []
    with pytest.raises(FtcalError, match="must end in .csv or .parquet"):
        write_dataset(ds, tmp_path / "data.xlsx")
