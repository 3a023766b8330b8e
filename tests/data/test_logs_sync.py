"""One clock for all streams, gaps, NaN stretches, saturated/stuck channels, smoothing, tables."""

import numpy as np
import pandas as pd
import pytest

from ftcal.data.alignment import align, timing
from ftcal.data.logs import read_recording
from ftcal.data.recording import Recording, Stream
from ftcal.data.signals import channel_issues, check_finite, smooth
from ftcal.runtime.errors import FtcalError, FtcalWarning

FT_COLS = tuple(f"u{i}" for i in range(1, 7))


def recording(t_ft, ft, t_q, q, t_temp=None, temp=None):
    t_temp = t_ft if t_temp is None else t_temp
    temp = np.full((len(t_temp), 1), 30.0) if temp is None else temp
    return Recording(path=__import__("pathlib").Path("rec.mat"),
                     ft={"r_arm_ft": Stream("ft", t_ft, ft, FT_COLS)},
                     temperature={"r_arm_ft_sensor": Stream("temp", t_temp, temp, ("T",))},
                     joints=Stream("q", t_q, q, ("a", "b")))


def test_align_trims_and_interpolates():
    t_ft = np.arange(0.0, 2.0, 0.01)            # 0 .. 1.99
    ft = np.tile(t_ft[:, None], (1, 6))
    t_q = np.arange(0.25, 1.5, 0.03)            # joints start late and stop early
    q = np.c_[2 * t_q + 1, -t_q]                # linear in time: interpolation is exact
    t_temp = np.arange(0.0, 2.0, 0.1)
    temp = (20 + 5 * t_temp)[:, None]
    data = align(recording(t_ft, ft, t_q, q, t_temp, temp), ("r_arm_ft",))
    assert data.time[0] >= t_q[0] and data.time[-1] <= t_q[-1]
    assert data.trimmed == (int(np.sum(t_ft < t_q[0])), int(np.sum(t_ft > t_q[-1])))
    np.testing.assert_allclose(data.q, np.c_[2 * data.time + 1, -data.time], atol=1e-12)
    np.testing.assert_allclose(data.temperature, 20 + 5 * data.time, atol=1e-12)
    np.testing.assert_array_equal(data.ft[:, 0], data.time)
    assert data.joint_names == ("a", "b")


def test_align_on_uniform_rate():
    t = np.linspace(0, 1, 101)
    data = align(recording(t, np.tile(t[:, None], 6), t, np.c_[t, t]), ("r_arm_ft_sensor",), rate=40.0)
    np.testing.assert_allclose(np.diff(data.time), 1 / 40)
    np.testing.assert_allclose(data.ft[:, 3], data.time, atol=1e-12)


def test_gaps_are_reported():
    t = np.arange(0.0, 1.0, 0.01)
    t_gap = np.r_[t[:40], t[45:]]               # samples 40..44 missing: 5
    s = Stream("joints", t_gap, np.zeros((len(t_gap), 2)), ("a", "b"))
    report = timing(s)
    assert (report.gaps, report.dropped) == (1, 5)
    assert report.largest_gap == pytest.approx(0.06)
    with pytest.warns(FtcalWarning, match="1 gap\\(s\\).*about 5 dropped"):
        align(recording(t, np.zeros((100, 6)), t_gap, s.data), ("r_arm_ft",))


