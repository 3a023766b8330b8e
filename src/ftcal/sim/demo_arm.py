"""The arm scenario of ``ftcal demo --scenario arm``: wrist sensor, unknown gripper, ROS 2 bag.

simulate the arm (:mod:`ftcal.sim.arm_bag`) into a ROS 2 bag
→ the bag's dataset (tf orientation, IMU, temperature on the F/T clock, as ``ftcal dataset``)
→ bias + payload identification, dynamic model from the IMU (as ``ftcal payload --dynamic``)
→ compensation (as ``ftcal compensate --dynamic``)
→ identified vs true parameters, residual RMS before/after, ``summary.json``, ``report.html``,
``payload.json`` and the ROS YAML files (``ft_calib.yaml``, ``calibration.yaml``).

The wrist moves between its still poses, so the fit uses the dynamic model
(angular velocity from the IMU, its derivative, the accelerometer): a static
fit would read the gripper's inertial wrench during the moves as error.
Nothing touches the gripper, so the true contact wrench is zero: the residual
RMS before compensation is the RMS of the readings, after it the RMS of the
contact wrench, which should be the sensor noise.
"""

from __future__ import annotations

import json
import shutil
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..payload.identify import AXES
from ..runtime.atomic import write_text_atomic
from .arm_bag import (
    BASE_FRAME,
    IMU_TOPIC,
    SENSOR_FRAME,
    TEMPERATURE_TOPIC,
    WRENCH_TOPIC,
    ArmScenario,
    ArmTruth,
    write_arm_bag,
)

# A temperature-stable sensor: the 10 + 6 parameter model has a constant bias (temperature drift is what
# `ftcal fit` with T models), so the identified bias is directly comparable with the simulator's.
ARM_DEMO_SCENARIO = ArmScenario(force_bias_tc=(0.0, 0.0, 0.0))
# `ftcal demo --scenario arm --quick`: fewer poses, lower rates
ARM_QUICK = {"n_poses": 8, "rate": 200.0, "tf_rate": 50.0, "imu_rate": 100.0}
BAG_NAME = "arm"  # the bag folder inside the output folder
DATASET_NAME, CONTACT_NAME, PAYLOAD_NAME = "arm.parquet", "contact.parquet", "payload.json"
ROS_YAML_FILES = {"ros-yaml": "ft_calib.yaml", "ft-tools-ros2": "calibration.yaml"}


@dataclass(frozen=True)
class ArmDemoConfig:
    """Where to write, what to simulate, and the dataset's Savitzky–Golay frame (None: raw samples).

    Raw samples by default: the standard errors assume independent residuals,
    which smoothing makes correlated over a frame (they would come out too small).
    """

    out_dir: Path = Path("ftcal-arm-demo")
    scenario: ArmScenario = ARM_DEMO_SCENARIO
    savgol_frame: int | None = None


def write_demo_bag(path: str | Path, scenario: ArmScenario = ARM_DEMO_SCENARIO) -> ArmTruth:
    """Record ``scenario`` into the ROS 2 bag folder ``path``, replacing a bag an earlier demo wrote there.

    The bag is written into a temporary folder beside ``path`` and moved into place,
    so an interrupted run leaves the previous bag intact.

    Parameters
    ----------
    path : str or Path
        Bag folder to (re)create.
    scenario : ArmScenario

    Returns
    -------
    ArmTruth
        The simulator's true values, with ``path`` as the bag's path.

    Raises
    ------
    FtcalError
        If ``path`` exists and is not a ROS 2 bag folder (it is left alone).
    """
    import dataclasses

    from ..runtime.errors import FtcalError

    path = Path(path)
    if path.exists() and not (path / "metadata.yaml").is_file():
        raise FtcalError(f"{path}: exists and is not a ROS 2 bag folder; the demo writes its arm bag there.")
    path.parent.mkdir(parents=True, exist_ok=True)
    scratch = Path(tempfile.mkdtemp(prefix=f".{path.name}.", dir=path.parent))
    try:
        truth = write_arm_bag(scratch / path.name, scenario)
        if path.exists():
            shutil.rmtree(path)
        (scratch / path.name).rename(path)
    finally:
        shutil.rmtree(scratch, ignore_errors=True)
    return dataclasses.replace(truth, path=path)


def true_parameters(truth: ArmTruth, scenario: ArmScenario) -> dict[str, np.ndarray]:
    """What the identification should find: the simulator's gripper and bias, sensor frame.

    The force bias is the one at the recording's mean temperature (the ramp's
    midpoint), the constant a temperature-free model sees.
    """
    mean_temperature = 0.5 * (scenario.temperature_start + scenario.temperature_end)
    return {"mass": np.array([truth.mass]), "com": truth.com,
            "force_bias": truth.force_bias + truth.force_bias_tc * (mean_temperature - truth.temperature_reference),
            "torque_bias": truth.torque_bias, "inertia": np.asarray(scenario.gripper_inertia, dtype=float)}


