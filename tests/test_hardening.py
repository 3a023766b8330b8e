"""One regression test per class of hostile or broken input (issue 17).

Each test names the class it guards and says why it fails on the code before
the fix. Hostile strings come from model/payload files (not trusted); the
command line is trusted.
"""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from ftcal.cli import main
from ftcal.core.dataset import Dataset
from ftcal.core.model import CalibrationModel
from ftcal.files.c_code import generate_c
from ftcal.files.model_json import save_model

CC = shutil.which("cc")
CXX = shutil.which("c++")
NM = shutil.which("nm")
needs_cc = pytest.mark.skipif(CC is None or NM is None, reason="needs a C compiler `cc` and `nm`")

# Names an attacker could put in a model file, each trying to end the comment or the string
# literal it lands in and declare a symbol of its own (injected_*): plain `*/`, a trailing
# backslash that splices the next line into the comment, the trigraph ??/ (a backslash under
# -std=c99), a bidirectional override, a quote and a raw newline.
HOSTILE = (
    "a */ int injected_a; /*",
    "b*\\\n/ int injected_b; /*",
    "c*??/\n/ int injected_c; /*",
    "d\u202e */ int injected_d; /* \u2066",
    'e"; int injected_e; static const char *x = "',
    "f\n#define predict injected_f\n",
    "g\\",
    "h??/",
    "i\x00\x1b[2J\U0001F600\udcff",
)


def hostile_model(n_inputs=3, n_outputs=2, **fit) -> CalibrationModel:
    rng = np.random.default_rng(0)
    u = rng.uniform(-1, 1, (60, n_inputs))
    y = u[:, :n_outputs] * 2.0 + 0.5
    data = Dataset.from_arrays(u, y, input_names=HOSTILE[:n_inputs], output_names=HOSTILE[n_inputs:n_inputs + n_outputs])
    return CalibrationModel(1, **fit).fit(data)


def defined_symbols(obj: Path) -> set[str]:
    out = subprocess.run([NM, "--defined-only", "-P", str(obj)], capture_output=True, text=True, check=True).stdout
    return {line.split()[0] for line in out.splitlines() if line.strip()}


@needs_cc
def test_names_from_the_model_file_never_become_c_code(tmp_path):
    """Class: data as code in generated C (comment terminators, line splices, trigraphs, bidi, quotes).

    Before the fix the header comment only replaced ``*/``: the names ending in a
    backslash or ``??/`` spliced the next comment line (``/``) onto ``*``, which
    closed the comment and declared ``injected_b`` / ``injected_c``.
    """
    model = hostile_model()
    code = generate_c(model, name="cal", source_name="evil */ int injected_g; /*\\",
                      input_units=["N*/ int injected_h; /*", "\\", "??/"], output_units=["*\\", "/"])
    (tmp_path / "cal.h").write_text(code.header)
    (tmp_path / "cal.c").write_text(code.source)
    for text in (code.header, code.source):
        assert all(" " <= ch <= "~" or ch == "\n" for ch in text), "only printable ASCII and newlines"
        assert not re.search(r"\\\n", text) and "??" not in re.sub(r'"[^"\n]*"', "", text)
    subprocess.run([CC, "-std=c99", "-trigraphs", "-Wall", "-Wextra", "-Werror", "-pedantic", "-c", "cal.c",
                    "-o", "cal.o"], cwd=tmp_path, check=True, capture_output=True, text=True)
    assert defined_symbols(tmp_path / "cal.o") == {"cal_in_range", "cal_input_names", "cal_output_names",
                                                   "cal_predict"}
    # The string tables hold the names' exact UTF-8 bytes (lone surrogates as surrogate-escaped bytes).
    driver = ('#include <stdio.h>\n#include "cal.h"\nint main(void) { int i; for (i = 0; i < CAL_N_INPUTS; ++i) '
              'fwrite(cal_input_names[i], 1, __builtin_strlen(cal_input_names[i]) + 1, stdout); return 0; }\n')
    (tmp_path / "d.c").write_text(driver)
    subprocess.run([CC, "d.c", "cal.o", "-o", "d"], cwd=tmp_path, check=True, capture_output=True)
    out = subprocess.run([str(tmp_path / "d")], capture_output=True, check=True).stdout
    assert out.split(b"\0")[:-1] == [n.encode("utf-8", "surrogatepass") for n in HOSTILE[:3]]
    if CXX:  # the header is also C++ (extern "C")
        (tmp_path / "x.cpp").write_text('#include "cal.h"\nint main() { return CAL_N_INPUTS - 3; }\n')
        subprocess.run([CXX, "-std=c++98", "-trigraphs", "-Wall", "-Werror", "-c", "x.cpp"], cwd=tmp_path,
                       check=True, capture_output=True)


def test_names_from_the_model_file_never_become_xml_or_yaml(tmp_path):
    """Class: data as markup in generated XML (WBD comment) and YAML (ROS frame names).

    Before the fix the WBD comment copied the names verbatim, so ``-->`` closed it and
    the next text became an XML element.
    """
    import xml.etree.ElementTree as ET

    import yaml

    from ftcal.files.ros_yaml import ros_yaml_text
    from ftcal.files.wbd import format_wbd
    from ftcal.payload.parameters import PayloadParameters

    rng = np.random.default_rng(1)
    names = ["x --><group name='injected'/><!--"] + [f"u{i}" for i in range(5)]
    u = rng.uniform(-1, 1, (80, 6))
    model = CalibrationModel(1).fit(Dataset.from_arrays(u, u @ rng.normal(size=(6, 6)), input_names=tuple(names), output_names=
                                            ("Fx", "Fy", "Fz", "Tx", "Ty", "Tz-")))
    root = ET.fromstring("<root>" + format_wbd(model, "ft") + "</root>")
    assert [g.get("name") for g in root] == ["FT_SECONDARY_CALIBRATION", "FT_OFFSET"]
    frame = 'f"\n\u2028injected: 1\x85\\'
    payload = PayloadParameters(1.0, np.zeros(3), np.zeros(3), np.zeros(3), 9.81, frame=frame)
    document = yaml.safe_load(ros_yaml_text(payload))
    assert document["gripper_com_frame_id"] == frame and "injected" not in document


def test_multi_file_export_is_all_or_nothing(tmp_path):
    """Class: lost/partial output of a multi-file export (``.h`` + ``.c``).

    The second file cannot be written (a directory stands at ``cal.c``); before the
    fix ``cal.h`` had already been renamed into place and stayed behind.
    """
    model = hostile_model()
    source = tmp_path / "m.json"
    save_model(model, source)
    out = tmp_path / "out"
    (out / "cal.c").mkdir(parents=True)
    assert main(["convert", str(source), "--to", "c", "--name", "cal", "-o", f"{out}/"]) == 2
    assert sorted(p.name for p in out.iterdir()) == ["cal.c"]
    assert (out / "cal.c").is_dir()
