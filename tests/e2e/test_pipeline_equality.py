"""The commands and their Python steps give the same numbers on the demo, with their own defaults.

The README's command pipeline (dataset from robot logs, fit --degree auto, evaluate, dataset from
the arm's ROS 2 bag, payload, compensate, convert) runs through the `ftcal` executable in one copy
of the quick demo; docs/pipeline.ipynb, which calls ``ftcal.build_dataset``, ``ftcal.fit``, ... with
only the keywords the commands spell as flags, runs in another (the shared ``notebook_run``
fixture). Every number is compared: what each command prints against the step's ``summary()``,
``evaluate --json`` against ``to_dict()``, and every written file (JSON numbers to 1e-12 relative,
tables value by value, the YAML byte for byte). Only the creation stamp and the digest that covers
it, and the fit's CPU-time estimate, may differ.
The comparisons' own sensitivity is tested first.
"""

from __future__ import annotations

import json
import math
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from conftest import demo_copy

pytestmark = pytest.mark.slow

FTCAL = str(Path(sys.executable).with_name("ftcal"))
LOGS = "ftcal-demo/logs/train/l0kg-r*/*.mat"
COMMANDS = {
    "dataset": ["dataset", LOGS, "--model", "iCubGenova11", "--sensor", "r_arm_ft",
                "--payload-file", "ftcal-demo/payloads.toml", "--dynamic", "-o", "ftcal-demo/dataset.parquet"],
    "fit": ["fit", "ftcal-demo/dataset.parquet", "--degree", "auto", "--group-by", "load",
            "-o", "ftcal-demo/best.json"],
    "evaluate": ["evaluate", "ftcal-demo/best.json", "ftcal-demo/validation.parquet"],
    "evaluate-json": ["evaluate", "ftcal-demo/best.json", "ftcal-demo/validation.parquet", "--json"],
    "arm": ["dataset", "ftcal-demo/arm", "--wrench-topic", "/ft_sensor/wrench", "--tf", "base_link",
            "--imu-topic", "/imu", "--temperature-topic", "/ft_sensor/temperature", "--no-filter",
            "-o", "ftcal-demo/arm.parquet"],
    "payload": ["payload", "ftcal-demo/arm.parquet", "--orientation", "qx,qy,qz,qw", "--dynamic",
                "--frame", "ft_sensor", "-o", "ftcal-demo/payload.json"],
    "compensate": ["compensate", "ftcal-demo/payload.json", "ftcal-demo/arm.parquet", "--orientation",
                   "qx,qy,qz,qw", "--dynamic", "-o", "ftcal-demo/contact.parquet"],
    "convert": ["convert", "ftcal-demo/payload.json", "--to", "ros-yaml", "-o", "ftcal-demo/ft_calib.yaml"],
}
# Which notebook variable holds each command's result.
STEP_OF = {"dataset": "data", "fit": "fitted", "evaluate": "scores", "arm": "arm", "payload": "tool",
           "compensate": "contact", "convert": "export"}
