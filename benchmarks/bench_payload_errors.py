"""Honesty of payload standard errors for every bias model (issue 44, item 4).

``python -m benchmarks.bench_payload_errors [SEEDS]``: recordings of :mod:`benchmarks.payload_recordings`
with a known mass (a drift that follows the pose order, holds, moves between holds, and holds with one more
assumption broken: slow coloured wander, a walk that speeds up, 10-bit quantisation, gain error), each fitted
by ``identify_recording`` with a constant bias (``none``) and a random walk. Per case:

- coverage: the share of seeds whose 95 % interval (±1.96 standard errors) holds the true mass;
- the largest |mass − truth| in standard errors;
- the stated standard error over the spread of delete-a-contiguous-block refits (5 blocks, refits on the
  kept rows: the reference the issue measured real data with), median over the first seeds (target 0.5-2);

now and with the rule before (the 20-block jackknife alone: :data:`~ftcal.core.jackknife.COARSER_BLOCKS`
emptied), on the same recordings and fits.
"""

from __future__ import annotations

import json
import sys
import time
import warnings
from contextlib import contextmanager

import numpy as np

from benchmarks.payload_recordings import MASS, breaking, simulate

SCENARIOS = ("sweep", "holds", "moves", "wander", "speed-up", "10-bit", "gain")
MODELS = ("none", "random-walk")
REFERENCE_SEEDS = 8  # seeds with the 5-refit reference spread (it costs five fits each)


def recording(scenario: str, seed: int):
    """Gravity, time and readings of one recording (20 poses of 40 samples for the time series)."""
    if scenario in ("sweep", "holds", "moves"):
        return simulate(scenario, seed, n_poses=20, per_pose=40)
    return breaking(scenario, seed)


def identify(g, time_s, wrench, model):
    from ftcal.payload.kinematics import Kinematics
    from ftcal.payload.tables import PayloadRecording, identify_recording

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return identify_recording(PayloadRecording(wrench, Kinematics(g), np.full(len(g), "run", dtype=object),
                                                   time_s, None), bias_drift=model, time_column="time").fit


@contextmanager
def previous_rule():
    """The standard errors before: the finest (20-block) jackknife only."""
    import ftcal.core.jackknife as jackknife
    import ftcal.payload.tables as tables

    kept = jackknife.COARSER_BLOCKS, tables.COARSER_BLOCKS
    jackknife.COARSER_BLOCKS = tables.COARSER_BLOCKS = ()
    try:
        yield
    finally:
        jackknife.COARSER_BLOCKS, tables.COARSER_BLOCKS = kept


def reference_spread(g, time_s, wrench, model, n_blocks: int = 5) -> float:
    """Delete-a-contiguous-block jackknife standard error of the mass (refits on the kept rows)."""
    edges = np.linspace(0, len(g), n_blocks + 1).astype(int)
    masses = np.array([identify(g[keep], time_s[keep], wrench[keep], model).mass
                       for keep in (np.r_[0:a, b:len(g)] for a, b in zip(edges[:-1], edges[1:]))])
    return float(np.sqrt((n_blocks - 1) / n_blocks * np.sum((masses - masses.mean()) ** 2)))


def one_case(scenario: str, model: str, seeds: int) -> dict:
    """Coverage, worst |z| and stated/reference ratio, now and before, over seeds 1000 ..."""
    out = {}
    data = [recording(scenario, 1000 + s) for s in range(seeds)]
    reference = [reference_spread(*data[s], model) for s in range(min(REFERENCE_SEEDS, seeds))]
    for rule in ("now", "before"):
        cpu = time.process_time()
        if rule == "now":
            fits = [identify(*d, model) for d in data]
        else:
            with previous_rule():
                fits = [identify(*d, model) for d in data]
        z = np.array([(f.mass - MASS) / f.stderr["mass"] for f in fits])
        ratio = [f.stderr["mass"] / r for f, r in zip(fits, reference)]
        out[rule] = {"coverage": float(np.mean(np.abs(z) < 1.96)), "worst_z": float(np.abs(z).max()),
                     "ratio": [float(np.min(ratio)), float(np.median(ratio)), float(np.max(ratio))],
                     "mass_error": float(np.median(np.abs([f.mass - MASS for f in fits])) / MASS),
                     "cpu_seconds": time.process_time() - cpu}
    return out


def payload_errors(seeds: int) -> dict:
    """The case ``make bench`` runs: every scenario and bias model."""
    start, cpu = time.perf_counter(), time.process_time()
    cases = {f"{scenario}/{model}": one_case(scenario, model, seeds) for scenario in SCENARIOS for model in MODELS}
    return {"seeds": seeds, "cases": cases, "seconds": time.perf_counter() - start,
            "cpu_seconds": time.process_time() - cpu}


PAYLOAD_ERROR_CASES = {"payload_errors": payload_errors}


if __name__ == "__main__":
    print(json.dumps(payload_errors(int(sys.argv[1]) if len(sys.argv) > 1 else 30), indent=1))
