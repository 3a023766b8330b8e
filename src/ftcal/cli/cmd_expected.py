"""``ftcal expected``: expected F/T wrenches for a table of joint positions."""

from __future__ import annotations

import argparse

from ..core.limits import MISSING_JOINTS
from ._common import add_scheduler_option, finite_float, require_suffix
from ._examples import epilog
from .cmd_sensors import add_cache_arguments, add_robot_arguments, load_robot

WRENCH = ("Fx", "Fy", "Fz", "Tx", "Ty", "Tz")


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "expected", **epilog("expected"), help="expected F/T wrenches for joint positions (iDynTree)",
        description="Compute the wrench each F/T sensor should measure for every row of a joint table "
                    "(static, fixed base). Output: the wrench the sensor's child link applies on its "
                    "parent link, in the sensor frame, torque about the sensor origin (N, N m).")
    add_robot_arguments(parser)
    parser.add_argument("--joints", metavar="FILE", required=True,
                        help="CSV/Parquet, one column per joint named as in the URDF (radians); every joint the "
                             "sensors' wrench depends on (chain from the base, and beyond the sensor) must be "
                             "there unless --missing-joints zero; an optional 'time' column is copied to the output")
    parser.add_argument("--sensor", metavar="NAME", action="append", default=[],
                        help="F/T sensor (sensor or joint name); repeatable; default all")
    parser.add_argument("--gravity", metavar=("X", "Y", "Z"), nargs=3, type=finite_float,
                        default=(0.0, 0.0, -9.81), help="gravity in base-frame axes, m/s² (default 0 0 -9.81)")
    parser.add_argument("--degrees", action="store_true", help="joint positions are in degrees")
    parser.add_argument("--missing-joints", choices=MISSING_JOINTS, default="refuse",
                        help="a joint the wrench depends on that the table lacks: refuse (default), or zero "
                             "(you say it is at 0 rad)")
    parser.add_argument("--workers", type=int, default=2, help="worker processes (default 2)")
    add_scheduler_option(parser)
    add_cache_arguments(parser)
    parser.add_argument("-o", "--output", metavar="OUT", required=True, help="output .csv or .parquet")
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """With --scheduler the joints file is one task (a worker reads it and computes in one process)."""
    from pathlib import Path

    import pandas as pd

    from ..data.tables import write_table
    from ..runtime.executors import open_executor

    require_suffix(args.output, (".csv", ".parquet", ".pq"), "-o")
    out = Path(args.output)
    robot = load_robot(args)
    sensors = [robot.sensor(name) for name in args.sensor] or list(robot.ft_sensors)
    labels = args.sensor or [s.name for s in sensors]
    _, base = robot.base_frame(args.base)
    settings = (base, tuple(args.gravity), args.degrees, not args.no_cache, args.cache_dir,
                tuple(s.name for s in sensors), args.missing_joints)
    if args.scheduler:
        description = (robot.urdf_text, robot.source, robot.payloads, robot.declared)
        with open_executor(args.scheduler) as executor:
            [(time, wrenches)] = executor.map(_remote_wrenches, [(args.joints, description)], 1, *settings,
                                              description="joints files")
    else:
        time, wrenches = joints_file_wrenches(args.joints, robot, args.workers, *settings)
    columns = {"time": time} if time is not None else {}
    for label, sensor in zip(labels, sensors):
        for axis, name in enumerate(WRENCH):
            columns[f"{label}_{name}"] = wrenches[:, sensor.index, axis]
    frame = pd.DataFrame(columns)
    write_table(frame, out)
    print(f"wrote {len(frame)} samples x {len(sensors)} sensor(s) to {out}")
    return 0


def joints_file_wrenches(joints, robot, workers, base, gravity, degrees, cache, cache_dir, sensors=(),
                         missing_joints="refuse"):
    """The ``time`` column (or None) and the (n_samples, n_sensors, 6) expected wrenches of a joints file.

    A joint that the wrench of one of ``sensors`` depends on and that the file lacks is refused unless
    ``missing_joints`` is ``"zero"`` (the user says it is at 0 rad).
    """
    from pathlib import Path

    import numpy as np

    from ..data.tables import numeric_columns, read_table
    from ..robot.cache import cache_key, cached
    from ..robot.expected import expected_wrenches
    from ..robot.kinematics import require_wrench_joints

    table = read_table(Path(joints))
    joint_cols = [c for c in table.columns if c != "time"]
    if missing_joints != "zero" and set(joint_cols) <= set(robot.joint_names):  # else joint_matrix names them
        require_wrench_joints(robot, joint_cols, base, sensors, f"--joints {joints}",
                              " (give their columns, or --missing-joints zero if they are at 0 rad)")
    values = numeric_columns(table, joint_cols, Path(joints), "joint")
    if degrees:
        values = np.deg2rad(values)
    q = robot.joint_matrix(joint_cols, values, str(joints))

    def compute() -> np.ndarray:
        return expected_wrenches(robot, q, base=base, gravity=gravity, workers=workers)

    if not cache:
        wrenches = compute()
    else:
        key = cache_key(robot, [q], (base, tuple(gravity), None))
        wrenches = cached(key, [s.name for s in robot.ft_sensors], q.shape[0], compute, cache_dir)
    return (table["time"].to_numpy() if "time" in table.columns else None), wrenches


def _remote_wrenches(joints, description, workers, *settings):
    """:func:`joints_file_wrenches` on a Dask worker: the robot rebuilt from its picklable description."""
    from ..insitu.recordings import robot_from_description

    return joints_file_wrenches(joints, robot_from_description(*description), workers, *settings)
