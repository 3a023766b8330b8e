"""The demo step: `ftcal demo` prints the summary of `ftcal.sim.demos.demo`, and the step names its parameters."""

from __future__ import annotations

import re

import pytest

from ftcal.cli import main
from ftcal.runtime.errors import ParameterError
from ftcal.sim.demos import demo

# Timings are not results: the elapsed seconds differ between two runs.
TIMING = re.compile(r"done in \d+ s")


def test_the_command_prints_the_steps_summary(tmp_path, capsys):
    result = demo("arm", out=tmp_path / "step", quick=True)
    assert main(["demo", "--scenario", "arm", "--quick", "--out", str(tmp_path / "command")]) == 0
    printed = capsys.readouterr().out
    expected = result.summary().replace(str(tmp_path / "step"), str(tmp_path / "command"))
    assert TIMING.sub("done", printed) == TIMING.sub("done", expected) + "\n"
    assert result.to_dict()["scenario"] == "arm" and (tmp_path / "step" / "summary.json").is_file()


@pytest.mark.parametrize("call, parameter", [(dict(scenario="nope"), "scenario"),
                                             (dict(scenario="paper", variant="long-task"), "variant"),
                                             (dict(scenario="arm", seeds=2), "variant"),
                                             (dict(scenario="closed-loop", seeds=0), "seeds")])
def test_refusals_name_the_parameter(tmp_path, call, parameter):
    with pytest.raises(ParameterError) as caught:
        demo(out=tmp_path / "d", **call)
    assert caught.value.parameter == parameter
    assert not (tmp_path / "d").exists()  # refused before anything is written


def test_an_output_that_is_a_file_is_refused(tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("not a folder")
    with pytest.raises(ParameterError, match="out .*: exists and is not a folder"):
        demo("arm", out=blocker)
