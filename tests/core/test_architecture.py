"""The layout in docs/architecture.md holds in the code: imports only point down, no circles, few loose modules.

The import graph is read from the source with ``ast`` (imports inside functions included),
independently of the code under test.
"""

from __future__ import annotations

import ast
import re
import sys
from pathlib import Path

SRC = Path(__file__).resolve().parents[2] / "src"
PACKAGE = SRC / "ftcal"
ARCHITECTURE = Path(__file__).resolve().parents[2] / "docs/architecture.md"
LOOSE_MODULE_LIMIT = 6


def layers() -> list[str]:
    """Package names from the top of the diagram in docs/architecture.md down."""
    text = ARCHITECTURE.read_text(encoding="utf-8")
    diagram = re.search(r"```\n(.*?)```", text, re.S).group(1)
    return [m.group(1) for m in re.finditer(r"^([a-z]+)\s{2,}", diagram, re.M)]


def module_name(path: Path) -> str:
    parts = list(path.relative_to(SRC).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def imports(path: Path) -> set[str]:
    """The ftcal modules (or packages) that ``path`` imports, resolved to absolute names."""
    name = module_name(path)
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    found = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            found |= {a.name for a in node.names if a.name.split(".")[0] == "ftcal"}
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")[: len(package.split(".")) - node.level + 1]
                target = ".".join(base + ([node.module] if node.module else []))
            else:
                target = node.module or ""
            if target.split(".")[0] != "ftcal":
                continue
            for alias in node.names:  # `from package import module` imports the module
                sub = f"{target}.{alias.name}"
                found.add(sub if (SRC / sub.replace(".", "/")).with_suffix(".py").exists()
                          or (SRC / sub.replace(".", "/")).is_dir() else target)
    return found


def graph() -> dict[str, set[str]]:
    modules = {module_name(p): p for p in PACKAGE.rglob("*.py")}
    return {name: {t for t in imports(path) if t in modules and t != name} for name, path in modules.items()}


def top_package(module: str) -> str | None:
    """The package of the pipeline a module belongs to; None for the loose modules at the top."""
    parts = module.split(".")
    if len(parts) < 2:
        return None
    return parts[1] if len(parts) > 2 or (SRC / module.replace(".", "/")).is_dir() else None


def test_the_map_names_every_package_and_nothing_else():
    packages = {p.name for p in PACKAGE.iterdir() if p.is_dir() and (p / "__init__.py").exists()}
    assert set(layers()) == packages


def test_imports_only_point_down():
    order = {name: rank for rank, name in enumerate(reversed(layers()))}  # runtime = 0
    upward = []
    for module, targets in graph().items():
        source = top_package(module)
        for target in targets:
            destination = top_package(target)
            if source and destination and order[destination] > order[source]:
                upward.append(f"{module} -> {target}")
    assert not upward, upward


def test_no_import_circle():
    edges = graph()
    index, low, stack, on_stack, circles = {}, {}, [], set(), []

    def visit(v):  # Tarjan's strongly connected components
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in edges[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                circles.append(sorted(component))

    for v in edges:
        if v not in index:
            visit(v)
    assert not circles, circles


def test_few_loose_modules():
    loose = [p.name for p in PACKAGE.glob("*.py") if p.name not in ("__init__.py", "__main__.py")]
    assert len(loose) <= LOOSE_MODULE_LIMIT, loose


def test_every_package_says_what_it_owns():
    for init in PACKAGE.glob("*/__init__.py"):
        doc = ast.get_docstring(ast.parse(init.read_text(encoding="utf-8")))
        assert doc and len(doc) > 80, f"{init.parent.name}: no docstring saying what it owns"


def test_the_checker_sees_an_upward_import(tmp_path, monkeypatch):
    """The graph reader resolves a relative import inside a function: a planted upward import is found."""
    fake = tmp_path / "ftcal" / "core"
    fake.mkdir(parents=True)
    (fake / "x.py").write_text("def f():\n    from ..cli import main\n")
    monkeypatch.setattr(sys.modules[__name__], "SRC", tmp_path)
    assert imports(fake / "x.py") == {"ftcal.cli"}


def test_no_command_module_imports_another():
    """A command parses, calls the library and prints: what two commands share lives in cli/_*.py or below."""
    crossing = [f"{module} -> {target}" for module, targets in graph().items()
                if module.startswith("ftcal.cli.cmd_")
                for target in targets if target.startswith("ftcal.cli.cmd_")]
    assert not crossing, crossing


# What a command may import besides cli/_*.py: the steps (``workflow``; ``sim``'s simulate and demo steps,
# which sit above ``workflow``), ``runtime`` and the declared limits (argparse choices and bounds).
STEP_LAYERS = ("ftcal.workflow", "ftcal.sim.simulate", "ftcal.sim.demos", "ftcal.runtime", "ftcal.core.limits")
# Commands that still reach below the steps, each for a reason (issue 43 lists them); the list only shrinks.
BELOW_THE_STEPS = {
    "ftcal.cli.cmd_convert": {"ftcal.files.targets"},  # the targets' registry names --to's choices
}


def test_a_command_reaches_the_library_through_its_steps():
    """A command parses, calls one step and prints: it imports the steps, not the layers below them."""
    below = {module: {t for t in targets if not t.startswith("ftcal.cli.")
                      and not any(t == layer or t.startswith(layer + ".") for layer in STEP_LAYERS)}
             for module, targets in graph().items() if module.startswith("ftcal.cli.cmd_")}
    assert {module: targets for module, targets in below.items() if targets} == BELOW_THE_STEPS


# What the steps wrap: a demo reaching these goes below the steps (issue 43: "every demo composed from steps only").
STEP_INTERNALS = ("ftcal.core.model", "ftcal.core.metrics", "ftcal.insitu", "ftcal.report", "ftcal.files",
                  "ftcal.payload", "ftcal.live", "ftcal.plan")
# What each demo still imports from them, each for the reason its comment or docstring gives; the list only shrinks.
DEMOS_BELOW_THE_STEPS = {
    # the network's and the firmware's validation metrics; the split datasets' files; the report page
    "ftcal.sim.demo": {"ftcal.core.metrics", "ftcal.insitu.recordings", "ftcal.report"},
    # two names (the axes, the wrench columns); the scenario's own page
    "ftcal.sim.demo_arm": {"ftcal.payload.identify", "ftcal.payload.tables", "ftcal.report.figures",
                           "ftcal.report.html", "ftcal.report.tables"},
    # the payload file as the demo has always written it (without the step's gain note); the flag bits
    "ftcal.sim.demo_live": {"ftcal.files.payload_json", "ftcal.live.health", "ftcal.payload.parameters"},
    # the payload draws' least-squares fit; the validation poses and the random designs
    "ftcal.sim.demo_plan": {"ftcal.payload.accumulate", "ftcal.payload.identify", "ftcal.payload.kinematics",
                            "ftcal.plan.candidates", "ftcal.plan.design"},
    # the tools' least-squares fit; the scenario's own page
    "ftcal.sim.closed_loop": {"ftcal.payload.accumulate", "ftcal.payload.identify", "ftcal.payload.kinematics",
                              "ftcal.payload.parameters", "ftcal.report.figures", "ftcal.report.html",
                              "ftcal.report.tables"},
}


def test_a_demo_reaches_the_library_through_its_steps():
    """The demos compose steps; what they still take from below the steps is the list above, no more."""
    modules = graph()
    below = {demo: {t for t in modules[demo]
                    if any(t == layer or t.startswith(layer + ".") for layer in STEP_INTERNALS)}
             for demo in DEMOS_BELOW_THE_STEPS}
    assert below == DEMOS_BELOW_THE_STEPS
