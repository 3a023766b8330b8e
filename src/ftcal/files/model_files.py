"""One entry point for model files: read by content, write by format name (``ftcal convert``)."""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path

from ..core.families import ModelFamily, check_export
from ..runtime.checks import check_choice
from ..runtime.errors import FtcalError
from .firmware import firmware_filename, write_firmware_matrix
from .model_json import ModelFile, check_model_size, load_model_file, save_model
from .paper_xml import read_paper_xml, write_paper_xml
from .wbd import write_wbd

WRITE_FORMATS = ("json", "paper-xml", "icub-firmware", "wbd")
_SNIFF_BYTES = 512


def read_model(path: str | Path) -> ModelFamily:
    """A model from a native JSON (any registered family) or a paper XML file, told apart by content.

    This is ``ftcal.load_model``: it reads every model file the ``ftcal`` commands read.

    Examples
    --------
    >>> import pathlib, tempfile
    >>> import numpy as np
    >>> from ftcal import CalibrationModel, load_model
    >>> from ftcal.files.paper_xml import write_paper_xml
    >>> path = pathlib.Path(tempfile.mkdtemp()) / "model.xml"
    >>> model = CalibrationModel(1).fit(np.array([[0.0], [1.0], [2.0]]), np.array([[1.0], [3.0], [5.0]]))
    >>> _ = write_paper_xml(model, path)
    >>> round(float(load_model(path).predict(np.array([[4.0]]))[0, 0]), 9)
    9.0
    """
    return read_model_file(path).model


def read_model_file(path: str | Path) -> ModelFile:
    """Like :func:`read_model`, with units and sources (empty for paper XML, which has none)."""
    path = Path(path)
    check_model_size(path)
    try:
        with open(path, "rb") as fh:
            head = fh.read(_SNIFF_BYTES)
    except OSError as exc:
        raise FtcalError(f"Cannot read model file {path}: {exc.strerror}.") from None
    first = head.lstrip(b"\xef\xbb\xbf \t\r\n")[:1]
    if first == b"{":
        return load_model_file(path)
    if first == b"<":
        model = read_paper_xml(path)
        return ModelFile(model, (None,) * len(model.input_names_), (None,) * len(model.output_names_),
                         (), None, None)
    raise FtcalError(f"{path}: neither an ftcal JSON model file nor a paper XML model file "
                     "(expected '{' or '<' as the first character).")


def write_model(model: ModelFamily, path: str | Path, fmt: str, *, sources: Sequence[str] = (),
                input_units: Sequence[str | None] | None = None,
                output_units: Sequence[str | None] | None = None,
                serial: str | None = None, sensor: str | None = None) -> Path:
    """Write ``model`` in format ``fmt`` (one of :data:`WRITE_FORMATS`); returns the path written.

    ``sources`` and the units go into JSON files (``icub-firmware`` checks the input
    units are ADC counts). For ``icub-firmware`` a
    directory ``path`` gets ``matrix_<serial>.txt`` inside it. ``wbd`` needs the
    ``sensor`` name used in the wholeBodyDynamics configuration.
    """
    check_choice(fmt, "fmt", "write_model", WRITE_FORMATS)
    check_export(model, fmt)
    folder = str(path).endswith(("/", os.sep))  # "-o firmware/": a folder, made if missing
    path = Path(path)
    if path.is_dir() and fmt != "icub-firmware":
        raise FtcalError(f"{path} is a directory; give the path of the {fmt} file to write.")
    if fmt == "json":
        save_model(model, path, sources=sources, input_units=input_units, output_units=output_units)
    elif fmt == "paper-xml":
        write_paper_xml(model, path)
    elif fmt == "icub-firmware":
        if path.is_dir() or folder:
            if serial is None:
                raise FtcalError(f"{path} is a directory: give the sensor serial number to name "
                                 "matrix_<serial>.txt, or a file path.")
            path = path / firmware_filename(serial)
        write_firmware_matrix(model, path, input_units)
    else:
        if sensor is None:
            raise FtcalError("The wbd format needs the sensor name used by wholeBodyDynamics "
                             "(such as r_arm_ft_sensor).")
        write_wbd(model, path, sensor)
    return path
