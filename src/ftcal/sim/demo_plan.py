"""``ftcal demo --scenario plan``: planned poses against random poses at the same budget.

One simulated 4-joint arm (:mod:`ftcal.sim.plan_arm`), one simulated strain-gauge
sensor (:class:`ftcal.sim.sensor.StrainGaugeSensor`, mildly nonlinear), four loads:

* calibration: ``n_poses`` poses chosen by ``ftcal plan`` (greedy D-optimal for
  degree 2) and as many random configurations with random loads (the planner's own
  random baseline, same seed stream, and ``random_designs`` − 1 more: the printed
  random error is their median per axis); each pose recorded ``samples_per_pose``
  times; a degree-2 calibration fitted on each; all validated on one common
  held-out set of random poses and loads, noise-free readings;
* payload: ``payload_poses`` poses planned for bias + mass + COM of one tool
  against as many random ones; readings = wrench + bias + noise, identified
  ``payload_repeats`` times with fresh noise; RMS errors against the true values.

Writes ``arm.urdf`` (so ``ftcal plan --urdf DIR/arm.urdf`` runs on the same
robot), ``plan.csv`` (the planned calibration poses, as ``ftcal plan`` writes
them) and ``summary.json``.
"""

from __future__ import annotations

import json
import time
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..data.tables import write_table
from ..payload.accumulate import payload_statistics
from ..payload.identify import identify_from_statistics
from ..payload.kinematics import Kinematics
from ..plan.candidates import candidate_poses
from ..plan.design import random_design
from ..robot.model import RobotModel
from ..robot.payloads import parse_payload_spec
from ..runtime.atomic import write_text_atomic
from ..runtime.errors import IllPosedFitWarning, OutOfRangeWarning
from ..workflow import plan_experiment
from .plan_arm import ARM_URDF, HAND_COM, HAND_MASS, SENSOR, TOOL_OFFSET
from .sensor import SensorParams, StrainGaugeSensor

CALIBRATION_LOADS = ("none", "tool:1@0.03,0,0.04", "tool:3@0,0.05,0.08", "tool:6@0.06,-0.03,0.12")
PAYLOAD_LOAD = "tool:1.5@0.04,0,0.06"
TEMPERATURE = 25.0  # °C, the sensor's reference: this scenario is about poses, not drift
FORCE_BIAS, TORQUE_BIAS = (4.2, -3.1, 7.5), (0.21, -0.12, 0.05)
AXES = ("Fx", "Fy", "Fz", "Tx", "Ty", "Tz")
CHANNELS = ("u1", "u2", "u3", "u4", "u5", "u6")  # the sensor's raw channels (no temperature: it is held)


@dataclass(frozen=True)
class PlanDemoConfig:
    """Sizes of the scenario (poses, candidates, validation configurations × 4 loads, random designs, noise draws)."""

    out_dir: Path = Path("ftcal-plan-demo")
    seed: int = 0
    n_poses: int = 60
    n_candidates: int = 10_000
    n_validation: int = 500
    samples_per_pose: int = 10
    random_designs: int = 10
    payload_poses: int = 6
    payload_repeats: int = 200
    payload_noise: tuple[float, float] = (0.1, 0.01)
    min_height: float = 0.2
    # Mildly nonlinear: a degree-2 fit leaves ~0.03 N of model error, below the noise of a 10-sample pose.
    sensor: SensorParams = field(default_factory=lambda: SensorParams(
        force_full_scale=250.0, torque_full_scale=25.0, stiffening=0.05, saturation=5.0, coupling=0.1))


# `ftcal demo --scenario plan --quick`
PLAN_QUICK = {"n_candidates": 3000, "n_validation": 200, "payload_repeats": 50}


def _loads(specs: tuple[str, ...]) -> tuple:
    return tuple(None if s == "none" else parse_payload_spec(s) for s in specs)


