"""``ftcal dataset``: robot logs or ROS bags to a fit-ready dataset for one F/T sensor."""

from __future__ import annotations

import argparse

from ._common import add_scheduler_option, finite_float, frame_pair, positive_float, require_suffix
from ._examples import epilog
from ._robot import add_cache_arguments, add_robot_arguments, robot_keywords


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "dataset", **epilog("dataset"), help="robot logs (.mat/.csv/.parquet) or ROS bags to a fit-ready dataset",
        description="Read robot recordings, put each on the F/T sensor's clock, smooth the raw channels, "
                    "compute the expected wrench with each recording's load case attached, and write a "
                    "dataset with columns u1..u6, T, Fx..Tz, time, the logged joint positions (named as the "
                    "joints), static (1 still, 0 moving, from the joints over the log's time stamps) and hold "
                    "(the still pose's number over all recordings, -1 moving), segment (one per recording) and "
                    "load (the load case's name, else the recording's), ready for 'ftcal fit DATA', which uses "
                    "segment and load by default ('--group-by hold': one cross-validation group per pose). ROS bags (.bag, ROS 2 bag folders, .db3, .mcap; see 'ftcal topics') "
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
    parser.add_argument("--sensor", metavar="NAME",
                        help="F/T sensor (sensor or joint name); default: the robot model's only one (e.g. the "
                             "--ft-joint sensor of a plain URDF)")
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
    bags.add_argument("--tf", metavar="BASE[:SENSOR_FRAME]", type=frame_pair,
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


def run(args: argparse.Namespace) -> int:
    from ..runtime.executors import open_executor
    from ..workflow.datasets import build_dataset

    require_suffix(args.output, (".csv", ".parquet", ".pq"), "-o")
    keywords = dict(robot_keywords(args, payloads=False), sensor=args.sensor, payload=tuple(args.payload),
                    base=args.base, wrench_topic=args.wrench_topic, joints_topic=args.joints_topic,
                    temperature_topic=args.temperature_topic, imu_topic=args.imu_topic,
                    receive_time=args.receive_time, tf=args.tf, payload_file=args.payload_file,
                    gravity=tuple(args.gravity), savgol_frame=args.savgol_frame, savgol_order=args.savgol_order,
                    no_filter=args.no_filter, rate=args.rate, no_temperature=args.no_temperature,
                    degrees=args.degrees, dynamic=args.dynamic, imu=args.imu, imu_frame=args.imu_frame,
                    align_first_sample=args.align_first_sample, adc_limits=args.adc_limits,
                    estimate_payload=args.estimate_payload, workers=args.workers, no_cache=args.no_cache,
                    cache_dir=args.cache_dir)
    with open_executor(args.scheduler) as executor:
        # without --scheduler: here, sharing one robot model
        result = build_dataset(args.logs, executor=executor if args.scheduler else None, **keywords)
        result.save(args.output)
    for line in result.notes:
        print(line)
    print(f"wrote {result.description}, to {args.output}")
    return 0
