"""Plan an experiment: candidates → information → greedy D-optimal design → execution order.

:func:`design_experiment` draws the candidate configurations, evaluates every one
under every load, chooses the poses (starting from the information of any
recorded data), orders them for execution, and compares the design with a
random one of the same size drawn from the same seed stream.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from ..core.limits import (MAX_DEGREE, MAX_PLAN_CANDIDATES, MAX_PLAN_POSES, MAX_PLAN_WORK, PLAN_DEFAULTS,
                           PLAN_OBJECTIVES)
from ..robot.model import RobotModel
from ..robot.payloads import Payload
from ..runtime.checks import check_choice, check_float, check_int
from ..runtime.errors import FtcalError, ParameterError
from ..runtime.threads import single_threaded_blas
from .candidates import Candidates, JointSpace, candidate_poses, joint_space
from .design import greedy_design, greedy_design_factored, random_design
from .information import (
    WrenchScaling,
    calibration_rows,
    excited_rank,
    information,
    log_det,
    payload_blocks,
    payload_parameter_names,
    payload_rows,
    prior,
    undetermined,
)
from .order import Step, execution_order, travel


@dataclass(frozen=True)
class PlanRequest:
    """What to plan (units: rad, m, N, N m).

    Attributes
    ----------
    loads : the loads the user can mount, None for nothing mounted; the plan's ``load`` indexes this
    n_poses : designed poses (the reference-pose visits come on top)
    objective : "calibration" (degree-``degree`` polynomial) or "payload" (bias + mass + COM)
    sensor : F/T sensor name (None: the model's only sensor)
    base : fixed base frame (None: the model's default)
    ranges, fixed : joint narrowing (name → (low, high)) and pins (name → value)
    min_height : lowest height of the sensor origin above the base's xy-plane, or None
    n_candidates : random configurations drawn (each tried with every load)
    reference_every : designed poses between two visits of the reference pose
    noise : (force, torque) noise of one pose's reading, for the payload weights and standard errors
    seed : seed of the random stream (candidates, then the random design compared with)
    """

    loads: tuple[Payload | None, ...]
    n_poses: int
    objective: str = "calibration"
    degree: int = PLAN_DEFAULTS["degree"]
    sensor: str | None = None
    base: str | None = None
    ranges: Mapping[str, tuple[float, float]] = field(default_factory=dict)
    fixed: Mapping[str, float] = field(default_factory=dict)
    min_height: float | None = None
    n_candidates: int = PLAN_DEFAULTS["candidates"]
    reference_every: int = PLAN_DEFAULTS["reference_every"]
    noise: tuple[float, float] = PLAN_DEFAULTS["noise"]
    seed: int = 0

    def __post_init__(self) -> None:
        owner = "PlanRequest"
        if not self.loads:
            raise ParameterError('load', "give at least one load ({load} SPEC, or {load} none for nothing mounted).")
        check_int(self.n_poses, "n_poses", owner, 1, MAX_PLAN_POSES)
        check_choice(self.objective, "objective", owner, PLAN_OBJECTIVES)
        check_int(self.degree, "degree", owner, 1, MAX_DEGREE)
        check_int(self.n_candidates, "n_candidates", owner, 1, MAX_PLAN_CANDIDATES)
        check_int(self.reference_every, "reference_every", owner, 1)
        check_int(self.seed, "seed", owner, 0)
        for value in self.noise:
            check_float(value, "noise", owner, 0.0, low_inclusive=False)
        if self.min_height is not None:
            check_float(self.min_height, "min_height", owner, -np.inf)


@dataclass(frozen=True)
class Recorded:
    """Poses already recorded (``--from``): expected wrench and/or sensor-frame gravity with load index.

    wrench : ndarray of shape (n, 6) or None; gravity : (n, 3) or None; load : (n,) int or None
    """

    source: str
    wrench: np.ndarray | None = None
    gravity: np.ndarray | None = None
    load: np.ndarray | None = None

    @property
    def n_poses(self) -> int:
        arrays = [a for a in (self.wrench, self.gravity) if a is not None]
        return arrays[0].shape[0] if arrays else 0


@dataclass(frozen=True)
class DesignScore:
    """How good a design is: log det of its information (prior and recorded data included) and errors.

    prediction_error : RMS over the candidates of the calibration's prediction standard error,
        in units of one pose's reading noise (calibration objective)
    standard_errors : parameter name → standard error (payload objective: kg, m·kg, N, N m)
    """

    log_det: float
    prediction_error: float | None = None
    standard_errors: Mapping[str, float] = field(default_factory=dict)


@dataclass(frozen=True)
class Plan:
    """A planned experiment.

    Attributes
    ----------
    request, space, candidates : what was asked, the joint box, the candidates
    configuration, load : ndarray of shape (n_poses,), the designed poses (candidate configuration, load)
    random_configuration, random_load : the random design compared with
    reference : int, the candidate configuration used as reference pose
    steps : execution order (see :mod:`ftcal.plan.order`)
    planned, random, recorded : DesignScore of the plan, of the random design, and of the data before
        either (prior + ``--from`` data)
    n_parameters, n_excited : size of the information matrix and how many directions the
        candidates can excite at all
    n_recorded : poses of the ``--from`` data
    travel, random_travel : joint-space travel (rad) of the plan and of the random design in the same order
    """

    request: PlanRequest
    space: JointSpace
    candidates: Candidates
    configuration: np.ndarray
    load: np.ndarray
    random_configuration: np.ndarray
    random_load: np.ndarray
    reference: int
    steps: list[Step]
    planned: DesignScore
    random: DesignScore
    recorded: DesignScore
    n_parameters: int
    n_excited: int
    n_recorded: int
    travel: float
    random_travel: float

    def table(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """The rows in execution order: joints (n, n_dofs), load (n,), reference flag (n,), wrench (n, 6)."""
        config = np.array([self.reference if s.reference else self.configuration[s.pose] for s in self.steps])
        load = np.array([s.load for s in self.steps], dtype=np.int64)
        return (self.candidates.q[config], load, np.array([s.reference for s in self.steps]),
                self.candidates.wrench[config, load])


def _rows(request: PlanRequest, candidates: Candidates, config: np.ndarray, load: np.ndarray,
          scaling: WrenchScaling | None) -> np.ndarray:
    if scaling is not None:
        return calibration_rows(candidates.wrench[config, load], request.degree, scaling)
    return payload_rows(candidates.gravity[config], load, candidates.n_loads, request.noise)


def _recorded_rows(request: PlanRequest, recorded: Sequence[Recorded], n_loads: int,
                   scaling: WrenchScaling | None, p: int) -> np.ndarray:
    parts = [np.zeros((0, 1 if scaling is not None else 6, p))]
    for data in recorded:
        if scaling is not None:
            if data.wrench is None:
                raise ParameterError('recorded', f"{{recorded}} {data.source}: no expected wrench columns Fx..Tz, which a "
                                 f"calibration plan needs.")
            parts.append(calibration_rows(data.wrench, request.degree, scaling))
        else:
            if data.gravity is None:
                raise ParameterError('recorded', f"{{recorded}} {data.source}: no joint columns of the robot, which a payload "
                                 f"plan needs for the sensor's orientation.")
            load = np.zeros(data.n_poses, dtype=np.int64) if data.load is None else data.load
            if n_loads > 1 and data.load is None:
                raise ParameterError(('recorded', 'load'), f"{{recorded}} {data.source}: no 'load' column, and {n_loads} loads are given; "
                                 f"add a column with the 0-based {{load}} index of each row.")
            if load.size and (load.min() < 0 or load.max() >= n_loads):
                raise ParameterError(('recorded', 'load'), f"{{recorded}} {data.source}: column 'load' must hold {{load}} indices 0..{n_loads - 1}.")
            parts.append(payload_rows(data.gravity, load, n_loads, request.noise))
    return np.concatenate(parts)


def _score(request: PlanRequest, start: np.ndarray, added: np.ndarray, all_rows: np.ndarray,
           names: tuple[str, ...]) -> DesignScore:
    total = start + information(added)
    inverse = np.linalg.inv(total)
    if request.objective == "calibration":
        # prediction variance of one pose, per unit noise: φᵀ M⁻¹ φ (the same for every output axis)
        flat = all_rows[:, 0, :]
        variance = ((flat @ inverse) * flat).sum(axis=1)
        return DesignScore(log_det(total), prediction_error=float(np.sqrt(np.mean(np.maximum(variance, 0)))))
    errors = dict(zip(names, np.sqrt(np.maximum(np.diag(inverse), 0.0)).tolist()))
    return DesignScore(log_det(total), standard_errors=errors)


def design_experiment(robot: RobotModel, request: PlanRequest, recorded: Sequence[Recorded] = ()) -> Plan:
    """Design ``request.n_poses`` poses, ordered for execution, and score them against a random design.

    Parameters
    ----------
    robot : RobotModel
        With its F/T sensor (and any permanent payloads); the loads come from ``request``.
    request : PlanRequest
    recorded : sequence of Recorded
        Poses already recorded (``--from``): the design starts from their information.

    Returns
    -------
    Plan

    Raises
    ------
    FtcalError
        Bad joints or ranges, fewer candidates than poses, nothing identifiable, recorded
        data without what the objective needs.

    Examples
    --------
    >>> from ftcal.robot import RobotModel, parse_payload_spec
    >>> from ftcal.sim.plan_arm import ARM_URDF
    >>> robot = RobotModel.from_text(ARM_URDF)
    >>> plan = design_experiment(robot, PlanRequest((None, parse_payload_spec("tool:2@0,0,0.05")), 12,
    ...                                           n_candidates=500))
    >>> plan.planned.log_det > plan.random.log_det
    True
    """
    sensor = request.sensor or _only_sensor(robot)
    _check_loads_beyond(robot, sensor, request)
    _check_work(request)
    space = joint_space(robot, sensor, request.base, ranges=request.ranges, fixed=request.fixed)
    rng = np.random.default_rng(request.seed)
    candidates = candidate_poses(robot, sensor, space, request.loads, request.n_candidates, rng,
                                 base=request.base, min_height=request.min_height)
    n_available = candidates.n_configurations * candidates.n_loads
    if request.n_poses > n_available:
        where = f" with the sensor above {{min_height}} {request.min_height:g} m" if request.min_height is not None else ""
        raise ParameterError(('poses', 'candidates', 'min_height'), f"{{poses}} {request.n_poses}: only {n_available} candidate poses ({candidates.n_configurations} "
                         f"configurations{where} x {candidates.n_loads} load(s)); raise {{candidates}} or lower {{poses}}.")
    # Many small products: multi-threaded BLAS only spins (see ftcal.runtime.threads).
    with single_threaded_blas():
        return _design(request, recorded, space, candidates, rng)


def _design(request: PlanRequest, recorded: Sequence[Recorded], space: JointSpace, candidates: Candidates,
            rng: np.random.Generator) -> Plan:
    n_loads = candidates.n_loads
    config = np.repeat(np.arange(candidates.n_configurations), n_loads)
    load = np.tile(np.arange(n_loads), candidates.n_configurations)
    # The payload objective needs gravity, not the wrench: a constant wrench is its rank check's business.
    scaling = WrenchScaling.of(candidates.wrench.reshape(-1, 6)) if request.objective == "calibration" else None
    rows = _rows(request, candidates, config, load, scaling)
    p = rows.shape[-1]
    total = information(rows)
    n_excited = excited_rank(total)
    names: tuple[str, ...] = ()
    if request.objective == "payload":
        names = payload_parameter_names(n_loads)
        if n_excited < p:
            missing = undetermined(total, names)
            raise FtcalError(f"nothing to plan for: no pose of these joints and loads determines "
                             f"{', '.join(missing[:6])} (rank {n_excited} of {p}); free a joint that tilts "
                             f"the sensor, or check the loads.")
    recorded_rows = _recorded_rows(request, recorded, n_loads, scaling, p)
    start = prior(rows) + information(recorded_rows)
    if request.objective == "payload":
        features = np.column_stack([np.ones(config.size), candidates.gravity[config]])
        chosen = greedy_design_factored(features, load, payload_blocks(n_loads, request.noise),
                                        request.n_poses, start)
    else:
        chosen = greedy_design(rows, request.n_poses, start)
    baseline = random_design(rows.shape[0], request.n_poses, rng)
    free = space.free_values(candidates.q)
    span = np.where(space.upper > space.lower, space.upper - space.lower, 1.0)
    reference = int(np.argmin(np.linalg.norm((free - 0.5 * (space.lower + space.upper)) / span, axis=1)))
    loads_order = list(range(n_loads))
    steps = execution_order(free[config[chosen]], load[chosen], free[reference], request.reference_every,
                            loads_order)
    random_steps = execution_order(free[config[baseline]], load[baseline], free[reference],
                                   request.reference_every, loads_order)
    return Plan(request, space, candidates, config[chosen], load[chosen], config[baseline], load[baseline],
                reference, steps,
                planned=_score(request, start, rows[chosen], rows, names),
                random=_score(request, start, rows[baseline], rows, names),
                recorded=_score(request, start, rows[:0], rows, names),
                n_parameters=p, n_excited=n_excited, n_recorded=recorded_rows.shape[0],
                travel=travel(free[config[chosen]], free[reference], steps),
                random_travel=travel(free[config[baseline]], free[reference], random_steps))


def _check_work(request: PlanRequest) -> None:
    """Refuse a design whose arithmetic would run for many minutes, saying what to lower (before any work)."""
    from math import comb

    n_loads = len(request.loads)
    if request.objective == "payload":
        p, r = 6 + 4 * n_loads, 6
    else:
        p, r = comb(6 + request.degree, 6), 1
    rows = request.n_candidates * n_loads * r
    work = rows * p * p + float(p) ** 3
    if work <= MAX_PLAN_WORK:
        return
    fits = int((MAX_PLAN_WORK - float(p) ** 3) / (n_loads * r * p * p))
    lower = (f"lower {{candidates}} to {fits} or less, or {{degree}}" if fits >= request.n_poses
             else "lower {degree}")
    raise ParameterError(('degree', 'candidates'), f"{{degree}} {request.degree} with {request.n_candidates} candidate configurations x {n_loads} "
                     f"load(s): {p} parameters, about {work:.1e} operations (the limit is {MAX_PLAN_WORK:.0e}, "
                     f"minutes of CPU); {lower}.")


def _check_loads_beyond(robot: RobotModel, sensor: str, request: PlanRequest) -> None:
    """Refuse a load the sensor cannot feel: one attached on the base side of the sensor's joint."""
    beyond = set(robot.links_beyond(robot.sensor(sensor), request.base))
    model = robot.model
    for k, load in enumerate(request.loads):
        if load is None:
            continue
        if not model.isFrameNameUsed(load.frame):
            raise ParameterError('load', f"{{load}} {load.name or load.frame}: URDF {robot.source} has no link or frame named "
                             f"{load.frame!r}.")
        link = model.getLinkName(model.getFrameLink(model.getFrameIndex(load.frame)))
        if link not in beyond:
            raise ParameterError('load', f"{{load}} {load.name or load.frame}: {load.frame!r} is on the base side of sensor "
                             f"{sensor!r} (link {link!r}); the sensor does not carry it. Attach loads to a link "
                             f"beyond the sensor: {', '.join(sorted(beyond)[:6])}.")


def _only_sensor(robot: RobotModel) -> str:
    robot.require_ft_sensors()
    if len(robot.ft_sensors) > 1:
        raise ParameterError('sensor', f"URDF {robot.source} has {len(robot.ft_sensors)} F/T sensors; choose one with {{sensor}} "
                         f"({', '.join(s.name for s in robot.ft_sensors)}).")
    return robot.ft_sensors[0].name
