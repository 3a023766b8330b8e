"""Light commands stay light (issue 43, item 5): what ``ftcal info MODEL`` and ``ftcal --help`` import.

``info`` reads a valid static polynomial JSON model file without numpy (:mod:`ftcal.files.model_info`);
other families, ARX models and invalid files go through the full loader, which imports numpy.

An invariant, not a time: the real command runs in a fresh interpreter with ``-X importtime``, whose
report names every module the process imported; the heavy libraries a model file's description does
not use must not be among them.
"""

import os
import pathlib
import subprocess
import sys

import numpy as np
import pytest

from ftcal.core.dataset import Dataset
from ftcal.core.model import CalibrationModel
from ftcal.files.model_files import save_model

SRC = os.path.join(os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__)))), "src")


def imported(*argv) -> set[str]:
    env = dict(os.environ, PYTHONPATH=SRC, FTCAL_PROGRESS="0")
    done = subprocess.run([sys.executable, "-X", "importtime", "-m", "ftcal", *argv], env=env,
                          capture_output=True, text=True, timeout=120)
    assert done.returncode in (0, 2), done.stderr[-2000:]
    return {line.rsplit("|", 1)[1].strip() for line in done.stderr.splitlines() if line.startswith("import time:")}


@pytest.fixture(scope="module")
def model_file(tmp_path_factory):
    rng = np.random.default_rng(0)
    u = rng.normal(size=(500, 3))
    path = tmp_path_factory.mktemp("light") / "model.json"
    save_model(CalibrationModel(2).fit(Dataset.from_arrays(u, u ** 2 + u, input_names=["a", "b", "c"],
                                                           output_names=["Fx", "Fy", "Fz"])), path)
    return str(path)


def test_info_imports_no_numerical_library(model_file):
    modules = imported("info", model_file)
    assert {"ftcal.files.model_info", "ftcal.files.json_document"} <= modules  # the report is the real run's
    assert not modules & {"numpy", "scipy", "pyarrow", "jsonschema", "pandas"}


def test_an_arx_model_file_still_goes_through_the_full_loader(tmp_path):
    rng = np.random.default_rng(1)
    u = rng.normal(size=(300, 2))
    path = tmp_path / "arx.json"
    model = CalibrationModel(1, na=1, nb=1).fit(Dataset.from_arrays(u, u + 0.01 * rng.normal(size=u.shape)))
    save_model(model, path)
    assert {"ftcal.files.model_files", "numpy"} <= imported("info", str(path))


def test_an_invalid_model_file_still_gets_jsonschema_s_message(model_file, tmp_path):
    """jsonschema words the error of a document the schema refuses (and is imported for it, only then)."""
    broken = tmp_path / "broken.json"
    broken.write_text(pathlib.Path(model_file).read_text().replace('"format_version": "1.0"', '"format_version": "1.0", "x": 1'))
    env = dict(os.environ, PYTHONPATH=SRC, FTCAL_PROGRESS="0")
    done = subprocess.run([sys.executable, "-m", "ftcal", "info", str(broken)], env=env, capture_output=True,
                          text=True, timeout=120)
    assert done.returncode == 2
    assert "invalid model file at $: Additional properties are not allowed ('x' was unexpected)" in done.stderr


def test_help_imports_no_numerical_library():
    modules = imported("--help")
    assert "ftcal.cli" in modules
    assert not modules & {"numpy", "pyarrow", "scipy", "jsonschema", "pandas"}
