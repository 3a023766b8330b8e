"""``ftcal simulate``: a dry run on your own robot: the recordings a plan would give, and their truth."""

from __future__ import annotations

import argparse

from ..core.limits import SIMULATE_CHANNELS, SIMULATE_MISTAKES
from ._common import finite_float, nonnegative_int, positive_float
from ._examples import epilog
from ._robot import add_robot_arguments


def pair(text: str) -> tuple[float, float]:
    parts = text.split(",")
    if len(parts) != 2:
        raise argparse.ArgumentTypeError(f"expected two numbers A,B, got {text!r}")
    return finite_float(parts[0]), finite_float(parts[1])


def mistake(text: str) -> tuple[str, float]:
    """``none``, ``sign``, ``swap-xy`` or ``rotate-z:DEG``."""
    name, _, degrees = text.partition(":")
    if name not in SIMULATE_MISTAKES:
        raise argparse.ArgumentTypeError(f"expected one of none, sign, swap-xy, rotate-z:DEG; got {text!r}")
    if name == "rotate-z":
        angle = finite_float(degrees) if degrees else float("nan")
        if not 0 < abs(angle) <= 180:
            raise argparse.ArgumentTypeError(f"rotate-z needs an angle in (0, 180] degrees, e.g. rotate-z:90; "
                                             f"got {text!r}")
        return name, angle
    if degrees:
        raise argparse.ArgumentTypeError(f"only rotate-z takes an angle; got {text!r}")
    return name, 0.0


def fraction(text: str) -> float:
    value = positive_float(text)
    if value > 1:
        raise argparse.ArgumentTypeError(f"must be in (0, 1], got {text!r}")
    return value


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "simulate", **epilog("simulate"),
        help="simulate the recordings a plan gives on your robot (ROS 2 bags / log tables) and their truth",
        description="A dry run before touching the robot: the robot of --urdf visits the poses of PLAN (an "
                    "`ftcal plan` CSV, or any table with one column per joint in rad and an optional 'load' "
                    "column), holding each pose and moving between them along minimum-jerk paths within the URDF "
                    "limits; a simulated sensor (calibration matrix, nonlinearity and crosstalk, temperature "
                    "sensitivity, a bias that ramps and random-walks, noise, saturation, and an optional mounting "
                    "mistake) reads the wrench iDynTree predicts. Writes one recording per load (ROS 2 bag: "
                    "/joint_states, /tf, /imu, /ft_sensor/wrench or /ft_sensor/raw, /ft_sensor/temperature; "
                    "and/or a robot-log table), loads.toml for `ftcal dataset --payload-file`, and truth.json "
                    "(true and factory matrices, drift, tool, holds) to score every later step. The same --seed "
                    "writes the same bytes.")
    parser.add_argument("plan", metavar="PLAN",
                        help="poses in order: `ftcal plan` CSV or a joint table (.csv/.parquet)")
    add_robot_arguments(parser)
    parser.add_argument("--sensor", metavar="NAME", help="F/T sensor (sensor or joint name; default: the only one)")
    parser.add_argument("--load", metavar="SPEC", action="append", default=[],
                        help="what PLAN's 'load' index k mounts: the k-th --load, FRAME:MASS[@X,Y,Z][/IXX,IYY,IZZ] "
                             "or 'none'; repeatable, in the order given to `ftcal plan` (default: none)")
    parser.add_argument("--hold", type=positive_float, default=2.0, metavar="S",
                        help="hold at each pose, s (default 2)")
    parser.add_argument("--speed", type=fraction, default=0.3, metavar="F",
                        help="fastest joint speed as a fraction of its URDF velocity limit, (0, 1] (default 0.3)")
    parser.add_argument("--rate", type=positive_float, default=250.0, metavar="HZ",
                        help="F/T sample rate (default 250 Hz; joints, tf and IMU at 100 Hz)")
    parser.add_argument("--format", choices=("bag", "table", "both"), default="bag",
                        help="ROS 2 bag folders, robot-log tables (.parquet), or both (default bag)")
    parser.add_argument("--channels", choices=SIMULATE_CHANNELS, default="wrench",
                        help="wrench: the driver's factory-calibrated wrench (N, N m; default); raw: the ADC counts")
    sensor = parser.add_argument_group("the simulated sensor (defaults: a mildly nonlinear 250 N / 25 N m sensor)")
    sensor.add_argument("--sensor-file", metavar="JSON",
                        help="sensor parameters as JSON (a truth.json's sensor.spec, or that object alone); the "
                             "options below override it")
    sensor.add_argument("--noise", type=finite_float, metavar="COUNTS", help="noise std, ADC counts")
    sensor.add_argument("--nonlinearity", type=finite_float, metavar="F",
                        help="scale the quadratic and cubic terms (0: a linear sensor; default 1)")
    sensor.add_argument("--crosstalk", type=finite_float, metavar="C", help="off-diagonal coupling std (default 0.15)")
    sensor.add_argument("--drift", type=pair, metavar="RAMP,WALK",
                        help="bias ramp std (full scale per s) and random walk (full scale per sqrt(s))")
    sensor.add_argument("--temperature", type=pair, default=(28.0, 34.0), metavar="START,END",
                        help="sensor temperature at the start and end of the session, degC (default 28,34)")
    sensor.add_argument("--mistake", type=mistake, default=("none", 0.0), metavar="KIND",
                        help="mount the sensor wrong, for `ftcal check` to find: none (default), sign, swap-xy, "
                             "rotate-z:DEG")
    parser.add_argument("--seed", type=nonnegative_int, default=0, help="random seed, >= 0 (default 0)")
    parser.add_argument("-o", "--output", metavar="DIR", required=True,
                        help="folder for the recordings, loads.toml and truth.json")
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from ..sim.simulate import simulate

    result = simulate(args.plan, output=args.output, urdf=args.urdf, robot=args.model, ft_joint=args.ft_joint,
                      ft_frame=args.ft_frame, payload=tuple(args.payload), base=args.base, sensor=args.sensor,
                      load=tuple(args.load), hold=args.hold, speed=args.speed, rate=args.rate,
                      formats=("bag", "table") if args.format == "both" else (args.format,), channels=args.channels,
                      sensor_file=args.sensor_file, noise=args.noise, nonlinearity=args.nonlinearity,
                      crosstalk=args.crosstalk, drift=args.drift, temperature=args.temperature, mistake=args.mistake,
                      seed=args.seed)
    print(result.summary())
    return 0
