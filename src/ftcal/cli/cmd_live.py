"""``ftcal live``: the live calibrator over a recording (--replay) or over Zenoh (--zenoh)."""

from __future__ import annotations

import argparse
import re

from ..core.limits import LIVE_KEY_CONVENTIONS
from ._common import column_list, finite_float, float_list, frame_pair, nonnegative_int, positive_float, require_suffix
from ._examples import epilog
from ._gravity import add_robot_source_options
from ._inputs import add_inputs_option, inputs_of


def tool_spec(text: str) -> tuple[str, str]:
    """``NAME=PAYLOAD.json``."""
    name, sep, path = text.partition("=")
    if not sep or not name or not path:
        raise argparse.ArgumentTypeError(f"expected NAME=PAYLOAD.json, got {text!r}")
    return name, path


def signed_list(text: str) -> tuple[float, ...]:
    """Comma-separated finite numbers of either sign (a bias)."""
    return tuple(finite_float(part) for part in text.split(","))


def switch_spec(text: str) -> tuple[float, str]:
    """``TIME:NAME``."""
    when, sep, name = text.partition(":")
    if not sep or not name:
        raise argparse.ArgumentTypeError(f"expected TIME:TOOL (e.g. 30:gripper), got {text!r}")
    return finite_float(when), name


