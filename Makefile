# Two commands work on a fresh machine: `make demo` and `make test`.
# Both create .venv when it is missing and (re)install the project only when
# pyproject.toml or constraints.txt (the exact releases, below) changed since the last install,
# so a second run starts at once.

PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed
TEST_STAMP := $(VENV)/.installed-test
export PYOPENGL_PLATFORM := egl
export PIP_DISABLE_PIP_VERSION_CHECK := 1

.PHONY: demo test bench install clean

$(BIN)/python:
	$(PYTHON) -m venv $(VENV)

# torch==2.13.0 must come from the local CPU wheel (PIP_FIND_LINKS), never the CUDA build.
$(STAMP): pyproject.toml constraints.txt | $(BIN)/python
	$(BIN)/pip install --quiet --find-links /opt/wheels -c constraints.txt torch==2.13.0
	$(BIN)/pip install --quiet --find-links /opt/wheels -c constraints.txt -e .
	touch $(STAMP)

# The tests also need the test tools and Ray (CI runs a sweep on the Ray backend).
$(TEST_STAMP): $(STAMP)
	$(BIN)/pip install --quiet --find-links /opt/wheels -c constraints.txt -e ".[test,ray]"
	touch $(TEST_STAMP)

install: $(TEST_STAMP)

demo: $(STAMP)
	$(BIN)/testbed run scenes/quickstart.yaml

test: $(TEST_STAMP)
	$(BIN)/python -m pytest -q -n 2

bench: $(TEST_STAMP)
	@for b in benchmarks/bench_*.py; do echo "== $$b"; $(BIN)/python $$b || exit 1; done

clean:
	rm -rf $(VENV) build *.egg-info
