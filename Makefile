# One-command entry points. Every target creates .venv and installs ftcal first,
# so a fresh machine with only Python 3.11 and pip is enough.
PYTHON ?= python3.11
VENV := .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed

.PHONY: install demo test bench clean ros2-venv

$(PY):
	@command -v $(PYTHON) >/dev/null 2>&1 || { echo "error: $(PYTHON) not found; set PYTHON=/path/to/python3.11" >&2; exit 2; }
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip

# setup.py builds the compiled statistics kernel (src/ftcal/core/_polynomial.c) and the live step's C core
# (src/ftcal/live/_core.c) when a C compiler is there.
$(STAMP): $(PY) pyproject.toml setup.py src/ftcal/core/_polynomial.c src/ftcal/live/_core.c \
	src/ftcal/live/csrc/ftcal_live.h src/ftcal/live/csrc/ftcal_live_selfcheck.h
	$(PY) -m pip install --quiet -e ".[test]"
	@touch $(STAMP)

install: $(STAMP)

demo: $(STAMP)
	$(VENV)/bin/ftcal demo --out ftcal-demo

# ROS 2 Jazzy's binary wheels and ftcal in a venv of their own for tests/live/test_live_ros2.py: their
# ros_wheels_bootstrapper .pth re-executes every Python of the venv it is in, so never in $(VENV). An install that
# fails (no network, no wheels for this Python) does not fail the build: it leaves .failed, and the tests skip
# with that line.
ROS2_VENV := .venv-ros2
ROS2_STAMP := $(ROS2_VENV)/.installed
ROS2_PACKAGES := "ros-jazzy-rclpy>=7.1,<8" "ros-jazzy-rmw-fastrtps-cpp>=8.4,<9" "ros-jazzy-geometry-msgs>=5.3,<6" \
	"ros-jazzy-sensor-msgs>=5.3,<6" "ros-jazzy-std-msgs>=5.3,<6" "ros-jazzy-std-srvs>=5.3,<6" \
	"ros-jazzy-diagnostic-msgs>=5.3,<6" "ros-jazzy-rosidl-generator-type-description>=4.6,<5"
$(ROS2_STAMP): pyproject.toml setup.py
	@rm -f $(ROS2_VENV)/.failed
	@{ $(PYTHON) -m venv $(ROS2_VENV) && $(ROS2_VENV)/bin/python -m pip install --quiet --upgrade pip \
	  && $(ROS2_VENV)/bin/python -m pip install --quiet $(ROS2_PACKAGES) \
	  && $(ROS2_VENV)/bin/python -m pip install --quiet -e . && touch $(ROS2_STAMP); } > $(ROS2_VENV).log 2>&1 \
	  || { mkdir -p $(ROS2_VENV); echo "the ROS 2 wheels did not install (see $(ROS2_VENV).log)" > $(ROS2_VENV)/.failed; \
	       echo "note: ROS 2 venv not made; tests/live/test_live_ros2.py will skip (see $(ROS2_VENV).log)"; }

ros2-venv: $(ROS2_STAMP)

# Two pytest-xdist workers, one test file each at a time (a file's module fixtures, e.g. the README's demo, run
# once); every test writes under its own tmp_path, ports are picked free, Dask dashboards bind ":0".
# TEST_WORKERS=0 runs in one process.
TEST_WORKERS ?= 2
# Bytecode first (as for bench): with PYTHONDONTWRITEBYTECODE set, each of the suite's `ftcal` child processes
# would compile every module it imports again.
test: $(STAMP) ros2-venv
	$(PY) -m compileall -q src
	$(PY) -m pytest -q -n $(TEST_WORKERS) --dist loadfile

# Bytecode first, as a wheel install has it: with PYTHONDONTWRITEBYTECODE set, an editable
# install would recompile every module in every timed process.
bench: $(STAMP)
	$(PY) -m compileall -q src benchmarks
	$(PY) -m benchmarks

clean:
	rm -rf $(VENV) $(ROS2_VENV) $(ROS2_VENV).log ftcal-demo .pytest_cache build src/ftcal/core/*.so src/ftcal/live/*.so
