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


def run_child(argv: list[str], src: str | None = None) -> dict:
    """``ftcal ARGV`` in a fresh Python process: wall, CPU (user + system of that child alone, from wait4) and
    its own peak resident memory (VmHWM, which starts afresh at exec; rusage's ru_maxrss would carry this
    parent's peak into it). ``src``: the ftcal source tree the child imports (default: this one's)."""
    env = dict(os.environ, FTCAL_PROGRESS="0")
    if src is not None:
        env["PYTHONPATH"] = os.pathsep.join([src, *env.get("PYTHONPATH", "").split(os.pathsep)[1:]])
    code = ("import sys\nfrom ftcal.cli import main\n"
            f"code = main({argv!r})\n"
            "hwm = [l for l in open('/proc/self/status') if l.startswith('VmHWM')][0]\n"
            "print('VmHWM', int(hwm.split()[1]) / 1024.0, file=sys.stderr)\nsys.exit(code)")
    with tempfile.TemporaryFile("w+") as out, tempfile.TemporaryFile("w+") as err:
        start = time.perf_counter()
        child = subprocess.Popen([sys.executable, "-c", code], stdout=out, stderr=err, env=env, text=True)
        _, status, usage = os.wait4(child.pid, 0)
        wall = time.perf_counter() - start
        child.returncode = os.waitstatus_to_exitcode(status)
        out.seek(0), err.seek(0)
        stdout, stderr = out.read(), err.read()
    if child.returncode != 0:
        raise RuntimeError(stderr[-2000:])
    peak = re.search(r"^VmHWM ([0-9.]+)", stderr, re.M)
    return {"wall_s": wall, "cpu_s": usage.ru_utime + usage.ru_stime, "peak_rss_mb": float(peak.group(1)),
            "stdout": stdout, "stderr": stderr}


def run_payload(table: str, bias_drift: str = "none", src: str | None = None) -> dict:
    """One ``ftcal payload TABLE --orientation qx,qy,qz,qw --bias-drift MODEL`` child process."""
    with tempfile.TemporaryDirectory() as folder:
        result = run_child(["payload", table, "--orientation", "qx,qy,qz,qw", "--bias-drift", bias_drift,
                            "-o", f"{folder}/payload.json"], src)
    mass = re.search(r"^\s*mass\s+([-0-9.e+]+)", result["stdout"], re.M)
    return {"wall_s": result["wall_s"], "cpu_s": result["cpu_s"], "peak_rss_mb": result["peak_rss_mb"],
            "mass": float(mass.group(1)) if mass else float("nan"), "bias_drift": bias_drift}


def payload_cli(n: int, bias_drift: str = "none", baseline_src: str | None = None) -> dict:
    """Make the table (not timed), then time whole ``ftcal payload`` processes on it: this tree's and, with
    ``baseline_src``, another tree's (the code before a change), in turn (this, baseline, this, baseline)."""
    with tempfile.TemporaryDirectory() as folder:
        table = str(Path(folder) / "holds.parquet")
        make_table(table, n)
        runs = {"this": [], "baseline": []}
        for _ in range(2 if baseline_src else 1):
            runs["this"].append(run_payload(table, bias_drift))
            if baseline_src:
                runs["baseline"].append(run_payload(table, bias_drift, baseline_src))
    result = {name: {key: float(np.median([r[key] for r in rows])) for key in ("wall_s", "cpu_s", "mass",
                                                                              "peak_rss_mb")}
              for name, rows in runs.items() if rows}
    result.update(n=n, bias_drift=bias_drift, seconds=result["this"]["wall_s"])
    return result


CASES = {f.__name__: f for f in (payload_cli,)}


if __name__ == "__main__":
    print(json.dumps(payload_cli(int(sys.argv[1]), *(sys.argv[2:3] or []))))
