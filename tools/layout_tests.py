"""Lay the tests out like the code: ``tests/{core,data,live,workflow,cli,e2e}/`` and ``tests/helpers/``.

``python tools/layout_tests.py [--dry-run]`` moves every ``tests/test_*.py`` still at the top of ``tests/``
into the folder of the layer it exercises, chosen by rule from what the file imports and runs (so a file
this script has never seen lands by the same rule), and the helper modules the tests import
(``tests/*.py`` other than ``conftest.py``) into ``tests/helpers/``. It then fixes what the move breaks:

- paths computed from ``__file__`` in a moved file gain one level (``.parent`` -> ``.parents[1]``, ...);
- ``sys.path.insert(0, <the tests folder>)`` lines go (pytest's ``pythonpath`` finds the helpers);
- every mention ``tests/NAME.py`` in the repository's text (README, docs, src, tests, benchmarks,
  Makefile, .ci) names the new place;
- code putting ``tests`` on ``sys.path`` for a helper (benchmarks) points at ``tests/helpers``;
- ``pyproject.toml`` gets ``pythonpath`` and the layer markers if it lacks them.

Files already in a sub-folder are left alone, so running it twice changes nothing. Moves use ``git mv``
inside a git work tree. The rule, first match wins:

1. a word of its name says the layer (``cli``; ``demo``, ``readme``, ``notebook`` -> ``e2e``; ``export``
   -> ``data``; ``workflow``, ``step`` -> ``workflow``; ``live``), or it imports another test module (it goes
   beside that one);
2. ``e2e``: the file runs the demo (the ``quick_demo`` / ``notebook_run`` fixtures, ``demo_copy``, a
   ``demo`` command, ``ftcal.sim.demo*``, the closed loop) or README.md / the notebook.
3. its name starts with a library module's or package's name (``test_c_runtime_drift.py``:
   ``ftcal/live/c_runtime.py`` -> ``live``; ``test_paper_xml.py`` -> ``data``);
4. otherwise the layer it uses most: uses of the names it imports from each layer (``ftcal.fit`` and the
   other re-exported steps count for ``workflow``, the helpers ``cli_data``/``adversarial`` for ``cli``,
   ``live_truth`` for ``live``), and each start of the ``ftcal`` command for ``cli``; ties go up.

Layers of the library: ``core`` (core, runtime), ``data`` (data, payload, robot, files, insitu, report,
check, plan, sim), ``live``, ``workflow``, ``cli``.
"""

from __future__ import annotations

import argparse
import ast
import re
import shutil
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
TESTS = ROOT / "tests"
HELPERS = "helpers"
LAYERS = ("core", "data", "live", "workflow", "cli", "e2e")
LAYER_TEXT = {"core": "the mathematics and infrastructure (ftcal.core, ftcal.runtime)",
              "data": "readers, payload, robot, files, in-situ datasets, report, check, plan, simulation",
              "live": "the live calibrator, its C core and transports (ftcal.live)",
              "workflow": "the pipeline's steps (ftcal.workflow)",
              "cli": "the ftcal commands (ftcal.cli)",
              "e2e": "the demo, README, notebook and help examples run end to end"}
# Library package -> test folder (ranked by LAYERS' order; the highest wins).
PACKAGE_LAYER = {"core": "core", "runtime": "core", "data": "data", "payload": "data", "robot": "data",
                 "files": "data", "insitu": "data", "report": "data", "check": "data", "plan": "data",
                 "sim": "data", "live": "live", "workflow": "workflow", "cli": "cli"}
HELPER_LAYER = {"cli_data": "cli", "adversarial": "cli", "live_truth": "live", "bag_data": "data"}
DEMO_FIXTURES = {"quick_demo", "notebook_run", "demo_copy", "run_notebook"}
DEMO_MODULES = ("ftcal.sim.demo", "ftcal.sim.closed_loop")
TEXT_SUFFIXES = {".py", ".md", ".toml", ".cfg", ".ini", ".txt", ".ipynb", ".yml", ".yaml", ".sh", ""}
TEXT_FOLDERS = ("README.md", "BENCHMARKS.md", "Makefile", ".ci", "docs", "src", "tests", "benchmarks", "tools")


