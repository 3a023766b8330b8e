"""Library messages name parameters, never command-line flags; the CLI maps one to the other.

The steps (``ftcal.workflow``) and everything below them raise :class:`~ftcal.FtcalError` and warn
with the Python names of what was wrong (``degree``), written ``{degree}`` in a
:class:`~ftcal.runtime.errors.ParameterError`; ``ftcal.cli._common.flag_of`` turns them into the
flags (``--degree``) when the command prints them. A flag spelled into a library message is wrong
for a Python caller, so the scan below reads every raise and ``warnings.warn`` in the library.
"""

from __future__ import annotations

import ast
import re
import warnings
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

import ftcal
from ftcal.cli._common import cli_message, flag_of
from ftcal.runtime.errors import FtcalError, ParameterError

SRC = Path(ftcal.__file__).parent
FLAG = re.compile(r"(?<![\w-])--[a-z][a-z0-9-]+")
# The layers above the steps speak to the command line (cli) or are the demos (sim).
ABOVE_THE_STEPS = {"cli", "sim"}
# Files other branches rewrite in this session; their flags are theirs to rename (see the branch report).
PENDING: set[str] = set()


def _flag_sites(path: Path) -> list[str]:
    """``line: flags`` for each string in a raise or a warnings.warn of ``path`` that names a flag
    (text in backquotes is an example command, and may)."""
    found = []
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        is_warn = (isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute)
                   and node.func.attr == "warn")
        if not (isinstance(node, ast.Raise) or is_warn):
            continue
        for sub in ast.walk(node):
            if isinstance(sub, ast.Constant) and isinstance(sub.value, str):
                flags = FLAG.findall(re.sub(r"`[^`]*`", "", sub.value))
                if flags:
                    found.append(f"{sub.lineno}: {', '.join(flags)}")
    return found


def _library_files():
    for path in sorted(SRC.rglob("*.py")):
        rel = path.relative_to(SRC).as_posix()
        if rel.split("/")[0] in ABOVE_THE_STEPS or rel.split("/")[0] in PENDING or rel in PENDING:
            continue
        yield rel, path


def test_the_scan_finds_a_flag_in_a_raise(tmp_path):
    # The scan itself can fail: a raise naming --degree and a warning naming --lasso are found.
    sample = tmp_path / "sample.py"
    sample.write_text('import warnings\n'
                      'def f(x):\n'
                      '    if x:\n'
                      '        raise ValueError(f"--degree {x}: too high")\n'
                      '    warnings.warn("use `ftcal fit --ridge 1`" " or --lasso")\n')
    assert _flag_sites(sample) == ["4: --degree", "5: --lasso"]


def test_no_library_raise_or_warning_names_a_flag():
    sites = {rel: found for rel, path in _library_files() if (found := _flag_sites(path))}
    assert sites == {}, f"library messages naming CLI flags (name the parameter, as {{name}}): {sites}"


def _frame(n=40, seed=0):
    rng = np.random.default_rng(seed)
    u = rng.normal(size=(n, 6))
    gain = np.eye(6) + 0.1 * rng.normal(size=(6, 6))
    return pd.DataFrame(np.c_[u, u @ gain.T],
                        columns=[*(f"u{i}" for i in range(1, 7)), "Fx", "Fy", "Fz", "Tx", "Ty", "Tz"])


@pytest.mark.parametrize("keywords, parameter", [
    (dict(degree=0), "degree"),
    (dict(family="mlp", degree=2), "degree"),
    (dict(family="mlp", seed=-1), "seed"),
    (dict(family="mlp", max_iter=0), "max_iter"),
    (dict(max_iter=5), "max_iter"),
    (dict(family="mlp", lasso=0.1), "lasso"),
    (dict(folds=1), "folds"),
])
def test_fit_refusals_name_the_parameter_and_the_cli_its_flag(keywords, parameter):
    with pytest.raises(FtcalError) as caught:
        ftcal.fit(_frame(), **keywords)
    text = str(caught.value)
    assert "--" not in text and parameter in text, text
    # The command prints the same sentence with the flag (one table: ftcal.cli._common.FLAGS).
    assert isinstance(caught.value, ParameterError)
    assert flag_of(parameter) in cli_message(caught.value)


