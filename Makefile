# Every target works from a fresh clone with only Python 3.11 and pip:
# the first one that needs it creates .venv and installs the project.
PYTHON ?= $(shell command -v python3.11 || command -v python3)
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed-stamp

.PHONY: run test lint bench bench-quick schema clean

RUNTIME_STAMP := $(VENV)/.runtime-stamp
DEMO_DB := $(VENV)/demo.db

# bash for `set -m` in run (below)
SHELL := /bin/bash

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[dev]'
	touch $(STAMP) $(RUNTIME_STAMP)

# The daemon alone (about a third of the dev toolchain's size), shown as it installs:
# what run needs on a fresh clone.
$(RUNTIME_STAMP): pyproject.toml
	@echo "make: installing dms and what it runs on into $(VENV) (the first time only; pip's progress follows)"
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --progress-bar on -e .
	touch $(RUNTIME_STAMP)

## run: the daemon on its embedded defaults, with a simulated visitor, decisions printed,
## on a database of its own (.venv/demo.db: your default one is left alone); Ctrl-C stops
## it, exit 0. `set -m` runs it as the terminal's foreground job, so Ctrl-C reaches the
## daemon only and make does not end on the signal.
run: $(RUNTIME_STAMP)
	@set -m; $(BIN)/dms run --visitor demo --db 'sqlite:///$(abspath $(DEMO_DB))'; \
	code=$$?; if [ $$code -eq 130 ]; then exit 0; else exit $$code; fi

## test: the whole suite (unit, integration, scenarios), a test file per worker, two at once
## (most integration tests wait on a real daemon's clock, so two workers halve the time)
test: $(STAMP)
	$(BIN)/python -m pytest -q -n 2 --dist loadfile

## lint: ruff, mypy and the import floors (docs/architecture.md); the Reachy Mini bridge's
## types against its own environment
lint: $(STAMP)
	$(BIN)/ruff check .
	$(BIN)/ruff format --check .
	$(BIN)/mypy dms managers activities motivation memory agenda sim
	$(BIN)/lint-imports
	@if [ -x .venv-reachy/bin/python ]; then \
	  $(BIN)/mypy --config-file reachy/pyproject.toml --python-executable .venv-reachy/bin/python reachy/dms_reachy; \
	else echo "lint: no .venv-reachy (dms reachy --prepare): the Reachy Mini bridge is not type-checked" >&2; fi

## bench: every benchmark, JSON on stdout (stops at the first that fails)
bench: $(STAMP)
	@set -e; for b in bench/bench_*.py; do echo "$$b" >&2; $(BIN)/python $$b; done

## bench-quick: every benchmark at small sizes through the same code (a smoke test for CI)
bench-quick: $(STAMP)
	@set -e; for b in bench/bench_*.py; do echo "$$b --quick" >&2; $(BIN)/python $$b --quick; done

schema: $(STAMP)
	$(BIN)/dms schema docs/schema

clean:
	rm -rf $(VENV) build *.egg-info
