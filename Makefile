# The front door. `make scenario town05_crowded` and `make test` create .venv on first use.
PYTHON ?= python3
VENV := .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed
NUSC_VENV := .venv-nuscenes
NUSC_STAMP := $(NUSC_VENV)/.installed

# `make scenario NAME [FRAMES=n] [SEED=s] [OUT=dir] [ARGS="--set key=value ..."]`. The name,
# FRAMES, SEED and OUT reach the command through the environment, quoted: whatever characters
# they hold (quotes, backticks, >, parentheses) are passed as they are, never run by the shell.
ifeq (scenario,$(firstword $(MAKECMDGOALS)))
  export SCENARIO_NAME := $(word 2,$(MAKECMDGOALS))
  .DEFAULT: ; @:
endif

RUN_FLAGS := $(if $(FRAMES),--frames "$$FRAMES") $(if $(SEED),--seed "$$SEED") $(if $(OUT),--out "$$OUT")

.PHONY: venv nuscenes-devkit scenario list test test-fast bench figure lint format clean

venv: $(STAMP)

$(STAMP): pyproject.toml constraints.txt
	@test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --disable-pip-version-check --upgrade pip
	$(PY) -m pip install --quiet --disable-pip-version-check -c constraints.txt -e '.[dev]'
	@touch $(STAMP)

# The official nuScenes devkit in an environment of its own (it pins numpy below 2): the tests
# read the nuScenes export with it.
nuscenes-devkit: $(NUSC_STAMP)

$(NUSC_STAMP): tests/nuscenes-devkit.txt
	@test -x $(NUSC_VENV)/bin/python || $(PYTHON) -m venv $(NUSC_VENV)
	$(NUSC_VENV)/bin/python -m pip install --quiet --disable-pip-version-check -r tests/nuscenes-devkit.txt
	@touch $(NUSC_STAMP)

scenario: $(STAMP)
	@test -n "$$SCENARIO_NAME" || { echo "usage: make scenario NAME [FRAMES=n SEED=s OUT=dir ARGS=...]; names: make list"; exit 2; }
	$(PY) -m cosim run "$$SCENARIO_NAME" $(RUN_FLAGS) $(ARGS)

list: $(STAMP)
	@$(PY) -m cosim list

# The suite on JOBS processes (pytest-xdist), each test file whole on one of them (its module
# fixtures made once): `make test JOBS=1` runs it in this process.
JOBS ?= 2
PYTEST_JOBS := $(if $(filter 1,$(JOBS)),,-n $(JOBS) --dist loadfile)

test: $(STAMP) $(NUSC_STAMP)
	$(PY) -m pytest -q $(PYTEST_JOBS)

test-fast: $(STAMP)
	$(PY) -m pytest -q -m "not slow" $(PYTEST_JOBS)

bench: $(STAMP)
	$(PY) -m cosim.bench $(ARGS)

# The README's flat/realistic camera figure (sensors/images/flat_vs_realistic.jpg), remade from a run.
figure: $(STAMP)
	$(PY) -m cosim.figure $(ARGS)

lint: $(STAMP)
	$(PY) -m ruff check cosim gtgen networks sensors tests
	$(PY) -m ruff format --check cosim gtgen networks sensors tests
	$(PY) -m mypy

format: $(STAMP)
	$(PY) -m ruff format cosim gtgen networks sensors tests
	$(PY) -m ruff check --fix cosim gtgen networks sensors tests

clean:
	rm -rf $(VENV) $(NUSC_VENV) out .pytest_cache .mypy_cache .ruff_cache