def lazy_names() -> dict[str, str]:
    """``ftcal.NAME`` -> the package it lives in, read from ``ftcal/__init__.py``'s lazy table (not imported)."""
    text = (ROOT / "src/ftcal/__init__.py").read_text(encoding="utf-8")
    names = {m.group(1): m.group(2) for m in re.finditer(r'"(\w+)": "(\w+)\.', text)}
    for block in re.finditer(r'\("(\w+)", \(([^)]*)\)\)', text):  # the steps: ("fitting", ("fit", ...))
        names.update({n: "workflow" for n in re.findall(r'"(\w+)"', block.group(2))})
    return names


def runs_demo(tree: ast.AST, text: str) -> bool:
    for node in ast.walk(tree):
        if isinstance(node, ast.FunctionDef) and DEMO_FIXTURES & {a.arg for a in node.args.args}:
            return True
        if isinstance(node, ast.ImportFrom) and node.module == "conftest" and \
                DEMO_FIXTURES & {a.name for a in node.names}:
            return True
        if isinstance(node, (ast.List, ast.Tuple)) and node.elts and isinstance(node.elts[0], ast.Constant) \
                and node.elts[0].value == "demo":
            return True
    return any(f"{m}" in text for m in DEMO_MODULES) or '"README.md"' in text or "pipeline.ipynb" in text


def command_call(node: ast.AST) -> bool:
    """Whether ``node`` names the ``ftcal`` console script or ``python -m ftcal``."""
    for sub in ast.walk(node):
        if isinstance(sub, ast.Call):
            name = getattr(sub.func, "attr", getattr(sub.func, "id", ""))
            if name in {"with_name", "join", "which"} and any(
                    isinstance(a, ast.Constant) and a.value == "ftcal" for a in sub.args):
                return True
        if isinstance(sub, (ast.List, ast.Tuple)):
            values = [e.value if isinstance(e, ast.Constant) else None for e in sub.elts]
            if any(a == "-m" and b == "ftcal" for a, b in zip(values, values[1:])):
                return True
    return False


def usage(tree: ast.AST, helpers: set[str]) -> dict[str, int]:
    """How often the file uses each layer: uses of the names it imports from it (``ftcal.NAME`` included),
    of its helper modules, and of the ``ftcal`` command (counted for ``cli``)."""
    lazy, bound, counts = lazy_names(), {}, dict.fromkeys(LAYERS, 0)

    def layer(module: str, name: str = "") -> str | None:
        parts = module.split(".")
        if parts[0] in helpers:
            return HELPER_LAYER.get(parts[0], "data")
        if parts[0] != "ftcal":
            return None
        package = parts[1] if len(parts) > 1 else (name if name in PACKAGE_LAYER else lazy.get(name))
        return PACKAGE_LAYER.get(package)

    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for alias in node.names:
                found, top = layer(alias.name), alias.name.split(".")[0]
                if found and (top in helpers or alias.asname):  # else used as ftcal.PACKAGE..., counted below
                    bound[alias.asname or top] = found
                if found:
                    counts[found] += 1
        elif isinstance(node, ast.ImportFrom) and not node.level and node.module:
            for alias in node.names:
                if found := layer(node.module, alias.name):
                    bound[alias.asname or alias.name] = found
                    counts[found] += 1
        elif isinstance(node, ast.Assign) and command_call(node.value):
            bound.update({t.id: "cli" for t in node.targets if isinstance(t, ast.Name)})
    for node in ast.walk(tree):
        if isinstance(node, ast.Name) and isinstance(node.ctx, ast.Load) and node.id in bound:
            counts[bound[node.id]] += 1
        elif isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name) and node.value.id == "ftcal":
            if found := layer("ftcal", node.attr):
                counts[found] += 1
        elif isinstance(node, ast.Call) and command_call(node) and not isinstance(node.func, ast.Attribute):
            counts["cli"] += 1
    return counts


