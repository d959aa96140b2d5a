# Every target works from a fresh clone with only Python 3.11 and pip:
# the first one that needs it creates .venv and installs the project.
PYTHON ?= $(shell command -v python3.11 || command -v python3)
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed-stamp

.PHONY: run test lint bench bench-quick schema clean

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[dev]'
	touch $(STAMP)

## run: the daemon on its embedded defaults, with a simulated visitor, decisions printed
run: $(STAMP)
	$(BIN)/dms run --visitor demo

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
