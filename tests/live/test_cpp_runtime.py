"""``convert --to cpp-runtime``: the C live step compiles as C++17 and C++20 with every warning an error (real g++),
and the header-only C++ wrapper beside it, built into a harness that runs a 1 kHz loop, gives the Python calibrator's
numbers."""

from __future__ import annotations

import shutil
import subprocess

import numpy as np
import pytest

from test_c_runtime import compare, gauge_model, python_replay, tool_payload

from ftcal.cli import main
from ftcal.files.model_files import save_model
from ftcal.files.payload_json import save_payload
from ftcal.live import LiveCalibrator
from ftcal.sim.live_scenario import LiveScenario, simulate_live

GXX = shutil.which("g++")
pytestmark = pytest.mark.skipif(GXX is None, reason="no C++ compiler g++")
FLAGS = ["-O2", "-Wall", "-Wextra", "-Werror", "-pedantic"]

# The controller's loop: samples from a binary file (time, raw inputs, gravity, action), outputs to another; the
# re-tare and the tool switch arrive as a request between samples, as a service would set them. Nothing in the loop
# allocates: the outputs go into a buffer sized before it starts.
HARNESS = r"""
#include <cstdio>
#include <cstdlib>
#include <vector>
#include "rt.hpp"

int main(int argc, char** argv) {
  if (argc != 4) return 2;
  std::FILE* in = std::fopen(argv[1], "rb");
  long n = std::atol(argv[3]);
  std::vector<double> out(static_cast<std::size_t>(n) * 27);
  ftcal::rt runtime(1);
  ftcal::rt::Output o;
  for (long k = 0; k < n; ++k) {
    double t, action;
    ftcal::rt::Inputs u;
    ftcal::rt::Gravity g;
    if (std::fread(&t, sizeof t, 1, in) != 1 || std::fread(u.data(), sizeof(double), u.size(), in) != u.size()
        || std::fread(g.data(), sizeof(double), 3, in) != 3 || std::fread(&action, sizeof action, 1, in) != 1)
      return 3;
    if (action < 0) runtime.retare();
    else if (action > 0 && !runtime.set_tool(static_cast<int>(action))) return 4;
    if (!runtime.step(t, u, g, o)) return 5;
    double* row = out.data() + 27 * k;
    for (std::size_t j = 0; j < 6; ++j) {
      row[j] = o.calibrated[j];
      row[6 + j] = o.compensated[j];
      row[12 + j] = o.bias[j];
      row[18 + j] = o.bias_std[j];
    }
    row[24] = o.chi2;
    row[25] = (o.is_static ? 1 : 0) + 2 * (o.updated ? 1 : 0);
    row[26] = o.flags;
  }
  std::fclose(in);
  std::FILE* f = std::fopen(argv[2], "wb");
  std::fwrite(out.data(), sizeof(double), out.size(), f);
  std::fclose(f);
  return runtime.find_tool("drill") == 2 ? 0 : 6;
}
"""
# The C header alone, compiled as C++ (a ros2_control plugin may include it without the wrapper).
PLAIN = '#include "rt.h"\nint main() { static rt_state s; rt_output o; double u[RT_N_INPUTS] = {0}, ' \
        'g[3] = {0, 0, -9.81}; if (rt_init(&s, 1)) return 1; return rt_step(&s, 1.0, u, g, -1, &o) == 0 ? 0 : 1; }\n'


@pytest.fixture(scope="module")
def written(tmp_path_factory):
    """``ftcal convert --to cpp-runtime`` with two tools: rt.hpp and rt.h."""
    folder = tmp_path_factory.mktemp("cpp")
    s = LiveScenario(duration=30.0, rate=1000.0, hold_s=3.0, move_s=1.0, walk=(3.0, 0.3),
                     contacts=((9.3, 2.0, 10.0),), swaps=((18.0, "drill"),), seed=8)
    model, mix = gauge_model(2)
    save_model(model, folder / "m.json")
    tools = {name: tool_payload(tool) for name, tool in s.tools.items()}
    for name, payload in tools.items():
        save_payload(payload, folder / f"{name}.json")
    assert main(["convert", str(folder / "m.json"), "--to", "cpp-runtime", "--payload-file",
                 f"gripper={folder / 'gripper.json'}", "--payload-file", f"drill={folder / 'drill.json'}",
                 "-o", str(folder / "rt.hpp")]) == 0
    return folder, s, model, mix, tools


@pytest.mark.parametrize("std", ["c++17", "c++20"])
def test_the_c_step_and_its_wrapper_compile_as_cpp(written, std):
    folder = written[0]
    assert (folder / "rt.h").exists() and "class rt" in (folder / "rt.hpp").read_text()
    (folder / "plain.cpp").write_text(PLAIN)
    (folder / "harness.cpp").write_text(HARNESS)
    for source in ("plain.cpp", "harness.cpp"):
        done = subprocess.run([GXX, f"-std={std}", *FLAGS, source, "-o", f"{source}.{std}"], cwd=folder,
                              capture_output=True, text=True)
        assert done.returncode == 0, done.stderr[-3000:]
    assert subprocess.run([str(folder / f"plain.cpp.{std}")]).returncode == 0


def test_a_1khz_loop_through_the_wrapper_gives_pythons_numbers(written):
    folder, s, model, mix, tools = written
    rec = simulate_live(s)
    n = rec.time.size
    temperature = np.full(n, 30.0)
    u = np.column_stack([rec.wrench @ mix.T, temperature])
    swap, retare = int(np.searchsorted(rec.time, 18.0)), int(np.searchsorted(rec.time, 24.5))
    action = np.zeros(n)
    action[swap], action[retare] = 2, -1
    np.column_stack([rec.time, u, rec.gravity, action]).astype("<f8").tofile(folder / "in.bin")
    (folder / "harness.cpp").write_text(HARNESS)
    done = subprocess.run([GXX, "-std=c++17", *FLAGS, "harness.cpp", "-o", "harness"], cwd=folder,
                          capture_output=True, text=True)
    assert done.returncode == 0, done.stderr[-3000:]
    run = subprocess.run([str(folder / "harness"), "in.bin", "out.bin", str(n)], cwd=folder)
    assert run.returncode == 0
    out = np.fromfile(folder / "out.bin", dtype="<f8").reshape(n, 27)
    live = LiveCalibrator(model, tools=tools, tool="gripper")
    ref = python_replay(live, rec.time, u, rec.gravity, None,
                        {swap: lambda c: c.switch_tool("drill"), retare: lambda c: c.retare()})
    compare(out, ref)
    assert ref["updated"].any() and np.any(ref["flags"])  # the loop updated the bias and raised flags
