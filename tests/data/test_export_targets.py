"""The convert registry: every target resolves, input kinds are read from the file's format field."""

from __future__ import annotations

import json

import numpy as np
import pytest

from ftcal.cli import main
from ftcal.core.model import CalibrationModel
from ftcal.files import targets
from ftcal.files.model_files import save_model
from ftcal.runtime.errors import FtcalError


@pytest.mark.parametrize("name", list(targets.TARGETS))
def test_every_target_has_a_writer_and_a_reader_for_its_input(name):
    spec = targets.TARGETS[name]
    assert callable(targets.resolve(spec.writer))
    assert spec.accepts in targets.INPUT_READERS
    assert spec.output in (targets.FILE, targets.DIRECTORY, targets.FILE_OR_DIRECTORY)


def test_input_kind_comes_from_the_format_field(tmp_path):
    rng = np.random.default_rng(0)
    model_path = tmp_path / "m.json"
    save_model(CalibrationModel(1).fit(rng.normal(size=(50, 2)), rng.normal(size=(50, 1))), model_path)
    payload = tmp_path / "p.json"
    payload.write_text(json.dumps({"format": "ftcal-payload", "mass": 1.0}))
    xml = tmp_path / "m.xml"
    xml.write_text("<group/>")
    assert targets.input_kind(model_path) == targets.MODEL
    assert targets.input_kind(payload) == targets.PAYLOAD
    assert targets.input_kind(xml) == targets.MODEL
    with pytest.raises(FtcalError, match="p.json is an ftcal-payload file; to c takes an ftcal-model file"):
        targets.write_target(payload, "c", tmp_path / "out", {})
    assert not (tmp_path / "out").exists()


def test_output_kinds_are_checked_before_reading(tmp_path, capsys):
    missing = tmp_path / "missing.json"  # never read: the output is refused first
    folder = tmp_path / "dir.onnx"
    folder.mkdir()
    for argv, fragment in [(["--to", "onnx", "-o", folder], "is a directory; --to onnx writes a file"),
                           (["--to", "onnx", "-o", tmp_path / "m.txt"], "must end in .onnx"),
                           (["--to", "wbd", "-o", missing], "is also an input")]:
        if fragment == "is also an input":
            missing.write_text("{}")
        assert main(["convert", str(missing), *map(str, argv)]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and fragment in err[0], err
