# `make demo`, `make test`, `make screenshots` (docs/images/rerun_*.png, tools/screenshots.py).  Each creates .venv when missing.
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: demo test venv clean screenshots

$(BIN)/python:
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip

$(STAMP): $(BIN)/python pyproject.toml
	$(BIN)/python -m pip install --quiet -e '.[test]'
	touch $(STAMP)

venv: $(STAMP)

demo: $(STAMP)
	$(BIN)/python examples/demo.py --out demo.rrd

# the real Rerun viewer, headless, on the recordings of the demo and every example (installs lavapipe/Xvfb via apt-get if missing)
screenshots: $(STAMP)
	$(BIN)/python tools/screenshots.py

# one pytest worker per core (pytest-xdist); `pytest` alone runs the same tests in one process
test: $(STAMP)
	$(BIN)/python -m pytest -n auto

clean:
	rm -rf $(VENV) build *.egg-info demo.rrd
