"""Open any robot log: a suffix → reader registry.

:func:`read_recording` picks the reader by the file's suffix in
:data:`READERS`; a reader takes the path (and its own keyword options) and
returns a :class:`~ftcal.data.recording.Recording`. Adding a log format is one
module plus one line here. Today:

* YARP robot-logger ``.mat`` files, v7.3 (HDF5) and v5 (docs/formats.md §4), see
  :mod:`ftcal.data.logs_mat`;
* CSV/Parquet tables, one row per sample, see :mod:`ftcal.data.logs_table` for
  the column convention;
* ROS 1 ``.bag`` files, ROS 2 bag folders, ``.db3`` and ``.mcap`` files, see
  :mod:`ftcal.data.bags` (their reader takes ``topics=BagTopics(...)``).

``joint_units="deg"`` converts logged joint data from degrees to radians.
"""

from __future__ import annotations

import dataclasses
import importlib
from pathlib import Path
from typing import Any

import numpy as np

from ..runtime.errors import FtcalError
from ..runtime.inputs import check_input_file
from .recording import Recording, Stream

# suffix (lower case) → "module:function"; imported on first use so opening a .csv never loads h5py.
READERS: dict[str, str] = {
    ".mat": "ftcal.data.logs_mat:read_mat",
    ".csv": "ftcal.data.logs_table:read_table_recording",
    ".parquet": "ftcal.data.logs_table:read_table_recording",
    ".pq": "ftcal.data.logs_table:read_table_recording",
    ".bag": "ftcal.data.bags:read_bag",
    ".db3": "ftcal.data.bags:read_bag",
    ".mcap": "ftcal.data.bags:read_bag",
    "/": "ftcal.data.bags:read_bag",  # a ROS 2 bag folder
}


def log_format(path: Path) -> str:
    """The registry key of ``path``: its lower-case suffix, or ``"/"`` for a folder."""
    return "/" if path.is_dir() else path.suffix.lower()


def is_bag(path: str | Path) -> bool:
    """Whether ``path`` is a ROS bag (a file or folder :data:`READERS` gives to :mod:`ftcal.data.bags`)."""
    return READERS.get(log_format(Path(path)), "").startswith("ftcal.data.bags:")


def read_recording(path: str | Path, joint_units: str = "rad", **options: Any) -> Recording:
    """Read a recording with the reader registered for its suffix.

    Parameters
    ----------
    path : str or Path
        The log file.
    joint_units : {"rad", "deg"}
        Unit of the logged joint data; degrees are converted to radians.
    **options
        Passed to the format's reader.

    Returns
    -------
    Recording

    Raises
    ------
    FtcalError
        If the file does not exist, its format is unknown, or its reader rejects it.
    """
    path = Path(path)
    if joint_units not in ("rad", "deg"):
        raise FtcalError(f"The 'joint_units' parameter must be 'rad' or 'deg'. Got {joint_units!r} instead.")
    check_input_file(path, "recording", folder_ok=True)
    key = log_format(path)
    if key not in READERS:
        what = "a folder" if key == "/" else f"of unknown format {key!r}"
        known = ", ".join(k for k in sorted(READERS) if k != "/")
        raise FtcalError(f"Recording {path}: is {what}; use {known}.")
    module, function = READERS[key].split(":")
    recording = getattr(importlib.import_module(module), function)(path, **options)
    return _joints_in_radians(recording) if joint_units == "deg" else recording


def _joints_in_radians(rec: Recording) -> Recording:
    def conv(s: Stream | None) -> Stream | None:
        return None if s is None else dataclasses.replace(s, data=np.deg2rad(s.data))

    return dataclasses.replace(rec, joints=conv(rec.joints), joint_velocities=conv(rec.joint_velocities),
                               joint_accelerations=conv(rec.joint_accelerations))
