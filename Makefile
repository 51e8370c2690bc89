# geoq: every target sets itself up on a fresh machine (Python 3.11 + pip) and is idempotent.
PYTHON ?= $(shell command -v python3.11 || command -v python3)
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed
OUT    ?= results/demo
# Worker processes of the reproduction's sweeps (results do not depend on it).
JOBS   ?= 2

.PHONY: install test demo lint bench reproduce-paper suite clean

install: $(STAMP)

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e ".[test,bench,dev]"
	touch $(STAMP)

test: install
	$(BIN)/python -m pytest -q

demo: install
	$(BIN)/geoq reproduce --out $(OUT) --scale quick --jobs $(JOBS)

reproduce-paper: install
	$(BIN)/geoq reproduce --out results/paper --scale paper --jobs $(JOBS)

suite: install
	$(BIN)/geoq suite --out results/suite --scale quick --jobs $(JOBS)

lint: install
	$(BIN)/ruff check src tests benchmarks
	$(BIN)/ruff format --check src tests benchmarks
	$(BIN)/mypy

bench: install
	$(BIN)/python benchmarks/run.py

clean:
	rm -rf $(VENV) build src/*.egg-info .pytest_cache .mypy_cache .ruff_cache
