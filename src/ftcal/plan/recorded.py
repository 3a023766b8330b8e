"""Recorded poses to build on (``ftcal plan --from DATA``), and the plan's own table.

A recorded table counts one pose per row: pass a table with one row per still
pose (a previous plan, or a dataset averaged per pose); a recording sampled at
a high rate would count each sample as a pose and weigh far more than the plan.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..core.columns import DEFAULT_OUTPUTS
from ..core.limits import MAX_WRENCH
from ..data.tables import numeric_columns, read_table
from ..robot.kinematics import require_chain_joints, sensor_poses
from ..robot.model import RobotModel
from ..runtime.errors import FtcalError, ParameterError
from .candidates import GRAVITY
from .experiment import Plan, Recorded

LOAD_COLUMN, REFERENCE_COLUMN = "load", "reference"


def read_recorded(path: str | Path, robot: RobotModel, sensor: str, *, base: str | None = None) -> Recorded:
    """Expected wrench (columns Fx..Tz), sensor-frame gravity (joint columns) and ``load`` of a table.

    Any of them may be missing; the objective that needs one says so
    (:func:`ftcal.plan.experiment.design_experiment`). A table with joint columns must hold every joint on
    the chain from the base to the sensor (they turn gravity in the sensor frame); others are 0.

    Raises
    ------
    FtcalError
        Unreadable file, no rows, non-numeric or non-finite cells, a ``load`` that is not a whole number.
    """
    path = Path(path)
    frame = read_table(path)
    if frame.shape[0] == 0:
        raise ParameterError('recorded', f"{{recorded}} {path}: the table has no rows.")
    wrench = gravity = load = None
    if all(c in frame.columns for c in DEFAULT_OUTPUTS):
        wrench = numeric_columns(frame, DEFAULT_OUTPUTS, path, "expected wrench")
        if np.abs(wrench).max() > MAX_WRENCH:  # beyond any sensor; its monomials would overflow to inf/NaN
            raise ParameterError('recorded', f"{{recorded}} {path}: expected wrench values beyond {MAX_WRENCH:g} N or N·m; not a recording "
                             "of a force/torque sensor.")
    joints = [c for c in frame.columns if c in robot.joint_names]
    if joints:
        require_chain_joints(robot, joints, robot.base_frame(base)[1], sensor, f"{{recorded}} {path}",
                             parameters=("recorded",))
        q = robot.joint_matrix(joints, numeric_columns(frame, joints, path, "joint"), str(path))
        rotation = sensor_poses(robot, sensor, q, base=base)[:, :3, :3]
        gravity = np.einsum("nji,j->ni", rotation, np.asarray(GRAVITY))
    if LOAD_COLUMN in frame.columns:
        values = numeric_columns(frame, [LOAD_COLUMN], path, "load")[:, 0]
        if not np.all(values == np.round(values)):
            raise ParameterError(('recorded', 'load'), f"{{recorded}} {path}: column 'load' must hold whole numbers (0-based {{load}} indices).")
        load = values.astype(np.int64)
    if wrench is None and gravity is None:
        raise ParameterError('recorded', f"{{recorded}} {path}: neither expected wrench columns ({','.join(DEFAULT_OUTPUTS)}) nor joint "
                         f"columns of URDF {robot.source}; nothing to build on.")
    return Recorded(str(path), wrench, gravity, load)


def plan_frame(plan: Plan):
    """The plan as a DataFrame in execution order: joint columns (rad), load, reference (0/1), Fx..Tz."""
    import pandas as pd

    q, load, reference, wrench = plan.table()
    index = {name: i for i, name in enumerate(plan.space.joint_names)}
    columns: dict[str, np.ndarray] = {name: q[:, index[name]] for name in plan.space.columns}
    columns[LOAD_COLUMN] = load
    columns[REFERENCE_COLUMN] = reference.astype(np.int64)
    for k, name in enumerate(DEFAULT_OUTPUTS):
        columns[name] = wrench[:, k]
    return pd.DataFrame(columns)
