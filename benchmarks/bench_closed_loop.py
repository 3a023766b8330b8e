"""The closed loop of ``ftcal demo --scenario closed-loop``: every condition per variant and seed, and its cost.

Not timings to assert: the numbers are the controller's contact-force RMSE and maximum error against
MuJoCo's own contact force, settling after the first ramp and the phantom force in free motion, for
(a) the factory matrix with a tare, (a') + ROS-style gravity compensation, (b0) the in-situ affine model +
tool, (b) ftcal's calibration + tool, (c) (b) + ``ftcal.live``, (d) the true wrench; the seed-by-seed ties
and the issue's targets; plus the run's wall and CPU time.

Run: ``python -m benchmarks.bench_closed_loop [variant] [seed ...]``; what the tracker saw and did, per phase:
``python -m benchmarks.bench_closed_loop tracking [variant] [seed] [cycles]``.
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


PHASES = ("approach", "contact", "release", "free motion", "back and still")


def tracking(variant: str = "long-task", seed: int = 0, cycles: int | None = None) -> dict:
    """Why tracking helps or not: (b) and (c) of one seed, with what the tracker saw and did, per phase.

    Runs ``ftcal + live`` with a recorder around ``ftcal.live.LiveCalibrator`` (its public ``step``; nothing
    changed in it) and reports, per task phase: the share of samples the tracker called static and the share it
    updated on; the calibrated wrench's true error (ftcal's model minus MuJoCo's sensor wrench: drift and model
    error) since the start tare, on the controlled axis (world z, in contact) and as a force norm, against what
    the tracker's bias left of it; and the flags raised. The untracked error on world z in contact is what
    tracking can remove from the contact RMSE; the controller's floor (the true wrench's RMSE) stays.
    """
    import dataclasses

    import numpy as np

    from ftcal.sim.closed_loop import (CYCLE_S, GRAVITY, ClosedLoopConfig, LiveEstimator, arm, calibrate,
                                       model_row, run_task)
    from ftcal.sim.plan_arm import SENSOR

    config = ClosedLoopConfig.of_variant(variant, seed=seed)
    if cycles is not None:
        config = dataclasses.replace(config, cycles=cycles)
    sensor = config.sensor.draw(config.seed)
    robot, scene = arm(config)
    calibration = calibrate(robot, sensor, config, np.random.default_rng([config.seed, 41]))
    row = model_row(calibration["model"])
    # preallocated per-sample record (lists of small arrays would take 0.7 GB for the long task)
    n_max = int((config.cycles * CYCLE_S + 2.0) * config.rate)
    error, bias, rotation = np.empty((n_max, 3)), np.empty((n_max, 3)), np.empty((n_max, 3, 3))
    static, updated = np.zeros(n_max, bool), np.zeros(n_max, bool)
    flags: dict[str, int] = {}
    calls = [0]

    class Recorded(LiveEstimator):
        def __call__(self, counts, temperature, rotation_now, true_wrench, t):
            sample = self.live.step(t, raw=np.append(counts, temperature), gravity=rotation_now.T @ GRAVITY,
                                    temperature=temperature)
            k = calls[0]
            calls[0] += 1
            error[k] = (row(counts, temperature) - true_wrench)[:3]
            bias[k] = np.asarray(sample.bias, float)[:3]
            static[k], updated[k], rotation[k] = sample.static, sample.updated, rotation_now
            for name in sample.flags:
                flags[name] = flags.get(name, 0) + 1
            return rotation_now @ np.asarray(sample.compensated)[:3]

    start, cpu = time.perf_counter(), time.process_time()
    trace = run_task(scene, sensor, Recorded(calibration["model"], calibration["payloads"]["ftcal"]), config,
                     noise_seed=config.seed * 1000 + 5)
    n = trace.time.size
    error, bias, rotation, static, updated = error[:n], bias[:n], rotation[:n], static[:n], updated[:n]
    world = np.einsum("nij,nj->ni", rotation, error[:, :3])
    # error left by the tracker's bias: its bias in world axes, at each sample (the tracker's start = the tare)
    left = world - np.einsum("nij,nj->ni", rotation, bias[:, :3])
    # each stretch of a phase by its mean (the per-sample noise, 0.15 N, averages out): a constant error over a
    # contact shifts its force by that much; the reference is the first approach's mean (the start pose's tare)
    stretches = np.flatnonzero(np.r_[True, trace.phase[1:] != trace.phase[:-1]])
    bounds = list(zip(stretches, [*stretches[1:], n]))
    first = world[bounds[0][0]:bounds[0][1]].mean(axis=0)
    first_left = left[bounds[0][0]:bounds[0][1]].mean(axis=0)
    out = {"variant": variant, "seed": seed, "cycles": config.cycles, "sensor": SENSOR, "phases": {}}
    for code, name in enumerate(PHASES):
        spans = [(a, b) for a, b in bounds if trace.phase[a] == code]
        if not spans:
            continue
        inside = trace.phase == code
        untracked = np.array([world[a:b].mean(axis=0) - first for a, b in spans])
        tracked = np.array([left[a:b].mean(axis=0) - first_left for a, b in spans])
        out["phases"][name] = {
            "stretches": len(spans), "static": float(static[inside].mean()), "updated": float(updated[inside].mean()),
            # RMS over the stretches of each stretch's mean error: world z, and the force's norm
            "untracked_z": float(np.sqrt(np.mean(untracked[:, 2] ** 2))),
            "tracked_z": float(np.sqrt(np.mean(tracked[:, 2] ** 2))),
            "untracked_force": float(np.sqrt(np.mean(np.sum(untracked ** 2, axis=1)))),
            "tracked_force": float(np.sqrt(np.mean(np.sum(tracked ** 2, axis=1)))),
            "untracked_z_last": float(untracked[-1, 2]), "tracked_z_last": float(tracked[-1, 2])}
    out["flags"] = dict(sorted(flags.items()))
    out["seconds"], out["cpu_seconds"] = time.perf_counter() - start, time.process_time() - cpu
    return out


CASES = {f.__name__: f for f in (closed_loop, tracking)}


if __name__ == "__main__":
    import json

    if len(sys.argv) > 1 and sys.argv[1] == "tracking":
        # python -m benchmarks.bench_closed_loop tracking [variant] [seed] [cycles]
        args = sys.argv[2:]
        print(json.dumps(tracking(args[0] if args else "long-task", int(args[1]) if len(args) > 1 else 0,
                                  int(args[2]) if len(args) > 2 else None)))
    else:
        print(json.dumps(closed_loop(sys.argv[1] if len(sys.argv) > 1 else "standard",
                                     [int(s) for s in sys.argv[2:]] or [0])))