def test_bad_streams():
    t = np.arange(0.0, 1.0, 0.01)
    ft = np.zeros((100, 6))
    ft[30:35, 2] = np.nan
    with pytest.raises(FtcalError, match=r"ft: NaN stretch in column 'u3' from t=0.300 to t=0.340 s \(5 samples"):
        align(recording(t, ft, t, np.zeros((100, 2))), ("r_arm_ft",))
    t_back = t.copy()
    t_back[50] = t_back[48]
    with pytest.raises(FtcalError, match="timestamps do not increase at sample 50"):
        timing(Stream("q", t_back, np.zeros((100, 1)), ("a",)))
    with pytest.raises(FtcalError, match="do not overlap"):
        align(recording(t, np.zeros((100, 6)), t + 5, np.zeros((100, 2))), ("r_arm_ft",))
    with pytest.raises(FtcalError, match="no temperature stream for sensor 'l_arm_ft'"):
        rec = recording(t, np.zeros((100, 6)), t, np.zeros((100, 2)))
        rec.ft["l_arm_ft"] = rec.ft["r_arm_ft"]
        align(rec, ("l_arm_ft",))
    with pytest.raises(FtcalError, match="2 timestamps but 3 samples"):
        Stream("x", np.zeros(2), np.zeros((3, 1)), ("a",))
    check_finite(Stream("ok", t, np.zeros((100, 1)), ("a",)))


def test_saturated_and_stuck_channels():
    rng = np.random.default_rng(1)
    n = 1000
    t = np.arange(n) * 0.001
    x = rng.normal(size=(n, 6))
    x[300:360, 1] = x[:, 1].max() + 1.0         # clipped at its top for 60 samples
    x[500:800, 4] = 0.123                       # frozen while the others move
    issues = {(i.column, i.kind): i for i in channel_issues(Stream("ft", t, x, FT_COLS))}
    assert set(issues) == {("u2", "saturated"), ("u5", "stuck")}
    assert issues[("u2", "saturated")].samples == 60
    assert issues[("u5", "stuck")].samples == 300
    assert issues[("u5", "stuck")].start_time == pytest.approx(0.5)
    # with explicit ADC limits, any sample at the limit counts
    x = rng.normal(size=(n, 6))
    x[10:13, 0] = 32767
    limited = channel_issues(Stream("ft", t, x, FT_COLS), adc_limits=(-32768, 32767))
    assert [(i.column, i.kind, i.samples) for i in limited] == [("u1", "saturated", 3)]
    # a robot standing still: every channel flat together is not a fault
    still = np.ones((n, 6))
    assert channel_issues(Stream("ft", t, still, FT_COLS)) == []


def test_smooth_keeps_cubics_and_cuts_noise():
    t = np.linspace(-1, 1, 501)
    cubic = np.c_[t**3 - t, 2 * t**2]
    np.testing.assert_allclose(smooth(cubic), cubic, atol=1e-10)  # order-3 SG is exact on cubics
    noisy = cubic + np.random.default_rng(0).normal(scale=0.1, size=cubic.shape)
    assert np.std(smooth(noisy) - cubic) < 0.4 * np.std(noisy - cubic)
    with pytest.raises(FtcalError, match="odd"):
        smooth(cubic, frame=100)
    with pytest.raises(FtcalError, match="fewer than the Savitzky"):
        smooth(cubic[:50], where="Recording x.mat")


def test_table_recording(tmp_path):
    n = 50
    t = np.arange(n) * 0.01
    frame = pd.DataFrame({"time": t, **{f"r_arm_ft_u{i}": t * i for i in range(1, 7)}, "r_arm_ft_T": 30.0,
                          "shoulder": np.sin(t), "shoulder.vel": np.cos(t)})
    frame.to_parquet(tmp_path / "rec.parquet")
    frame.to_csv(tmp_path / "rec.csv", index=False)
    for name in ("rec.parquet", "rec.csv"):
        rec = read_recording(tmp_path / name)
        np.testing.assert_allclose(rec.ft_stream("r_arm_ft_sensor").data[:, 5], 6 * t)
        assert rec.joints.columns == ("shoulder",)
        np.testing.assert_allclose(rec.joint_velocities.data[:, 0], np.cos(t))
    frame.drop(columns=["r_arm_ft_u4"]).to_csv(tmp_path / "bad.csv", index=False)
    with pytest.raises(FtcalError, match="lacks column\\(s\\) r_arm_ft_u4"):
        read_recording(tmp_path / "bad.csv")
    frame.drop(columns=["time"]).to_csv(tmp_path / "bad.csv", index=False)
    with pytest.raises(FtcalError, match="no 'time' column"):
        read_recording(tmp_path / "bad.csv")
