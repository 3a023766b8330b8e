"""Where gravity (and motion) in the sensor frame comes from, for the payload, compensate and check steps.

The steps take the same keywords as the commands' flags (``orientation``, ``gravity_columns``,
``urdf``, ``robot``, ``sensor``, ...) and build the
:class:`~ftcal.payload.kinematics.KinematicsSource` here, so every caller gets the same sources
and the same messages.
"""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from typing import Any

from ..runtime.errors import FtcalError, ParameterError

DEFAULT_WRENCH = ("u1", "u2", "u3", "u4", "u5", "u6")

# keyword -> default: the options of the gravity source (the commands' --orientation ... --degrees).
SOURCE_OPTIONS: dict[str, Any] = {
    "orientation": None, "gravity_columns": None, "g": 9.81, "urdf": None, "robot": None, "sensor": None,
    "ft_joint": None, "ft_frame": None, "base": None, "degrees": False, "dynamic": False,
    "angular_velocity": ("wx", "wy", "wz"), "linear_acceleration": ("ax", "ay", "az"),
    "angular_acceleration": None, "time": None,
}


def source_options(given: Mapping[str, Any], step: str) -> dict[str, Any]:
    """``given`` completed with the defaults of :data:`SOURCE_OPTIONS`; an unknown keyword is an error.

    Parameters
    ----------
    given : keyword arguments a step received for its gravity source
    step : the step's name, for the message

    Returns
    -------
    dict
        Every key of :data:`SOURCE_OPTIONS`.

    Raises
    ------
    FtcalError
        A keyword that names no source option.

    Examples
    --------
    >>> source_options({"orientation": ("qx", "qy", "qz", "qw")}, "identify_payload")["g"]
    9.81
    """
    unknown = sorted(set(given) - set(SOURCE_OPTIONS))
    if unknown:
        raise FtcalError(f"{step}: unknown keyword {unknown[0]!r}; the gravity source takes "
                         f"{', '.join(SOURCE_OPTIONS)}.")
    return {**SOURCE_OPTIONS, **given}


def gravity_source(options: Mapping[str, Any], robot_parameters: Sequence[str] = ("urdf", "robot")):
    """The :class:`~ftcal.payload.kinematics.KinematicsSource` the options describe.

    Parameters
    ----------
    options : the keywords of :data:`SOURCE_OPTIONS` (see :func:`source_options`)
    robot_parameters : the caller's parameters that give the robot model, for messages

    Returns
    -------
    KinematicsSource

    Raises
    ------
    FtcalError
        No source or two sources, wrong column counts, an unknown sensor or a URDF error.
    """
    from ..robot.kinematics import kinematics_source

    o = options
    return kinematics_source(orientation=_columns(o["orientation"]), gravity_columns=_columns(o["gravity_columns"]),
                             g=o["g"], urdf=_text(o["urdf"]), robot_name=o["robot"], sensor=o["sensor"],
                             ft_joint=o["ft_joint"], ft_frame=o["ft_frame"], base=o["base"], degrees=o["degrees"],
                             dynamic=o["dynamic"], angular_velocity=_columns(o["angular_velocity"]),
                             linear_acceleration=_columns(o["linear_acceleration"]),
                             angular_acceleration=_columns(o["angular_acceleration"]), time=o["time"],
                             robot_parameters=robot_parameters)


def _columns(value: Sequence[str] | str | None) -> tuple[str, ...] | None:
    if value is None:
        return None
    return tuple(value.split(",")) if isinstance(value, str) else tuple(value)


def _text(value) -> str | None:
    return None if value is None else str(value)


def robot_model(*, urdf=None, robot: str | None = None, ft_joint: str | None = None, ft_frame: str | None = None,
                payload: Sequence[str] = ()):
    """The robot model of the robot commands: a URDF or a named icub-models robot, with an F/T sensor declared
    on the fixed joint ``ft_joint`` (sensor frame ``ft_frame``) and the ``payload`` specs attached.

    Parameters
    ----------
    urdf : path of a URDF, or None
    robot : name of a robot model shipped by icub-models (e.g. ``iCubGenova04``), or None
    ft_joint, ft_frame : declare an F/T sensor on this fixed joint of a plain URDF, and its frame
    payload : specs ``FRAME:MASS[@X,Y,Z][/IXX,IYY,IZZ[,IXY,IXZ,IYZ]]`` (kg, m, kg m²)

    Returns
    -------
    RobotModel

    Raises
    ------
    FtcalError
        ``ft_frame`` without ``ft_joint``, an unreadable URDF, an unknown model or a bad payload spec.
    """
    from ..robot import RobotModel, SensorDeclaration, parse_payload_spec

    if ft_joint is None and ft_frame is not None:
        raise ParameterError(('ft_frame', 'ft_joint'),
                             "{ft_frame} needs {ft_joint} (the fixed joint the sensor sits on).")
    declared = () if ft_joint is None else (SensorDeclaration(ft_joint, ft_frame),)
    model = RobotModel.load(urdf=None if urdf is None else str(urdf), name=robot, declared=declared)
    payloads = [parse_payload_spec(spec) for spec in payload]
    return model.with_payloads(payloads) if payloads else model


