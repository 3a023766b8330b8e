"""``ftcal payload`` as a user runs it: the whole process on one Parquet table of static holds.

The table: ``n`` rows at 100 Hz, a 1.3 kg tool held still in 100 random orientations (quaternion
columns ``qx..qw``) with 2 s slerp moves between them, readings ``u1..u6`` with noise and a bias that
walks (so ``--bias-drift random-walk`` has something to find). Each case is one child process: CPU
seconds (user + system from its rusage), wall seconds, peak resident memory, and the mass it printed
(against the 1.3 kg the table was made with).

Run: ``python -m benchmarks.bench_payload_cli N [BIAS_DRIFT]``.
"""

from __future__ import annotations

import json
import os
import re
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

MASS, COM = 1.3, np.array([0.01, -0.02, 0.07])
BIAS = np.array([3.0, -2.0, 5.0, 0.1, -0.2, 0.05])
RATE_HZ, POSES, MOVE_S = 100.0, 100, 2.0


def make_table(path: str | os.PathLike, n: int, seed: int = 0) -> None:
    """Write the static-holds table of ``n`` rows (see the module docstring) to ``path`` (Parquet)."""
    import pandas as pd
    from scipy.spatial.transform import Rotation, Slerp

    rng = np.random.default_rng(seed)
    poses = Rotation.random(POSES, random_state=seed)
    per_pose = n // POSES
    move = int(MOVE_S * RATE_HZ)
    quats = np.empty((n, 4))
    for i in range(POSES):
        a, b = i * per_pose, (i + 1) * per_pose if i < POSES - 1 else n
        quats[a:b] = poses[i].as_quat()
        if i:  # the first rows of each pose's span move there from the previous pose
            slerp = Slerp([0.0, 1.0], Rotation.concatenate([poses[i - 1], poses[i]]))
            quats[a:a + move] = slerp(np.linspace(0.0, 1.0, move)).as_quat()
    rot = Rotation.from_quat(quats)
    g = rot.inv().apply([0.0, 0.0, -9.81])
    wrench = np.c_[MASS * g, np.cross(COM, MASS * g)] + BIAS
    wrench += rng.normal(size=wrench.shape) * [0.3, 0.3, 0.3, 0.01, 0.01, 0.01]
    wrench += np.cumsum(rng.normal(size=wrench.shape), axis=0) * [3e-4, 3e-4, 3e-4, 1e-5, 1e-5, 1e-5]
    frame = pd.DataFrame(wrench, columns=[f"u{i + 1}" for i in range(6)])
    frame[["qx", "qy", "qz", "qw"]] = quats
    frame["time"] = np.arange(n) / RATE_HZ
    frame.to_parquet(path)


def run_payload(table: str, bias_drift: str = "none") -> dict:
    """One ``ftcal payload TABLE --orientation qx,qy,qz,qw --bias-drift MODEL`` child process."""
    ftcal = str(Path(sys.executable).with_name("ftcal"))
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    with tempfile.TemporaryDirectory() as folder:
        argv = [ftcal, "payload", table, "--orientation", "qx,qy,qz,qw", "--bias-drift", bias_drift,
                "-o", f"{folder}/payload.json"]
        start = time.perf_counter()
        done = subprocess.run(argv, capture_output=True, text=True, env=dict(os.environ, FTCAL_PROGRESS="0"))
        wall = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if done.returncode != 0:
        raise RuntimeError(done.stderr[-2000:])
    mass = re.search(r"mass\s+([-0-9.e+]+)", done.stdout)
    return {"wall_s": wall, "cpu_s": (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime),
            "child_peak_rss_mb": after.ru_maxrss / 1024.0, "mass": float(mass.group(1)) if mass else float("nan"),
            "bias_drift": bias_drift}


def payload_cli(n: int, bias_drift: str = "none") -> dict:
    """Make the table (not timed), then time one whole ``ftcal payload`` process on it."""
    with tempfile.TemporaryDirectory() as folder:
        table = str(Path(folder) / "holds.parquet")
        make_table(table, n)
        result = run_payload(table, bias_drift)
    result.update(n=n, seconds=result["wall_s"])
    return result


CASES = {f.__name__: f for f in (payload_cli,)}


if __name__ == "__main__":
    print(json.dumps(payload_cli(int(sys.argv[1]), *(sys.argv[2:3] or []))))
