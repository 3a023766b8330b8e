"""Writers for the native model formats (JSON, paper XML, firmware, WBD), in the registry's writer contract.

Each adapter hands a loaded model file to :func:`ftcal.files.model_files.save_model`
with the options its format uses.
"""

from __future__ import annotations

import os
from pathlib import Path

from .model_files import save_model
from .model_json import ModelFile
from .targets import ConvertOptions, Written


def write_json(source: ModelFile, output: Path, options: ConvertOptions) -> Written:
    """Native JSON, keeping units and data sources (the input file when it lists none)."""
    return Written((save_model(source.model, output, "json",
                                sources=source.sources or (str(options.input_path),),
                                input_units=source.input_units, output_units=source.output_units),))


def write_paper_xml(source: ModelFile, output: Path, options: ConvertOptions) -> Written:
    """The paper's XML (raw-input coefficients), with a note of the measured digit loss, found or not.

    The XML holds one degree per file, so a per-output (or per-block) selection says what it wrote.
    """
    from ..core.conversion import PRECISION_TOLERANCE
    from .paper_xml import write_paper_xml as write_xml

    notes = []
    selection = source.model.solver_info_.get("selection") or []
    degrees = sorted({entry.get("degree") for entry in selection})
    if len(degrees) > 1:
        notes.append(f"the paper's XML holds one degree per file: this per-{source.model.solver_info_.get('select_per')} "
                     f"selection (degrees {', '.join(map(str, degrees))}) is written at degree {degrees[-1]}, with "
                     "zero coefficients for the terms an output's own degree does not have")
    loss = write_xml(source.model, output)  # warns (PrecisionLossWarning) when the loss is significant
    notes.append(f"digit-loss check: the raw-input coefficients reproduce the model's predictions to within "
                 f"{loss:.3g} (N, N·m) over the training box; more than {PRECISION_TOLERANCE:g} of an output's "
                 "training range would have printed a warning")
    return Written((output,), tuple(notes))


def write_icub_firmware(source: ModelFile, output: Path, options: ConvertOptions) -> Written:
    """``matrix_<serial>.txt`` (``output`` a file, or a directory plus ``serial``)."""
    target = f"{output}{os.sep}" if options.output_is_folder else output
    return Written((save_model(source.model, target, "icub-firmware", serial=options.get("serial"),
                                input_units=source.input_units),))


def write_wbd(source: ModelFile, output: Path, options: ConvertOptions) -> Written:
    """wholeBodyDynamics groups for ``sensor``."""
    return Written((save_model(source.model, output, "wbd", sensor=options.get("sensor")),))