@pytest.mark.parametrize("setup, options, parameter, says", [
    ({}, dict(keys="rmw_zenoh", domain_id=233), "domain_id", "domain_id 233: ROS 2 domain ids go from 0 to 232"),
    ({}, dict(domain_id=3), "domain_id", "domain_id goes with keys rmw_zenoh"),
    ({}, dict(rt_priority=0), "rt_priority", "rt_priority 0: SCHED_FIFO priorities go from 1 to 99"),
    ({}, dict(rt_priority=100), "rt_priority", "rt_priority 100: SCHED_FIFO priorities go from 1 to 99"),
    ({}, dict(keys="dds"), "keys", "keys must be 'bridge' or 'rmw_zenoh'"),
    ({}, dict(joints_topic="/joint_states"), "joints_topic", "joints_topic and urdf go together"),
    # Refused before the URDF is read: the file need not exist.
    (dict(urdf="robot.urdf"), dict(imu_topic="/imu", joints_topic="/joint_states"), "imu_topic",
     "give one gravity source"),
])
def test_serve_zenoh_refusals_name_the_parameter_and_the_cli_its_flag(setup, options, parameter, says):
    from ftcal.workflow.live import LiveSetup, serve_zenoh

    with pytest.raises(ParameterError) as caught:
        serve_zenoh(LiveSetup(**setup), **options)  # refused before Zenoh is imported or a session opened
    text = str(caught.value)
    assert says in text and "--" not in text and caught.value.parameter == parameter, text
    assert flag_of(parameter) in cli_message(caught.value)


def test_replay_live_refuses_a_model_or_drop_incomplete_with_a_bag(tmp_path):
    from ftcal.workflow.live import LiveSetup, replay_live

    for setup, keywords, parameter in ((LiveSetup(model="cal.json"), {}, "model"),
                                       (LiveSetup(), dict(drop_incomplete=True), "drop_incomplete")):
        with pytest.raises(ParameterError) as caught:  # by the suffix, before the bag is opened
            replay_live(tmp_path / "run.mcap", setup, output=tmp_path / "out.parquet", **keywords)
        assert caught.value.parameter == parameter and "--" not in str(caught.value)
        assert cli_message(caught.value).startswith(flag_of(parameter) + " ")
    assert not (tmp_path / "out.parquet").exists()


def test_an_ill_posed_fit_warns_with_parameter_names():
    # 6 rows for the 28 coefficients of a degree-2 model over 6 inputs: under-determined (the fit
    # step refuses it outright; the model warns and fits the minimum-norm solution).
    frame = _frame(n=6)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        ftcal.CalibrationModel(degree=2).fit(frame.iloc[:, :6].to_numpy(), frame.iloc[:, 6:].to_numpy())
    texts = [str(w.message) for w in caught if issubclass(w.category, ftcal.FtcalWarning)]
    assert any("under-determined" in t for t in texts), texts
    assert not any("--" in t for t in texts), texts
    shown = [cli_message(w.message) for w in caught if "under-determined" in str(w.message)]
    assert "--lasso" in shown[0] and "--ridge" in shown[0]


def _named_parameters():
    """Every parameter a library ParameterError or ParameterWarning names by a literal (``"degree"`` or
    ``("urdf", "robot")``), with where."""
    kinds = {"ParameterError", "ParameterWarning", "IllPosedParameterWarning"}
    for rel, path in _library_files():
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if (isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id in kinds
                    and node.args):
                first = node.args[0]
                items = first.elts if isinstance(first, ast.Tuple) else [first]
                for item in items:
                    if isinstance(item, ast.Constant) and isinstance(item.value, str):
                        yield item.value, f"{rel}:{node.lineno}"


def test_every_named_parameter_is_a_flag_of_some_command():
    # The CLI shows a parameter as flag_of(parameter): that must be an option some command takes, or
    # the message would send the user to a flag that does not exist.
    import argparse

    from ftcal.cli import build_parser

    options = set()
    root = build_parser()
    for action in root._actions:
        if isinstance(action, argparse._SubParsersAction):
            for sub in action.choices.values():
                options.update(o for a in sub._actions for o in a.option_strings)
    named = dict(_named_parameters())
    assert len(named) > 40  # the scan reads the library's ParameterErrors
    unknown = {name: where for name, where in named.items() if flag_of(name) not in options}
    assert unknown == {}, unknown
