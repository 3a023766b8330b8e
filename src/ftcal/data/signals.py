"""Checks and smoothing for logged streams.

* :func:`check_finite` rejects NaN/inf stretches, naming the stream, column and time span;
* :func:`channel_issues` finds saturated channels (at an ADC limit, or flat at
  the channel's extreme value) and stuck channels (constant while the other
  channels of the same stream move);
* :func:`smooth` is the Savitzky–Golay filter the paper applies (order 3, frame 101).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..runtime.checks import check_int
from ..runtime.errors import FtcalError, ParameterError
from .recording import Stream

# A noisy analog channel does not repeat its exact extreme value this many times in a row
# unless it is clipped.
SATURATION_RUN = 20
# Constant this long (samples) while a sibling channel moves means the channel is stuck.
STUCK_RUN = 200


@dataclass(frozen=True)
class ChannelIssue:
    """A suspicious stretch in one channel."""

    stream: str
    column: str
    kind: str  # "saturated" or "stuck"
    samples: int
    start_time: float

    def __str__(self) -> str:
        return (f"{self.stream} channel {self.column} looks {self.kind}: {self.samples} samples "
                f"from t={self.start_time:.3f} s")


def check_finite(stream: Stream) -> None:
    """Raise :class:`FtcalError` if the stream has NaN/inf values or timestamps."""
    bad_t = ~np.isfinite(stream.time)
    if bad_t.any():
        raise FtcalError(f"{stream.name}: {int(bad_t.sum())} non-finite timestamp(s), first at sample "
                         f"{int(np.argmax(bad_t))}.")
    bad = ~np.isfinite(stream.data)
    if not bad.any():
        return
    col = int(np.argmax(bad.any(axis=0)))
    start, stop = _runs(bad[:, col])[0]
    n_runs = sum(len(_runs(bad[:, c])) for c in range(bad.shape[1]))
    raise FtcalError(f"{stream.name}: NaN stretch in column {stream.columns[col]!r} from t={stream.time[start]:.3f} "
                     f"to t={stream.time[stop - 1]:.3f} s ({stop - start} samples; {n_runs} stretch(es) in all).")


def channel_issues(stream: Stream, adc_limits: tuple[float, float] | None = None) -> list[ChannelIssue]:
    """Saturated and stuck channels of ``stream`` (see the module docstring)."""
    issues = []
    x = stream.data
    moving = np.ptp(x, axis=0) > 0 if x.shape[0] else np.zeros(x.shape[1], bool)
    for c, name in enumerate(stream.columns):
        col = x[:, c]
        if adc_limits is not None:
            clipped = (col <= adc_limits[0]) | (col >= adc_limits[1])
            if clipped.any():
                issues.append(ChannelIssue(stream.name, name, "saturated", int(clipped.sum()),
                                           float(stream.time[np.argmax(clipped)])))
                continue
        runs = _runs(np.r_[False, np.diff(col) == 0])
        if not runs:
            continue
        start, stop = max(runs, key=lambda r: r[1] - r[0])
        start -= 1  # the run of equal differences starts one sample earlier
        length = stop - start
        value = col[start]
        others_move = any(np.ptp(x[start:stop, o]) > 0 for o in range(x.shape[1]) if o != c and moving[o])
        if adc_limits is None and length >= SATURATION_RUN and value in (col.min(), col.max()) and moving[c]:
            issues.append(ChannelIssue(stream.name, name, "saturated", length, float(stream.time[start])))
        elif length >= STUCK_RUN and others_move:
            issues.append(ChannelIssue(stream.name, name, "stuck", length, float(stream.time[start])))
    return issues


def smooth(x: np.ndarray, frame: int = 101, order: int = 3, where: str = "data") -> np.ndarray:
    """Savitzky–Golay smoothing along samples.

    x : ndarray of shape (n_samples, n_columns) or (n_samples,); returns the same shape.
    """
    from scipy.signal import savgol_filter

    frame = check_int(frame, "savgol_frame", "smooth", 3)
    order = check_int(order, "savgol_order", "smooth", 0, 10)
    if frame % 2 == 0 or order >= frame:
        raise FtcalError(f"The 'savgol_frame' parameter must be odd and larger than the order ({order}). "
                         f"Got {frame} instead.")
    if x.shape[0] < frame:
        raise ParameterError(('savgol_frame', 'no_filter'), f"{where}: {x.shape[0]} samples is fewer than the Savitzky–Golay frame ({frame}); "
                         f"use a smaller {{savgol_frame}} or {{no_filter}}.")
    return savgol_filter(x, frame, order, axis=0)


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """(start, stop) of each run of True in a 1-D boolean array."""
    edges = np.flatnonzero(np.diff(np.r_[0, mask.astype(np.int8), 0]))
    return [(int(a), int(b)) for a, b in zip(edges[::2], edges[1::2])]
