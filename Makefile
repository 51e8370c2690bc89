# geoq: every target sets itself up on a fresh machine (Python 3.11 + pip) and is idempotent.
PYTHON ?= $(shell command -v python3.11 || command -v python3)
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed
EXTRAS := test,bench,dev
# The lock: exact versions of everything make install installs, one file per Python
# (make lock writes it; pyproject.toml keeps the loose lower bounds for library users).
PYVER  := $(shell $(PYTHON) -c 'import sys; print("%d.%d" % sys.version_info[:2])')
LOCK   := requirements/py$(PYVER).txt
OUT    ?= results/demo
comma  := ,
# Worker processes of the reproduction's sweeps (results do not depend on it).
JOBS   ?= 2

.PHONY: install test test-kernels test-latest test-mujoco lock demo lint bench reproduce-paper suite docs clean

install: $(STAMP)

$(STAMP): pyproject.toml $(wildcard $(LOCK))
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	@if [ -f $(LOCK) ]; then \
		echo "installing the locked versions of $(LOCK)"; \
		$(BIN)/python -m pip install --quiet -c $(LOCK) -e ".[$(EXTRAS)]"; \
	else \
		echo "no lock for Python $(PYVER) ($(LOCK)): installing the newest releases; make lock writes one"; \
		$(BIN)/python -m pip install --quiet -e ".[$(EXTRAS)]"; \
	fi
	touch $(STAMP)

# Both cores (pytest-xdist, one worker per CPU; idle workers take queued tests).
PYTEST := $(BIN)/python -m pytest -q -n auto --dist worksteal

test: install
	$(PYTEST)

# The tests that compare numbers with recorded ones, under the kernels of three kinds of
# x86-64 CPU on this one (native, AVX2, SSE; tests/_kernels.py). Arguments: ARGS="...".
test-kernels: install
	$(BIN)/python -m tests._kernels $(ARGS)

# Re-resolve the lock to the newest releases pyproject.toml allows (uv, in a venv of its own).
lock:
	$(PYTHON) -m venv .venv-lock
	.venv-lock/bin/python -m pip install --quiet --upgrade "uv>=0.5"
	.venv-lock/bin/uv pip compile pyproject.toml --upgrade --python-version $(PYVER) \
		$(foreach e,$(subst $(comma), ,$(EXTRAS)),--extra $(e)) --no-emit-package geoq \
		--custom-compile-command "make lock" --output-file $(LOCK)

# The suite against the newest releases, in a fresh venv of its own: drift found on purpose.
# The tests of Gymnasium's MuJoCo tasks: installs the optional extra mujoco into .venv first.
test-mujoco: install
	$(BIN)/python -m pip install --quiet -c $(LOCK) -e ".[mujoco]"
	$(PYTEST) -m mujoco

test-latest:
	rm -rf .venv-latest
	$(PYTHON) -m venv .venv-latest
	.venv-latest/bin/python -m pip install --quiet --upgrade pip
	.venv-latest/bin/python -m pip install --quiet --upgrade --upgrade-strategy eager -e ".[$(EXTRAS)]"
	.venv-latest/bin/python -m pip list --format=freeze | grep -iE "^(numpy|scipy|numba|gymnasium|matplotlib)=="
	.venv-latest/bin/python -m pytest -q -n auto --dist worksteal -p no:cacheprovider

demo: install
	$(BIN)/geoq reproduce --out $(OUT) --scale quick --jobs $(JOBS)

reproduce-paper: install
	$(BIN)/geoq reproduce --out results/paper --scale paper --jobs $(JOBS)

suite: install
	$(BIN)/geoq suite --out results/suite --scale quick --jobs $(JOBS)

lint: install
	$(BIN)/ruff check src tests benchmarks research
	$(BIN)/ruff format --check src tests benchmarks research
	$(BIN)/mypy
	$(BIN)/lint-imports

# The documentation site into build/site, warnings as errors. MkDocs + Material + mkdocstrings:
# the pages stay Markdown that reads on GitHub as it is, and the API pages come from the
# docstrings by static analysis (nothing imported). Its packages: the docs extra, installed
# here on first use (make install does not need them).
DOCS_STAMP := $(VENV)/.docs-installed

docs: $(DOCS_STAMP)
	NO_MKDOCS_2_WARNING=1 $(BIN)/mkdocs build --strict

$(DOCS_STAMP): $(STAMP)
	@if [ -f $(LOCK) ]; then \
		$(BIN)/python -m pip install --quiet -c $(LOCK) -e ".[docs]"; \
	else \
		$(BIN)/python -m pip install --quiet -e ".[docs]"; \
	fi
	touch $(DOCS_STAMP)

bench: install
	$(BIN)/python benchmarks/run.py

clean:
	rm -rf $(VENV) .venv-lock .venv-latest build src/*.egg-info .pytest_cache .mypy_cache .ruff_cache
