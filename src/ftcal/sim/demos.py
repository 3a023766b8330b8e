"""The demo step: one ``ftcal demo`` scenario, run by name, and the text it prints.

It lives in ``sim`` with the scenarios it runs (the step layer, ``workflow``, sits below ``sim``, as for
:func:`ftcal.sim.simulate.simulate`); the command parses its options, calls :func:`demo` and prints the
result. Each scenario is one module (``demo``, ``demo_arm``, ``demo_plan``, ``demo_live``, ``closed_loop``)
and one line of :data:`SCENARIOS`. Messages name the parameters; the CLI writes them as flags.
"""

from __future__ import annotations

import dataclasses
import os
from dataclasses import dataclass
from pathlib import Path

from ..runtime.atomic import output_folder
from ..runtime.errors import ParameterError
from ..workflow.result import StepResult

# scenario -> the folder its files go to by default
SCENARIOS = {"paper": "ftcal-demo", "arm": "ftcal-arm-demo", "plan": "ftcal-plan-demo", "live": "ftcal-live-demo",
             "closed-loop": "ftcal-closed-loop-demo"}


@dataclass(repr=False)
class DemoResult(StepResult):
    """What :func:`demo` ran and wrote.

    Attributes
    ----------
    scenario : one of :data:`SCENARIOS`
    out : the folder written
    record : dict
        The scenario's ``summary.json`` content, plus ``elapsed_s`` (and ``cpu_s`` for ``closed-loop``).
    bag : Path or None
        ``paper``: the arm scenario's ROS 2 bag, written beside the paper's files.
    """

    scenario: str
    out: Path
    record: dict
    bag: Path | None = None

    def summary(self) -> str:
        s = self.record
        if self.scenario == "paper":
            from .demo import format_tables

            return "\n".join([format_tables(s), "",
                              f"{s['n_train_samples']} training / {s['n_validation_samples']} validation samples; "
                              f"done in {s['elapsed_s']:.0f} s",
                              f"wrote {self.out / 'summary.json'} and {self.out / 'report.html'}",
                              f"wrote {self.bag} (ROS 2 bag of the arm scenario, see --scenario arm)"])
        done = f"done in {s['elapsed_s']:.0f} s"
        if self.scenario == "arm":
            from .demo_arm import format_arm_tables as tables

            done = f"{s['n_samples']} samples; {done}"
        elif self.scenario == "plan":
            from .demo_plan import format_plan_tables as tables
        elif self.scenario == "live":
            from .demo_live import format_live_tables as tables
        else:
            from .closed_loop import format_closed_loop as tables

            done += f" ({s['cpu_s']:.0f} s CPU)"
        return "\n".join([tables(s), "", done, "wrote " + ", ".join(s["files"])])

    def to_dict(self) -> dict:
        from ..workflow.result import plain

        return plain({"scenario": self.scenario, "out": self.out, "bag": self.bag, **self.record})


def demo(scenario: str = "paper", *, out: str | os.PathLike | None = None, seed: int = 0, quick: bool = False,
         variant: str = "standard", seeds: int = 1) -> DemoResult:
    """Run one demo scenario on simulated data, end to end, as ``ftcal demo`` does; the keywords are its flags.

    Parameters
    ----------
    scenario : {"paper", "arm", "plan", "live", "closed-loop"}
        ``paper``: the paper's iCub experiment (also writes the arm scenario's ROS 2 bag to ``out/arm``);
        ``arm``: a wrist sensor with an unknown gripper, from a ROS 2 bag; ``plan``: planned poses against
        random ones; ``live``: a drifting wrist sensor replayed through the live calibrator; ``closed-loop``:
        a MuJoCo force controller with the factory, ftcal-calibrated and true wrench.
    out : path, optional
        Folder for the files (default: :data:`SCENARIOS`'s, in the working folder).
    seed : int
        Simulation seed (closed-loop: the first of ``seeds``).
    quick : bool
        A smaller experiment.
    variant : str
        closed-loop only: ``standard``, ``high-loads``, ``long-task`` or ``tool-change``.
    seeds : int
        closed-loop only: run seeds ``seed .. seed + seeds - 1``.

    Returns
    -------
    DemoResult

    Raises
    ------
    ParameterError
        An unknown scenario or variant, closed-loop options for another scenario, a folder that cannot be written.
    """
    if scenario not in SCENARIOS:
        raise ParameterError("scenario", f"{{scenario}} {scenario}: unknown scenario; choose one of "
                                         f"{', '.join(SCENARIOS)}.")
    if scenario != "closed-loop" and (variant != "standard" or seeds != 1):
        raise ParameterError(("variant", "seeds", "scenario"), "{variant} and {seeds} go with {scenario} closed-loop.")
    if scenario == "closed-loop" and seeds < 1:
        raise ParameterError("seeds", f"{{seeds}} {seeds}: must be at least 1.")
    folder = output_folder(out or SCENARIOS[scenario], "out")
    return _RUNS[scenario](folder, seed, quick, variant, seeds)


def _paper(out: Path, seed: int, quick: bool, *_) -> DemoResult:
    from .demo import DemoConfig, run_demo
    from .demo_arm import BAG_NAME, write_demo_bag

    record = run_demo(DemoConfig(out_dir=out, seed=seed, quick=quick))
    return DemoResult("paper", out, record, write_demo_bag(out / BAG_NAME).path)


def _arm(out: Path, seed: int, quick: bool, *_) -> DemoResult:
    from .demo_arm import ARM_DEMO_SCENARIO, ARM_QUICK, ArmDemoConfig, run_arm_demo

    scenario = dataclasses.replace(ARM_DEMO_SCENARIO, seed=seed, **(ARM_QUICK if quick else {}))
    return DemoResult("arm", out, run_arm_demo(ArmDemoConfig(out_dir=out, scenario=scenario)))


def _plan(out: Path, seed: int, quick: bool, *_) -> DemoResult:
    from .demo_plan import PLAN_QUICK, PlanDemoConfig, run_plan_demo

    config = dataclasses.replace(PlanDemoConfig(out_dir=out, seed=seed), **(PLAN_QUICK if quick else {}))
    return DemoResult("plan", out, run_plan_demo(config))


def _live(out: Path, seed: int, quick: bool, *_) -> DemoResult:
    from .demo_live import LiveDemoConfig, run_live_demo

    return DemoResult("live", out, run_live_demo(LiveDemoConfig(out_dir=out, seed=seed, quick=quick)))


def _closed_loop(out: Path, seed: int, quick: bool, variant: str, seeds: int) -> DemoResult:
    from .closed_loop import CLOSED_LOOP_QUICK, ClosedLoopConfig, run_closed_loop

    config = ClosedLoopConfig.of_variant(variant, out_dir=out, seed=seed)
    record = run_closed_loop(dataclasses.replace(config, **(CLOSED_LOOP_QUICK if quick else {})),
                             seeds=tuple(range(seed, seed + seeds)))
    return DemoResult("closed-loop", out, record)


_RUNS = {"paper": _paper, "arm": _arm, "plan": _plan, "live": _live, "closed-loop": _closed_loop}
