"""The ``ftcal convert`` registry: target name → what it reads, what it writes, and its writer.

A new target is one module with a writer function plus one line in
:data:`TARGETS`. A writer is called as ``writer(source, output, options)`` with

- ``source``: what the input kind's reader returned (for ``ftcal-model`` files a
  :class:`~ftcal.files.model_json.ModelFile`),
- ``output``: the ``-o`` path (already checked against the target's output kind),
- ``options``: a :class:`ConvertOptions`,

and returns the paths it wrote plus notes for the user. It raises
:class:`~ftcal.runtime.errors.FtcalError` before writing anything when it cannot export.

Input kinds are the ``format`` field of an ftcal JSON document (paper XML files
are model files). A target declares the kind it accepts, so targets that take a
payload file (``format: "ftcal-payload"``) only need a reader in
:data:`INPUT_READERS` and their lines in :data:`TARGETS`.

This module imports no numpy: ``ftcal convert --help`` lists the targets from it.
"""

from __future__ import annotations

import importlib
import json
import os
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..core.families import check_export
from ..core.limits import MAX_MODEL_BYTES
from ..runtime.errors import FtcalError, ParameterError
from ..runtime.inputs import check_input_file
from ..runtime.deprecation import deprecated_alias

MODEL = "ftcal-model"
PAYLOAD = "ftcal-payload"
FILE, DIRECTORY, FILE_OR_DIRECTORY = "file", "directory", "file or directory"


@dataclass(frozen=True)
class Target:
    """One ``--to`` target.

    Attributes
    ----------
    accepts : input kind it reads (:data:`MODEL` or :data:`PAYLOAD`)
    output : :data:`FILE`, :data:`DIRECTORY` (created if missing) or :data:`FILE_OR_DIRECTORY`
    suffixes : endings a file output must have; empty means any
    writer : ``"module:function"``, imported only when the target is used
    summary : a few words for ``--help``
    """

    accepts: str
    output: str
    suffixes: tuple[str, ...]
    writer: str
    summary: str


@dataclass(frozen=True)
class ConvertOptions:
    """What a writer may use besides the source: the input path and the target's own options.

    ``values`` holds the command-line options by name (``serial``, ``sensor``,
    ``name``, ``single_precision``, ...); a target reads the ones it declares.
    """

    input_path: Path
    values: Mapping[str, Any] = field(default_factory=dict)
    output_is_folder: bool = False  # ``-o DIR/``: a trailing separator names a folder (made if missing)

    def get(self, name: str, default: Any = None) -> Any:
        value = self.values.get(name)
        return default if value is None else value


@dataclass(frozen=True)
class Written:
    """Paths a writer wrote, and notes to print (such as a measured precision)."""

    paths: tuple[Path, ...]
    notes: tuple[str, ...] = ()


TARGETS: dict[str, Target] = {
    "json": Target(MODEL, FILE, (".json",), "ftcal.files.model_formats:write_json", "ftcal JSON model"),
    "paper-xml": Target(MODEL, FILE, (".xml",), "ftcal.files.model_formats:write_paper_xml", "the paper's XML"),
    "icub-firmware": Target(MODEL, FILE_OR_DIRECTORY, (), "ftcal.files.model_formats:write_icub_firmware",
                            "iCub strain-board matrix (affine, ADC counts)"),
    "wbd": Target(MODEL, FILE, (), "ftcal.files.model_formats:write_wbd",
                  "wholeBodyDynamics groups (affine, optional T)"),
    "c": Target(MODEL, DIRECTORY, (), "ftcal.files.c_code:write_c", "C99 NAME.h + NAME.c"),
    "c-runtime": Target(MODEL, FILE, (".h",), "ftcal.live.c_runtime:write_c_runtime",
                        "C99 live step NAME.h: calibration, tool, bias filter, health (--payload-file)"),
    "cpp-runtime": Target(MODEL, FILE, (".hpp",), "ftcal.live.cpp_runtime:write_cpp_runtime",
                          "C++17 wrapper NAME.hpp (RAII, std::array) beside the C99 live step NAME.h"),
    "onnx": Target(MODEL, FILE, (".onnx",), "ftcal.files.onnx_graph:write_onnx", "ONNX graph (static models)"),
    "ros-yaml": Target(PAYLOAD, FILE, (".yaml", ".yml"), "ftcal.files.payload_formats:write_force_torque_tools",
                       "force_torque_tools ft_calib YAML (payload files)"),
    "ft-tools-ros2": Target(PAYLOAD, FILE, (".yaml", ".yml"), "ftcal.files.payload_formats:write_ft_tools_ros2_yaml",
                            "ft_tools_ros2 calibration.yaml (payload files)"),
    "admittance-controller": Target(PAYLOAD, FILE, (".yaml", ".yml"),
                                    "ftcal.files.controller_formats:write_admittance",
                                    "ros2_controllers admittance_controller gravity_compensation (payload files)"),
    "gravity-compensation-filter": Target(PAYLOAD, FILE, (".yaml", ".yml"),
                                          "ftcal.files.controller_formats:write_gravity_filter",
                                          "control_toolbox GravityCompensation filter (payload files)"),
    "ur-payload": Target(PAYLOAD, FILE, (".script", ".urscript", ".txt"),
                         "ftcal.files.controller_formats:write_ur_payload",
                         "URScript set_payload and ur_msgs SetPayload (payload files)"),
}

