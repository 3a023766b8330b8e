"""docs/pipeline.ipynb runs, cell by cell in one namespace, on the quick demo, and shows its results.

No Jupyter: the notebook's JSON is read with the standard library and its code cells run as a
kernel would run them (see ``run_notebook`` in conftest.py). The numbers it prints are checked
against the physics the demo simulates, not against ftcal's own output.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
NOTEBOOK = ROOT / "docs" / "pipeline.ipynb"


def code_lines(text: str) -> list[str]:
    """The logical statements of a code text, continuation lines joined, comments and blanks dropped."""
    joined, lines = "", []
    for line in text.splitlines():
        line = line.split("#")[0].rstrip() if "#" in line and '"' not in line else line.rstrip()
        joined = f"{joined} {line.strip()}" if joined else line
        if joined and joined.count("(") == joined.count(")"):
            lines.append(" ".join(joined.split()))
            joined = ""
    return lines


def test_the_notebook_is_a_plain_nbformat_4_file_without_outputs():
    notebook = json.loads(NOTEBOOK.read_text(encoding="utf-8"))
    assert notebook["nbformat"] == 4
    kinds = [cell["cell_type"] for cell in notebook["cells"]]
    assert kinds.count("markdown") >= 5 and kinds.count("code") >= 5
    assert all(cell.get("outputs") == [] and cell.get("execution_count") is None
               for cell in notebook["cells"] if cell["cell_type"] == "code")


def test_the_notebook_runs_the_readme_pipeline():
    """Every statement of README's pipeline block is in the notebook, so the two cannot drift apart."""
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    blocks = [b for b in re.findall(r"^```python\n(.*?)^```", readme, re.M | re.S) if "identify_payload" in b]
    assert len(blocks) == 1
    # The size: at most 15 lines, importing ftcal (and the shell's glob) only.
    assert len([line for line in blocks[0].splitlines() if line.strip()]) <= 15
    assert [line for line in code_lines(blocks[0]) if line.startswith(("import", "from"))] == ["import glob",
                                                                                              "import ftcal"]
    pipeline = [line for line in code_lines(blocks[0]) if not line.startswith(("import", "for ", "print"))]
    notebook = json.loads(NOTEBOOK.read_text(encoding="utf-8"))
    cells = code_lines("\n".join("".join(c["source"]) for c in notebook["cells"] if c["cell_type"] == "code"))
    assert pipeline and [line for line in pipeline if line not in cells] == []


@pytest.mark.slow
def test_the_notebook_runs_and_shows_each_step(notebook_run):
    folder, namespace, printed, shown = notebook_run
    # Each step printed its summary and wrote its file.
    for name in ("dataset.parquet", "best.json", "arm.parquet", "payload.json", "contact.parquet", "ft_calib.yaml"):
        assert (folder / "ftcal-demo" / name).stat().st_size > 0, name
    assert not list(folder.rglob("*.tmp"))
    assert "force-norm RMSE" in printed and "mass" in printed
    # The notebook displays results as HTML (a metrics table, the payload, the compensation).
    assert len(shown) == 3 and all(html.lstrip().startswith("<") for html in shown)
    # The demo's bag simulates a known gripper and sensor bias (the truth ftcal.sim wrote it from).
    from ftcal.sim.demo_arm import ARM_DEMO_SCENARIO as truth

    mass = float(re.search(r"^\s*mass\s+([0-9.]+)", printed, re.M).group(1))
    assert mass == pytest.approx(truth.gripper_mass, abs=0.005)
    tool = namespace["tool"]
    assert tool.mass == pytest.approx(mass, abs=1e-5)
    assert tool.com == pytest.approx(truth.gripper_com, abs=5e-4)
    assert tool.to_dict()["force_bias"] == pytest.approx(truth.force_bias, abs=0.01)
    # Evaluated on the held-out recordings: the force-norm RMSE printed is the one in the metrics.
    rmse = float(re.search(r"^force-norm RMSE: ([0-9.]+) N", printed, re.M).group(1))
    assert namespace["scores"].metrics["force_norm_rmse"] == pytest.approx(rmse, rel=1e-4)
