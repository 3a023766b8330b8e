"""One entry point for model files: read by content (:func:`load_model`, ``ftcal.load_model``), write by
format name (:func:`save_model`, ``ftcal.save_model``; ``ftcal convert``).

``load``/``save`` name these entry points (every format); ``read_<format>``/``write_<format>`` name one
format's reader and writer (:func:`~ftcal.files.model_json.read_model_json`,
:func:`~ftcal.files.paper_xml.write_paper_xml`, ...). The old names ``read_model``, ``read_model_file``
and ``write_model`` stay one release, with a DeprecationWarning.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path

from ..core.families import ModelFamily, check_export
from ..runtime.checks import check_choice, check_path
from ..runtime.deprecation import deprecated_alias
from ..runtime.errors import FtcalError
from .firmware import firmware_filename, write_firmware_matrix
from .model_json import ModelFile, check_model_size, read_model_json, write_model_json
from .paper_xml import read_paper_xml, write_paper_xml
from .wbd import write_wbd

WRITE_FORMATS = ("json", "paper-xml", "icub-firmware", "wbd")
_SNIFF_BYTES = 512


def load_model(path: str | Path) -> ModelFamily:
    """A model from a native JSON (any registered family) or a paper XML file, told apart by content.

    This is ``ftcal.load_model``: it reads every model file the ``ftcal`` commands read.

    Parameters
    ----------
    path : str or Path

    Returns
    -------
    ModelFamily
        A fitted model (:class:`~ftcal.core.model.CalibrationModel` for polynomials).

    Raises
    ------
    FtcalError
        Not a model file, or a file that is wrong somewhere (the message says where).

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
    return load_model_file(path).model


def load_model_file(path: str | Path) -> ModelFile:
    """Like :func:`load_model`, with units and sources (empty for paper XML, which has none)."""
    check_path(path, "path", "ftcal.load_model")
    path = Path(path)
    check_model_size(path)
    try:
        with open(path, "rb") as fh:
            head = fh.read(_SNIFF_BYTES)
    except OSError as exc:
        raise FtcalError(f"Cannot read model file {path}: {exc.strerror}.") from None
    first = head.lstrip(b"\xef\xbb\xbf \t\r\n")[:1]
    if first == b"{":
        return read_model_json(path)
    if first == b"<":
        model = read_paper_xml(path)
        return ModelFile(model, (None,) * len(model.input_names_), (None,) * len(model.output_names_),
                         (), None, None)
    raise FtcalError(f"{path}: neither an ftcal JSON model file nor a paper XML model file "
                     "(expected '{' or '<' as the first character).")


def save_model(model: ModelFamily, path: str | Path, fmt: str = "json", *, sources: Sequence[str] = (),
               input_units: Sequence[str | None] | None = None,
               output_units: Sequence[str | None] | None = None,
               training_segments: Sequence[dict] | None = None, prior: str | Path | None = None,
               serial: str | None = None, sensor: str | None = None) -> Path:
    """Write ``model`` in format ``fmt`` (one of :data:`WRITE_FORMATS`, atomically); returns the path written.

    This is ``ftcal.save_model``; the default is the native JSON model file (versioned schema,
    sha256 digest, every float exact).

    Parameters
    ----------
    model : a fitted model of a registered family
    path : file to write; for ``icub-firmware`` a directory gets ``matrix_<serial>.txt`` inside it
    fmt : {"json", "paper-xml", "icub-firmware", "wbd"}
    sources, input_units, output_units : recorded in JSON files (``icub-firmware`` checks the input
        units are ADC counts)
    training_segments, prior : JSON only; see :func:`ftcal.files.model_json.write_model_json`
    serial : sensor serial, naming the firmware matrix file in a directory
    sensor : the sensor name used in the wholeBodyDynamics configuration (``wbd``)

    Returns
    -------
    Path

    Raises
    ------
    FtcalError
        An unknown format, one the model's family cannot be written to, or a missing serial/sensor.

    Examples
    --------
    >>> import pathlib, tempfile
    >>> import numpy as np
    >>> from ftcal import CalibrationModel, load_model, save_model
    >>> folder = pathlib.Path(tempfile.mkdtemp())
    >>> model = CalibrationModel(1).fit(np.array([[0.0], [1.0], [2.0]]), np.array([[1.0], [3.0], [5.0]]))
    >>> save_model(model, folder / "model.json").name, save_model(model, folder / "model.xml", "paper-xml").name
    ('model.json', 'model.xml')
    >>> round(float(load_model(folder / "model.json").predict(np.array([[1.5]]))[0, 0]), 9)
    4.0
    """
    check_choice(fmt, "fmt", "save_model", WRITE_FORMATS)
    check_export(model, fmt)
    folder = str(path).endswith(("/", os.sep))  # "-o firmware/": a folder, made if missing
    check_path(path, "path", "ftcal.save_model")
    path = Path(path)
    if path.is_dir() and fmt != "icub-firmware":
        raise FtcalError(f"{path} is a directory; give the path of the {fmt} file to write.")
    if fmt == "json":
        write_model_json(model, path, sources=sources, input_units=input_units, output_units=output_units,
                         training_segments=training_segments, prior=prior)
    elif training_segments is not None or prior is not None:
        raise FtcalError(f"save_model: training_segments and prior are fields of the JSON model file, not of {fmt}.")
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


# The old names, one release (runtime.deprecation).
read_model = deprecated_alias(load_model, "ftcal.files.model_files.read_model", "ftcal.load_model")
read_model_file = deprecated_alias(load_model_file, "ftcal.files.model_files.read_model_file",
                                   "ftcal.files.model_files.load_model_file")
write_model = deprecated_alias(save_model, "ftcal.files.model_files.write_model", "ftcal.save_model")
