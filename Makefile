# One-command entry points. Every target creates .venv and installs ftcal first,
# so a fresh machine with only Python 3.11 and pip is enough.
PYTHON ?= python3.11
VENV := .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed

.PHONY: install demo test bench clean

$(PY):
	@command -v $(PYTHON) >/dev/null 2>&1 || { echo "error: $(PYTHON) not found; set PYTHON=/path/to/python3.11" >&2; exit 2; }
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip

# setup.py builds the compiled statistics kernel (src/ftcal/core/_polynomial.c) when a C compiler is there.
$(STAMP): $(PY) pyproject.toml setup.py src/ftcal/core/_polynomial.c
	$(PY) -m pip install --quiet -e ".[test]"
	@touch $(STAMP)

install: $(STAMP)

demo: $(STAMP)
	$(VENV)/bin/ftcal demo --out ftcal-demo

# Two pytest-xdist workers, one test file each at a time (a file's module fixtures, e.g. the README's demo, run
# once); every test writes under its own tmp_path, ports are picked free, Dask dashboards bind ":0".
# TEST_WORKERS=0 runs in one process.
TEST_WORKERS ?= 2
test: $(STAMP)
	$(PY) -m pytest -q -n $(TEST_WORKERS) --dist loadfile

# Bytecode first, as a wheel install has it: with PYTHONDONTWRITEBYTECODE set, an editable
# install would recompile every module in every timed process.
bench: $(STAMP)
	$(PY) -m compileall -q src benchmarks
	$(PY) -m benchmarks

clean:
	rm -rf $(VENV) ftcal-demo .pytest_cache build src/ftcal/core/*.so
