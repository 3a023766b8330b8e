"""``ftcal dataset``: robot logs to a fit-ready dataset for one F/T sensor."""

from __future__ import annotations

import argparse

from ._common import finite_float, positive_float, require_suffix
from .cmd_sensors import add_cache_arguments, add_robot_arguments


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "dataset", help="robot logs (.mat/.csv/.parquet) to a fit-ready dataset",
        description="Read robot recordings, put each on the F/T sensor's clock, smooth the raw channels, "
                    "compute the expected wrench with each recording's load case attached, and write a "
                    "dataset with columns u1..u6, T, Fx..Tz, segment (one per recording) and group "
                    "(load case or recording), ready for 'ftcal fit DATA --segment-by segment "
                    "--group-by group'.")
    parser.add_argument("logs", metavar="LOG", nargs="+", help="recordings: .mat (v5/v7.3), .csv, .parquet")
    add_robot_arguments(parser)
    parser.add_argument("--sensor", metavar="NAME", required=True, help="F/T sensor (sensor or joint name)")
    parser.add_argument("--payload-file", metavar="TOML",
                        help="payloads and load cases per recording (incl. the l<x>kg-r<y>kg folder convention)")
    parser.add_argument("--gravity", metavar=("X", "Y", "Z"), nargs=3, type=finite_float,
                        default=(0.0, 0.0, -9.81), help="gravity in base-frame axes, m/s² (default 0 0 -9.81)")
    parser.add_argument("--savgol-frame", type=int, default=101, metavar="N",
                        help="Savitzky-Golay frame length in samples, odd (default 101)")
    parser.add_argument("--savgol-order", type=int, default=3, metavar="K", help="Savitzky-Golay order (default 3)")
    parser.add_argument("--no-filter", action="store_true", help="do not smooth the raw channels and temperature")
    parser.add_argument("--rate", type=positive_float, metavar="HZ",
                        help="resample on a uniform clock (default: the F/T timestamps)")
    parser.add_argument("--no-temperature", action="store_true", help="inputs u1..u6 only, no T")
    parser.add_argument("--degrees", action="store_true", help="joint data in the logs are in degrees")
    parser.add_argument("--dynamic", action="store_true",
                        help="use logged joint velocities and accelerations (default: static)")
    parser.add_argument("--imu", metavar="NAME", help="accelerometer/gyro stream for a floating base")
    parser.add_argument("--imu-frame", metavar="FRAME", help="URDF frame of that IMU")
    parser.add_argument("--align-first-sample", action="store_true",
                        help="the paper's dataset offset: shift each recording's raw channels so the "
                             "first sample equals the expected wrench")
    parser.add_argument("--adc-limits", nargs=2, type=finite_float, metavar=("LOW", "HIGH"),
                        help="raw values meaning the ADC saturated (reported as warnings)")
    parser.add_argument("--workers", type=int, default=2, help="worker processes (default 2)")
    add_cache_arguments(parser)
    parser.add_argument("-o", "--output", metavar="DATASET", required=True, help="output .parquet or .csv")
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from pathlib import Path

    from ..insitu import InsituOptions, build_dataset, write_dataset
    from ..robot import load_case_config, parse_payload_spec
    from ..robot.model import RobotModel

    require_suffix(args.output, (".csv", ".parquet", ".pq"), "-o")
    out = Path(args.output)
    robot = RobotModel.load(urdf=args.urdf, name=args.model)
    payloads = [parse_payload_spec(spec) for spec in args.payload]
    config = load_case_config(args.payload_file) if args.payload_file else None
    options = InsituOptions(
        base=args.base, gravity=tuple(args.gravity),
        savgol_frame=None if args.no_filter else args.savgol_frame, savgol_order=args.savgol_order,
        rate=args.rate, temperature=not args.no_temperature, derivatives=args.dynamic,
        imu=args.imu, imu_frame=args.imu_frame, align_first_sample=args.align_first_sample,
        joint_units="deg" if args.degrees else "rad",
        adc_limits=tuple(args.adc_limits) if args.adc_limits else None,
        cache=not args.no_cache, cache_dir=args.cache_dir, workers=args.workers)
    dataset = build_dataset(args.logs, robot, args.sensor, payloads=payloads, load_cases=config, options=options)
    write_dataset(dataset, out)
    groups = sorted(set(map(str, dataset.groups)))
    print(f"wrote {dataset.n_samples} samples from {len(args.logs)} recording(s), "
          f"group(s) {', '.join(groups)}, to {out}")
    return 0
