"""``ftcal payload``: identify the sensor bias and the tool's mass, centre of mass (and inertia)."""

from __future__ import annotations

from ..core.limits import BIAS_DRIFTS
from ..runtime.errors import FtcalError
from ._common import require_suffix
from ._examples import epilog
from ._gravity import add_kinematics_options, add_robot_source_options, check_not_input, source_keywords
from ._inputs import add_inputs_option, inputs_of


def register(sub) -> None:
    p = sub.add_parser("payload", **epilog("payload"), help="identify the sensor bias and the tool's mass and centre of mass",
                       description="Identify, by linear least squares, the F/T sensor's force and torque bias "
                                   "and the attached tool's mass and centre of mass (sensor frame) from static "
                                   "poses; --dynamic adds the inertia from angular velocity/acceleration and "
                                   "linear acceleration. Sign convention: the sensor reads the wrench the tool "
                                   "applies on it (a mass m at rest adds m·g); use --reaction for sensors that "
                                   "report the opposite sign.")
    p.add_argument("data", nargs="+", metavar="DATA", help="CSV or Parquet files, one row per sample")
    p.add_argument("-o", "--output", required=True, metavar="PAYLOAD.json",
                   help="payload file: mass (kg), com (m), force/torque bias (N, N·m), inertia with --dynamic, "
                        "standard errors; for 'ftcal compensate' and 'ftcal convert --to ros-yaml|ft-tools-ros2'")
    add_inputs_option(p, "measured wrench columns, N and N·m (default u1,...,u6)")
    add_kinematics_options(p)
    add_robot_source_options(p)
    p.add_argument("--group-by", metavar="COL",
                   help="column naming the cross-validation groups, e.g. the pose (default: the 'hold' column "
                        "ftcal dataset writes when every file has one, else one per file)")
    p.add_argument("--keep-moving", action="store_true",
                   help="static model: use every sample (default: only the static holds, found from the orientation, "
                        "joints or gravity over --time, else the table's static column from ftcal dataset; the moving "
                        "samples are counted and excluded)")
    p.add_argument("--reaction", action="store_true",
                   help="the sensor reports the wrench it applies on the tool (opposite sign): negate readings")
    p.add_argument("--frame", metavar="NAME", help="name of the sensor frame, stored in the file (e.g. ft_sensor)")
    p.add_argument("--calibration", metavar="CAL.json",
                   help="identify on the calibrated wrench: apply this model (ftcal fit -o) to its input columns "
                        "(the raw channels) first, in the same command (--inputs then does not apply)")
    drift = p.add_argument_group("a bias that drifts (needs --time for the time models)")
    drift.add_argument("--bias-drift", choices=BIAS_DRIFTS, default="auto",
                       help="bias over the recording: constant, affine in time, a random walk (state-space model), "
                            "or auto: chosen by BIC, the simpler model unless the evidence is strong (default "
                            "auto; without --time the bias is constant)")
    drift.add_argument("--temperature", metavar="COL", help="the bias is also affine in this temperature column")
    drift.add_argument("--rebias", metavar="PAYLOAD.json",
                       help="re-tare: re-estimate only the bias from DATA with this file's mass and centre of mass "
                            "fixed, report the drift since identification, write the updated file to -o")
    p.set_defaults(func=run)


def run(args) -> int:
    import sys

    from ..workflow.payload import identify_payload, retare
    from ..workflow.sources import DEFAULT_WRENCH

    require_suffix(args.output, (".json",), "-o")
    check_not_input(args.output, args.data + ([args.rebias] if args.rebias else []))
    inputs = inputs_of(args, None)
    if args.calibration is not None:
        check_not_input(args.output, [args.calibration])
        if inputs is not None:
            raise FtcalError("--inputs does not go with --calibration: the model names its input columns.")
    inputs = inputs or DEFAULT_WRENCH
    if args.rebias:
        # Options that change nothing in a re-tare are refused rather than silently ignored.
        for option, given in (("--dynamic", args.dynamic), ("--bias-drift", args.bias_drift != "auto"),
                              ("--group-by", args.group_by is not None), ("--frame", args.frame is not None),
                              ("--calibration", args.calibration is not None)):
            if given:
                raise FtcalError(f"{option} does not apply to --rebias (the re-tare keeps {args.rebias}'s model and "
                                 "estimates one constant bias); leave it out.")
        result = retare(args.rebias, args.data, inputs=inputs, keep_moving=args.keep_moving,
                                reaction=args.reaction, temperature=args.temperature, **source_keywords(args))
    else:
        result = identify_payload(args.data, inputs=inputs, group_by=args.group_by,
                                  keep_moving=args.keep_moving, reaction=args.reaction, frame=args.frame,
                                  bias_drift=args.bias_drift, temperature=args.temperature,
                                  calibration=args.calibration, **source_keywords(args))
    print(result.summary())
    result.save(args.output)
    print(f"wrote {args.output}", file=sys.stderr)
    return 0
