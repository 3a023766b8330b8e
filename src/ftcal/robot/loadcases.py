"""Load cases: which payloads were attached during which recording (docs/formats.md §6).

A TOML file (``--payload-file``) describes them::

    # attached in every recording (e.g. the metal supports)
    [[payload]]
    frame = "r_forearm"
    mass = 0.4
    com = [0.0, 0.0, -0.05]               # optional, m, in frame coordinates
    inertia = [1e-4, 1e-4, 1e-4, 0, 0, 0]  # optional, kg m², about the COM

    # named load cases; a recording belongs to the load that lists its file
    # name or stem, or whose name is its stem or one of its folder names
    [[load]]
    name = "r5kg"
    recordings = ["grid_1.mat"]           # optional
    [[load.payload]]
    frame = "r_forearm"
    mass = 5.0

    # the paper's folder convention l<x>kg-r<y>kg: x kg on the left mount,
    # y kg on the right mount, masses read from the folder or file name
    [convention.left]
    frame = "l_forearm"
    com = [0.0, 0.0, -0.05]
    [convention.right]
    frame = "r_forearm"
    com = [0.0, 0.0, -0.05]

A file that declares load cases (``[[load]]`` or ``[convention.*]``) must name every
recording: one that matches no case is refused, with the known names and the nearest
match (a forgotten or mistyped case would otherwise get no payload, and the reference
wrench of a sensor with nothing else beyond it would be zero). A file with only
``[[payload]]`` entries applies them to every recording, each its own load case.
``[[case]]`` (with ``[[case.payload]]``) is the old spelling of ``[[load]]``: still read, with a notice.
"""

from __future__ import annotations

import difflib
import re
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..core.limits import MAX_TEXT_FILE_BYTES
from ..runtime.deprecation import old_spelling
from ..runtime.errors import FtcalError
from ..runtime.inputs import check_input_file
from .payloads import Payload

# The TOML array of load cases, and its old spelling (read with a notice).
LOAD_KEY, OLD_LOAD_KEY = "load", "case"
CONVENTION = re.compile(r"^l(?P<left>\d+(?:\.\d+)?)kg-r(?P<right>\d+(?:\.\d+)?)kg$")
# A folder name that was meant to follow the convention (for the message when it does not quite).
CONVENTION_LIKE = re.compile(r"^l\d.*kg", re.IGNORECASE)


@dataclass(frozen=True)
class LoadCase:
    """The payloads of one recording; ``name`` is its group label."""

    name: str
    payloads: tuple[Payload, ...] = ()


@dataclass(frozen=True)
class Mount:
    """Where the paper's weights go on one arm (mass comes from the folder name)."""

    frame: str
    com: tuple[float, float, float] = (0.0, 0.0, 0.0)
    inertia: tuple[float, ...] = (0.0,) * 6


@dataclass(frozen=True)
class LoadCaseConfig:
    """Payloads always attached, named cases, and the l<x>kg-r<y>kg convention."""

    payloads: tuple[Payload, ...] = ()
    cases: tuple[tuple[str, tuple[str, ...], tuple[Payload, ...]], ...] = ()
    mounts: dict[str, Mount] = field(default_factory=dict)
    source: str = ""

    def resolve(self, recording: str | Path, extra: tuple[Payload, ...] = ()) -> LoadCase:
        """The load case of ``recording``, with the always-on and ``extra`` payloads added."""
        path = Path(recording)
        always = (*self.payloads, *extra)
        for name, files, payloads in self.cases:
            if path.name in files or path.stem in files:
                return LoadCase(name, (*always, *payloads))
        components = [path.stem, *(p.name for p in path.parents if p.name)]
        for component in components:
            for name, _, payloads in self.cases:
                if component == name:
                    return LoadCase(name, (*always, *payloads))
        for component in components:
            match = CONVENTION.match(component)
            if match:
                return LoadCase(component, (*always, *self._convention(match, path)))
        if self.cases or self.mounts:
            raise FtcalError(self._unnamed(path, components))
        return LoadCase(path.stem, always)

    def _unnamed(self, path: Path, components: list[str]) -> str:
        """Why ``path`` matches no declared load case: the names known and the nearest one."""
        names = [name for name, _, _ in self.cases]
        files = [f for _, recordings, _ in self.cases for f in recordings]
        known = ", ".join(repr(n) for n in names) or "none"
        if self.mounts:
            known += " and folder or file names l<x>kg-r<y>kg"
        ratio, best = max(((difflib.SequenceMatcher(None, given, c).ratio(), c)
                           for given in (path.name, *components) for c in names + files), default=(0.0, None))
        hint = f"; nearest: {best!r}" if ratio >= 0.6 else ""
        almost = next((c for c in components if self.mounts and CONVENTION_LIKE.match(c)), None)
        if almost is not None and not hint:
            hint = f"; {almost!r} is not of the form l<x>kg-r<y>kg"
        where = f"Payload file {self.source}" if self.source else "The payload file"
        return (f"{where}: recording {path} matches no load case (loads: {known}{hint}); name it in a "
                f"[[load]]'s recordings, or declare a load without payload for an unloaded recording.")

    def _convention(self, match: re.Match, path: Path) -> tuple[Payload, ...]:
        out = []
        for side in ("left", "right"):
            mass = float(match.group(side))
            if mass == 0:
                continue
            mount = self.mounts.get(side)
            if mount is None:
                raise FtcalError(f"Recording {path} follows the l<x>kg-r<y>kg convention but the payload file "
                                 f"has no [convention.{side}] section saying where the {side} weight goes.")
            out.append(Payload(mount.frame, mass, mount.com, mount.inertia,  # type: ignore[arg-type]
                               name=f"{side} {match.group(0)}"))
        return tuple(out)


