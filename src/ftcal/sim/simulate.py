"""The simulate step: the recordings an experiment plan gives on a robot, and their truth (`ftcal simulate`).

It lives in ``sim`` with the simulated robot and sensor it drives (the step layer, ``workflow``, sits
below ``sim``); the command parses its options, calls :func:`simulate` and prints the result, and
Python users call the same function. Messages name the parameters; the CLI writes them as flags.
"""

from __future__ import annotations

import dataclasses
import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ..runtime.atomic import output_folder
from ..runtime.errors import FtcalError, ParameterError
from ..workflow.result import StepResult


@dataclass(repr=False)
class SimulationResult(StepResult):
    """What :func:`simulate` wrote.

    Attributes
    ----------
    sensor : the simulated F/T sensor's name
    channels : ``"wrench"`` or ``"raw"``
    temperature : sensor temperature at the start and end of the session, degC
    mistake, mistake_deg : the mounting mistake simulated (``"none"``, ``"sign"``, ``"swap-xy"``, ``"rotate-z"``)
    recordings : one dict per recording (name, holds, duration_s, n_samples, load, ...), as in truth.json
    files : the files and folders written
    truth : the content of truth.json
    """

    sensor: str
    channels: str
    temperature: tuple[float, float]
    mistake: str
    mistake_deg: float
    recordings: list
    files: list
    truth: dict

    def summary(self) -> str:
        lines = [f"{rec['name']}: {len(rec['holds'])} poses, {rec['duration_s']:.1f} s, {rec['n_samples']} F/T "
                 f"samples, load {rec['load']}" for rec in self.recordings]
        mistake = "" if self.mistake == "none" else f"; mounting mistake: {self.mistake}" + (
            f" {self.mistake_deg:g} deg" if self.mistake == "rotate-z" else "")
        lines.append(f"sensor {self.sensor}: {self.channels} channels, temperature {self.temperature[0]:g} -> "
                     f"{self.temperature[1]:g} degC{mistake}")
        lines.append("wrote " + ", ".join(self.files))
        return "\n".join(lines)

    def to_dict(self) -> dict:
        from ..workflow.result import plain

        return plain({f.name: getattr(self, f.name) for f in dataclasses.fields(self) if f.name != "truth"})


def _sensor_spec(sensor_file, *, noise=None, nonlinearity=None, crosstalk=None, drift=None):
    """The :class:`~ftcal.sim.sensor_model.SensorSpec`: the defaults, or ``sensor_file`` (a SensorSpec, or a
    JSON file holding a truth.json's sensor.spec or that object alone), then the overrides."""
    from ..core.limits import MAX_TEXT_FILE_BYTES
    from ..runtime.inputs import check_input_file
    from .sensor_model import SensorSpec, spec_from_json

    spec = SensorSpec()
    if isinstance(sensor_file, SensorSpec):
        spec = sensor_file
    elif sensor_file is not None:
        try:
            path = check_input_file(Path(sensor_file), "{sensor_file}", max_bytes=MAX_TEXT_FILE_BYTES)
            try:
                text = path.read_text(encoding="utf-8")
            except (OSError, UnicodeDecodeError) as exc:
                raise FtcalError(f"{{sensor_file}} {path}: cannot read it ({exc}).") from None
            spec = spec_from_json(text, f"{{sensor_file}} {path}")
        except ParameterError:
            raise
        except FtcalError as exc:
            raise ParameterError("sensor_file", str(exc)) from None
    changes = {}
    if noise is not None:
        changes["noise"] = noise
    if nonlinearity is not None:
        if nonlinearity < 0:
            raise ParameterError("nonlinearity", f"{{nonlinearity}} {nonlinearity:g}: must be >= 0.")
        changes["quadratic"], changes["cubic"] = spec.quadratic * nonlinearity, spec.cubic * nonlinearity
    if crosstalk is not None:
        changes["crosstalk"] = crosstalk
    if drift is not None:
        changes["ramp"], changes["walk"] = drift
    return dataclasses.replace(spec, **changes).check()