# Metadata that is not a result: when and by which run a file was written (the digest covers it).
NOT_RESULTS = {"created", "sha256"}
PRINTS_TO_STDERR = {"compensate"}
# The fit's note estimating its CPU time (timings, not results) is in its printout and its file.
ESTIMATE = "estimated work:"
NUMBER = re.compile(r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?")


@pytest.fixture(scope="module")
def commands_run(quick_demo, tmp_path_factory):
    """The command pipeline in a copy of the demo: (folder, {command: stdout})."""
    import glob

    folder = demo_copy(quick_demo, tmp_path_factory.mktemp("commands"))
    printed = {}
    for name, args in COMMANDS.items():
        args = [word for arg in args for word in (sorted(glob.glob(arg, root_dir=folder)) if "*" in arg else [arg])]
        done = subprocess.run([FTCAL, *args], cwd=folder, capture_output=True, text=True, timeout=900)
        assert done.returncode == 0, f"ftcal {' '.join(args)}\n{done.stderr}"
        # compensate prints its one line to stderr (its stdout stays free for the table it writes).
        printed[name] = done.stderr if name in PRINTS_TO_STDERR else done.stdout
    return folder, printed


def numbers(text: str) -> list[str]:
    """The numbers of a printout, in order, as printed; the fit's CPU-time estimate left out."""
    lines = [line for line in text.splitlines() if not line.startswith(ESTIMATE)]
    return NUMBER.findall("\n".join(lines))


def differences(a, b, where: str = "") -> list[str]:
    """Where two JSON values differ: numbers beyond 1e-12 relative, anything else at all."""
    if isinstance(a, dict) and isinstance(b, dict):
        keys = (set(a) | set(b)) - NOT_RESULTS
        return [d for k in sorted(keys) for d in (differences(a.get(k), b.get(k), f"{where}/{k}")
                                                   if k in a and k in b else [f"{where}/{k}: in one only"])]
    if isinstance(a, list) and isinstance(b, list):
        if len(a) != len(b):
            return [f"{where}: {len(a)} vs {len(b)} items"]
        return [d for i, (x, y) in enumerate(zip(a, b)) for d in differences(x, y, f"{where}[{i}]")]
    if isinstance(a, (int, float)) and isinstance(b, (int, float)) and not isinstance(a, bool):
        return [] if math.isclose(a, b, rel_tol=1e-12, abs_tol=0.0) else [f"{where}: {a!r} vs {b!r}"]
    if isinstance(a, str) and isinstance(b, str) and a.startswith(ESTIMATE) and b.startswith(ESTIMATE):
        return []
    return [] if a == b else [f"{where}: {a!r} vs {b!r}"]


def test_the_json_comparison_finds_a_change_in_the_last_digits():
    """The comparison itself: a relative change of 1e-11 or a missing key is found, 1e-13 is not."""
    value = {"a": [1.0, {"b": 2.5}], "created": {"time_utc": "x"}}
    assert differences(value, {"a": [1.0, {"b": 2.5 * (1 + 1e-13)}], "created": {"time_utc": "y"}}) == []
    assert differences(value, {"a": [1.0, {"b": 2.5 * (1 + 1e-11)}], "created": {}}) != []
    assert differences(value, {"a": [1.0, {}], "created": {}}) != []
    assert differences(["estimated work: 5.2 s", "np1"], ["estimated work: 5.6 s", "np1"]) == []
    assert differences(["estimated work: 5.2 s", "np1"], ["estimated work: 5.2 s", "np2"]) != []
    assert numbers("estimated work: 5.6 s\nforce 9.531 N, +0 N, 1e-05·λ") == ["9.531", "+0", "1e-05"]


@pytest.mark.parametrize("command", ["dataset", "fit", "evaluate", "arm", "payload", "compensate", "convert"])
def test_each_command_prints_the_numbers_of_its_step(command, commands_run, notebook_run):
    _, printed = commands_run
    _, namespace, _, _ = notebook_run
    from_python = numbers(namespace[STEP_OF[command]].summary())
    assert numbers(printed[command]) == from_python
    if command in ("fit", "evaluate", "payload"):
        assert len(from_python) > 20  # the tables and estimates, not only a sample count


def test_evaluate_json_is_the_steps_dict(commands_run, notebook_run):
    _, printed = commands_run
    _, namespace, _, _ = notebook_run
    from_command = json.loads(printed["evaluate-json"])
    assert "force_norm_rmse" in from_command
    assert differences(from_command, json.loads(namespace["scores"].to_json())) == []


@pytest.mark.parametrize("name", ["best.json", "payload.json"])
def test_the_written_json_files_hold_the_same_numbers(name, commands_run, notebook_run):
    written = [json.loads((run[0] / "ftcal-demo" / name).read_text(encoding="utf-8"))
               for run in (commands_run, notebook_run)]
    assert differences(*written) == []


@pytest.mark.parametrize("name", ["dataset.parquet", "arm.parquet", "contact.parquet"])
def test_the_written_tables_hold_the_same_values(name, commands_run, notebook_run):
    tables = [pd.read_parquet(run[0] / "ftcal-demo" / name) for run in (commands_run, notebook_run)]
    assert list(tables[0].columns) == list(tables[1].columns) and len(tables[0]) == len(tables[1]) > 0
    for column in tables[0].columns:
        a, b = tables[0][column].to_numpy(), tables[1][column].to_numpy()
        if a.dtype.kind == "f":
            np.testing.assert_allclose(a, b, rtol=1e-12, atol=0.0, err_msg=column)
        else:
            assert (a == b).all(), column


def test_the_exported_file_is_byte_equal(commands_run, notebook_run):
    files = [(run[0] / "ftcal-demo" / "ft_calib.yaml").read_bytes() for run in (commands_run, notebook_run)]
    assert files[0] == files[1] and b"gripper_mass" in files[0]