def register(sub) -> None:
    p = sub.add_parser("live", **epilog("live"),
                       help="calibrate, remove the tool, track the drifting bias and watch the sensor while the "
                            "robot runs (replay a recording, or live over Zenoh)",
                       description="The live calibrator (docs/live.md): each sample's calibrated wrench, the "
                                   "wrench with the mounted tool's gravity and the tracked bias removed (Fx..Tz), "
                                   "the bias ± its standard deviation, and health flags. The bias is a Kalman "
                                   "filter of the random-walk model of `ftcal payload --bias-drift random-walk`; "
                                   "it updates only on static samples whose innovation passes a chi-square gate, "
                                   "so a contact is flagged and never absorbed. Tools come from payload files "
                                   "(--tool NAME=PAYLOAD.json); re-tares (bias only, tool kept) and tool switches "
                                   "can be scripted by time.")
    mode = p.add_mutually_exclusive_group(required=True)
    mode.add_argument("--replay", metavar="DATA", help="CSV or Parquet recording, or a ROS bag (.bag, .mcap, .db3, "
                                                       "ROS 2 bag folder; with --wrench-topic and --joints-topic "
                                                       "or --tf), to run through the calibrator")
    mode.add_argument("--zenoh", action="store_true", help="run live over Zenoh (see the Zenoh options)")
    mode.add_argument("--ros2", action="store_true",
                      help="run live as a ROS 2 node (rclpy: source ROS 2 first); every option is also a ROS "
                           "parameter, and --ros-args (last) passes remappings, -p and --params-file to ROS")
    p.add_argument("-o", "--output", metavar="OUT.parquet|OUT.csv", help="--replay: the results table")
    p.add_argument("--model", metavar="CAL.json", help="calibration model: its input columns are the raw channels")
    add_inputs_option(p, "--replay's sensor columns: without --model the wrench, 6 columns Fx..Tz (default: the "
                         "first tool's payload file's, else u1,...,u6); with --model its raw input channels, in "
                         "the model's input order (default: the model's input names)", metavar="C1,C2,...")
    gravity = p.add_mutually_exclusive_group()
    gravity.add_argument("--orientation", type=column_list, metavar="QX,QY,QZ,QW",
                         help="quaternion columns, ROS order x,y,z,w: sensor frame to a world with gravity along -z")
    gravity.add_argument("--gravity-columns", type=column_list, metavar="GX,GY,GZ",
                         help="gravity vector in the sensor frame, m/s²")
    gravity.add_argument("--imu-columns", type=column_list, metavar="AX,AY,AZ",
                         help="accelerometer in the sensor frame, m/s² (gravity = minus the reading at rest)")
    p.add_argument("--g", type=positive_float, default=9.81, metavar="M/S2", help="gravity magnitude (default 9.81)")
    p.add_argument("--time", default="time", metavar="COL", help="time column, s (default time)")
    p.add_argument("--temperature", metavar="COL", help="temperature column, checked against the model's range")
    p.add_argument("--tool", type=tool_spec, action="append", default=[], metavar="NAME=PAYLOAD.json",
                   help="a tool of the library (repeat for several); 'none' is always there")
    p.add_argument("--mount", metavar="NAME", help="tool mounted at the start (default: the first --tool, else none)")
    p.add_argument("--retare-at", type=finite_float, action="append", default=[], metavar="TIME",
                   help="--replay: re-tare (bias only, tool kept) at this time, s; repeatable")
    p.add_argument("--switch-tool", type=switch_spec, action="append", default=[], metavar="TIME:NAME",
                   help="--replay: mount tool NAME at this time, s (e.g. 30:gripper); repeatable")
    p.add_argument("--walk-std", type=float_list, metavar="F,T",
                   help="bias random-walk std per √h, force (N) and torque (N·m), or six values (default: the "
                        "walk `payload --bias-drift random-walk` identified, from the first tool file that has "
                        "one, else 1 N, 0.1 N·m)")
    p.add_argument("--noise-std", type=float_list, metavar="F,T",
                   help="per-sample noise std, force and torque, or six values (default: the per-sample noise "
                        "within the holds the random-walk identification stored, else the first tool's residual "
                        "RMS, else 0.1 N, 0.01 N·m; the self-check raises it when the innovations say so)")
    # argparse takes "-1.5" for a value but "-1.5,2,..." for an option: let a list of signed numbers be a value
    p._negative_number_matcher = re.compile(r"^-\d*\.?\d+([eE][-+]?\d+)?(,[-+]?\d*\.?\d+([eE][-+]?\d+)?)*$")
    p.add_argument("--bias", type=signed_list, metavar="B1,...,B6",
                   help="initial bias, N and N·m, either sign (default unknown: the first static, contact-free "
                        "samples set it)")
    p.add_argument("--state", metavar="STATE.json",
                   help="state file: resumed from when it exists, saved (atomically) at the end and on Ctrl-C")
    p.add_argument("--realtime", action="store_true", help="--replay at the recording's speed")
    p.add_argument("--drop-incomplete", action="store_true",
                   help="--replay of a table: skip rows with an empty or NaN cell in the columns used (counted; the "
                        "next row's time step spans the gap) instead of refusing the table")
    add_robot_source_options(p, named_models=False)
    zenoh = p.add_argument_group("Zenoh and ROS bags (Zenoh keys follow zenoh-bridge-ros2dds: topic /ft/raw is "
                                 "key ft/raw; rmw_zenoh's with --keys rmw_zenoh)")
    zenoh.add_argument("--listen", action="append", default=[], metavar="ENDPOINT",
                       help="endpoint to listen on (repeatable; default tcp/127.0.0.1:7448, or tcp/127.0.0.1:0 beside "
                            "--connect)")
    zenoh.add_argument("--connect", action="append", default=[], metavar="ENDPOINT",
                       help="endpoint to connect to, e.g. the Zenoh router of rmw_zenoh (rmw_zenohd) or "
                            "zenoh-bridge-ros2dds, tcp/127.0.0.1:7447 (repeatable; must answer within 5 s)")
    zenoh.add_argument("--wrench-topic", metavar="TOPIC",
                       help="raw geometry_msgs/msg/WrenchStamped (default /ft/raw; --ros2: ft/raw, in the node's "
                            "namespace)")
    zenoh.add_argument("--imu-topic", metavar="TOPIC", help="sensor_msgs/msg/Imu in the sensor frame: gravity "
                                                           "from its orientation (else its acceleration)")
    zenoh.add_argument("--joints-topic", metavar="TOPIC",
                       help="sensor_msgs/msg/JointState (e.g. /joint_states): gravity from the joints and --urdf")
    zenoh.add_argument("--temperature-topic", metavar="TOPIC",
                       help="--zenoh, --ros2: sensor_msgs/msg/Temperature, checked against the model's temperature "
                            "range and fed to a model with a temperature input")
    zenoh.add_argument("--tf", metavar="BASE[:SENSOR_FRAME]", type=frame_pair,
                       help="--replay of a bag: the sensor's orientation from /tf and /tf_static (BASE gravity-"
                            "aligned, z up)")
    zenoh.add_argument("--receive-time", action="store_true",
                       help="--replay of a bag: time the messages by the bag's receive time, not their header stamps "
                            "(as ftcal dataset --receive-time: for stamps that repeat or go back)")
    zenoh.add_argument("--prefix", metavar="TOPIC",
                       help="outputs: PREFIX/calibrated, PREFIX/compensated (WrenchStamped), PREFIX/diagnostics "
                            "(JSON); queryables PREFIX/retare, /switch_tool, /identify_tool, /status "
                            "(default /ft; --ros2: ft, and services PREFIX/retare, PREFIX/identify/start, "
                            "PREFIX/identify/finish)")
    zenoh.add_argument("--silence", type=positive_float, default=1.0, metavar="S",
                       help="flag the input silent after this many seconds without a message (default 1)")
    zenoh.add_argument("--duration", type=positive_float, metavar="S", help="stop after this many seconds")
    zenoh.add_argument("--keys", choices=LIVE_KEY_CONVENTIONS, default="bridge",
                       help="key expressions of the ROS topics: zenoh-bridge-ros2dds's (default: /ft/raw is ft/raw) "
                            "or rmw_zenoh's (DOMAIN/ft/raw/geometry_msgs::msg::dds_::WrenchStamped_/RIHS01_..., with "
                            "attachments and liveliness tokens); diagnostics and queryables keep PREFIX/NAME")
    zenoh.add_argument("--domain-id", type=nonnegative_int, default=0, metavar="N",
                       help="--keys rmw_zenoh: the ROS domain id at the head of every key (default 0)")
    zenoh.add_argument("--rt-priority", type=nonnegative_int, metavar="N",
                       help="--zenoh: run the node under SCHED_FIFO at priority N (1-99; Linux, needs CAP_SYS_NICE "
                            "or an rtprio limit); says in one line when it is not permitted and runs on")
    p.add_argument("--ros-args", nargs=argparse.REMAINDER, metavar="ROS_ARGS",
                   help="--ros2, last: the rest goes to ROS (e.g. --ros-args -r __ns:=/robot1 --params-file ft.yaml)")
    p.set_defaults(func=run)