def simulate(plan: str | os.PathLike, *, output: str | os.PathLike, urdf: str | os.PathLike | None = None,
             robot: Any = None, ft_joint: str | None = None, ft_frame: str | None = None, payload: Sequence[str] = (),
             base: str | None = None, sensor: str | None = None, load: Sequence[Any] = (), hold: float = 2.0,
             speed: float = 0.3, rate: float = 250.0, formats: Sequence[str] = ("bag",), channels: str = "wrench",
             sensor_file: Any = None, noise: float | None = None, nonlinearity: float | None = None,
             crosstalk: float | None = None, drift: tuple[float, float] | None = None,
             temperature: tuple[float, float] = (28.0, 34.0), mistake: tuple[str, float] = ("none", 0.0),
             seed: int = 0) -> SimulationResult:
    """Simulate the recordings ``plan`` gives on a robot: one recording per load, loads.toml and truth.json.

    Parameters
    ----------
    plan : `ftcal plan` CSV, or any table with one column per joint (rad) and an optional ``load`` column
    output : folder for the recordings, loads.toml and truth.json
    urdf, robot, ft_joint, ft_frame, payload : the robot: a URDF, or ``robot`` (a
        :class:`~ftcal.robot.model.RobotModel`, or the name of an icub-models robot), with an F/T sensor declared
        on a fixed joint and payload specs attached (as :func:`ftcal.workflow.sources.robot_model`)
    base : fixed base frame
    sensor : the F/T sensor (default: the only one)
    load : what the plan's load index k mounts: a :class:`~ftcal.robot.payloads.Payload`, a spec
        ``FRAME:MASS[@X,Y,Z][/IXX,IYY,IZZ]``, or None / ``"none"`` (default: nothing mounted)
    hold, speed, rate : hold at each pose (s), fastest joint speed as a fraction of the URDF limit, F/T rate (Hz)
    formats : ``"bag"`` and/or ``"table"``
    channels : ``"wrench"`` (the driver's factory-calibrated wrench) or ``"raw"`` (ADC counts)
    sensor_file : a :class:`~ftcal.sim.sensor_model.SensorSpec` or a JSON file of one; the next four override it
    noise, nonlinearity, crosstalk, drift : noise std (counts), scale of the nonlinear terms, coupling std,
        (ramp, walk) of the bias
    temperature : sensor temperature at the start and end of the session, degC
    mistake : (kind, degrees) of a mounting mistake: none, sign, swap-xy, rotate-z
    seed : random seed; the same seed writes the same bytes

    Returns
    -------
    SimulationResult

    Raises
    ------
    FtcalError
        A robot without the sensor or a load's frame, a plan that does not fit the robot, an output that is a file.
    """
    from ..robot import RobotModel, parse_payload_spec
    from ..workflow.sources import robot_model
    from .robot_recording import SimulationConfig, check_session_size, read_waypoints, simulate_session

    out = Path(output)
    if out.exists() and not out.is_dir():
        raise ParameterError("output", f"{{output}} {out}: exists and is not a folder; give a folder for the "
                                       "recordings.")
    if isinstance(robot, RobotModel):
        model = robot.with_payloads([parse_payload_spec(s) for s in payload]) if payload else robot
    else:
        model = robot_model(urdf=urdf, robot=robot, ft_joint=ft_joint, ft_frame=ft_frame, payload=tuple(payload))
    model.require_ft_sensors()
    if sensor is None and len(model.ft_sensors) > 1:
        raise ParameterError("sensor", f"{{sensor}} is required: URDF {model.source} has {len(model.ft_sensors)} "
                                       f"F/T sensors ({', '.join(s.name for s in model.ft_sensors)}).")
    sensor_name = model.sensor(sensor).name if sensor else model.ft_sensors[0].name
    loads = tuple(None if spec is None or (isinstance(spec, str) and spec.strip().lower() == "none")
                  else parse_payload_spec(spec) if isinstance(spec, str) else spec for spec in (load or [None]))
    for mounted in loads:
        if mounted is not None and not model.model.isFrameNameUsed(mounted.frame):
            raise ParameterError("load", f"{{load}} {mounted.name}: URDF {model.source} has no link or frame named "
                                         f"{mounted.frame!r}.")
    spec = _sensor_spec(sensor_file, noise=noise, nonlinearity=nonlinearity, crosstalk=crosstalk, drift=drift)
    simulated = spec.draw(seed, *mistake)
    waypoints = read_waypoints(plan, model, len(loads))
    config = SimulationConfig(hold_s=hold, speed=speed, rate=rate, temperature_start=temperature[0],
                              temperature_end=temperature[1], channels=channels, seed=seed, formats=tuple(formats))
    check_session_size(model, waypoints, config)  # before the output folder is made
    session = simulate_session(model, sensor_name, waypoints, simulated, output_folder(out),
                               loads=loads, base=base, config=config)
    return SimulationResult(sensor_name, channels, tuple(temperature), simulated.mistake, simulated.mistake_deg,
                            list(session.truth["recordings"]), list(session.files), session.truth)
