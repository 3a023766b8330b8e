"""Every message that suggests a command-line flag suggests one the command accepts (issue 27).

Before the fix ``ftcal compensate`` told users to pass ``--urdf … --sensor`` and then rejected
those flags. This test reads every string of every error, warning and printed message in the
source (``raise …(…)``, ``warnings.warn``, ``print``, ``FtcalError(…)``) with ``ast``, finds the
``--flags`` they name, and checks each against the argparse parser of the command(s) that can
show the message:

- a ``cli/cmd_NAME.py`` module: the command NAME;
- a shared CLI helper (``cli/_*.py``): every command module that imports it;
- a library module: at least one command (the library cannot know its caller; this still
  catches flags that exist nowhere).

A flag written after ``ftcal OTHER`` in the same message is checked against OTHER instead.
"""

from __future__ import annotations

import argparse
import ast
import re
from pathlib import Path

import pytest

from ftcal.cli import COMMAND_MODULES, build_parser

SRC = Path(__file__).resolve().parents[2] / "src" / "ftcal"
FLAG = re.compile(r"(?<![\w-])--[a-z][a-z0-9]*(?:-[a-z0-9]+)*")
OTHER_COMMAND = re.compile(r"ftcal ([a-z]+)\b")
MESSAGE_CALLS = {"FtcalError", "warn", "print", "FtcalWarning", "OutOfRangeWarning", "IllPosedFitWarning",
                 "ValueError", "_fail", "fail"}


def command_options() -> dict[str, dict[str, str | None]]:
    """Per command: each option string and its metavar (None where argparse has none)."""
    parser = build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return {name: {s: action.metavar if isinstance(action.metavar, str) else None
                   for action in p._actions for s in action.option_strings}
            for name, p in sub.choices.items()}


def metavar_after(text: str, end: int) -> str | None:
    """The upper-case placeholder written right after a flag (``--urdf PATH``), if any."""
    match = re.match(r" ([A-Z][A-Z0-9_]*(?:\.[A-Za-z0-9]+)?)(?![\w])", text[end:])
    return match.group(1) if match else None


def message_strings(tree: ast.AST):
    """(line, text) of each string literal (f-string constant parts joined) inside a message call."""
    for node in ast.walk(tree):
        if not isinstance(node, ast.Call):
            continue
        name = node.func.attr if isinstance(node.func, ast.Attribute) else getattr(node.func, "id", "")
        if name not in MESSAGE_CALLS:
            continue
        for arg in [*node.args, *(k.value for k in node.keywords if k.arg in (None, "message"))]:
            text = "".join(literal_parts(arg))
            if "--" in text:
                yield node.lineno, text


def literal_parts(node: ast.AST):
    if isinstance(node, ast.Constant) and isinstance(node.value, str):
        yield node.value
    elif isinstance(node, ast.JoinedStr):
        for value in node.values:
            yield from literal_parts(value)
    elif isinstance(node, ast.BinOp):
        yield from literal_parts(node.left)
        yield from literal_parts(node.right)
    elif isinstance(node, ast.IfExp):
        yield from literal_parts(node.body)
        yield " "
        yield from literal_parts(node.orelse)
    elif isinstance(node, ast.FormattedValue):
        yield "{}"


def suggested(text: str, default: set[str] | None):
    """(flag, commands it must belong to, placeholder after it) per flag; a preceding 'ftcal OTHER' overrides."""
    for match in FLAG.finditer(text):
        # 'ftcal OTHER' names a command only when OTHER is one ("an ftcal history", "ftcal keeps" are prose).
        before = [name for name in OTHER_COMMAND.findall(text[:match.start()]) if name in COMMAND_MODULES]
        yield match.group(0), ({before[-1]} if before else default), metavar_after(text, match.end())


def accepted(options: dict, command: str, flag: str, placeholder: str | None) -> bool:
    """The command has the flag, and the flag takes what the message says it takes (``--model NAME``
    is not ``--model CAL.json``)."""
    if flag not in options.get(command, {}):
        return False
    metavar = options[command][flag]
    return placeholder is None or metavar is None or metavar == placeholder or "," in metavar


def modules():
    cli = SRC / "cli"
    importers: dict[str, set[str]] = {}
    for name in COMMAND_MODULES:
        path = cli / f"cmd_{name.replace('-', '_')}.py"
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ImportFrom) and node.level == 1 and node.module:
                importers.setdefault(node.module, set()).add(name)
    for path in sorted(SRC.rglob("*.py")):
        if path.parent == cli and path.name.startswith("cmd_"):
            yield path, {path.stem[4:].replace("_", "-")}
        elif path.parent == cli and path.name.startswith("_") and path.name != "__init__.py":
            yield path, importers.get(path.stem, set()) or None
        else:
            yield path, None  # the library: any command


def test_every_suggested_flag_is_accepted_by_its_command():
    options = command_options()
    wrong = []
    for path, commands in modules():
        for line, text in message_strings(ast.parse(path.read_text())):
            for flag, owners, placeholder in suggested(text, commands):
                if owners is None:
                    ok = any(accepted(options, c, flag, placeholder) for c in options)
                else:
                    ok = all(accepted(options, c, flag, placeholder) for c in owners)
                if not ok:
                    wrong.append(f"{path.relative_to(SRC)}:{line}: {flag} (commands {sorted(owners or ['any'])})")
    assert not wrong, "\n".join(wrong)


def test_the_scanner_finds_a_wrong_suggestion(tmp_path):
    """The check can fail: a message of compensate suggesting a flag compensate does not have is caught."""
    options = command_options()
    tree = ast.parse('raise FtcalError(f"give --orientation or a calibration (--calibration NAME) with --sensor {x}")')
    found = [(flag, accepted(options, "compensate", flag, placeholder)) for _, text in message_strings(tree)
             for flag, _, placeholder in suggested(text, {"compensate"})]
    # compensate's --calibration is a model file (CAL.json), not a NAME: a wrong placeholder is caught
    assert found == [("--orientation", True), ("--calibration", False), ("--sensor", True)]
    assert accepted(options, "payload", "--model", "NAME")
    tree = ast.parse('raise FtcalError("pass --robot-name X")')
    assert [f for _, t in message_strings(tree) for f, _, p in suggested(t, {"compensate"})
            if not accepted(options, "compensate", f, p)] == ["--robot-name"]