def module_layers() -> dict[str, str]:
    """Module and package names of the library layers -> their test folder; a name in two folders is left out.

    The steps' and commands' modules are not read by name (``export``, ``payload``): a file's name word
    ``export`` or ``payload`` says what it checks, not that it checks the step."""
    found: dict[str, set[str]] = {}
    package_root = ROOT / "src" / "ftcal"
    for path in package_root.rglob("*.py"):
        parts = path.relative_to(package_root).with_suffix("").parts
        if parts[0] not in PACKAGE_LAYER or parts[0] in {"workflow", "cli"}:
            continue
        for name in {parts[0], *parts[1:]} - {"__init__"}:
            found.setdefault(name.lstrip("_"), set()).add(PACKAGE_LAYER[parts[0]])
    return {name: layers.pop() for name, layers in found.items() if len(layers) == 1}


# Words of a file's name that say its layer, strongest first (test_live_cli.py is about the command).
NAME_LAYER = (("cli", "cli"), ("demo", "e2e"), ("readme", "e2e"), ("notebook", "e2e"), ("export", "data"),
              ("exports", "data"), ("workflow", "workflow"), ("step", "workflow"), ("steps", "workflow"),
              ("live", "live"))


def layer_of(path: Path, helpers: set[str], known: dict[str, str]) -> str:
    """The test folder ``path`` belongs in (the rule in this module's docstring)."""
    text = path.read_text(encoding="utf-8")
    tree = ast.parse(text)
    words = path.stem.split("_")[1:]
    for word, layer in NAME_LAYER:
        if word in words:
            return layer
    for node in ast.walk(tree):  # a test module importing another test module goes beside it
        if isinstance(node, ast.ImportFrom) and (node.module or "").startswith("test_") and node.module in known:
            return known[node.module]
    if runs_demo(tree, text):
        return "e2e"
    modules = module_layers()
    for k in range(len(words), 0, -1):  # test_c_runtime_drift.py: ftcal/live/c_runtime.py
        if (layer := modules.get("_".join(words[:k]))) is not None:
            return layer
    counts = usage(tree, helpers)
    best = max(counts.values())
    return "core" if not best else [layer for layer in LAYERS if counts[layer] == best][-1]


def depth_fixed(text: str) -> str:
    """Paths from ``__file__`` one folder deeper; ``sys.path`` entries for the tests folder dropped."""
    text = re.sub(r"^[ \t]*sys\.path\.insert\(0, str\(Path\(__file__\)(?:\.resolve\(\))?\.parent\)\)[ \t]*\n",
                  "", text, flags=re.M)
    text = re.sub(r"(Path\(__file__\)(?:\.resolve\(\))?)\.parents\[(\d)\]",
                  lambda m: f"{m.group(1)}.parents[{int(m.group(2)) + 1}]", text)
    text = re.sub(r"(Path\(__file__\)(?:\.resolve\(\))?)\.parent\b(?!s)", r"\1.parents[1]", text)
    return re.sub(r"os\.path\.dirname\((os\.path\.dirname\(os\.path\.abspath\(__file__\)\))\)",
                  r"os.path.dirname(os.path.dirname(\1))", text)


def text_files() -> list[Path]:
    found = []
    for name in TEXT_FOLDERS:
        path = ROOT / name
        candidates = [path] if path.is_file() else sorted(p for p in path.rglob("*") if p.is_file()) \
            if path.is_dir() else []
        found += [p for p in candidates if p.suffix in TEXT_SUFFIXES and "__pycache__" not in p.parts
                  and p.resolve() != Path(__file__).resolve()]
    return found


def mentions_fixed(text: str, moved: dict[str, str]) -> str:
    """``tests/NAME.py`` (and globs such as ``tests/test_report*.py``) pointed at the files' new places."""
    def one(match):
        name = match.group(1)
        if "*" not in name:
            return f"tests/{moved[name]}" if name in moved else match.group(0)
        pattern = re.compile(re.escape(name).replace(r"\*", ".*") + "$")
        places = {moved[n].rsplit("/", 1)[0] for n in moved if pattern.match(n)}
        return f"tests/{places.pop()}/{name}" if len(places) == 1 else match.group(0)

    text = re.sub(r"(?<![\w/])tests/([\w*]+\.py)\b", one, text)
    # code outside tests/ that puts the tests folder on sys.path to import a helper (benchmarks)
    if any(place.startswith(HELPERS + "/") for place in moved.values()):
        text = re.sub(r'(sys\.path\.insert\(0, str\([^\n]*?/ "tests")\)\)', r'\1 / "helpers"))', text)
    return text


