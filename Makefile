# pickplace: `make run` runs the main job, `make test` runs the whole test suite.
# Both create .venv (if missing) and install the package into it with the versions locked in constraints.txt;
# only Python 3.11+, pip and make are needed. `make lock` re-resolves the newest versions pyproject.toml allows
# (all extras) in a throw-away venv and rewrites constraints.txt; run `make test` after it, commit if green.

PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed
LOCK   := constraints.txt
PIP    := $(BIN)/python -m pip install --quiet --constraint $(LOCK)

.PHONY: run test lint bench bench-env lock clean

# robosuite's own venv for `pickplace bench env --robosuite` (robosuite pins its own mujoco, numba and numpy: never in
# pickplace's venv); the versions in benchmarks/robosuite-constraints.txt
RS_VENV  := .bench-venv/robosuite
RS_STAMP := $(RS_VENV)/.installed

$(BIN)/python:
	$(PYTHON) -m venv $(VENV)

$(STAMP): pyproject.toml $(LOCK) | $(BIN)/python
	$(PIP) --upgrade pip
	$(PIP) -e ".[dev]"
	touch $(STAMP)

run: $(STAMP)
	$(BIN)/pickplace run

test: $(STAMP)
	$(BIN)/python -m pytest

lint: $(STAMP)
	$(BIN)/ruff check .

bench: $(STAMP)
	$(PIP) -e ".[dev,bench]"
	$(BIN)/pickplace bench planning

$(RS_STAMP): benchmarks/robosuite-constraints.txt
	rm -rf $(RS_VENV)
	$(PYTHON) -m venv $(RS_VENV)
	$(RS_VENV)/bin/python -m pip install --quiet --upgrade pip
	$(RS_VENV)/bin/python -m pip install --quiet --constraint benchmarks/robosuite-constraints.txt robosuite mujoco
	touch $@

# the Gymnasium environments' speed next to robosuite's Lift in the same run, and the skill level's success
bench-env: $(STAMP) $(RS_STAMP)
	$(BIN)/pickplace bench env --robosuite $(RS_VENV)/bin/python

lock:
	rm -rf .lock-venv
	$(PYTHON) -m venv .lock-venv
	.lock-venv/bin/python -m pip install --quiet --upgrade pip
	.lock-venv/bin/python -m pip install --quiet -e ".[dev,bench,video,ray]"
	{ echo "# Versions the test suite passes with; written by 'make lock' with $$(.lock-venv/bin/python -V)" \
	       "on $$(uname -sm), $$(date -u +%Y-%m-%d)."; \
	  .lock-venv/bin/python -m pip freeze --all --exclude-editable; } > $(LOCK)
	rm -rf .lock-venv

clean:
	rm -rf $(VENV) .lock-venv .bench-venv .pytest_cache .ruff_cache build src/*.egg-info
