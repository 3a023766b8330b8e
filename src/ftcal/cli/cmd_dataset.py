"""``ftcal dataset``: robot logs or ROS bags to a fit-ready dataset for one F/T sensor."""

from __future__ import annotations

import argparse

from ._common import add_scheduler_option, finite_float, positive_float, require_suffix, single_line
from ._examples import epilog
from .cmd_sensors import add_cache_arguments, add_robot_arguments, load_robot


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "dataset", **epilog("dataset"), help="robot logs (.mat/.csv/.parquet) or ROS bags to a fit-ready dataset",
        description="Read robot recordings, put each on the F/T sensor's clock, smooth the raw channels, "
                    "compute the expected wrench with each recording's load case attached, and write a "
                    "dataset with columns u1..u6, T, Fx..Tz, time, the logged joint positions (named as the "
                    "joints), static (1 still, 0 moving, from the joints over the log's time stamps) and hold "
                    "(the still pose's number over all recordings, -1 moving), segment (one per recording) and "
                    "group (load case or recording), ready for 'ftcal fit DATA --segment-by segment "
                    "--group-by group' ('--group-by hold': one cross-validation group per pose). ROS bags (.bag, ROS 2 bag folders, .db3, .mcap; see 'ftcal topics') "
                    "take --wrench-topic and optional --joints-topic, --temperature-topic, --imu-topic, "
                    "--tf BASE[:SENSOR_FRAME]; they need no URDF: the table then holds the measured wrench "
                    "u1..u6, time, and the orientation qx,qy,qz,qw (sensor to a gravity-aligned BASE, "
                    "gravity -z), IMU columns wx..wz, ax..az and the joint positions (named as the joints) when "
                    "asked for, and static (1 still, 0 moving) and hold (the still pose's number, -1 moving; "
                    "'--group-by hold' gives one cross-validation group per pose), ready for 'ftcal payload' "
                    "(--orientation, or --urdf with the joint columns); with --urdf/--model, --sensor and "
                    "--joints-topic it adds the expected wrench Fx..Tz.")
    parser.add_argument("logs", metavar="LOG", nargs="+",
                        help="recordings: .mat (v5/v7.3), .csv, .parquet, or ROS bags")
    add_robot_arguments(parser, required=False)
    parser.add_argument("--sensor", metavar="NAME", help="F/T sensor (sensor or joint name); required with a URDF")
    bags = parser.add_argument_group("ROS bags")
    bags.add_argument("--wrench-topic", metavar="TOPIC",
                      help="geometry_msgs/WrenchStamped or Wrench topic of the F/T sensor (its clock is the table's)")
    bags.add_argument("--joints-topic", metavar="TOPIC",
                      help="sensor_msgs/JointState topic (joints by name, rad) -> one column per joint, for "
                           "'ftcal payload --urdf' (and the expected wrench with --urdf/--model)")
    bags.add_argument("--temperature-topic", metavar="TOPIC",
                      help="sensor_msgs/Temperature or std_msgs/Float64 topic (degC) -> column T")
    bags.add_argument("--imu-topic", metavar="TOPIC",
                      help="sensor_msgs/Imu topic on the sensor -> wx,wy,wz (rad/s), ax,ay,az (m/s^2) and, "
                           "without --tf, qx,qy,qz,qw")
    bags.add_argument("--receive-time", action="store_true",
                      help="time every message by the bag's receive time, not its header stamp (default: header "
                           "stamps where messages have them, e.g. when a driver's stamps repeat or jump)")
    bags.add_argument("--tf", metavar="BASE[:SENSOR_FRAME]", type=_frame_pair,
                      help="sensor orientation from /tf and /tf_static: the chain BASE -> ... -> SENSOR_FRAME, "
                           "BASE gravity-aligned with z up -> qx,qy,qz,qw (SENSOR_FRAME defaults to the wrench "
                           "messages' header.frame_id)")
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
    parser.add_argument("--estimate-payload", metavar="LINK",
                        help="also write the regressor columns Y_<LINK>_<axis>_<parameter> of an unknown payload "
                             "on LINK, for 'ftcal fit --estimate-payload LINK'")
    parser.add_argument("--workers", type=int, default=2, help="worker processes (default 2)")
    add_scheduler_option(parser)
    add_cache_arguments(parser)
    parser.add_argument("-o", "--output", metavar="DATASET", required=True, help="output .parquet or .csv")
    parser.set_defaults(func=run)


