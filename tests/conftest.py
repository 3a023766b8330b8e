"""Shared fixtures: seeded data, independent references, the quick demo; layer markers by folder.

The tests are laid out like the code (``tests/core``, ``data``, ``live``, ``workflow``, ``cli``, ``e2e``;
``tools/layout_tests.py`` places new files): every test gets its folder's marker, so
``pytest -m core`` runs the mathematics alone and ``-m "not e2e"`` leaves the demo out.
"""

import os
from pathlib import Path

import numpy as np
import pytest
from hypothesis import settings
from sklearn.preprocessing import PolynomialFeatures


def reference_features(u, degree):
    """Monomials of degree 1..degree then the offset, built by scikit-learn (not ftcal)."""
    full = PolynomialFeatures(degree, include_bias=True).fit_transform(np.asarray(u, dtype=float))
    return np.roll(full, -1, axis=1)  # sklearn puts the bias first; the paper puts it last


def sensor_like_data(rng, n, n_channels=6):
    """Raw inputs like a real sensor: ADC counts ~5000 of mixed loads, temperature 25–44 °C.

    Outputs are the loads (N, Nm) with a mild non-polynomial response and a
    temperature effect, so no polynomial degree fits them exactly.
    """
    loads = rng.uniform(-1.0, 1.0, size=(n, n_channels))
    temperature = rng.uniform(25.0, 44.0, size=n)
    mixing = np.eye(n_channels) + 0.2 * np.random.default_rng(123).standard_normal((n_channels, n_channels))
    counts = 5000.0 + 800.0 * loads @ mixing.T + 3.0 * (temperature[:, None] - 35.0)
    wrench = loads * np.array([100.0, 100.0, 100.0, 10.0, 10.0, 10.0])[:n_channels]
    wrench = wrench + 5.0 * np.tanh(2.0 * loads[:, :1]) + 0.01 * (temperature[:, None] - 35.0) ** 2
    return np.c_[counts, temperature], wrench


LAYERS = ("core", "data", "live", "workflow", "cli", "e2e")

# The property tests draw the same examples on every run (``derandomize``), so ``make test`` on a clean checkout
# passes or fails on the code alone; ``HYPOTHESIS_PROFILE=explore`` draws fresh examples to hunt for new cases (a
# case it finds becomes an ``@example`` regression).
settings.register_profile("repeatable", derandomize=True, database=None)
settings.register_profile("explore", derandomize=False)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "repeatable"))


def pytest_collection_modifyitems(config, items):
    for item in items:
        layer = Path(str(item.path)).parent.name
        if layer in LAYERS:
            item.add_marker(getattr(pytest.mark, layer))


@pytest.fixture(autouse=True, scope="session")
def private_cache_home(tmp_path_factory):
    """The expected-wrench cache of every test (and of the CLI it starts) goes to a temporary folder."""
    previous = os.environ.get("XDG_CACHE_HOME")
    os.environ["XDG_CACHE_HOME"] = str(tmp_path_factory.mktemp("xdg-cache"))
    yield
    if previous is None:
        os.environ.pop("XDG_CACHE_HOME", None)
    else:
        os.environ["XDG_CACHE_HOME"] = previous


def write_frame(frame, path):
    """CSV (full precision) or Parquet with 1000-row groups, by ``path``'s suffix: many chunks per file."""
    if str(path).endswith(".csv"):
        frame.to_csv(path, index=False, float_format="%.17g")
    else:
        frame.to_parquet(path, row_group_size=1000)
    return str(path)


@pytest.fixture
def rng():
    return np.random.default_rng(20240611)


@pytest.fixture
def ref_features():
    return reference_features


@pytest.fixture
def make_sensor_data():
    return sensor_like_data


# The quick demo (`ftcal demo --quick`), run once per session; the notebook and the CLI/Python
# equality tests each work in a copy of its inputs, so neither sees the other's outputs.
DEMO_INPUTS = ("logs", "arm", "payloads.toml", "validation.parquet")


