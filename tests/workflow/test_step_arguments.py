"""The library's errors (issues 39 and 43): the public steps refuse wrong arguments with a ParameterError
(an FtcalError) naming the Python parameter; workflow/ messages never name a command-line flag; the CLI
maps the parameter back to its flag in one table.

References: the steps' own signatures (inspect), the CLI's own parser (its option strings), the source of
workflow/ (ast), and by-hand lists of wrong values (types the docstrings exclude, out-of-range numbers).
"""

import ast
import inspect
import pathlib
import re

import numpy as np
import pandas as pd
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import ftcal
from ftcal import workflow
from ftcal.cli import build_parser, main
from ftcal.cli._common import FLAGS, cli_message, flag_of
from ftcal.core.features import n_coefficients
from ftcal.runtime.errors import FtcalError, ParameterError, ParameterWarning

WORKFLOW = pathlib.Path(workflow.__file__).parent
COLUMNS = ["u1", "u2", "u3", "u4", "u5", "u6", "T", "Fx", "Fy", "Fz", "Tx", "Ty", "Tz"]


@pytest.fixture(scope="module")
def frame():
    return pd.DataFrame(np.random.default_rng(0).normal(size=(60, 13)), columns=COLUMNS)


@pytest.fixture(scope="module")
def model(frame):
    return ftcal.fit(frame, degree=1).model


# (step, keyword, wrong value): types the docstrings exclude and values outside the documented sets.
WRONG = [
    ("fit", "solver", "magic"), ("fit", "solver", 3), ("fit", "outputs", ["Fx", "Fx"]), ("fit", "inputs", "u1"),
    ("fit", "inputs", [1, 2]), ("fit", "na", -1), ("fit", "nb", 2.5), ("fit", "ridge", -1.0),
    ("fit", "lasso", float("nan")), ("fit", "folds", "3"), ("fit", "max_degree", None), ("fit", "verbose", "yes"),
    ("fit", "normalization", "zscore"), ("fit", "select_per", ["model"]), ("fit", "objective", "all"),
    ("fit", "penalties", "lasso"), ("fit", "family", "tree"), ("fit", "group_by", 7), ("fit", "budget", 0.0),
    ("fit", "drop_incomplete", 1), ("evaluate", "mode", "x"), ("evaluate", "start", None),
    ("evaluate", "warmup", True), ("evaluate", "segment_by", ""), ("predict", "mode", "two-step"),
    ("predict", "start", "ones"), ("identify_payload", "keep_moving", "False"),
    ("identify_payload", "reaction", 0), ("identify_payload", "inputs", ("Fx", "Fy", "Fx")),
    ("check_sensor", "rate", -5.0), ("check_sensor", "max_force_error", "2 N"), ("check_sensor", "reaction", None),
    ("plan_experiment", "poses", 0), ("plan_experiment", "objective", "speed"), ("plan_experiment", "degree", "4"),
    ("plan_experiment", "seed", -1), ("convert", "single_precision", "no"), ("convert", "model", 42),
    ("compensate", "payload", 42), ("check_sensor", "accept", 42), ("fit", "output", "model.txt"),
    ("predict", "output", "out.json"),
]


def call(step, keyword, value, frame, model):
    """The step with one wrong keyword and otherwise valid (or harmless) positional arguments."""
    first = {"fit": (frame,), "evaluate": (model, frame), "predict": (model, frame),
             "identify_payload": (frame,), "check_sensor": (frame,), "plan_experiment": (10,),
             "convert": ("model.json", "json", "unused.json"), "compensate": ("payload.json", frame)}[step]
    if (step, keyword) in (("plan_experiment", "poses"), ("convert", "model"), ("compensate", "payload")):
        return getattr(ftcal, step)(value, *first[1:])
    return getattr(ftcal, step)(*first, **{keyword: value})


@pytest.mark.parametrize("step, keyword, value", WRONG, ids=[f"{s}-{k}-{v!r}" for s, k, v in WRONG])
def test_a_wrong_argument_is_a_parameter_error_naming_it(step, keyword, value, frame, model):
    assert keyword in inspect.signature(getattr(ftcal, step)).parameters  # the table lists real keywords
    with pytest.raises(ParameterError) as caught:
        call(step, keyword, value, frame, model)
    assert isinstance(caught.value, FtcalError) and caught.value.parameter == keyword
    assert keyword in str(caught.value) and "--" not in str(caught.value)


CHOICES = {("fit", "solver"): {"lstsq", "osqp"}, ("evaluate", "mode"): {"one-step", "free-run"},
           ("predict", "start"): {"zeros", "measured"}, ("fit", "objective"): {"both", "force", "torque"}}