# The helpers, and the layer folders too: a test module may import another's builders (test_cli_robot.py
# takes make_recording from test_insitu.py), wherever the rule put each.
PYTEST_SETTINGS = "pythonpath = [" + ", ".join(f'"tests/{f}"' for f in ("", HELPERS, *LAYERS)).replace('/"', '"') + "]"


def configured(text: str) -> str:
    """pyproject.toml with the helpers on pytest's path and one marker per layer (kept if present)."""
    if re.search(r"^pythonpath = .*$", text, re.M):
        text = re.sub(r"^pythonpath = .*$", PYTEST_SETTINGS, text, count=1, flags=re.M)
    else:
        text = text.replace('testpaths = ["tests"]\n', f'testpaths = ["tests"]\n{PYTEST_SETTINGS}\n', 1)
    missing = [f'    "{layer}: {LAYER_TEXT[layer]} (tests/{layer}/)",' for layer in LAYERS
               if not re.search(rf'^\s*"{layer}:', text, re.M)]
    if missing:
        text = text.replace("markers = [\n", "markers = [\n" + "\n".join(missing) + "\n", 1)
    return text


def move(source: Path, target: Path, git: bool) -> None:
    target.parent.mkdir(parents=True, exist_ok=True)
    if git and subprocess.run(["git", "ls-files", "--error-unmatch", str(source)], cwd=ROOT,
                              capture_output=True).returncode == 0:
        subprocess.run(["git", "mv", str(source), str(target)], cwd=ROOT, check=True)
    else:
        shutil.move(source, target)


def plan() -> dict[str, str]:
    """``NAME.py`` -> its place under tests/ for every file still at the top of tests/."""
    helpers = {p.stem for p in TESTS.glob("*.py") if not p.name.startswith("test_") and p.name != "conftest.py"}
    helpers |= {p.stem for p in (TESTS / HELPERS).glob("*.py")}
    known = {p.stem: p.parent.name for p in TESTS.glob("*/test_*.py")}
    places = {}
    # Files importing another test module go last, so the one they import is placed first.
    for path in sorted(TESTS.glob("*.py"), key=lambda p: ("from test_" in p.read_text(encoding="utf-8"), p.name)):
        if path.name == "conftest.py":
            continue
        folder = HELPERS if path.stem in helpers else layer_of(path, helpers, known)
        known[path.stem] = folder
        places[path.name] = f"{folder}/{path.name}"
    return dict(sorted(places.items()))


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--dry-run", action="store_true", help="print the moves, change nothing")
    args = parser.parse_args(argv)
    places = plan()
    for name, place in places.items():
        print(f"tests/{name} -> tests/{place}")
    if args.dry_run:
        return 0
    git = (ROOT / ".git").exists()
    for name, place in places.items():
        source, target = TESTS / name, TESTS / place
        if not place.startswith(HELPERS + "/"):
            source.write_text(depth_fixed(source.read_text(encoding="utf-8")), encoding="utf-8")
        move(source, target, git)
    # every file already placed, not only this run's: text merged from elsewhere may still name the old place
    placed = {p.name: str(p.relative_to(TESTS)) for p in TESTS.glob("*/*.py")}
    for path in text_files():
        text = path.read_text(encoding="utf-8", errors="surrogateescape")
        fixed = mentions_fixed(text, placed)
        if path.name == "pyproject.toml" and path.parent == ROOT:
            fixed = configured(fixed)
        if fixed != text:
            path.write_text(fixed, encoding="utf-8", errors="surrogateescape")
    pyproject = ROOT / "pyproject.toml"
    pyproject.write_text(configured(pyproject.read_text(encoding="utf-8")), encoding="utf-8")
    return 0


if __name__ == "__main__":
    sys.exit(main())