def build_quick_demo(root):
    """Run `ftcal demo --out ftcal-demo --quick` in ``root``."""
    import subprocess
    import sys

    ftcal = str(Path(sys.executable).with_name("ftcal"))
    done = subprocess.run([ftcal, "demo", "--out", "ftcal-demo", "--quick"], cwd=root, capture_output=True,
                          text=True, timeout=1800)
    assert done.returncode == 0, done.stderr


@pytest.fixture(scope="session")
def quick_demo(tmp_path_factory):
    """A folder holding ``ftcal-demo/`` as `ftcal demo --out ftcal-demo --quick` writes it, built once per run.

    Under pytest-xdist the workers share one build: the first to take the lock (a file in the run's
    common temporary folder) builds it, the others wait and read it. Tests only read it (or copy it).
    """
    import fcntl

    if os.environ.get("PYTEST_XDIST_WORKER") is None:
        root = tmp_path_factory.mktemp("quick-demo")
        build_quick_demo(root)
        return root
    shared = tmp_path_factory.getbasetemp().parent  # the same folder for every worker of this run
    root, done = shared / "quick-demo", shared / "quick-demo.done"
    with open(shared / "quick-demo.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        try:
            if not done.exists():
                root.mkdir(exist_ok=True)
                build_quick_demo(root)
                done.touch()
        finally:
            fcntl.flock(lock, fcntl.LOCK_UN)
    return root


def demo_copy(quick_demo, folder):
    """A fresh ``folder`` whose ``ftcal-demo/`` holds the demo's pipeline inputs (copied)."""
    import shutil

    for name in DEMO_INPUTS:
        source, target = quick_demo / "ftcal-demo" / name, folder / "ftcal-demo" / name
        target.parent.mkdir(parents=True, exist_ok=True)
        (shutil.copytree if source.is_dir() else shutil.copy2)(source, target)
    return folder


def run_notebook(path, cwd):
    """Execute a notebook's code cells in order in one namespace, in ``cwd``, as a kernel would.

    A cell's last expression is displayed as Jupyter does: its ``_repr_html_()`` when it has one,
    else its ``repr``; None is not shown. Returns the namespace, what the cells printed and the displayed values.
    """
    import ast
    import contextlib
    import io
    import json

    notebook = json.loads(path.read_text(encoding="utf-8"))
    assert notebook["nbformat"] == 4
    namespace, printed, shown = {"__name__": "__main__"}, io.StringIO(), []
    with contextlib.chdir(cwd), contextlib.redirect_stdout(printed):
        for number, cell in enumerate(notebook["cells"]):
            if cell["cell_type"] != "code":
                continue
            assert not cell.get("outputs"), f"cell {number} stores outputs"
            tree = ast.parse("".join(cell["source"]), filename=f"{path.name}[{number}]")
            last = tree.body.pop() if tree.body and isinstance(tree.body[-1], ast.Expr) else None
            exec(compile(tree, f"{path.name}[{number}]", "exec"), namespace)
            if last is not None:
                value = eval(compile(ast.Expression(last.value), f"{path.name}[{number}]", "eval"), namespace)
                if value is not None:  # Jupyter shows no None (a cell ending in print())
                    html = getattr(value, "_repr_html_", None)
                    shown.append(html() if html is not None else repr(value))
    return namespace, printed.getvalue(), shown


@pytest.fixture(scope="session")
def notebook_run(quick_demo, tmp_path_factory):
    """docs/pipeline.ipynb executed on a copy of the quick demo: (folder, namespace, printed, shown)."""
    folder = demo_copy(quick_demo, tmp_path_factory.mktemp("notebook"))
    namespace, printed, shown = run_notebook(Path(__file__).resolve().parents[1] / "docs" / "pipeline.ipynb",
                                             folder)
    return folder, namespace, printed, shown
