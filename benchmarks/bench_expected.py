"""Throughput of expected F/T wrenches: all six F/T sensors of an iCub.

Three ways, measured in the same run on the same random static poses:

* ``per-sample loop``: the plain iDynTree recipe, as a user would write it —
  per sample a fresh ``JointPosDoubleArray`` filled joint by joint, then one
  ``getMeasurement`` + ``toNumPy`` per sensor;
* ``ftcal, 1 process``: :class:`ftcal.robot.WrenchPredictor` (buffers reused,
  only F/T sensors in the estimator, one vector read per sample);
* ``ftcal, N workers``: :func:`ftcal.robot.expected_wrenches`, samples split
  across worker processes, each with its own estimator.

Peak memory is the peak resident set size (``resource.getrusage``) of this
process and, separately, of the largest worker process.

Run: ``python -m benchmarks.bench_expected [n_samples]``.
"""

from __future__ import annotations

import os
import resource
import sys
import time

import numpy as np

MODEL = "iCubGenova04"


def _baseline(urdf: str, q: np.ndarray) -> np.ndarray:
    import idyntree.swig as idyn

    est = idyn.ExtWrenchesAndJointTorquesEstimator()
    est.loadModelAndSensorsFromFile(urdf)
    model, sensors = est.model(), est.sensors()
    n_ft = sensors.getNrOfSensors(idyn.SIX_AXIS_FORCE_TORQUE)
    base = model.getFrameIndex("root_link")
    unknowns = idyn.LinkUnknownWrenchContacts(model)
    unknowns.addNewUnknownFullWrenchInFrameOrigin(model, base)
    meas, contacts = idyn.SensorsMeasurements(sensors), idyn.LinkContactWrenches(model)
    tau, zero = idyn.JointDOFsDoubleArray(model), idyn.JointDOFsDoubleArray(model)
    zero.zero()
    gravity = idyn.Vector3.FromPython(np.array([0.0, 0.0, -9.81]))
    wrench = idyn.Wrench()
    out = np.empty((len(q), n_ft, 6))
    for k, row in enumerate(q):
        qj = idyn.JointPosDoubleArray(model)
        for j, v in enumerate(row):
            qj.setVal(j, float(v))
        est.updateKinematicsFromFixedBase(qj, zero, zero, base, gravity)
        est.computeExpectedFTSensorsMeasurements(unknowns, meas, contacts, tau)
        for i in range(n_ft):
            meas.getMeasurement(idyn.SIX_AXIS_FORCE_TORQUE, i, wrench)
            out[k, i] = wrench.toNumPy()
    return out


def _peak_mb(who: int) -> float:
    return resource.getrusage(who).ru_maxrss / 1024.0  # ru_maxrss is in KiB on Linux


def main(n_samples: int = 100_000, baseline_samples: int = 10_000, workers: int = 2) -> list[dict]:
    """Measure, print a markdown table, and return its rows as dicts."""
    os.environ.setdefault("FTCAL_PROGRESS", "0")
    from ftcal.robot import RobotModel, WrenchPredictor, expected_wrenches
    from ftcal.robot.model import icub_model_path

    robot = RobotModel.load(name=MODEL)
    rng = np.random.default_rng(0)
    q = rng.uniform(-1.0, 1.0, (n_samples, len(robot.joint_names)))
    rows = []

    def record(method: str, n: int, seconds: float, result: np.ndarray, peak: float) -> None:
        rows.append({"method": method, "samples": n, "seconds": round(seconds, 3),
                     "samples_per_s": round(n / seconds), "sensors": result.shape[1],
                     "peak_rss_mb": round(peak, 1)})

    t = time.perf_counter()
    base = _baseline(str(icub_model_path(MODEL)), q[:baseline_samples])
    record("per-sample loop (plain iDynTree)", baseline_samples, time.perf_counter() - t, base,
           _peak_mb(resource.RUSAGE_SELF))

    predictor = WrenchPredictor(robot)
    t = time.perf_counter()
    single = predictor.compute(q[:baseline_samples * 2])
    record("ftcal, 1 process", baseline_samples * 2, time.perf_counter() - t, single,
           _peak_mb(resource.RUSAGE_SELF))
    if not np.allclose(single[:baseline_samples], base, rtol=1e-12, atol=1e-12):
        raise AssertionError("ftcal and the plain loop disagree")

    t = time.perf_counter()
    pooled = expected_wrenches(robot, q, workers=workers)
    record(f"ftcal, {workers} worker processes", n_samples, time.perf_counter() - t, pooled,
           max(_peak_mb(resource.RUSAGE_SELF), _peak_mb(resource.RUSAGE_CHILDREN)))
    if not np.array_equal(pooled[:baseline_samples * 2], single):
        raise AssertionError("the worker processes disagree with the single process")

    reference = rows[0]["samples_per_s"]
    for row in rows:
        row["speedup"] = round(row["samples_per_s"] / reference, 2)
    print(f"Expected wrenches, {MODEL}, {len(robot.ft_sensors)} F/T sensors, {len(robot.joint_names)} joints, "
          f"{os.cpu_count()} CPUs\n")
    print("| method | samples | s | samples/s | speed-up | peak RSS (MB) |")
    print("|---|---:|---:|---:|---:|---:|")
    for r in rows:
        print(f"| {r['method']} | {r['samples']} | {r['seconds']} | {r['samples_per_s']} | "
              f"{r['speedup']}× | {r['peak_rss_mb']} |")
    return rows


if __name__ == "__main__":
    main(*(int(a) for a in sys.argv[1:2]))
