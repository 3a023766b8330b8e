"""Worker processes (ftcal.runtime.processes): ordered results, errors, dead workers, and stopping.

The functions run in the workers are standard-library callables (``abs``, ``bytes``,
``math.sqrt``) except one that kills its worker, defined here.
"""

from __future__ import annotations

import math
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

from ftcal.runtime.errors import FtcalError
from ftcal.runtime.processes import WorkerProcesses

SRC = str(Path(__file__).resolve().parents[2] / "src")


def test_results_come_back_in_the_order_of_the_jobs():
    jobs = [(-1) ** k * k for k in range(37)]
    with WorkerProcesses(3, abs, (0,)) as processes:
        assert list(processes.map(abs, jobs)) == [abs(j) for j in jobs]


def test_a_workers_error_is_raised_here_with_its_own_type_and_message():
    with pytest.raises(ValueError, match="math domain error"):
        with WorkerProcesses(2, abs, (0,)) as processes:
            list(processes.map(math.sqrt, [4.0, 9.0, -1.0, 16.0]))


def test_an_initializer_error_is_raised_here():
    with pytest.raises(ValueError, match="math domain error"):
        with WorkerProcesses(1, math.sqrt, (-1.0,)) as processes:
            list(processes.map(abs, [1]))


def test_a_worker_that_dies_is_one_ftcal_error():
    with pytest.raises(FtcalError, match="worker process died while computing job 1"):
        with WorkerProcesses(1, abs, (0,)) as processes:
            list(processes.map(_exit_second, [0, 3]))


def _exit_second(code):  # pragma: no cover - runs in the worker
    return os._exit(code) if code else code


@pytest.mark.skipif(not Path("/proc/self").is_dir(), reason="needs /proc to see the workers")
def test_an_interrupt_while_workers_send_large_results_stops_them(tmp_path):
    """The class behind a hung `ftcal expected --workers 2`: multiprocessing.Pool.terminate waits forever
    for the result pipe's lock when a worker is blocked sending a large result (checked by hand: a Pool
    with 20 MB results interrupted after the first one hangs). Here the block must end, workers dead."""
    script = tmp_path / "interrupt.py"
    script.write_text(textwrap.dedent(f"""
        import multiprocessing, sys
        sys.path.insert(0, {SRC!r})
        from ftcal.runtime.processes import WorkerProcesses
        if __name__ == "__main__":
            try:
                with WorkerProcesses(2, abs, (0,)) as processes:
                    print(*[p.pid for p in multiprocessing.active_children()], flush=True)
                    for result in processes.map(bytes, [20_000_000] * 20):
                        raise KeyboardInterrupt
            except KeyboardInterrupt:
                print("interrupted", flush=True)
    """))
    done = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, timeout=120)
    lines = done.stdout.splitlines()
    assert done.returncode == 0 and lines[-1] == "interrupted", done.stderr
    pids = [int(p) for p in lines[0].split()]
    assert len(pids) == 2
    for pid in pids:
        stat = Path(f"/proc/{pid}/stat")
        assert not stat.exists() or stat.read_text().split()[2] == "Z"


PIPELINE = """
import sys
sys.path.insert(0, {src!r})
import numpy as np
from ftcal.robot import RobotModel
from ftcal.robot.expected import PARALLEL_MIN_SAMPLES, expected_wrenches
from ftcal.sim.plan_arm import ARM_URDF
{guard}
{indent}robot = RobotModel.from_text(ARM_URDF, "arm.urdf")
{indent}q = np.random.default_rng(0).uniform(-1, 1, (PARALLEL_MIN_SAMPLES + 10, len(robot.joint_names)))
{indent}wrench = expected_wrenches(robot, q, workers=2, description="")
{indent}np.save({out!r}, wrench)
"""


def test_a_script_without_the_main_guard_runs_in_process_with_one_warning(tmp_path):
    # README's Python pipeline saved as a file and run: the spawned workers imported the script again and
    # each tried to spawn its own (three tracebacks). Now the work runs in this process, with one warning;
    # with the guard, the same numbers come from two worker processes.
    runs = {}
    for name, guard in (("bare", ""), ("guarded", 'if __name__ == "__main__":')):
        script = tmp_path / f"{name}.py"
        script.write_text(PIPELINE.format(src=SRC, guard=guard, indent="    " if guard else "",
                                          out=str(tmp_path / f"{name}.npy")))
        done = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, timeout=300,
                              cwd=tmp_path)
        assert done.returncode == 0 and "Traceback" not in done.stderr, done.stderr
        runs[name] = done
    bare, guarded = runs["bare"], runs["guarded"]
    assert f"{tmp_path / 'bare.py'} calls ftcal at its top level without 'if __name__ == \"__main__\":'" in bare.stderr
    assert bare.stderr.count("FtcalWarning") == 1 and "FtcalWarning" not in guarded.stderr
    np.testing.assert_array_equal(np.load(tmp_path / "bare.npy"), np.load(tmp_path / "guarded.npy"))


def test_a_local_dask_cluster_from_a_script_without_the_guard_is_one_line(tmp_path):
    # Dask spawns its workers too: from the top level of an unguarded script they would run it again.
    script = tmp_path / "cluster.py"
    script.write_text(textwrap.dedent(f"""
        import sys
        sys.path.insert(0, {SRC!r})
        from ftcal.runtime.errors import FtcalError
        from ftcal.runtime.executors import open_executor
        try:
            with open_executor("local:2") as executor:
                executor.client
        except FtcalError as exc:
            print(exc)
    """))
    done = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, timeout=120, cwd=tmp_path)
    assert done.returncode == 0 and "Traceback" not in done.stderr, done.stderr
    assert done.stdout.strip() == (f"scheduler local:2: {script} calls ftcal at its top level without 'if __name__ "
                                   "== \"__main__\":', and each local worker process would run the script again; put "
                                   "the calls under that guard, or leave out the scheduler.")
