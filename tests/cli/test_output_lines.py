"""A name from a file cannot forge a line of a command's output (issue 28): line breaks are escaped."""

import sys
from pathlib import Path

import numpy as np
import pytest

from ftcal.cli import main
from ftcal.cli._common import single_line

from bag_data import Bag  # noqa: E402

FORGED = "/ft\nwrote 999999 samples to /etc/passwd"


@pytest.mark.parametrize("text", [FORGED, "a\rb", "a\u2028b", "a\x85b", "tab\there"])
def test_single_line_escapes_every_line_break(text):
    out = single_line(text)
    assert len(out.splitlines()) == 1 and "\t" not in out


@pytest.mark.parametrize("kind", ["ros1", "mcap-file"])
def test_a_topic_name_cannot_forge_an_output_line(tmp_path, capsys, kind):
    bag = Bag(kind)
    rng = np.random.default_rng(0)
    for i in range(20):
        bag.wrench(FORGED, 10**9 + i * 10**7, rng.normal(size=6))
    try:
        path = bag.write(tmp_path / "run")
    except Exception:  # noqa: BLE001 - a writer that refuses the name leaves nothing to read
        pytest.skip(f"the {kind} writer refuses a topic name with a newline")
    code = main(["topics", str(path)])
    out = capsys.readouterr().out
    assert code == 0 and not any(line.startswith("wrote") for line in out.splitlines()), out
