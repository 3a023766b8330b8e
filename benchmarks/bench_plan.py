"""``ftcal plan``'s design time: ``n_poses`` poses from ``n_candidates`` configurations × 4 loads.

The robot is the 4-joint arm of ``ftcal demo --scenario plan``; loads as in that
scenario. Timed: the whole :func:`ftcal.plan.design_experiment` (candidates, one
batched iDynTree pass per load, information, greedy design, order, scores),
with the candidate pass and the design reported apart. The robot model is
built before the clock starts. Target (issue 19): 60 poses from 10⁴ candidates
in ≤ 5 s on 2 cores.

Run: ``python -m benchmarks.bench_plan [n_poses] [n_candidates]``.
"""

from __future__ import annotations

import sys
import time


def plan_design(n_poses: int, n_candidates: int, objective: str = "calibration", degree: int = 2) -> dict:
    """Plan with the demo arm and its four loads; seconds of the whole call and of its two phases."""
    import numpy as np

    from ftcal.plan import PlanRequest, design_experiment
    from ftcal.plan import experiment as experiment_module
    from ftcal.robot import RobotModel
    from ftcal.sim.demo_plan import CALIBRATION_LOADS, _loads
    from ftcal.sim.plan_arm import ARM_URDF, SENSOR

    robot = RobotModel.from_text(ARM_URDF, "arm.urdf")
    request = PlanRequest(_loads(CALIBRATION_LOADS), n_poses, objective=objective, degree=degree, sensor=SENSOR,
                          min_height=0.2, n_candidates=n_candidates)
    phases: dict[str, float] = {}
    original = experiment_module.candidate_poses

    def timed_candidates(*args, **kwargs):
        start = time.perf_counter()
        out = original(*args, **kwargs)
        phases["candidates_seconds"] = time.perf_counter() - start
        return out

    experiment_module.candidate_poses = timed_candidates
    try:
        start, cpu = time.perf_counter(), time.process_time()
        plan = design_experiment(robot, request)
        seconds, cpu = time.perf_counter() - start, time.process_time() - cpu
    finally:
        experiment_module.candidate_poses = original
    # cpu_seconds: this process's CPU time; on a machine shared with other jobs it is closer than the
    # wall time to what an idle machine takes (the work runs on one core but for a short threaded step).
    return {"seconds": seconds, "cpu_seconds": cpu, **phases, "design_seconds": seconds - phases["candidates_seconds"],
            "log_det_planned": plan.planned.log_det, "log_det_random": plan.random.log_det,
            "n_candidate_poses": int(plan.candidates.n_configurations * plan.candidates.n_loads),
            "poses_per_load": np.bincount(plan.load, minlength=plan.candidates.n_loads).tolist()}


CASES = {f.__name__: f for f in (plan_design,)}


if __name__ == "__main__":
    import json

    n_poses = int(sys.argv[1]) if len(sys.argv) > 1 else 60
    n_candidates = int(sys.argv[2]) if len(sys.argv) > 2 else 10_000
    for objective in ("calibration", "payload"):
        print(json.dumps({"objective": objective, **plan_design(n_poses, n_candidates, objective)}))
