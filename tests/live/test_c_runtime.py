"""``convert --to c-runtime``: the generated C live step against the Python live calibrator.

The reference is :class:`ftcal.live.LiveCalibrator` (its own tests hold it to the simulation's
truth) fed the same samples, tool switches and re-tares; the C must agree to 1e-9 on a simulated
recording with drift (random walk + ramp), moves, a contact, a tool swap, a re-tare, a stuck
channel and a temperature excursion. The simulation's truth also checks the C directly: the held
contact is flagged while it lasts.
"""

from __future__ import annotations

import ctypes
import dataclasses
import shutil
import subprocess

import numpy as np
import pytest

from ftcal.cli import main
from ftcal.core.dataset import Dataset
from ftcal.core.model import CalibrationModel
from ftcal.files.model_files import save_model
from ftcal.files.payload_json import save_payload
from ftcal.live import LiveCalibrator
from ftcal.live.c_runtime import generate_c_runtime
from ftcal.live.health import BIT
from ftcal.payload.parameters import PayloadParameters
from ftcal.sim.live_scenario import LiveScenario, simulate_live

CC = shutil.which("cc")
pytestmark = pytest.mark.skipif(CC is None, reason="no C compiler `cc`")
NOISE = np.r_[np.full(3, 0.05), np.full(3, 0.004)]
FIELDS = 27  # per sample: calibrated, compensated, bias, bias_std (6 each), chi2, static + 2 updated, flags

# The driver lines that step one sample and store its FIELDS outputs (every replay driver shares them).
STEP_AND_STORE = r"""
        if (rt_step(&s, t[k], u + RT_N_INPUTS * k, g + 3 * k, override[k], &o)) return -1 - k;
        for (j = 0; j < 6; ++j) {
            out[27 * k + j] = o.calibrated[j];
            out[27 * k + 6 + j] = o.compensated[j];
            out[27 * k + 12 + j] = o.bias[j];
            out[27 * k + 18 + j] = o.bias_std[j];
        }
        out[27 * k + 24] = o.chi2;
        out[27 * k + 25] = o.is_static + 2 * o.updated;
        out[27 * k + 26] = o.flags;
"""

DRIVER = r"""
#include "rt.h"
/* action[k]: 0 nothing, -1 re-tare, t > 0 mount tool t, before sample k */
int replay(int n, const double *t, const double *u, const double *g, const int *override, const int *action,
           int tool, double *out)
{
    rt_state s;
    rt_output o;
    int k, j;
    if (rt_init(&s, tool)) return -2;
    for (k = 0; k < n; ++k) {
        if (action[k] == -1) rt_retare(&s);
        else if (action[k] > 0 && rt_set_tool(&s, action[k])) return -3;
""" + STEP_AND_STORE + r"""    }
    return 0;
}

/* A bad sample is refused and leaves the state as it was. */
int refuses(const double *u, const double *g)
{
    rt_state s, before;
    rt_output o;
    double nan_u[RT_N_INPUTS], zero[3] = {0.0, 0.0, 0.0};
    int j, refused;
    rt_init(&s, 0);
    if (rt_step(&s, 1.0, u, g, -1, &o)) return 0;
    before = s;
    for (j = 0; j < RT_N_INPUTS; ++j) nan_u[j] = u[j];
    nan_u[0] = nan_u[0] / 0.0 * 0.0;
    refused = rt_step(&s, 2.0, nan_u, g, -1, &o) == -1 && rt_step(&s, 1.0, u, g, -1, &o) == -1
              && rt_step(&s, 3.0, u, zero, -1, &o) == -1 && rt_init(&s, RT_N_TOOLS) == -1
              && rt_set_tool(&s, -1) == -1;
    return refused && memcmp(&s, &before, sizeof s) == 0;
}
"""


