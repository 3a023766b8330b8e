"""Memory stays flat over a long ``ftcal live --replay``: the peak (tracemalloc: Python objects and numpy arrays)
of a 4× longer recording is that of the shorter one, not 4× it. The 1-hour case is a row of ``make bench``."""

from __future__ import annotations

import tracemalloc

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from ftcal.live import LiveCalibrator
from ftcal.live.replay import ReplayColumns, replay_table

AXES = ("Fx", "Fy", "Fz", "Tx", "Ty", "Tz")
RATE = 1000.0
PIECE = 30_000  # rows written at a time
CHUNK = 4096  # rows replayed at a time (the command's default is 65,536: the bench's 1-hour row)


def still_recording(path, n_rows: int, seed: int = 0) -> None:
    """A still sensor at 1 kHz: a walking bias, noise, a 1.2 kg tool's weight, written piece by piece."""
    rng = np.random.default_rng(seed)
    bias = np.zeros(6)
    schema = pa.schema([(c, pa.float64()) for c in ("time", "qx", "qy", "qz", "qw", *AXES)])
    with pq.ParquetWriter(path, schema) as writer:
        for start in range(0, n_rows, PIECE):
            n = min(PIECE, n_rows - start)
            t = (start + np.arange(n)) / RATE
            walk = bias + np.cumsum(rng.normal(scale=3.0 / 60.0 / np.sqrt(RATE), size=(n, 6)), axis=0)
            bias = walk[-1]
            wrench = walk + rng.normal(scale=0.05, size=(n, 6))
            wrench[:, 2] -= 1.2 * 9.81
            cols = {"time": t, "qx": np.zeros(n), "qy": np.zeros(n), "qz": np.zeros(n), "qw": np.ones(n)}
            cols.update({a: wrench[:, j] for j, a in enumerate(AXES)})
            writer.write_table(pa.table(cols, schema=schema))


def replay_peak(path, out) -> tuple[int, int]:
    live = LiveCalibrator(noise_std=np.full(6, 0.05), walk_std=np.full(6, 3.0))
    columns = ReplayColumns("time", AXES, False, "quaternion", ("qx", "qy", "qz", "qw"))
    tracemalloc.start()
    try:
        summary = replay_table(path, live, columns, out, chunk_rows=CHUNK)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    return summary.n_samples, peak


def test_replay_memory_does_not_grow_with_length(tmp_path):
    short, long = tmp_path / "short.parquet", tmp_path / "long.parquet"
    still_recording(short, 30_000)
    still_recording(long, 120_000)
    n_short, peak_short = replay_peak(short, tmp_path / "out-short.parquet")
    n_long, peak_long = replay_peak(long, tmp_path / "out-long.parquet")
    assert (n_short, n_long) == (30_000, 120_000)
    # One chunk's arrays dominate; 4x the samples (29 chunks against 8) may not add a fifth to the peak.
    assert peak_long < 1.2 * peak_short, (peak_short, peak_long)
    # A chunk's worth, not the recording's: 120,000 rows of the 30 float64 output columns alone are 29 MB.
    assert peak_long < 0.5 * n_long * 30 * 8, peak_long
