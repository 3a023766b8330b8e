"""Write a model or payload file in another format: ``ftcal convert`` (targets: :mod:`ftcal.files.targets`)."""

from __future__ import annotations

from dataclasses import dataclass, field

from .arguments import CONVERT, check_arguments
from .result import StepResult


@dataclass(repr=False)
class ConvertResult(StepResult):
    """What :func:`convert` wrote: the paths, and notes such as the measured precision of single-precision C.

    Attributes
    ----------
    target : the target's name (``ftcal convert --to``)
    paths : list of str, the files written
    notes : list of str

    Examples
    --------
    >>> print(ConvertResult("c", ["out/r_arm.h", "out/r_arm.c"]).summary())
    wrote out/r_arm.h, out/r_arm.c
    """

    target: str
    paths: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)

    def summary(self) -> str:
        return "\n".join([*self.notes, f"wrote {', '.join(self.paths)}"])


def convert(model, to: str, output, *, serial: str | None = None, sensor: str | None = None,
            name: str | None = None, single_precision: bool = False, frame: str | None = None,
            com_frame: str | None = None, payload_files: list[str] | None = None,
            world_frame: str | None = None) -> ConvertResult:
    """Write ``model`` (a model or payload file) as target ``to`` at ``output``: ``ftcal convert``.

    Parameters
    ----------
    model : path of an ftcal JSON or paper XML model file, or of an ftcal payload file
    to : a target of :data:`ftcal.files.targets.TARGETS` (``json``, ``paper-xml``, ``icub-firmware``,
        ``wbd``, ``c``, ``onnx``, ``ros-yaml``, ``ft-tools-ros2``, ...)
    output : file, or folder where the target writes several files
    serial, sensor, name, single_precision, frame, com_frame, world_frame : the target's options (``ftcal convert
        --help``)
    payload_files : ``c-runtime`` only: the tool library compiled into the header, ``[NAME=]TOOL.json`` each

    Returns
    -------
    ConvertResult

    Raises
    ------
    FtcalError
        Unknown target, an input the target does not take, a bad output path; nothing is written then.

    Examples
    --------
    >>> import numpy as np, tempfile, os
    >>> from ftcal import CalibrationModel, Dataset, save_model
    >>> raw = np.random.default_rng(0).normal(size=(50, 6))
    >>> folder = tempfile.mkdtemp()
    >>> _ = save_model(CalibrationModel(1).fit(Dataset.from_arrays(raw, 2.0 * raw)), os.path.join(folder, "m.json"))
    >>> result = convert(os.path.join(folder, "m.json"), "paper-xml", os.path.join(folder, "m.xml"))
    >>> result.paths == [os.path.join(folder, "m.xml")]
    True
    """
    check_arguments(CONVERT, locals(), "ftcal.convert")
    from ..files.targets import write_target as write

    written = write(model, to, output, {"serial": serial, "sensor": sensor, "name": name,
                                        "single_precision": single_precision, "frame": frame,
                                        "com_frame": com_frame, "payload_files": payload_files,
                                        "world_frame": world_frame})
    return ConvertResult(to, [str(p) for p in written.paths], list(written.notes))
