"""``ftcal demo``: the paper's experiment (or the arm scenario) on simulated data, end to end."""

from __future__ import annotations

from ._common import nonnegative_int
from ._examples import epilog


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
    from ..sim.demos import demo

    print(demo(args.scenario, out=args.out, seed=args.seed, quick=args.quick, variant=args.variant,
               seeds=args.seeds).summary())
    return 0
