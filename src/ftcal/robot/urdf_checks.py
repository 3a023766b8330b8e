"""Checks of a URDF's structure and physics, made before iDynTree loads it.

A URDF is a file from someone else (a vendor, a colleague): it is not trusted.

* Structure: a URDF is a tree. A link that is the child of two joints, or a
  chain of joints that comes back to where it started (a kinematic loop), is
  refused naming the joints and links; otherwise the parser would pick one
  parent silently, or walk the loop.
* Joints: iDynTree (ftcal's kinematics) models fixed, revolute, continuous and
  prismatic joints only; a planar or floating joint is refused naming it, with
  the way round (it used to load as an empty model: "no F/T sensor" for a
  sensor declared with ``--ft-joint``).
* Physics: a mass or inertia entry that is not a finite number, a negative
  mass, or a negative diagonal moment is refused naming the link (the
  expected wrenches would be meaningless); an inertia tensor that is not
  positive semi-definite, or whose principal moments break the triangle
  inequality (I1 <= I2 + I3), is physically impossible but common in
  hand-written URDFs, and only affects rotating payloads: a warning names the link.
"""

from __future__ import annotations

import math
import warnings
import xml.etree.ElementTree as ET

import numpy as np

from ..runtime.errors import FtcalError, FtcalWarning

INERTIA_KEYS = ("ixx", "ixy", "ixz", "iyy", "iyz", "izz")
# Relative slack on the PSD and triangle tests: URDF inertias are printed with few digits.
_RELATIVE_TOLERANCE = 1e-6


class ImplausibleInertiaWarning(FtcalWarning):
    """A link's inertia tensor is not physically possible (not PSD, or breaks the triangle inequality)."""


def check_urdf(text: str, source: str) -> None:
    """Refuse or warn about a URDF's structure and inertial data (see the module docstring).

    Parameters
    ----------
    text : the URDF text
    source : names the file in messages

    Raises
    ------
    FtcalError
        Not XML, a link with two parent joints, a kinematic loop, a planar or floating joint, or a mass or
        inertia that is not a finite number (or a negative mass or moment).
    """
    try:
        root = ET.fromstring(text)
    except ET.ParseError as exc:
        raise FtcalError(f"URDF {source} does not parse: not valid XML ({exc}).") from None
    except RecursionError:
        raise FtcalError(f"URDF {source} is nested too deeply to be a URDF.") from None
    except LookupError as exc:  # <?xml encoding="..."?> naming no codec
        raise FtcalError(f"URDF {source} does not parse: unknown encoding ({exc}).") from None
    for tag in ("link", "joint"):
        for element in root.findall(tag):
            if not element.get("name"):
                raise FtcalError(f"URDF {source}: a <{tag}> element has no name attribute.")
    _check_tree(root, source)
    _check_joint_types(root, source)
    for link in root.findall("link"):
        _check_inertial(link, source)


def _check_tree(root: ET.Element, source: str) -> None:
    parent_of: dict[str, tuple[str, str]] = {}  # child link -> (parent link, joint)
    for joint in root.findall("joint"):
        parent, child = joint.find("parent"), joint.find("child")
        if parent is None or child is None:
            continue  # iDynTree names the missing element
        a, b, name = parent.get("link"), child.get("link"), joint.get("name")
        if b in parent_of:
            raise FtcalError(f"URDF {source}: link {b!r} is the child of two joints, {parent_of[b][1]!r} and "
                             f"{name!r}; a URDF is a tree (one parent joint per link).")
        parent_of[b] = (a, name)
    for start in parent_of:
        chain = [start]
        while (step := parent_of.get(chain[-1])) is not None:
            if step[0] in chain:
                loop = chain[chain.index(step[0]):] + [step[0]]
                raise FtcalError(f"URDF {source}: the joints form a kinematic loop through links "
                                 f"{' -> '.join(loop)}; a URDF is a tree.")
            chain.append(step[0])


JOINT_TYPES = ("fixed", "revolute", "continuous", "prismatic")


def _check_joint_types(root: ET.Element, source: str) -> None:
    for joint in root.findall("joint"):
        kind = joint.get("type")
        if kind in JOINT_TYPES:
            continue
        name = joint.get("name")
        parent, child = (joint.find(t) for t in ("parent", "child"))
        parent, child = (None if e is None else e.get("link") for e in (parent, child))
        if kind == "floating":
            way = (f"a floating joint is a floating base: remove it and link {parent!r}, so that {child!r} is the "
                   "root link (its motion is then the base's: give the IMU data)")
        elif kind == "planar":
            way = ("write the planar joint as two prismatic joints and a revolute one through intermediate links, "
                   "or fix it (type fixed) if it does not move in the recordings")
        else:
            way = f"use one of {', '.join(JOINT_TYPES)}"
        raise FtcalError(f"URDF {source}: joint {name!r} (from link {parent!r} to {child!r}) has type {kind!r}, "
                         f"which ftcal's kinematics (iDynTree) do not model: only {', '.join(JOINT_TYPES)} "
                         f"joints; {way}.")


def _number(element: ET.Element, key: str, what: str, link: str, source: str) -> float:
    text = element.get(key)
    try:
        value = float(text) if text is not None else 0.0
    except ValueError:
        value = math.nan
    if not math.isfinite(value):
        raise FtcalError(f"URDF {source}: link {link!r} has {what} {key}={text!r}; expected a finite number.")
    return value


def _check_inertial(link: ET.Element, source: str) -> None:
    inertial = link.find("inertial")
    if inertial is None:
        return
    name = link.get("name")
    mass_tag = inertial.find("mass")
    if mass_tag is not None:
        mass = _number(mass_tag, "value", "mass", name, source)
        if mass < 0:
            raise FtcalError(f"URDF {source}: link {name!r} has a negative mass ({mass} kg).")
    tag = inertial.find("inertia")
    if tag is None:
        return
    ixx, ixy, ixz, iyy, iyz, izz = (_number(tag, k, "inertia", name, source) for k in INERTIA_KEYS)
    if min(ixx, iyy, izz) < 0:
        raise FtcalError(f"URDF {source}: link {name!r} has a negative moment of inertia "
                         f"(ixx={ixx}, iyy={iyy}, izz={izz}).")
    moments = np.linalg.eigvalsh(np.array([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]]))
    slack = _RELATIVE_TOLERANCE * max(float(np.max(np.abs(moments))), 1e-300)
    if moments[0] < -slack:
        warnings.warn(f"URDF {source}: link {name!r} has an inertia tensor that is not positive semi-definite "
                      f"(principal moments {', '.join(f'{m:.4g}' for m in moments)}); it is physically "
                      "impossible, check the link's <inertia>.", ImplausibleInertiaWarning, stacklevel=3)
    elif moments[2] > moments[0] + moments[1] + slack:
        warnings.warn(f"URDF {source}: link {name!r} has principal moments {', '.join(f'{m:.4g}' for m in moments)} "
                      "that break the triangle inequality (the largest exceeds the sum of the others); it is "
                      "physically impossible, check the link's <inertia>.", ImplausibleInertiaWarning, stacklevel=3)
