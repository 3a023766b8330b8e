"""``ftcal demo``: the paper's experiment (or the arm scenario) on simulated data, end to end."""

from __future__ import annotations

from ._common import nonnegative_int, output_folder
from ._examples import epilog

SCENARIOS = ("paper", "arm", "plan", "live", "closed-loop")


def register(sub) -> None:
    p = sub.add_parser("demo", **epilog("demo"), help="simulate the paper's experiment (or --scenario arm) and calibrate "
                                    "(no robot needed)")
    p.add_argument("--scenario", default="paper", metavar="NAME",
                   help="paper: the paper's iCub experiment (default; also writes the arm scenario's ROS 2 bag "
                        "to DIR/arm); arm: a wrist sensor with an unknown gripper, from a ROS 2 bag; plan: "
                        "poses planned by `ftcal plan` against random poses at the same budget; live: a drifting "
                        "wrist sensor with a contact and a tool swap, replayed through `ftcal live`; closed-loop: a "
                        "MuJoCo force controller driven by the factory, ftcal-calibrated and true wrench")
    p.add_argument("--out", metavar="DIR",
                   help="folder for the recordings, models, summary.json, report.html and the inputs "
                        "README.md's examples use (default ftcal-demo/, ftcal-arm-demo/ for --scenario arm, "
                        "ftcal-plan-demo/ for --scenario plan, ftcal-live-demo/ for --scenario live, "
                        "ftcal-closed-loop-demo/ for --scenario closed-loop)")
    p.add_argument("--seed", type=nonnegative_int, default=0, help="simulation seed, >= 0 (default 0)")
    p.add_argument("--quick", action="store_true", help="a smaller experiment (a few recordings; arm: 8 poses)")
    p.add_argument("--variant", default="standard", metavar="NAME",
                   help="closed-loop only: standard (one 40 s task, default), high-loads (forces near the sensor's "
                        "range), long-task (32 contacts over 10 min with a warm-up drift and a temperature change) "
                        "or tool-change (a gripper swapped in halfway)")
    p.add_argument("--seeds", type=nonnegative_int, default=1, metavar="N",
                   help="closed-loop only: run seeds SEED .. SEED+N-1 and say which conditions tie within their "
                        "spread (default 1)")
    p.set_defaults(func=run)


def run(args) -> int:
    from ..runtime.errors import FtcalError
    from ..sim.demo import DemoConfig, format_tables, run_demo
    from ..sim.demo_arm import BAG_NAME, write_demo_bag

    if args.scenario not in SCENARIOS:
        raise FtcalError(f"--scenario {args.scenario}: unknown scenario; choose one of {', '.join(SCENARIOS)}.")
    if args.scenario == "arm":
        return run_arm(args)
    if args.scenario == "plan":
        return run_plan(args)
    if args.scenario == "live":
        return run_live(args)
    if args.scenario == "closed-loop":
        return run_closed_loop(args)
    if args.variant != "standard" or args.seeds != 1:
        raise FtcalError("--variant and --seeds go with --scenario closed-loop.")
    out = output_folder(args.out or "ftcal-demo")
    summary = run_demo(DemoConfig(out_dir=out, seed=args.seed, quick=args.quick))
    print(format_tables(summary))
    print(f"\n{summary['n_train_samples']} training / {summary['n_validation_samples']} validation samples; "
          f"done in {summary['elapsed_s']:.0f} s")
    print(f"wrote {out / 'summary.json'} and {out / 'report.html'}")
    print(f"wrote {write_demo_bag(out / BAG_NAME).path} (ROS 2 bag of the arm scenario, see --scenario arm)")
    return 0


def run_arm(args) -> int:
    import dataclasses

    from ..sim.demo_arm import ARM_DEMO_SCENARIO, ARM_QUICK, ArmDemoConfig, format_arm_tables, run_arm_demo

    scenario = dataclasses.replace(ARM_DEMO_SCENARIO, seed=args.seed, **(ARM_QUICK if args.quick else {}))
    summary = run_arm_demo(ArmDemoConfig(out_dir=output_folder(args.out or "ftcal-arm-demo"), scenario=scenario))
    print(format_arm_tables(summary))
    print(f"\n{summary['n_samples']} samples; done in {summary['elapsed_s']:.0f} s")
    print("wrote " + ", ".join(summary["files"]))
    return 0


def run_plan(args) -> int:
    import dataclasses

    from ..sim.demo_plan import PLAN_QUICK, PlanDemoConfig, format_plan_tables, run_plan_demo

    config = PlanDemoConfig(out_dir=output_folder(args.out or "ftcal-plan-demo"), seed=args.seed)
    summary = run_plan_demo(dataclasses.replace(config, **(PLAN_QUICK if args.quick else {})))
    print(format_plan_tables(summary))
    print(f"\ndone in {summary['elapsed_s']:.0f} s")
    print("wrote " + ", ".join(summary["files"]))
    return 0


def run_live(args) -> int:
    from ..sim.demo_live import LiveDemoConfig, format_live_tables, run_live_demo

    config = LiveDemoConfig(out_dir=output_folder(args.out or "ftcal-live-demo"), seed=args.seed, quick=args.quick)
    summary = run_live_demo(config)
    print(format_live_tables(summary))
    print(f"\ndone in {summary['elapsed_s']:.0f} s")
    print("wrote " + ", ".join(summary["files"]))
    return 0


def run_closed_loop(args) -> int:
    import dataclasses

    from ..runtime.errors import FtcalError
    from ..sim.closed_loop import CLOSED_LOOP_QUICK, ClosedLoopConfig, format_closed_loop, run_closed_loop

    if args.seeds < 1:
        raise FtcalError(f"--seeds {args.seeds}: must be at least 1.")
    config = ClosedLoopConfig.of_variant(args.variant, out_dir=output_folder(args.out or "ftcal-closed-loop-demo"),
                                         seed=args.seed)
    summary = run_closed_loop(dataclasses.replace(config, **(CLOSED_LOOP_QUICK if args.quick else {})),
                              seeds=tuple(range(args.seed, args.seed + args.seeds)))
    print(format_closed_loop(summary))
    print(f"\ndone in {summary['elapsed_s']:.0f} s ({summary['cpu_s']:.0f} s CPU)")
    print("wrote " + ", ".join(summary["files"]))
    return 0
