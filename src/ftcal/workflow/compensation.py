"""The contact wrench: readings minus the bias and the tool's weight (and inertia): ``ftcal compensate``."""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from dataclasses import dataclass, field

from .arguments import COMPENSATE, check_arguments
from ..runtime.deprecation import renamed_keyword
from ..runtime.errors import FtcalError, ParameterError
from .result import StepResult
from .sources import gravity_source, reads_tables, source_options

CONTACT_COLUMNS = ("Fx", "Fy", "Fz", "Tx", "Ty", "Tz")


@dataclass(repr=False)
class CompensationResult(StepResult):
    """The compensated table: every row of the input tables, with the contact wrench as ``Fx..Tz``.

    Attributes
    ----------
    table : pandas.DataFrame, the other columns kept
    sources : list of str, the input tables

    Examples
    --------
    >>> import pandas as pd
    >>> table = pd.DataFrame({"Fx": [0.5], "Fy": [0.0], "Fz": [-1.0], "Tx": [0.0], "Ty": [0.0], "Tz": [0.0]})
    >>> CompensationResult(table, ["run.csv"]).contact.tolist()
    [[0.5, 0.0, -1.0, 0.0, 0.0, 0.0]]
    """

    table: object
    sources: list[str] = field(default_factory=list)

    @property
    def contact(self):
        """The contact wrench, ndarray of shape (n_samples, 6), N and N·m."""
        return self.table[list(CONTACT_COLUMNS)].to_numpy(dtype=float)

    def summary(self) -> str:
        return f"{len(self.table)} contact wrenches from {', '.join(self.sources)}"

    def to_dict(self) -> dict:
        from .result import plain

        return plain({"n_samples": len(self.table), "columns": list(map(str, self.table.columns)),
                      "contact": self.contact, "sources": self.sources})

    def save(self, path) -> None:
        """Write the table (CSV or Parquet by suffix, atomically)."""
        from ..data.tables import write_table

        write_table(self.table, path)


@reads_tables()
def compensate(payload, data, *, calibration=None, inputs: Sequence[str] | None = None, output=None,
               **source) -> CompensationResult:
    """Contact wrench = readings (or a calibration's prediction) − bias − the payload's gravity (and inertial) wrench.

    Parameters
    ----------
    payload : path of a payload file (``ftcal payload -o``)
    data : path, list of paths, DataFrame, list or dict of DataFrames, or Dataset
        CSV or Parquet tables, or the same tables in memory (as
        :func:`ftcal.workflow.payload.identify_payload`); the compensated table is the one the same
        tables give from Parquet files. There is no ``executor``: each table is read and compensated
        in this process (``ftcal compensate`` has no ``--scheduler``).
    calibration : path of a calibration model file, or None
        When given, the measured wrench is its prediction from its input columns.
    inputs : six measured-wrench columns (default: the payload file's, else u1..u6; ``wrench=``, the old
        spelling, still works)
    output : path or None; when given, the table is written there
    **source
        The gravity source, as :func:`ftcal.workflow.payload.identify_payload`; ``g`` defaults to
        the payload file's and ``time`` to its time column.

    Returns
    -------
    CompensationResult

    Raises
    ------
    FtcalError
        Bad input, ``dynamic`` with a payload file that has no inertia, or a ``g`` other than the file's.

    Examples
    --------
    >>> import numpy as np, pandas as pd, tempfile, os
    >>> from scipy.spatial.transform import Rotation
    >>> from ftcal.workflow.payload import identify_payload
    >>> gravity = Rotation.random(10, random_state=4).inv().apply([0.0, 0.0, -9.81])
    >>> force = 1.5 * gravity + [0.3, -0.2, 0.1]                 # a 1.5 kg tool and a force bias
    >>> table = pd.DataFrame(np.c_[force, np.zeros((10, 3)), gravity],
    ...                      columns=["u1", "u2", "u3", "u4", "u5", "u6", "gx", "gy", "gz"])
    >>> folder = tempfile.mkdtemp()
    >>> table.to_csv(os.path.join(folder, "poses.csv"), index=False)
    >>> _ = identify_payload(os.path.join(folder, "poses.csv"), gravity_columns=("gx", "gy", "gz"),
    ...                      output=os.path.join(folder, "tool.json"))
    >>> result = compensate(os.path.join(folder, "tool.json"), os.path.join(folder, "poses.csv"),
    ...                     gravity_columns=("gx", "gy", "gz"))
    >>> bool(np.abs(result.contact).max() < 1e-9)   # no contact: weight and bias removed
    True
    """
    check_arguments(COMPENSATE, locals(), "ftcal.compensate")
    import pandas as pd

    from ..files.model_files import load_model
    from ..files.payload_json import load_payload
    from ..payload.compensate import warn_undetermined
    from ..payload.tables import compensate_table

    wrench = renamed_keyword(source, "wrench", "inputs", inputs)
    paths, names = data.paths, data.sources
    options = source_options(source, "compensate")
    tool = load_payload(payload)
    if options["dynamic"] and tool.inertia is None:
        raise ParameterError('dynamic', f"{payload}: has no inertia (identified without {{dynamic}}); "
                         "compensate without {dynamic} or re-identify with it.")
    if source.get("g") is None:
        options["g"] = tool.gravity
    elif abs(options["g"] - tool.gravity) > 1e-9 * tool.gravity:
        raise ParameterError('g',
                             f"{{g}} {options['g']:g}: {payload} was identified with g = {tool.gravity:g} m/s² (its "
                         "mass times g is what the data determined); leave {g} out.")
    gravity_from = gravity_source(options)
    model = load_model(calibration) if calibration is not None else None
    parts = [compensate_table(path, tool, gravity_from, wrench=wrench, model=model, time_column=options["time"],
                              warn_out_of_range=False)
             for path in paths]
    outside = sum(part.attrs.get("undetermined_samples", 0) for part in parts)
    table = pd.concat(parts, ignore_index=True) if len(parts) > 1 else parts[0]
    warn_undetermined(tool, outside, len(table), ", ".join(names))  # once for all the files
    if model is not None:  # one out-of-range warning for all the files
        from ..core.ranges import RangeSums, describe, span_of
        from ..runtime.errors import OutOfRangeWarning

        from ..payload.tables import predicted_loads_text

        inputs = table[list(model.input_names_)].to_numpy(dtype=float)
        ranges = RangeSums.of(inputs, model.input_range_, outside_span=span_of(model, inputs))
        loads = predicted_loads_text(model, [part.attrs["predicted_loads"] for part in parts
                                             if part.attrs.get("predicted_loads") is not None])
        # one line: the inputs outside their training range, then the predicted loads beyond the training loads
        message = " ".join(part for part in (describe(ranges.to_dict(model.input_names_)), loads) if part)
        if message:
            warnings.warn(message, OutOfRangeWarning, stacklevel=2)
    result = CompensationResult(table, names)
    if output is not None:
        result.save(output)
    return result
