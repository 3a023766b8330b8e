"""The closed loop of ``ftcal demo --scenario closed-loop``: contact-force errors per condition, and its cost.

Not timings to assert: the numbers are the controller's contact-force RMSE and maximum error against
MuJoCo's own contact force, settling after the 5 → 30 N ramp and the phantom force in free motion, for
(a) the factory matrix with a tare, (b) ftcal's calibration + tool compensation, (c) (b) + ``ftcal.live``
when importable, (d) the true wrench; plus the scenario's wall and CPU time.

Run: ``python -m benchmarks.bench_closed_loop [seed]``.
"""

from __future__ import annotations

import sys
import tempfile
import time


def closed_loop(seed: int = 0, quick: bool = False) -> dict:
    """One run of the scenario; its summary's conditions, ratios and calibration, with wall and CPU seconds."""
    import dataclasses
    from pathlib import Path

    from ftcal.sim.closed_loop import CLOSED_LOOP_QUICK, ClosedLoopConfig, run_closed_loop

    with tempfile.TemporaryDirectory() as folder:
        config = ClosedLoopConfig(out_dir=Path(folder), seed=seed)
        if quick:
            config = dataclasses.replace(config, **CLOSED_LOOP_QUICK)
        start, cpu = time.perf_counter(), time.process_time()
        summary = run_closed_loop(config)
        seconds, cpu = time.perf_counter() - start, time.process_time() - cpu
    return {"seconds": seconds, "cpu_seconds": cpu, "conditions": summary["conditions"], "ratios": summary["ratios"],
            "calibration": summary["calibration"]}


CASES = {f.__name__: f for f in (closed_loop,)}


if __name__ == "__main__":
    import json

    print(json.dumps(closed_loop(int(sys.argv[1]) if len(sys.argv) > 1 else 0)))
