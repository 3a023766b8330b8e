"""Write simulated recordings as YARP robot-logger ``.mat`` files (docs/formats.md §4).

What is written
---------------
One MATLAB variable, the struct ``robot_logger_device``, with these fields (MATLAB
dimensions; ``N`` samples of that stream, ``J`` joints; ``layout="channels_first"`` is
the current logger's ``k × 1 × N``, ``layout="samples_first"`` the older ``N × k``):

================================================  ==================  ===============
field                                             channels_first      samples_first
================================================  ==================  ===============
``FTs.<sensor>.data`` (Fx Fy Fz Tx Ty Tz, raw)    6 × 1 × N           N × 6
``FTs.<sensor>.timestamps`` (s)                   N × 1               N × 1
``temperatures.<sensor>.data`` (°C)               1 × 1 × N           N × 1
``temperatures.<sensor>.timestamps``              N × 1               N × 1
``joints_state.positions.data`` (rad)             J × 1 × N           N × J
``joints_state.positions.timestamps``             N × 1               N × 1
``joints_state.velocities`` / ``.accelerations``  as positions (only when given)
``description_list`` (joint names, data order)    J × 1 cell of char  J × 1 cell
``yarp_robot_name`` (only when given)             1 × L char          1 × L char
================================================  ==================  ===============

All numbers are ``double``. Every stream has its own timestamps (s, YARP clock).

``version="7.3"`` writes HDF5 the way MATLAB does: a 512-byte user block holding the
MAT-file header text (``MATLAB 7.3 MAT-file, ...``, version 0x0200, endian ``IM``);
structs are groups with attribute ``MATLAB_class = "struct"`` and ``MATLAB_fields``;
arrays are datasets with ``MATLAB_class = "double"`` (gzip-compressed from 1024 elements) stored with their dimensions
reversed (HDF5 row-major holds MATLAB's column-major data, so a MATLAB ``6 × 1 × N``
array is an HDF5 dataset of shape ``(N, 1, 6)``); a cell array is a dataset of object
references (``MATLAB_class = "cell"``, HDF5 shape reversed: ``(1, J)``) to datasets in
the root group ``#refs#``; a char array is ``uint16`` with ``MATLAB_class = "char"`` and
``MATLAB_int_decode = 2`` (a 1 × L string is HDF5 shape ``(L, 1)``).

``version="5"`` writes the same struct with :func:`scipy.io.savemat`.
"""

from __future__ import annotations

import time
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..runtime.atomic import write_with
from ..runtime.checks import check_choice
from ..runtime.errors import FtcalError

ROOT = "robot_logger_device"
LAYOUTS = ("channels_first", "samples_first")
VERSIONS = ("7.3", "5")
USERBLOCK = 512


@dataclass(frozen=True, eq=False)
class Stream:
    """One logged signal: samples with their own timestamps.

    timestamps : ndarray of shape (n_samples,), s
    data : ndarray of shape (n_samples, n_channels)
    """

    timestamps: np.ndarray
    data: np.ndarray

    def __post_init__(self) -> None:
        t = np.asarray(self.timestamps, dtype=np.float64)
        d = np.asarray(self.data, dtype=np.float64)
        if d.ndim == 1:
            d = d[:, None]
        if t.ndim != 1 or d.ndim != 2 or d.shape[0] != t.shape[0]:
            raise FtcalError(f"A stream needs timestamps of shape (n,) and data of shape (n, k); "
                             f"got {t.shape} and {d.shape}.")
        object.__setattr__(self, "timestamps", t)
        object.__setattr__(self, "data", d)


@dataclass(frozen=True, eq=False)
class RobotLog:
    """The content of one robot-logger recording.

    ft : F/T sensor name → stream with 6 channels (the raw Fx..Tz the board sends)
    temperatures : sensor name → stream with 1 channel (°C)
    joint_names : names of the columns of the joint streams
    positions, velocities, accelerations : joint streams (rad, rad/s, rad/s²)
    robot_name : written as ``yarp_robot_name`` when not empty
    """

    ft: Mapping[str, Stream]
    temperatures: Mapping[str, Stream]
    joint_names: tuple[str, ...]
    positions: Stream
    velocities: Stream | None = None
    accelerations: Stream | None = None
    robot_name: str = field(default="")

    def __post_init__(self) -> None:
        for name, stream in self.ft.items():
            if stream.data.shape[1] != 6:
                raise FtcalError(f"F/T stream {name!r} must have 6 channels; got {stream.data.shape[1]}.")
        for name, stream in self.temperatures.items():
            if stream.data.shape[1] != 1:
                raise FtcalError(f"Temperature stream {name!r} must have 1 channel; got {stream.data.shape[1]}.")
        for what in ("positions", "velocities", "accelerations"):
            stream = getattr(self, what)
            if stream is not None and stream.data.shape[1] != len(self.joint_names):
                raise FtcalError(f"Joint {what} have {stream.data.shape[1]} columns but there are "
                                 f"{len(self.joint_names)} joint names.")


