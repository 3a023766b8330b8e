"""Put the streams one F/T sensor needs on one clock.

The reference clock is the sensor's own F/T timestamps (or a uniform grid at
``rate`` Hz). Samples outside the time span that every stream covers are
trimmed; the other streams are linearly interpolated onto the reference
times (orientations, columns ``qx, qy, qz, qw``, with slerp). Gaps
(intervals longer than 1.5× a stream's median period) are
reported with the number of samples they dropped.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np

from ..runtime.checks import check_float
from ..runtime.errors import FtcalError, FtcalWarning, ParameterError
from .recording import Recording, Stream
from .signals import check_finite
from .tf_chain import QUATERNION_COLUMNS


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
        # Header stamps that repeat or go back are a driver's; the bag's receive time still increases.
        fix = ("time the messages by the bag's receive time with {receive_time}, or sort the bag by stamp"
               if stream.clock == "header stamps" else "sort the samples by time")
        raise ParameterError("receive_time", f"{stream.name}: timestamps do not increase at sample {k + 1} "
                         f"(t={stream.time[k]:.6f} then {stream.time[k + 1]:.6f}); {fix}.")
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
    names = "F/T, joints" + (", temperature" if temperature else "")
    clock, on_clock, trimmed, reports = align_streams(used, "ft", rate=rate,
                                                      where=f"Recording {recording.path}", names=names)
    clocked = {key: on_clock.get(key) for key in ("ft", "q", "T", "dq", "ddq", "acc", "gyro")}
    temp = clocked["T"]
    q_stream = used["q"]
    for key in ("dq", "ddq"):
        if key in used and used[key].columns != q_stream.columns:
            raise FtcalError(f"{used[key].name}: joint columns differ from the joint positions.")
    return Aligned(clock, clocked["ft"], None if temp is None else temp[:, 0], q_stream.columns,
                   clocked["q"], clocked["dq"], clocked["ddq"], clocked["acc"], clocked["gyro"],
                   trimmed, reports)


def align_streams(streams: dict[str, Stream], reference: str, *, rate: float | None = None,
                  where: str = "recording", names: str | None = None
                  ) -> tuple[np.ndarray, dict[str, np.ndarray], tuple[int, int], tuple[StreamReport, ...]]:
    """Put ``streams`` on the clock of ``streams[reference]`` (or a uniform ``rate`` grid).

    Samples outside the span every stream covers are trimmed; the other streams are
    interpolated: linearly, except quaternion streams (columns ``qx, qy, qz, qw``), which
    are slerped. Gaps are reported as warnings.

    Parameters
    ----------
    streams : dict of str to Stream
        Streams by key; ``reference`` is one of the keys.
    reference : str
        Key of the stream whose timestamps are the clock.
    rate : float or None
        Hz of a uniform clock instead of the reference's timestamps.
    where, names : str
        Name the recording and its streams in the error messages.

    Returns
    -------
    clock : ndarray of shape (n_samples,), seconds
    on_clock : dict of str to ndarray of shape (n_samples, n_columns)
        Each stream's values at ``clock``, by key.
    trimmed : (int, int)
        Reference samples cut at the start and at the end.
    reports : tuple of StreamReport

    Raises
    ------
    FtcalError
        Non-finite values, timestamps that do not increase, or streams that do not overlap.
    """
    ref = streams[reference]
    reports = tuple(timing(s) for s in streams.values())
    for r in reports:
        if r.dropped:
            warnings.warn(f"{r.name}: {r.gaps} gap(s) in the timestamps, about {r.dropped} dropped sample(s) "
                          f"(largest gap {r.largest_gap:.3f} s); values across gaps are interpolated.",
                          FtcalWarning, stacklevel=3)
    start = max(s.time[0] for s in streams.values())
    end = min(s.time[-1] for s in streams.values())
    if end <= start:
        listed = names or ", ".join(s.name for s in streams.values())
        raise FtcalError(f"{where}: the streams do not overlap in time ({listed}).")
    if rate is not None:
        rate = check_float(rate, "rate", "align", 0.0, low_inclusive=False)
        n_clock = int(np.floor((end - start) * rate)) + 1
        if n_clock > MAX_UPSAMPLING * ref.n_samples:
            raise FtcalError(f"{where}: rate {rate:g} Hz gives {n_clock} samples, more than "
                             f"{MAX_UPSAMPLING} times the {ref.n_samples} {ref.name} samples; choose a rate near "
                             f"the sensor's ({1 / timing(ref).period:.4g} Hz).")
        clock = start + np.arange(n_clock) / rate
        trimmed = (int(np.sum(ref.time < start)), int(np.sum(ref.time > end)))
    else:
        keep = (ref.time >= start) & (ref.time <= end)
        clock = ref.time[keep]
        trimmed = (int(np.argmax(keep)), int(ref.n_samples - 1 - np.flatnonzero(keep)[-1]))
    return clock, {key: _on_clock(s, clock) for key, s in streams.items()}, trimmed, reports


def _on_clock(stream: Stream, clock: np.ndarray) -> np.ndarray:
    if stream.columns == QUATERNION_COLUMNS:
        from scipy.spatial.transform import Rotation, Slerp

        if stream.n_samples == clock.size and np.array_equal(stream.time, clock):
            return stream.data.copy()
        return Slerp(stream.time, Rotation.from_quat(stream.data))(clock).as_quat()
    return np.column_stack([np.interp(clock, stream.time, stream.data[:, c]) for c in range(stream.data.shape[1])])


def _imu(recording: Recording, streams: dict[str, Stream], name: str, group: str) -> Stream:
    if name not in streams:
        raise FtcalError(f"Recording {recording.path}: no {group}.{name} stream "
                         f"(has: {', '.join(sorted(streams)) or 'none'}).")
    return streams[name]
