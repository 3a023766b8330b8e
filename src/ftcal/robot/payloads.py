"""Payloads: extra rigid bodies (weights, supports) attached to robot links.

A payload is a mass with a centre of mass and a rotational inertia, fixed to a
link or to any frame of the URDF. Payloads are described without editing the
URDF: on the command line (:func:`parse_payload_spec`) or in a TOML file
(:mod:`ftcal.robot.loadcases`), and attached to the iDynTree model in memory
(:meth:`ftcal.robot.model.RobotModel.with_payloads`).

Spec string syntax (one payload)::

    FRAME:MASS[@X,Y,Z][/IXX,IYY,IZZ[,IXY,IXZ,IYZ]]

``MASS`` in kg; ``X,Y,Z`` the centre of mass in metres, in FRAME coordinates
(default: the frame origin); the inertia in kg m² about the centre of mass, in
FRAME axes (default: zero, a point mass). Example: ``r_forearm:2.5@0.08,0,-0.01``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from ..core.limits import MAX_LOAD_DISTANCE, MAX_LOAD_MASS
from ..runtime.errors import FtcalError

Vector3 = tuple[float, float, float]
Inertia6 = tuple[float, float, float, float, float, float]


@dataclass(frozen=True)
class Payload:
    """A rigid body fixed to ``frame`` (a link or any frame of the URDF).

    Attributes
    ----------
    frame : link or frame name it is attached to
    mass : kg, > 0
    com : centre of mass in ``frame`` coordinates, metres
    inertia : (ixx, iyy, izz, ixy, ixz, iyz) about the centre of mass, ``frame`` axes, kg m²
    name : label used in messages (optional)
    """

    frame: str
    mass: float
    com: Vector3 = (0.0, 0.0, 0.0)
    inertia: Inertia6 = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    name: str = ""

    def __post_init__(self) -> None:
        label = self.name or self.frame
        if not self.frame:
            raise FtcalError(f"Payload {label!r} needs the name of the link or frame it is attached to.")
        if not (isinstance(self.mass, (int, float)) and math.isfinite(self.mass) and self.mass > 0):
            raise FtcalError(f"Payload {label!r}: mass must be a finite number > 0 kg; got {self.mass!r}.")
        if len(self.com) != 3 or not all(math.isfinite(v) for v in self.com):
            raise FtcalError(f"Payload {label!r}: com must be three finite numbers (x, y, z in m); got {self.com!r}.")
        if self.mass > MAX_LOAD_MASS:
            raise FtcalError(f"Payload {label!r}: mass {self.mass:g} kg is beyond {MAX_LOAD_MASS:g} kg; a typo?")
        if math.hypot(*self.com) > MAX_LOAD_DISTANCE:
            raise FtcalError(f"Payload {label!r}: centre of mass {math.hypot(*self.com):g} m from its frame is "
                             f"beyond {MAX_LOAD_DISTANCE:g} m; a typo?")
        if len(self.inertia) != 6 or not all(math.isfinite(v) for v in self.inertia):
            raise FtcalError(f"Payload {label!r}: inertia must be six finite numbers "
                             f"(ixx, iyy, izz, ixy, ixz, iyz); got {self.inertia!r}.")

    def key(self) -> str:
        """A canonical text form, for cache keys (full float precision)."""
        numbers = ",".join(repr(float(v)) for v in (self.mass, *self.com, *self.inertia))
        return f"{self.frame}:{numbers}"


def _numbers(text: str, what: str, spec: str, counts: tuple[int, ...]) -> tuple[float, ...]:
    try:
        values = tuple(float(v) for v in text.split(","))
    except ValueError:
        values = ()
    if len(values) not in counts:
        expected = " or ".join(str(c) for c in counts)
        raise FtcalError(f"Payload spec {spec!r}: {what} must be {expected} comma-separated numbers; got {text!r}.")
    return values


def parse_payload_spec(spec: str) -> Payload:
    """Parse ``FRAME:MASS[@X,Y,Z][/IXX,IYY,IZZ[,IXY,IXZ,IYZ]]`` into a :class:`Payload`."""
    frame, sep, rest = spec.strip().partition(":")
    if not sep or not frame or not rest:
        raise FtcalError(f"Payload spec {spec!r} must look like FRAME:MASS[@X,Y,Z][/IXX,IYY,IZZ[,IXY,IXZ,IYZ]], "
                         f"e.g. r_forearm:2.5@0.08,0,0.")
    rest, _, inertia_text = rest.partition("/")
    mass_text, _, com_text = rest.partition("@")
    (mass,) = _numbers(mass_text, "MASS", spec, (1,))
    com = _numbers(com_text, "the centre of mass @X,Y,Z", spec, (3,)) if com_text else (0.0, 0.0, 0.0)
    inertia: tuple[float, ...] = (0.0,) * 6
    if inertia_text:
        inertia = _numbers(inertia_text, "the inertia /IXX,IYY,IZZ[,IXY,IXZ,IYZ]", spec, (3, 6))
        inertia = (*inertia, 0.0, 0.0, 0.0)[:6]
    return Payload(frame.strip(), mass, com, inertia, name=spec.strip())  # type: ignore[arg-type]
