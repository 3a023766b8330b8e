"""README.md runs as written: every `ftcal` command and the Python snippet, in order, after the demo.

The demo runs once, into a temporary folder that stands in for the repository root (so the
README's `ftcal-demo/...` paths resolve there). It runs at its `--quick` size; so does any
`ftcal demo` command the README holds. Everything else runs exactly as the README spells it.
"""

from __future__ import annotations

import glob
import re
import shlex
import subprocess
import sys
from pathlib import Path

import pytest

README = Path(__file__).resolve().parents[2] / "README.md"
FTCAL = str(Path(sys.executable).with_name("ftcal"))
DEMO = ["demo", "--out", "ftcal-demo", "--quick"]
OUTPUT_OPTIONS = ("-o", "--output", "--out")


def code_blocks(text: str, languages: tuple[str, ...]) -> list[str]:
    """Bodies of the fenced code blocks whose info string is one of ``languages``."""
    return [m.group(2) for m in re.finditer(r"^```(\w*)[^\n]*\n(.*?)^```", text, re.M | re.S)
            if m.group(1) in languages]


def ftcal_commands(text: str) -> list[list[str]]:
    """Each `ftcal ...` command line of the shell blocks, continuations joined, comments dropped."""
    commands = []
    for block in code_blocks(text, ("", "sh", "shell", "bash", "console")):
        for line in block.replace("\\\n", " ").splitlines():
            words = shlex.split(line, comments=True)
            if words and words[0] == "ftcal":
                commands.append(words[1:])
    return commands


def expand(words: list[str], cwd: Path) -> list[str]:
    """What the shell would pass: glob patterns replaced by the sorted files they match."""
    out = []
    for word in words:
        matches = sorted(glob.glob(word, root_dir=cwd)) if glob.has_magic(word) else []
        out += matches or [word]
    return out


def run_ftcal(args: list[str], cwd: Path) -> subprocess.CompletedProcess:
    return subprocess.run([FTCAL, *args], cwd=cwd, capture_output=True, text=True, timeout=900)


@pytest.fixture(scope="module")
def repo_root(tmp_path_factory, quick_demo) -> Path:
    """A copy of the session's quick demo (conftest.py runs `ftcal demo --out ftcal-demo --quick` once)."""
    import shutil

    root = tmp_path_factory.mktemp("readme")
    shutil.copytree(quick_demo / "ftcal-demo", root / "ftcal-demo")
    return root


def test_the_readme_has_commands_for_the_whole_flow():
    commands = ftcal_commands(README.read_text(encoding="utf-8"))
    # The extraction itself: continuation lines joined, trailing comments dropped.
    assert ["sensors", "--model", "iCubGenova11"] in commands
    assert all("#" not in word for command in commands for word in command)
    assert {"fit", "evaluate", "predict", "dataset"} <= {c[0] for c in commands}


@pytest.mark.slow
def test_every_readme_command_runs_as_written(repo_root):
    for words in ftcal_commands(README.read_text(encoding="utf-8")):
        args = expand(words, repo_root)
        if args[0] == "demo":
            args = [*args, "--quick"]
            if args == DEMO:
                continue  # what the fixture ran
        done = run_ftcal(args, repo_root)
        shown = "ftcal " + shlex.join(words)
        assert done.returncode == 0, f"{shown}\n{done.stderr}"
        assert "Traceback" not in done.stderr, shown
        # The README's flow never evaluates a model on its own training recordings.
        assert "training segment" not in done.stderr, f"{shown}\n{done.stderr}"
        for option, value in zip(args, args[1:]):
            if option in OUTPUT_OPTIONS:
                written = repo_root / value
                assert written.exists() and (written.is_dir() or written.stat().st_size > 0), shown
                if written.is_dir():
                    assert any(written.iterdir()), shown
        assert not list(repo_root.rglob("*.tmp")), f"{shown} left a temporary file"


@pytest.mark.slow
def test_the_python_snippet_runs_as_written(repo_root):
    blocks = code_blocks(README.read_text(encoding="utf-8"), ("python",))
    assert blocks
    for block in blocks:
        done = subprocess.run([sys.executable, "-c", block], cwd=repo_root, capture_output=True,
                              text=True, timeout=900)
        assert done.returncode == 0, done.stderr
    # The snippet's last line saves a model that the CLI reads back.
    assert run_ftcal(["info", "ftcal-demo/np4.json"], repo_root).returncode == 0


def test_every_file_the_code_and_docs_cite_is_in_the_repository():
    root = README.parent
    cited = re.compile(r"(?<![\w/.-])((?:[\w-]+/)*[\w-]+\.md)\b")
    missing = []
    for path in [*root.glob("src/**/*.py"), *root.glob("tests/**/*.py"), *root.glob("benchmarks/*.py"),
                 *root.glob("*.md"), *root.glob("docs/*.md")]:
        for name in cited.findall(path.read_text(encoding="utf-8")):
            if not (root / name).exists() and not (path.parent / name).exists():
                missing.append(f"{path.relative_to(root)} cites {name}")
    assert not missing