def load_case_config(path: str | Path) -> LoadCaseConfig:
    """Read a payload/load-case TOML file (see the module docstring)."""
    path = check_input_file(path, "payload file", max_bytes=MAX_TEXT_FILE_BYTES)
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise FtcalError(f"Payload file {path}: no such file.") from None
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError) as exc:
        raise FtcalError(f"Payload file {path}: cannot read it as TOML ({exc}).") from None
    unknown = set(data) - {"payload", LOAD_KEY, OLD_LOAD_KEY, "convention"}
    if unknown:
        raise FtcalError(f"Payload file {path}: unknown section(s) {', '.join(sorted(unknown))}; "
                         f"expected payload, load, convention.")
    key = LOAD_KEY
    if OLD_LOAD_KEY in data:
        if LOAD_KEY in data:
            raise FtcalError(f"Payload file {path}: both [[load]] and [[case]] (its old spelling); "
                             "write every load case as [[load]].")
        old_spelling(f"Payload file {path}: [[case]]", "[[load]] (with [[load.payload]])")
        key = OLD_LOAD_KEY
    payloads = tuple(_payload(p, path, f"payload[{i}]") for i, p in enumerate(_list(data, "payload", path)))
    cases = []
    for i, case in enumerate(_list(data, key, path)):
        where = f"{LOAD_KEY}[{i}]"  # the new spelling in messages and payload names, either way
        name = case.get("name")
        if not isinstance(name, str) or not name:
            raise FtcalError(f"Payload file {path}: {where} needs a non-empty 'name'.")
        files = case.get("recordings", [])
        if not isinstance(files, list) or not all(isinstance(f, str) for f in files):
            raise FtcalError(f"Payload file {path}: {where}.recordings must be a list of file names.")
        items = tuple(_payload(p, path, f"{where}.payload[{j}]") for j, p in enumerate(_list(case, "payload", path)))
        cases.append((name, tuple(files), items))
    mounts = {}
    convention = data.get("convention", {})
    if not isinstance(convention, dict):
        raise FtcalError(f"Payload file {path}: 'convention' must be a table ([convention.left], [convention.right]).")
    for side, spec in convention.items():
        if side not in ("left", "right") or not isinstance(spec, dict):
            raise FtcalError(f"Payload file {path}: [convention.{side}] must be convention.left or convention.right.")
        probe = _payload({**spec, "mass": 1.0}, path, f"convention.{side}")
        mounts[side] = Mount(probe.frame, probe.com, probe.inertia)
    return LoadCaseConfig(payloads, tuple(cases), mounts, str(path))


def _list(table: dict, key: str, path: Path) -> list[dict]:
    items = table.get(key, [])
    if not isinstance(items, list) or not all(isinstance(i, dict) for i in items):
        raise FtcalError(f"Payload file {path}: '{key}' must be an array of tables ([[{key}]]).")
    return items


def _is(value: Any, want) -> bool:
    """TOML type check: booleans are not numbers."""
    def number(v: Any) -> bool:
        return isinstance(v, (int, float)) and not isinstance(v, bool)
    if want == "number":
        return number(value)
    if want == "numbers":
        return isinstance(value, list) and all(number(v) for v in value)
    return isinstance(value, want)


def _payload(spec: dict[str, Any], path: Path, where: str) -> Payload:
    unknown = set(spec) - {"frame", "mass", "com", "inertia", "name"}
    if unknown:
        raise FtcalError(f"Payload file {path}: {where} has unknown key(s) {', '.join(sorted(unknown))}.")
    for key, want in (("frame", str), ("name", str), ("mass", "number"), ("com", "numbers"), ("inertia", "numbers")):
        if key in spec and not _is(spec[key], want):
            kind = {"number": "a number", "numbers": "a list of numbers", str: "a string"}[want]
            raise FtcalError(f"Payload file {path}: {where}.{key} must be {kind}; got {spec[key]!r}.")
    try:
        inertia = tuple(float(v) for v in spec.get("inertia", (0.0,) * 6))
        if len(inertia) == 3:
            inertia = (*inertia, 0.0, 0.0, 0.0)
        return Payload(str(spec.get("frame", "")), float(spec.get("mass", float("nan"))),
                       tuple(float(v) for v in spec.get("com", (0.0, 0.0, 0.0))),  # type: ignore[arg-type]
                       inertia, name=str(spec.get("name", where)))  # type: ignore[arg-type]
    except (TypeError, ValueError):
        raise FtcalError(f"Payload file {path}: {where} must have a frame name and numbers for "
                         f"mass, com [x, y, z] and inertia.") from None
    except FtcalError as exc:
        raise FtcalError(f"Payload file {path}: {where}: {exc}") from None