def calibration_errors(sensor: StrainGaugeSensor, wrench: np.ndarray, validation: np.ndarray, samples: int,
                       rng: np.random.Generator) -> tuple[np.ndarray, int]:
    """Validation RMS error per axis of a degree-2 calibration fitted at ``wrench`` (n, 6) poses.

    Also returns how many validation samples lie outside the training range (extrapolated).
    """
    from ..core.dataset import Dataset
    from ..workflow import evaluate, fit

    train = np.repeat(wrench, samples, axis=0)
    readings = sensor.measure(train, np.full(train.shape[0], TEMPERATURE), rng)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", IllPosedFitWarning)  # random designs may leave terms weakly excited
        model = fit(Dataset.from_arrays(readings, train, input_names=CHANNELS), inputs=CHANNELS, degree=2).model
    # Noise-free held-out readings: the error is the calibration's, not the validation noise.
    held_out = sensor.measure(validation, np.full(validation.shape[0], TEMPERATURE))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", OutOfRangeWarning)  # counted in the summary instead
        metrics = evaluate(model, Dataset.from_arrays(held_out, validation, input_names=CHANNELS)).metrics
    return np.asarray(metrics["rmse"]), int(metrics["n_outside_range"])


def payload_errors(designs: list[np.ndarray], truth: dict, noise: tuple[float, float], repeats: int,
                   rng: np.random.Generator) -> dict[str, float]:
    """RMS identification errors over designs × ``repeats`` noise draws.

    designs : sensor-frame gravity at the poses of each design, ndarrays of shape (n_poses, 3)
    """
    errors: dict[str, list[float]] = {"mass": [], "com": [], "force_bias": [], "torque_bias": []}
    for gravity in designs:
        _identify_repeatedly(gravity, truth, noise, repeats, rng, errors)
    return {k: float(np.sqrt(np.mean(np.square(v)))) for k, v in errors.items()}


def _identify_repeatedly(gravity: np.ndarray, truth: dict, noise: tuple[float, float], repeats: int,
                         rng: np.random.Generator, errors: dict[str, list[float]]) -> None:
    mc = truth["mass"] * truth["com"]
    clean = np.column_stack([truth["mass"] * gravity, np.cross(mc, gravity)])
    clean += np.concatenate([truth["force_bias"], truth["torque_bias"]])
    sigma = np.repeat(noise, 3)
    kinematics = Kinematics(gravity)
    # The payload step (identify_payload) is not used here: its grouped fit differs in the last digits (and by
    # grams on some 6-pose random designs), and it costs ~15x more per draw over hundreds of draws.
    for _ in range(repeats):
        readings = clean + sigma * rng.standard_normal(clean.shape)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", IllPosedFitWarning)
            fit = identify_from_statistics({"all": payload_statistics(readings, kinematics)}, cross_validate=False)
        errors["mass"].append(fit.mass - truth["mass"])
        errors["com"].append(float(np.linalg.norm(fit.com - truth["com"])))
        errors["force_bias"].append(float(np.linalg.norm(fit.force_bias - truth["force_bias"])))
        errors["torque_bias"].append(float(np.linalg.norm(fit.torque_bias - truth["torque_bias"])))


