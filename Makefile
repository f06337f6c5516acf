# Clark Engine: every task is one command. `make demo` and `make test` work on
# a fresh clone with only Python 3.11 and make; they create .venv themselves.

PYTHON ?= $(shell command -v python3.11 2>/dev/null || command -v python3)
VENV   := .venv
BIN    := $(VENV)/bin
# Test processes: one per core, one for the tests that wait on the wall clock and one for the
# second group of SITL tests by default
# (tests/conftest.py); `make test TEST_WORKERS=0` runs in one process.
TEST_WORKERS ?= auto
CKSUM  := $(shell cat pyproject.toml | cksum | cut -d' ' -f1)
# What is installed, by pyproject.toml's checksum: the engine alone (what `make demo`
# needs, about half the size) or with the test and development tools (everything else).
RUN_STAMP := $(VENV)/.installed-run-$(CKSUM)
STAMP     := $(VENV)/.installed-dev-$(CKSUM)

.PHONY: demo test lint format typecheck schemas docs bench golden check clean

$(BIN)/python:
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip

$(RUN_STAMP): pyproject.toml | $(BIN)/python
	$(BIN)/python -m pip install --quiet -e .
	rm -f $(VENV)/.installed-run-*
	touch $(RUN_STAMP)

$(STAMP): pyproject.toml | $(BIN)/python
	$(BIN)/python -m pip install --quiet -e '.[dev]'
	rm -f $(VENV)/.installed-*
	touch $(STAMP) $(RUN_STAMP)

## demo: validate and compile every example mission, print a summary and where the configs are
demo: $(RUN_STAMP)
	$(BIN)/python tools/demo.py

## test: the whole suite, spread over the machine's cores (pytest-xdist); first makes sure
## the browser tests have Debian's chromium (installed when absent and we may; else they skip)
## Python's bytecode caches are written during the run even where the environment says not
## to (PYTHONDONTWRITEBYTECODE, set on this project's machines): the suite starts hundreds of
## `clark` processes, and without the caches each compiled the engine's modules again (about
## 1 s of CPU for a dry run's; 19 % of the CLI tests' CPU). __pycache__ is git-ignored.
test: $(STAMP)
	bash tools/ensure_browser.sh
	PYTHONDONTWRITEBYTECODE= $(BIN)/python -m pytest -n $(TEST_WORKERS) --dist loadgroup

## lint / format / typecheck: the same commands CI runs
lint: $(STAMP)
	$(BIN)/ruff check .
	$(BIN)/ruff format --check .

format: $(STAMP)
	$(BIN)/ruff format .
	$(BIN)/ruff check --fix .

typecheck: $(STAMP)
	$(BIN)/mypy

## schemas: regenerate schemas/*.json, docs/reference.md and docs/runtime.md's behaviour
## sections from their Python source
schemas: $(STAMP)
	$(BIN)/python -m clark_engine.mission.schema_source
	$(BIN)/python tools/gen_reference.py
	$(BIN)/python tools/gen_runtime_doc.py

## golden: make everything the examples make again (compiled configs, seed-1 dry runs,
## generated schemas, docs and protobuf module) and compare it byte for byte with
## tests/golden/manifest.json; the gate for moving code (docs/architecture.md)
golden: $(STAMP)
	$(BIN)/python tools/golden.py --check

## bench: run the benchmarks and print their figures
bench: $(STAMP)
	$(BIN)/python benchmarks/bench_validate.py

check: lint typecheck test

clean:
	rm -rf $(VENV) build dist demo-output .pytest_cache .mypy_cache .ruff_cache
