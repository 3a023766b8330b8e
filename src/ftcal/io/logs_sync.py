"""Put the streams one F/T sensor needs on one clock.

The reference clock is the sensor's own F/T timestamps (or a uniform grid at
``rate`` Hz). Samples outside the time span that every stream covers are
trimmed; the other streams are linearly interpolated onto the reference
times. Gaps (intervals longer than 1.5× a stream's median period) are
reported with the number of samples they dropped.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np

from .._checks import check_float
from ..errors import FtcalError, FtcalWarning
from .logs import Recording, Stream
from .logs_quality import check_finite


@dataclass(frozen=True)
class StreamReport:
    """Timing of one stream: median period, gaps and the samples they dropped."""

    name: str
    n_samples: int
    period: float
    gaps: int
    dropped: int
    largest_gap: float


@dataclass(frozen=True)
class Aligned:
    """One sensor's streams on one clock.

    time : ndarray of shape (n_samples,)
    ft : ndarray of shape (n_samples, 6), raw channels
    temperature : ndarray of shape (n_samples,) or None
    q, dq, ddq : ndarray of shape (n_samples, n_joints) (dq, ddq may be None), columns ``joint_names``
    accelerometer, gyro : ndarray of shape (n_samples, 3) or None
    trimmed : F/T samples cut at the (start, end) because another stream did not cover them
    """

    time: np.ndarray
    ft: np.ndarray
    temperature: np.ndarray | None
    joint_names: tuple[str, ...]
    q: np.ndarray
    dq: np.ndarray | None
    ddq: np.ndarray | None
    accelerometer: np.ndarray | None
    gyro: np.ndarray | None
    trimmed: tuple[int, int]
    reports: tuple[StreamReport, ...]

# A uniform clock may resample, but not invent more than this many samples per F/T sample.
MAX_UPSAMPLING = 100


def timing(stream: Stream) -> StreamReport:
    """Check the timestamps increase and count gaps/dropped samples."""
    check_finite(stream)
    if stream.n_samples < 2:
        raise FtcalError(f"{stream.name}: needs at least 2 samples; has {stream.n_samples}.")
    dt = np.diff(stream.time)
    if np.any(dt <= 0):
        k = int(np.argmax(dt <= 0))
        raise FtcalError(f"{stream.name}: timestamps do not increase at sample {k + 1} "
                         f"(t={stream.time[k]:.6f} then {stream.time[k + 1]:.6f}).")
    period = float(np.median(dt))
    gaps = dt > 1.5 * period
    dropped = int(np.sum(np.round(dt[gaps] / period) - 1))
    largest = float(dt.max()) if gaps.any() else 0.0
    return StreamReport(stream.name, stream.n_samples, period, int(gaps.sum()), dropped, largest)


def align(recording: Recording, sensor: tuple[str, ...], *, temperature: bool = True,
          derivatives: bool = False, imu: str | None = None, rate: float | None = None) -> Aligned:
    """Streams of F/T sensor ``sensor`` (its name aliases) on one clock.

    ``temperature`` requires the sensor's temperature stream; ``derivatives``
    uses joint velocities and accelerations when logged; ``imu`` names the
    accelerometer/gyro pair for floating-base kinematics; ``rate`` (Hz) puts
    everything on a uniform grid instead of the F/T timestamps.
    """
    ft = recording.ft_stream(*sensor)
    streams: dict[str, Stream | None] = {"ft": ft, "q": recording.joint_stream()}
    streams["T"] = recording.temperature_stream(*sensor) if temperature else None
    streams["dq"] = recording.joint_velocities if derivatives else None
    streams["ddq"] = recording.joint_accelerations if derivatives else None
    if imu is not None:
        streams["acc"] = _imu(recording, recording.accelerometers, imu, "accelerometers")
        streams["gyro"] = _imu(recording, recording.gyros, imu, "gyros")
    used = {k: s for k, s in streams.items() if s is not None}
    reports = tuple(timing(s) for s in used.values())
    for r in reports:
        if r.dropped:
            warnings.warn(f"{r.name}: {r.gaps} gap(s) in the timestamps, about {r.dropped} dropped sample(s) "
                          f"(largest gap {r.largest_gap:.3f} s); values across gaps are interpolated.",
                          FtcalWarning, stacklevel=2)
    start = max(s.time[0] for s in used.values())
    end = min(s.time[-1] for s in used.values())
    if end <= start:
        raise FtcalError(f"Recording {recording.path}: the streams do not overlap in time "
                         f"(F/T, joints{', temperature' if temperature else ''}).")
    if rate is not None:
        rate = check_float(rate, "rate", "align", 0.0, low_inclusive=False)
        n_clock = int(np.floor((end - start) * rate)) + 1
        if n_clock > MAX_UPSAMPLING * ft.n_samples:
            raise FtcalError(f"Recording {recording.path}: rate {rate:g} Hz gives {n_clock} samples, more than "
                             f"{MAX_UPSAMPLING} times the {ft.n_samples} F/T samples; choose a rate near the "
                             f"sensor's ({1 / timing(ft).period:.4g} Hz).")
        clock = start + np.arange(n_clock) / rate
        trimmed = (int(np.sum(ft.time < start)), int(np.sum(ft.time > end)))
    else:
        keep = (ft.time >= start) & (ft.time <= end)
        clock = ft.time[keep]
        trimmed = (int(np.argmax(keep)), int(ft.n_samples - 1 - np.flatnonzero(keep)[-1]))

    def on_clock(key: str) -> np.ndarray | None:
        s = used.get(key)
        if s is None:
            return None
        return np.column_stack([np.interp(clock, s.time, s.data[:, c]) for c in range(s.data.shape[1])])

    temp = on_clock("T")
    q_stream = used["q"]
    for key in ("dq", "ddq"):
        if key in used and used[key].columns != q_stream.columns:
            raise FtcalError(f"{used[key].name}: joint columns differ from the joint positions.")
    return Aligned(clock, on_clock("ft"), None if temp is None else temp[:, 0], q_stream.columns,
                   on_clock("q"), on_clock("dq"), on_clock("ddq"), on_clock("acc"), on_clock("gyro"),
                   trimmed, reports)


def _imu(recording: Recording, streams: dict[str, Stream], name: str, group: str) -> Stream:
    if name not in streams:
        raise FtcalError(f"Recording {recording.path}: no {group}.{name} stream "
                         f"(has: {', '.join(sorted(streams)) or 'none'}).")
    return streams[name]