def run_arm_demo(config: ArmDemoConfig = ArmDemoConfig()) -> dict:
    """Run the arm scenario; returns the summary written to ``summary.json``.

    Parameters
    ----------
    config : ArmDemoConfig

    Returns
    -------
    dict
        ``parameters`` (name, unit, true, identified, stderr per scalar), ``residual_rms_before`` /
        ``residual_rms_after`` (N, N·m by axis), ``noise`` (the simulator's force and torque noise),
        ``n_samples``, ``files`` and ``elapsed_s``.
    """
    from ..payload.tables import WRENCH_COLUMNS
    from ..workflow.compensation import compensate
    from ..workflow.datasets import build_dataset
    from ..workflow.export import convert
    from ..workflow.payload import identify_payload

    started = time.perf_counter()
    out, scenario = Path(config.out_dir), config.scenario
    out.mkdir(parents=True, exist_ok=True)
    truth = write_demo_bag(out / BAG_NAME, scenario)
    # The steps `ftcal dataset`, `payload --dynamic`, `compensate` and `convert` run, with the same defaults.
    dataset = out / DATASET_NAME
    table = build_dataset(truth.path, wrench_topic=WRENCH_TOPIC, temperature_topic=TEMPERATURE_TOPIC,
                          imu_topic=IMU_TOPIC, tf=(BASE_FRAME, SENSOR_FRAME), savgol_frame=config.savgol_frame,
                          no_filter=config.savgol_frame is None, output=dataset).table
    motion = {"orientation": ("qx", "qy", "qz", "qw"), "g": scenario.gravity, "dynamic": True}
    # Held-out choice of weighting, grouped-jackknife standard errors.
    fit = identify_payload(dataset, bias_drift="none", frame=SENSOR_FRAME, output=out / PAYLOAD_NAME, **motion).fit
    contact = compensate(out / PAYLOAD_NAME, dataset, output=out / CONTACT_NAME, **motion).table
    for target, name in ROS_YAML_FILES.items():
        convert(out / PAYLOAD_NAME, target, out / name)

    measured = np.column_stack([table.columns[c] for c in WRENCH_COLUMNS])
    compensated = contact[list(AXES)].to_numpy()
    summary = {
        "scenario": "arm", "bag": str(truth.path), "n_samples": table.n_samples,
        "parameters": _parameter_rows(fit, true_parameters(truth, scenario)),
        "residual_rms_before": dict(zip(AXES, _rms(measured).tolist())),
        "residual_rms_after": dict(zip(AXES, _rms(compensated).tolist())),
        "noise": {"force": scenario.force_noise, "torque": scenario.torque_noise},
        "smoothing": config.savgol_frame,
        "files": [str(out / n) for n in (BAG_NAME, DATASET_NAME, PAYLOAD_NAME, CONTACT_NAME,
                                         *ROS_YAML_FILES.values(), "summary.json", "report.html")]}
    write_text_atomic(out / "summary.json", json.dumps(summary, indent=2) + "\n")
    _write_report(out / "report.html", summary, table.columns["time"], measured, compensated)
    summary["elapsed_s"] = time.perf_counter() - started
    return summary


PARAMETER_UNITS = {"mass": "kg", "com": "m", "force_bias": "N", "torque_bias": "N·m", "inertia": "kg·m²"}


def _parameter_rows(fit, true: dict[str, np.ndarray]) -> list[dict]:
    """One row per scalar: name, unit, true value, identified value, standard error."""
    rows = []
    for key, unit in PARAMETER_UNITS.items():
        if key == "inertia":  # the simulator's gripper has a diagonal inertia about its COM
            identified, stderr = np.diag(fit.inertia), np.diag(fit.stderr["inertia"])
            names = [f"inertia {a}{a}" for a in "xyz"]
        else:
            identified = np.atleast_1d(getattr(fit, key))
            stderr = np.atleast_1d(fit.stderr[key])
            names = [key] if key == "mass" else [f"{key.replace('_', ' ')} {a}" for a in "xyz"]
        for name, t, v, s in zip(names, true[key], identified, stderr):
            rows.append({"name": name, "unit": unit, "true": float(t), "identified": float(v), "stderr": float(s)})
    return rows


def _rms(wrench: np.ndarray) -> np.ndarray:
    return np.sqrt(np.mean(wrench ** 2, axis=0))


