"""``ftcal expected``: expected F/T wrenches for a table of joint positions."""

from __future__ import annotations

import argparse

from ._common import finite_float, require_suffix
from .cmd_sensors import add_cache_arguments, add_robot_arguments, load_robot

WRENCH = ("Fx", "Fy", "Fz", "Tx", "Ty", "Tz")


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "expected", help="expected F/T wrenches for joint positions (iDynTree)",
        description="Compute the wrench each F/T sensor should measure for every row of a joint table "
                    "(static, fixed base). Output: the wrench the sensor's child link applies on its "
                    "parent link, in the sensor frame, torque about the sensor origin (N, N m).")
    add_robot_arguments(parser)
    parser.add_argument("--joints", metavar="FILE", required=True,
                        help="CSV/Parquet, one column per joint named as in the URDF (radians); joints "
                             "not given are 0; an optional 'time' column is copied to the output")
    parser.add_argument("--sensor", metavar="NAME", action="append", default=[],
                        help="F/T sensor (sensor or joint name); repeatable; default all")
    parser.add_argument("--gravity", metavar=("X", "Y", "Z"), nargs=3, type=finite_float,
                        default=(0.0, 0.0, -9.81), help="gravity in base-frame axes, m/s² (default 0 0 -9.81)")
    parser.add_argument("--degrees", action="store_true", help="joint positions are in degrees")
    parser.add_argument("--workers", type=int, default=2, help="worker processes (default 2)")
    add_cache_arguments(parser)
    parser.add_argument("-o", "--output", metavar="OUT", required=True, help="output .csv or .parquet")
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from pathlib import Path

    import numpy as np
    import pandas as pd

    from ..io.tables import numeric_columns, read_table, write_table
    from ..robot.cache import cache_key, cached
    from ..robot.expected import expected_wrenches

    require_suffix(args.output, (".csv", ".parquet", ".pq"), "-o")
    out = Path(args.output)
    robot = load_robot(args)
    sensors = [robot.sensor(name) for name in args.sensor] or list(robot.ft_sensors)
    labels = args.sensor or [s.name for s in sensors]
    _, base = robot.base_frame(args.base)
    table = read_table(Path(args.joints))
    joint_cols = [c for c in table.columns if c != "time"]
    values = numeric_columns(table, joint_cols, Path(args.joints), "joint")
    if args.degrees:
        values = np.deg2rad(values)
    q = robot.joint_matrix(joint_cols, values, str(args.joints))

    def compute() -> np.ndarray:
        return expected_wrenches(robot, q, base=base, gravity=args.gravity, workers=args.workers)

    if args.no_cache:
        wrenches = compute()
    else:
        key = cache_key(robot, [q], (base, tuple(args.gravity), None))
        wrenches = cached(key, [s.name for s in robot.ft_sensors], q.shape[0], compute, args.cache_dir)
    columns = {"time": table["time"].to_numpy()} if "time" in table.columns else {}
    for label, sensor in zip(labels, sensors):
        for axis, name in enumerate(WRENCH):
            columns[f"{label}_{name}"] = wrenches[:, sensor.index, axis]
    frame = pd.DataFrame(columns)
    write_table(frame, out)
    print(f"wrote {len(frame)} samples x {len(sensors)} sensor(s) to {out}")
    return 0
