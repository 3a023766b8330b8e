"""On-disk cache of expected wrenches, in a per-user cache folder.

Entries are ``<cache dir>/expected-<key>.npz``; the cache dir is ``--cache-dir`` or
``$XDG_CACHE_HOME/ftcal`` (``~/.cache/ftcal`` by default, the XDG convention), never
the user's data folder. The key is the sha256 of everything the result depends on:
URDF text, attached payloads, joint data (names and values), base frame, gravity and
floating-base data. Change any of them and the key changes, so a stale entry is never read.

Each entry also stores the sha256 of its own content (key, sensor names, shape and
values). An entry is used only if it verifies: readable, the right key, sensors and
shape, finite, and content matching its digest. Anything else is ignored with a warning
naming the file, and recomputed. A cache that cannot be written is a warning, never a
failure of the computation it would have saved.
"""

from __future__ import annotations

import hashlib
import os
import warnings
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np

from ..runtime.atomic import write_with
from ..runtime.errors import FtcalError, FtcalWarning, ParameterWarning
from ..runtime.inputs import check_input_file
from .model import RobotModel

FORMAT = b"ftcal-expected-cache-v1"
ENTRY_FORMAT = "ftcal-expected-cache-entry-v2"


def default_cache_dir() -> Path:
    """``$XDG_CACHE_HOME/ftcal``, or ``~/.cache/ftcal`` when XDG_CACHE_HOME is unset or relative."""
    base = os.environ.get("XDG_CACHE_HOME", "")
    if not base or not os.path.isabs(base):
        base = os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base) / "ftcal"


def cache_key(robot: RobotModel, arrays: Sequence[np.ndarray | None], options: Sequence[object]) -> str:
    """sha256 hex digest of the model, payloads, joint arrays and options."""
    h = hashlib.sha256(FORMAT)
    h.update(robot.urdf_text.encode("utf-8"))
    for payload in robot.payloads:
        h.update(payload.key().encode("utf-8"))
    for declaration in robot.declared:
        h.update(declaration.key().encode("utf-8"))
    h.update(repr(robot.joint_names).encode("utf-8"))
    for arr in arrays:
        if arr is None:
            h.update(b"none")
            continue
        a = np.ascontiguousarray(arr, dtype=np.float64)
        h.update(repr(a.shape).encode("ascii"))
        h.update(a.tobytes())
    h.update(repr(tuple(options)).encode("utf-8"))
    return h.hexdigest()


def cache_path(key: str, cache_dir: str | Path | None = None) -> Path:
    """Where the entry for ``key`` lives (``cache_dir`` None: :func:`default_cache_dir`)."""
    folder = Path(cache_dir) if cache_dir is not None else default_cache_dir()
    return folder / f"expected-{key}.npz"


def content_digest(key: str, sensors: Sequence[str], wrenches: np.ndarray) -> str:
    """sha256 of an entry's content: its key, sensor names, array shape and float64 values."""
    h = hashlib.sha256(ENTRY_FORMAT.encode("ascii"))
    h.update(key.encode("ascii"))
    h.update(repr(tuple(sensors)).encode("utf-8"))
    values = np.ascontiguousarray(wrenches, dtype="<f8")
    h.update(repr(values.shape).encode("ascii"))
    h.update(values.tobytes())
    return h.hexdigest()


def cached(key: str, sensors: Sequence[str], n_samples: int, compute: Callable[[], np.ndarray],
           cache_dir: str | Path | None = None) -> np.ndarray:
    """The verified cache entry for ``key``, else ``compute()`` (then stored).

    Parameters
    ----------
    key : :func:`cache_key` of everything the result depends on
    sensors : names of the robot's F/T sensors, in the order of the result's second axis
    n_samples : number of samples the result has
    compute : returns the expected wrenches, ndarray of shape (n_samples, n_sensors, 6), N and N·m
    cache_dir : folder of the entries (None: :func:`default_cache_dir`)

    Returns
    -------
    ndarray of shape (n_samples, n_sensors, 6)
    """
    path = cache_path(key, cache_dir)
    shape = (n_samples, len(sensors), 6)
    if os.path.lexists(path):
        try:  # a FIFO or device planted in the cache folder is refused, never opened
            check_input_file(path, "expected-wrench cache entry")
            wrenches, problem = _verified(path, key, sensors, shape)
        except FtcalError as exc:
            wrenches, problem = None, str(exc)
        if problem is None:
            return wrenches
        warnings.warn(f"ignoring the expected-wrench cache entry {path} ({problem}); recomputing it.",
                      FtcalWarning, stacklevel=2)
    wrenches = compute()

    def write(tmp: Path) -> None:
        with open(tmp, "wb") as fh:
            np.savez(fh, format=np.array(ENTRY_FORMAT), key=np.array(key), sensors=np.array(list(sensors)),
                     wrenches=wrenches, sha256=np.array(content_digest(key, sensors, wrenches)))

    try:
        write_with(path, write)
    except (FtcalError, OSError) as exc:
        warnings.warn(ParameterWarning(("cache_dir", "no_cache"), f"could not write the expected-wrench cache entry "
                                       f"{path}: {exc} (use {{cache_dir}} to choose a writable folder, or "
                                       "{no_cache})."), stacklevel=2)
    return wrenches


def _verified(path: Path, key: str, sensors: Sequence[str],
              shape: tuple[int, int, int]) -> tuple[np.ndarray | None, str | None]:
    """(wrenches, None) when the entry at ``path`` verifies, else (None, what is wrong)."""
    try:
        with open(path, "rb") as fh, np.load(fh, allow_pickle=False) as npz:
            fields = {name: npz[name] for name in ("format", "key", "sensors", "wrenches", "sha256")}
    except KeyError as exc:
        return None, f"no field {exc}"
    except Exception as exc:  # noqa: BLE001 - zip, npy and OS errors of a damaged file
        return None, f"unreadable: {type(exc).__name__}"
    if str(fields["format"]) != ENTRY_FORMAT or str(fields["key"]) != key:
        return None, "written for other inputs"
    if tuple(map(str, fields["sensors"].tolist())) != tuple(sensors):
        return None, "other sensors"
    wrenches = fields["wrenches"]
    if wrenches.shape != shape or wrenches.dtype != np.float64:
        return None, f"shape {wrenches.shape} {wrenches.dtype}, expected {shape} float64"
    if not np.isfinite(wrenches).all():
        return None, "non-finite values"
    if str(fields["sha256"]) != content_digest(key, sensors, wrenches):
        return None, "content does not match its digest"
    return wrenches, None
