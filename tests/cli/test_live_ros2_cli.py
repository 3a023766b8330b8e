"""``ftcal live --ros2`` where ROS 2 is not installed (this venv: the ROS 2 wheels live in .venv-ros2 only), and the
options that do not go with it: one line each, exit 2, nothing written."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

FTCAL = str(Path(sys.executable).with_name("ftcal"))


def test_without_rclpy_one_line_says_what_to_source_or_install(tmp_path):
    pytest.importorskip("zenoh")  # the product's venv
    try:
        import rclpy  # noqa: F401
        pytest.skip("rclpy is importable here")
    except ImportError:
        pass
    done = subprocess.run([FTCAL, "live", "--ros2", "--state", "state.json"], cwd=tmp_path, capture_output=True,
                          text=True, timeout=60)
    assert done.returncode == 2 and done.stderr.count("\n") == 1, done.stderr
    assert "source your ROS 2 setup" in done.stderr and "pip install ros-jazzy-rclpy" in done.stderr
    assert not os.listdir(tmp_path)


@pytest.mark.parametrize("argv, message", [
    (["--zenoh", "--ros-args", "-r", "a:=b"], "--ros-args goes with --ros2"),
    (["--ros2", "--listen", "tcp/127.0.0.1:7448"], "do not apply to --ros2"),
    (["--ros2", "--keys", "rmw_zenoh"], "do not apply to --ros2"),
    (["--replay", "x.csv", "--temperature-topic", "/t", "-o", "o.csv"], "--temperature-topic applies to --zenoh"),
])
def test_options_that_do_not_go_with_the_mode_are_one_line(tmp_path, argv, message):
    done = subprocess.run([FTCAL, "live", *argv], cwd=tmp_path, capture_output=True, text=True, timeout=60)
    assert done.returncode == 2 and done.stderr.count("\n") == 1 and message in done.stderr, done.stderr
    assert not os.listdir(tmp_path)
