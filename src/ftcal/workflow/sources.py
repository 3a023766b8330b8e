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

from ..runtime.errors import FtcalError

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


def gravity_source(options: Mapping[str, Any], robot_options: str = "--urdf PATH or --model NAME"):
    """The :class:`~ftcal.payload.kinematics.KinematicsSource` the options describe.

    Parameters
    ----------
    options : the keywords of :data:`SOURCE_OPTIONS` (see :func:`source_options`)
    robot_options : how the caller spells its robot-model options, for messages

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
                             robot_options=robot_options)


def _columns(value: Sequence[str] | str | None) -> tuple[str, ...] | None:
    if value is None:
        return None
    return tuple(value.split(",")) if isinstance(value, str) else tuple(value)


def _text(value) -> str | None:
    return None if value is None else str(value)


def paths_of(data, role: str = "DATA") -> list[str]:
    """One path or several, as a list of strings (what the steps read).

    Raises
    ------
    FtcalError
        No path given.
    """
    import os

    items = [data] if isinstance(data, (str, os.PathLike)) else list(data)
    if not items:
        raise FtcalError(f"{role}: no file given.")
    return [os.fspath(p) for p in items]


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
        raise FtcalError("--ft-frame needs --ft-joint (the fixed joint the sensor sits on).")
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
        segment_by = default_label_column(paths, SEGMENT_COLUMN)
        if segment_by is not None:
            notes.append(f"segments: the tables' {SEGMENT_COLUMN!r} column (one per recording, from ftcal dataset); "
                         "--segment-by COL for another")
    if group_by is not None:
        group_by = label_column(paths, group_by)
    elif groups:
        group_by = default_label_column(paths, LOAD_COLUMN)
        if group_by is not None:
            notes.append(f"groups: the tables' {group_by!r} column (the load cases ftcal dataset writes); "
                         "--group-by COL for another")
    return segment_by, group_by


class tables_of:
    """``data`` as (paths, Dataset or None, source names), for the steps that stream files.

    A DataFrame becomes one temporary Parquet file (removed on exit), so that it runs the very
    path files run; a :class:`~ftcal.core.dataset.Dataset` is handed on whole.
    """

    def __init__(self, data):
        self.data = data
        self.folder = None

    def __enter__(self):
        from ..core.dataset import Dataset

        data = self.data
        if isinstance(data, Dataset):
            return [], data, list(data.sources)
        if isinstance(data, (str, os.PathLike)):
            return [str(data)], None, [str(data)]
        if hasattr(data, "to_parquet") and hasattr(data, "columns"):
            import tempfile

            self.folder = tempfile.TemporaryDirectory(prefix="ftcal-frame-")
            path = os.path.join(self.folder.name, "frame.parquet")
            data.to_parquet(path, index=False)
            return [path], None, ["DataFrame"]
        if isinstance(data, Sequence) and data and all(isinstance(p, (str, os.PathLike)) for p in data):
            return [str(p) for p in data], None, [str(p) for p in data]
        raise FtcalError(f"data: expected a file name, a list of them, a pandas DataFrame or a Dataset; "
                         f"got {type(data).__name__}.")

    def __exit__(self, *exc):
        if self.folder is not None:
            self.folder.cleanup()
        return False