FAMILY_WRITERS: dict[tuple[str, str], str] = {
    ("c", "mlp"): "ftcal.files.mlp_code:write_c",
    ("onnx", "mlp"): "ftcal.files.mlp_code:write_onnx",
}
"""(target, model family) → writer, where a family's models need their own writer for a target;
other families use the target's. A family lists the targets it accepts in its ``exports``."""

INPUT_READERS: dict[str, str] = {
    MODEL: "ftcal.files.model_files:load_model_file",
    PAYLOAD: "ftcal.files.payload_json:load_payload",
}

_SNIFF_BYTES = 512


def target(name: str) -> Target:
    """The registered target ``name``; one-line :class:`FtcalError` naming the choices otherwise."""
    try:
        return TARGETS[name]
    except KeyError:
        raise ParameterError('to', f"{{to}} {name}: unknown target; choose one of {', '.join(TARGETS)}.") from None


def input_kind(path: str | Path) -> str:
    """:data:`MODEL` for paper XML files, else the ``format`` field of the ftcal JSON document."""
    path = check_input_file(path, "model or payload file", max_bytes=MAX_MODEL_BYTES)
    try:
        with open(path, "rb") as fh:
            head = fh.read(_SNIFF_BYTES)
    except OSError as exc:
        raise FtcalError(f"Cannot read {path}: {exc.strerror}.") from None
    if head.lstrip(b"\xef\xbb\xbf \t\r\n")[:1] != b"{":
        return MODEL  # paper XML, or something the model reader rejects with its own message
    try:
        document = json.loads(path.read_text(encoding="utf-8"))
    except (ValueError, OSError, RecursionError):
        return MODEL  # the model reader says what is wrong with it
    kind = document.get("format") if isinstance(document, dict) else None
    return kind if kind in INPUT_READERS or kind == PAYLOAD else MODEL


def resolve(dotted: str) -> Callable:
    """The function named by ``"module:function"``."""
    module, _, function = dotted.partition(":")
    return getattr(importlib.import_module(module), function)


def check_output(name: str, spec: Target, output: Path, input_path: Path) -> None:
    """Refuse an output the target cannot write, before anything is read or written."""
    if spec.output == FILE:
        if output.is_dir():
            raise ParameterError(('output', 'to'), f"{{output}} {output} is a directory; {{to}} {name} writes a file.")
        if spec.suffixes and not output.name.lower().endswith(spec.suffixes):
            raise ParameterError('output', f"{{output}} {output}: must end in {' or '.join(spec.suffixes)}.")
    elif spec.output == DIRECTORY and output.exists() and not output.is_dir():
        raise ParameterError(('output', 'to'), f"{{output}} {output} is a file; {{to}} {name} writes files into a directory.")
    if output.exists() and output.resolve() == input_path.resolve():
        raise ParameterError('output', f"{{output}} {output} is the input file; choose another output path.")


def write_target(input_path: str | Path, name: str, output: str | Path, values: Mapping[str, Any]) -> Written:
    """Read ``input_path`` and write it as target ``name`` to ``output``.

    Parameters
    ----------
    input_path : model file (ftcal JSON or paper XML) or another registered input kind
    name : a key of :data:`TARGETS`
    output : file or directory, as the target declares
    values : target options by name (see :class:`ConvertOptions`)

    Returns
    -------
    Written

    Raises
    ------
    FtcalError
        Unknown target, an input kind the target does not take, a target the model's
        family cannot be exported to, a bad output path, or anything the writer refuses; nothing is written then.
    """
    spec = target(name)
    output_is_folder = str(output).endswith(("/", os.sep))
    input_path, output = Path(input_path), Path(output)
    if output_is_folder and spec.output == FILE:
        raise ParameterError(('output', 'to'), f"{{output}} {output}{os.sep} names a folder; {{to}} {name} writes a file.")
    check_output(name, spec, output, input_path)
    kind = input_kind(input_path)
    if kind != spec.accepts:
        raise ParameterError('to', f"{input_path} is an {kind} file; {{to}} {name} takes an {spec.accepts} file.")
    if kind not in INPUT_READERS:
        raise FtcalError(f"{input_path}: this ftcal cannot read {kind} files.")
    source = resolve(INPUT_READERS[kind])(input_path)
    writer = spec.writer
    if kind == MODEL:
        check_export(source.model, name)  # a family lists the targets it can be written to
        writer = FAMILY_WRITERS.get((name, source.model.family), writer)
    return resolve(writer)(source, output, ConvertOptions(input_path, dict(values), output_is_folder))


# The old name, shadowed by the convert step (ftcal.convert, another signature).
convert = deprecated_alias(write_target, "ftcal.files.targets.convert", "ftcal.files.targets.write_target")