ANYTHING = st.one_of(st.none(), st.booleans(), st.integers(), st.floats(allow_nan=True), st.text(max_size=12),
                     st.lists(st.text(max_size=4), max_size=3), st.dictionaries(st.text(max_size=3), st.integers(),
                                                                                max_size=2))


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(which=st.sampled_from(sorted(CHOICES)), value=ANYTHING)
def test_any_value_outside_a_choice_is_refused_by_name(which, value, frame, model):
    step, keyword = which
    if isinstance(value, str) and value in CHOICES[which]:
        return  # a valid choice: not what this property is about
    with pytest.raises(ParameterError) as caught:
        call(step, keyword, value, frame, model)
    assert caught.value.parameter == keyword and keyword in str(caught.value)


@pytest.mark.parametrize("call", [lambda: ftcal.load_model(42), lambda: ftcal.load_dataset(["a.csv", 7]),
                                  lambda: ftcal.save_model(ftcal.CalibrationModel(1), None),
                                  lambda: ftcal.Dataset.from_arrays(1.0, 2.0)])
def test_the_core_api_refuses_wrong_types_by_name(call):
    with pytest.raises(ParameterError) as caught:
        call()
    assert caught.value.parameter in str(caught.value)


@pytest.mark.parametrize("args", [(7, -1), (0, 2), (7, 2, 0), (7, 2, 6, -1), (7, 2.0), (7, True)])
def test_n_coefficients_refuses_impossible_counts(args):
    with pytest.raises(ParameterError):
        n_coefficients(*args)
    assert n_coefficients(7, 4, 6) == 1980  # the paper's count (Table 2): still given


def raised_strings(path):
    """Every string constant inside every ``raise`` statement and ``warnings.warn`` call of a module
    (f-string parts included)."""
    for node in ast.walk(ast.parse(path.read_text())):
        message = node.exc if isinstance(node, ast.Raise) else node if isinstance(node, ast.Call) and \
            isinstance(node.func, ast.Attribute) and node.func.attr == "warn" else None
        if message is not None:
            for inner in ast.walk(message):
                if isinstance(inner, ast.Constant) and isinstance(inner.value, str):
                    yield node.lineno, inner.value


def test_no_message_raised_in_workflow_names_a_flag():
    found = [f"{path.name}:{line}: {text!r}" for path in sorted(WORKFLOW.glob("*.py"))
             for line, text in raised_strings(path) if re.search(r"(^|[\s(\"'/])--[a-z]|^-o ", text)]
    assert found == []


@pytest.mark.parametrize("keywords, expected", [
    (dict(degree=0), "degree must be in 1..10 or 'auto'; got 0."),
    (dict(degree="auto", solver="osqp"), "degree auto uses the streaming solvers; drop solver osqp."),
    (dict(degree=2, max_degree=3), "max_degree goes with degree auto"),
])
def test_library_messages_name_the_parameter_and_the_cli_its_flag(keywords, expected, frame):
    with pytest.raises(ParameterError) as caught:
        ftcal.fit(frame, **keywords)
    assert str(caught.value).startswith(expected)
    flags = cli_message(caught.value)
    for name in caught.value.parameters:
        assert flag_of(name) in flags
    assert flags.startswith("--")


def test_a_warning_names_the_parameters_too(frame):
    with pytest.warns(ParameterWarning, match="^lasso without degree fits degree 1") as caught:
        ftcal.fit(frame, lasso=0.1)
    warning = next(w.message for w in caught if isinstance(w.message, ParameterWarning))
    assert cli_message(warning).startswith("--lasso without --degree fits degree 1")


def test_the_command_prints_the_flag(tmp_path, capsys):
    data = tmp_path / "data.csv"
    pd.DataFrame(np.random.default_rng(1).normal(size=(40, 13)), columns=COLUMNS).to_csv(data, index=False)
    assert main(["fit", str(data), "--degree", "2", "--max-degree", "3", "-o", str(tmp_path / "m.json")]) == 2
    err = capsys.readouterr().err
    assert "--max-degree goes with --degree auto" in err and len(err.strip().splitlines()) == 1


def test_the_flag_table_maps_parameters_to_flags_the_commands_have():
    options = set()
    parser = build_parser()
    for action in parser._subparsers._group_actions[0].choices.values():
        options |= {o for a in action._actions for o in a.option_strings}
    for parameter, flag in FLAGS.items():
        assert flag in options, parameter
        assert any(parameter in inspect.signature(getattr(workflow, step)).parameters
                   for step in workflow.__all__ if callable(getattr(workflow, step))
                   and not isinstance(getattr(workflow, step), type)), parameter