def _frame_pair(text: str) -> tuple[str, str | None]:
    base, sep, frame = text.partition(":")
    if not base.strip() or (sep and not frame.strip()):
        raise argparse.ArgumentTypeError(f"expected BASE or BASE:SENSOR_FRAME, got {text!r}")
    return base.strip(), frame.strip() or None


BAG_OPTIONS = ("wrench_topic", "joints_topic", "temperature_topic", "imu_topic", "tf", "receive_time")


def run(args: argparse.Namespace) -> int:
    from pathlib import Path

    from ..data.logs import READERS, log_format
    from ..insitu.recordings import InsituOptions, build_log_table, write_dataset
    from ..robot import load_case_config, parse_payload_spec
    from ..runtime.errors import FtcalError

    require_suffix(args.output, (".csv", ".parquet", ".pq"), "-o")
    out = Path(args.output)
    is_bag = [READERS.get(log_format(Path(p)), "").startswith("ftcal.data.bags:") for p in args.logs]
    if any(is_bag) and not all(is_bag):
        raise FtcalError(f"LOG {args.logs[is_bag.index(False)]}: mix of ROS bags and other logs; "
                         "build one dataset per kind.")
    if not any(is_bag):
        given = [f"--{o.replace('_', '-')}" for o in BAG_OPTIONS if getattr(args, o) not in (None, False)]
        if given:
            raise FtcalError(f"{given[0]} applies to ROS bags only; {args.logs[0]} is not a bag.")
        if args.urdf is None and args.model is None:
            raise FtcalError("--urdf or --model is required for .mat/.csv/.parquet logs.")
        if args.sensor is None:
            raise FtcalError("--sensor is required for .mat/.csv/.parquet logs.")
    if any(is_bag) and args.estimate_payload:
        raise FtcalError("--estimate-payload applies to .mat/.csv/.parquet logs; for a bag, identify "
                         "the tool with `ftcal payload` on the bag's dataset.")
    robot = load_robot(args, payloads=False) if args.urdf or args.model else None
    payloads = [parse_payload_spec(spec) for spec in args.payload]
    config = load_case_config(args.payload_file) if args.payload_file else None
    options = InsituOptions(
        base=args.base, gravity=tuple(args.gravity),
        savgol_frame=None if args.no_filter else args.savgol_frame, savgol_order=args.savgol_order,
        rate=args.rate, temperature=not args.no_temperature, derivatives=args.dynamic,
        imu=args.imu, imu_frame=args.imu_frame, align_first_sample=args.align_first_sample,
        joint_units="deg" if args.degrees else "rad",
        adc_limits=tuple(args.adc_limits) if args.adc_limits else None,
        cache=not args.no_cache, cache_dir=args.cache_dir, workers=args.workers,
        payload_link=args.estimate_payload)
    from ..runtime.executors import open_executor

    with open_executor(args.scheduler) as executor:
        executor = executor if args.scheduler else None  # without --scheduler: here, sharing one robot model
        if all(is_bag):
            return _run_bags(args, out, robot, payloads, config, options, executor)
        table = build_log_table(args.logs, robot, args.sensor, payloads=payloads, load_cases=config,
                                options=options, executor=executor)
    write_dataset(table, out)
    for line in table.notes:
        print(single_line(line))
    dataset = table.dataset
    groups = sorted(set(map(str, dataset.groups)))
    n_holds = int(table.columns["hold"].max()) + 1 if dataset.n_samples else 0
    print(f"wrote {dataset.n_samples} samples from {len(args.logs)} recording(s), "
          f"group(s) {', '.join(groups)}, {n_holds} static hold(s), to {out}")
    return 0


def _run_bags(args, out, robot, payloads, config, options, executor) -> int:
    from ..data.bags import BagTopics
    from ..insitu.bags import build_bag_table, write_bag_table
    from ..runtime.errors import FtcalError

    if args.wrench_topic is None:
        raise FtcalError(f"Bag {args.logs[0]}: --wrench-topic is required (list the topics with "
                         f"'ftcal topics {args.logs[0]}').")
    topics = BagTopics(args.wrench_topic, args.joints_topic, args.temperature_topic, args.imu_topic, args.tf,
                       receive_time=args.receive_time)
    table = build_bag_table(args.logs, topics, robot=robot, sensor=args.sensor, payloads=payloads,
                            load_cases=config, options=options, executor=executor)
    write_bag_table(table, out)
    for line in table.notes:
        print(single_line(line))
    print(f"wrote {table.n_samples} samples from {len(args.logs)} bag(s), columns "
          f"{single_line(','.join(table.columns))}, to {out}")
    return 0