def run_plan_demo(config: PlanDemoConfig = PlanDemoConfig()) -> dict:
    """Run the scenario; returns the summary written to ``summary.json``."""
    started = time.perf_counter()
    out = Path(config.out_dir)
    urdf = out / "arm.urdf"
    write_text_atomic(urdf, ARM_URDF)
    robot = RobotModel(ARM_URDF, str(urdf))
    sensor = StrainGaugeSensor.create(config.sensor, seed=config.seed)
    rng = np.random.default_rng([config.seed, 1])

    options = dict(urdf=urdf, sensor=SENSOR, degree=2, min_height=config.min_height,
                   candidates=config.n_candidates, seed=config.seed)
    planned_calibration = plan_experiment(config.n_poses, load=CALIBRATION_LOADS, **options)
    plan = planned_calibration.plan
    write_table(planned_calibration.table, out / "plan.csv")
    held_out = candidate_poses(robot, SENSOR, plan.space, _loads(CALIBRATION_LOADS), config.n_validation, rng,
                               min_height=config.min_height)
    validation = held_out.wrench.reshape(-1, 6)
    wrench = plan.candidates.wrench
    planned, planned_out = calibration_errors(sensor, wrench[plan.configuration, plan.load], validation,
                                 config.samples_per_pose, rng)
    # Random designs vary a lot from draw to draw: the planner's own baseline and more drawn like it.
    random_runs = [calibration_errors(sensor, wrench[plan.random_configuration, plan.random_load], validation,
                                      config.samples_per_pose, rng)]
    n_configurations, n_loads = wrench.shape[:2]
    for _ in range(config.random_designs - 1):
        pick = random_design(n_configurations * n_loads, config.n_poses, rng)
        random_runs.append(calibration_errors(sensor, wrench[pick // n_loads, pick % n_loads], validation,
                                              config.samples_per_pose, rng))
    random = np.median([errors for errors, _ in random_runs], axis=0)
    random_out = int(np.median([out for _, out in random_runs]))

    tool = parse_payload_spec(PAYLOAD_LOAD)
    mass = HAND_MASS + tool.mass
    com = (HAND_MASS * np.array(HAND_COM) + tool.mass * (np.array(TOOL_OFFSET) + tool.com)) / mass
    truth = {"mass": mass, "com": com, "force_bias": np.array(FORCE_BIAS), "torque_bias": np.array(TORQUE_BIAS)}
    payload_plan = plan_experiment(config.payload_poses, load=[PAYLOAD_LOAD], objective="payload",
                                   noise=config.payload_noise, **options).plan
    gravity = payload_plan.candidates.gravity
    random_picks = [payload_plan.random_configuration] + [
        random_design(gravity.shape[0], config.payload_poses, rng) for _ in range(config.random_designs - 1)]
    payload = {"planned": payload_errors([gravity[payload_plan.configuration]], truth, config.payload_noise,
                                         config.payload_repeats, rng),
               "random": payload_errors([gravity[pick] for pick in random_picks], truth, config.payload_noise,
                                        max(1, config.payload_repeats // config.random_designs), rng)}
    summary = {
        "scenario": "plan", "seed": config.seed, "n_poses": config.n_poses, "loads": list(CALIBRATION_LOADS),
        "n_candidates": config.n_candidates, "n_validation": int(validation.shape[0]),
        "samples_per_pose": config.samples_per_pose, "random_designs": config.random_designs,
        "calibration_rms": {"planned": planned.tolist(), "random": random.tolist()},
        "calibration_ratio": (planned / random).tolist(),
        "calibration_ratio_mean": float(np.mean(planned / random)),
        "validation_outside_training_range": {"planned": planned_out, "random": random_out},
        "payload_poses": config.payload_poses, "payload_load": PAYLOAD_LOAD, "payload_repeats": config.payload_repeats,
        "payload_rms": payload,
        "payload_ratio": {k: payload["planned"][k] / payload["random"][k] for k in payload["planned"]},
        "log_det": {"planned": plan.planned.log_det, "random": plan.random.log_det},
        "files": [str(urdf), str(out / "plan.csv"), str(out / "summary.json")],
        "elapsed_s": time.perf_counter() - started,
    }
    write_text_atomic(out / "summary.json", json.dumps(summary, indent=2) + "\n")
    return summary


def format_plan_tables(summary: dict) -> str:
    """The printout of :func:`run_plan_demo`."""
    lines = [f"degree-2 calibration from {summary['n_poses']} poses ({len(summary['loads'])} loads), validated on "
             f"{summary['n_validation']} held-out random poses: RMS error (N, N m)",
             "                " + "".join(f"{a:>9}" for a in AXES)]
    for name in ("planned", "random"):
        lines.append(f"{name:<16}" + "".join(f"{v:9.4f}" for v in summary["calibration_rms"][name]))
    lines[-1] += f"   (median of {summary['random_designs']} random designs)"
    lines.append(f"{'planned/random':<16}" + "".join(f"{v:9.2f}" for v in summary["calibration_ratio"])
                 + f"   (mean {summary['calibration_ratio_mean']:.2f})")
    lines.append("")
    lines.append(f"payload identification ({summary['payload_load']} on the hand) from {summary['payload_poses']} "
                 f"poses: RMS error over {summary['payload_repeats']} noise draws ({summary['random_designs']} "
                 f"random designs)")
    units = {"mass": ("mass [g]", 1e3), "com": ("COM [mm]", 1e3), "force_bias": ("force bias [N]", 1.0),
             "torque_bias": ("torque bias [mN m]", 1e3)}
    lines.append("                " + "".join(f"{label:>20}" for label, _ in units.values()))
    for name in ("planned", "random"):
        lines.append(f"{name:<16}" + "".join(f"{summary['payload_rms'][name][k] * f:20.3f}"
                                             for k, (_, f) in units.items()))
    lines.append(f"{'planned/random':<16}" + "".join(f"{summary['payload_ratio'][k]:20.2f}" for k in units))
    return "\n".join(lines)