def write_robot_log(path: str | Path, log: RobotLog, version: str = "7.3",
                    layout: str = "channels_first") -> Path:
    """Write ``log`` to ``path`` as a robot-logger ``.mat`` file (atomically); return the path."""
    version = check_choice(version, "version", "write_robot_log", VERSIONS)
    layout = check_choice(layout, "layout", "write_robot_log", LAYOUTS)
    tree = {ROOT: _struct(log, layout)}
    target = Path(path)
    write_with(target, lambda tmp: _write_hdf5(tmp, tree) if version == "7.3" else _write_v5(tmp, tree))
    return target


class _CellStr(tuple):
    """Marks a tuple of strings to be written as a MATLAB J × 1 cell of char."""


def _struct(log: RobotLog, layout: str) -> dict:
    def stream(s: Stream) -> dict:
        data = s.data[:, :, None].transpose(1, 2, 0) if layout == "channels_first" else s.data
        return {"data": data, "timestamps": s.timestamps[:, None]}

    joints = {"positions": stream(log.positions)}
    for what in ("velocities", "accelerations"):
        if getattr(log, what) is not None:
            joints[what] = stream(getattr(log, what))
    out = {"description_list": _CellStr(log.joint_names),
           "FTs": {k: stream(v) for k, v in log.ft.items()},
           "temperatures": {k: stream(v) for k, v in log.temperatures.items()},
           "joints_state": joints}
    if log.robot_name:
        out["yarp_robot_name"] = log.robot_name
    return out


def _write_v5(path: Path, tree: dict) -> None:
    from scipy.io import savemat

    def convert(node):
        if isinstance(node, dict):
            return {k: convert(v) for k, v in node.items()}
        if isinstance(node, _CellStr):
            cell = np.empty((len(node), 1), dtype=object)
            cell[:, 0] = list(node)
            return cell
        return node

    savemat(path, convert(tree), format="5", do_compression=True, oned_as="column")


def _write_hdf5(path: Path, tree: dict) -> None:
    import h5py

    with h5py.File(path, "w", userblock_size=USERBLOCK, libver="earliest") as f:
        refs = f.create_group("#refs#")
        counter = iter(range(1 << 30))
        for name, node in tree.items():
            _h5_node(f, refs, counter, name, node)
    with open(path, "r+b") as fh:
        fh.write(_mat73_header())


def _h5_node(parent, refs, counter, name: str, node) -> None:
    import h5py

    if isinstance(node, dict):
        group = parent.create_group(name)
        group.attrs["MATLAB_class"] = np.bytes_("struct")
        fields = np.empty(len(node), dtype=object)
        fields[:] = [np.frombuffer(k.encode("ascii"), dtype="S1") for k in node]
        group.attrs.create("MATLAB_fields", fields, dtype=h5py.vlen_dtype(np.dtype("S1")))
        for key, child in node.items():
            _h5_node(group, refs, counter, key, child)
    elif isinstance(node, _CellStr):
        targets = []
        for text in node:
            ds = _h5_char(refs, _ref_name(next(counter)), text)
            targets.append(ds.ref)
        cell = parent.create_dataset(name, data=np.array([targets], dtype=h5py.ref_dtype))
        cell.attrs["MATLAB_class"] = np.bytes_("cell")
    elif isinstance(node, str):
        _h5_char(parent, name, node)
    else:
        # MATLAB is column-major: its k × 1 × N array is HDF5 (N, 1, k), i.e. the transpose.
        data = np.asarray(node, dtype=np.float64).T
        # Deflate, as MATLAB's own -v7.3 files do; joint streams shrink several-fold.
        packed = {"compression": "gzip", "compression_opts": 4} if data.size >= 1024 else {}
        ds = parent.create_dataset(name, data=data, **packed)
        ds.attrs["MATLAB_class"] = np.bytes_("double")


def _h5_char(parent, name: str, text: str):
    codes = np.frombuffer(text.encode("utf-16-le"), dtype="<u2")
    ds = parent.create_dataset(name, data=codes[:, None])  # MATLAB 1 × L → HDF5 (L, 1)
    ds.attrs["MATLAB_class"] = np.bytes_("char")
    ds.attrs["MATLAB_int_decode"] = np.int32(2)
    return ds


def _ref_name(i: int) -> str:
    # Short names like MATLAB's own: a, b, ..., z, ba, bb, ...
    letters = "abcdefghijklmnopqrstuvwxyz"
    out = letters[i % 26]
    while i >= 26:
        i //= 26
        out = letters[i % 26] + out
    return out


def _mat73_header() -> bytes:
    stamp = time.strftime("%a %b %d %H:%M:%S %Y", time.gmtime())
    text = f"MATLAB 7.3 MAT-file, Platform: GLNXA64, Created on: {stamp} HDF5 schema 1.00 ."
    # 116 bytes of text, 8 bytes of subsystem offset, version 0x0200, endian indicator "IM".
    head = text.encode("ascii").ljust(116, b" ") + b"\x00" * 8 + b"\x00\x02" + b"IM"
    return head.ljust(USERBLOCK, b"\x00")
