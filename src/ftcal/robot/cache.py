"""On-disk cache of expected wrenches, next to the recording they belong to.

Files live in ``<recording>.ftcal-cache/expected-<key>.npz``. The key is the
sha256 of everything the result depends on: URDF text, attached payloads,
joint data (names and values), base frame, gravity and floating-base data.
Change any of them and the key changes, so a stale file is never read.
"""

from __future__ import annotations

import hashlib
import warnings
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np

from ..errors import FtcalWarning
from ..io.atomic import write_with
from .model import RobotModel

FORMAT = b"ftcal-expected-cache-v1"


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


def cache_path(recording: str | Path, key: str) -> Path:
    recording = Path(recording)
    return recording.parent / f"{recording.name}.ftcal-cache" / f"expected-{key[:32]}.npz"


def cached(recording: str | Path, key: str, sensors: Sequence[str],
           compute: Callable[[], np.ndarray]) -> np.ndarray:
    """The cached array for ``key`` if present and valid, else ``compute()`` (then stored)."""
    path = cache_path(recording, key)
    if path.is_file():
        try:
            with np.load(path, allow_pickle=False) as npz:
                if str(npz["key"]) == key and tuple(npz["sensors"]) == tuple(sensors):
                    return npz["wrenches"]
        except (OSError, ValueError, KeyError):
            pass  # unreadable cache file: recompute and overwrite it
    wrenches = compute()

    def write(tmp: Path) -> None:
        with open(tmp, "wb") as fh:
            np.savez(fh, key=np.array(key), sensors=np.array(list(sensors)), wrenches=wrenches)

    try:
        write_with(path, write)
    except OSError as exc:
        warnings.warn(f"could not write the expected-wrench cache {path}: {exc}", FtcalWarning, stacklevel=2)
    return wrenches