def default_label_columns(paths: Sequence[str], segment_by: str | None, notes: list[str], *,
                          group_by: str | None = None, groups: bool = False) -> tuple[str | None, str | None]:
    """(segment column, group column): the ``segment`` and (with ``groups``) ``load`` columns that
    `ftcal dataset` writes, where none is named and every table has them; each default is said in ``notes``.

    The same defaults for fit, evaluate, predict and report, so a model is evaluated on the segments
    it was fitted with (its training fingerprints are taken per segment).
    """
    from ..core.columns import LOAD_COLUMN, SEGMENT_COLUMN
    from ..data.tables import default_label_column, label_column

    if not paths:
        return segment_by, group_by
    if segment_by is None:
        segment_by = default_label_column(paths, SEGMENT_COLUMN, notes)
        if segment_by is not None:
            notes.append(f"segments: the tables' {SEGMENT_COLUMN!r} column (one per recording, from ftcal dataset); "
                         "--segment-by COL for another")
    if group_by is not None:
        group_by = label_column(paths, group_by)
    elif groups:
        group_by = default_label_column(paths, LOAD_COLUMN, notes)
        if group_by is not None:
            notes.append(f"groups: the tables' {group_by!r} column (the load cases ftcal dataset writes); "
                         "--group-by COL for another")
    return segment_by, group_by


class tables_of:
    """``data`` as (paths, Dataset or None, source names), for the steps that read tables.

    ``data`` may be a path or a list of paths (CSV/Parquet), a pandas DataFrame, a list of
    DataFrames (one per recording, named ``DataFrame 1``, ``DataFrame 2``, ...), a dict
    name -> DataFrame (the names name the recordings), an object with ``to_frame()`` (the
    :class:`~ftcal.workflow.datasets.DatasetResult` of :func:`~ftcal.workflow.datasets.build_dataset`,
    a bag table) or a :class:`~ftcal.core.dataset.Dataset`.
    Each DataFrame becomes one temporary Parquet file (removed on exit), so that it runs the very
    path files run. :meth:`named` puts the given names back in place of the temporary files' paths
    in the step's text, and an :class:`~ftcal.runtime.errors.FtcalError` raised inside the ``with``
    block names the DataFrame, not its temporary file.

    Parameters
    ----------
    data : what the step was given
    role : how the step's messages call it (``DATA``, ``LOG``, ...)
    dataset : {"whole", "tables", "refuse"}
        What a Dataset becomes: handed on whole (fit, evaluate, predict); one table per segment
        holding its input and output columns (steps that read columns by name, such as the payload
        steps); or an error (steps that need recordings, such as building a dataset).

    Attributes
    ----------
    paths : list of str, the files to read (temporary for DataFrames), set on entry
    sources : list of str, their names (the paths, or the DataFrames' names)
    dataset : Dataset or None, a Dataset handed on whole

    Examples
    --------
    >>> import pandas as pd
    >>> tables = tables_of({"left": pd.DataFrame({"u1": [1.0]}), "right": pd.DataFrame({"u1": [2.0]})})
    >>> with tables as (paths, dataset, names):
    ...     [pd.read_parquet(p)["u1"].item() for p in paths], dataset, names, tables.named(paths[1] + ": ok")
    ([1.0, 2.0], None, ['left', 'right'], 'right: ok')
    """

    def __init__(self, data, role: str = "DATA", *, dataset: str = "whole"):
        self.data = data
        self.role = role
        self.mode = dataset
        self.folder = None
        self.given: dict[str, str] = {}  # temporary path -> the name the user gave
        self.paths: list[str] = []
        self.sources: list[str] = []
        self.dataset = None

    def __enter__(self):
        try:
            self.paths, self.dataset, self.sources = self._open(self.data)
        except BaseException:  # __exit__ does not run when __enter__ fails
            if self.folder is not None:
                self.folder.cleanup()
            raise
        return self.paths, self.dataset, self.sources

    def _open(self, data):
        from ..core.dataset import Dataset

        if isinstance(data, Dataset):
            if self.mode == "refuse":
                raise FtcalError(f"{self.role}: a Dataset is already built; give the recordings (paths or "
                                 "DataFrames).")
            if self.mode == "whole":
                return [], data, list(data.sources)
            return self._write(_dataset_frames(data))
        if isinstance(data, (str, os.PathLike)):
            return [str(data)], None, [str(data)]
        if _is_frame(data) or hasattr(data, "to_frame"):
            return self._write({"DataFrame": data})
        if isinstance(data, Mapping):
            if not data:
                raise FtcalError(f"{self.role}: no table given (an empty dict).")
            return self._write({str(name): frame for name, frame in data.items()})
        if isinstance(data, Sequence) and all(isinstance(p, (str, os.PathLike)) for p in data):
            if not data:
                raise FtcalError(f"{self.role}: no file given.")
            return [str(p) for p in data], None, [str(p) for p in data]
        if isinstance(data, Sequence) and all(_is_frame(f) or hasattr(f, "to_frame") for f in data):
            return self._write({f"DataFrame {k}": frame for k, frame in enumerate(data, 1)})
        raise FtcalError(f"{self.role}: expected a file name, a list of them, a pandas DataFrame, a list or dict of "
                         f"them, or a Dataset; got {type(data).__name__}.")

    def _write(self, frames: dict):
        import tempfile

        from ..data.tables import parquet_write_options

        self.folder = tempfile.TemporaryDirectory(prefix="ftcal-frame-")
        paths = []
        for k, (name, frame) in enumerate(frames.items()):
            if not _is_frame(frame) and hasattr(frame, "to_frame"):
                frame = frame.to_frame()
            if not _is_frame(frame):
                raise FtcalError(f"{self.role} {name}: expected a pandas DataFrame; got {type(frame).__name__}.")
            # A folder per table keeps the paths apart; the file's stem is the name (a log's default group).
            folder = os.path.join(self.folder.name, str(k))
            os.mkdir(folder)
            stem = "".join("_" if c in "/\\\0" else c for c in name).strip(" .") or "table"
            path = os.path.join(folder, f"{stem}.parquet")
            try:
                import pyarrow as pa

                schema = pa.Schema.from_pandas(frame, preserve_index=False)  # text columns dictionary-encoded only
                frame.to_parquet(path, index=False, **parquet_write_options(schema))
            except (TypeError, ValueError, ImportError) as error:  # e.g. non-string column names
                first = str(error).splitlines()[0] if str(error) else type(error).__name__
                raise FtcalError(f"{self.role} {name}: cannot be written as a table: {first}.") from None
            self.given[path] = name
            paths.append(path)
        return paths, None, list(frames)

    def named(self, value):
        """``value`` (a string, or a list/tuple of them) with each temporary path replaced by its name."""
        if isinstance(value, (list, tuple)):
            return type(value)(self.named(v) for v in value)
        if not isinstance(value, str):
            return value
        for path, name in self.given.items():
            value = value.replace(path, name)
        return value

    def named_labels(self, labels):
        """An object array of per-sample labels (such as one group per file) with the temporary paths named."""
        import numpy as np

        if not self.given:
            return labels
        values, inverse = np.unique(labels, return_inverse=True)
        return np.array(self.named(list(values)), dtype=object)[inverse]

    def __exit__(self, kind, error, traceback):
        if self.folder is not None:
            self.folder.cleanup()
        if isinstance(error, FtcalError) and self.given:
            text = str(error)
            if self.named(text) != text:
                raise type(error)(self.named(text)) from None
        return False