def setup_of(args):
    """The :class:`~ftcal.workflow.live.LiveSetup` the options describe."""
    from ..workflow.live import LiveSetup

    return LiveSetup(model=args.model, tools=list(args.tool), mount=args.mount, walk_std=args.walk_std,
                     noise_std=args.noise_std, bias=args.bias, g=args.g, state=args.state, urdf=args.robot_urdf,
                     sensor=args.sensor, ft_joint=args.ft_joint, ft_frame=args.ft_frame, base=args.base,
                     degrees=args.degrees)


def run(args) -> int:
    from ..runtime.errors import FtcalError

    inputs_of(args)  # --wrench, the old spelling, read as --inputs (with a notice)
    relative = args.ros2  # ROS names without a leading slash live in the node's namespace
    if args.wrench_topic is None:
        args.wrench_topic = "ft/raw" if relative else "/ft/raw"
    if args.prefix is None:
        args.prefix = "ft" if relative else "/ft"
    if args.ros_args is not None and not args.ros2:
        raise FtcalError("--ros-args goes with --ros2.")
    if args.temperature_topic is not None and args.replay is not None:
        raise FtcalError("--temperature-topic applies to --zenoh and --ros2; --replay takes --temperature COL.")
    if args.zenoh:
        return run_zenoh(args)
    if args.ros2:
        return run_ros2(args)
    return run_replay(args)


def run_replay(args) -> int:
    from ..runtime.errors import FtcalError
    from ..workflow.live import replay_live
    from ._gravity import check_not_input

    if args.output is None:
        raise FtcalError("--replay needs -o OUT.parquet (or OUT.csv) for the results.")
    require_suffix(args.output, (".csv", ".parquet"), "-o")
    inputs = [args.replay, *(path for _, path in args.tool)] + ([args.model] if args.model else [])
    check_not_input(args.output, inputs)
    if args.state:
        from pathlib import Path

        if any(Path(p).resolve() == Path(args.state).resolve() for p in inputs + [args.output]):
            raise FtcalError(f"--state {args.state}: is also an input or the output; give the state its own file.")
    _refuse_zenoh_options(args)
    _refuse_source_options(args)
    result = replay_live(args.replay, setup_of(args), output=args.output, time=args.time, inputs=args.inputs,
                         orientation=args.orientation, gravity_columns=args.gravity_columns,
                         imu_columns=args.imu_columns, temperature=args.temperature, retare_at=args.retare_at,
                         switch_tool=args.switch_tool, realtime=args.realtime, drop_incomplete=args.drop_incomplete,
                         wrench_topic=args.wrench_topic, joints_topic=args.joints_topic, imu_topic=args.imu_topic,
                         tf=args.tf, receive_time=args.receive_time)
    print(result.summary())
    return 0


