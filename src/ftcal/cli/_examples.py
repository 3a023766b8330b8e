"""The "examples:" section of every command's ``--help``.

Every example runs as written from a folder where ``ftcal demo --out ftcal-demo`` ran
(``make demo`` in the repository): the demo writes each input they name.
tests/e2e/test_help_examples.py runs them all, command by command in this order.
Lines starting with ``ftcal`` are commands (``\\`` continues one); ``#`` lines explain the next.
"""

from __future__ import annotations

import argparse
import textwrap

# The ftcal-demo/ files the examples read, for the line under every examples section.
DEMO_NOTE = ("The files come from `ftcal demo --out ftcal-demo` (paper scenario: robot logs, train/validation "
             "tables, models/; arm scenario: the ROS 2 bag ftcal-demo/arm).")

EXAMPLES = {
    "plan": """\
  # 30 poses of an iCub's torso and right arm, with and without a 2 kg plate on the forearm
  ftcal plan --model iCubGenova11 --sensor r_arm_ft --load none --load r_forearm:2.0@-0.09,0,0.03 \\
      --poses 30 --candidates 2000 -o ftcal-demo/icub-plan.csv
  # 10 more for the plate's mass and centre of mass, on top of that plan, within narrower limits
  ftcal plan --model iCubGenova11 --sensor r_arm_ft --load none --load r_forearm:2.0@-0.09,0,0.03 \\
      --poses 10 --objective payload --joint-range torso_pitch:0:0.5 --fixed torso_yaw=0 --min-height 0.1 \\
      --from ftcal-demo/icub-plan.csv --candidates 2000 -o ftcal-demo/icub-more.csv --html ftcal-demo/icub-more.html""",
    "simulate": """\
  # a dry run: 6 planned poses of an iCub arm, with and without a 2 kg plate, as ROS 2 bags + truth.json
  ftcal plan --model iCubGenova11 --sensor r_arm_ft --load none --load r_forearm:2.0@-0.09,0,0.03 \\
      --poses 6 --candidates 500 -o ftcal-demo/sim-plan.csv
  ftcal simulate ftcal-demo/sim-plan.csv --model iCubGenova11 --sensor r_arm_ft --load none \\
      --load r_forearm:2.0@-0.09,0,0.03 --hold 1 -o ftcal-demo/sim
  # robot-log tables of a sensor mounted a quarter turn off (`ftcal check` on them reports the rotation)
  ftcal simulate ftcal-demo/sim-plan.csv --model iCubGenova11 --sensor r_arm_ft --load none \\
      --load r_forearm:2.0@-0.09,0,0.03 --hold 1 --format table --mistake rotate-z:90 -o ftcal-demo/sim-turned""",
    "check": """\
  # sign, axes, frame, zeroing and torque reference of the arm bag's table (made by `dataset` above)
  ftcal check ftcal-demo/arm.parquet --orientation qx,qy,qz,qw
  # acceptance of a calibration on held-out poses, kept in the sensor's history
  ftcal check --accept ftcal-demo/models/np4-lasso50.json ftcal-demo/validation.parquet --group-by load \\
      --max-error-percent 2 --serial SN001 --history-dir ftcal-demo/history
  ftcal check --history SN001 --history-dir ftcal-demo/history""",
    "demo": """\
  # the paper's experiment, simulated: logs, tables, models, Tables II/III, report.html,
  # plus the arm scenario's ROS 2 bag in ftcal-demo/arm (about a minute; --quick: less data)
  ftcal demo --out ftcal-demo
  # a wrist sensor with an unknown gripper, from a ROS 2 bag (writes ftcal-arm-demo/)
  ftcal demo --scenario arm
  # the calibrated sensor in a MuJoCo force-control loop (writes ftcal-closed-loop-demo/)
  ftcal demo --scenario closed-loop""",
    "sensors": """\
  # F/T sensors, joints, and the mass beyond each sensor of a shipped robot model
  ftcal sensors --model iCubGenova11
  # the same with a 2 kg plate on the right forearm (LINK:KG@X,Y,Z, COM in the link frame, m)
  ftcal sensors --model iCubGenova11 --payload r_forearm:2.0@-0.09,0,0.03""",
    "expected": """\
  # the wrench r_arm_ft should read for each row of a joint table (one column per joint, rad);
  # the demo's table has the arm joints only: the torso is said to be at 0 rad
  ftcal expected --model iCubGenova11 --joints ftcal-demo/joints.csv --sensor r_arm_ft \\
      --missing-joints zero --payload r_forearm:2.0@-0.09,0,0.03 -o ftcal-demo/expected.parquet""",
    "topics": """\
  # which topics a bag holds (type, count, rate), to pick --wrench-topic etc. for `ftcal dataset`
  ftcal topics ftcal-demo/arm""",
    "dataset": """\
  # robot logs + URDF: one segment per recording, load = load case (folders l<x>kg-r<y>kg,
  # plates placed by payloads.toml), static holds from the logged joints (columns static, hold);
  # ready for `ftcal fit --segment-by segment --group-by load` (or --group-by hold: one group per pose)
  ftcal dataset ftcal-demo/logs/validation/l0kg-r*/*.mat --model iCubGenova11 --sensor r_arm_ft \\
      --payload-file ftcal-demo/payloads.toml -o ftcal-demo/validation-from-logs.parquet
  # a ROS 2 bag, no URDF: wrench, orientation from tf, IMU and temperature (for `ftcal payload`)
  ftcal dataset ftcal-demo/arm --wrench-topic /ft_sensor/wrench --tf base_link --imu-topic /imu \\
      --temperature-topic /ft_sensor/temperature --no-filter -o ftcal-demo/arm.parquet""",
    "fit": """\
  # affine model u1..u6,T -> Fx..Tz (the default columns)
  ftcal fit ftcal-demo/train.parquet -o ftcal-demo/affine.json
  # LASSO: the paper's problem and lambda scale
  ftcal fit ftcal-demo/train.parquet --degree 4 --lasso 50 -o ftcal-demo/np4-lasso50.json
  # grouped cross-validation chooses the degree and penalty (here among ridge lambdas 1 and 100)
  ftcal fit ftcal-demo/train.parquet --degree auto --group-by load --penalties ridge --lambdas 1,100 \\
      -o ftcal-demo/best.json
  # shrink toward an earlier calibration
  ftcal fit ftcal-demo/train.parquet --degree 2 --ridge 10 --prior ftcal-demo/models/np2.json \\
      -o ftcal-demo/np2-prior.json
  # ARX: one past output and one input lag, lags never crossing a recording
  ftcal fit ftcal-demo/train.parquet --na 1 --nb 1 --segment-by segment -o ftcal-demo/arx.json
  # per-file tasks on Dask (local:N worker processes, or tcp://host:8786)
  ftcal fit ftcal-demo/train.parquet --degree 2 --scheduler local:2 -o ftcal-demo/np2-dask.json
  # neural baseline: a 16-unit MLP early-stopped on the grouped folds, scored beside the affine model
  ftcal fit ftcal-demo/train.parquet --family mlp --hidden 16 --group-by load -o ftcal-demo/mlp16.json""",
    "evaluate": """\
  # per-axis RMSE (N, N·m), BestFit (%), max |error|, force/torque-norm RMSE on held-out data
  ftcal evaluate ftcal-demo/models/np4-lasso50.json ftcal-demo/validation.parquet
  # the same as one JSON object (keys: docs/metrics.md)
  ftcal evaluate ftcal-demo/models/np4-lasso50.json ftcal-demo/validation.parquet --json
  # against the vendor's matrix (the inputs already are a wrench), both re-tared at each recording's first hold
  ftcal evaluate ftcal-demo/models/np4-lasso50.json ftcal-demo/validation.parquet --baseline identity --tare first-hold
  # an ARX model: one-step by default (the paper's evaluation), or free-run as on the robot
  ftcal fit ftcal-demo/train.parquet --na 1 --nb 1 --segment-by segment -o ftcal-demo/arx.json
  ftcal evaluate ftcal-demo/arx.json ftcal-demo/validation.parquet --segment-by segment --mode free-run""",
    "report": """\
  # compare models on the validation set, per recording (segment) and load case (load)
  ftcal report ftcal-demo/models/np1.json ftcal-demo/models/np4-lasso50.json ftcal-demo/validation.parquet \\
      --train ftcal-demo/train.parquet --segment-by segment --group-by load -o ftcal-demo/my-report.html""",
    "predict": """\
  # the wrench from raw channels (no reference needed)
  ftcal predict ftcal-demo/models/np4-lasso50.json ftcal-demo/new_data.csv -o ftcal-demo/wrench.csv
  # Parquet out; several input files are joined in order
  ftcal predict ftcal-demo/models/np4-lasso50.json ftcal-demo/new_data.csv ftcal-demo/validation.parquet \\
      -o ftcal-demo/wrench.parquet""",
    "convert": """\
  # C99 for a controller (ftcal-demo/c/r_arm_ft.h and .c) and ONNX for onnxruntime
  ftcal convert ftcal-demo/models/np4-lasso50.json --to c --name r_arm_ft -o ftcal-demo/c
  ftcal convert ftcal-demo/models/np4.json --to onnx -o ftcal-demo/np4.onnx
  # the live step in C (calibration, tool, bias filter, health); tools: --payload-file NAME=PAYLOAD.json
  ftcal convert ftcal-demo/models/np4.json --to c-runtime -o ftcal-demo/ft_runtime.h
  # the paper's XML (raw-input monomials; reports the digits the conversion loses)
  ftcal convert ftcal-demo/models/np2.json --to paper-xml -o ftcal-demo/np2.xml
  # iCub strain-board matrix: an affine model of the six ADC channels, no temperature
  ftcal fit ftcal-demo/train-adc.parquet --inputs u1,u2,u3,u4,u5,u6 -o ftcal-demo/affine-adc.json
  ftcal convert ftcal-demo/affine-adc.json --to icub-firmware -o ftcal-demo/matrix_SN001.txt
  # wholeBodyDynamics: an affine model with temperature
  ftcal convert ftcal-demo/models/np1.json --to wbd --sensor r_arm_ft_sensor -o ftcal-demo/wbd.ini
  # payload files: see `ftcal payload --help` (ros-yaml, ft-tools-ros2)""",
    "info": """\
  # class, counts, training ranges, training metrics and the 5 largest terms
  ftcal info ftcal-demo/models/np4-lasso50.json --terms 5""",
    "payload": """\
  # the arm bag as a table, then bias, mass and COM (static) or also inertia (--dynamic)
  ftcal dataset ftcal-demo/arm --wrench-topic /ft_sensor/wrench --tf base_link --imu-topic /imu \\
      --temperature-topic /ft_sensor/temperature --no-filter -o ftcal-demo/arm.parquet
  ftcal payload ftcal-demo/arm.parquet --orientation qx,qy,qz,qw --dynamic --frame ft_sensor \\
      -o ftcal-demo/payload.json
  # for ROS: force_torque_tools (ros-yaml) or ft_tools_ros2 (ft-tools-ros2)
  ftcal convert ftcal-demo/payload.json --to ros-yaml -o ftcal-demo/ft_calib.yaml
  ftcal convert ftcal-demo/payload.json --to ft-tools-ros2 -o ftcal-demo/ft_tools_ros2.yaml""",
    "compensate": """\
  # the contact wrench: readings minus bias minus the tool's gravity and inertial wrench
  ftcal dataset ftcal-demo/arm --wrench-topic /ft_sensor/wrench --tf base_link --imu-topic /imu \\
      --temperature-topic /ft_sensor/temperature --no-filter -o ftcal-demo/arm.parquet
  ftcal payload ftcal-demo/arm.parquet --orientation qx,qy,qz,qw --dynamic -o ftcal-demo/payload.json
  ftcal compensate ftcal-demo/payload.json ftcal-demo/arm.parquet --orientation qx,qy,qz,qw --dynamic \\
      -o ftcal-demo/contact.parquet""",
    "live": """\
  # a drifting wrist sensor in operation, its two tools identified offline (writes ftcal-demo/live/)
  ftcal demo --scenario live --out ftcal-demo/live
  # replay it: the gripper is swapped for the drill at 61 s, a re-tare (tool kept) at 100 s
  ftcal live --replay ftcal-demo/live/live.parquet --orientation qx,qy,qz,qw --inputs Fx,Fy,Fz,Tx,Ty,Tz \\
      --tool gripper=ftcal-demo/live/gripper.json --tool drill=ftcal-demo/live/drill.json \\
      --switch-tool 61:drill --retare-at 100 --state ftcal-demo/live/state.json -o ftcal-demo/live/replayed.parquet""",
}


class ExamplesFormatter(argparse.HelpFormatter):
    """Wraps the description as usual but prints the examples section as written."""

    def _fill_text(self, text: str, width: int, indent: str) -> str:
        if text.startswith("examples:\n"):
            return "".join(indent + line for line in text.splitlines(keepends=True))
        return super()._fill_text(text, width, indent)


def epilog(command: str, extra: str = "") -> dict:
    """Keyword arguments for ``add_parser``: the command's examples (and pre-wrapped ``extra`` text after them)."""
    note = "\n".join(textwrap.wrap(DEMO_NOTE, 96))
    text = f"examples:\n{EXAMPLES[command]}\n\n{note}" + (f"\n\n{extra}" if extra else "")
    return {"epilog": text, "formatter_class": ExamplesFormatter}