def reads_tables(argument: str = "data", role: str = "DATA", dataset: str = "tables"):
    """Decorator: the step's ``argument`` arrives opened as a :class:`tables_of` (``.paths``, ``.sources``,
    ``.named``), whatever the caller gave (paths, DataFrames, a Dataset); the temporary files live
    while the step runs, and its errors name what the caller gave.

    Parameters
    ----------
    argument : the step's parameter that takes the data
    role, dataset : as :class:`tables_of`

    Examples
    --------
    >>> import pandas as pd
    >>> @reads_tables()
    ... def rows(data):
    ...     return data.sources, [len(pd.read_parquet(p)) for p in data.paths]
    >>> rows([pd.DataFrame({"u1": [1.0, 2.0]}), pd.DataFrame({"u1": [3.0]})])
    (['DataFrame 1', 'DataFrame 2'], [2, 1])
    """
    import functools
    import inspect

    def decorate(step):
        signature = inspect.signature(step)

        @functools.wraps(step)
        def run(*args, **kwargs):
            bound = signature.bind(*args, **kwargs)
            tables = tables_of(bound.arguments[argument], role, dataset=dataset)
            with tables:
                bound.arguments[argument] = tables
                return step(*bound.args, **bound.kwargs)

        return run

    return decorate


def _is_frame(value) -> bool:
    return hasattr(value, "to_parquet") and hasattr(value, "columns")


def _dataset_frames(dataset) -> dict:
    """One DataFrame per segment of ``dataset`` (its input and output columns), named by its source."""
    import pandas as pd

    frames = {}
    for k, (start, stop) in enumerate(dataset.segment_bounds()):
        segment = int(dataset.segments[start])
        columns = {name: dataset.inputs[start:stop, j] for j, name in enumerate(dataset.input_names)}
        if dataset.outputs is not None:
            columns.update({name: dataset.outputs[start:stop, j] for j, name in enumerate(dataset.output_names)})
        name = dataset.sources[segment] if 0 <= segment < len(dataset.sources) else f"segment {segment}"
        frames[name if name not in frames else f"{name} ({k + 1})"] = pd.DataFrame(columns)
    return frames