# Options only --zenoh reads, and their defaults: --replay refuses them instead of ignoring them.
_ZENOH_ONLY = {"listen": [], "connect": [], "prefix": "/ft", "silence": 1.0, "duration": None, "keys": "bridge",
               "domain_id": 0, "rt_priority": None}


def _refuse_zenoh_options(args) -> None:
    from ..runtime.errors import FtcalError

    given = [name for name, default in _ZENOH_ONLY.items() if getattr(args, name, default) != default]
    if given:
        raise FtcalError(f"{', '.join('--' + g.replace('_', '-') for g in given)} go with --zenoh; --replay "
                         f"{args.replay} does not read {'it' if len(given) == 1 else 'them'}.")


def _refuse_source_options(args) -> None:
    """A ROS bag's options with a --replay table (the message names --zenoh, so the check is the CLI's; a table's
    options with a bag are the step's to refuse: ftcal.workflow.live.replay_live)."""
    from ..runtime.errors import FtcalError
    from ..workflow.live import replays_a_bag

    if replays_a_bag(args.replay):
        return
    if args.wrench_topic != "/ft/raw" or args.imu_topic is not None:
        raise FtcalError(f"--{'wrench' if args.wrench_topic != '/ft/raw' else 'imu'}-topic applies to --zenoh "
                         f"and to ROS bags; {args.replay} is a table (give its columns).")
    for option in ("joints_topic", "tf"):
        if getattr(args, option) is not None:
            raise FtcalError(f"--{option.replace('_', '-')} applies to --zenoh and to ROS bags; "
                             f"{args.replay} is a table (give its columns).")
    if args.receive_time:
        raise FtcalError(f"--receive-time applies to ROS bags; {args.replay} is a table (its --time column "
                         "is the time).")


def run_zenoh(args) -> int:
    """``--zenoh``: the options combined with --replay's are refused here; their values are checked by the step
    (ftcal.workflow.live.serve_zenoh)."""
    from ..runtime.errors import FtcalError
    from ..workflow.live import serve_zenoh

    if (args.output or args.retare_at or args.switch_tool or args.realtime or args.tf or args.receive_time
            or args.drop_incomplete):
        raise FtcalError("-o, --retare-at, --switch-tool, --realtime, --tf, --receive-time and --drop-incomplete go "
                         "with --replay; live, use the queryables (see docs/live.md).")
    return serve_zenoh(setup_of(args), listen=tuple(args.listen), connect=tuple(args.connect),
                       wrench_topic=args.wrench_topic, imu_topic=args.imu_topic, joints_topic=args.joints_topic,
                       temperature_topic=args.temperature_topic, prefix=args.prefix, silence=args.silence,
                       duration=args.duration, keys=args.keys, domain_id=args.domain_id, rt_priority=args.rt_priority)


def run_ros2(args) -> int:
    """``--ros2``: the options are the node's parameters' defaults; a params file or ``-p`` may override them
    (ftcal.workflow.live.serve_ros2)."""
    from ..runtime.errors import FtcalError
    from ..workflow.live import serve_ros2

    if (args.output or args.retare_at or args.switch_tool or args.realtime or args.tf or args.receive_time
            or args.drop_incomplete or args.listen or args.connect or args.keys != "bridge" or args.domain_id
            or args.rt_priority is not None):
        raise FtcalError("-o, --retare-at, --switch-tool, --realtime, --tf, --receive-time, --drop-incomplete, "
                         "--listen, --connect, --keys, --domain-id and --rt-priority do not apply to --ros2 (ROS picks "
                         "the transport: RMW_IMPLEMENTATION, ROS_DOMAIN_ID); use its services (docs/live.md).")
    node = {name: getattr(args, name) for name in ("wrench_topic", "imu_topic", "joints_topic", "temperature_topic",
                                                   "prefix", "silence", "duration")}
    return serve_ros2(setup_of(args), node, args.ros_args or ())
