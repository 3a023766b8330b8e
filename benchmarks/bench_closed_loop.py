"""The closed loop of ``ftcal demo --scenario closed-loop``: every condition per variant and seed, and its cost.

Not timings to assert: the numbers are the controller's contact-force RMSE and maximum error against
MuJoCo's own contact force, settling after the first ramp and the phantom force in free motion, for
(a) the factory matrix with a tare, (a') + ROS-style gravity compensation, (b0) the in-situ affine model +
tool, (b) ftcal's calibration + tool, (c) (b) + ``ftcal.live``, (d) the true wrench; the seed-by-seed ties
and the issue's targets; plus the run's wall and CPU time.

Run: ``python -m benchmarks.bench_closed_loop [variant] [seed ...]``.
"""

from __future__ import annotations

import sys
import tempfile
import time


def closed_loop(variant: str = "standard", seeds=(0,), quick: bool = False) -> dict:
    """One variant over ``seeds``; its summary's per-seed conditions, ties, targets, with wall and CPU seconds."""
    import dataclasses
    from pathlib import Path

    from ftcal.sim.closed_loop import CLOSED_LOOP_QUICK, ClosedLoopConfig, run_closed_loop

    with tempfile.TemporaryDirectory() as folder:
        config = ClosedLoopConfig.of_variant(variant, out_dir=Path(folder))
        if quick:
            config = dataclasses.replace(config, **CLOSED_LOOP_QUICK)
        start, cpu = time.perf_counter(), time.process_time()
        summary = run_closed_loop(config, seeds=tuple(seeds))
        seconds, cpu = time.perf_counter() - start, time.process_time() - cpu
    return {"seconds": seconds, "cpu_seconds": cpu, "variant": variant, "seeds": list(seeds),
            "description": summary["description"], "conditions": summary["conditions"],
            "per_seed": summary["per_seed"], "ties": summary["ties"], "targets": summary["targets"],
            "ratios": summary["ratios"], "calibration": summary["calibration"]}


CASES = {f.__name__: f for f in (closed_loop,)}


if __name__ == "__main__":
    import json

    print(json.dumps(closed_loop(sys.argv[1] if len(sys.argv) > 1 else "standard",
                                 [int(s) for s in sys.argv[2:]] or [0])))
