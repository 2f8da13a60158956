# The two commands of the README: `make run` and `make test`. Each one creates the virtual
# environment in .venv (if absent), installs the project with its pinned dependencies, then
# does its job. Nothing is installed outside the repository.
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed
HOST ?= 127.0.0.1
PORT ?= 8000

.PHONY: install run test bench lint clean lock

$(STAMP): pyproject.toml constraints.txt
	@test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --disable-pip-version-check --upgrade pip
	$(BIN)/python -m pip install --quiet --disable-pip-version-check -c constraints.txt -e '.[dev]'
	@touch $@

install: $(STAMP)

# numba compiles the kernels once into its on-disk cache (about 10 s the first time), so that
# neither the first request nor a test's time budget pays for it.
run: $(STAMP)
	$(BIN)/planner warm-up
	$(BIN)/planner serve --host $(HOST) --port $(PORT)

test: $(STAMP)
	$(BIN)/planner warm-up
	$(BIN)/python -m pytest -q -n 2

bench: $(STAMP)
	@for f in benchmarks/*.py; do echo "== $$f"; $(BIN)/python $$f || exit 1; done

lint: $(STAMP)
	$(BIN)/ruff check src api tests benchmarks examples deploy
	$(BIN)/ruff format --check src api tests benchmarks examples deploy

# Re-pin constraints.txt from the current environment (after changing pyproject.toml).
lock: $(STAMP)
	$(BIN)/python -m pip freeze --exclude-editable --disable-pip-version-check | grep -v '^hybrid-planner' > constraints.txt

clean:
	rm -rf $(VENV) build *.egg-info .pytest_cache .ruff_cache
