"""Design a calibration (or payload identification) experiment: ``ftcal plan``."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

from .arguments import PLAN, check_arguments
from ..core.limits import MAX_DEGREE, PLAN_DEFAULTS
from ..runtime.errors import FtcalError, ParameterError
from .result import StepResult
from .sources import robot_model


@dataclass(repr=False)
class PlanResult(StepResult):
    """A planned experiment: the poses in execution order, and the comparison with a random design.

    Attributes
    ----------
    plan : Plan (:mod:`ftcal.plan`)
    table : pandas.DataFrame, one row per pose: joint columns (rad), load, reference, expected Fx..Tz
    recorded : the tables of poses already recorded that the plan adds to

    Examples
    --------
    >>> import pandas as pd
    >>> PlanResult(None, pd.DataFrame({"load": [0, 0, 1], "reference": [1, 0, 0]})).to_dict()["n_rows"]
    3
    """

    plan: object
    table: object
    recorded: list = field(default_factory=list)

    def summary(self) -> str:
        from ..plan.page import format_summary

        return format_summary(self.plan)

    def to_dict(self) -> dict:
        from .result import plain

        return plain({"n_rows": len(self.table), "columns": list(map(str, self.table.columns)),
                      "rows": {str(c): self.table[c].to_numpy() for c in self.table.columns}})

    def save(self, path, html=None) -> None:
        """Write the plan (CSV) and, when ``html`` is given, its page; both or neither (atomically)."""
        from ..data.tables import check_finite_output
        from ..runtime.atomic import write_texts_atomic

        check_finite_output(self.table, str(path))
        texts = {path: self.table.to_csv(index=False, float_format="%.17g")}
        if html is not None:
            from ..plan.page import page_text

            texts[html] = page_text(self.plan, self.recorded)
        write_texts_atomic(texts)


def plan_experiment(poses: int, *, urdf=None, robot: str | None = None, ft_joint: str | None = None,
         ft_frame: str | None = None, payload: Sequence[str] = (), base: str | None = None,
         sensor: str | None = None, load: Sequence[str] = (), objective: str = "calibration",
         degree: int = PLAN_DEFAULTS["degree"], joint_range: Sequence[tuple[str, float, float]] = (),
         fixed: Mapping[str, float] | Sequence[tuple[str, float]] = (), min_height: float | None = None,
         candidates: int = PLAN_DEFAULTS["candidates"], reference_every: int = PLAN_DEFAULTS["reference_every"],
         noise: tuple[float, float] = PLAN_DEFAULTS["noise"], recorded: Sequence = (), seed: int = 0,
         output=None, html=None) -> PlanResult:
    """Choose the poses and loads of a calibration experiment (greedy D-optimal), in execution order: ``ftcal plan``.

    No collision checking: the only limits are the joint limits, ``joint_range``, ``fixed`` and ``min_height``.

    Parameters
    ----------
    poses : poses to design (the reference-pose visits come on top)
    urdf, robot, ft_joint, ft_frame, payload, base : the robot model (as ``ftcal plan``; ``robot`` is ``--model``)
    sensor : F/T sensor (default: the model's only one)
    load : loads one can mount, specs ``FRAME:MASS[@X,Y,Z]...`` or ``"none"`` (default: none)
    objective : {"calibration", "payload"}
    degree : degree of the calibration to design for
    joint_range : (joint, low, high) in rad, each joint once
    fixed : joint -> value in rad (or (joint, value) pairs), each joint once
    min_height, candidates, reference_every, noise, seed : as the command's flags
    recorded : paths of tables of poses already recorded (``--from``)
    output, html : paths or None; when ``output`` is given the plan (and page) are written

    Returns
    -------
    PlanResult

    Raises
    ------
    FtcalError
        Bad robot options, loads, ranges or pins, or a degree out of range.

    Examples
    --------
    >>> import tempfile, os
    >>> from ftcal.sim.plan_arm import ARM_URDF                   # a small arm with one F/T sensor
    >>> urdf = os.path.join(tempfile.mkdtemp(), "arm.urdf")
    >>> with open(urdf, "w") as f:
    ...     _ = f.write(ARM_URDF)
    >>> result = plan_experiment(6, urdf=urdf, objective="payload", candidates=40, load=["none"])
    >>> int((result.table["reference"] == 0).sum())                # the designed poses
    6
    """
    check_arguments(PLAN, locals(), "ftcal.plan_experiment")
    from ..plan import PlanRequest
    from ..plan import design_experiment as design
    from ..plan.recorded import plan_frame, read_recorded
    from ..robot import parse_payload_spec

    if not 1 <= degree <= MAX_DEGREE:
        raise ParameterError('degree', f"{{degree}} {degree}: must be 1..{MAX_DEGREE}.")
    model = robot_model(urdf=urdf, robot=robot, ft_joint=ft_joint, ft_frame=ft_frame, payload=payload)
    loads = tuple(None if spec.strip().lower() == "none" else parse_payload_spec(spec)
                  for spec in (list(load) or ["none"]))
    ranges: dict[str, tuple[float, float]] = {}
    for name, low, high in joint_range:
        if name in ranges:
            raise ParameterError('joint_range', f"{{joint_range}} {name}: given more than once.")
        if not low < high:
            raise ParameterError('joint_range',
                                 f"{{joint_range}} {name}:{low:g}:{high:g}: empty range (LOW must be below HIGH).")
        ranges[name] = (low, high)
    pins: dict[str, float] = {}
    for name, value in (fixed.items() if isinstance(fixed, Mapping) else fixed):
        if name in pins:
            raise ParameterError('fixed', f"{{fixed}} {name}: given more than once.")
        pins[name] = value
    sensor = model.sensor(sensor).name if sensor else None
    request = PlanRequest(loads, poses, objective=objective, degree=degree, sensor=sensor, base=base,
                          ranges=ranges, fixed=pins, min_height=min_height, n_candidates=candidates,
                          reference_every=reference_every, noise=tuple(noise), seed=seed)
    tables = []
    if recorded:
        model.require_ft_sensors()
        which = sensor or (model.ft_sensors[0].name if len(model.ft_sensors) == 1 else None)
        if which is None:
            raise ParameterError(('recorded', 'sensor'),
                                 "{recorded} needs {sensor}: the robot has more than one F/T sensor.")
        tables = [read_recorded(path, model, which, base=base) for path in recorded]
    designed = design(model, request, tables)
    result = PlanResult(designed, plan_frame(designed), tables)
    if output is not None:
        result.save(output, html)
    return result
