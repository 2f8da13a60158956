# The two commands of the README: `make run` and `make test`. Each one creates the virtual
# environment in .venv (if absent), installs the project with its pinned dependencies, then
# does its job. Nothing is installed outside the repository.
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
PIP := $(BIN)/python -m pip install --quiet --disable-pip-version-check -c constraints.txt
# `make run` serves on PLANNER_HOST:PLANNER_PORT, the variables `planner serve` reads (default
# 127.0.0.1:8000): `PLANNER_PORT=8821 make run`; `make run PORT=8821` works too.
HOST ?= $(or $(PLANNER_HOST),127.0.0.1)
PORT ?= $(or $(PLANNER_PORT),8000)

.PHONY: install install-test run test bench lint typecheck clean lock

# The run-time install (`make run`: the library and the service, no test tools, no Ray) and
# the test install (`make test`: adds the test tools and the Ray extra its test needs) share
# one .venv; each has its own stamp, redone when pyproject.toml or constraints.txt change.
$(BIN)/python:
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --disable-pip-version-check --upgrade pip

$(VENV)/.installed-run: pyproject.toml constraints.txt | $(BIN)/python
	$(PIP) -e .
	@touch $@

# openapi-python-client (tests/service/test_openapi_client.py generates a client with it) caps
# typer below the version the CLI pins, for its own command line only; the test calls its
# library, so it is installed without its dependencies (those it uses are in the test extra),
# at the version constraints.txt pins.
$(VENV)/.installed-test: pyproject.toml constraints.txt | $(BIN)/python
	$(PIP) -e '.[test,ray]'
	$(PIP) --no-deps openapi-python-client
	@touch $@ $(VENV)/.installed-run

install: $(VENV)/.installed-run

install-test: $(VENV)/.installed-test

# numba compiles the kernels once into its on-disk cache (tens of seconds the first time on a
# slow machine, with a progress bar), so that neither the first request nor a test pays.
run: $(VENV)/.installed-run
	$(BIN)/planner warm-up
	$(BIN)/planner serve --host $(HOST) --port $(PORT)

test: $(VENV)/.installed-test
	$(BIN)/planner warm-up
	$(BIN)/python -m pytest -q -n 2

bench: $(VENV)/.installed-test
	@for f in benchmarks/[a-z]*.py; do echo "== $$f"; $(BIN)/python $$f || exit 1; done

lint: $(VENV)/.installed-test typecheck
	$(BIN)/ruff check src api tests benchmarks examples deploy
	$(BIN)/ruff format --check src api tests benchmarks examples deploy

# mypy over the library, the service and the CLI ([tool.mypy] in pyproject.toml), so that the
# type hints `py.typed` promises are checked, not only claimed. The service's folder api/
# installs as planner_api through setuptools' editable finder, which mypy does not run: a link
# build/mypy/planner_api -> api/ lets mypy find the package under its installed name.
typecheck: $(VENV)/.installed-test
	@mkdir -p build/mypy
	@ln -sfn ../../api build/mypy/planner_api
	$(BIN)/python -m mypy

# Re-pin constraints.txt from the test environment (a superset of the run-time one) after
# changing pyproject.toml.
lock: $(VENV)/.installed-test
	$(BIN)/python -m pip freeze --exclude-editable --disable-pip-version-check | grep -v '^hybrid-planner' > constraints.txt

clean:
	rm -rf $(VENV) build *.egg-info .pytest_cache .ruff_cache .mypy_cache
