"""YARP robot-logger ``.mat`` files (docs/formats.md §4), MATLAB v7.3 (HDF5) and v5.

Layout, under the struct ``robot_logger_device``::

    FTs.<sensor>.data / .timestamps             samples × 6, or 6 × 1 × samples
    temperatures.<sensor>.data / .timestamps    samples × 1, or 1 × 1 × samples
    joints_state.positions.data / .timestamps   samples × joints, or joints × 1 × samples
    joints_state.velocities / .accelerations    (optional) same shapes
    description_list                            cell array of joint names, data order
    accelerometers.<imu>.data, gyros.<imu>.data (optional) samples × 3 or 3 × 1 × samples

v7.3 files are HDF5 with a 512-byte MATLAB header; MATLAB writes arrays
column-major, so HDF5 sees every array with its axes reversed and we reverse
them back. Cell arrays of strings are HDF5 object references to ``uint16``
character arrays.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from ..core.limits import MAX_DECLARED_ELEMENTS, MAX_MAT_ARRAYS, MAX_NESTING
from ..runtime.errors import FtcalError
from ..runtime.inputs import check_input_file
from .mat_v5 import check_v5
from .recording import Recording, Stream

ROOT = "robot_logger_device"
GROUPS = ("FTs", "temperatures", "joints_state", "accelerometers", "gyros", "description_list")
JOINT_FIELDS = {"positions": "joints", "velocities": "joint_velocities", "accelerations": "joint_accelerations"}




def read_mat(path: Path) -> Recording:
    """Read a robot-logger ``.mat`` file (v7.3 or v5) into a :class:`Recording`."""
    import h5py

    path = check_input_file(path, ".mat recording")

    tree = _read_hdf5(path) if h5py.is_hdf5(path) else _read_v5(path)
    return _recording(path, tree)


def _read_hdf5(path: Path) -> dict[str, Any]:
    import h5py

    try:
        with h5py.File(path, "r") as fh:
            if fh.get(ROOT, getlink=True) is None:  # the link itself: never resolved to learn it exists
                raise FtcalError(f"Recording {path}: no '{ROOT}' struct (has: {', '.join(fh.keys()) or 'nothing'}).")
            walk = _Walk(fh, path)
            root = _child(fh, ROOT, path)
            walk.open[_address(root)] = f"/{ROOT}"  # a link back to the root is a loop too
            return {name: walk.node(_child(root, name, path), f"/{ROOT}/{name}", 1)
                    for name in GROUPS if root.get(name, getlink=True) is not None}
    except FtcalError:
        raise
    except (OSError, RuntimeError, KeyError, ValueError, TypeError) as exc:  # h5py's errors on corrupt files
        raise FtcalError(f"Recording {path}: cannot read the MATLAB v7.3 (HDF5) file; "
                         f"it may be truncated or corrupt ({type(exc).__name__}: {exc}).") from None


def _child(group, key: str, path: Path):
    """``group[key]``, refusing links to other files, soft links that never resolve and dangling links."""
    import h5py

    link = group.get(key, getlink=True)
    where = f"{group.name.rstrip('/')}/{key}"
    if isinstance(link, h5py.ExternalLink):
        # A recording must not make ftcal read another file.
        raise FtcalError(f"Recording {path}: {where} is a link to another file ({link.filename}); "
                         "ftcal does not follow links out of a recording.")
    try:
        return group[key]
    except KeyError:
        raise FtcalError(f"Recording {path}: {where} is a link to nothing.") from None
    except RuntimeError:  # HDF5 gives up after 16 soft links in a row: a soft link loop
        target = f" ({link.path})" if isinstance(link, h5py.SoftLink) else ""
        raise FtcalError(f"Recording {path}: {where} is a soft link{target} that never resolves "
                         "(a loop of links); not a robot-logger file.") from None


def _address(node) -> int:
    """Where ``node`` lives in its file: one object reached by two links has one address."""
    import h5py

    return h5py.h5o.get_info(node.id).addr


class _Walk:
    """One bounded walk over an HDF5 tree: each object is read once, loops are refused.

    Hard links, soft links and MATLAB cell references (``#refs#``) can make a
    group contain itself or point back to an ancestor, and links shared along
    many paths make a tree of a few objects exponentially large. Objects are
    keyed by their address in the file: one on the current path again is a loop
    (refused, naming both paths); one seen elsewhere is reused, not read again.
    """

    def __init__(self, fh, path: Path):
        self.fh, self.path = fh, path
        self.done: dict[int, Any] = {}
        self.open: dict[int, str] = {}  # objects on the current path → the HDF5 path they were reached by

    def node(self, node, where: str, depth: int) -> Any:
        """The value of ``node`` (dict, list, str or array), reached by the HDF5 path ``where``."""
        if depth > MAX_NESTING:
            raise FtcalError(f"Recording {self.path}: {where} is nested more than {MAX_NESTING} levels deep; "
                             "not a robot-logger file.")
        addr = _address(node)
        if addr in self.done:
            return self.done[addr]
        if addr in self.open:
            raise FtcalError(f"Recording {self.path}: {where} links back to {self.open[addr]}, which contains it "
                             "(a loop of links); not a robot-logger file.")
        if len(self.done) + len(self.open) >= MAX_MAT_ARRAYS:
            raise FtcalError(f"Recording {self.path}: more than {MAX_MAT_ARRAYS:,} groups and arrays (at {where}); "
                             "not a robot-logger recording.")
        self.open[addr] = where
        value = self._read(node, where, depth)
        del self.open[addr]
        self.done[addr] = value
        return value

    def _read(self, node, where: str, depth: int) -> Any:
        import h5py

        path = self.path
        if isinstance(node, h5py.Group):
            return {key: self.node(_child(node, key, path), f"{where}/{key}", depth + 1) for key in node.keys()}
        if node.is_virtual or node.id.get_create_plist().get_external_count():
            raise FtcalError(f"Recording {path}: the data of {where} is stored in other files; "
                             "ftcal reads only the recording itself.")
        if node.size > MAX_DECLARED_ELEMENTS:  # checked on the declared shape, before anything is allocated
            raise FtcalError(f"Recording {path}: {where} declares {node.size:,} values (shape "
                             f"{'x'.join(map(str, node.shape))}), more than the limit of {MAX_DECLARED_ELEMENTS:,}; "
                             "not a robot-logger recording.")
        attr = node.attrs.get("MATLAB_class", b"")
        matlab_class = attr.decode() if isinstance(attr, bytes) else str(attr)
        if node.dtype == h5py.ref_dtype:  # cell array: references into #refs#
            return [self.node(self._deref(ref, where), f"{where}{{{i + 1}}}", depth + 1)
                    for i, ref in enumerate(np.asarray(node[()]).T.ravel())]
        value = np.asarray(node[()])
        if matlab_class == "char":
            return "".join(map(chr, value.T.ravel()))
        return value.T  # back to MATLAB axis order

    def _deref(self, ref, where: str):
        try:
            return self.fh[ref]
        except (ValueError, KeyError, RuntimeError, TypeError):
            raise FtcalError(f"Recording {self.path}: a reference in {where} points to nothing; "
                             "not a robot-logger file.") from None


def _read_v5(path: Path) -> dict[str, Any]:
    import scipy.io

    check_v5(path)  # declared sizes and truncation, before scipy allocates what the file claims
    try:
        data = scipy.io.loadmat(path, simplify_cells=True, variable_names=[ROOT])
    except Exception as exc:  # scipy raises many types (ValueError, OSError, MatReadError, ...) on bad files
        raise FtcalError(f"Recording {path}: cannot read the MATLAB file; it may be truncated, corrupt "
                         f"or not a MAT-file ({type(exc).__name__}: {exc}).") from None
    if ROOT not in data or not isinstance(data[ROOT], dict):
        raise FtcalError(f"Recording {path}: no '{ROOT}' struct.")
    return {name: data[ROOT][name] for name in GROUPS if name in data[ROOT]}


def _recording(path: Path, tree: dict[str, Any]) -> Recording:
    ft = {name: _stream(path, f"FTs.{name}", node, 6, tuple(f"u{i}" for i in range(1, 7)))
          for name, node in _struct(path, tree, "FTs").items()}
    if not ft:
        raise FtcalError(f"Recording {path}: no F/T streams (robot_logger_device.FTs is missing or empty).")
    temps = {name: _stream(path, f"temperatures.{name}", node, 1, ("T",))
             for name, node in _struct(path, tree, "temperatures").items()}
    joints: dict[str, Stream | None] = dict.fromkeys(JOINT_FIELDS.values())
    state = _struct(path, tree, "joints_state")
    if state:
        names = _joint_names(path, tree)
        for field_name, attr in JOINT_FIELDS.items():
            if field_name in state:
                joints[attr] = _stream(path, f"joints_state.{field_name}", state[field_name], len(names), names)
    imu = {group: {name: _stream(path, f"{group}.{name}", node, 3, ("x", "y", "z"))
                   for name, node in _struct(path, tree, group).items()}
           for group in ("accelerometers", "gyros")}
    return Recording(path, ft, temps, joints["joints"], joints["joint_velocities"],
                     joints["joint_accelerations"], imu["accelerometers"], imu["gyros"])


def _struct(path: Path, tree: dict[str, Any], name: str) -> dict[str, Any]:
    node = tree.get(name, {})
    if not isinstance(node, dict):
        raise FtcalError(f"Recording {path}: robot_logger_device.{name} is not a struct.")
    return node


def _joint_names(path: Path, tree: dict[str, Any]) -> tuple[str, ...]:
    names = tree.get("description_list")
    if names is None:
        raise FtcalError(f"Recording {path}: joints_state is present but description_list (the joint names) is missing.")
    if isinstance(names, str):
        names = [names]
    names = [str(n).strip() for n in np.asarray(names, dtype=object).ravel()]
    if not names or not all(names):
        raise FtcalError(f"Recording {path}: description_list must hold the joint names as strings.")
    return tuple(names)


def _stream(path: Path, where: str, node: Any, k: int, columns: tuple[str, ...]) -> Stream:
    if not isinstance(node, dict) or "data" not in node or "timestamps" not in node:
        raise FtcalError(f"Recording {path}: {where} must have 'data' and 'timestamps'.")
    try:
        time = np.asarray(node["timestamps"], dtype=np.float64).ravel()
        data = np.asarray(node["data"], dtype=np.float64)
    except (TypeError, ValueError):
        raise FtcalError(f"Recording {path}: {where} data and timestamps must be numeric arrays.") from None
    return Stream(f"{path.name}:{where}", time, _samples_by_channels(path, where, data, time.size, k), columns)


def _samples_by_channels(path: Path, where: str, data: np.ndarray, n: int, k: int) -> np.ndarray:
    """Bring samples × k, k × 1 × samples (or squeezed forms) to shape (n, k)."""
    squeezed = data.reshape([d for d in data.shape if d != 1]) if data.size > 1 else data.reshape(-1)
    if squeezed.ndim == 1 and k == 1 and squeezed.size == n:
        return squeezed.reshape(n, 1)
    if squeezed.ndim == 2:
        if squeezed.shape == (n, k):
            return squeezed
        if squeezed.shape == (k, n):
            return squeezed.T.copy()
    raise FtcalError(f"Recording {path}: {where}.data has shape {data.shape}; expected samples × {k} or "
                     f"{k} × 1 × samples with {n} samples to match its timestamps (mismatched lengths?).")