def format_arm_tables(summary: dict) -> str:
    """The parameter table (true vs identified ± stderr) and the residual RMS before/after, as text."""
    lines = ["Gripper and sensor bias: simulator's true values vs identified (sensor frame)",
             f"{'parameter':<16} {'unit':<6} {'true':>11} {'identified':>11} {'± stderr':>9} {'error/se':>9}"]
    for row in summary["parameters"]:
        z = (row["identified"] - row["true"]) / row["stderr"]
        lines.append(f"{row['name']:<16} {row['unit']:<6} {row['true']:>11.5g} {row['identified']:>11.5g} "
                     f"{row['stderr']:>9.2g} {z:>9.2f}")
    noise = summary["noise"]
    lines += ["", "Residual RMS (the gripper touches nothing: the true contact wrench is zero)",
              f"{'axis':<6} {'before':>10} {'after':>10} {'noise':>10}"]
    for axis in AXES:
        sigma = noise["force"] if axis.startswith("F") else noise["torque"]
        lines.append(f"{axis:<6} {summary['residual_rms_before'][axis]:>10.4g} "
                     f"{summary['residual_rms_after'][axis]:>10.4g} {sigma:>10.4g}")
    lines.append("(N and N·m; noise: the simulator's per-sample noise"
                 + (", before the dataset's smoothing)" if summary["smoothing"] else ")"))
    return "\n".join(lines)


def _wrench_figure(t: np.ndarray, measured: np.ndarray, compensated: np.ndarray):
    """Six panels: each axis' reading (before) and contact wrench (after) over time."""
    from ..report.figures import envelope_indices, new_figure

    fig = new_figure(11.0, 6.5)
    axes = fig.subplots(3, 2, sharex=True)
    t = t - t[0]
    for j, name in enumerate(AXES):
        ax = axes[j % 3, j // 3]
        for values, label, color in ((measured[:, j], "before (reading)", "#c44e52"),
                                     (compensated[:, j], "after (contact wrench)", "#4c72b0")):
            keep = envelope_indices(values)
            ax.plot(t[keep], values[keep], lw=0.7, color=color, label=label)
        ax.set_ylabel(f"{name} [{'N' if name.startswith('F') else 'N·m'}]")
        ax.grid(alpha=0.3)
    for ax in axes[-1]:
        ax.set_xlabel("time [s]")
    axes[0, 0].legend(loc="upper right")
    fig.suptitle("Wrench before and after bias + payload compensation")
    return fig


def _write_report(path: Path, summary: dict, t: np.ndarray, measured: np.ndarray, compensated: np.ndarray) -> None:
    import html

    from matplotlib import rc_context

    from ..report.html import CSS, STYLE, figure_html
    from ..report.tables import html_table

    parameters = html_table(
        ["parameter", "unit", "true", "identified", "± stderr", "error / stderr"],
        [[r["name"], r["unit"], f"{r['true']:.6g}", f"{r['identified']:.6g}", f"{r['stderr']:.2g}",
          f"{(r['identified'] - r['true']) / r['stderr']:.2f}"] for r in summary["parameters"]],
        caption="The simulator's gripper and sensor bias (sensor frame; inertia about the centre of mass) and "
                "what ftcal identified from the bag, with standard errors.")
    noise = summary["noise"]
    residuals = html_table(
        ["axis", "before", "after", "simulated noise"],
        [[a, f"{summary['residual_rms_before'][a]:.4g}", f"{summary['residual_rms_after'][a]:.4g}",
          f"{noise['force'] if a.startswith('F') else noise['torque']:.4g}"] for a in AXES],
        caption="Residual RMS per axis (N, N·m). Nothing touches the gripper, so the true contact wrench is zero.")
    with rc_context(STYLE):
        figure = figure_html(_wrench_figure(t, measured, compensated), "wrench",
                              "Each axis' reading and the contact wrench after compensation, over the recording.")
    files = "".join(f"<li><code>{html.escape(f)}</code></li>" for f in summary["files"])
    title = "ftcal demo: wrist sensor and unknown gripper, from a ROS 2 bag"
    page = ("<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n"
            f"<title>{html.escape(title)}</title>\n<style>{CSS}</style>\n</head>\n<body>\n"
            f"<h1>{html.escape(title)}</h1>\n"
            f"<p class=\"meta\">{summary['n_samples']} samples from {html.escape(summary['bag'])}; "
            "bias, mass, centre of mass and inertia identified by linear least squares (dynamic model).</p>\n"
            f"<section id=\"parameters\"><h2>True vs identified parameters</h2>\n{parameters}</section>\n"
            f"<section id=\"residuals\"><h2>Residuals before and after compensation</h2>\n{residuals}\n{figure}"
            f"</section>\n<section id=\"files\"><h2>Files</h2><ul class=\"notes\">{files}</ul></section>\n"
            "</body>\n</html>\n")
    write_text_atomic(path, page)