def tool_payload(tool) -> PayloadParameters:
    """A payload file's content for a known tool (the bias it carries is not used live)."""
    return PayloadParameters(tool.mass, np.asarray(tool.com), np.zeros(3), np.zeros(3), 9.81,
                             stderr={"mass": 0.001, "com": np.full(3, 1e-4), "force_bias": np.full(3, 0.01),
                                     "torque_bias": np.full(3, 0.001)},
                             fit={"n_samples": 100, "residual_rms": NOISE, "condition_number": 1.0,
                                  "wrench_columns": ["Fx", "Fy", "Fz", "Tx", "Ty", "Tz"]})


def gauge_model(degree: int, seed: int = 21):
    """A 7-input model (six gauges mixing the axes + temperature) fitted on a wide box of loads."""
    rng = np.random.default_rng(seed)
    mix = np.eye(6) + 0.05 * rng.normal(size=(6, 6))
    wrench = rng.uniform(-40, 40, size=(6000, 6)) * np.r_[np.ones(3), np.full(3, 0.1)]
    temperature = rng.uniform(20.0, 45.0, size=6000)
    raw = np.column_stack([wrench @ mix.T + 0.01 * (temperature[:, None] - 30.0), temperature])
    names = ("g1", "g2", "g3", "g4", "g5", "g6", "T")
    model = CalibrationModel(degree=degree).fit(Dataset.from_arrays(raw, wrench, input_names=names,
                                                                    output_names=("Fx", "Fy", "Fz", "Tx", "Ty", "Tz")))
    return model, mix


