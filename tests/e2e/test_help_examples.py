"""Every command's --help has examples, and each runs exactly as written after the demo.

Like tests/e2e/test_readme.py: the examples run in a copy of the session's quick demo (conftest.py builds
it once per run), a temporary folder standing in for the repository root; then each command's examples run, in the order of
`ftcal --help` (the workflow), each command's in the order written.
"""

from __future__ import annotations

import shlex
import subprocess
import sys
from pathlib import Path

import pytest
from test_readme import DEMO, OUTPUT_OPTIONS, expand, run_ftcal

from ftcal.cli import COMMAND_MODULES

FTCAL = str(Path(sys.executable).with_name("ftcal"))


def help_output(*command: str) -> str:
    done = subprocess.run([FTCAL, *command, "--help"], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    return done.stdout


def examples(text: str) -> list[list[str]]:
    """The `ftcal ...` commands of the "examples:" section of a help text, continuations joined."""
    assert "\nexamples:\n" in text
    section = text.split("\nexamples:\n", 1)[1].replace("\\\n", " ")
    commands = []
    for line in section.splitlines():
        words = shlex.split(line, comments=True)
        if words and words[0] == "ftcal":
            commands.append(words[1:])
    return commands


def test_every_command_has_examples_of_itself():
    for name in COMMAND_MODULES:
        commands = examples(help_output(name))
        assert any(c[0] == name for c in commands), name


def test_the_top_help_lists_the_commands_in_workflow_order():
    text = help_output()
    listed = [line.split()[0] for line in text.split("COMMAND\n", 1)[1].split("\noptions:")[0].splitlines()
              if line.startswith("    ") and not line.startswith("      ")]
    assert listed == list(COMMAND_MODULES)
    # The pipeline sketch names the steps in the order the commands are listed.
    sketch = text.split("calibration:", 1)[1].splitlines()[0]
    steps = ["sensors", "expected", "dataset", "fit", "evaluate", "report", "convert"]
    assert [sketch.index(s) for s in steps] == sorted(sketch.index(s) for s in steps)
    assert all(listed.index(a) < listed.index(b) for a, b in zip(steps, steps[1:]))


def test_the_options_newcomers_asked_about_say_what_they_do():
    def option_help(command: str, option: str) -> str:
        text = " ".join(help_output(command).split())
        return text.rsplit(f" {option} ", 1)[1].split(" --", 1)[0]  # the last mention: the options list

    assert "predicted wrench" in option_help("predict", "--output OUT.csv|OUT.parquet")
    assert "payload file" in option_help("payload", "--output PAYLOAD.json")
    frame = option_help("convert", "--frame FRAME")
    # the targets that read it, and the one that ignores it
    assert all(t in frame for t in ("ros-yaml,", "admittance-controller,", "gravity-compensation- filter:"))
    assert "ignored by ft-tools-ros2" in frame


@pytest.fixture(scope="module")
def demo_root(tmp_path_factory, quick_demo) -> Path:
    import shutil

    root = tmp_path_factory.mktemp("help-examples")
    shutil.copytree(quick_demo / "ftcal-demo", root / "ftcal-demo")
    return root


@pytest.mark.slow
def test_every_help_example_runs_as_written(demo_root):
    for name in COMMAND_MODULES:
        for words in examples(help_output(name)):
            args = expand(words, demo_root)
            if args[0] == "demo":
                args = [*args, "--quick"]
                if args == DEMO:
                    continue  # what the fixture ran
            done = run_ftcal(args, demo_root)
            shown = f"ftcal {name} --help: ftcal {shlex.join(words)}"
            assert done.returncode == 0, f"{shown}\n{done.stderr}"
            assert "Traceback" not in done.stderr, shown
            for option, value in zip(args, args[1:]):
                if option in OUTPUT_OPTIONS:
                    written = demo_root / value
                    assert written.exists(), shown
                    assert written.is_dir() and any(written.iterdir()) or written.stat().st_size > 0, shown
            assert not list(demo_root.rglob("*.tmp")), f"{shown} left a temporary file"