def compile_driver(tmp_path, header: str, driver: str, defines=(), name: str = "driver"):
    """The generated header as rt.h and ``driver`` as NAME.c, built by ``cc`` (-O2, C99, every warning an error,
    ``-D`` each of ``defines``) into the shared library NAME.so, loaded."""
    (tmp_path / "rt.h").write_text(header)
    (tmp_path / f"{name}.c").write_text(driver)
    library = tmp_path / f"{name}.so"
    done = subprocess.run([CC, "-O2", "-std=c99", "-Wall", "-Wextra", "-Werror", "-pedantic",
                           *(f"-D{d}" for d in defines), "-shared", "-fPIC", f"{name}.c", "-o", str(library), "-lm"],
                          cwd=tmp_path, capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    return ctypes.CDLL(str(library))


def build(tmp_path, header: str):
    lib = compile_driver(tmp_path, header, DRIVER)
    lib.replay.restype = lib.refuses.restype = ctypes.c_int
    return lib


def pointer(a: np.ndarray, kind=ctypes.c_double):
    return a.ctypes.data_as(ctypes.POINTER(kind))


def replay_c(lib, time, u, gravity, override, action, tool):
    n = time.size
    out = np.zeros((n, FIELDS))
    arrays = [np.ascontiguousarray(x, dtype=float) for x in (time, u, gravity)]
    ints = [np.ascontiguousarray(x, dtype=np.int32) for x in (override, action)]
    rc = lib.replay(n, *(pointer(a) for a in arrays), *(pointer(a, ctypes.c_int) for a in ints), tool, pointer(out))
    assert rc == 0
    return out


@pytest.fixture(scope="module")
def scenario():
    s = LiveScenario(duration=40.0, rate=250.0, hold_s=3.0, move_s=1.0, walk=(3.0, 0.3), ramp=(20.0, 1.0),
                     contacts=((9.3, 2.0, 10.0),), swaps=((24.0, "drill"),), seed=5)
    return s, simulate_live(s)


def python_replay(live: LiveCalibrator, time, u, gravity, static, actions):
    """The Python calibrator over the same samples, with the same calls before the same samples."""
    cuts = sorted(set(actions) | {0, time.size})
    parts = []
    for a, b in zip(cuts[:-1], cuts[1:]):
        if a in actions:
            actions[a](live)
        parts.append(live.run(time[a:b], raw=u[a:b], gravity=gravity[a:b],
                              static=None if static is None else static[a:b]))
    return {k: np.concatenate([getattr(p, k) for p in parts]) for k in
            ("calibrated", "compensated", "bias", "bias_std", "chi2", "static", "updated", "flags")}


def compare(out, ref):
    for i, key in enumerate(("calibrated", "compensated", "bias", "bias_std")):
        np.testing.assert_allclose(out[:, 6 * i:6 * i + 6], ref[key], rtol=1e-9, atol=1e-9, err_msg=key)
    np.testing.assert_allclose(out[:, 24], ref["chi2"], rtol=1e-9, atol=1e-9)
    code = out[:, 25].astype(int)
    np.testing.assert_array_equal(code & 1, ref["static"])
    np.testing.assert_array_equal(code >> 1, ref["updated"])
    np.testing.assert_array_equal(out[:, 26].astype(int), ref["flags"])


@pytest.mark.parametrize("degree", [1, 3])
def test_c_step_replays_a_recording_as_the_python_calibrator(tmp_path, scenario, degree):
    s, rec = scenario
    model, mix = gauge_model(degree)
    tools = {name: tool_payload(tool) for name, tool in s.tools.items()}
    lib = build(tmp_path, generate_c_runtime(model, tools, name="rt"))
    n = rec.time.size
    temperature = np.where(rec.time < 33.0, 30.0, 50.0)  # beyond the model's 20-45 °C from 33 s on
    u = np.column_stack([rec.wrench @ mix.T + 0.01 * (temperature[:, None] - 30.0), temperature])
    u[int(0.5 * n):int(0.5 * n) + 300, 3] = u[int(0.5 * n), 3]  # gauge 4 freezes while the others move
    swap, retare = int(np.searchsorted(rec.time, 24.0)), int(np.searchsorted(rec.time, 30.5))
    action = np.zeros(n, int)
    action[swap], action[retare] = 2, -1
    out = replay_c(lib, rec.time, u, rec.gravity, np.full(n, -1), action, 1)
    live = LiveCalibrator(model, tools=tools, tool="gripper")
    ref = python_replay(live, rec.time, u, rec.gravity, None,
                        {swap: lambda c: c.switch_tool("drill"), retare: lambda c: c.retare()})
    compare(out, ref)
    # The replay exercised what it claims: updates and holds, and each of these flags.
    assert ref["updated"].any() and (ref["static"] & ~ref["updated"]).any()
    for flag in ("contact", "stuck", "temperature"):
        assert np.any(ref["flags"] & BIT[flag]), flag
    # Truth: the held contact (10 N) is flagged by the C step, mid-contact, while the robot holds still.
    flags = out[:, 26].astype(int)
    held = (np.abs(rec.contact[:, :3]).max(axis=1) > 5.0) & rec.holding
    assert held.sum() > 100 and np.mean(flags[held] & BIT["contact"] != 0) > 0.95


@pytest.mark.parametrize("reaction", [False, True])
def test_static_override_and_saturation_follow_the_python_calibrator(tmp_path, scenario, reaction):
    """With a ``reaction`` payload the sensor reports the opposite sign, and so do the readings here."""
    s, rec = scenario
    model, mix = gauge_model(1, seed=4)
    tools = {"gripper": dataclasses.replace(tool_payload(s.tools["gripper"]), reaction=reaction)}
    lib = build(tmp_path, generate_c_runtime(model, tools, name="rt"))
    n = 3000
    time, gravity = rec.time[:n], rec.gravity[:n]
    u = np.column_stack([(-1.0 if reaction else 1.0) * rec.wrench[:n] @ mix.T, np.full(n, 30.0)])
    u[1000:1100, 0] = 1e3  # gauge 1 pinned far beyond anything the calibration saw
    static = rec.holding[:n] & (np.arange(n) % 7 != 0)
    out = replay_c(lib, time, u, gravity, static.astype(int), np.zeros(n, int), 1)
    ref = python_replay(LiveCalibrator(model, tools=tools, tool="gripper"), time, u, gravity, static, {})
    compare(out, ref)
    assert ref["updated"].sum() > 1000  # the tool's sign is right: its static samples pass the gate
    saturated = (ref["flags"] & BIT["saturated"]) != 0
    # Flat for >= 20 samples outside the range: samples 1019 to 1099 (data.signals.SATURATION_RUN = 20).
    assert saturated[1019:1100].all() and not saturated[:1019].any() and not saturated[1100:].any()
    assert np.all(ref["flags"][1000:1100] & BIT["out_of_range"])


FLOAT_DRIVER = r"""
#include "rt.h"
/* The same replay in a float build (-DRT_REAL=float): samples converted to float, outputs back to double. */
int replay(int n, const double *t, const double *u, const double *g, const int *override, const int *action,
           int tool, double *out)
{
    rt_state s;
    rt_output o;
    rt_real uf[RT_N_INPUTS], gf[3];
    int k, j;
    if (sizeof(rt_real) != sizeof(float) || rt_init(&s, tool)) return -2;
    for (k = 0; k < n; ++k) {
        (void)action;
        for (j = 0; j < RT_N_INPUTS; ++j) uf[j] = (rt_real)u[RT_N_INPUTS * k + j];
        for (j = 0; j < 3; ++j) gf[j] = (rt_real)g[3 * k + j];
        if (rt_step(&s, t[k], uf, gf, override[k], &o)) return -1 - k;
        for (j = 0; j < 6; ++j) {
            out[27 * k + j] = o.calibrated[j];
            out[27 * k + 6 + j] = o.compensated[j];
            out[27 * k + 12 + j] = o.bias[j];
            out[27 * k + 18 + j] = o.bias_std[j];
        }
        out[27 * k + 24] = o.chi2;
        out[27 * k + 25] = o.is_static + 2 * o.updated;
        out[27 * k + 26] = o.flags;
    }
    return 0;
}
"""


def test_a_float_build_tracks_the_bias_and_flags_the_contact(tmp_path, scenario):
    """``-DRT_REAL=float``: the same core in single precision (times stay double). Truth: the simulated bias and
    the held contact; and it stays within float's reach of the double build."""
    s, rec = scenario
    model, mix = gauge_model(1)
    tools = {name: tool_payload(tool) for name, tool in s.tools.items()}
    header = generate_c_runtime(model, tools, name="rt")
    single = compile_driver(tmp_path, header, FLOAT_DRIVER, defines=["RT_REAL=float"], name="float")
    single.replay.restype = ctypes.c_int
    n = 5000  # before the tool swap
    u = np.column_stack([rec.wrench[:n] @ mix.T, np.full(n, 30.0)])
    args = (rec.time[:n], u, rec.gravity[:n], np.full(n, -1), np.zeros(n, int), 1)
    out = replay_c(single, *args)
    double = replay_c(build(tmp_path, header), *args)
    flags = out[:, 26].astype(int)
    held = (np.abs(rec.contact[:n, :3]).max(axis=1) > 5.0) & rec.holding[:n]
    assert held.sum() > 100 and np.mean(flags[held] & BIT["contact"] != 0) > 0.95
    settled = rec.time[:n] > 5.0
    # the bias follows the simulated one (within 4 of its own standard deviations and 0.1 N) as the double does
    error = np.abs(out[settled, 12:15] - rec.bias[:n][settled, :3])
    assert np.mean(np.all(error < np.maximum(4 * out[settled, 18:21], 0.1), axis=1)) > 0.95
    # single precision: the compensated force within 1e-4 N of the double build's on all but a few samples
    near = np.all(np.abs(out[:, 6:9] - double[:, 6:9]) < 1e-4, axis=1)
    assert np.mean(near) > 0.99


def test_bad_samples_are_refused_and_leave_the_state_unchanged(tmp_path):
    model, _ = gauge_model(1)
    lib = build(tmp_path, generate_c_runtime(model, {}, name="rt"))
    u = np.r_[np.zeros(6), 30.0]
    assert lib.refuses(pointer(u), pointer(np.array([0.0, 0.0, -9.81]))) == 1


def test_convert_writes_a_header_that_compiles_with_hostile_names(tmp_path, capsys):
    model, _ = gauge_model(2)
    model_path = tmp_path / "m.json"
    save_model(model, model_path)
    payload = tmp_path / "tool.json"
    save_payload(tool_payload(LiveScenario().tools["gripper"]), payload)
    header = tmp_path / "ft_runtime.h"
    hostile = 'x"*/ int evil; /*??/\n'
    assert main(["convert", str(model_path), "--to", "c-runtime", "--payload-file", str(payload),
                 "--payload-file", f"{hostile}={payload}", "--name", "rt", "-o", str(header)]) == 0
    assert "rt_step" in capsys.readouterr().out
    # Without --name the prefix is the header's name when it is a C identifier, else ftcal_runtime.
    for file_name, prefix in (("ft_x.h", "ft_x_step"), ("ft-x.h", "ftcal_runtime_step")):
        assert main(["convert", str(model_path), "--to", "c-runtime", "-o", str(tmp_path / file_name)]) == 0
        assert prefix in capsys.readouterr().out and f"{prefix}(" in (tmp_path / file_name).read_text()
    # The name reaches the C only as a string literal: the program prints it back byte for byte.
    (tmp_path / "use.c").write_text('#include "ft_runtime.h"\n#include <stdio.h>\n'
                                    'int main(void) { rt_state s; rt_init(&s, 2);\n'
                                    '  fputs(rt_tool_name(&s, s.tool), stdout); return 0; }\n')
    done = subprocess.run([CC, "-O2", "-std=c99", "-Wall", "-Werror", "use.c", "-o", "use", "-lm"], cwd=tmp_path,
                          capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    assert subprocess.run([str(tmp_path / "use")], capture_output=True).stdout == hostile.encode()


@pytest.mark.parametrize("argv, fragment", [
    (["--payload-file", "missing.json"], "missing.json"),
    (["--payload-file", "a=PAYLOAD", "--payload-file", "a=PAYLOAD"], "the name 'a' is taken"),
    (["--payload-file", "none=PAYLOAD"], "a name other than 'none'"),
    (["--name", "2x"], "is not a C identifier"),
])
def test_bad_convert_input_is_one_line_and_writes_nothing(tmp_path, capsys, argv, fragment):
    model, _ = gauge_model(1)
    model_path = tmp_path / "m.json"
    save_model(model, model_path)
    payload = tmp_path / "tool.json"
    save_payload(tool_payload(LiveScenario().tools["gripper"]), payload)
    header = tmp_path / "rt.h"
    argv = [a.replace("PAYLOAD", str(payload)).replace("missing.json", str(tmp_path / "missing.json")) for a in argv]
    assert main(["convert", str(model_path), "--to", "c-runtime", *argv, "-o", str(header)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and fragment in err[0], err
    assert not header.exists()


def test_the_ros2_control_snippet_of_docs_live_compiles(tmp_path):
    from pathlib import Path

    docs = (Path(__file__).resolve().parents[2] / "docs/live.md").read_text()
    snippet = docs[docs.index("**From ros2_control.**"):].split("```c\n", 1)[1].split("```", 1)[0]
    model, _ = gauge_model(1)
    tools = {"gripper": tool_payload(LiveScenario().tools["gripper"])}
    (tmp_path / "ft_runtime.h").write_text(generate_c_runtime(model, tools, name="ft_runtime"))
    (tmp_path / "controller.c").write_text(snippet)
    done = subprocess.run([CC, "-O2", "-std=c99", "-Wall", "-Wextra", "-Werror", "-c", "controller.c"], cwd=tmp_path,
                          capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
